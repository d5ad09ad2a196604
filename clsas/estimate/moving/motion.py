"""The public moving-target API: :func:`estimate` a moving target's velocity (and
position) from a raw multistatic echo (Kiang & Kiang 2022, sections III-V); its images are made
by :func:`.focus.focus`.

``estimate`` runs the per-receiver chain (:func:`.chain.estimate_receiver`: K_a,eq from the
modified SoWVD, f_dc,eq from the Radon slope, tau_c, eta_c) on every receiver, then solves for
the velocity (:func:`.velocity.solve_velocity`, section V) at the given position, or for the
position and velocity together (:func:`.velocity.solve_motion`), and checks that one velocity
explains every receiver's FM rate (:mod:`.consistency`): a receiver that disagrees is re-run
with the rate its neighbours predict when its SoWVD holds a peak there, and what disagreement
is left lowers the confidence and widens sigma, with the problem named by receiver
(:attr:`MotionEstimate.problems`).

Which point. The closed forms are evaluated at one point, the given (or estimated) position: the
target's centre. The chain's tau_c and eta_c are the middle of the target's extent in its
focused image (:mod:`.extent`), where the centre focuses at every receiver, not its strongest
glint (on a hull a different scatterer at each receiver; derivation there). The centroids it
solves with are refined by the focus: after RWC with f~_dc and compression with K~, a point
with the true centroid f_dc focuses at eta = -(f_dc - f~_dc) / K~ (a residual linear phase
shifts the compressed chirp), so f~_dc - K~ eta_c is the centre's centroid (to ~1 / T_a,
against the Radon slope's fraction of a range cell over the aperture); it is used when the
receiver focuses (|K| T_a^2 large enough) and within half a PRF of the Radon estimate.

Which point, when the position is given. The middle of the image of a rigid target is the
image of the given position only when the target reaches equally far both ways from it: the
centroids and delays are those of a point dp away, the same point at every receiver to first
order, and a velocity solved at the given position with them is off (the three receivers see the
target from nearby directions, so the vertical component is poorly determined). So on an
extended target (its image more than :data:`EXTENDED_CELLS` range cells beyond a point's) the
point measured is fitted with the velocity (:func:`.velocity.solve_motion`) from the delays and
centroids, the given position a prior with sigma = :data:`MIDDLE_FRACTION` x the target's size
(anywhere within it, uniformly; the size from the chain's extents): the delays place the middle
in range, the prior keeps it near the given point where the delays cannot (depth).
:attr:`MotionEstimate.position` is then that point, ``given_position`` the one given. A refined
centroid carries :data:`REFINED_SIGMA` (the focus reads the aperture, the closed forms are Taylor
coefficients at eta_ref).

Position when not given. Solved from the delays, centroids and rates (:func:`.velocity.solve_motion`),
it is the point whose delays and centroids those are: on a point target the target; on an
extended one each receiver's image middle is a different point of it (a receiver that sees the
hull end-on sees its near end), and the solve, which has 9 equations for 6 unknowns, absorbs
the difference in its residuals: its formal sigma of centimetres says nothing about it (Table II
cases 1, 5, 6 on the hull: the position 0.8-1.3 m off; tests/test_moving_position.py). So the
target's size in the images (:func:`target_extent`) widens ``position_sigma`` as for a given
position (:data:`MIDDLE_FRACTION` of it, every component), and beyond :data:`POSITION_FLAG_SIZE`
the estimate says so (:attr:`MotionEstimate.position_problem`). The velocity's confidence is not
lowered by it: the velocity comes out as well as with the position given.

Refocus. The chain compresses with the quadratic phase only; over long apertures the delay's
higher-order terms (cubic and beyond: carrier cycles at the ends of Table II case 6's 25 s)
smear the image to one side, which moves the middle of its extent. So the solution is used
:data:`REFOCUS_PASSES` times to predict those terms (:func:`.closedforms.higher_order_delay`, at
the solved position and velocity: they change little with a velocity error of a few %), every
focusable receiver is refocused with them and its extent measured again (:func:`.located.locate`;
K~ and f~ stay the chain's), and the velocity solved again. The refocus compresses with the
model's own Taylor K and f_dc at the solution, not the chain's K~ and f~: over long apertures
the SoWVD's K~ is the aperture's average rate, above the Taylor K (the quartic term's share), and
the higher-order terms on top of K~ would count the quartic twice.

A receiver "cannot focus" when |K_a,eq| T_a^2 < 4 at the solved velocity (the target keeps its
range to it: Table II case 7 at A and B); it still gives its centroid to the velocity solve and
is left out of :func:`.focus.focus`.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field

import numpy as np

from ... import validate
from ...errors import EstimationError
from ...model import EchoData
from . import consistency
from .chain import estimate_records, with_rate
from .records import UPSAMPLE, check_pulse_times, records
from .closedforms import delay_terms, higher_order_delay
from .doppler import Doppler
from .extent import SMOOTH_CELLS
from .layout import Layout, layout_of
from .located import MIN_TIME_BANDWIDTH, locate
from .mapping import along_track_speed
from .velocity import centroid_sigma, confidence, solve_motion, solve_velocity

log = logging.getLogger("clsas")

#: 1-sigma of a centroid refined by the azimuth focus, Hz (plus 1e-4 of it): the closed forms are
#: Taylor coefficients at eta_ref, the focus sees the aperture (tests/test_moving.py holds point
#: targets' refined centroids to the closed forms).
REFINED_SIGMA = 0.05
#: The 1-sigma of the given position about the middle of the target's extent, as a fraction of
#: the extent: a uniform spread over it (module docstring).
MIDDLE_FRACTION = 1.0 / (2.0 * np.sqrt(3.0))
#: A target whose image reaches more than this many range resolution cells c / (2 B) beyond a
#: point's is extended: its middle is fitted (module docstring).
EXTENDED_CELLS = 4.0
#: A point's own extent in range at the extent's level, range cells 1 / B (:mod:`.extent`).
POINT_CELLS = 2.0
#: A point's image as the chain measures it (:mod:`.extent`) spans about twice the nominal
#: (SMOOTH_CELLS + 1) / (|K| T_a) in eta and ~8 range cells 1 / B in tau: 2.05x and 7.9-8.0 cells
#: on tests/test_moving.py::test_point_target_on_another_layout_position_estimated (512 pulses).
#: The position's size (:func:`target_extent`) counts beyond these, with a margin.
POINT_ETA_SPANS = 2.5
#: See :data:`POINT_ETA_SPANS`.
POINT_TAU_SPAN_CELLS = 10.0
#: An estimated position is flagged (:attr:`MotionEstimate.position_problem`) when the target's
#: images reach this far beyond a point's, m: a point's extent, measured in noise or at another
#: layout, reaches a few tenths of a metre (tests/test_moving.py).
POSITION_FLAG_SIZE = 1.0
#: :func:`estimate` keeps the receivers' range-compressed records between its passes up to this
#: many bytes in all (above, each is made again when needed, one at a time).
KEEP_RECORDS_BYTES = 256 << 20
#: Passes of :func:`estimate` that refocus every receiver with the delay's higher-order terms at
#: the previous pass's solution and solve again (module docstring).
REFOCUS_PASSES = 2
#: A confidence below this flags the estimate (issue #26's contract: a velocity off by more than
#: 3 % has confidence below it, or raises); :attr:`MotionEstimate.problems` then names why.
UNSURE = 0.5


@dataclass(frozen=True)
class MotionEstimate:
    """A moving target's motion from a multistatic echo.

    velocity : (3,) m/s. position : (3,) m at slow time 0: the point the estimate is about
    (estimated when ``position_estimated``; when a position was given, ``given_position``, it is
    that point, or on an extended target the middle of its image fitted near it: module
    docstring). receivers : {name: ReceiverEstimate} (K_a,eq, f_dc,eq, tau_c,
    eta_c, ...). residual : RMS misfit of the centroid equations at the solution, Hz.
    confidence : probability in [0, 1] that the velocity error is within the paper's 3 % bound
    (:mod:`.velocity`), lowered when the receivers disagree (:mod:`.consistency`). sigma,
    position_sigma : (3,) 1-sigma errors, m/s and m (widened by the disagreement). centroids :
    {name: Hz} the centroids solved with (refined by the focus where possible);
    centroid_sigmas : {name: Hz} their 1-sigma. consistency : the receivers' FM rates against
    the solution (:class:`.consistency.Consistency`); problems : what is wrong, one sentence
    per receiver naming it and why (empty when nothing is). repicked : names of the receivers
    re-run with another candidate of their rate search. cannot_focus :
    names of the receivers with |K_a,eq| T_a^2 < 4 at the solved velocity. range_residual : RMS
    of c (tau_c,measured - tau_c,model) / 2 over the receivers at the solution, m: a few
    centimetres when the focused scatterer is at ``position``; metres when a given position is
    not where the strongest scatterer is (an extended target: estimate the position instead).
    layout : the geometry used. position_problem : "" or, when the position was estimated on
    an extended target, why it may be off (also in ``problems``; its ``position_sigma`` then
    holds the target's size: module docstring, "Position when not given").
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
    centroid_sigmas: dict = field(default_factory=dict)
    consistency: consistency.Consistency | None = field(default=None, repr=False)
    repicked: tuple = ()
    given_position: np.ndarray | None = None
    position_problem: str = ""
    ambiguity: int = 1

    @property
    def problems(self) -> tuple:
        """One sentence per receiver that disagrees with the solution, naming it and why, one
        about the position when it may be off (:attr:`position_problem`), and, when the
        confidence is below :data:`UNSURE` and no receiver disagrees, one saying why
        (:attr:`uncertainty_problem`): a flagged estimate always names its reason."""
        found = tuple(self.consistency.problems.values()) if self.consistency is not None else ()
        unsure = () if found or not self.uncertainty_problem else (self.uncertainty_problem,)
        return found + unsure + ((self.position_problem,) if self.position_problem else ())

    @property
    def uncertainty_problem(self) -> str:
        """"" unless the confidence is below :data:`UNSURE`; then why, when no receiver's FM
        rate disagrees with the solution: other velocities fit the centroids as well (the
        ambiguity), or the velocity's own 1-sigma, propagated from the centroids' and rates'
        errors through the closed forms, is too wide against the paper's 3 % bound."""
        if not self.confidence < UNSURE:
            return ""
        speed = max(self.speed, 1e-12)
        if self.ambiguity > 1:
            return (f"velocity: {self.ambiguity} velocities fit the receivers' centroids equally well (confidence "
                    f"{self.confidence:.2f} < {UNSURE:g}); this one may not be the target's")
        worst = int(np.argmax(self.sigma))
        return (f"velocity: its 1-sigma ({', '.join(f'{s:.3g}' for s in self.sigma)}) m/s, "
                f"{100 * float(np.linalg.norm(self.sigma)) / speed:.2g} % of the speed {speed:.3g} m/s and widest in "
                f"{'xyz'[worst]}, leaves a probability of {self.confidence:.2f} < {UNSURE:g} that the error lies "
                f"within the paper's 3 %: the receivers' geometry or the centroids' errors do not pin that "
                f"component down")

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
    """None, or ``position`` as a finite (3,) float64 vector, m, within +-MAX_COORDINATE
    (TypeError for a wrong kind, ValueError for a bad value)."""
    return None if position is None else np.array(validate.vector3("position", position))


def check_echo(echo, receivers=None) -> list:
    """The receiver names to use, after checking ``echo`` is a raw EchoData with >= 3 of them."""
    if not isinstance(echo, EchoData):
        raise TypeError(f"echo must be an EchoData, got {type(echo).__name__}")
    validate.compression("echo", echo, compressed=False,
                         advice="the moving-target chain range-compresses it itself (Kiang & Kiang 2022 eq. 8)")
    names = list(echo.receivers) if receivers is None else [echo.receivers[i] for i in
                                                           echo.select_receivers(receivers, "receivers")]
    if len(names) < 3:
        raise ValueError(f"echo must hold at least 3 receivers to solve the 3 velocity components (the paper's "
                         f"A, B and C), got {tuple(names)}")
    check_pulse_times(echo)
    return names


def refined_centroid(rx, layout: Layout) -> tuple[float, float]:
    """(centroid, 1-sigma) of one receiver estimate: f~ - K~ eta_c when the focus gives it, with
    the uncertainty of which point the middle of the target's extent is (module docstring),
    else the Radon slope's f~ with :func:`.velocity.centroid_sigma`."""
    f, k = float(rx.doppler_centroid), float(rx.fm_rate)
    eta_c = float(getattr(rx, "eta_c", np.nan))
    aperture = float(getattr(rx, "aperture", layout.aperture))
    shift = -k * (eta_c - layout.eta_ref)
    if np.isfinite(shift) and abs(k) * aperture**2 >= MIN_TIME_BANDWIDTH and abs(shift) < 0.5 * layout.prf:
        return f + shift, REFINED_SIGMA + 1e-4 * abs(f)
    return f, centroid_sigma(f)


def target_extent(layout: Layout, receivers: dict, position, velocity, point_eta_spans: float = 1.0,
                  point_tau_cells: float = POINT_CELLS) -> tuple[float, float]:
    """(size, range size), m, of the target in the chain's focused images beyond a point's own:
    the largest along-track extent |V_h| x eta span and range extent c tau span / 2 over the
    receivers that focused it (those with an extent); size is the larger of the two. A point's
    own extent: ``point_eta_spans`` x (SMOOTH_CELLS + 1) / (|K| T_a) in eta, ``point_tau_cells``
    / B in tau."""
    along = across = 0.0
    for name, rx in receivers.items():
        ext = getattr(rx, "extent", None)
        if ext is None:
            continue
        point = point_eta_spans * (SMOOTH_CELLS + 1.0) / (abs(float(rx.fm_rate))
                                                         * float(getattr(rx, "aperture", layout.aperture)))
        speed = abs(along_track_speed(layout, name, position, velocity))
        along = max(along, speed * max(0.0, float(ext.eta[1] - ext.eta[0]) - point))
        across = max(across, 0.5 * layout.sound_speed * max(0.0, float(ext.tau[1] - ext.tau[0]) - point_tau_cells
                                                            / layout.bandwidth))
    return max(along, across), across


def pulse_delays(layout: Layout, receivers: dict, centroids: dict) -> dict:
    """{name: tau_c - f_dc range_doppler}: the receivers' delays (measured at the compressed
    peak) at the pulse's centre, where the closed forms put them (:mod:`.layout`)."""
    return {n: float(rx.tau_c) - layout.range_doppler * centroids[n] for n, rx in receivers.items()}


def _refuse_unphysical(layout: Layout, receivers: dict, centroids: dict, sigmas: dict, position, velocity,
                       delays: dict | None = None) -> None:
    """EstimationError when the receivers' (K, f_dc) solve to a speed beyond
    :data:`clsas.validate.MAX_SPEED` (no target this model describes moves so fast: some
    receiver's measurements are not its target's), naming the receiver furthest from the others'
    consensus (:func:`.consistency.culprit`)."""
    speed = float(np.linalg.norm(velocity))
    if speed <= validate.MAX_SPEED:
        return
    name, z, k_pred, f_pred = consistency.culprit(layout, receivers, centroids, sigmas, position, velocity, delays)
    rx = receivers[name]
    raise EstimationError(f"receiver {name}: the receivers' FM rates and Doppler centroids solve to a speed of "
                          f"{speed:.1f} m/s, beyond the {validate.MAX_SPEED:g} m/s of any target; receiver {name}'s "
                          f"K = {float(rx.fm_rate):.4g} Hz/s and f_dc = {centroids[name]:.4g} Hz sit {z:.0f} sigma from "
                          f"the K = {k_pred:.4g} Hz/s and f_dc = {f_pred:.4g} Hz the other receivers predict (its "
                          "SoWVD or Radon line may have followed noise or a cross-term)")


def motion_from_receivers(layout: Layout, receivers: dict, position=None, refine: bool = True,
                          aperture: float | None = None, quiet: bool = False) -> MotionEstimate:
    """Solve a :class:`MotionEstimate` from per-receiver estimates (anything with fm_rate,
    doppler_centroid, tau_c and eta_c: the chain's ReceiverEstimate, or the closed forms), and
    check that the solution explains every receiver's FM rate (:mod:`.consistency`).

    ``aperture`` (s) decides which receivers cannot focus (default: the layout's T_a). ``quiet``
    logs the solution and its problems at DEBUG (trial solutions) instead of INFO and WARNING.

    Raises :class:`clsas.errors.EstimationError` naming a receiver when the estimates solve to a
    speed beyond :data:`clsas.validate.MAX_SPEED` (:func:`_refuse_unphysical`).
    """
    position = _check_position(position)
    if not isinstance(receivers, dict) or len(receivers) < 3:
        raise ValueError(f"receivers must map at least 3 receiver names to estimates, got {receivers!r}")
    centroids, sigmas = {}, {}
    for name, rx in receivers.items():
        centroids[name], sigmas[name] = refined_centroid(rx, layout) if refine else \
            (float(rx.doppler_centroid), centroid_sigma(rx.doppler_centroid))
    rates = {n: float(rx.fm_rate) for n, rx in receivers.items()}
    delays = pulse_delays(layout, receivers, centroids)
    position_problem = ""
    if position is None:
        sol = solve_motion(layout, delays, centroids, rates, sigmas)
        _refuse_unphysical(layout, receivers, centroids, sigmas, sol.position, sol.velocity, delays)
        check = consistency.check(layout, receivers, sol.position, sol.velocity, sol.fit_chi2, sol.fit_dof)
        size, _ = target_extent(layout, receivers, sol.position, sol.velocity, POINT_ETA_SPANS, POINT_TAU_SPAN_CELLS)
        if size > EXTENDED_CELLS * layout.sound_speed / (2 * layout.bandwidth):
            # the delays and centroids are each receiver's image middle, not one point: the
            # position is anywhere within the target's size (module docstring, "Position")
            spread = MIDDLE_FRACTION * size
            sol = dataclasses.replace(sol, position_sigma=np.sqrt(sol.position_sigma**2 + spread**2))
            if size > POSITION_FLAG_SIZE:
                position_problem = (f"position: estimated from the middles of an extended target's images ({size:.1f} m "
                                    f"across them), which differ between receivers: it may be off by up to half that "
                                    f"(1-sigma {spread:.2f} m per component); give the position if it is known")
    else:
        sol = solve_velocity(layout, position, centroids, sigmas, rates)
        _refuse_unphysical(layout, receivers, centroids, sigmas, position, sol.velocity)
        size, across = target_extent(layout, receivers, position, sol.velocity)
        if size > EXTENDED_CELLS * layout.sound_speed / (2 * layout.bandwidth):
            # an extended target: its middle, whose centroids these are, within its size of the given point
            sol = solve_motion(layout, delays, centroids, rates, sigmas,
                               delay_sigma=(0.1 + 2 * MIDDLE_FRACTION * across * layout.bandwidth / layout.sound_speed)
                               / layout.bandwidth, prior=position, prior_sigma=MIDDLE_FRACTION * size,
                               start_velocity=sol.velocity)
            _refuse_unphysical(layout, receivers, centroids, sigmas, sol.position, sol.velocity)
        check = consistency.check(layout, receivers, sol.position, sol.velocity)
    cov = sol.covariance * check.birge**2
    conf = confidence(sol.velocity, cov, sol.ambiguity) * check.factor
    aperture = layout.aperture if aperture is None else float(aperture)
    tau_misfit = [delays[n] - delay_terms(layout, n, sol.position, sol.velocity)[0] for n in receivers]
    range_residual = float(0.5 * layout.sound_speed * np.sqrt(np.mean(np.square(tau_misfit))))
    blind = tuple(n for n in receivers
                  if abs(delay_terms(layout, n, sol.position, sol.velocity)[2]) * aperture**2 < MIN_TIME_BANDWIDTH)
    est = MotionEstimate(velocity=sol.velocity, position=sol.position, receivers=dict(receivers),
                         residual=sol.residual, confidence=conf, sigma=np.sqrt(np.abs(np.diag(cov))),
                         position_sigma=sol.position_sigma * check.birge, position_estimated=sol.position_estimated,
                         centroids=centroids, cannot_focus=blind, range_residual=range_residual, layout=layout,
                         centroid_sigmas=sigmas, consistency=check, given_position=position,
                         position_problem=position_problem, ambiguity=int(sol.ambiguity))
    if not quiet:
        announce(est)
    return est


def announce(est: MotionEstimate, level: int = logging.INFO) -> None:
    """Log ``est`` (at ``level``) and each of its problems (a WARNING)."""
    log.log(level, "moving target: v = %s m/s (sigma %s), FM-rate chi2 %.3g (%d dof), confidence %.2f%s%s",
            np.round(est.velocity, 3), np.round(est.sigma, 3), est.consistency.chi2, est.consistency.dof,
            est.confidence, f"; {est.note}" if est.note else "",
            f"; receivers re-run with another FM rate: {', '.join(est.repicked)}" if est.repicked else "")
    for problem in est.problems:
        log.warning("moving target: %s", problem)


def _refocus(layout: Layout, est: MotionEstimate, estimates: dict, record_of, position,
             passes: int = REFOCUS_PASSES) -> MotionEstimate:
    """``passes`` times: every focusable receiver located again in its record focused with the
    model at ``est`` (Taylor K and f_dc with the higher-order delay; module docstring), then the
    motion solved again. ``estimates`` is updated in place."""
    for _ in range(passes):
        for name, rx in estimates.items():
            if rx.focusable:
                rec = record_of(name)
                _, f_dc, k = delay_terms(layout, name, est.position, est.velocity)
                estimates[name] = locate(rec, rx, higher_order_delay(layout, name, est.position, est.velocity, rec.eta),
                                         Doppler(fm_rate=float(k), doppler_centroid=float(f_dc)))
        est = dataclasses.replace(motion_from_receivers(layout, estimates, position, quiet=True), repicked=est.repicked)
    return est


def _repick(layout: Layout, est: MotionEstimate, estimates: dict, record_of, position) -> MotionEstimate:
    """Re-run the receivers whose FM rate disagrees with the solution (:mod:`.consistency`) with
    another candidate of their rate search, refocus, and keep the change when it lowers the
    misfit. First every outlier at once with the candidate nearest the rate the solution predicts
    for it (the centroids, refined by the refocus, fix the solution better than the rates); then
    each alone with the candidate nearest what the other receivers predict without it. A
    candidate is taken only within :data:`.consistency.OUTLIER_SIGMAS` of its prediction.
    ``estimates`` is updated in place."""

    def candidate(name, k_pred):
        rx = estimates[name]
        if rx.search is None or not rx.fm_rate_candidates:
            return None
        pick = min((c[0] for c in rx.fm_rate_candidates), key=lambda k: abs(k - k_pred))
        tolerance = consistency.OUTLIER_SIGMAS * consistency.rate_sigma(k_pred, layout, rx.p0)
        return pick if abs(pick - k_pred) <= tolerance < abs(pick - rx.fm_rate) else None

    def attempt(est, picks):
        trial = dict(estimates)
        try:
            for name, pick in picks.items():
                trial[name] = with_rate(record_of(name), estimates[name].search, pick)
            again = _refocus(layout, motion_from_receivers(layout, trial, position, quiet=True), trial, record_of,
                             position, 1)
        except EstimationError as err:  # that candidate has no trace to focus
            log.info("moving target: re-run with K = %s Hz/s failed: %s", list(picks.values()), err)
            return est
        log.info("moving target: receivers %s re-run with K = %s Hz/s: FM-rate chi2 %.3g -> %.3g", sorted(picks),
                 [round(p, 4) for p in picks.values()], est.consistency.chi2, again.consistency.chi2)
        if again.consistency.chi2 < est.consistency.chi2:
            estimates.update(trial)
            return dataclasses.replace(again, repicked=est.repicked + tuple(sorted(picks)))
        return est

    if not est.consistency.outliers:
        return est
    picks = {n: candidate(n, est.consistency.model_rates[n]) for n in est.consistency.outliers}
    picks = {n: k for n, k in picks.items() if k is not None}
    if picks:
        est = attempt(est, picks)
    tried = set()
    while True:
        todo = [n for n in est.consistency.outliers if n not in tried]
        if not todo:
            return est
        name = todo[0]
        tried.add(name)
        delays = pulse_delays(layout, estimates, est.centroids) if position is None else None
        k_pred, _, _ = consistency.predict_without(layout, estimates, est.centroids, est.centroid_sigmas, name,
                                                   est.position, est.velocity, delays)
        pick = candidate(name, k_pred)
        if pick is not None:
            est = attempt(est, {name: pick})


def estimate(echo: EchoData, position=None, receivers=None, **chain_options) -> MotionEstimate:
    """Velocity vector (and position, when not given) of the strongest moving target in a raw
    multistatic echo, with no prior knowledge of its motion (Kiang & Kiang 2022, sections III-V).

    Parameters
    ----------
    echo : raw EchoData with at least three receivers (the paper's A, B, C), found by name.
    position : (3,) m, the target at slow time 0 (the paper assumes it known), or None to
        estimate it from the receivers' delays, centroids and FM rates.
    receivers : names (or indices) to use; default all of the echo's.
    chain_options : passed to :func:`.chain.estimate_receiver` (p0, threshold_db, focus_db).

    Raises :class:`clsas.errors.EstimationError` naming the receiver when its SoWVD shows no
    peak, or when the receivers solve to a speed beyond :data:`clsas.validate.MAX_SPEED` (the
    receiver furthest from the others' consensus). When the receivers disagree (a receiver's FM rate far from what the solution
    predicts), the estimate says so: ``problems`` names the receiver and why, ``confidence``
    falls and ``sigma`` widens (:mod:`.consistency`).
    """
    position = _check_position(position)
    names = check_echo(echo, receivers)
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

    def record_of(name):
        return kept[name] if keep else records(echo, name)

    layout = layout_of(echo)
    est = _refocus(layout, motion_from_receivers(layout, estimates, position, quiet=True), estimates, record_of,
                   position)
    est = _repick(layout, est, estimates, record_of, position)
    announce(est)
    return est
