"""bench_dpca.py --bias, --edges and --edge-cut: the motionless yaw of issue #30 over seafloors
(the scenes: bench/_dpca_scenes.py; what each option measures: bench_dpca.py's docstring)."""

from __future__ import annotations

import os
import time

import numpy as np
from _dpca_scenes import ACROSS, NEARER, annulus_scene, controlled_mean, motionless_scene, seafloor_control
from _harness import report

from clsas.estimate import dpca

# the --edges cases: (transmitter factor, seafloor extent, block length in samples); --quick: the first
EDGE_CASES = ((1.0, 1.0, 128), (1.0, 1.0, 64), (2.0, 1.0, 128), (1.0, 4.0, 128))


def yaw_bias(args, seeds: int, pings: int) -> None:
    """The --bias rows (see bench_dpca.py's docstring): seeds 1000 .. 1000 + seeds - 1."""
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
    """The --edges rows (see bench_dpca.py's docstring): seeds 1000 .. 1000 + seeds - 1."""
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



def edge_cut(args, seeds: int, pings: int) -> None:
    """The --edge-cut rows (see bench_dpca.py's docstring): seeds 1000 .. 1000 + seeds - 1."""
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
