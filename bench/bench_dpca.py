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
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import os
import statistics
import sys
import time

import numpy as np
from _harness import arguments, measure, report

import clsas
from clsas import EchoData, Image, Medium, Waveform
from clsas.estimate import autofocus, dpca
from clsas.scene import presets
from clsas.scene.scenario import Array, Platform, PulseSchedule, Scenario
from clsas.scene.targets import PointTargets

ACROSS = (27.0, 47.0)      # m, the bias scenes' seafloor across track
R0 = 37.0                  # m, the range at which their footprint is measured
# scatterers a square metre of the bias scenes' seafloor up to one footprint long; a longer one
# holds as many a range cell (3.75 cm x its length) as one footprint long at this density, i.e.
# the speckle of the 0.5x case doubled, for a quarter of the simulation at 4x
DENSITY = 20.0
# the --edges cases: (transmitter factor, seafloor extent, block length in samples); --quick: the first
EDGE_CASES = ((1.0, 1.0, 128), (1.0, 1.0, 64), (2.0, 1.0, 128), (1.0, 4.0, 128))
# --edge-cut: the 4x seafloor drawn again reaching this much nearer the track, m (three 128-sample
# blocks: its blocks stay on the same ranges)
NEARER = 5.76
# --self-terms: the processings the one-scatterer sums go through (module docstring)
SELF_TERM_VARIANTS = ("as-is", "own-range", "unfolded", "hamming")


def bias_sonar(tx_factor: float, pings: int) -> Scenario:
    """The issue #30 sonar: 24 hydrophones 5 cm long and 5 cm apart (contiguous), a transmitter
    ``tx_factor`` x 5 cm long in the middle, 100 kHz, 20 kHz bandwidth, 5 ms chirp, 1 m/s, 12
    phase-centre spacings a ping (D = 0.3 m); no targets."""
    d = 0.05
    array = Array.uniform_line(24, d, first=-12 * d, tx_length=tx_factor * d, rx_length=d)
    return Scenario(medium=Medium(1500.0), waveform=Waveform(f0=100e3, bandwidth=20e3, duration=5e-3, fs=25e3),
                    platform=Platform(speed=1.0), array=array, schedule=PulseSchedule(prf=1 / 0.3, n_pulses=pings))


def footprint(scene: Scenario) -> float:
    """The two-way main lobe's along-track width at R0, m (between the first nulls)."""
    return 2 * R0 * scene.waveform.wavelength(scene.medium) / max(scene.array.tx_length, scene.array.rx_length[0])


def motionless_scene(tx_factor: float, extent: float, pings: int = 30, seed: int = 3, nearer: float = 0.0):
    """(scene, the seafloor's dpca.SeafloorExtent, range-compressed echo): :func:`bias_sonar`
    over a speckle seafloor of random point scatterers (DENSITY / max(1, extent) a square metre,
    complex Gaussian reflectivities) ACROSS m across track and ``extent`` x the footprint long,
    centred on the track, on a motionless platform (every pair's true yaw is 0). ``nearer`` m:
    the seafloor reaches that much nearer the track, the same scatterers in ACROSS (drawn first,
    as without it) and as dense a draw in front of them (for --edge-cut)."""
    scene = bias_sonar(tx_factor, pings)
    half = extent * footprint(scene) / 2
    rng = np.random.default_rng(seed)
    n = seafloor_points(extent, half)
    pos = np.stack([rng.uniform(*ACROSS, n), rng.uniform(-half, half, n), np.zeros(n)], -1)
    reflectivity = (rng.normal(size=n) + 1j * rng.normal(size=n)) / np.sqrt(2)
    if nearer > 0:
        m = int(round(n * nearer / (ACROSS[1] - ACROSS[0])))
        front = np.stack([rng.uniform(ACROSS[0] - nearer, ACROSS[0], m), rng.uniform(-half, half, m), np.zeros(m)], -1)
        pos = np.concatenate([pos, front])
        reflectivity = np.concatenate([reflectivity, (rng.normal(size=m) + 1j * rng.normal(size=m)) / np.sqrt(2)])
    scene = scene.replace(targets=(PointTargets(pos, reflectivity=reflectivity),))
    echo = clsas.range_compress(clsas.simulate(scene, progress=False), upsample=2)
    return scene, dpca.SeafloorExtent(x=(ACROSS[0] - nearer, ACROSS[1]), y=(-half, half)), echo


class PhaseCentreControl:
    """A control variate for the motionless yaw of :func:`motionless_scene` (issue #30): what the
    seafloor's own scatterers make each ping pair read through the phase-centre approximation's
    residual, computed from the scatterers the simulation placed, and zero in expectation by
    construction, so that subtracting it (scaled) from the estimator's mean yaw removes speckle
    without touching the bias.

    The phase-centre correction takes out D cos^2(theta) / (4 r)-type delays with the mean
    <sin^2 theta> of each range block (dpca.geometry.pca_delay, look_moments): a scatterer at
    along-track direction cosine s reads -D (s^2 - m) / r of yaw, m the block's mean. A block's
    finite set of scatterers, each weighted by its reflectivity's power |a|^2 and the two-way
    pattern P(s), does not average that to zero: the speckle of the yaw that is shared by a
    seafloor's pairs (they see the same scatterers a few degrees apart). Per ping pair p and
    range ring b (fixed rings BLOCK m long inside the swath, a ring's length from its edges; the
    same for every seafloor)

        C_pb = -(D / r_b) sum_{k in b} |a_k|^2 P(s_kp) (s_kp^2 - m_pb) / W_pb,

    s_kp seen from the couples' phase centre, m_pb = int P s^2 dA / int P dA over the part of
    the rectangle ring b holds and W_pb = (n / A) int P dA: both integrals by Gauss-Legendre
    quadrature (the seafloor's rectangle of area A holds n points drawn uniformly, E|a|^2 = 1),
    so E[sum |a|^2 P (s^2 - m)] = (n / A) (int P s^2 - m int P) = 0: E[C_pb] = 0 for every
    pair and ring, whatever the estimator does. C_p is the mean over the rings. The
    estimator's mean corrected by it, mean(Y) - beta (mean(C) - 0), has the estimator's own
    expectation for any beta (beta fitted across seafloors: the usual O(1 / seafloors) term
    of an estimated coefficient, far below the standard error at the test's counts); a
    bias of the estimator (the correction's m, the edge blocks, the weighting) is not in C and
    cannot be taken out by it. Only its variance changes: by 1 - corr(Y, C)^2."""

    BLOCK = 1.92    # m, the rings' length (the estimator's 128-sample blocks at 50 kHz)
    NODES = (8, 512)  # Gauss-Legendre nodes in range and in azimuth per ring

    def __init__(self, scene: Scenario, half: float, n_points: int):
        array, c, f0 = scene.array, scene.medium.sound_speed, scene.waveform.f0
        prf = scene.schedule.prf
        s, pc, n_couples = dpca.geometry.pairing(array, scene.platform.speed, prf, 2)
        self.D = s * (pc[1] - pc[0])
        edges = np.arange(ACROSS[0] + self.BLOCK, ACROSS[1] - self.BLOCK + 1e-9, self.BLOCK)
        self.lo, self.r = edges[:-1], edges[:-1] + self.BLOCK / 2
        ahead = pc[:n_couples].mean() - array.tx_offset[1] + scene.platform.speed * 2 * R0 / c
        self.y = scene.platform.speed * scene.eta[1:] + ahead        # couples' centre, pair p (x = z = 0)
        self.pattern = lambda sin_t: dpca.geometry._pattern(array, f0, c, sin_t)
        self.half = half
        xr, wr = np.polynomial.legendre.leggauss(self.NODES[0])
        xp, wp = np.polynomial.legendre.leggauss(self.NODES[1])
        density = n_points / ((ACROSS[1] - ACROSS[0]) * 2 * half)
        weight, second = np.zeros((self.y.size, self.r.size)), np.zeros((self.y.size, self.r.size))
        for b, lo in enumerate(self.lo):
            rho = lo + self.BLOCK * (xr + 1) / 2                   # (node,)
            for p, yc in enumerate(self.y):
                bound = np.arccos(ACROSS[0] / rho)                 # x = rho cos(phi) >= ACROSS[0]
                a0 = np.maximum(-bound, np.arcsin(np.clip((-half - yc) / rho, -1, 1)))
                a1 = np.minimum(bound, np.arcsin(np.clip((half - yc) / rho, -1, 1)))
                a1 = np.maximum(a1, a0)
                phi = a0[:, None] + (a1 - a0)[:, None] * (xp[None, :] + 1) / 2
                sin_t = np.sin(phi)
                area = (a1 - a0)[:, None] / 2 * wp[None, :] * (self.BLOCK / 2 * wr * rho)[:, None]
                pw = self.pattern(sin_t) * area
                weight[p, b], second[p, b] = pw.sum(), (pw * sin_t**2).sum()
        self.m = second / weight
        self.W = density * weight

    def __call__(self, positions: np.ndarray, reflectivity: np.ndarray) -> np.ndarray:
        """C_p (pair,), rad: the control variate of one seafloor (its points' positions (n, 3)
        and reflectivities (n,))."""
        rng = np.hypot(positions[:, 0], positions[:, 1][None, :] - self.y[:, None])   # (pair, n)
        ring = np.floor((rng - self.lo[0]) / self.BLOCK).astype(int)
        inside = (ring >= 0) & (ring < self.r.size)
        sin_t = (positions[:, 1][None, :] - self.y[:, None]) / rng
        power = np.abs(reflectivity) ** 2 * self.pattern(sin_t)
        out = np.zeros((self.y.size, self.r.size))
        for p in range(self.y.size):
            k = inside[p]
            num = np.bincount(ring[p, k], power[p, k] * (sin_t[p, k] ** 2 - self.m[p, ring[p, k]]),
                              minlength=self.r.size)
            out[p] = -self.D / self.r * num / self.W[p]
        return out.mean(axis=1)


@functools.cache
def seafloor_control(tx_factor: float, extent: float, pings: int = 30) -> PhaseCentreControl:
    """The :class:`PhaseCentreControl` of :func:`motionless_scene`'s seafloors (the same for
    every seed: the geometry and the number of points do not depend on it)."""
    scene = bias_sonar(tx_factor, pings)
    half = extent * footprint(scene) / 2
    return PhaseCentreControl(scene, half, seafloor_points(extent, half))


def seafloor_points(extent: float, half: float) -> int:
    """How many random points :func:`motionless_scene` draws for a seafloor ``half`` m either
    side of the track along it."""
    return int(DENSITY / max(1.0, extent) * (ACROSS[1] - ACROSS[0]) * 2 * half)


def controlled_mean(means, controls) -> tuple[float, float, float]:
    """(mean, its standard error, beta): the seafloors' mean yaws ``means`` corrected by their
    control variates ``controls`` (E = 0, :class:`PhaseCentreControl`), beta the least-squares
    coefficient across the seafloors; the standard error from the residuals (n - 2 degrees of
    freedom)."""
    y, x = np.asarray(means, dtype=float), np.asarray(controls, dtype=float)
    beta = float(np.cov(y, x)[0, 1] / np.var(x, ddof=1))
    adjusted = y - beta * x
    return float(np.mean(adjusted)), float(np.sqrt(np.sum((adjusted - adjusted.mean()) ** 2) / (y.size - 2) / y.size)), beta


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


def yaw_bias(args, seeds: int, pings: int) -> None:
    """The --bias rows (see the module docstring): seeds 1000 .. 1000 + seeds - 1."""
    for tx_factor in (1.0, 2.0):
        for extent in (0.5, 1.0, 4.0):
            control = seafloor_control(tx_factor, extent, pings)
            means, controls, rms, start = [], [], [], time.perf_counter()
            for seed in range(1000, 1000 + seeds):
                scene, _, echo = motionless_scene(tx_factor, extent, pings, seed)
                yaw = dpca.estimate(echo, scene.array, scene.platform.speed).yaw
                means.append(float(np.mean(yaw)))
                rms.append(float(np.std(yaw)))
                controls.append(float(np.mean(control(scene.targets[0].positions, scene.targets[0].reflectivity))))
            seconds = time.perf_counter() - start
            error = float(np.std(means, ddof=1) / np.sqrt(seeds)) if seeds > 1 else float("nan")
            controlled, controlled_error, beta = controlled_mean(means, controls) if seeds > 2 else (np.nan,) * 3
            report(args, "dpca-yaw-bias", "numpy", {"tx_factor": tx_factor, "extent": extent, "seeds": seeds,
                                                    "pings": pings}, seeds * (pings - 1) / seconds,
                   "ping pairs/s (with simulation)", seconds, yaw_mean_urad=1e6 * float(np.mean(means)),
                   yaw_error_urad=1e6 * error, controlled_mean_urad=1e6 * controlled,
                   controlled_error_urad=1e6 * controlled_error, control_beta=beta,
                   pair_rms_urad=1e6 * float(np.mean(rms)), load=[round(x, 2) for x in os.getloadavg()])


def edge_profile(args, seeds: int, pings: int) -> None:
    """The --edges rows (see the module docstring): seeds 1000 .. 1000 + seeds - 1."""
    for tx_factor, extent, block in EDGE_CASES[:1] if args.quick else EDGE_CASES:
        yaws, start = {}, time.perf_counter()
        for seed in range(1000, 1000 + seeds):
            scene, floor, echo = motionless_scene(tx_factor, extent, pings, seed)
            pairs = dpca.estimate(echo, scene.array, scene.platform.speed, block=block)
            for r, column, kept in zip(pairs.block_range, pairs.block_yaw.T, pairs.block_inside.T):
                if np.any(np.isfinite(column)):
                    # the depth into the swath of the block's middle from the nearer slant edge
                    edge = "near" if r - floor.x[0] < floor.x[1] - r else "far"
                    depth = round(float(min(r - floor.x[0], floor.x[1] - r)) * 4) / 4
                    yaws.setdefault((edge, depth), []).append((float(np.nanmean(column)), float(np.mean(kept))))
        seconds = time.perf_counter() - start
        for edge, depth in sorted(yaws):
            values = np.array(yaws[edge, depth])
            if values.shape[0] < 2:
                continue
            report(args, "dpca-yaw-edges", "numpy", {"tx_factor": tx_factor, "extent": extent, "block": block,
                                                     "seeds": seeds, "pings": pings, "edge": edge,
                                                     "depth_m": depth},
                   values.shape[0] / seconds, "block means/s (with simulation)", seconds,
                   yaw_mean_urad=1e6 * float(np.mean(values[:, 0])),
                   yaw_error_urad=1e6 * float(np.std(values[:, 0], ddof=1) / np.sqrt(values.shape[0])),
                   kept=float(np.mean(values[:, 1])), load=[round(x, 2) for x in os.getloadavg()])


def annulus_scene(tx_factor: float, pings: int, seed: int):
    """(scene, range-compressed echo): :func:`bias_sonar` over a speckle seafloor that fills the
    half annulus ACROSS[0] < |S - (0, y_m)| < ACROSS[1] around the track's middle y_m, out to
    +-4 footprints along the track (DENSITY / 4 a square metre): its edges are range edges only,
    its rings whole at every look angle (for --edge-cut; estimate it with extent=None)."""
    scene = bias_sonar(tx_factor, pings)
    middle = scene.platform.speed * float(np.mean(scene.eta))
    half = 4 * footprint(scene) / 2
    rng = np.random.default_rng(seed)
    n = int(DENSITY / 4 * ACROSS[1] * 2 * half)
    x, y = rng.uniform(0, ACROSS[1], n), rng.uniform(-half, half, n)
    keep = (np.hypot(x, y) > ACROSS[0]) & (np.hypot(x, y) < ACROSS[1])
    m = int(keep.sum())
    pos = np.stack([x[keep], y[keep] + middle, np.zeros(m)], -1)
    reflectivity = (rng.normal(size=m) + 1j * rng.normal(size=m)) / np.sqrt(2)
    scene = scene.replace(targets=(PointTargets(pos, reflectivity=reflectivity),))
    return scene, clsas.range_compress(clsas.simulate(scene, progress=False), upsample=2)


def edge_cut(args, seeds: int, pings: int) -> None:
    """The --edge-cut rows (see the module docstring): seeds 1000 .. 1000 + seeds - 1."""
    variants = ("rectangle", "nearer", "annulus")
    yaws, start = {}, time.perf_counter()
    for seed in range(1000, 1000 + seeds):
        for variant in variants:
            if variant == "annulus":
                scene, echo = annulus_scene(1.0, pings, seed)
                pairs, near = dpca.estimate(echo, scene.array, scene.platform.speed, extent=None), ACROSS[0]
            else:
                scene, floor, echo = motionless_scene(1.0, 4.0, pings, seed, NEARER if variant == "nearer" else 0.0)
                pairs, near = dpca.estimate(echo, scene.array, scene.platform.speed), floor.x[0]
            span = np.diff(pairs.block_range)[0]
            for r, column in zip(pairs.block_range, pairs.block_yaw.T):
                # the depth of the block's middle inside the near edge, in block lengths
                depth = int(np.floor((r - near) / span))
                if np.any(np.isfinite(column)) and 0 <= depth <= 3:
                    yaws.setdefault((variant, depth), []).append(float(np.nanmean(column)))
    seconds = time.perf_counter() - start
    for (variant, depth), values in sorted(yaws.items()):
        if len(values) > 1:
            report(args, "dpca-yaw-edge-cut", "numpy", {"tx_factor": 1.0, "seafloor": variant, "seeds": seeds,
                                                        "pings": pings, "depth_blocks": depth},
                   len(values) / seconds, "block means/s (with simulation)", seconds,
                   yaw_mean_urad=1e6 * float(np.mean(values)),
                   yaw_error_urad=1e6 * float(np.std(values, ddof=1) / np.sqrt(len(values))),
                   load=[round(x, 2) for x in os.getloadavg()])


def _couples_setup(echo, scene, extent, block: int = 128) -> dict:
    """What the estimator's plain slope needs on ``echo``'s grid (dpca.estimate's own steps)."""
    from clsas.estimate.dpca.correlate import aligned
    from clsas.estimate.dpca.geometry import look_moments, pairing, pca_delay
    array, speed, c, f0 = scene.array, scene.platform.speed, echo.medium.sound_speed, echo.waveform.f0
    s, pc, n_couples = pairing(array, speed, 1 / np.diff(echo.eta)[0], 2)
    _, start = aligned(echo, array.n_receivers)
    nb = echo.n_samples // block
    r_blocks = c / 2 * (start + (np.arange(nb) + 0.5) * block / echo.fs)
    r_samples = (c / 2 * (start + np.arange(nb * block) / echo.fs)).reshape(nb, block)
    ahead = pc[:n_couples].mean() - array.tx_offset[1] + speed * float(np.median(r_blocks)) / c
    centre = echo.tx_pos[1:].copy()
    centre[:, 1] += ahead
    cos2 = 1 - np.nan_to_num(look_moments(array, f0, c, r_blocks, centre, extent, c / 2 * block / echo.fs, ahead)[0])
    i = np.arange(pc.size - s)
    return dict(i=i, j=i + s, u=pc[i] - pc[i].mean(), nb=nb, block=block, r_blocks=r_blocks, cos2=cos2[0],
                r_samples=r_samples, env=pca_delay(array, i, i + s, r_blocks, speed, c, 0.0) * cos2[0],
                delay=lambda r: pca_delay(array, i, i + s, r, speed, c, 0.0))


def _slope_yaw(z: np.ndarray, u: np.ndarray, c: float, f0: float) -> np.ndarray:
    """The least-squares yaw of couples' correlations z (couple, ...) along their positions u."""
    phase = np.angle(z * np.conj(z.sum(axis=0))[None])
    return -np.tensordot(u, phase, axes=(0, 0)) / np.sum(u**2) * c / (4 * np.pi * f0)


def self_terms(args, points: int) -> None:
    """The --self-terms rows (see the module docstring)."""
    from scipy.stats import qmc
    from clsas.estimate.dpca.correlate import aligned
    from clsas.kernelmath import unit_phasor
    for variant in SELF_TERM_VARIANTS:
        start_time = time.perf_counter()
        scene, extent, _ = motionless_scene(1.0, 1.0, 2, 1)
        raw = clsas.simulate(scene, progress=False)
        upsample = 2
        if variant == "unfolded":
            scene = scene.replace(waveform=dataclasses.replace(scene.waveform, fs=2 * scene.waveform.fs))
            upsample = 1
        window = clsas.Recording(t0=np.asarray(raw.t0), n_samples=np.asarray(raw.provenance["n_valid"]) * (2 // upsample))
        array, c, f0 = scene.array, scene.medium.sound_speed, scene.waveform.f0
        o, v = array.rx_offsets[:, 1], scene.platform.speed
        q = qmc.Sobol(2, scramble=True, seed=1).random(points)
        xy = np.stack([extent.x[0] + np.diff(extent.x)[0] * q[:, 0], extent.y[0] + np.diff(extent.y)[0] * q[:, 1]], -1)
        setup = None
        for x, y in xy:
            one = scene.replace(targets=(PointTargets(np.array([[x, y, 0.0]]), reflectivity=1.0),), recording=window)
            echo = clsas.range_compress(clsas.simulate(one, progress=False), upsample=upsample,
                                        window="hamming" if variant == "hamming" else "none")
            if setup is None:
                setup = _couples_setup(echo, one, extent)
                i, j, nb, block = setup["i"], setup["j"], setup["nb"], setup["block"]
                total, own, model = (np.zeros((i.size, nb), complex) for _ in range(3))
            # the diagonal model: exact two-way paths (the receiver moving on while the echo
            # travels) and element patterns, the estimator's correction at the scatterer's range
            legs, weights = [], []
            for ping, hydrophones in ((0, j), (1, i)):
                y_tx = echo.tx_pos[ping, 1]
                out = np.hypot(x, y - y_tx) / c
                back = np.full(hydrophones.size, out)
                for _ in range(4):
                    y_rx = y_tx + o[hydrophones] + v * (out + back)
                    back = np.hypot(x, y - y_rx) / c
                legs.append(out + back)
                weights.append(np.sinc(array.tx_length * (y - y_tx) / (c * out) * f0 / c)
                               * np.sinc(array.rx_length[hydrophones] * (y - y_rx) / (c * back) * f0 / c))
            r_k = c / 2 * float(np.mean(legs[0]))
            b = int(np.floor((r_k - setup["r_blocks"][0]) / np.diff(setup["r_blocks"][:2])[0] + 0.5))
            records = aligned(echo, array.n_receivers)[0][..., :nb * block].reshape(array.n_receivers, 2, nb, block)
            r = np.full(setup["r_samples"].shape, r_k) if variant == "own-range" else setup["r_samples"]
            g = records[i, 1] * unit_phasor(2 * np.pi * f0 * setup["delay"](r) * setup["cos2"][:, None])
            f = records[j, 0]
            norm = np.sqrt(np.sum(np.abs(f) ** 2, -1) * np.sum(np.abs(g) ** 2, -1))
            corr = dpca.correlations(f, g, 2, delay=setup["env"], fs=echo.fs)[..., 2] * norm
            total += corr
            if 0 <= b < nb:
                own[:, b] += corr[:, b]
                residual = legs[1] - legs[0] - setup["delay"](np.array(r_k)).ravel() * setup["cos2"][b]
                model[:, b] += weights[0] * weights[1] * unit_phasor(2 * np.pi * f0 * residual)
        seconds = time.perf_counter() - start_time
        yaws = [_slope_yaw(z, setup["u"], c, f0) for z in (total, own, model)]
        energy = np.abs(total).sum(axis=0)
        for b in np.flatnonzero(energy > 0.02 * energy.max()):
            report(args, "dpca-yaw-self-terms", "numpy", {"variant": variant, "points": points,
                                                          "range_m": round(float(setup["r_blocks"][b]), 2)},
                   points / seconds, "scatterers/s (with simulation)", seconds,
                   pipeline_urad=1e6 * float(yaws[0][b]), own_urad=1e6 * float(yaws[1][b]),
                   model_urad=1e6 * float(yaws[2][b]),
                   others_energy=float(1 - np.abs(own[:, b]).sum() / energy[b]),
                   load=[round(x, 2) for x in os.getloadavg()])


def main() -> None:
    extra = argparse.ArgumentParser(add_help=False)
    extra.add_argument("--bias", type=int, default=0, metavar="SEEDS")
    extra.add_argument("--edges", type=int, default=0, metavar="SEEDS")
    extra.add_argument("--edge-cut", type=int, default=0, metavar="SEEDS")
    extra.add_argument("--self-terms", type=int, default=0, metavar="POINTS")
    extra.add_argument("--ratio", type=int, default=0, metavar="SEEDS")
    extra.add_argument("--pings", type=int, default=30)
    own, sys.argv[1:] = extra.parse_known_args()
    args = arguments(__doc__.splitlines()[0])
    if own.bias:
        yaw_bias(args, own.bias, own.pings)
        return
    if own.edges:
        edge_profile(args, own.edges, own.pings)
        return
    if own.edge_cut:
        edge_cut(args, own.edge_cut, own.pings)
        return
    if own.ratio:
        from _dpca_ratio import ratio_bias
        ratio_bias(args, report, bias_sonar, footprint, seafloor_points, ACROSS, own.ratio)
        return
    if own.self_terms:
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
