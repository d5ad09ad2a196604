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
"""

from __future__ import annotations

import statistics
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
    args = arguments(__doc__.splitlines()[0])
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
