"""Wu, Tang & Zhong 2018 (inclined-array correction): Table 2, IRW / PSLR / ISLR of P1 and P5 in four correction cases.

The five-point scene of section 3.3 with random 1-2 degree yaw and pitch per pulse
(:func:`clsas.scene.presets.wu2018_inclined`), range-compressed, corrected by
:func:`clsas.correct_inclined_array` with no angle, pitch only, yaw only and both (the paper's
method) corrected (the multireceiver range offset of eq. 18 is compensated in every case), and
imaged by nonlinear chirp scaling (:func:`clsas.nonlinear_chirp_scaling`, the paper's imager,
its ref. [24]; ``--imager`` picks another strip-map imager) on the slant-range plane, the
elements' beam patterns simulated and not deconvolved. IRW (cm), PSLR and ISLR (dB) of the range and azimuth slices through P1
(297, -3) and P5 (300, 0) m.

Definitions. Range: the 10-IRW side-lobe region of :mod:`clsas.metrics`. Azimuth: the side
lobes are counted over +-2.9 m of the slice (``AZIMUTH_HALF``), which holds the false targets
an inclined array makes at the array period's grating offsets +-lambda r / (2 v PRI) = +-2.5 m
(the paper: "many false targets", and the pitch correction "mainly affects a part of the energy
of the false targets"); 2.9 m stops short of the neighbouring targets (6 m away along track)
and their false targets. The experiment ``sidelobe-region`` prints both definitions.

Experiments (printed, each behind a reason in the output): ``sidelobe-region`` (the side-lobe
region); ``angle-size`` (the uncorrected rows against the size and the time history of the
angles); ``height`` (the array's height above the seafloor, which the paper does not give:
the pitch's false targets and the range resolution on the ground); ``imager`` (omega-k,
range-Doppler, chirp scaling and nonlinear chirp scaling on the same corrected records: the
differences are not the imager's).
"""

from __future__ import annotations

import argparse
import math
import warnings

import numpy as np

from . import report

# Table 2: (range IRW cm, PSLR, ISLR, azimuth IRW cm, PSLR, ISLR) for P1 and P5
PAPER = {
    "none": [(8.03, -12.09, -7.83, 7.93, -8.10, 2.96), (7.84, -12.74, -8.06, 8.72, -7.83, 0.96)],
    "pitch": [(7.66, -10.31, -5.80, 7.53, -9.25, 0.06), (7.47, -10.96, -7.08, 7.53, -8.10, 0.50)],
    "yaw": [(7.66, -12.96, -10.07, 7.93, -14.70, -12.00), (7.66, -12.94, -10.03, 7.93, -14.18, -12.03)],
    "both": [(7.66, -12.96, -10.01, 7.93, -15.95, -14.12), (7.66, -12.97, -10.01, 7.93, -15.78, -13.62)],
}
CASES = {"none": (), "pitch": ("pitch",), "yaw": ("yaw",), "both": ("yaw", "pitch")}
LABELS = {"none": "no correction", "pitch": "pitch only", "yaw": "yaw only", "both": "both (the paper's)"}
POINTS = {"P1": (297.0, -3.0), "P5": (300.0, 0.0)}  # slant range, along track (m)
QUANTITIES = (("range IRW", "cm"), ("range PSLR", "dB"), ("range ISLR", "dB"), ("azimuth IRW", "cm"),
              ("azimuth PSLR", "dB"), ("azimuth ISLR", "dB"))
HEIGHT = 30.0  # m above the seafloor (assumed)
AZIMUTH_HALF = 2.9  # m, the azimuth side-lobe region's half width
ELEMENTS = (0.16, 0.08)  # transmitter, hydrophone lengths (Table 1), m
TOLERANCE = {"IRW": 0.05, "PSLR": 1.0, "ISLR": 1.5}  # IRW relative; dB
IMAGERS = ("nonlinear_chirp_scaling", "omega_k", "range_doppler", "chirp_scaling")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pulses", type=report.count(1), default=96, help="pulses (>= 40 cover the points' apertures)")
    parser.add_argument("--seed", type=report.count(0), default=2018, help="seed of the random yaw and pitch")
    parser.add_argument("--imager", default="nonlinear_chirp_scaling", choices=IMAGERS,
                        help="the strip-map imager (default: nonlinear chirp scaling, the paper's)")
    report.add_arguments(parser)


def echo_of(n_pulses: int = 96, seed: int | None = 2018, height: float = HEIGHT, low_deg: float = 1.0,
            high_deg: float = 2.0):
    """The range-compressed echoes of the five points under random yaw and pitch in
    [low_deg, high_deg] per pulse (equal bounds: a constant angle)."""
    import clsas
    from clsas.scene import presets

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = presets.wu2018_inclined(n_pulses=n_pulses, height=height, seed=seed, low_deg=low_deg, high_deg=high_deg)
    return clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


def image_of(echo, case: str, imager: str = IMAGERS[0], height: float = HEIGHT):
    """The echo corrected for ``case``'s angles and imaged on the slant-range plane."""
    import clsas

    record = clsas.correct_inclined_array(echo, correct=CASES[case], depth=-height)
    return getattr(clsas, imager)(record, elements=ELEMENTS, window="none", deconvolve=False)


def quality(image, r: float, y: float) -> dict:
    """The point near (slant range r, along track y): range and azimuth metrics (the azimuth ones
    with the 10-IRW region, ``*_10``, and over +-AZIMUTH_HALF), the location error (m) and the
    peak magnitude."""
    from clsas import metrics

    q = metrics.analyse_point(image, near=(y, r), radius=0.1)
    ys, xs = image.axes["y"], image.axes["x"]
    iy = int(np.argmin(np.abs(ys - q["location"][0])))
    ix = int(np.argmin(np.abs(xs - q["location"][1])))
    rows = np.flatnonzero(np.abs(ys - ys[iy]) <= AZIMUTH_HALF)
    wide = metrics.point_response(image.data[rows, ix], ys[rows], extent=0.999 * AZIMUTH_HALF / q["y"].irw,
                                  near=iy - rows[0], radius=1.0)
    return {"range IRW": 100 * q["x"].irw, "range PSLR": q["x"].pslr_db, "range ISLR": q["x"].islr_db,
            "azimuth IRW": 100 * q["y"].irw, "azimuth PSLR": wide.pslr_db, "azimuth ISLR": wide.islr_db,
            "azimuth PSLR_10": q["y"].pslr_db, "azimuth ISLR_10": q["y"].islr_db,
            "dy": q["location"][0] - y, "dx": q["location"][1] - r, "peak": abs(q["y"].peak)}


def measure(echo, imager: str = IMAGERS[0], height: float = HEIGHT, cases=tuple(CASES)) -> dict:
    """{case: {point name: quality}}."""
    out = {}
    for case in cases:
        image = image_of(echo, case, imager, height)
        out[case] = {name: quality(image, r, y) for name, (r, y) in POINTS.items()}
    return out


def _db(x: float) -> float:
    return 20 * math.log10(x) if x > 0 else -math.inf


def table(rep: report.Report, result: dict) -> None:
    """Table 2's rows; the reasons are attached by their keys (explained in :func:`run`)."""
    for case in CASES:
        for k, name in enumerate(POINTS):
            for i, (quantity, unit) in enumerate(QUANTITIES):
                paper, ours = PAPER[case][k][i], result[case][name][quantity]
                kind = quantity.split()[1]
                tol = TOLERANCE[kind] * paper if kind == "IRW" else TOLERANCE[kind]
                reason = ""
                if case in ("none", "pitch"):
                    reason = "angle-size"
                elif quantity == "range IRW":
                    reason = "range-resolution"
                elif quantity in ("azimuth PSLR", "azimuth ISLR") and case == "yaw":
                    reason = "pitch-false-targets"
                elif quantity == "azimuth ISLR":
                    reason = "sidelobe-region"
                rep.add("Table 2", f"{name}, {LABELS[case]}", quantity, unit, paper, ours, abs(tol), reason)


def experiments(rep: report.Report, args, echo, result: dict) -> None:
    """Run and record the four experiments of the module docstring."""
    ratio_db = {case: {n: _db(result[case][n]["peak"] / result["both"][n]["peak"]) for n in POINTS} for case in CASES}
    rows = []
    for case in ("yaw", "both"):
        for n in POINTS:
            q = result[case][n]
            rows.append((LABELS[case], n, q["azimuth PSLR_10"], q["azimuth ISLR_10"], q["azimuth PSLR"],
                         q["azimuth ISLR"], PAPER[case][list(POINTS).index(n)][4], PAPER[case][list(POINTS).index(n)][5]))
    gain_10 = np.mean([result["yaw"][n]["azimuth ISLR_10"] - result["both"][n]["azimuth ISLR_10"] for n in POINTS])
    gain_w = np.mean([result["yaw"][n]["azimuth ISLR"] - result["both"][n]["azimuth ISLR"] for n in POINTS])
    rep.experiment(
        "sidelobe-region", "Does the paper's gain from adding the pitch correction to the yaw correction show "
        "when the azimuth side lobes are counted over the slice (+-2.9 m) instead of 10 IRWs?",
        ("case", "point", "PSLR 10 IRW", "ISLR 10 IRW", "PSLR +-2.9 m", "ISLR +-2.9 m", "paper PSLR", "paper ISLR"),
        rows,
        f"Over 10 IRWs (+-0.8 m) the yaw-only and fully corrected responses are alike (ISLR gain of the pitch "
        f"correction {gain_10:+.2f} dB); over +-2.9 m the uncorrected pitch leaves false targets at the array "
        f"period's grating offsets (+-2.5 m) and the pitch correction gains {gain_w:+.2f} dB of ISLR (the paper: "
        f"1.6-2.1 dB ISLR, 1.3-1.6 dB PSLR). The table uses +-2.9 m; the ISLR of a focused point depends on the "
        f"region by ~0.5 dB.")

    scales = [("1-2 deg random (Table 2)", 1.0, 2.0, None), ("0.2-0.4 deg random", 0.2, 0.4, None),
              ("1.5 deg constant (Fig. 7)", 1.5, 1.5, None)]
    rows = []
    for label, lo, hi, _ in scales:
        res = result if (lo, hi) == (1.0, 2.0) else measure(echo_of(args.pulses, args.seed, HEIGHT, lo, hi),
                                                             cases=("none", "pitch", "both"))
        for case in ("none", "pitch"):
            for n in POINTS:
                q = res[case][n]
                rows.append((label, LABELS[case], n, q["azimuth IRW"], q["azimuth PSLR"], q["azimuth ISLR"],
                             _db(q["peak"] / res["both"][n]["peak"])))
    c, lam = 1500.0, 1500.0 / 70e3
    span = 2.48  # m, the hydrophones' offsets d_i from -1.20 to +1.28 m
    rep.experiment(
        "angle-size", "What do the stated angles do to the uncorrected image, and what size of angle gives the "
        "paper's uncorrected rows (main lobe kept at the corrected IRW, azimuth PSLR -8 dB, ISLR +1..+3 dB)?",
        ("angles", "case", "point", "az. IRW cm", "az. PSLR", "az. ISLR", "peak vs corrected dB"), rows,
        f"A yaw of 1-2 deg turns the {span} m array's ends by d sin(yaw) = {100 * 1.28 * math.sin(math.radians(1.5)):.1f} "
        f"cm = {1.28 * math.sin(math.radians(1.5)) / lam:.1f} wavelengths (the paper's own budget is lambda / 8): the "
        f"uncorrected main lobe is lost ({ratio_db['none']['P1']:.0f} and {ratio_db['none']['P5']:.0f} dB below the "
        "corrected peak; constant angles, as Fig. 7's caption says, do no better). Angles about five times smaller "
        "(0.2-0.4 deg) give rows like the paper's (main lobe kept, PSLR near -7 dB over +-2.9 m). The paper's "
        "uncorrected rows are not what its stated angles do under its own exact path (eqs. 1-6); what it simulated "
        "there is not recoverable from the text.")

    rows = []
    for h in (15.0, HEIGHT, 45.0, 137.0):
        res = result if h == HEIGHT else measure(echo_of(args.pulses, args.seed, h), height=h, cases=("yaw", "both"))
        for n, (r, _) in POINTS.items():
            ground = math.sqrt(r * r - h * h) / r
            rows.append((h, n, res["yaw"][n]["azimuth PSLR"], res["yaw"][n]["azimuth ISLR"],
                         res["both"][n]["azimuth ISLR"], res["both"][n]["range IRW"],
                         res["both"][n]["range IRW"] / ground))
    theory = 100 * 0.886 * c / (2 * 10e3)
    rep.experiment(
        "height", "The paper gives no height of the array above the seafloor: how does it set the pitch's false "
        "targets (yaw-only rows) and the range IRW on the ground?",
        ("height m", "point", "yaw-only PSLR", "yaw-only ISLR", "both ISLR", "slant range IRW cm",
         "ground range IRW cm"), rows,
        f"The pitch's path error d h sin(pitch) / r grows with the height: the yaw-only rows degrade with it (its "
        f"false targets at +-2.5 m), the fully corrected rows do not. No height gives the paper's yaw-only pair "
        f"(PSLR -14.7 dB with ISLR -12.0 dB): false targets strong enough to set the PSLR at -14.7 dB raise the "
        f"ISLR far above -12 dB. The unweighted range IRW is 0.886 c / 2B = "
        f"{theory:.2f} cm (clsas measures it within 3 %); the paper's 7.66 cm is 15 % wider with an unweighted "
        "PSLR (-12.96 dB). A ground-range projection would widen it so only at ~137 m, where the pitch's false "
        "targets wreck the yaw-only rows (unlike the paper's -14.7 dB): the paper's range IRW stays unexplained by "
        "any height consistent with its other rows.")

    rows = []
    for imager in IMAGERS:
        res = result if imager == args.imager else measure(echo, imager, cases=("none", "both"))
        for case in ("none", "both"):
            q = res[case]["P5"]
            rows.append((imager, LABELS[case], q["azimuth IRW"], q["azimuth PSLR"], q["azimuth ISLR"],
                         _db(q["peak"] / res["both"]["P5"]["peak"])))
    rep.experiment(
        "imager", "Is any difference the imager's? (P5, the same corrected records through nonlinear chirp scaling, "
        "the paper's imager, and clsas's other three strip-map imagers.)",
        ("imager", "case", "az. IRW cm", "az. PSLR", "az. ISLR", "peak vs corrected dB"), rows,
        f"The four imagers agree on the corrected point (azimuth PSLR {min(r[3] for r in rows if r[1] != LABELS['none']):.2f}.."
        f"{max(r[3] for r in rows if r[1] != LABELS['none']):.2f} dB) and all lose the uncorrected one (peak "
        f"{max(r[5] for r in rows if r[1] == LABELS['none']):.0f} dB or lower): the differences are the records' "
        "(the angles), not the imager's.")

    rep.explain("angle-size", "Under the exact path the stated 1-2 deg yaw puts 1-2 wavelengths of error across "
                "the array, so clsas's uncorrected and pitch-only images lose the main lobe (peak -35..-40 dB below "
                "the corrected one) where the paper's keep it with -8 dB side lobes; angles ~5x smaller reproduce "
                "the paper's kind of rows; no imager changes this.",
                ["experiment:angle-size", "experiment:imager", "test:tests/test_reproduce_wu2018.py::test_wu_table2_reproduction"])
    rep.explain("pitch-false-targets", "The yaw-only image keeps the pitch's false targets at +-2.5 m, whose level "
                "is set by the height above the seafloor the paper does not give (30 m assumed): at 30 m they lie "
                "below the main lobe's side lobes (PSLR) but hold side-lobe energy (ISLR); at no height do they give "
                "the paper's yaw-only PSLR and ISLR together.",
                ["experiment:height", "experiment:sidelobe-region"])
    rep.explain("sidelobe-region", "The paper does not define the side-lobe region; the ISLR of the focused point "
                "moves by ~0.5 dB between 10 IRWs and +-2.9 m.", ["experiment:sidelobe-region"])
    rep.explain("range-resolution", "The paper's range IRW is 15 % wider than an unweighted response of its "
                "10 kHz band; clsas gives the theory's 0.886 c / 2B; no assumed height consistent with the paper's "
                "yaw-only rows widens it so.", ["experiment:height", "test:tests/test_rangecomp.py::test_unweighted_sidelobes_and_resolution"])


def run(args: argparse.Namespace) -> int:
    report.check_output(args)
    rep = report.Report(
        "wu2018", f"Wu, Tang & Zhong 2018, Table 2: clsas beside the paper ({args.pulses} pulses, {args.imager})",
        assumptions=[f"the array {HEIGHT:.0f} m above the seafloor (the points on it)",
                     "yaw and pitch drawn per pulse, uniform in 1-2 deg (seed %d), spline-joined" % args.seed,
                     "azimuth side lobes counted over +-2.9 m of the slice (false targets included), range over 10 IRWs",
                     f"images by {args.imager}, beam patterns not deconvolved",
                     "PRF 3 / 1.28 Hz (the printed 2.3436 rounded so that v / PRF is the array's 1.28 m)"],
        settings={"pulses": args.pulses, "seed": args.seed, "imager": args.imager})
    with rep.stage("Table 2 (simulate, correct four ways, image)", estimate_s=5):
        echo = echo_of(args.pulses, args.seed)
        result = measure(echo, args.imager)
    table(rep, result)
    with rep.stage("experiments (4 more simulations, 2 more imagers)", estimate_s=25):
        experiments(rep, args, echo, result)
    errors = ", ".join(f"{n} {1000 * q['dy']:.2f} / {1000 * q['dx']:.2f}" for n, q in result["both"].items())
    rep.note(f"with both corrections, location errors (mm, along / across): {errors}")
    return report.finish(rep, args)
