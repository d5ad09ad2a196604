"""Zhang, Tan & Ying 2019 (numerical PTRS imaging): Tables 2-4 (PSLR/ISLR of 18 points for PTRS, PCA, BP) and Table 5 (time).

The 18-point scene of section 6.1.2 (:func:`clsas.scene.presets.point_scene` "zhang2019": each
point half a sub-block width of 20, 14, 12, 10, 8 or 2 m from its group's reference range 53,
143 or 194 m) with the Table 1 sonar sampled as the preset's docstring explains (15 receivers
on a 0.04 m pitch, PRI 0.15 s), the elements' beam patterns simulated and not deconvolved,
the Doppler band |f_t| <= v / D_tx of all three methods alike (back-projection integrates the
matching angle). Three imagers:

- numerical PTRS (:func:`clsas.ptrs_image`), decoupled at the three reference ranges, so that
  each point measures the residual coupling of its sub-block width (the paper's design);
- PCA: :func:`clsas.pca_record` then range-Doppler (the paper's "PCA based R-D algorithm");
- back-projection (:func:`clsas.backproject`) on each point's patch.

PSLR and ISLR are measured on the azimuth slice through each peak (:func:`clsas.metrics.analyse_point`).
Table 5 times PTRS with 4 and 8 uniform sub-blocks over the swath (stationary points solved
beforehand: the paper's second scheme) and back-projection of the same pixels, as ratios
(the paper's were on real data with Matlab: BP 35,234 s, PTRS 608 s and 1149 s).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

# Tables 2-4: (PSLR, ISLR) dB for the presented method, PCA and BP, T1..T18
PAPER = {
    "ptrs": [(-11.61, -6.44), (-13.01, -8.36), (-10.82, -8.21), (-13.41, -9.39), (-14.61, -9.87), (-14.69, -10.12),
             (-11.61, -6.44), (-13.26, -8.67), (-10.36, -7.87), (-13.86, -9.38), (-14.02, -9.53), (-14.13, -10.13),
             (-14.49, -10.22), (-14.17, -9.97), (-13.23, -9.60), (-12.45, -7.83), (-11.96, -8.80), (-11.28, -6.51)],
    "pca": [(-14.38, -9.57), (-14.45, -9.49), (-14.54, -9.98), (-14.63, -9.68), (-14.44, -9.59), (-14.26, -9.60),
            (-13.92, -9.52), (-13.87, -9.37), (-13.86, -9.32), (-14.01, -9.71), (-13.73, -9.22), (-13.69, -9.17),
            (-13.23, -9.93), (-13.13, -9.80), (-12.87, -9.47), (-12.99, -9.39), (-13.15, -9.79), (-13.55, -9.67)],
    "bp": [(-14.83, -10.34), (-14.88, -10.25), (-14.90, -10.82), (-14.77, -10.44), (-14.81, -10.15), (-14.69, -10.06),
           (-14.81, -10.23), (-14.92, -10.25), (-14.77, -10.09), (-14.78, -10.28), (-14.87, -10.21), (-14.70, -10.12),
           (-14.76, -10.26), (-14.80, -10.22), (-14.72, -10.35), (-14.83, -10.18), (-14.86, -10.41), (-14.78, -10.21)],
}
PAPER_TIMES = {"ptrs_4": 608.0, "ptrs_8": 1149.0, "bp": 35234.0}
GROUPS = ("close range (Table 2)", "medium range (Table 3)", "far range (Table 4)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pulses", type=int, default=208, help="pulses (208 cover every point's aperture)")
    parser.add_argument("--no-timing", action="store_true", help="skip Table 5 (back-projection of the whole image)")
    parser.add_argument("--backend", default="opencl", help="numpy, opencl or auto")


def scene(n_pulses: int = 208):
    """The scenario and its range-compressed echoes."""
    import clsas
    from clsas.scene import presets

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = presets.point_scene("zhang2019", n_pulses=n_pulses, receivers=15, pri=0.15)
    return sc, clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


def measure(echo, points, backend: str = "opencl", reference_ranges=None, block_width=None) -> dict:
    """Per point: azimuth (PSLR, ISLR) dB and the location error (m, (y, x)) for "ptrs",
    "pca" and "bp"; ``reference_ranges`` / ``block_width`` set PTRS's sub-blocks (default: the
    paper's three reference ranges)."""
    import clsas
    from clsas.data import Grid, Image
    from clsas.scene.presets import ZHANG_REFERENCES

    elements = (0.04, 0.02)
    if reference_ranges is None and block_width is None:
        reference_ranges = ZHANG_REFERENCES
    images = {
        "ptrs": clsas.ptrs_image(echo, reference_ranges=reference_ranges, block_width=block_width, elements=elements,
                                 deconvolve=False, backend=backend),
        "pca": clsas.range_doppler(clsas.pca_record(echo, backend=backend), elements=elements, deconvolve=False,
                                   backend=backend),
    }
    lam = echo.medium.sound_speed / echo.waveform.f0
    aperture = 2 * np.arcsin(lam / (2 * max(elements)))
    out = {name: [] for name in ("ptrs", "pca", "bp")}
    for p in points:
        near = (p[1], p[0])
        for name, image in images.items():
            out[name].append(_quality(image, near))
        patch = _patch(images["ptrs"], p, 0.25, 0.15)
        bp = clsas.backproject(echo, Grid.points(patch.positions, dims=("y", "x")), backend=backend, interp="sinc8",
                               aperture=aperture, progress=False)
        out["bp"].append(_quality(Image(data=bp.data, dims=("y", "x"), axes=patch.axes, positions=patch.positions),
                                  near))
    return out


def _quality(image, near):
    from clsas import metrics

    q = metrics.analyse_point(image, near=near, radius=0.02)
    return {"pslr": q["y"].pslr_db, "islr": q["y"].islr_db, "dy": q["location"][0] - near[0],
            "dx": q["location"][1] - near[1]}


def _patch(image, point, half_y: float, half_x: float):
    from clsas.data import Image

    y, x = image.axes["y"], image.axes["x"]
    rows = np.flatnonzero(np.abs(y - point[1]) <= half_y)
    cols = np.flatnonzero(np.abs(x - point[0]) <= half_x)
    sub = np.ix_(rows, cols)
    return Image(data=image.data[sub], dims=("y", "x"), axes={"y": y[rows], "x": x[cols]}, positions=image.positions[sub])


def timing(echo, backend: str) -> dict:
    """Seconds of PTRS with 4 and 8 uniform sub-blocks (stationary points solved beforehand)
    and of back-projection over the PTRS image's pixels."""
    import clsas
    from clsas.data import Grid
    from clsas.image.ptrs import StationaryPoints

    swath = echo.medium.sound_speed * (echo.n_samples / echo.fs) / 2
    times = {}
    points = StationaryPoints()
    for blocks in (4, 8):
        kwargs = {"block_width": swath / blocks, "elements": (0.04, 0.02), "deconvolve": False, "backend": backend}
        clsas.ptrs_image(echo, points=points, **kwargs)  # the second scheme: the PSPs solved beforehand
        start = time.perf_counter()
        image = clsas.ptrs_image(echo, points=points, **kwargs)
        times[f"ptrs_{blocks}"] = time.perf_counter() - start
    grid = Grid.plane(image.axes["x"], image.axes["y"], float(image.positions[0, 0, 2]))
    start = time.perf_counter()
    clsas.backproject(echo, grid, backend=backend, interp="sinc8", progress=False)
    times["bp"] = time.perf_counter() - start
    times["pixels"] = grid.size
    return times


def run(args: argparse.Namespace) -> int:
    from clsas.scene.presets import ZHANG_REFERENCES, ZHANG_WIDTHS

    sc, echo = scene(args.pulses)
    points = sc.targets[0].positions
    result = measure(echo, points, args.backend)
    widths = [*ZHANG_WIDTHS, *ZHANG_WIDTHS, *ZHANG_WIDTHS[::-1]]
    print(f"Zhang, Tan & Ying 2019: azimuth PSLR / ISLR (dB), clsas [paper]; {echo.n_rx} receivers x "
          f"{echo.n_pulses} pulses x {echo.n_samples} samples")
    for g, group in enumerate(GROUPS):
        print(f"\n{group}: PTRS decoupled at the reference range {ZHANG_REFERENCES[g]:.0f} m")
        print(f"{'':4} {'width':>5}  {'PTRS PSLR':>17} {'ISLR':>17}  {'PCA PSLR':>17} {'ISLR':>17}  "
              f"{'BP PSLR':>17} {'ISLR':>17}")
        for k in range(6 * g, 6 * g + 6):
            cells = []
            for name in ("ptrs", "pca", "bp"):
                q, paper = result[name][k], PAPER[name][k]
                cells.append(f"{q['pslr']:7.2f} [{paper[0]:7.2f}] {q['islr']:7.2f} [{paper[1]:7.2f}]")
            print(f"T{k + 1:<3} {widths[k]:5.0f}  " + "  ".join(cells))
    worst = max(max(abs(q["dy"]) for q in result[name]) for name in result)
    print(f"\nlargest azimuth location error of any point and method: {worst * 1000:.2f} mm")
    if not args.no_timing:
        times = timing(echo, args.backend)
        print(f"\nTable 5: time (s) over {times['pixels']:,} pixels, clsas [paper, real data, Matlab]")
        for key, label in (("ptrs_4", "PTRS, 4 sub-blocks"), ("ptrs_8", "PTRS, 8 sub-blocks"), ("bp", "back-projection")):
            ratio = times["bp"] / times[key]
            print(f"{label:22} {times[key]:8.2f} [{PAPER_TIMES[key]:7.0f}]   BP / it: {ratio:6.2f} "
                  f"[{PAPER_TIMES['bp'] / PAPER_TIMES[key]:5.1f}]")
    return 0
