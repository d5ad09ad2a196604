"""One receiver's target focused on the tau-eta plane by the paper's chain (Kiang & Kiang 2022,
eqs. 17-20) with its estimate from :mod:`.chain`."""

from __future__ import annotations

import numpy as np

from ... import validate
from ...errors import EstimationError
from ...model import EchoData, Image
from .azimuth import focus_bins, sharpened_bins
from .chain import ReceiverEstimate
from .located import MIN_TIME_BANDWIDTH
from .records import UPSAMPLE, records, without_wrapped_band
from .doppler import Doppler
from .sharpen import fm_rate_correction


def focus_receiver(echo: EchoData, receiver: str, rx_estimate: ReceiverEstimate, *,
                   tau_span: float | None = None, higher_order: np.ndarray | None = None,
                   sharpen: bool = False) -> Image:
    """The target focused on the tau-eta plane from ``receiver``'s raw echo with ``rx_estimate``'s
    K_a,eq and f_dc,eq: RCMC, range-walk compensation and azimuth compression (eqs. 17-20), and
    the delay's terms beyond the quadratic, ``higher_order`` (n_pulses,) s, when given
    (:func:`.closedforms.higher_order_delay`: the quadratic focus leaves them, which blurs
    80 s apertures). ``sharpen``: the residual phase beyond those (what the estimate's errors
    leave) is found by image sharpness and removed (:func:`sharpened_bins`, :mod:`.sharpen`);
    the provenance then holds it ("residual_phase_cycles", (p2, p3, p4)) and the data's Taylor
    FM rate ("sharpened_fm_rate", Hz/s). The range band where an echo with intra-pulse Doppler
    wraps round the sampling rate is zeroed first (:func:`.records.wrapped_band`), as in the
    chain's own focus.

    Returns an Image with dims ("eta", "tau"): eta spans one period PRF / |K| centred on the
    focus (see :mod:`.filters`), tau the receiver's fast times (all of them, or ``tau_span``
    seconds centred on ``rx_estimate.tau_c``). Raises EstimationError when the estimate is not
    focusable (|K| T_a^2 too small: the target moves with the receiver).
    """
    if not isinstance(rx_estimate, Doppler):
        raise TypeError(f"rx_estimate must be a ReceiverEstimate, got {type(rx_estimate).__name__}")
    sharpen = validate.flag("focus_receiver sharpen", sharpen)
    if higher_order is not None:
        higher_order = validate.array("focus_receiver higher_order", higher_order, (echo.n_pulses,), bound=1.0,
                                      copy=False)
    # the band intra-pulse Doppler wraps round F_r zeroed, as the chain's locate does
    rec = without_wrapped_band(records(echo, receiver), rx_estimate.doppler_centroid, rx_estimate.fm_rate)
    aperture = float(np.ptp(rec.eta) + 1.0 / rec.prf)
    if abs(rx_estimate.fm_rate) * aperture**2 < MIN_TIME_BANDWIDTH:
        raise EstimationError(f"receiver {receiver}: cannot focus: |K_a,eq| T_a^2 = "
                              f"{abs(rx_estimate.fm_rate) * aperture**2:.3g} < {MIN_TIME_BANDWIDTH} "
                              "(the target keeps its range to this receiver)")
    n = rec.x.shape[1]
    bins = slice(0, n)
    if tau_span is not None:
        if not (np.isfinite(tau_span) and tau_span > 0):
            raise ValueError(f"tau_span must be a positive number of seconds, got {tau_span}")
        centre = (getattr(rx_estimate, "tau_c", np.nan) - rec.t0) * rec.fs
        if not np.isfinite(centre):
            raise ValueError("tau_span needs rx_estimate.tau_c")
        half = 0.5 * tau_span * rec.fs
        bins = slice(int(np.clip(np.floor(centre - half), 0, n - 1)), int(np.clip(np.ceil(centre + half) + 1, 1, n)))
    provenance = {"algorithm": "clsas.estimate.moving.focus_receiver", "receiver": receiver,
                  "fm_rate": float(rx_estimate.fm_rate), "doppler_centroid": float(rx_estimate.doppler_centroid),
                  "range_upsample": UPSAMPLE, "reference": "Kiang & Kiang 2022 eqs. 17-20"}
    if sharpen:
        image, eta_axis, p = sharpened_bins(rec, rx_estimate.fm_rate, rx_estimate.doppler_centroid, bins, higher_order)
        provenance.update(residual_phase_cycles=tuple(float(c) for c in p),
                          sharpened_fm_rate=float(rx_estimate.fm_rate + fm_rate_correction(rec.eta, p[0])))
    else:
        image, eta_axis = focus_bins(rec, rx_estimate.fm_rate, rx_estimate.doppler_centroid, bins, higher_order)
    tau = rec.t0 + np.arange(bins.start, bins.stop) / rec.fs
    return Image(image, ("eta", "tau"), {"eta": eta_axis, "tau": tau}, provenance=provenance)
