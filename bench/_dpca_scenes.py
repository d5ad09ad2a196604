"""The issue #30 bias scenes of bench_dpca.py (--bias, --edges, --edge-cut, --self-terms, --ratio) and
tests/test_dpca_bias.py: the 24-hydrophone sonar on a motionless platform over speckle seafloors of
random point scatterers (:func:`motionless_scene`, :func:`annulus_scene`), and the control variate
that takes the seafloors' own phase-centre speckle out of their mean yaw
(:class:`PhaseCentreControl`, :func:`controlled_mean`)."""

from __future__ import annotations

import functools

import numpy as np

import clsas
from clsas import Medium, Waveform
from clsas.estimate import dpca
from clsas.scene.scenario import Array, Platform, PulseSchedule, Scenario
from clsas.scene.targets import PointTargets

ACROSS = (27.0, 47.0)      # m, the bias scenes' seafloor across track
R0 = 37.0                  # m, the range at which their footprint is measured
# scatterers a square metre of the bias scenes' seafloor up to one footprint long; a longer one
# holds as many a range cell (3.75 cm x its length) as one footprint long at this density, i.e.
# the speckle of the 0.5x case doubled, for a quarter of the simulation at 4x
DENSITY = 20.0
# the --edges cases: (transmitter factor, seafloor extent, block length in samples); --quick: the first
# --edge-cut: the 4x seafloor drawn again reaching this much nearer the track, m (three 128-sample
# blocks: its blocks stay on the same ranges)
NEARER = 5.76


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
