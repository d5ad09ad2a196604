"""Step 5 of the moving-target chain (:mod:`.chain`): a receiver's target focused in the window
about its trace with a K_a,eq and f_dc,eq, and measured there (:func:`locate`: its extent, tau_c,
eta_c); and the two readings of that focus that confirm a rate below the SoWVD's threshold
(:func:`sharpness`) or refine it (:func:`focused_rate`). ``est`` is a receiver's estimate,
:class:`.chain.ReceiverEstimate` (its K_a,eq, f_dc,eq, tau_c, aperture).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...errors import EstimationError
from ...kernelmath import unit_phasor
from .azimuth import compress, focus_bins, sharpened_bins, sharpened_window
from .doppler import Doppler
from .extent import extent, peak_db
from .records import Records, without_wrapped_band
from .sharpen import aperture_time, fm_rate_correction

#: Focus steps (4 / T_a^2 each) off the candidate K at which :func:`sharpness` refocuses.
SHARP_STEPS = 3.0
#: An azimuth chirp with time-bandwidth product |K| T_a^2 below this has nothing to compress
#: (the target keeps its range to the receiver: Table II case 7 at A and B).
MIN_TIME_BANDWIDTH = 4.0
#: Half-width of the focused window searched for the target's extent, s of two-way delay
#: (+-12 m of range at 1500 m/s: the scaled Albacore is 10.35 m long).
EXTENT_WINDOW = 0.016


def locate(rec: Records, est: Doppler, higher_order: np.ndarray | None = None,
           reference: Doppler | None = None, sharpen: bool = False) -> Doppler:
    """``est`` with tau_c, eta_c and extent measured in the focused image of ``rec`` within
    :data:`EXTENT_WINDOW` of est.tau_c (:mod:`.extent`): focused with est's K_a,eq and f_dc,eq, and
    with ``higher_order`` (n_pulses,) s, the delay's terms beyond the quadratic, when given
    (:func:`.closedforms.higher_order_delay` of a first velocity estimate: they blur and skew
    the image over long apertures), and with ``reference``'s K_a,eq and f_dc,eq instead of est's
    when given (the model's Taylor coefficients that go with ``higher_order``: over 80 s the
    SoWVD reads 4-7 % above them, its line's band spread by the higher-order terms
    (:mod:`.sowvd`), and would count them twice). K_a,eq and f_dc,eq are kept; eta_c is where the target focuses with them,
    f~ - K~ eta_c being its centroid.

    ``sharpen``: the image is :func:`.azimuth.sharpened_bins`' (the residual phase and its range
    migration found by sharpness and removed; both vanish at eta_ref, so the target stays at its
    delay there). :func:`.chain.estimate_records` sharpens: its focus is quadratic only, and over long
    apertures the delay's cubic and quartic terms, which the SoWVD's aperture-averaged K~ does
    not hold, leave the focused target smeared in range to one side, which moves the middle of
    its extent (over Table I's 80 s at receiver B: tau_c several samples and eta_c tenths of a
    second off with the quadratic focus, not with the sharpened one). The refocus passes of
    :func:`.motion.estimate` give the model's higher-order terms instead."""
    if not est.focusable:
        raise EstimationError(f"receiver {rec.name}: cannot locate a target that does not focus "
                              f"(|K_a,eq| T_a^2 = {abs(est.fm_rate) * est.aperture**2:.3g} < {MIN_TIME_BANDWIDTH})")
    ref = est if reference is None else reference
    rec, bins = _window(rec, est, ref)
    if sharpen:
        image, eta_axis, _ = sharpened_bins(rec, ref.fm_rate, ref.doppler_centroid, bins, higher_order)
    else:
        image, eta_axis = focus_bins(rec, ref.fm_rate, ref.doppler_centroid, bins, higher_order)
    tau_axis = rec.t0 + np.arange(bins.start, bins.stop) / rec.fs
    ext = extent(image, eta_axis, tau_axis, 1.0 / (abs(ref.fm_rate) * est.aperture), 1.0 / rec.bandwidth)
    # the centre's centroid f_ref - K_ref (eta_mid - eta_ref), as the eta_c of est's f~ and K~
    eta_c = rec.eta_ref + (est.doppler_centroid - ref.doppler_centroid
                           + ref.fm_rate * (ext.eta_mid - rec.eta_ref)) / est.fm_rate
    return dataclasses.replace(est, tau_c=ext.tau_mid, eta_c=eta_c, extent=ext)


def _window(rec: Records, est: Doppler, reference: Doppler | None = None) -> tuple[Records, slice]:
    """(``rec`` without the band that wraps round at the reference's f_dc and K
    (:func:`.records.without_wrapped_band`; ``reference`` defaults to ``est``), the range bins
    within :data:`EXTENT_WINDOW` of est.tau_c); EstimationError when they lie outside the record."""
    k0 = (est.tau_c - rec.t0) * rec.fs
    half = EXTENT_WINDOW * rec.fs
    n = rec.x.shape[1]
    if not (np.isfinite(k0) and -half < k0 < n + half):
        raise EstimationError(f"receiver {rec.name}: the target's trace lies outside the record (tau_c = "
                              f"{est.tau_c:.6g} s; K_a,eq = {est.fm_rate:.4g} Hz/s may be wrong)")
    lo = int(np.clip(np.floor(k0 - half), 0, n - 2))
    bins = slice(lo, int(np.clip(np.ceil(k0 + half) + 1, lo + 2, n)))
    ref = est if reference is None else reference
    return without_wrapped_band(rec, ref.doppler_centroid, ref.fm_rate), bins


def focused_rate(rec: Records, est: Doppler) -> float:
    """The azimuth FM rate (Hz/s) at which ``rec``'s window about est's target focuses sharpest:
    est's K plus the rate correction of the sharpening's quadratic (:func:`.azimuth.sharpened_window`; its
    Legendre P2 part p2 + 6/7 p4 cycles at the aperture's ends, :func:`.sharpen.fm_rate_correction`),
    which :mod:`.sharpen` searches over +-3 % of K with the cubic and quartic terms beside it."""
    rec, bins = _window(rec, est)
    _, _, (p2, _, p4), _ = sharpened_window(rec, est.fm_rate, est.doppler_centroid, bins)
    return est.fm_rate + fm_rate_correction(rec.eta, p2 + 6.0 / 7.0 * p4)


def sharpness(rec: Records, est: Doppler) -> tuple[float, tuple[float, float]]:
    """(peak over median of ``rec`` focused with est's K and f_dc, dB; the same window compressed
    with K -+ :data:`SHARP_STEPS` focus steps 4 / T_a^2). A focus step is the rate error that
    leaves one cycle of quadratic phase at the aperture's ends (pi dK (T_a / 2)^2 = pi): a
    focused target's peak falls well below its own three steps away, while a bright feature
    that the rate does not focus (clutter, a stationary highlight, the noise's largest value)
    stays as bright (review M6: the image's peak over its median alone confirms brightness,
    not focus).

    The window is the sharpened one (:func:`.azimuth.sharpened_window`) with the sharpening's own rate
    correction taken out again: on the Legendre basis of :mod:`.sharpen` its P3 and P4 parts
    (the delay's cubic and quartic terms) stay removed, its P2 part is undone, so the check is of
    est's K (which, like the SoWVD's, is the aperture's average rate), and only the compression
    rate is detuned. With the quadratic focus alone the check could not tell focus over long
    apertures: the cubic and quartic terms blur a point more than three focus steps do, and a
    right K read as "not sharp" (tests/test_moving_noise.py::test_sharpness_holds_the_higher_order_terms
    has the figures)."""
    rec, bins = _window(rec, est)
    _, _, (p2, _, p4), win = sharpened_window(rec, est.fm_rate, est.doppler_centroid, bins)
    # the sharpening's own rate correction (its Legendre P2 part, p2 + 6/7 p4 in u^2) put back:
    # the check is of est's K, not of the rate the sharpening would have chosen
    win = win * unit_phasor(-2 * np.pi * (p2 + 6.0 / 7.0 * p4) * aperture_time(rec.eta, rec.eta_ref) ** 2)[:, None]
    step = SHARP_STEPS * 4.0 / est.aperture**2
    at, below, above = (peak_db(compress(rec, win, est.fm_rate + s)[0]) for s in (0.0, -step, step))
    return at, (below, above)
