"""The public moving-target API (issue 14): :func:`estimate` a moving target's velocity (and
position) from a raw multistatic echo, :func:`focus` it on the r-y plane of every receiver that
can focus it (Kiang & Kiang 2022, sections III-VI).

``estimate`` runs the per-receiver chain (:func:`.chain.estimate_receiver`: K_a,eq from the
modified SoWVD, f_dc,eq from the Radon slope, tau_c, eta_c) on every receiver, then solves for
the velocity (:func:`.velocity.solve_velocity`, section V) at the given position, or for the
position and velocity together (:func:`.velocity.solve_motion`).

Which point. The closed forms are evaluated at one point, the given (or estimated) position: the
target's centre. The chain's tau_c and eta_c are the middle of the target's extent in its
focused image (:mod:`.extent`), where the centre focuses at every receiver, not its strongest
glint (on a hull a different scatterer at each receiver; derivation there). The centroids it
solves with are refined by the focus: after RWC with f~_dc and compression with K~, a point
with the true centroid f_dc focuses at eta = -(f_dc - f~_dc) / K~ (a residual linear phase
shifts the compressed chirp), so f~_dc - K~ eta_c is the centre's centroid (to ~1 / T_a,
against the Radon slope's fraction of a range cell over the aperture); it is used when the
receiver focuses (|K| T_a^2 large enough) and within half a PRF of the Radon estimate.

Refocus. The chain compresses with the quadratic phase only; over long apertures the delay's
higher-order terms (cubic and beyond, ~10 carrier cycles at the ends of 25 s in Table II case 6)
smear the image to one side, which moves the middle of its extent (points, 2048 pulses: centroid
errors up to 1.3 Hz, velocity 1 %). So the solution is used :data:`REFOCUS_PASSES` times to
predict those terms (:func:`.closedforms.higher_order_delay`, at the solved position and
velocity: they change little with a velocity error of a few %), every focusable receiver is
refocused with them and its extent measured again (:func:`.chain.locate`; K~ and f~ stay the
chain's), and the velocity solved again. Measured (2048 pulses, Table II): point targets
0.001-0.05 % (0.002-0.08 % with the quadratic focus and the peak), the hull 0.003-1.3 %
(1.0-8.4 % with its strongest glint). The refocus compresses with the model's own Taylor K and
f_dc at the solution, not the chain's K~ and f~: over 80 s the SoWVD's K~ is the aperture's
average rate, 4-6 % above the Taylor K (the quartic term's share), and the higher-order terms on
top of K~ count the quartic twice.

Focus. :func:`focus` compresses with the same model history, then removes what the estimate's
errors leave by image sharpness (:mod:`.sharpen`): over 80 s a velocity error of 0.1 % leaves
~27 rad of quadratic phase. Measured on points, Table II at 6400 pulses: see :func:`focus`.

A receiver "cannot focus" when |K_a,eq| T_a^2 < 4 at the solved velocity (the target keeps its
range to it: Table II case 7 at A and B); it still gives its centroid to the velocity solve and
is left out of :func:`focus`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ... import validate
from ...model import EchoData, Image
from .chain import MIN_TIME_BANDWIDTH, UPSAMPLE, estimate_records, focus_receiver, locate, records
from .closedforms import Predicted, delay_terms, higher_order_delay
from .doppler import Doppler
from .layout import Layout, layout_of
from .mapping import to_ry
from .velocity import centroid_sigma, solve_motion, solve_velocity

log = logging.getLogger("clsas")

#: 1-sigma of a centroid refined by the azimuth focus, Hz (plus 1e-4 of it): the closed forms are
#: Taylor coefficients at eta_ref, the focus sees the aperture (measured on point targets, Table II
#: cases 1-8, 2048 pulses: 0.00-0.07 Hz from the closed forms).
REFINED_SIGMA = 0.05
#: :func:`estimate` keeps the receivers' range-compressed records between its passes up to this
#: many bytes in all (above, each is made again when needed, one at a time).
KEEP_RECORDS_BYTES = 256 << 20
#: Passes of :func:`estimate` that refocus every receiver with the delay's higher-order terms at
#: the previous pass's solution and solve again (module docstring).
REFOCUS_PASSES = 2


@dataclass(frozen=True)
class MotionEstimate:
    """A moving target's motion from a multistatic echo.

    velocity : (3,) m/s. position : (3,) m at slow time 0 (given, or estimated when
    ``position_estimated``). receivers : {name: ReceiverEstimate} (K_a,eq, f_dc,eq, tau_c,
    eta_c, ...). residual : RMS misfit of the centroid equations at the solution, Hz.
    confidence : probability in [0, 1] that the velocity error is within the paper's 3 % bound
    (:mod:`.velocity`). sigma, position_sigma : (3,) 1-sigma errors, m/s and m. centroids :
    {name: Hz} the centroids solved with (refined by the focus where possible). cannot_focus :
    names of the receivers with |K_a,eq| T_a^2 < 4 at the solved velocity. range_residual : RMS
    of c (tau_c,measured - tau_c,model) / 2 over the receivers at the solution, m: a few
    centimetres when the focused scatterer is at ``position``; metres when a given position is
    not where the strongest scatterer is (an extended target: estimate the position instead).
    layout : the geometry used.
    """

    velocity: np.ndarray
    position: np.ndarray
    receivers: dict
    residual: float
    confidence: float
    sigma: np.ndarray
    position_sigma: np.ndarray
    position_estimated: bool
    centroids: dict
    cannot_focus: tuple
    range_residual: float
    layout: Layout = field(repr=False)

    @property
    def speed(self) -> float:
        return float(np.linalg.norm(self.velocity))

    @property
    def note(self) -> str:
        """"A and B cannot focus" (Table II case 7), or ""."""
        if not self.cannot_focus:
            return ""
        names = list(self.cannot_focus)
        who = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
        return f"{who} cannot focus"


def _check_position(position):
    if position is None:
        return None
    arr = np.asarray(position, dtype=np.float64) if np.ndim(position) else None
    if arr is None or arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"position must be None or a finite 3-vector (x, y, z) in m, got {position!r}")
    return arr


def check_echo(echo, receivers=None) -> list:
    """The receiver names to use, after checking ``echo`` is a raw EchoData with >= 3 of them."""
    if not isinstance(echo, EchoData):
        raise TypeError(f"echo must be an EchoData, got {type(echo).__name__}")
    if echo.compressed:
        raise ValueError("echo must be raw (EchoData.compressed is False); got a range-compressed echo: the "
                         "moving-target chain range-compresses it itself (Kiang & Kiang 2022 eq. 8)")
    names = list(echo.receivers) if receivers is None else [echo.receivers[i] for i in
                                                           echo.select_receivers(receivers, "receivers")]
    if len(names) < 3:
        raise ValueError(f"echo must hold at least 3 receivers to solve the 3 velocity components (the paper's "
                         f"A, B and C), got {tuple(names)}")
    return names


def refined_centroid(rx, layout: Layout) -> tuple[float, float]:
    """(centroid, 1-sigma) of one receiver estimate: f~ - K~ eta_c when the focus gives it (module
    docstring), else the Radon slope's f~ with :func:`.velocity.centroid_sigma`."""
    f, k = float(rx.doppler_centroid), float(rx.fm_rate)
    eta_c = float(getattr(rx, "eta_c", np.nan))
    aperture = float(getattr(rx, "aperture", layout.aperture))
    shift = -k * (eta_c - layout.eta_ref)
    if np.isfinite(shift) and abs(k) * aperture**2 >= MIN_TIME_BANDWIDTH and abs(shift) < 0.5 * layout.prf:
        return f + shift, REFINED_SIGMA + 1e-4 * abs(f)
    return f, centroid_sigma(f)


def motion_from_receivers(layout: Layout, receivers: dict, position=None, refine: bool = True,
                          aperture: float | None = None) -> MotionEstimate:
    """Solve a :class:`MotionEstimate` from per-receiver estimates (anything with fm_rate,
    doppler_centroid, tau_c and eta_c: the chain's ReceiverEstimate, or the closed forms).

    ``aperture`` (s) decides which receivers cannot focus (default: the layout's T_a).
    """
    position = _check_position(position)
    if len(receivers) < 3:
        raise ValueError(f"receivers must hold at least 3 receiver estimates, got {sorted(receivers)}")
    centroids, sigmas = {}, {}
    for name, rx in receivers.items():
        centroids[name], sigmas[name] = refined_centroid(rx, layout) if refine else \
            (float(rx.doppler_centroid), centroid_sigma(rx.doppler_centroid))
    rates = {n: float(rx.fm_rate) for n, rx in receivers.items()}
    if position is None:
        sol = solve_motion(layout, {n: float(rx.tau_c) for n, rx in receivers.items()}, centroids, rates, sigmas)
    else:
        sol = solve_velocity(layout, position, centroids, sigmas, rates)
    aperture = layout.aperture if aperture is None else float(aperture)
    tau_misfit = [float(rx.tau_c) - delay_terms(layout, n, sol.position, sol.velocity)[0] for n, rx in receivers.items()]
    range_residual = float(0.5 * layout.sound_speed * np.sqrt(np.mean(np.square(tau_misfit))))
    blind = tuple(n for n in receivers
                  if abs(delay_terms(layout, n, sol.position, sol.velocity)[2]) * aperture**2 < MIN_TIME_BANDWIDTH)
    log.info("moving target: v = %s m/s (sigma %s), residual %.3g Hz, confidence %.2f%s", np.round(sol.velocity, 3),
             np.round(sol.sigma, 3), sol.residual, sol.confidence, f"; {', '.join(blind)} cannot focus" if blind else "")
    return MotionEstimate(velocity=sol.velocity, position=sol.position, receivers=dict(receivers),
                          residual=sol.residual, confidence=sol.confidence, sigma=sol.sigma,
                          position_sigma=sol.position_sigma, position_estimated=sol.position_estimated,
                          centroids=centroids, cannot_focus=blind, range_residual=range_residual, layout=layout)


def estimate(echo: EchoData, position=None, receivers=None, **chain_options) -> MotionEstimate:
    """Velocity vector (and position, when not given) of the strongest moving target in a raw
    multistatic echo, with no prior knowledge of its motion (Kiang & Kiang 2022, sections III-V).

    Parameters
    ----------
    echo : raw EchoData with at least three receivers (the paper's A, B, C), found by name.
    position : (3,) m, the target at slow time 0 (the paper assumes it known), or None to
        estimate it from the receivers' delays, centroids and FM rates.
    receivers : names (or indices) to use; default all of the echo's.
    chain_options : passed to :func:`.chain.estimate_receiver` (p0, threshold_db).

    Raises :class:`clsas.errors.EstimationError` naming the receiver when its SoWVD shows no peak.
    """
    names = check_echo(echo, receivers)
    position = _check_position(position)
    # the range-compressed records are kept for the refocus passes when they are small, and made
    # again one at a time when not (Table I: ~0.7 GB each)
    keep = len(names) * echo.n_pulses * echo.n_samples * 8 * UPSAMPLE <= KEEP_RECORDS_BYTES
    kept, estimates = {}, {}
    for name in names:
        rec = records(echo, name)
        estimates[name] = estimate_records(rec, **chain_options)
        if keep:
            kept[name] = rec
    del rec
    layout = layout_of(echo)
    est = motion_from_receivers(layout, estimates, position)
    for _ in range(REFOCUS_PASSES):
        for name, rx in estimates.items():
            if rx.focusable:
                rec = kept[name] if keep else records(echo, name)
                _, f_dc, k = delay_terms(layout, name, est.position, est.velocity)
                estimates[name] = locate(rec, rx, higher_order_delay(layout, name, est.position, est.velocity, rec.eta),
                                         Doppler(fm_rate=float(k), doppler_centroid=float(f_dc)))
        est = motion_from_receivers(layout, estimates, position)
    return est


def focus(echo: EchoData, est: MotionEstimate, tau_span: float | None = None, sharpen: bool = True) -> dict:
    """The target focused at every receiver that can focus it, on the r-y plane (section VI):
    {name: Image with dims ("y", "r")}. Receivers in ``est.cannot_focus`` are left out (case 7:
    imaged from C only). ``tau_span`` (s) limits the range extent around tau_c.

    Each receiver is compressed with the model's whole delay history at ``est``'s position and
    velocity: its Taylor K_a,eq and f_dc,eq at eta_ref (:func:`.closedforms.delay_terms`) and
    the terms beyond them (:func:`.closedforms.higher_order_delay`), not the chain's K~ with
    those terms: over 80 s the SoWVD's K~ is the aperture's average, 4-6 % above the Taylor K
    (the quartic term's share), and the higher-order terms on top of it count the quartic twice
    (Table II case 6, points, 6400 pulses: azimuth IRW 390-600 ms at A, B, C against 15-22 ms
    with K~ alone and a 1.4-2.1 ms resolution cell). With ``sharpen`` (default) the phase the
    estimate's errors leave is then found by image sharpness and removed (:mod:`.sharpen`; over
    80 s a velocity error of 0.1 % widens the response five times): the point's azimuth
    response reaches the resolution cell 0.886 |V_h| / (|K| T_a). Measured on points at 6400
    pulses, IRW / cell and PSLR at A, B, C: case 6 1.00, -13.3 dB (the model history alone
    1.3-3.7 cells, -0.3 to -17.6 dB, at a velocity error of 0.097 %), case 8 1.00, -13.2 to
    -13.3 dB, case 1 1.00, -13.0 to -13.4 dB (model history alone 1.1-1.3 cells, -4.4 to
    -11.5 dB, at 0.010 %), cases 2, 3, 4, 5 and 7 (C) 1.00, -13.2 to -13.3 dB (cases 3 and 4,
    at 0.06 % and 0.05 %: the model history alone 5.6-9.9 cells at -0.1 to -0.5 dB, wider than
    K~ alone at 4 of the 6 receivers; the sharpness search is what makes every case better than
    the quadratic focus). On the scaled Albacore (2048 pulses, cases 5, 6, 8) the search changes
    the images' entropy by -0.33 to +0.02 (worse only in case 5 at A) and their SSIM against
    the scan image by -0.021 to +0.019 (0.74-0.91). The image is placed by ``est``: its centre (where the centroid
    ``est.centroids[name]`` focuses with the model) at the model's y of the reference point.
    """
    if not isinstance(est, MotionEstimate):
        raise TypeError(f"est must be a MotionEstimate (from estimate()), got {type(est).__name__}")
    sharpen = validate.flag("focus_moving sharpen", sharpen)
    check_echo(echo, list(est.receivers))
    images = {}
    for name, rx in est.receivers.items():
        if name in est.cannot_focus:
            continue
        _, f_dc, k = delay_terms(est.layout, name, est.position, est.velocity)
        model = Predicted(fm_rate=float(k), doppler_centroid=float(f_dc), tau_c=float(rx.tau_c))
        image: Image = focus_receiver(echo, name, model, tau_span=tau_span, sharpen=sharpen,
                                      higher_order=higher_order_delay(est.layout, name, est.position, est.velocity,
                                                                      echo.eta))
        # where the centre focuses (its centroid's offset from the model's, over K)
        eta_c = est.layout.eta_ref - (est.centroids[name] - model.doppler_centroid) / model.fm_rate
        images[name] = to_ry(image, est.layout, name, est.position, est.velocity, rx.tau_c, eta_c)
    return images
