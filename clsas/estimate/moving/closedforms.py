"""Closed forms of a moving point target's Doppler parameters at each receiver (Kiang & Kiang 2022,
eqs. 1-6, 15-16, 21-26, 28, 32-35): the "true" values the estimators are held to.

Model. A pulse leaves the transmitter T(eta) = T_0 + V_T eta, meets the target Q(t) = q + v t
at eta + t1 and reaches receiver h, R_h(t) = R_0 + V_h t, at eta + t1 + t2 (non-stop-and-go,
docs/design.md; times relative to the reference slow time eta_ref). The two-way delay
tau(eta) = t1 + t2 expands as

    tau(eta) = tau_c + (f_dc,eq / f0) eta + (K_a,eq / (2 f0)) eta^2 + ...,

so the echo's carrier phase -2 pi f0 tau(eta) has the Doppler centroid f_dc,eq = f0 tau'(0)
and the azimuth FM rate K_a,eq = f0 tau''(0) (eqs. 15-16 and 26-28: the mean of the one-way
"forward" and "backward" terms, f_dc,eq = (f' + f'')/2 with f' = (2 f0 / c) dR'/deta).
A positive f_dc,eq is a growing delay (the range-walk line tau - (f_dc,eq / f0) eta = tau_c
of eq. 17).

``model="exact"`` (default): the exact Taylor coefficients of the non-stop-and-go delay for
uniform motion, derived here (the paper does not give them). With the leg vectors
D1 = Q(eta + t1) - T(eta), D2 = R_h(eta + t1 + t2) - Q(eta + t1), |D_i| = c t_i, unit vectors
u_i = D_i / |D_i|, differentiate c t1 = |D1| and c t2 = |D2| once and twice:

    t1'  = u1.(v - V_T) / (c - u1.v)
    t2'  = (1 + t1') u2.(V_h - v) / (c - u2.V_h)
    a    = v (1 + t1') - V_T,        b = V_h (1 + t1' + t2') - v (1 + t1')   (dD1/deta, dD2/deta)
    t1'' = (|a|^2 - (u1.a)^2) / (|D1| (c - u1.v))
    t2'' = [(|b|^2 - (u2.b)^2) / |D2| + t1'' u2.(V_h - v)] / (c - u2.V_h)

with t1, t2 from :func:`clsas.geometry.meet_time` (the closed-form leg times). These
agree with a polynomial fit of the simulator's exact delays to ~1e-6 (tests/test_moving.py).

``model="paper"``: eqs. 3-6, 22-25 and 32 as printed, generalised to any receiver R_h: the
scatterer is taken at eta + R10/c (R10 = |q - T_0|, the stop-and-go range), receiver h at
eta + R10/c + Rh0/c (Rh0 = |q - R_0|; eq. 4 for A, eq. 22 for B, eq. 32 for C), and

    f' = 2 f0 D'.(v - V_T) / (c |D'|),   f'' = 2 f0 D''.(v - V_h) / (c |D''|)        (eqs. 3, 4, 23, 32)
    K' = 2 f0 |v - V_T|^2 / (c |D'|),     K'' = 2 f0 |v - V_h|^2 / (c |D''|)          (eqs. 5, 6, 25)

Two discrepancies, both documented by the tests:

- eqs. 5, 6 and 25 drop the radial term: the curvature of |D + w eta| is
  (|w|^2 - (u.w)^2) / |D|, not |w|^2 / |D|. They hold only when the line of sight is square to
  the relative velocity w (case 1 at A). At B in case 1 the exact K_a2,eq is 4.817 Hz/s against
  the printed 4.863 (eq. 25 gives 4.853); in case 8 (w along the line of sight) eq. 5 is twice
  the true rate. The printed eqs. are kept as ``model="paper"`` to reproduce the printed values.
- the paper's case-1 rates are 0.19 % above what its stated geometry gives (K_a1 4.870 against
  the printed 4.879, with either model); its centroid f_dc1 = 6.533 Hz is reproduced to the
  printed digits. The printed tau_c1 = 2.677 s (range 2008 m) against 2.683 s here suggests the
  paper's ranges were rounded to about 2008 m.

Table II lists f_dc,eq per case after estimation (case 1: 6.355 Hz, the text's truth 6.533 Hz):
the paper's tables are estimates, the closed forms here are the truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import validate
from ...geometry import meet_time
from .doppler import Doppler
from .layout import Layout, layout_of

MODELS = ("exact", "paper")


@dataclass(frozen=True)
class Predicted(Doppler):
    """Closed-form Doppler parameters at one receiver, with where the target focuses.

    tau_c: two-way delay at the reference slow time (s) -- the range line after RCMC and RWC
    (eqs. 17, 20: tau = (R'_10 + R''_10) / c); eta_c: the reference slow time (s), where azimuth
    compression focuses the target when f_dc,eq is exact (eq. 20: sinc(B_a eta)).
    """

    tau_c: float = float("nan")
    eta_c: float = 0.0


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _vector(name: str, value) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim < 1 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (3,) (or (..., 3)), m or m/s; got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return arr


def delay_terms(layout: Layout, receiver: str, position, velocity, model: str = "exact"):
    """(tau_c, f_dc,eq, K_a,eq) at ``receiver`` for targets at ``position`` (at slow time 0) moving
    with ``velocity``; both (..., 3) and broadcast, results of the broadcast shape (s, Hz, Hz/s).
    The vectorised core of :func:`closed_forms` (the velocity solver evaluates it on grids)."""
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    c, f0 = layout.sound_speed, layout.f0
    p = _vector("position", position)
    v = _vector("velocity", velocity)
    rx, v_rx = layout.receiver(receiver)
    tx, v_tx = layout.tx_position, layout.tx_velocity
    q = p + v * layout.eta_ref  # the target at the reference slow time
    if model == "paper":
        dt1 = np.linalg.norm(q - tx, axis=-1)[..., None] / c  # R10 / c
        dth = np.linalg.norm(q - rx, axis=-1)[..., None] / c  # Rh0 / c
        d1 = q + v * dt1 - tx
        d2 = q + v * dt1 - (rx + v_rx * (dt1 + dth))
        r1, r2 = np.linalg.norm(d1, axis=-1), np.linalg.norm(d2, axis=-1)
        w1, w2 = v - v_tx, v - v_rx
        f1, f2 = 2 * f0 * _dot(d1, w1) / (c * r1), 2 * f0 * _dot(d2, w2) / (c * r2)
        k1, k2 = 2 * f0 * _dot(w1, w1) / (c * r1), 2 * f0 * _dot(w2, w2) / (c * r2)
        return (r1 + r2) / c, 0.5 * (f1 + f2), 0.5 * (k1 + k2)
    v, q = np.broadcast_arrays(v, q)
    shape = v.shape[:-1]
    v, q = v.reshape(-1, 3), q.reshape(-1, 3)  # meet_time works in place on arrays
    t1 = meet_time(q - tx, v, c)
    d1 = q - tx + v * t1[..., None]  # transmitter -> scatterer
    scatter = q + v * t1[..., None]
    t2 = meet_time(rx + v_rx * t1[..., None] - scatter, np.broadcast_to(v_rx, v.shape), c)
    d2 = rx + v_rx * (t1 + t2)[..., None] - scatter  # scatterer -> receiver
    r1, r2 = c * t1, c * t2
    u1, u2 = d1 / r1[..., None], d2 / r2[..., None]
    den1, den2 = c - _dot(u1, v), c - _dot(u2, v_rx)
    t1p = _dot(u1, v - v_tx) / den1
    t2p = (1 + t1p) * _dot(u2, v_rx - v) / den2
    a = v * (1 + t1p)[..., None] - v_tx
    b = v_rx * (1 + t1p + t2p)[..., None] - v * (1 + t1p)[..., None]
    t1pp = (_dot(a, a) - _dot(u1, a) ** 2) / (r1 * den1)
    t2pp = ((_dot(b, b) - _dot(u2, b) ** 2) / r2 + t1pp * _dot(u2, v_rx - v)) / den2
    return (t1 + t2).reshape(shape), (f0 * (t1p + t2p)).reshape(shape), (f0 * (t1pp + t2pp)).reshape(shape)


def delay_history(layout: Layout, receiver: str, position, velocity, eta) -> np.ndarray:
    """The exact non-stop-and-go two-way delay tau(eta) (s) at ``receiver`` of the point at
    ``position`` (slow time 0) moving with ``velocity``, for emissions at slow times ``eta`` (s,
    any shape; the result has its shape): the model whose Taylor coefficients at eta_ref are
    :func:`delay_terms` (module docstring), evaluated in full."""
    p = validate.vector3("delay_history position", position)
    v = validate.vector3("delay_history velocity", velocity, bound=validate.MAX_SPEED)
    times = validate.array("delay_history eta", np.ravel(eta), (-1,), bound=validate.MAX_TIME)
    c = layout.sound_speed
    rx, v_rx = layout.receiver(receiver)
    dt = times[:, None] - layout.eta_ref
    tx = layout.tx_position + layout.tx_velocity * dt
    q = p + v * (dt + layout.eta_ref)
    t1 = meet_time(q - tx, np.broadcast_to(v, q.shape), c)
    scatter = q + v * t1[..., None]
    t2 = meet_time(rx + v_rx * (dt + t1[..., None]) - scatter, np.broadcast_to(v_rx, q.shape), c)
    return (t1 + t2).reshape(np.shape(eta))


def higher_order_delay(layout: Layout, receiver: str, position, velocity, eta) -> np.ndarray:
    """The terms of :func:`delay_history` beyond its quadratic Taylor polynomial at eta_ref,
    tau(eta) - (tau_c + (f_dc,eq / f0) d + (K_a,eq / (2 f0)) d^2) with d = eta - eta_ref (s, the
    shape of ``eta``): what a focus with K_a,eq and f_dc,eq leaves uncompensated (cubic and
    higher; ~10 carrier cycles at the ends of 25 s in Table II case 6)."""
    tau = delay_history(layout, receiver, position, velocity, eta)
    tau_c, f_dc, k = delay_terms(layout, receiver, position, velocity)
    d = np.asarray(eta, dtype=np.float64) - layout.eta_ref
    return tau - (tau_c + (f_dc / layout.f0) * d + (k / (2 * layout.f0)) * d * d)


def closed_forms(scenario, position, velocity, receivers=None, model: str = "exact",
                 eta_ref: float | None = None) -> dict:
    """The true K_a,eq, f_dc,eq, tau_c and eta_c of a point target at every receiver.

    Parameters
    ----------
    scenario : Scenario, EchoData or :class:`~clsas.estimate.moving.layout.Layout`
        The geometry (transmitter and receivers, found by name; any number of receivers).
    position : (3,) m, the target at slow time 0 (e.g. (1989, 0, -350) in the paper), within
        +-:data:`clsas.validate.MAX_COORDINATE`.
    velocity : (3,) m/s, within +-:data:`clsas.validate.MAX_SPEED` (the delay model needs speeds
        far below the sound speed).
    receivers : names to evaluate (default: all of the scenario's).
    model : "exact" (default) or "paper" (the printed eqs.; see the module docstring).
    eta_ref : reference slow time, s (default: the middle of the exposure, 0 for the paper; a
        Layout's own unless given).

    Returns
    -------
    dict name -> :class:`Predicted` (fm_rate Hz/s, doppler_centroid Hz, tau_c s, eta_c s).
    """
    validate.choice("closed_forms model", model, MODELS)
    position = validate.vector3("closed_forms position", position)
    velocity = validate.vector3("closed_forms velocity", velocity, bound=validate.MAX_SPEED)
    if eta_ref is not None:
        eta_ref = validate.scalar("closed_forms eta_ref", eta_ref, low=-validate.MAX_TIME, high=validate.MAX_TIME,
                                  unit="s")
    layout = layout_of(scenario, eta_ref)
    names = layout.names if receivers is None else tuple(receivers)
    out = {}
    for name in names:
        tau, fdc, k = delay_terms(layout, name, position, velocity, model)
        out[name] = Predicted(fm_rate=float(k), doppler_centroid=float(fdc), tau_c=float(tau),
                              eta_c=float(layout.eta_ref))
    return out


def aperture_fm_rate(layout: Layout, receiver: str, position, velocity, eta) -> float:
    """The FM rate the SoWVD measures: 2 f0 c2 (Hz/s) of the least-squares parabola
    tau ~ c0 + c1 d + c2 d^2 (d = eta - eta_ref) through :func:`delay_history` over the slow
    times ``eta`` (s, (n_pulses,)): the rate averaged over the aperture, not the Taylor K_a,eq
    at eta_ref (they part over long apertures, where the quartic term grows; the test
    ``test_rate_search_reads_the_aperture_average`` measures both against the chain)."""
    eta = np.asarray(eta, dtype=np.float64).ravel()
    d = eta - layout.eta_ref
    tau = delay_history(layout, receiver, position, velocity, eta)
    scale = max(float(np.max(np.abs(d))), 1e-12)
    c2 = np.polynomial.polynomial.polyfit(d / scale, tau - tau[tau.size // 2], 2)[2] / scale**2
    return float(2.0 * layout.f0 * c2)
