"""DPCA micronavigation and phase gradient autofocus: ping pairs per second, the correlation
hot loop direct vs FFT, and PGA time per iteration.

DPCA runs on a synthetic track whose pings share phase centres exactly (ping p + 1's hydrophone
i records what ping p's hydrophone i + 7 recorded, plus noise: Heremans 2009's 15-hydrophone
geometry), so the estimator does its full work on every pair without a simulation first:
1000 pings (quick: 100) of 2048 samples. The correlations of eq. (51) (clsas.estimate.dpca.
correlations) are timed by their two methods, one multiply-add pass per t-lag ("direct") and
zero-padded block FFTs ("fft", every lag computed, 2 t_lags + 1 kept), and by the form the
estimator uses, with a fractional delay taken out of g's envelope ("fft-delay": blocks padded
to 2 x 128 so the whole linear correlation is held), interleaved A B C A B C, for pass 1
(t_lags 8) and pass 2 (t_lags 2), over 6 couples x 200 pairs x 16 blocks of 128 samples. PGA runs on a 2048 x 2048 image (quick: 1024^2) of speckle and bright points blurred
by a quadratic phase error; rate = iterations per second. All on the host (NumPy / scipy.fft).

The figures are in the JSON output (--json); rerun with --quick for a short run.

``--bias SEEDS`` measures instead the yaw bias of issue #30 on a motionless platform (no
timing): the 24-hydrophone sonar of tests/test_dpca_bias.py (:func:`motionless_scene`) over a
speckle seafloor 0.5x, 1x and 4x the beam's footprint long, transmitters 1x and 2x the
hydrophones' length, SEEDS seafloors of 30 pings each (``--pings``); per case the mean of the
per-pair yaws over all pairs and seeds with its standard error (from the spread of the seeds'
means), the same corrected by the seafloors' control variate (:class:`PhaseCentreControl`:
controlled_mean_urad, controlled_error_urad), the per-pair RMS and the load average.

``--edges SEEDS`` measures how the motionless yaw depends on a range block's distance from the
seafloor's near or far slant edge (issue #30's edge blocks; no timing): per case (transmitter,
extent, block length) and per edge (near, far) and depth into the swath (the block's middle, m, to
that edge, rounded to 0.25 m; negative outside), the mean over SEEDS seafloors of the block's mean yaw over the pairs
(PingPairs.block_yaw), its standard error and the fraction of pairs whose yaw took the block
(PingPairs.block_inside).

``--edge-cut SEEDS`` asks what sets the near-edge zone (no timing), on the 1x transmitter
over three seafloors per seed: the 4x seafloor of :func:`motionless_scene` ("rectangle"), the
same scatterers and more in front of them, its near edge NEARER m nearer the track ("nearer":
the zone's blocks then hold the old cut's wider look angles too), and a half annulus
(:func:`annulus_scene`, "annulus": range edges that cut no ring, estimated with extent=None).
Per seafloor and block depth inside its near edge (0: the block that holds it, 1, 2, 3 blocks
in), the mean block yaw over SEEDS seafloors and its standard error.

``--self-terms POINTS`` asks whether the edge zone is in each scatterer's own contribution or in
the interference between scatterers (no timing): on the 1x transmitter and the 1x seafloor,
POINTS scatterers (scrambled Sobol points over the seafloor, one a simulation, reflectivity 1,
two pings, the seafloor's recording window) are simulated alone and their couples' correlations
(t-lag 0, the estimator's corrections: the plain slope the estimator's block yaws equal) summed
per range block: the mean over reflectivity draws of a seafloor's correlations, with no
interference. Per block: the yaw of the sum ("pipeline"), of the block's own scatterers alone
("own"), of the diagonal model (exact two-way paths, element patterns, each scatterer in the
block of its range: "model") and the energy share of the other blocks' scatterers (their range
sidelobes). Variants of the processing (SELF_TERM_VARIANTS): as the estimator does it; the
phase-centre correction at each scatterer's own range instead of each sample's ("own-range");
the pulse sampled at 2.5 B instead of 1.25 B (its skirt not folded: "unfolded"); a Hamming range
window ("hamming").

``--ratio SEEDS`` measures the ratio bias of a range block's yaw in the diagonal model (no
simulation; bench/_dpca_ratio.py): per case and seafloor density (1/4, 1 and 4 times
:func:`motionless_scene`'s), the mean over SEEDS seafloors of the blocks' unweighted mean yaw, of
their pooled (power-weighted) mean, and the first-order bias of one block.

``--pooling SEEDS`` compares rules for pooling a pair's blocks into its yaw (no timing;
bench/_dpca_pooling.py): on the Heremans 2009 scene over SEEDS seafloors, the DPCA track's heading
and cross-track errors per rule, all from the same blocks.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np
from _harness import arguments, measure, report

from clsas import EchoData, Image, Medium, Waveform
from clsas.estimate import autofocus, dpca
from clsas.scene import presets


def dpca_track(n_pings: int, n_samples: int, rng) -> tuple[EchoData, object, float]:
    scene = presets.heremans2009(n_pulses=n_pings)
    shift, _ = dpca.nominal_shift(scene.array, scene.platform.speed, scene.schedule.prf)
    h = scene.array.n_receivers
    centres = (rng.standard_normal((shift * n_pings + h, n_samples))
               + 1j * rng.standard_normal((shift * n_pings + h, n_samples))).astype(np.complex64)
    index = shift * np.arange(n_pings)[None, :] + np.arange(h)[:, None]      # phase centre of (h, p)
    data = centres[index] + 0.1 * (rng.standard_normal((h, n_pings, n_samples))).astype(np.complex64)
    wf: Waveform = scene.waveform
    echo = EchoData(data=data, eta=scene.eta, t0=np.full(h, 0.12), fs=wf.fs, tx_pos=np.zeros((n_pings, 3)),
                    rx_pos=np.zeros((h, n_pings, 1, 3)), rx_tau=np.zeros((h, 1)), waveform=wf, medium=Medium(),
                    receivers=scene.receiver_names, compressed=True)
    return echo, scene.array, scene.platform.speed


def interleaved(runs: dict, repeats: int) -> dict:
    """{name: (min, median) seconds}, the runs called in turn A B A B after one warm-up each."""
    times = {name: [] for name in runs}
    for run in runs.values():
        run()
    for _ in range(repeats):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - start)
    return {name: (min(t), statistics.median(t)) for name, t in times.items()}


def blurred_image(n: int, rng) -> Image:
    img = 0.05 * (rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n)))
    rows, cols = rng.integers(0, n, 32), rng.integers(0, n, 32)
    img[rows, cols] += 30.0
    k = np.linspace(-1, 1, n)
    blurred = autofocus.apply_phase_correction(img.astype(np.complex64), -8 * k**2, 0)
    return Image(blurred, ("y", "x"), {"y": np.arange(n) * 0.01, "x": np.arange(n) * 0.01})


def main() -> None:
    extra = argparse.ArgumentParser(add_help=False)
    extra.add_argument("--bias", type=int, default=0, metavar="SEEDS")
    extra.add_argument("--edges", type=int, default=0, metavar="SEEDS")
    extra.add_argument("--edge-cut", type=int, default=0, metavar="SEEDS")
    extra.add_argument("--self-terms", type=int, default=0, metavar="POINTS")
    extra.add_argument("--ratio", type=int, default=0, metavar="SEEDS")
    extra.add_argument("--pooling", type=int, default=0, metavar="SEEDS")
    extra.add_argument("--pings", type=int, default=30)
    own, sys.argv[1:] = extra.parse_known_args()
    args = arguments(__doc__.splitlines()[0])
    if own.bias or own.edges or own.edge_cut:
        from _dpca_bias import edge_cut, edge_profile, yaw_bias
        for seeds, run in ((own.bias, yaw_bias), (own.edges, edge_profile), (own.edge_cut, edge_cut)):
            if seeds:
                run(args, seeds, own.pings)
                return
    if own.ratio:
        from _dpca_ratio import ratio_bias
        ratio_bias(args, own.ratio)
        return
    if own.pooling:
        from _dpca_pooling import pooling
        pooling(args, own.pooling)
        return
    if own.self_terms:
        from _dpca_self_terms import self_terms
        self_terms(args, own.self_terms)
        return
    rng = np.random.default_rng(0)
    repeats = args.repeats or 3
    n_pings, n_samples = (100, 2048) if args.quick else (1000, 2048)
    echo, array, speed = dpca_track(n_pings, n_samples, rng)
    seconds = measure(lambda: dpca.estimate(echo, array, speed), repeats=repeats)
    report(args, "dpca", "numpy", {"pings": n_pings, "hydrophones": echo.n_rx, "samples": n_samples},
           (n_pings - 1) / seconds, "ping pairs/s", seconds, per_pair_ms=1e3 * seconds / (n_pings - 1))

    shape = (6, 50 if args.quick else 200, 16, 128)
    f = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)).astype(np.complex64)
    g = (0.9 * f + 0.1 * rng.standard_normal(shape)).astype(np.complex64)
    blocks = int(np.prod(shape[:3]))
    delay = rng.uniform(-0.5, 0.5, shape[:3])          # samples (fs = 1)
    for t_lags in (8, dpca.pairs.FINE_T_LAGS):
        runs = {method: (lambda method=method: dpca.correlations(f, g, t_lags, method)) for method in ("direct", "fft")}
        runs["fft-delay"] = lambda: dpca.correlations(f, g, t_lags, delay=delay, fs=1.0)
        timed = interleaved(runs, repeats=max(repeats, 5))
        for name, (fastest, median) in timed.items():
            report(args, f"dpca-correlations-{name}", "numpy",
                   {"couples": shape[0], "pairs": shape[1], "blocks": shape[2], "block": shape[3], "t_lags": t_lags},
                   blocks / median, "block correlations/s", median, min_ms=1e3 * fastest,
                   direct_over_fft=timed["direct"][1] / timed["fft"][1],
                   delay_over_fft=timed["fft-delay"][1] / timed["fft"][1])

    n = 1024 if args.quick else 2048
    image = blurred_image(n, rng)
    result = autofocus.pga(image, max_iterations=5, tolerance=1e-9)
    seconds = measure(lambda: autofocus.pga(image, max_iterations=5, tolerance=1e-9), repeats=repeats)
    report(args, "pga", "numpy", {"pixels": [n, n]}, result.iterations / seconds, "iterations/s", seconds,
           per_iteration_ms=1e3 * seconds / result.iterations, iterations=result.iterations)


if __name__ == "__main__":
    main()
