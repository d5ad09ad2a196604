"""Moving-target chain cost on Kiang & Kiang 2022 case 1 (Table III): each step of one receiver's
chain through its public steps (range compression, RFRT + modified SoWVD, RCMC, Radon, RWC +
azimuth compression, the refocus with the higher-order delay and the target's extent, the focus of
the target's range window with and without the sharpness search of :mod:`clsas.estimate.moving.sharpen`),
the velocity solve, the joint position + velocity solve and the r-y mapping, in seconds and as a
share of the whole estimate + focus, with echo synthesis of the same scene and back-projection of
the same echo (receiver A, a 256 x 256 patch with the target's velocity) beside them as ratios.

One point target at the hull's centre moving at case 1's (0, -4, 0) m/s; Table I's 6400 pulses
(80 s) at 80 Hz, 512 with --quick. Warm-up runs (kernel builds) are excluded; medians. The focus
is timed both ways on the same range extent (4 ms of delay): back-projection in the target's frame
(``method="bp"``, the default: every scatterer focused) and the paper's chain (``method="paper"``),
and ``focus_moving`` with its default image (the target's size). The figures are the bench's
output (``--json``), not kept here.
"""

from __future__ import annotations

import numpy as np
from _harness import arguments, measure, report

import clsas
from clsas.model import Grid
from clsas.estimate.moving import azimuth, centroid, chain, closed_forms, located, receiver_focus, higher_order_delay, layout_of, mapping, solve_motion, solve_velocity
from clsas.estimate.moving.closedforms import delay_terms
from clsas.scene import presets
from clsas.scene.targets import PointTargets

CENTRE = np.array([1989.0, 0.0, -350.0])


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    n_pulses = 512 if args.quick else 6400
    repeats = args.repeats or 3
    v = np.array(presets.KIANG_CASES[1])
    sc = presets.kiang2022(n_pulses=n_pulses).replace(targets=(PointTargets(CENTRE, velocity=v),))
    size = {"pulses": n_pulses, "receivers": 3, "case": 1}

    steps = {}
    steps["echo synthesis (opencl)"] = measure(lambda: clsas.simulate(sc, backend="opencl", progress=False),
                                               repeats=repeats)
    echo = clsas.simulate(sc, backend="opencl", progress=False)
    size["samples"] = echo.n_samples

    rec = chain.records(echo, "A")
    est = chain.estimate_receiver(echo, "A")
    k, f_dc = est.fm_rate, est.doppler_centroid
    steps["range compression"] = measure(lambda: chain.records(echo, "A"), repeats=repeats)
    steps["RFRT + SoWVD (K)"] = measure(lambda: chain.sowvd(rec, chain.P0), repeats=repeats)
    rcmc = centroid.rcmc(rec, k)
    steps["RCMC"] = measure(lambda: centroid.rcmc(rec, k), repeats=repeats)
    steps["Radon (f_dc)"] = measure(lambda: centroid.doppler_centroid_radon(rec, rcmc), repeats=repeats)
    steps["RWC + azimuth compression"] = measure(
        lambda: azimuth.focus_bins(rec, k, f_dc, slice(0, rec.x.shape[1])), repeats=repeats)
    steps["estimate_receiver (A, whole)"] = measure(lambda: chain.estimate_receiver(echo, "A"), repeats=repeats)

    steps["sharpened locate (A, first pass)"] = measure(lambda: located.locate(rec, est, sharpen=True),
                                                        repeats=repeats)

    lay = layout_of(echo)
    higher = higher_order_delay(lay, "A", CENTRE, v, rec.eta)
    steps["refocus + extent (A, higher order)"] = measure(lambda: located.locate(rec, est, higher), repeats=repeats)
    k_c = (est.tau_c - rec.t0) * rec.fs
    bins = slice(int(k_c) - 80, int(k_c) + 81)  # +-2 ms around the target, as focus_moving(tau_span=0.004)
    _, f_model, k_model = delay_terms(lay, "A", CENTRE, v)  # the model's history, as focus_moving
    steps["focus, model history (A, 4 ms)"] = measure(
        lambda: azimuth.focus_bins(rec, k_model, f_model, bins, higher), repeats=repeats)
    steps["focus + sharpness search (A, 4 ms)"] = measure(
        lambda: azimuth.sharpened_bins(rec, k_model, f_model, bins, higher), repeats=repeats)
    truth = closed_forms(lay, CENTRE, v)
    centroids = {n: d.doppler_centroid for n, d in truth.items()}
    steps["velocity solve"] = measure(lambda: solve_velocity(lay, CENTRE, centroids), repeats=repeats)
    steps["position + velocity solve"] = measure(
        lambda: solve_motion(lay, {n: d.tau_c for n, d in truth.items()}, centroids,
                             {n: d.fm_rate for n, d in truth.items()}), repeats=repeats)
    motion = clsas.estimate_motion(echo, position=CENTRE)
    steps["estimate_motion (A, B, C)"] = measure(lambda: clsas.estimate_motion(echo, position=CENTRE),
                                                 repeats=repeats)
    image = receiver_focus.focus_receiver(echo, "A", motion.receivers["A"])
    steps["r-y mapping"] = measure(lambda: mapping.to_ry(image, motion.layout, "A", motion.position, motion.velocity,
                                                         est.tau_c, est.eta_c), repeats=repeats)
    steps["focus_moving (A, B, C)"] = measure(lambda: clsas.focus_moving(echo, motion), repeats=repeats)
    steps["focus_moving bp (A, B, C, 4 ms)"] = measure(lambda: clsas.focus_moving(echo, motion, tau_span=0.004),
                                                       repeats=repeats)
    steps["focus_moving paper (A, B, C, 4 ms)"] = measure(
        lambda: clsas.focus_moving(echo, motion, tau_span=0.004, method="paper"), repeats=repeats)

    compressed = clsas.range_compress(echo)
    grid = Grid.plane(CENTRE[0] + np.linspace(-6.4, 6.4, 256), np.linspace(-6.4, 6.4, 256), CENTRE[2])
    steps["back-projection (A, 256^2, opencl)"] = measure(
        lambda: clsas.backproject(compressed, grid, backend="opencl", receivers=["A"], target_velocity=v,
                                  progress=False), repeats=repeats)

    whole = steps["estimate_motion (A, B, C)"] + steps["focus_moving (A, B, C)"]
    for name, seconds in steps.items():
        report(args, "moving", "numpy" if "opencl" not in name else "opencl", size, seconds / whole,
               "x (estimate + focus)", seconds, step=name,
               per_synthesis=seconds / steps["echo synthesis (opencl)"],
               per_backprojection=seconds / steps["back-projection (A, 256^2, opencl)"])


if __name__ == "__main__":
    main()
