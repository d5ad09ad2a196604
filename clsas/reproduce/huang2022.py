"""Huang & Yang 2022 (PCA + range-Doppler for multireceiver SAS): Table 2 (PSLR, ISLR, along-track resolution of T1-T6, proposed and BP) and Table 3 (time).

The Table 1 sonar (:func:`clsas.scene.presets.huang2022`: 32 receivers over 1.28 m, 2 m/s,
PRI 0.32 s, 150 kHz, 20 kHz), the six points of Fig. 4 (:func:`clsas.scene.presets.point_scene`
"huang2022": coordinates assumed, the paper prints none), simulated with exact non-stop-and-go
delays and the elements' beam patterns, range-compressed, then imaged two ways:

- the proposed method: the bistatic deformation compensated (eqs. 15-17,
  :func:`clsas.pca_record`; the Doppler phase of eq. 18 by interleaving the receivers at their
  phase centres) and range-Doppler with sub-block secondary range compression (eqs. 19-25,
  :func:`clsas.range_doppler`), over the transmitter's Doppler band |k_u| <= 2 pi / D_tx, the
  beam patterns not deconvolved;
- back-projection (:func:`clsas.backproject`, the paper's benchmark) on the same pixels,
  integrating the matching angle 2 arcsin(lambda / 2 D_tx).

Each point's azimuth PSLR (:mod:`clsas.metrics`, 10 IRWs) and along-track resolution (the
-3 dB width, AR) and its ISLR, which the paper does not define: clsas takes the 2-D ISLR
(:func:`clsas.reproduce._points.islr_2d`: side-lobe energy over +-10 IRWs in range and azimuth against the main lobe's
rectangle between the first nulls), the figure whose level and proposed-BP spread match the
paper's (experiment ``islr-definition`` prints the 1-D one beside it). Table 3 (real data,
Matlab: BP 1761 s, proposed 28 s, 63x) becomes the ratio of back-projection's time over the
proposed method's on the simulated scene's image (``--timing-pulses``).

Experiments (each behind a reason in the output): ``beam-pattern`` (the elements' patterns,
which the paper leaves out of its model and does not give, set the absolute PSLR);
``islr-definition``; ``band-edge`` (back-projection's integration angle against the
range-Doppler band: the proposed-BP PSLR difference); ``timing`` (the time ratio against
back-projection's implementation and interpolator).
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from . import report
from ._points import backprojected, patch, quality

# Table 2: per target, (PSLR dB, ISLR dB, AR m) of the proposed method and of BP
PAPER = {
    "T1": ((-14.44, -8.61, 0.04), (-14.57, -8.69, 0.04)),
    "T2": ((-14.34, -8.09, 0.04), (-14.47, -8.11, 0.04)),
    "T3": ((-14.64, -9.51, 0.04), (-14.77, -9.56, 0.04)),
    "T4": ((-14.63, -9.36, 0.04), (-14.74, -9.41, 0.04)),
    "T5": ((-14.65, -9.95, 0.04), (-14.84, -10.00, 0.04)),
    "T6": ((-14.63, -9.65, 0.04), (-14.76, -9.69, 0.04)),
}
PAPER_TIMES = {"proposed": 28.0, "bp": 1761.0}  # Table 3, real data (800 range samples), Matlab, s
ELEMENTS = (0.08, 0.04)  # transmitter, receiver widths (Table 1), m
TOLERANCE = {"PSLR": 1.0, "ISLR": 1.5, "AR": 0.005, "loss": 0.2}  # dB, dB, m (the printed digit), dB
BP_RATE = 4e8  # pixel x pulse x receiver products a second (clsas.progress's nominal OpenCL rate)
NUMPY_BP_RATE = 1e6  # the same for the NumPy reference
NUMPY_FRACTION = 512  # the NumPy reference of back-projection is timed on this fraction of the rows


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pulses", type=report.count(1), default=64, help="pulses (>= 40 cover the six points' apertures)")
    parser.add_argument("--timing-pulses", type=report.count(1), default=64,
                        help="pulses of the scene timed for Table 3 (64: ~1 min with its experiment; "
                             "back-projection's cost grows as the square of it: 256 takes ~15 min)")
    parser.add_argument("--backend", default="opencl", help="numpy, opencl or auto")
    report.add_arguments(parser)


def scene(n_pulses: int = 64, tx_length: float | None = None, rx_length: float | None = None, backend="opencl"):
    """The six-point scenario (element lengths replaced when given, 0 for omnidirectional) and its
    range-compressed echoes."""
    import clsas
    from clsas.scene import presets

    sc = presets.point_scene("huang2022", n_pulses=n_pulses)
    lengths = {k: v for k, v in (("tx_length", tx_length), ("rx_length", rx_length)) if v is not None}
    if lengths:
        sc = sc.replace(array=dataclasses.replace(sc.array, **lengths))
    return sc, clsas.range_compress(clsas.simulate(sc, backend=backend, progress=False))


def proposed(echo, elements=ELEMENTS, deconvolve: bool = False, backend="opencl"):
    """The proposed method's image: the bistatic deformation compensated and the receivers
    interleaved (eqs. 15-18), then range-Doppler with sub-block SRC (eqs. 19-25)."""
    import clsas

    return clsas.range_doppler(clsas.pca_record(echo, backend=backend), elements=elements, deconvolve=deconvolve,
                               window="none", backend=backend)


def aperture_of(echo, scale: float = 1.0) -> float:
    """Back-projection's integration angle matching the band |k_u| <= 2 pi / D_tx, rad (times ``scale``)."""
    lam = echo.medium.sound_speed / echo.waveform.f0
    return 2 * np.arcsin(min(1.0, scale * lam / (2 * ELEMENTS[0])))


def measure(echo, points, elements=ELEMENTS, bp_aperture=None, backend="opencl") -> dict:
    """{"proposed": [quality per point], "bp": [...]} (``bp_aperture`` default: :func:`aperture_of`)."""
    image = proposed(echo, elements, backend=backend)
    aperture = aperture_of(echo) if bp_aperture is None else bp_aperture
    out = {"proposed": [], "bp": []}
    for p in points:
        mine = patch(image, p)
        out["proposed"].append(quality(mine, p))
        out["bp"].append(quality(backprojected(echo, mine, None if aperture == "none" else aperture, backend), p))
    return out


def timing(echo, backend: str = "opencl", interp: str = "sinc8", bp_backend: str | None = None,
           rows_fraction: float = 1.0, repeats: int = 2) -> dict:
    """Seconds of the proposed method (conversion and range-Doppler) and of back-projection of
    its whole image's pixels (on ``bp_backend``, default ``backend``; timed on ``rows_fraction``
    of the rows and scaled), each the minimum of ``repeats`` runs interleaved (A B A B), and the
    sizes."""
    import clsas
    from clsas.model import Grid

    t_proposed, t_bp = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        image = proposed(echo, backend=backend)
        t_proposed.append(time.perf_counter() - start)
        n_rows = max(1, int(round(image.axes["y"].size * rows_fraction)))
        grid = Grid.plane(image.axes["x"], image.axes["y"][:n_rows], float(image.positions[0, 0, 2]))
        start = time.perf_counter()
        clsas.backproject(echo, grid, backend=bp_backend or backend, interp=interp, aperture=aperture_of(echo),
                          progress=True)
        t_bp.append((time.perf_counter() - start) * image.axes["y"].size / n_rows)
    return {"proposed": min(t_proposed), "bp": min(t_bp), "pixels": image.data.size,
            "products": bp_products(echo, image.data.size)}


def bp_products(echo, pixels: int) -> float:
    """Back-projection's work: pixel x pulse x receiver products."""
    return float(pixels) * echo.n_pulses * echo.n_rx


def image_pixels(echo) -> int:
    """Pixels of the proposed method's image of ``echo`` (rows: the interleaved phase centres,
    padded to an FFT length; columns: the record's samples), for the time estimates."""
    import scipy.fft

    return scipy.fft.next_fast_len(echo.n_pulses * echo.n_rx) * echo.n_samples


def _names(points) -> list:
    return [f"T{k + 1}" for k in range(len(points))]


def table(rep: report.Report, points, result: dict) -> None:
    for k, name in enumerate(_names(points)):
        where = f"{name} ({points[k][0]:.0f}, {points[k][1]:+.0f}) m"
        for m, method in enumerate(("proposed", "bp")):
            label = "proposed" if method == "proposed" else "BP"
            q, paper = result[method][k], PAPER[name][m]
            rep.add("Table 2", f"{where} {label}", "azimuth PSLR", "dB", paper[0], q["PSLR"], TOLERANCE["PSLR"],
                    "beam-pattern")
            rep.add("Table 2", f"{where} {label}", "ISLR (2-D)", "dB", paper[1], q["ISLR"], TOLERANCE["ISLR"],
                    "islr-definition")
            rep.add("Table 2", f"{where} {label}", "AR", "m", paper[2], q["AR"], TOLERANCE["AR"])
        loss = result["proposed"][k]["PSLR"] - result["bp"][k]["PSLR"]
        rep.add("Table 2", f"{where}", "PSLR proposed - BP", "dB", PAPER[name][0][0] - PAPER[name][1][0], loss,
                TOLERANCE["loss"], "band-edge")
        rep.add("Table 2", f"{where}", "ISLR proposed - BP", "dB", PAPER[name][0][1] - PAPER[name][1][1],
                result["proposed"][k]["ISLR"] - result["bp"][k]["ISLR"], TOLERANCE["loss"], "band-edge")


def experiments(rep: report.Report, args, echo, timed, points, result: dict) -> None:
    """Run and record the experiments of the module docstring, and the reasons they back."""
    names = _names(points)
    pick = [0, 3, 4]  # T1 (40 m), T4 (60 m), T5 (80 m)
    _beam_pattern(rep, args, echo, points, names, pick, result)
    _islr_definition(rep, names, result)
    _band_edge(rep, args, echo, points, names, pick, result)
    _timing(rep, args, timed, result)
    rep.explain("beam-pattern", "The absolute azimuth PSLR is set by the elements' patterns over the processed "
                "band; the paper neither models nor gives them, and its -14.3..-14.8 dB lies between clsas's "
                "one-element figures (receiver only, transmitter only); with both patterns, the simulated physics, "
                "clsas's PSLR is lower.", ["experiment:beam-pattern"])
    rep.explain("islr-definition", "The paper's ISLR is read as the 2-D ISLR (the 1-D azimuth ISLR is ~5 dB "
                "lower); ISLR depends on the main-lobe and side-lobe regions, which the paper does not state.",
                ["experiment:islr-definition", "test:tests/test_reproduce_huang2022.py::test_islr_2d_of_a_separable_sinc"])
    rep.explain("band-edge", "Back-projection's integration angle (seen from the transmitter) and range-Doppler's "
                "Doppler band cut the spectrum's edge differently for receivers ahead of the transmitter; a 10 % "
                "change of that angle moves the proposed - BP PSLR difference over a span that holds the paper's "
                "figure.", ["experiment:band-edge", "test:tests/test_reproduce_huang2022.py::test_band_edge_moves_the_bp_pslr"])
    rep.explain("implementation", "Table 3 times Matlab on real data of unknown size; clsas's back-projection is a "
                "vectorised OpenCL kernel: the ratio is the implementations' (clsas's own NumPy reference of "
                "back-projection is hundreds of times slower).", ["experiment:timing"])


def _beam_pattern(rep, args, echo, points, names, pick, result) -> None:
    variants = (("both (simulated physics)", None, None, False), ("both, deconvolved", None, None, True),
                ("transmitter only", None, 0.0, False), ("receiver only", 0.0, None, False),
                ("none (omnidirectional)", 0.0, 0.0, False))
    rows = []
    for label, tx, rx, deconvolve in variants:
        if tx is None and rx is None and not deconvolve:
            res = result["proposed"]
        else:
            variant = echo if tx is None and rx is None else scene(args.pulses, tx, rx, args.backend)[1]
            image = proposed(variant, deconvolve=deconvolve, backend=args.backend)
            res = {k: quality(patch(image, points[k]), points[k]) for k in pick}
        rows += [(label, names[k], res[k]["PSLR"], res[k]["AR"], res[k]["ISLR"]) for k in pick]

    def span(label):
        values = [r[2] for r in rows if r[0] == label]
        return f"{min(values):.1f}..{max(values):.1f}"

    rep.experiment(
        "beam-pattern", "What sets the absolute azimuth PSLR? The elements' patterns taper the processed Doppler "
        "band; the paper leaves the pattern out of its model (\"it is suppressed\") and does not say what it "
        "simulated.", ("elements' patterns", "target", "PSLR dB", "AR m", "ISLR 2-D dB"), rows,
        f"Without a pattern the response is the unweighted sinc ({span('none (omnidirectional)')} dB; deconvolved "
        f"{span('both, deconvolved')}); the receiver's 0.04 m pattern alone gives {span('receiver only')} dB, the "
        f"transmitter's 0.08 m alone {span('transmitter only')} dB, both {span('both (simulated physics)')} dB. "
        f"The paper's -14.3..-14.8 dB lies inside this span: its beam pattern (not given) sets it. The AR "
        f"({min(r[3] for r in rows):.4f}-{max(r[3] for r in rows):.4f} m) rounds to the paper's 0.04 m in every case.")


def _islr_definition(rep, names, result) -> None:
    rows = [(f"{names[k]} {label}", result[m][k]["ISLR 1-D"], result[m][k]["ISLR"], PAPER[names[k]][i][1])
            for k in range(len(names)) for i, (m, label) in enumerate((("proposed", "proposed"), ("bp", "BP")))]
    spread_1d = [result["proposed"][k]["ISLR 1-D"] - result["bp"][k]["ISLR 1-D"] for k in range(len(names))]
    spread_2d = [result["proposed"][k]["ISLR"] - result["bp"][k]["ISLR"] for k in range(len(names))]
    rep.experiment(
        "islr-definition", "The paper does not define its ISLR: the 1-D azimuth ISLR (10 IRWs) or the 2-D one "
        "(range and azimuth, +-10 IRWs, main lobe between the first nulls)?",
        ("target", "ISLR 1-D dB", "ISLR 2-D dB", "paper dB"), rows,
        f"The 1-D azimuth ISLR is {min(r[1] for r in rows):.1f}..{max(r[1] for r in rows):.1f} dB, far below the "
        f"paper's -8.1..-10.0; the 2-D ISLR lies at {min(r[2] for r in rows):.1f}..{max(r[2] for r in rows):.1f} dB, "
        f"inside the paper's span, and its proposed - BP spread ({min(spread_2d):+.2f}..{max(spread_2d):+.2f} dB) "
        f"is the paper's kind (+0.02..+0.08 dB), where the 1-D one spreads {min(spread_1d):+.2f}.."
        f"{max(spread_1d):+.2f} dB. The table uses the 2-D ISLR.")


def _band_edge(rep, args, echo, points, names, pick, result) -> None:
    angles = (("2 arcsin(lambda / 2 D_tx) (the table)", aperture_of(echo)), ("x 1.1", aperture_of(echo, 1.1)),
              ("x 1.25", aperture_of(echo, 1.25)), ("whole beam (no limit)", "none"))
    rows = []
    for label, aperture in angles:
        if label.endswith("(the table)"):
            res, at = result, {k: k for k in pick}
        else:
            res, at = measure(echo, [points[k] for k in pick], bp_aperture=aperture, backend=args.backend), \
                {k: j for j, k in enumerate(pick)}
        for k in pick:
            p, b = res["proposed"][at[k]], res["bp"][at[k]]
            rows.append((label, names[k], b["PSLR"], p["PSLR"] - b["PSLR"], p["ISLR"] - b["ISLR"]))
    near = [r[3] for r in rows if r[0] in (angles[0][0], angles[1][0])]
    wide = [r[3] for r in rows if r[0] == angles[2][0]]
    islr = max(abs(r[4]) for r in rows if r[0] in (angles[0][0], angles[1][0]))
    rep.experiment(
        "band-edge", "Range-Doppler cuts the Doppler band at |k_u| = 2 pi / D_tx; back-projection cuts the angle "
        "seen from the transmitter, while each receiver's phase centre sits d_i / 2 (up to 0.65 m) ahead of it. "
        "How much of the proposed - BP PSLR difference is that band edge?",
        ("BP integration angle", "target", "BP PSLR dB", "PSLR proposed - BP dB", "ISLR 2-D proposed - BP dB"), rows,
        f"Within 10 % of back-projection's angle the proposed - BP PSLR difference spans {min(near):+.2f}.."
        f"{max(near):+.2f} dB (the paper's +0.11..+0.19 dB "
        f"{'inside it' if min(near) <= 0.11 and max(near) >= 0.19 else 'NOT inside it'}), at 25 % "
        f"{min(wide):+.2f}..{max(wide):+.2f} dB, "
        f"while the 2-D ISLR difference stays within {islr:.2f} dB over the first two. The PSLR difference measures "
        "how the two methods cut the band's edge, which the paper does not give, more than the method's loss.")


def _timing(rep, args, echo, result) -> None:
    work = bp_products(echo, image_pixels(echo))
    estimate = work / BP_RATE * 2 + work / NUMPY_FRACTION / NUMPY_BP_RATE
    rows = [(args.timing_pulses, f"sinc8 {args.backend} (the table)", result["timing"]["pixels"],
             result["timing"]["proposed"], result["timing"]["bp"], result["timing"]["bp"] / result["timing"]["proposed"])]
    with rep.stage(f"timing: back-projection linear, and NumPy on 1/{NUMPY_FRACTION} of the rows", estimate_s=estimate):
        for backend, interp, fraction in ((args.backend, "linear", 1), ("numpy", "sinc8", NUMPY_FRACTION)):
            t = timing(echo, args.backend, interp, bp_backend=backend, rows_fraction=1 / fraction,
                       repeats=2 if fraction == 1 else 1)
            rows.append((args.timing_pulses, f"{interp} {backend}" + (f" (1/{fraction} of rows, scaled)"
                                                                     if fraction > 1 else ""),
                         t["pixels"], t["proposed"], t["bp"], t["bp"] / t["proposed"]))
    rep.experiment(
        "timing", "Back-projection / proposed time: how much is the implementation's? (Table 3 is Matlab on real "
        "data whose size is not given beyond 800 range samples.)",
        ("pulses", "back-projection", "pixels", "proposed s", "BP s", "BP / proposed"), rows,
        f"clsas's own NumPy reference of back-projection (float64, written for clarity) is "
        f"{rows[2][4] / rows[0][4]:.0f}x its OpenCL kernel and makes the ratio {rows[2][5]:.0f}x; the interpolator "
        f"alone moves it from {rows[0][5]:.1f}x to {rows[1][5]:.1f}x. The ratio is a property of the two "
        "implementations (and of the scene's size), not of the method alone.")


def run(args: argparse.Namespace) -> int:
    report.check_output(args)
    for name in ("pulses", "timing_pulses"):
        if getattr(args, name) < 40:
            raise ValueError(f"--{name.replace('_', '-')}: must be at least 40 (the points' apertures), "
                             f"got {getattr(args, name)}")
    rep = report.Report(
        "huang2022", f"Huang & Yang 2022, Tables 2-3: clsas beside the paper ({args.pulses} pulses)",
        assumptions=["T1..T6 at x = 40, 40, 60, 60, 80, 80 m and y = -2, +2 m (Fig. 4 prints no coordinates)",
                     "pulse 10 ms, sampling 25 kHz, c = 1500 m/s, receivers contiguous 0.06-1.30 m ahead of the "
                     "transmitter (clsas.scene.presets.huang2022)",
                     "the elements' beam patterns simulated and not deconvolved; Doppler band |k_u| <= 2 pi / D_tx",
                     "ISLR: the 2-D ISLR (+-10 IRWs in range and azimuth; experiment islr-definition)",
                     "Table 3: the simulated scene's image, back-projected with sinc8 (the paper: real data)"],
        settings={"pulses": args.pulses, "timing_pulses": args.timing_pulses, "backend": args.backend})
    with rep.stage("Table 2 (simulate, proposed method, back-projection of six patches)", estimate_s=6):
        sc, echo = scene(args.pulses, backend=args.backend)
        points = sc.targets[0].positions
        result = measure(echo, points, backend=args.backend)
    table(rep, points, result)
    _, timed = (sc, echo) if args.timing_pulses == args.pulses else scene(args.timing_pulses, backend=args.backend)
    estimate = bp_products(timed, image_pixels(timed)) / BP_RATE
    with rep.stage(f"Table 3 (back-projection of the whole {image_pixels(timed):,}-pixel image, twice)",
                   estimate_s=2 * estimate):
        result["timing"] = t = timing(timed, args.backend)
    rep.add("Table 3", f"{args.timing_pulses} pulses x 32 receivers", "BP / proposed time", "x",
            PAPER_TIMES["bp"] / PAPER_TIMES["proposed"], t["bp"] / t["proposed"], 10.0, "implementation")
    with rep.stage("experiments (beam-pattern, islr-definition, band-edge, timing)", estimate_s=25 + 3 * estimate):
        experiments(rep, args, echo, timed, points, result)
    worst = max(max(abs(q["dy"]), abs(q["dx"])) for m in ("proposed", "bp") for q in result[m])
    rep.note(f"largest location error of any point and method: {1000 * worst:.2f} mm; proposed {t['proposed']:.2f} s, "
             f"BP {t['bp']:.1f} s over {t['pixels']:,} pixels")
    return report.finish(rep, args)
