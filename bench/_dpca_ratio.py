"""bench_dpca.py --ratio: the ratio bias of a range block's DPCA yaw (issue #30), in the diagonal
model (no simulation, no interference between scatterers).

A block's yaw is, to first order, the power-weighted mean of its scatterers' phase-centre
residuals, xi_b = N_b / W_b with N_b = sum_k w_k e_k, W_b = sum_k w_k, w_k = |a_k|^2 P(s_k) and
e_k = -D (s_k^2 - m_b) / r_b (the package docstring of clsas.estimate.dpca, "Pooling the blocks'
yaws"). Here the seafloors of bench_dpca.motionless_scene are drawn (their random points and
reflectivities, ``density`` times as many) and each ping pair's blocks (the estimator's blocks
clear of the range edges that hold their seafloor in the main lobe, m_b from
dpca.look_moments) are read in this model: the mean over the pairs and seafloors of the
blocks' unweighted mean ("unweighted", what a plain mean of the blocks reads) and of their
W-weighted mean ("pooled", sum N / sum W), against the first-order bias of one block,
(D / r) E|a|^4 / E|a|^2^2 E[P^2 (s^2 - m)] / (n_b E[P]^2) averaged over the same blocks
("first_order"). Every figure is the bias of the model itself: E[e] = 0 by construction.
"""

from __future__ import annotations

import os
import time

import numpy as np
from _dpca_scenes import ACROSS, bias_sonar, footprint, seafloor_points
from _harness import report

from clsas.estimate import dpca
from clsas.estimate.dpca.geometry import _pattern, inside_swath, look_moments, pairing
from clsas.estimate.dpca.pairs import MAIN_LOBE

BLOCK = 128             # samples, the estimator's default block
FS = 50e3               # Hz, the bias scenes' sampling rate after range_compress(upsample=2)
START = 26.07           # m, the first block's centre range on the bias scenes' records
N_BLOCKS = 23


class DiagonalBlocks:
    """The blocks of one bias case (transmitter factor, extent) in the diagonal model."""

    def __init__(self, scene, half: float, across: tuple, density: float):
        array, c, f0 = scene.array, scene.medium.sound_speed, scene.waveform.f0
        s, pc, n_couples = pairing(array, scene.platform.speed, scene.schedule.prf, 2)
        self.D = s * (pc[1] - pc[0])
        self.span = c / 2 * BLOCK / FS
        self.r = START + self.span * np.arange(N_BLOCKS)
        ahead = pc[:n_couples].mean() - array.tx_offset[1] + scene.platform.speed * float(np.median(self.r)) / c
        self.yc = scene.platform.speed * scene.eta[1:] + np.asarray(scene.platform.start)[1] + ahead
        centre = np.zeros((self.yc.size, 3))
        centre[:, 1] = self.yc
        self.floor = dpca.SeafloorExtent(x=across, y=(-half, half))
        self.m, fraction, content = look_moments(array, f0, c, self.r, centre, self.floor, self.span, ahead)
        whole = inside_swath(array, f0, c, self.r, centre, self.floor, self.span, ahead, content, guard=self.span)
        self.inside = whole & (fraction >= MAIN_LOBE) & (content > 0)
        self.pattern = lambda sin_t: _pattern(array, f0, c, sin_t)
        self.density = density
        self.half, self.across = half, across

    def sums(self, positions: np.ndarray, power: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(W, S) (pair, block): sum w and sum w s^2 of each block's scatterers."""
        rng = np.hypot(positions[:, 0][None], positions[:, 1][None] - self.yc[:, None])
        sin_t = (positions[:, 1][None] - self.yc[:, None]) / rng
        w = power[None] * self.pattern(sin_t)
        b = np.floor((rng - (self.r[0] - self.span / 2)) / self.span).astype(int)
        k = (b >= 0) & (b < self.r.size)
        cell = (np.arange(self.yc.size)[:, None] * self.r.size + b)[k]       # (pair, block) flattened
        size, shape = self.yc.size * self.r.size, (self.yc.size, self.r.size)
        return (np.bincount(cell, w[k], minlength=size).reshape(shape),
                np.bincount(cell, (w * sin_t**2)[k], minlength=size).reshape(shape))

    def seafloor_yaws(self, seed: int, n: int, across: tuple, half: float) -> tuple[float, float]:
        """(unweighted, pooled) mean yaw (rad) over the pairs of one seafloor of ``n`` random
        scatterers (Rayleigh amplitudes, ``across`` (m) by +-``half`` (m) along track, rng
        ``seed``): the blocks' yaws -D / r (S / W - m) averaged alike, and pooled by their power W
        (sum N / sum W) over the blocks inside the swath."""
        rng = np.random.default_rng(seed)
        pos = np.stack([rng.uniform(*across, n), rng.uniform(-half, half, n), np.zeros(n)], -1)
        power = np.abs((rng.normal(size=n) + 1j * rng.normal(size=n)) / np.sqrt(2)) ** 2
        W, S = self.sums(pos, power)
        with np.errstate(invalid="ignore", divide="ignore"):
            yaw = -self.D / self.r[None] * (S / W - self.m)
        W = np.where(self.inside, W, 0.0)
        unweighted = float(np.nanmean(np.where(self.inside, yaw, np.nan)))
        return unweighted, float(np.mean(np.nansum(W * np.nan_to_num(yaw), axis=1) / W.sum(axis=1)))

    def first_order(self, nodes: int = 4001) -> float:
        """The first-order bias of a block, averaged over the middle pair's blocks, rad."""
        p = self.yc.size // 2
        phi = np.linspace(-np.pi / 2, np.pi / 2, nodes)
        values = []
        for b in np.flatnonzero(self.inside[p]):
            rr = self.r[b] + self.span * ((np.arange(8) + 0.5) / 8 - 0.5)
            x, y = rr[:, None] * np.cos(phi), rr[:, None] * np.sin(phi) + self.yc[p]
            on = (x >= self.across[0]) & (x <= self.across[1]) & (np.abs(y) <= self.half)
            area = rr[:, None] * (phi[1] - phi[0]) * self.span / 8 * on
            sin_t = np.broadcast_to(np.sin(phi), area.shape)
            power = self.pattern(sin_t)
            m = np.sum(power * sin_t**2 * area) / np.sum(power * area)
            n = self.density * np.sum(area)
            mean_p = np.sum(power * area) / np.sum(area)
            mean_p2 = np.sum(power**2 * (sin_t**2 - m) * area) / np.sum(area)
            values.append(self.D / self.r[b] * 2.0 * mean_p2 / (n * mean_p**2))   # E|a|^4 / E|a|^2^2 = 2
        return float(np.mean(values))


def ratio_bias(args, seeds: int) -> None:
    """The --ratio rows: per case and density factor (1/4, 1, 4 times the bias scenes'), over
    ``seeds`` seafloors (seeds 1000..)."""
    for tx_factor in (1.0, 2.0):
        for extent in (0.5, 1.0, 4.0):
            for factor in ((1.0,) if args.quick else (0.25, 1.0, 4.0)):
                scene = bias_sonar(tx_factor, 30)
                half = extent * footprint(scene) / 2
                n = int(seafloor_points(extent, half) * factor)
                model = DiagonalBlocks(scene, half, ACROSS, n / ((ACROSS[1] - ACROSS[0]) * 2 * half))
                start = time.perf_counter()
                unweighted, pooled = [], []
                for seed in range(1000, 1000 + seeds):
                    u, p = model.seafloor_yaws(seed, n, ACROSS, half)
                    unweighted.append(u)
                    pooled.append(p)
                seconds = time.perf_counter() - start
                report(args, "dpca-yaw-ratio", "numpy", {"tx_factor": tx_factor, "extent": extent,
                                                         "density_factor": factor, "points": n, "seeds": seeds},
                       seeds / seconds, "seafloors/s (diagonal model)", seconds,
                       unweighted_urad=1e6 * float(np.mean(unweighted)),
                       unweighted_error_urad=1e6 * float(np.std(unweighted) / np.sqrt(seeds)),
                       pooled_urad=1e6 * float(np.mean(pooled)),
                       pooled_error_urad=1e6 * float(np.std(pooled) / np.sqrt(seeds)),
                       first_order_urad=1e6 * model.first_order(), load=[round(x, 2) for x in os.getloadavg()])
