"""Zhang, Tan & Ying 2019 (numerical PTRS imaging): Tables 2-4 (PSLR/ISLR of 18 points for PTRS, PCA, BP) and Table 5 (time).

The 18-point scene of section 6.1.2 (:func:`clsas.scene.presets.point_scene` "zhang2019": each
point half a sub-block width of 20, 14, 12, 10, 8 or 2 m from its group's reference range 53,
143 or 194 m) with the Table 1 sonar sampled as the preset's docstring explains (30 contiguous
0.02 m receivers, the printed 0.6 m array; PRI 0.15 s instead of 0.3 s so that the phase
centres tile the track), the elements' beam patterns simulated and not deconvolved, the
Doppler band |f_t| <= v / D_tx of all methods alike (back-projection integrates the matching
angle). Imagers, each point's azimuth PSLR and ISLR (:func:`clsas.metrics.analyse_point`):

- PTRS as the paper: decoupled at the three reference ranges (each point measures the residual
  coupling of its sub-block width), with clsas's residual range cell migration correction
  ("PTRS") and with eq. (13) alone ("eq. 13"), the paper's processor;
- PTRS with uniform 8 m sub-blocks over the whole swath ("8 m"), every point wherever it falls;
- PCA + range-Doppler (the paper's "PCA based R-D algorithm") twice: the paper's baseline,
  the bistatic path excess (with the forward motion 2 v r / c) compensated at the swath
  centre for every range ("PCA r_c", range-invariant, as the classic PCA of its ref. [12]),
  and clsas's default, each range's own excess ("PCA");
- back-projection (:func:`clsas.backproject`) on each point's patch.

Measured (208 pulses): PTRS with uniform 8 m sub-blocks stays within PSLR -0.21..+0.13 dB and
ISLR +0.11..+0.46 dB of back-projection at every point, the paper's blocks likewise; eq. (13)
alone (the paper's processor) loses up to 5.3 dB PSLR / 4.8 dB ISLR at the 10-20 m blocks'
edges (the residual range migration: :mod:`clsas.image.ptrs.imaging`, step 3b). Both PCA
variants lose up to 2.2 dB PSLR at medium and far range (mean |PSLR - BP| 1.46 dB over
T13-T18 against 0.10 dB for PTRS); compensating the path excess at the swath centre instead
of at each range changes them by < 0.02 dB here: the excess (d + 2 v r / c)^2 / (4 r) varies
by ~1 mm over the swath, and the loss is the phase-centre approximation itself.

Table 5 times PTRS with 4 and 8 uniform sub-blocks over the swath (stationary points solved
beforehand: the paper's second scheme), PCA + range-Doppler, and back-projection of the PTRS
image's pixels (timed on a band of rows and scaled by the pixel count), as ratios; the paper's
were on real data with Matlab (BP 35,234 s, PTRS 608 s and 1149 s).
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
    parser.add_argument("--no-timing", action="store_true", help="skip Table 5")
    parser.add_argument("--backend", default="opencl", help="numpy, opencl or auto")


RECEIVERS, PRI = 30, 0.15
ELEMENTS = (0.04, 0.02)
METHODS = ("ptrs", "ptrs_eq13", "ptrs_8m", "pca_rc", "pca", "bp")


def scene(n_pulses: int = 208):
    """The scenario and its range-compressed echoes."""
    import clsas
    from clsas.scene import presets

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = presets.point_scene("zhang2019", n_pulses=n_pulses, receivers=RECEIVERS, pri=PRI)
    return sc, clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


def swath_centre(echo) -> float:
    """The middle of the recorded ranges, m (PCA r_c's reference)."""
    c = echo.medium.sound_speed
    return float(c * (np.min(echo.t0) + np.max(echo.t0) + echo.n_samples / echo.fs) / 4)


def imagers(echo, backend: str = "opencl", points=None) -> dict:
    """The five frequency-domain imagers of the module docstring, by method name: functions of
    no argument that return the image (each image is ~1 GB with its pixel positions: make one
    at a time)."""
    import clsas
    from clsas.image.ptrs import StationaryPoints
    from clsas.scene.presets import ZHANG_REFERENCES

    points = StationaryPoints() if points is None else points
    ptrs = dict(elements=ELEMENTS, deconvolve=False, backend=backend, points=points)
    rd = dict(elements=ELEMENTS, deconvolve=False, backend=backend)
    return {
        "ptrs": lambda: clsas.ptrs_image(echo, reference_ranges=ZHANG_REFERENCES, **ptrs),
        "ptrs_eq13": lambda: clsas.ptrs_image(echo, reference_ranges=ZHANG_REFERENCES, rcmc=False, **ptrs),
        "ptrs_8m": lambda: clsas.ptrs_image(echo, block_width=8.0, **ptrs),
        "pca_rc": lambda: clsas.range_doppler(clsas.pca_record(echo, reference_range=swath_centre(echo),
                                                               backend=backend), **rd),
        "pca": lambda: clsas.range_doppler(clsas.pca_record(echo, backend=backend), **rd),
    }


def measure(echo, points, backend: str = "opencl", cache=None) -> dict:
    """Per point: azimuth (PSLR, ISLR) dB and the location error (m, (y, x)) for each of
    :data:`METHODS` (``cache``: a StationaryPoints to fill and reuse)."""
    import clsas
    from clsas.model import Grid, Image

    lam = echo.medium.sound_speed / echo.waveform.f0
    aperture = 2 * np.arcsin(lam / (2 * max(ELEMENTS)))
    out = {name: [] for name in METHODS}
    for name, make in imagers(echo, backend, cache).items():
        image = make()
        for p in points:
            out[name].append(_quality(image, (p[1], p[0])))
            if name == "ptrs":  # back-projection on the same pixels around each point
                patch = _patch(image, p, 0.25, 0.15)
                bp = clsas.backproject(echo, Grid.points(patch.positions, dims=("y", "x")), backend=backend,
                                       interp="sinc8", aperture=aperture, progress=False)
                out["bp"].append(_quality(Image(data=bp.data, dims=("y", "x"), axes=patch.axes,
                                                positions=patch.positions), (p[1], p[0])))
        del image
    return out


def _quality(image, near):
    from clsas import metrics

    q = metrics.analyse_point(image, near=near, radius=0.02)
    return {"pslr": q["y"].pslr_db, "islr": q["y"].islr_db, "dy": q["location"][0] - near[0],
            "dx": q["location"][1] - near[1]}


def _patch(image, point, half_y: float, half_x: float):
    from clsas.model import Image

    y, x = image.axes["y"], image.axes["x"]
    rows = np.flatnonzero(np.abs(y - point[1]) <= half_y)
    cols = np.flatnonzero(np.abs(x - point[0]) <= half_x)
    sub = np.ix_(rows, cols)
    return Image(data=image.data[sub], dims=("y", "x"), axes={"y": y[rows], "x": x[cols]}, positions=image.positions[sub])


def timing(echo, backend: str, points=None, bp_fraction: float = 0.125) -> dict:
    """Seconds of PTRS with 4 and 8 uniform sub-blocks over the swath, of PCA + range-Doppler,
    and of back-projection over the PTRS image's pixels (timed on ``bp_fraction`` of its rows,
    scaled). ``points``: the StationaryPoints an earlier image of this echo filled (the second
    scheme: only the few new reference ranges are solved, milliseconds)."""
    import clsas
    from clsas.model import Grid
    from clsas.image.ptrs import StationaryPoints

    points = StationaryPoints() if points is None else points
    c = echo.medium.sound_speed
    swath = c * (echo.n_samples / echo.fs) / 2
    times = {}
    for blocks in (4, 8):
        kwargs = {"block_width": swath / blocks, "elements": ELEMENTS, "deconvolve": False, "backend": backend,
                  "points": points}
        start = time.perf_counter()
        image = clsas.ptrs_image(echo, **kwargs)
        times[f"ptrs_{blocks}"] = time.perf_counter() - start
        axes, depth = image.axes, float(image.positions[0, 0, 2])
        del image
    start = time.perf_counter()
    clsas.range_doppler(clsas.pca_record(echo, backend=backend), elements=ELEMENTS, deconvolve=False, backend=backend)
    times["pca"] = time.perf_counter() - start
    rows = max(1, int(round(axes["y"].size * bp_fraction)))
    grid = Grid.plane(axes["x"], axes["y"][:rows], depth)
    start = time.perf_counter()
    clsas.backproject(echo, grid, backend=backend, interp="sinc8", progress=False)
    times["bp"] = (time.perf_counter() - start) * axes["y"].size / rows
    times["pixels"] = axes["y"].size * axes["x"].size
    return times


def _cell(q) -> str:
    return f"{q['pslr']:6.2f}/{q['islr']:6.2f}"


def _paper(values) -> str:
    return f"[{values[0]:6.2f}/{values[1]:6.2f}]"


def run(args: argparse.Namespace) -> int:
    from clsas.image.ptrs import StationaryPoints
    from clsas.scene.presets import ZHANG_REFERENCES, ZHANG_WIDTHS

    sc, echo = scene(args.pulses)
    points = sc.targets[0].positions
    cache = StationaryPoints()
    result = measure(echo, points, args.backend, cache)
    widths = [*ZHANG_WIDTHS, *ZHANG_WIDTHS, *ZHANG_WIDTHS[::-1]]
    print(f"Zhang, Tan & Ying 2019: azimuth PSLR/ISLR (dB), clsas [paper]; {echo.n_rx} receivers x "
          f"{echo.n_pulses} pulses x {echo.n_samples} samples; PCA r_c compensated at {swath_centre(echo):.0f} m")
    for g, group in enumerate(GROUPS):
        print(f"\n{group}: PTRS, eq. 13 decoupled at the reference range {ZHANG_REFERENCES[g]:.0f} m; 8 m: uniform "
              f"8 m sub-blocks")
        print(f"{'':4}{'width':>5}  {'PTRS':>13} {'[paper]':>15}  {'eq. 13':>13}  {'8 m':>13}  {'PCA r_c':>13} "
              f"{'[paper]':>15}  {'PCA':>13}  {'BP':>13} {'[paper]':>15}")
        for k in range(6 * g, 6 * g + 6):
            r = {name: result[name][k] for name in METHODS}
            print(f"T{k + 1:<3}{widths[k]:5.0f}  {_cell(r['ptrs'])} {_paper(PAPER['ptrs'][k])}  {_cell(r['ptrs_eq13'])}  "
                  f"{_cell(r['ptrs_8m'])}  {_cell(r['pca_rc'])} {_paper(PAPER['pca'][k])}  {_cell(r['pca'])}  "
                  f"{_cell(r['bp'])} {_paper(PAPER['bp'][k])}")
    print()
    for name, label in (("ptrs", "PTRS (paper's blocks)"), ("ptrs_eq13", "eq. 13 alone"), ("ptrs_8m", "PTRS, 8 m"),
                        ("pca_rc", "PCA r_c"), ("pca", "PCA")):
        dp = [result[name][k]["pslr"] - result["bp"][k]["pslr"] for k in range(len(points))]
        di = [result[name][k]["islr"] - result["bp"][k]["islr"] for k in range(len(points))]
        far = slice(12, 18)
        print(f"{label:22} - BP: PSLR {min(dp):+5.2f}..{max(dp):+5.2f} dB, ISLR {min(di):+5.2f}..{max(di):+5.2f} dB; "
              f"far range (T13-T18) mean |PSLR - BP| {np.mean(np.abs(dp[far])):.2f} dB, |ISLR - BP| "
              f"{np.mean(np.abs(di[far])):.2f} dB")
    worst = max(max(abs(q["dy"]) for q in result[name]) for name in result)
    print(f"largest azimuth location error of any point and method: {worst * 1000:.2f} mm")
    if not args.no_timing:
        times = timing(echo, args.backend, cache)
        print(f"\nTable 5: time (s) over {times['pixels']:,} pixels, clsas [paper, real data, Matlab]")
        for key, label in (("ptrs_4", "PTRS, 4 sub-blocks"), ("ptrs_8", "PTRS, 8 sub-blocks"), ("pca", "PCA + R-D"),
                           ("bp", "back-projection")):
            paper = PAPER_TIMES.get(key)
            cell = f"[{paper:7.0f}]   BP / it: {times['bp'] / times[key]:6.2f} [{PAPER_TIMES['bp'] / paper:5.1f}]" \
                if paper else f"{'':9}   BP / it: {times['bp'] / times[key]:6.2f}"
            print(f"{label:22} {times[key]:8.2f} {cell}")
        print(f"PTRS (4) / PCA + R-D: {times['ptrs_4'] / times['pca']:.1f}")
    return 0
