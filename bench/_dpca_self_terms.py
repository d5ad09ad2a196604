"""bench_dpca.py --self-terms: is the near-edge zone of issue #30 in each scatterer's own
contribution or in the interference between scatterers? (what it measures: bench_dpca.py's
docstring; the scenes: bench/_dpca_scenes.py)."""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np
from _dpca_scenes import motionless_scene
from _harness import report

import clsas
from clsas.estimate import dpca
from clsas.scene.targets import PointTargets

# --self-terms: the processings the one-scatterer sums go through (module docstring)
SELF_TERM_VARIANTS = ("as-is", "own-range", "unfolded", "hamming")


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
    """The --self-terms rows (see bench_dpca.py's docstring)."""
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
