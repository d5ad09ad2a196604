"""Heremans et al. 2009 section 5: DPCA sway and yaw vs the truth, images before/after compensation.

Prints the DPCA sway and yaw per ping against the injected truth, and the nine-point image's
azimuth PSLR, ISLR and entropy before and after motion compensation (back-projected; and by
omega-k on the interleaved record compensated over the beam, dpca.compensate_record); then phase gradient
autofocus on Kiang & Kiang 2022's cases 5, 6 and 8 (blurred in that paper, section VII-D):
entropy, contrast and azimuth PSLR of each receiver's focused image before and after PGA.

The report's rows (``--json``), each with the chapter's value or bound and a verdict:

- section 5.5 (Figs. 23-24): the largest sway error against "the highest difference ... is 2 mm"
  (at most), the largest yaw error against "of the order of 1e-4 radians" (at most 0.1 mrad,
  matched up to half of it beyond), and DPCA's own heading uncertainty (its standard error and
  bias bound at the last ping) against the same 0.1 mrad;
- section 6 (Figs. 7-8: the image defocused by the motion, focused again once corrected; no
  number): the centre point's azimuth PSLR against the reference image's (below), worse uncompensated,
  the same within 1 dB compensated (eqs. 74-75) and along the DPCA track;
- eqs. 45-47: omega-k with the chapter's processing (radiation pattern deconvolved, 2-D Hamming
  window) gives 3 dB widths alpha_w c / 2B across and alpha_w D / 2 along track (alpha_w =
  1.30; within 10 %), on the reference and the compensated record; without the window the
  compensated record's azimuth PSLR is the reference's within 1 dB;
- Kiang & Kiang 2022 section VII-D ("The PGA works marvelously well"): each receiver's image
  after PGA against the same image focused without the target's sway: entropy at most 0.2
  nats and azimuth PSLR at most 1 dB worse.

The images' reference: by default the moving record itself imaged along its true track (what
a perfect navigation gives, on the same speckle; for omega-k the record compensated over the
beam along the true track), so that the seafloor is simulated once; ``--straight-reference``
simulates the scene on the straight track too and measures against that motion-free image (the
chapter's), at twice the cost of the longest stage. The DPCA rows do not depend on it.

Cost: the simulation of the seafloor's facets (``--scatterers-per-cell`` a resolution cell of
the focused image, default 4) and the PGA cases dominate.

Kiang & Kiang attribute the blur of cases 5, 6 and 8 to "the sway motion of the target"
(section VII-D; case 5 "bearing some sway and heave motions", section VI) and give neither its
size nor its period. clsas's targets move at constant velocity, and its moving-target chain
focuses them to the resolution cell (azimuth PSLR -13.26 dB, the unweighted sinc's), so without
a sway PGA has nothing to correct. The target's sway and heave are therefore injected into the
records: by default 1 mm across track (x) over 6 s and 0.7 mm in depth (z) over 9 s, sinusoids
(``--kiang-sway``), i.e. about 1.36 rad of phase at 150 kHz, several cycles over the 25.6 s
aperture, which the chain's model and its low-order sharpness search cannot follow (azimuth
PSLR about -2 dB). Each receiver's ping is delayed by dt, the difference of the exact
non-stop-and-go two-way delays to the point with and without the displacement (bounce and
reception times solved for each; target_sway_delays), applied as a phase over the baseband
frequencies (dpca.delay_records). That phase is exact for a band-limited record; the simulated
chirp's hard edges are not, and at the Kiang records' critical sampling (fs = B) their aliased
components get the wrong delay: against an exact simulation of the point displaced by
(3, 0, -2) mm (2.2 rad), the range-compressed peak agrees to a few mrad and per cent in
amplitude (tests/test_dpca.py). For the scaled hull the centre's dt is applied to every facet;
the line of sight turns by about 5 mrad across its 10 m at 2 km, which changes dt by d * 5e-3,
under 5 um of path against the 10 mm wavelength. The table gives the sway-free image's entropy
(the same estimate, focused from the records without the sway) as the figure PGA should reach.

The chapter's scene: 15 hydrophones 21.88 cm apart, transmitter in the middle, v = 1.2763 m/s,
PRT 0.6 s, f0 = 50 kHz, nine point targets around r0 = 100 m (presets.point_scene
("heremans2009")). The chapter does not give its motion errors or seafloor; assumed here: sway
5 cm and yaw 3 mrad, sinusoids of 40 s and 30 s periods starting from zero at the first ping
(the size of its Figs. 23-24), and a sand seafloor 15 m below the track over 88-112 m x +-20 m
with the nine points laid on it (presets.heremans2009_seafloor), so that every range block
correlates. The chapter reports a sway
error of at most 2 mm (lambda / 15) and a yaw error of the order of 1e-4 rad.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from .. import metrics
from ..model import Grid
from ..estimate import dpca
from ..image import backproject, omega_k, pca_record, range_compress
from ..scene import presets
from ..scene.scenario import Platform
from ..synthesis import simulate
from . import report

R0 = 100.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pings", type=int, default=32, help="pings simulated (default 32)")
    parser.add_argument("--out", default="reproduce-heremans2009", help="folder for the PNG images")
    parser.add_argument("--seed", type=report.count(0), default=5, help="seed of the seafloor's scatterers")
    parser.add_argument("--kiang-cases", type=int, nargs="*", default=[5, 6, 8],
                        help="Kiang & Kiang 2022 cases to autofocus with PGA (default 5 6 8; the option with no "
                             "case skips PGA)")
    parser.add_argument("--kiang-sway", type=float, nargs=2, default=[1.0, 0.7], metavar=("SWAY", "HEAVE"),
                        help="the Kiang targets' sway (x, 6 s period) and heave (z, 9 s period) amplitudes in mm "
                             "(default 1.0 0.7; 0 0 for none)")
    parser.add_argument("--kiang-targets", choices=("points", "submarine"), default="points",
                        help="one point at the hull's centre (seconds a case, default) or the scaled hull "
                             "(minutes a case)")
    parser.add_argument("--scatterers-per-cell", type=float, default=4.0,
                        help="seafloor facets a resolution cell (default 4; the synthesis's time grows with it)")
    parser.add_argument("--straight-reference", action="store_true",
                        help="also simulate the scene on the straight track and compare the images with it "
                             "(doubles the simulation, the longest stage); by default the reference is the "
                             "moving record imaged along its true track")
    report.add_arguments(parser)


ALTITUDE = 15.0   # m, the seafloor below the track (presets.heremans2009_seafloor)
# s a ping, a facet a resolution cell and a simulation: a rough rate on 2 cores for the progress
# line's time estimate of the simulation stage only (it decides nothing else)
SIMULATION_S = 8.5 / 8


def _scene(pings: int, seed: int, scatterers_per_cell: float = 4.0):
    """presets.heremans2009_seafloor (the nine points on 15 m deep sand over 88-112 m x +-20 m,
    ``seed`` its speckle, ``scatterers_per_cell`` facets a resolution cell) at fs = 2 B, and the
    assumed sway and yaw."""
    scene = presets.heremans2009_seafloor(n_pulses=pings, altitude=ALTITUDE, seed=seed)
    floor = dataclasses.replace(scene.seafloor, scatterers_per_cell=scatterers_per_cell)
    scene = scene.replace(seafloor=floor)
    scene = scene.replace(waveform=dataclasses.replace(scene.waveform, fs=2 * scene.waveform.bandwidth))
    t0 = scene.eta[0]
    sway = lambda t: 0.05 * np.sin(2 * np.pi * (t - t0) / 40.0)  # noqa: E731
    yaw = lambda t: 0.003 * np.sin(2 * np.pi * (t - t0) / 30.0)  # noqa: E731
    return scene, sway, yaw


def run(args: argparse.Namespace) -> int:
    if args.pings < 8:
        raise SystemExit(f"clsas reproduce heremans2009: --pings must be >= 8, got {args.pings}")
    if not all(np.isfinite(a) and 0 <= a <= 100 for a in args.kiang_sway):
        raise SystemExit(f"clsas reproduce heremans2009: --kiang-sway amplitudes must be in [0, 100] mm, "
                         f"got {args.kiang_sway}")
    if not (np.isfinite(args.scatterers_per_cell) and 0.5 <= args.scatterers_per_cell <= 16):
        raise SystemExit(f"clsas reproduce heremans2009: --scatterers-per-cell must be in [0.5, 16], "
                         f"got {args.scatterers_per_cell}")
    report.check_output(args)
    rep = report.Report("heremans2009", "Heremans, Dupont & Acheroy 2009, section 5: DPCA micronavigation", assumptions=[
        f"the seafloor: sand {ALTITUDE:g} m below the track over 88-112 m x +-20 m (presets.heremans2009_seafloor), "
        f"{args.scatterers_per_cell:g} facets a resolution cell, the nine points laid on it at TS -20 dB",
        "sway 5 cm / 40 s and yaw 3 mrad / 30 s, sinusoids from zero",
        "fs = 2 B, range compression upsampled 4x",
        "B = 10 kHz (presets.heremans2009): the range width of eq. 47 follows from it"],
        settings={"pings": args.pings, "seed": args.seed, "scatterers_per_cell": args.scatterers_per_cell,
                  "straight_reference": bool(args.straight_reference), "kiang_cases": list(args.kiang_cases or [])})
    scene, sway, yaw = _scene(args.pings, args.seed, args.scatterers_per_cell)
    speed = scene.platform.speed
    moving = scene.replace(platform=Platform(speed=speed, start=scene.platform.start, sway=sway, yaw=yaw))
    print(f"Heremans et al. 2009: {scene.array.n_receivers} hydrophones, {args.pings} pings, nine points on a sand "
          "seafloor; sway 5 cm / 40 s and yaw 3 mrad / 30 s injected")
    scenes = (scene, moving) if args.straight_reference else (moving,)
    with rep.stage(f"simulating the scene {'without and ' if args.straight_reference else ''}with the motion",
                   estimate_s=SIMULATION_S * len(scenes) * args.pings * args.scatterers_per_cell):
        # no bottom bounces (multipath=0): the chapter's scene has none, and the image sources
        # of half a million facets would double the synthesis
        *clean, echo = [range_compress(simulate(s, progress=False, multipath=0), upsample=4) for s in scenes]
    with rep.stage("DPCA over the ping pairs", estimate_s=0.1 * args.pings):
        pairs = dpca.estimate(echo, scene.array, speed)
    # DPCA measures changes of heading; the first ping's heading (at its reception, see
    # Trajectory.heading_times) comes from the vehicle's compass: here from the truth.
    first_reception = echo.eta[0] + pairs.two_way
    track = dpca.integrate(pairs, echo.eta, speed, scene.array, heading0=float(yaw(first_reception)))
    _dpca_rows(rep, track, sway(track.times) - sway(track.times[0]), yaw(track.heading_times))
    # the reference the images are measured against: the record imaged where it was taken (the
    # true track: what a perfect navigation gives, on the same speckle), or with
    # --straight-reference a second simulation on the straight track (the chapter's motion-free
    # image)
    truth = dataclasses.replace(track, along=np.zeros_like(track.along), cross=sway(track.times),
                                heading=yaw(track.heading_times))
    reference = "motion-free" if clean else "true track"

    d = scene.array.rx_length[0]
    rres = scene.medium.sound_speed / (2 * scene.waveform.bandwidth)
    floor_z = scene.platform.start[2] - ALTITUDE
    grid = Grid.plane(np.arange(93.0, 107.0, rres / 2), np.arange(-8.0, 8.0, d / 4), floor_z)
    cases = {reference: clean[0] if clean else echo, "uncompensated": dpca.with_track(echo, scene),
             "compensated (eqs. 74-75)": dpca.compensate(echo, track, scene, depth=floor_z),
             "along the DPCA track": dpca.with_track(echo, scene.replace(platform=track.platform(speed, surge=False)))}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"\n{'image':26s} {'PSLR az dB':>11} {'ISLR az dB':>11} {'entropy':>8}")
    measured = []
    for name, data in cases.items():
        with rep.stage(f"back-projecting the {name} image", estimate_s=0.05 * args.pings):
            image = backproject(data, grid, progress=False)
        res = metrics.analyse_point(image, near=(0.0, R0), radius=d)
        measured.append((name, res["y"].pslr_db, res["y"].islr_db, res["y"].irw, metrics.entropy(image)))
        print(f"{name:26s} {res['y'].pslr_db:11.2f} {res['y'].islr_db:11.2f} {metrics.entropy(image):8.3f}")
        try:
            from .. import plot

            stem = name.split(" (")[0].replace(" ", "_")
            plot.save_figure(plot.plot_image(image, floor_db=-40, title=f"Heremans 2009: {name}"), out / f"{stem}.png")
        except ImportError:
            pass
    _image_rows(rep, measured, reference)
    # The frequency-domain imagers on the interleaved record of hydrophones 5-11 (7 phase
    # centres a ping interleave without overlap), compensated over the whole beam.
    receivers = list(range(4, 11))
    records = {reference: pca_record(clean[0], receivers) if clean else
               dpca.compensate_record(echo, truth, scene, receivers, depth=floor_z),
               "compensated over the beam": dpca.compensate_record(echo, track, scene, receivers, depth=floor_z)}
    _omega_k_rows(rep, records, scene, d)
    if args.kiang_cases:
        per_case = 600.0 if args.kiang_targets == "submarine" else 70.0
        with rep.stage(f"PGA on Kiang & Kiang 2022 cases {list(args.kiang_cases)}",
                       estimate_s=per_case * len(args.kiang_cases)):
            _kiang_pga(rep, args.kiang_cases, args.kiang_targets, [a * 1e-3 for a in args.kiang_sway], out)
    print(f"\nimages in {out}/")
    return report.finish(rep, args)


# the chapter's figures (section 5.5): the largest sway error (Fig. 23, mm) and the order of the
# yaw error (Fig. 24, mrad); eq. 47's Hamming broadening alpha_w
PAPER_SWAY_MM, PAPER_YAW_MRAD, ALPHA_HAMMING = 2.0, 0.1, 1.30


def _dpca_rows(rep: report.Report, track, true_sway: np.ndarray, true_yaw: np.ndarray) -> None:
    """Print the DPCA track against the truth (per ping) and add the section 5.5 rows: the
    largest sway and yaw errors against the chapter's (Figs. 23-24: "the highest difference ... is
    2 mm"; the yaw error "of the order of 1e-4 radians", read as at most 0.1 mrad, matched up to
    half of it), and DPCA's own heading uncertainty (standard error and bias bound at the last
    ping) against the same 0.1 mrad: the accuracy DPCA claims for itself must be the chapter's."""
    print(f"\n{'ping':>4} {'true sway mm':>13} {'DPCA mm':>9} {'error mm':>9} {'true yaw mrad':>14} "
          f"{'DPCA mrad':>10} {'error mrad':>11}")
    for p in range(track.eta.size):
        print(f"{p:4d} {true_sway[p] * 1e3:13.2f} {track.cross[p] * 1e3:9.2f} {(track.cross[p] - true_sway[p]) * 1e3:9.2f} "
              f"{true_yaw[p] * 1e3:14.3f} {track.heading[p] * 1e3:10.3f} {(track.heading[p] - true_yaw[p]) * 1e3:11.3f}")
    sway_err = np.abs(track.cross - true_sway).max() * 1e3
    yaw_err = np.abs(track.heading - true_yaw).max() * 1e3
    rep.add("section 5.5, Fig. 23", "sway", "max error", "mm", PAPER_SWAY_MM, sway_err, 0.0, kind="at most")
    rep.add("section 5.5, Fig. 24", "yaw", "max error", "mrad", PAPER_YAW_MRAD, yaw_err, PAPER_YAW_MRAD / 2,
            kind="at most")
    rep.add("section 5.5, Fig. 24", "heading", "standard error at the last ping (DPCA's own)", "mrad",
            PAPER_YAW_MRAD, track.heading_std[-1] * 1e3, PAPER_YAW_MRAD / 2, kind="at most")
    if track.heading_bias is not None:
        rep.add("section 5.5, Fig. 24", "heading", "bias bound at the last ping (DPCA's own)", "mrad",
                PAPER_YAW_MRAD, track.heading_bias[-1] * 1e3, PAPER_YAW_MRAD / 2, kind="at most")
    rms = np.sqrt(np.mean((track.cross - true_sway) ** 2)) * 1e3
    print(f"\nsway error: max {sway_err:.2f} mm, RMS {rms:.2f} mm (paper: at most 2 mm); yaw error: max "
          f"{yaw_err:.3f} mrad (paper: ~0.1 mrad)")


def _image_rows(rep: report.Report, measured, reference: str = "motion-free") -> None:
    """Section 6 (Figs. 7-8): the chapter shows the image defocused by the uncorrected motion and
    focused again once corrected, without a number. Rows: each image's azimuth PSLR of the centre
    point against the ``reference`` image's (``measured[0]``: motion-free, or the record imaged
    along its true track; compensated and along the DPCA track: the same, within 1 dB;
    uncompensated: worse, by any amount, the chapter giving none); the absolute figures are the
    experiment ``images``."""
    free = measured[0][1]
    bounds = {"uncompensated": (0.0, 0.0, "at least"), "compensated (eqs. 74-75)": (0.0, 1.0, "value"),
              "along the DPCA track": (0.0, 1.0, "value")}
    for name, pslr, *_ in measured[1:]:
        paper, tol, kind = bounds[name]
        rep.add("section 6, Figs. 7-8", f"centre point, {name}", f"azimuth PSLR re {reference}", "dB", paper,
                pslr - free, tol, kind=kind)
    rep.experiment("images", "How focused is each back-projected image of the centre point (no window, the "
                   "beam over the whole aperture)?", ("image", "PSLR az dB", "ISLR az dB", "IRW az m", "entropy"),
                   [(name, pslr, islr, irw, ent) for name, pslr, islr, irw, ent in measured],
                   f"the rows above are the PSLRs against the {reference} image's")


def _omega_k_rows(rep: report.Report, records, scene, d: float) -> None:
    """Eqs. 40-47: omega-k of the interleaved PCA records, the radiation pattern deconvolved and
    a 2-D Hamming window over the processed bandwidths (eq. 46), as the chapter processes; the
    centre point's 3 dB widths against eq. 47 (alpha_w c / 2B across, alpha_w D / 2 along track,
    alpha_w = 1.30; matched within 10 %), and without the window its azimuth PSLR, compensated
    against the reference record's (the first of ``records``: motion-free, or compensated along
    the true track; within 1 dB, as the back-projected rows)."""
    c, bandwidth = scene.medium.sound_speed, scene.waveform.bandwidth
    slant = float(np.hypot(R0, ALTITUDE))
    widths = {"x": ALPHA_HAMMING * c / (2 * bandwidth), "y": ALPHA_HAMMING * d / 2}
    print(f"\n{'omega-k, PCA record':26s} {'window':>8} {'PSLR az dB':>11} {'ISLR az dB':>11} {'IRW az m':>9} "
          f"{'IRW rg m':>9} {'entropy':>8}")
    plain = {}
    for name, record in records.items():
        for window, deconvolve in (("none", False), ("hamming", True)):
            image = omega_k(record, elements=(d, d), window=window, deconvolve=deconvolve)
            res = metrics.analyse_point(image, near=(0.0, slant), radius=d)   # slant range
            print(f"{name:26s} {window:>8} {res['y'].pslr_db:11.2f} {res['y'].islr_db:11.2f} {res['y'].irw:9.4f} "
                  f"{res['x'].irw:9.4f} {metrics.entropy(image):8.3f}")
            if window == "none":
                plain[name] = res["y"].pslr_db
                continue
            for dim, label in (("y", "azimuth"), ("x", "range")):
                rep.add("eqs. 45-47", f"omega-k, {name}, Hamming", f"{label} 3 dB width", "m", widths[dim],
                        res[dim].irw, 0.1 * widths[dim])
    (free, _), *others = plain.items()
    for name, pslr in others:
        rep.add("eqs. 45-47", f"omega-k, {name}, no window", f"azimuth PSLR re {free}", "dB", 0.0,
                pslr - plain[free], 1.0)


SWAY_PERIODS = (6.0, 9.0)   # s: the injected sway (x) and heave (z) of the Kiang targets


def _two_way(echo, scene, h: int, trajectory) -> np.ndarray:
    """Two-way delays (s, (n_pulses,)) from the transmitter at each emission to a point moving
    along ``trajectory(t)`` (m, t.shape + (3,)) and on to receiver ``h``: the bounce at
    t_b = eta + |q(t_b) - tx(eta)| / c and the reception at t_r = t_b + |q(t_b) - rx(t_r)| / c
    (non-stop-and-go), each by fixed-point iteration (|v| / c < 1e-2 a step: eight steps leave
    under 1e-16 s)."""
    c = echo.medium.sound_speed
    tx = scene.tx_position(echo.eta)
    t_b = echo.eta.copy()
    for _ in range(8):
        t_b = echo.eta + np.linalg.norm(trajectory(t_b) - tx, axis=-1) / c
    q = trajectory(t_b)
    t_r = t_b.copy()
    for _ in range(8):
        t_r = t_b + np.linalg.norm(q - scene.receiver_position(h, t_r), axis=-1) / c
    return t_r - echo.eta


def target_sway_delays(echo, scene, position, velocity, displacement) -> np.ndarray:
    """Extra two-way delays (s, (n_rx, n_pulses)) of a point at ``position`` + ``velocity`` t
    (m, m/s) displaced by ``displacement(t)`` (m, t.shape + (3,)): the difference of the exact
    non-stop-and-go delays with and without the displacement, at each receiver and ping."""
    q0, v = np.asarray(position, dtype=np.float64), np.asarray(velocity, dtype=np.float64)
    still = lambda t: q0 + v * t[..., None]  # noqa: E731
    moved = lambda t: still(t) + displacement(t)  # noqa: E731
    return np.stack([_two_way(echo, scene, h, moved) - _two_way(echo, scene, h, still) for h in range(echo.n_rx)])


def _kiang_pga(rep: report.Report, cases, targets: str, sway, out: Path) -> None:
    """PGA on each receiver's focused image of Kiang & Kiang 2022's ``cases`` (section VII-D),
    the target swaying by ``sway`` = (x, z) amplitudes in m (module docstring). The images are the
    paper's chain (``focus_moving(method="paper")``), the one section VII-D autofocuses; the default
    back-projection focus runs its own sharpness autofocus first, which would leave PGA a
    different, partly corrected phase error.

    Rows (Kiang & Kiang 2022, section VII-D: "The PGA works marvelously well"; no figure): each
    receiver's image after PGA against the same image focused without the sway, entropy within
    0.2 nats and azimuth PSLR within 1 dB (at most that much worse)."""
    from ..errors import EstimationError
    from ..estimate import autofocus
    from ..estimate.moving import estimate as estimate_motion
    from ..estimate.moving import focus as focus_moving
    from ..scene import presets
    from . import kiang2022

    def displacement(t):
        (ax, az), (tx, tz) = sway, SWAY_PERIODS
        return np.stack([ax * np.sin(2 * np.pi * t / tx), np.zeros_like(t), az * np.sin(2 * np.pi * t / tz)], -1)

    print(f"\nKiang & Kiang 2022 cases {cases} ({targets}; target sway {sway[0] * 1e3:g} mm / {SWAY_PERIODS[0]:g} s, "
          f"heave {sway[1] * 1e3:g} mm / {SWAY_PERIODS[1]:g} s): focused images before and after PGA")
    print(f"{'case':>4} {'rx':>3} {'entropy':>8} {'-> PGA':>8} {'no sway':>8} {'contrast':>9} {'-> PGA':>8} "
          f"{'PSLR az':>8} {'-> PGA':>8} {'iter':>5}")
    for case in cases:
        scene = kiang2022.scene(case, targets, 6400 if targets == "submarine" else 2048)
        still = simulate(scene, seed=case, progress=False)
        dt = target_sway_delays(still, scene, kiang2022.CENTRE, presets.KIANG_CASES[case], displacement)
        echo = still.replace(data=dpca.delay_records(still.data, dt, still.waveform.f0, still.fs),
                             provenance={**still.provenance, "target_sway": {
                                 "amplitudes_m": [float(a) for a in sway], "periods_s": list(SWAY_PERIODS)}})
        try:
            est = estimate_motion(echo, position=kiang2022.CENTRE)
        except EstimationError as err:
            print(f"{case:4d}  estimation failed: {err}")
            continue
        q = est.position + est.velocity * est.layout.eta_ref
        r_c, y_c = float(np.linalg.norm(q - est.layout.tx_position)), float(q[1])
        reference = focus_moving(still, est, tau_span=0.04, method="paper")
        for name, image in focus_moving(echo, est, tau_span=0.04, method="paper").items():
            image = kiang2022.window(image, r_c, y_c, 12.0)
            sway_free = metrics.entropy(kiang2022.window(reference[name], r_c, y_c, 12.0))
            try:
                result = autofocus.pga(image)
            except EstimationError as err:
                print(f"{case:4d} {name:>3}  PGA: {err}")
                continue
            before = metrics.analyse_point(image)["y"].pslr_db
            after = metrics.analyse_point(result.image)["y"].pslr_db
            free_pslr = metrics.analyse_point(kiang2022.window(reference[name], r_c, y_c, 12.0))["y"].pslr_db
            item = f"case {case}, receiver {name}, after PGA"
            rep.add("Kiang 2022 section VII-D", item, "entropy re sway-free", "nats", 0.0,
                    result.entropy_after - sway_free, 0.2, kind="at most")
            rep.add("Kiang 2022 section VII-D", item, "azimuth PSLR re sway-free", "dB", 0.0, after - free_pslr, 1.0,
                    kind="at most")
            print(f"{case:4d} {name:>3} {result.entropy_before:8.3f} {result.entropy_after:8.3f} {sway_free:8.3f} "
                  f"{result.contrast_before:9.2f} {result.contrast_after:8.2f} {before:8.2f} {after:8.2f} "
                  f"{result.iterations:5d}")
            try:
                from .. import plot

                plot.save_figure(plot.plot_image(result.image, floor_db=-40,
                                                 title=f"Kiang 2022 case {case}, {name}, after PGA"),
                                 out / f"kiang_case{case}_{name}_pga.png")
            except ImportError:
                pass
