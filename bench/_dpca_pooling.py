"""bench_dpca.py --pooling SEEDS: how a ping pair's yaw is pooled from its range blocks, on the
Heremans 2009 scene (clsas.reproduce.heremans2009: 32 pings, its sway and yaw, the nine points on
a sand seafloor; seeds 5 .. 5 + SEEDS - 1 of the seafloor's speckle), the DPCA track's errors
against the truth per rule, the rules all applied to the same blocks of the same estimate
(pairs.pooled_mean's arguments, recorded as the estimator calls it):

- "pooled": the estimator's rule (weights rho x energy, bright blocks as one typical, the cut at
  pairs.YAW_OUTLIER scaled MADs, pairs.OUTLIER within pairs.SIDELOBE_BLOCKS of a bright block);
- "pooled-cut-3": the cut at pairs.OUTLIER (3) scaled MADs everywhere (the rule of dpca 9a129be);
- "pooled-cut-5": the cut at pairs.YAW_OUTLIER everywhere;
- "trimmed": the unweighted mean of the blocks within pairs.OUTLIER MADs of their median, median
  and MAD weighted by min(weight, the pair's median weight) (close to the rule before pooling,
  which weighted them by min(energy, median energy)).

Per seed and rule: the heading's RMS and largest error (mrad) and the cross track's (mm) along the
track (dpca.integrate, heading0 from the truth as in the reproduction), the per-pair yaw RMS
error (urad); then per rule the mean over the seeds and the mean difference from "pooled" with
its standard error (paired: the same blocks).
"""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np
from _harness import report

from clsas.estimate import dpca
from clsas.estimate.dpca import pairs as dpca_pairs
from clsas.image import range_compress
from clsas.reproduce import heremans2009
from clsas.scene.scenario import Platform
from clsas.synthesis import simulate


def _trimmed(x: np.ndarray, use: np.ndarray, weight: np.ndarray) -> np.ndarray:
    votes = np.where(use, np.minimum(weight, np.nanmedian(np.where(use, weight, np.nan), axis=1, keepdims=True)), 0.0)
    x = np.where(use, x, 0.0)
    med = dpca_pairs._weighted_median(x, votes)[:, None]
    mad = 1.4826 * dpca_pairs._weighted_median(np.abs(x - med), votes)[:, None]
    kept = use & (np.abs(x - med) <= dpca_pairs.OUTLIER * mad)
    return np.sum(np.where(kept, x, 0.0), axis=1) / np.sum(kept, axis=1)


RULES = {"pooled": lambda x, use, w, cut: dpca_pairs.pooled_mean(x, use, w, cut)[0],
         "pooled-cut-3": lambda x, use, w, cut: dpca_pairs.pooled_mean(x, use, w, dpca_pairs.OUTLIER)[0],
         "pooled-cut-5": lambda x, use, w, cut: dpca_pairs.pooled_mean(x, use, w, dpca_pairs.YAW_OUTLIER)[0],
         "trimmed": lambda x, use, w, cut: _trimmed(x, use, w)}


def _errors(pairs, echo, scene, sway, yaw) -> dict:
    track = dpca.integrate(pairs, echo.eta, scene.platform.speed, scene.array,
                           heading0=float(yaw(echo.eta[0] + pairs.two_way)))
    heading = track.heading - yaw(track.heading_times)
    cross = track.cross - (sway(track.times) - sway(track.times[0]))
    return {"heading_rms_mrad": 1e3 * float(np.sqrt(np.mean(heading**2))),
            "heading_max_mrad": 1e3 * float(np.abs(heading).max()),
            "cross_rms_mm": 1e3 * float(np.sqrt(np.mean(cross**2))), "cross_max_mm": 1e3 * float(np.abs(cross).max()),
            "pair_yaw_rms_urad": 1e6 * float(np.sqrt(np.mean((np.diff(heading)) ** 2)))}


def pooling(args, seeds: int, pings: int = 32) -> None:
    """The --pooling rows (module docstring)."""
    recorded = {}
    original = dpca_pairs.pooled_mean

    def recording(x, use, weight, cut=dpca_pairs.YAW_OUTLIER):
        recorded.update(x=x, use=use, weight=weight, cut=cut)
        return original(x, use, weight, cut)

    rows = {name: [] for name in RULES}
    dpca_pairs.pooled_mean = recording
    try:
        for seed in range(5, 5 + seeds):
            start = time.perf_counter()
            scene, sway, yaw = heremans2009._scene(pings, seed)
            moving = scene.replace(platform=Platform(speed=scene.platform.speed, start=scene.platform.start,
                                                     sway=sway, yaw=yaw))
            echo = range_compress(simulate(moving, progress=False, multipath=0), upsample=4)
            pairs = dpca.estimate(echo, scene.array, scene.platform.speed)
            seconds = time.perf_counter() - start
            for name, rule in RULES.items():
                y = rule(recorded["x"], recorded["use"], recorded["weight"], recorded["cut"])
                rows[name].append(_errors(dataclasses.replace(pairs, yaw=y), echo, scene, sway, yaw))
                report(args, "dpca-yaw-pooling", "numpy", {"seed": seed, "pings": pings, "rule": name}, 1 / seconds,
                       "seeds/s (with simulation)", seconds, **rows[name][-1],
                       load=[round(x, 2) for x in os.getloadavg()])
    finally:
        dpca_pairs.pooled_mean = original
    base = rows["pooled"]
    for name, values in rows.items():
        summary = {}
        for key in base[0]:
            v = np.array([r[key] for r in values])
            d = v - np.array([r[key] for r in base])
            summary[key] = float(np.mean(v))
            summary[key + "_minus_pooled"] = float(np.mean(d))
            summary[key + "_minus_pooled_error"] = float(np.std(d, ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("nan")
        report(args, "dpca-yaw-pooling-mean", "numpy", {"seeds": seeds, "pings": pings, "rule": name}, 0.0,
               "(summary)", 0.0, **summary, load=[round(x, 2) for x in os.getloadavg()])
