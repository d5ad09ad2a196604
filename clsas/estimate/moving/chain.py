"""One receiver's moving-target chain (Kiang & Kiang 2022, sections III and IV, Fig. 3).

The monostatic chain of transceiver A (section III) and the bistatic chains of receiver B and
sonobuoy C (section IV) are the same processing of one receiver's record: only the closed forms
of K_a,eq and f_dc,eq (eqs. 15-16, 23-25, 28, 32) differ, and the chain does not use them. With
tau(eta) = tau_0 + (f_dc / f0) d + (K / (2 f0)) d^2, d = eta - eta_ref, the two-way delay of the
target (eqs. 1-2, 21, the R'' of C; f_dc = f_dc,eq, K = K_a,eq):

1. range compression (eq. 8; :func:`clsas.range_compress`, upsampled twice so that the envelope
   stages see a well-sampled |s|),
2. RFRT (eqs. 10-11) gated to where the echo stands out of the noise, modified SoWVD
   (eqs. 12-14) at several lag offsets and the K at which they agree (:func:`.sowvd.rate_search`:
   on a target of several scatterers the strongest peak of one map can be a cross-term; the
   gates: :mod:`.gated`); :class:`clsas.errors.EstimationError` is raised (section VII-C) when
   the echo stands out of the noise in too few pulses, or when no SoWVD peak stands out of the
   maps' background (:data:`THRESHOLD_DB`) and the record focused with the best candidate holds
   no target either, or holds something bright that this K does not focus (:data:`FOCUS_DB`,
   :func:`.located.sharpness`: the SoWVD, a fourth-order product of the record, loses to the noise
   well before the coherent focus does: tests/test_moving_noise.py has the scores), and the
   same holds for the rate the followed trace's curvature gives (:func:`.track.trace_rate`,
   the delay's second derivative K / f0: on a many-scatterer target at the paper's floor the
   SoWVD's best candidate can be noise while the trace still bends as the target's K; tried
   after it, through the same checks; two confirmed rates that disagree are two objects, and the
   receiver says so: :func:`_weak_rate`, :attr:`ReceiverEstimate.fm_rate_source`),
3. RCMC (eq. 17, :mod:`.filters`), Radon transform of |s_rcmc| -> slope -> f_dc (:mod:`.radon`),
4. range-walk compensation and azimuth compression (eqs. 18-20; :func:`.filters.compress`) of
   the target's neighbourhood (:data:`.located.EXTENT_WINDOW` around the Radon intercept, the trace's delay
   at eta_ref; eq. 20: (R'_10 + R''_10) / c_s), sharpened (:func:`.located.locate`: the residual phase
   and range migration the quadratic focus leaves over long apertures), and the target's extent
   in that image (:mod:`.extent`): tau_c and eta_c are the middle of the extent, where the
   target's centre focuses (for a point target its peak: eta_c = eta_ref - (f_dc,true - f_dc) / K, ~eta_ref; on a
   hull the middle of the hull's image rather than its strongest glint, which differs between
   receivers).

The reference slow time. The paper centres its exposure on eta = 0 and expands there. The chain
expands about eta_ref, the middle of the record (:attr:`Records.eta_ref`), which is where
:func:`.layout.layout_of` puts the closed forms' Taylor coefficients by default: RCMC, RWC and
the deramp run in d, the Radon intercept is the trace's delay at the middle pulse, so K~, f~ and
tau_c are the coefficients the velocity solver compares with the closed forms, on any schedule
(``PulseSchedule(start=...)``). Expanded about eta = 0 instead, an exposure over 0..25.6 s
gives f~ = f_dc(0) = f_dc(eta_ref) - K eta_ref, K eta_ref away from the closed forms' centroid, and a
velocity tens of % off (tests/test_moving_focus.py::test_schedule_off_eta_0_estimates_and_places_the_point);
the centred schedules, eta_ref = 0, are unchanged.

Faint copies of a target +-c T / 2 = +-3.75 m in range (T the 5 ms pulse) are Table I's
critical sampling, not the chain: with F_r = B = 20 kHz the rectangular chirp's spectral leakage
beyond +-B / 2 wraps to the opposite band edge, where the matched filter's group delay differs by
B / K_r = T. They sit well below the peak of the unweighted compression, lower with a Taylor
window, and sink below the sidelobes once F_r exceeds B by a quarter. The chain keeps the
unweighted matched filter (its range resolution feeds tau_c). With intra-pulse Doppler the echo's band is
shifted by -f_dc and, at F_r = B, its far edge wraps round: that copy carries a slow-time Doppler
f_dc F_r / f0 away from the target's, so it focuses seconds away in eta as well, and
:func:`.located.locate` zeroes that band first (:func:`.records.wrapped_band`).

Several targets (section VII-B): :func:`.targets.estimate_receivers` takes the strongest SoWVD peak,
focuses it, windows its image, undoes the chain on the window (inverse azimuth compression,
RWC, RCMC: all unitary here) and subtracts the result from the range-compressed record
before looking for the next peak.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass

import numpy as np

from ... import validate
from ...model import EchoData
from ...errors import EstimationError
from .centroid import bent, doppler_centroid_radon, doppler_centroid_walking, doppler_centroid_whitened, rcmc
from .doppler import Doppler
from .extent import Extent
from .located import EXTENT_WINDOW, MIN_TIME_BANDWIDTH, SHARP_STEPS, focused_rate, locate, sharpness
from .records import Records, records
from .gated import THRESHOLD_DB, sowvd
from .sowvd import RateSearch

log = logging.getLogger("clsas")

#: Default lag offset p0 (s): Kiang & Kiang 2022 Fig. 5(b) reads f_eta = 1.934 Hz for
#: K = 4.834 Hz/s, i.e. 4 p0 = 0.4 s.
P0 = 0.1
#: Below :data:`THRESHOLD_DB` the rate search's best candidate is still taken when the record
#: focused with it holds a target: its image's peak this far over the image's median, dB (step 2
#: of the module docstring). Focused noise peaks ~13 dB over its median on a 10^6-pixel image
#: (the largest of n exponential powers over their median: ln n / ln 2); a point focused at
#: the paper's floor stands well over it (tests/test_moving_noise.py).
FOCUS_DB = 20.0
#: A candidate confirmed by the focus (:data:`FOCUS_DB`) must also be sharp: its image's peak
#: this far above the record's focused :data:`SHARP_STEPS` focus steps off in K (:func:`.located.sharpness`), dB.
SHARP_DB = 3.0
#: Passes of :func:`.located.focused_rate` at most below the SoWVD's threshold (each from the last one's rate).
FOCUS_PASSES = 3
#: Below the SoWVD's threshold, a confirmed K within this fraction (or :data:`.located.SHARP_STEPS` focus
#: steps) of a followed trace's curvature rate (:func:`.track.trace_rate`, within a few % of the
#: target's) agrees with it; else that rate is tried too, and two confirmed Ks further apart than
#: this are two objects (:func:`estimate_records`: the brighter kept, the receiver flagged).
TRACE_AGREES = 0.1
#: Where a receiver's K_a,eq came from (:attr:`ReceiverEstimate.fm_rate_source`): the rate search's
#: (its peak over the threshold, or a candidate :func:`.motion.estimate` re-picked); below the
#: threshold, its best candidate confirmed (and refined) by the focus; a followed trace's curvature
#: rate confirmed (and refined) by the focus.
FM_RATE_SOURCES = ("sowvd", "focus", "trace")


@dataclass(frozen=True)
class ReceiverEstimate(Doppler):
    """A target's Doppler parameters at one receiver, estimated from its echo.

    fm_rate : K_a,eq, Hz/s (SoWVD peak, eq. 14); doppler_centroid : f_dc,eq, Hz (Radon slope).
    receiver : its name. tau_c, eta_c : where the target's centre focuses, s: the middle of its
    extent in the focused image (:mod:`.extent`; a point target's peak: (R'_10 + R''_10) / c_s
    and ~eta_ref in eq. (20)); when the target cannot be focused, tau_c is the trace's delay at
    eta_ref (the Radon intercept) and eta_c nan. tau_trace : the Radon intercept, s (the strongest
    track's delay at eta_ref: on a point target tau_c to a fifth of a sample; on a hull its
    strongest glint's). peak_to_background : the SoWVD peak over the map's
    median (linear; :attr:`.sowvd.RateSearch.peak_to_background`). p0 : the first lag offset
    used, s. aperture : the record's slow-time span T_a, s. extent : the target's
    :class:`~.extent.Extent` in the focused image (None when it cannot be focused).
    fm_rate_candidates : ((K Hz/s, score dB), ...) the rate search's candidates, the one nearest
    fm_rate first (a rate from the focus or a trace is none of them); slope_limited : the Radon slope sits at the edge of its search (no straight trace
    after RCMC: K is wrong or there is no target). search : the :class:`.sowvd.RateSearch`
    without its map (to refine another candidate), or None. fm_rate_source : where fm_rate came
    from, one of :data:`FM_RATE_SOURCES`. fm_rate_rivals : ((K Hz/s, source, image peak dB over
    its median), ...) other rates that the focus also confirmed and that disagree with fm_rate
    (:func:`estimate_records`; then :attr:`rate_problem` says so), () when none did.
    """

    receiver: str
    tau_c: float
    eta_c: float
    peak_to_background: float
    p0: float
    aperture: float
    tau_trace: float = float("nan")
    extent: Extent | None = None
    fm_rate_candidates: tuple = ()
    slope_limited: bool = False
    search: RateSearch | None = dataclasses.field(default=None, repr=False, compare=False)
    fm_rate_source: str = "sowvd"
    fm_rate_rivals: tuple = ()

    @property
    def rate_problem(self) -> str:
        """"" unless the focus confirmed another rate that disagrees with fm_rate
        (:attr:`fm_rate_rivals`); then a sentence naming both rates (:func:`.consistency.check`
        lists it under the receiver's name and lowers the confidence)."""
        if not self.fm_rate_rivals:
            return ""
        peak = f", image peak {self.extent.peak_db:.1f} dB" if self.extent is not None else ""
        others = "; ".join(f"K = {k:.4g} Hz/s ({source}, image peak {db:.1f} dB)" for k, source, db in self.fm_rate_rivals)
        return (f"its record focuses sharply at K = {self.fm_rate:.4g} Hz/s ({self.fm_rate_source}, kept{peak}) "
                f"and at {others}, more than {100 * TRACE_AGREES:g} % apart: they focus different objects, and the "
                f"brighter one kept may not be the target the other receivers see")

    @property
    def focusable(self) -> bool:
        """False when |K| T_a^2 < :data:`.located.MIN_TIME_BANDWIDTH`: the azimuth chirp has no
        bandwidth to compress (the target moves with the receiver)."""
        return abs(self.fm_rate) * self.aperture**2 >= MIN_TIME_BANDWIDTH


def _finite(value) -> bool:
    """Whether the real number ``value`` is finite as a float (an int past float's range is not;
    np.isfinite raised an unnamed TypeError on ints past int64)."""
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def _check_chain_options(p0, threshold_db, focus_db) -> tuple[float, float]:
    """(p0, threshold_db) as floats, checked."""
    if isinstance(p0, (bool, np.complexfloating)) or not isinstance(p0, (int, float, np.number)):
        raise TypeError(f"p0 must be a finite number of seconds, got {p0!r}")
    if not _finite(p0):
        raise ValueError(f"p0 must be a finite number of seconds, got {p0!r}")
    if isinstance(threshold_db, (bool, np.complexfloating)) or not isinstance(threshold_db, (int, float, np.number)):
        raise TypeError(f"threshold_db must be a finite number of dB, got {threshold_db!r}")
    if not _finite(threshold_db):
        raise ValueError(f"threshold_db must be a finite number of dB, got {threshold_db!r}")
    if focus_db is not None:
        validate.scalar("focus_db", focus_db, unit="dB", why="or None")
    return float(p0), float(threshold_db)


def estimate_records(rec: Records, p0: float = P0, threshold_db: float = THRESHOLD_DB,
                     focus_db: float | None = FOCUS_DB) -> ReceiverEstimate:
    """Steps 2-5 on a receiver's :func:`records`: :func:`estimate_receiver` without the range compression."""
    p0, threshold_db = _check_chain_options(p0, threshold_db, focus_db)
    search = dataclasses.replace(sowvd(rec, p0, threshold_db), primary=None)
    ratio_db = search.score_db
    if ratio_db >= threshold_db:
        return with_rate(rec, search)
    weak = (f"receiver {rec.name}: no SoWVD peak stands out of the background: peak-to-background "
            f"{ratio_db:.1f} dB < threshold {threshold_db:.1f} dB")
    if focus_db is None:
        raise EstimationError(weak)
    est = _weak_rate(rec, search, focus_db, weak)
    log.info("receiver %s: SoWVD score %.1f dB below the threshold %.1f dB; K = %.5g Hz/s (%s) confirmed by the focus "
             "(image peak %.1f dB over its median)", rec.name, ratio_db, threshold_db, est.fm_rate, est.fm_rate_source,
             est.extent.peak_db)
    return est


def focus_step(rec: Records) -> float:
    """``rec``'s focus step 4 / T_a^2, Hz/s (T_a its aperture, as :attr:`ReceiverEstimate.aperture`):
    the rate error that leaves one cycle of quadratic phase at the aperture's ends (:func:`.located.sharpness`)."""
    return 4.0 / _aperture(rec) ** 2


def _aperture(rec: Records) -> float:
    """``rec``'s slow-time span T_a, s: its pulses' span and one pulse interval."""
    return float(np.ptp(rec.eta) + 1.0 / rec.prf)


def _agree(k: float, other: float, step: float) -> bool:
    """Whether the rate ``other`` lies within :data:`TRACE_AGREES` of ``k`` (Hz/s), or within
    :data:`.located.SHARP_STEPS` focus steps ``step`` of it."""
    return abs(other - k) <= max(TRACE_AGREES * abs(k), SHARP_STEPS * step)


#: How :func:`_confirmed`'s messages name a candidate of each :data:`FM_RATE_SOURCES` below the threshold.
_NAMED = {"focus": "its best candidate", "trace": "the followed trace's curvature"}


def _weak_rate(rec: Records, search: RateSearch, focus_db: float, weak: str) -> ReceiverEstimate:
    """Below the SoWVD's threshold (``weak`` says so): the estimate with the rate search's best
    candidate when the record focused with it holds a target it focuses sharply
    (:func:`_confirmed`), else with the first rate a followed trace's curvature reads
    (:func:`.track.trace_rate`: where the SoWVD of a many-scatterer target at the noise floor
    peaks on noise, the trace still bends as the target's K) that passes the same checks;
    EstimationError naming every candidate and why when none does. A trace rate with
    |K| T_a^2 < :data:`.located.MIN_TIME_BANDWIDTH` is not tried: the focus cannot confirm a
    rate that leaves nothing to compress. Such a rate bends the trace by less than
    MIN_TIME_BANDWIDTH fs / (8 f0) = 0.13 upsampled samples at the record's ends (Table I), and it
    is what a trace that keeps to its straight seed line within the blocks' whole-sample lags
    reads: a parabola of rounding (random target 4002 at B, -15 dB: 5.4e-14 Hz/s).

    A confirmed best candidate that no trace rate agrees with (:func:`_agree`) may be something
    else's (a cross-term's), so the trace rates are then tried too, and two confirmed rates can
    disagree. They cannot both be the target's: a confirmed K focuses its object sharply, its
    peak at least :data:`SHARP_DB` above the same window compressed :data:`.located.SHARP_STEPS` focus steps
    4 / T_a^2 either side, so one object's focus falls off within a few steps of its K, and two
    rates more than :data:`TRACE_AGREES` apart (and more than SHARP_STEPS steps: 10 % of a K of
    5 Hz/s over 25.6 s is ~80 steps) focus two objects (two targets, clutter, or a trace that
    followed another object). The record alone does not say which one the other receivers see:
    the brighter focus is kept (the chain's strongest target), the other named in
    :attr:`ReceiverEstimate.fm_rate_rivals`, and the receiver flagged
    (:attr:`ReceiverEstimate.rate_problem`, a WARNING; :func:`.consistency.check` lists it and
    halves the confidence: one of two equally confirmed objects). Two confirmed rates that
    agree are one object's: the first is kept."""
    step = focus_step(rec)
    rates = [r for r in search.trace_rates if abs(r) * _aperture(rec) ** 2 >= MIN_TIME_BANDWIDTH]
    failures, tried, confirmed = [], [], []
    for k, source in [(None, "focus")] + [(r, "trace") for r in rates]:
        if k is not None and any(abs(k - t) <= SHARP_STEPS * step for t in tried):
            continue  # focused_rate from there would end where that one did
        try:
            est = _confirmed(rec, search, k, source, focus_db)
        except _Unconfirmed as err:
            failures.append(str(err))
            tried.extend(err.rates)
            continue
        confirmed.append(est)
        tried.extend([est.fm_rate] + ([] if k is None else [k]))
        # a trace's own rate, or a candidate a trace's curvature agrees with, ends the search
        if k is not None or any(_agree(est.fm_rate, r, step) for r in rates):
            break
    if not confirmed:
        raise EstimationError(f"{weak}, and " + "; and ".join(failures))
    if failures:
        log.info("receiver %s: %s", rec.name, "; ".join(failures))
    est = confirmed[0]
    if len(confirmed) > 1 and not _agree(est.fm_rate, confirmed[1].fm_rate, step):
        est, other = sorted(confirmed, key=lambda c: -c.extent.peak_db)
        est = dataclasses.replace(est, fm_rate_rivals=((other.fm_rate, other.fm_rate_source, other.extent.peak_db),))
        log.warning("receiver %s: %s", rec.name, est.rate_problem)
    return est


class _Unconfirmed(Exception):
    """A weak candidate rate that its focus does not confirm (:func:`_confirmed`): the message and
    the rates tried (Hz/s)."""

    def __init__(self, message: str, rates: list):
        super().__init__(message)
        self.rates = rates


def _confirmed(rec: Records, search: RateSearch, k: float | None, source: str, focus_db: float) -> ReceiverEstimate:
    """The estimate with the candidate rate ``k`` (Hz/s; None: the rate search's own) refined by
    the focus, its :attr:`~ReceiverEstimate.fm_rate_source` ``source`` ("focus" or "trace"), when
    the record focused with it holds a target (:data:`FOCUS_DB`) that it focuses sharply
    (:data:`SHARP_DB`); else :class:`_Unconfirmed` saying why."""
    what = _NAMED[source]
    k0 = search.fm_rate if k is None else float(k)
    tried = [k0]
    try:
        est = with_rate(rec, search) if k is None else with_rate(rec, search, k0, refine=False)
    except EstimationError as err:
        raise _Unconfirmed(f"{what} K = {k0:.4g} Hz/s fails: {err}", tried) from None
    if est.extent is None:
        raise _Unconfirmed(f"{what} K = {k0:.4g} Hz/s does not focus (|K| T_a^2 < {MIN_TIME_BANDWIDTH}) to "
                           f"confirm it", tried)
    step = focus_step(rec)
    if not est.extent.peak_db >= focus_db:
        raise _Unconfirmed(f"focused with {what} K = {k0:.4g} Hz/s the record holds no target: image peak "
                           f"{est.extent.peak_db:.1f} dB over its median < {focus_db:g} dB", tried)
    # the SoWVD's rate near its floor is a few focus steps off (its bin is ~16 of them over 25.6 s):
    # the rate the focus itself is sharpest at (:func:`.located.focused_rate`) replaces it when they differ
    # from a rate several steps off, the sharpening's search (+-3 % of K, with the cubic and quartic
    # terms) may settle beside the target's own terms and its rate correction point the wrong way;
    # from the rate it gives, it finds them (Table II case 6 at B, -17 dB: the SoWVD's 7.725 Hz/s ->
    # 7.791 with the cubic term missed -> 7.695 with it, the noise-free rate): so again from each
    # new rate until it moves by less than a focus step
    for _ in range(FOCUS_PASSES):
        k = focused_rate(rec, est)
        if not abs(k - est.fm_rate) > step:
            break
        log.info("receiver %s: %s K = %.5g Hz/s focuses sharpest at %.5g Hz/s (%.1f focus steps off)",
                 rec.name, what, est.fm_rate, k, (k - est.fm_rate) / step)
        tried.append(k)
        try:
            est = with_rate(rec, search, k, refine=False)
        except EstimationError as err:
            raise _Unconfirmed(f"{what}'s focused K = {k:.4g} Hz/s fails: {err}", tried) from None
    at, detuned = sharpness(rec, est)
    if not at - max(detuned) >= SHARP_DB:
        raise _Unconfirmed(f"focused with {what} K = {est.fm_rate:.4g} Hz/s the record's peak ({at:.1f} dB over "
                           f"its median) is not sharper there than at K -+ {SHARP_STEPS:g} focus steps "
                           f"({detuned[0]:.1f}, {detuned[1]:.1f} dB): something bright, not a target focused by "
                           f"that K", tried)
    log.info("receiver %s: %s K = %.5g Hz/s focuses a target sharply: its window's peak %.1f dB over its median, "
             "%.1f dB over the window focused %g focus steps off", rec.name, what, est.fm_rate, at, at - max(detuned),
             SHARP_STEPS)
    return dataclasses.replace(est, fm_rate_source=source)


def with_rate(rec: Records, search: RateSearch, fm_rate: float | None = None, refine: bool = True) -> ReceiverEstimate:
    """Steps 3-5 on ``rec`` with the azimuth FM rate ``fm_rate`` (Hz/s): the rate search's own
    (default), or another of its candidates (:func:`.motion.estimate` re-picks a receiver whose
    rate disagrees with the others'), refined (:meth:`.sowvd.RateSearch.refine`) unless
    ``refine`` is False (a rate found by the focus, :func:`.located.focused_rate`, is finer than the
    SoWVD's bin). The candidates are kept, the one used first."""
    k = search.fm_rate if fm_rate is None else search.refine(fm_rate) if refine else float(fm_rate)
    candidates = tuple(tuple(map(float, c)) for c in search.candidates)
    peak_to_background, p0, margin_db = search.peak_to_background, search.p0[0], search.margin_db
    aligned = rcmc(rec, k)
    found = [doppler_centroid_radon(rec, aligned), doppler_centroid_walking(rec, aligned)]
    del aligned
    if bent(rec, k):
        found.append(doppler_centroid_whitened(rec, k))
    if search.trace_line is not None:
        # the followed trace's tangent at eta_ref (:mod:`.track`): where the SoWVD needed the
        # followed trace, the Radon line of the whole RCMC'd record may find the noise's (a fast
        # walker at -17 dB, Table II case 6 at A: -83 Hz where the trace's tangent reads 512 Hz)
        slope, sample = search.trace_line
        tangent = (slope * rec.f0 * rec.prf / rec.fs, rec.t0 + sample / rec.fs, False)
        # and a line whose focus window (:data:`.located.EXTENT_WINDOW` about its delay at eta_ref) does not
        # hold the followed trace there follows something else: over a long record the trace's
        # own far end (Table II case 6 at A, 6400 pulses, -17 dB: a Radon line of slope 0 at
        # 173 ms from the trace focused part of its end 1.9 dB above the tangent's focus, and
        # the velocity went to 102.7 m/s)
        found = [line for line in found if abs(line[1] - tangent[1]) <= EXTENT_WINDOW] + [tangent]
    # the lines agree (within two samples of walk over the aperture) unless noise, a still trace
    # or a long aperture's bent noise floor fooled one of them: then the one whose focus stands
    # higher is kept
    lines = []
    for line in found:
        if all(abs(line[0] - kept[0]) * rec.fs / rec.f0 * float(np.ptp(rec.eta)) > 2.0 for kept in lines):
            lines.append(line)
    aperture = _aperture(rec)
    if candidates:
        used = int(np.argmin([abs(c[0] - k) for c in candidates]))
        candidates = (candidates[used],) + tuple(candidates[:used]) + tuple(candidates[used + 1:])
    tried = []
    for f_dc, tau_c, limited in lines:
        est = ReceiverEstimate(fm_rate=k, doppler_centroid=f_dc, receiver=rec.name, tau_c=tau_c, eta_c=np.nan,
                               peak_to_background=peak_to_background, p0=p0, aperture=aperture,
                               tau_trace=tau_c, fm_rate_candidates=tuple(candidates), slope_limited=limited,
                               search=search)
        if not est.focusable:
            break
        try:
            tried.append(locate(rec, est, sharpen=True))
        except EstimationError:
            if len(lines) == 1:
                raise
    if tried:
        est = max(tried, key=lambda e: e.extent.peak_db)
        if len(lines) > 1:
            log.info("receiver %s: Radon lines at f_dc %s Hz; kept %.5g Hz (focus %s dB over the median)", rec.name,
                     ", ".join(f"{f:.5g}" for f, _, _ in lines), est.doppler_centroid,
                     ", ".join(f"{e.extent.peak_db:.1f}" for e in tried))
    elif est.focusable:
        raise EstimationError(f"receiver {rec.name}: the target's trace lies outside the record at every Radon line "
                              f"(f_dc {', '.join(f'{f:.5g}' for f, _, _ in lines)} Hz)")
    log.info("receiver %s: K = %.5g Hz/s, f_dc = %.5g Hz, tau_c = %.6f s, eta_c = %.4g s, SoWVD score %.1f dB "
             "(next candidate %.1f dB lower)%s", rec.name, k, est.doppler_centroid, est.tau_c, est.eta_c,
             20 * np.log10(peak_to_background), margin_db,
             "; the Radon slope is at its search's edge" if est.slope_limited else "")
    return est


def estimate_receiver(echo: EchoData, receiver: str, *, p0: float = P0,
                      threshold_db: float = THRESHOLD_DB, focus_db: float | None = FOCUS_DB) -> ReceiverEstimate:
    """K_a,eq and f_dc,eq of the strongest moving target in ``receiver``'s echo (section III for a
    transceiver, IV for a receiver or sonobuoy), with no knowledge of its motion.

    Parameters
    ----------
    echo : raw EchoData (not range-compressed) holding ``receiver``.
    receiver : the receiver's name (e.g. "A", "B", "C").
    p0 : the first lag offset of the modified SoWVD, s (eq. 12), rounded to whole pulses (the
        others are :data:`.sowvd.P0_RATIOS` times it); K must satisfy |K| < PRF / (8 p0)
        (see :mod:`.sowvd`).
    threshold_db : SoWVD score (the maps' peak over their median, averaged over the maps, dB)
        below which the rate search's best candidate needs the focus to confirm it.
    focus_db : the focused image's peak over its median, dB, that confirms a candidate below
        ``threshold_db`` (:data:`FOCUS_DB`); below both, or with ``focus_db=None`` below
        ``threshold_db``, :class:`clsas.errors.EstimationError` is raised naming the receiver and
        the figures.
    """
    return estimate_records(records(echo, receiver), p0, threshold_db, focus_db)
