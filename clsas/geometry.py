"""Exact two-way delays, meeting times and element gains (NumPy, float64): the geometry shared by
echo synthesis (:mod:`clsas.synthesis`; a scenario's paths: :mod:`clsas.synthesis.paths`) and
imaging (:mod:`clsas.image`); its kernel twin is ``kernels/geometry.h``.

Delay (docs/design.md, non-stop-and-go). A pulse is emitted at slow time ``eta`` from the
transmitter at T = T(eta). Scatterer n moves, Q(t) = p0 + v t. The outgoing wave meets it
at ``eta + t1`` where

    c t1 = | Q(eta + t1) - T |                                            (1a)

and the echo reaches receiver h at ``eta + t1 + t2`` where

    c t2 = | R_h(eta + t1 + t2) - Q(eta + t1) |                           (1b)

(the receiver moves while the echo travels). Both are solved by fixed-point iteration,
``t <- |...(t)| / c``, a contraction with ratio |speed| / c (~2e-3); the iteration stops when
an update is below ``1e-9 / f0`` (1e-9 of a carrier period), so the remaining error is
below 1e-11 of a period. The two-way delay is ``tau = t1 + t2``. For a straight track and a
stationary target this is Zhang et al. 2019 eq. (1) (checked by the tests):

    tau_i = [b + sqrt(b^2 + (c^2 - v^2)(2 v t d_i + d_i^2))] / (c^2 - v^2),
    b = v (v t + d_i) + c sqrt(v^2 t^2 + r^2),

obtained by squaring (c tau - c t1)^2 = r^2 + (v t + d_i + v tau)^2 with c t1 = sqrt(r^2 + v^2 t^2).
``stop_and_go=True`` freezes everything at ``eta``: t1 = |Q(eta) - T| / c, t2 = |R_h(eta) - Q(eta)| / c.

Amplitude of the path (Kiang & Kiang 2022 signal model; Heremans et al. 2009 eq. 33):

    a = reflectivity * sinc(L_tx sin(theta_tx) / lambda) * sinc(L_h sin(theta_h) / lambda)
        [* 1 / (R1 R2) with spreading]

with ``sinc(x) = sin(pi x)/(pi x)``, lambda = c / f0 and theta the angle off broadside: sin(theta)
is the component, along the element's axis (body y at the emission / reception time), of the
unit vector from the element to the scatterer. Heremans eq. (33) gives the transmit pattern
in the Doppler domain as D sinc(D k_u / 2 pi) (its integrand lost the ``l`` of exp(i k_u l)
in the extraction); with k_u = k sin(theta) = 2 pi sin(theta) / lambda this is
D sinc(D sin(theta) / lambda), normalised here to 1 at broadside. The same law holds on receive.
R1 = c t1 and R2 = c t2 are the path lengths.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .cstruct import record_dtype

if TYPE_CHECKING:
    from .model import EchoData

MAX_ITERATIONS = 60
# a receiver's position and element axis at one node (kernels/geometry.h ``node_t``), m and unit vector
NODE = record_dtype([("pos", "f8", 3), ("axis", "f8", 3)])


def iteration_tolerance(f0: float) -> float:
    """Stop the fixed point when an update is below 1e-9 of a carrier period, s (the issue asks for
    1e-6; the stricter stop keeps the reference well inside the 1e-9 agreement of double kernels)."""
    return 1e-9 / f0


def _fixed_point(update, t, tol: float, what: str):
    for _ in range(MAX_ITERATIONS):
        new = update(t)
        if np.max(np.abs(new - t), initial=0.0) < tol:
            return new
        t = new
    raise RuntimeError(f"{what}: the delay fixed point did not converge in {MAX_ITERATIONS} iterations "
                       "(a speed close to the sound speed?)")


def outgoing(tx: np.ndarray, eta: np.ndarray, p0: np.ndarray, vel: np.ndarray, c: float, tol: float,
             stop_and_go: bool):
    """t1 (P, N) s and the scatterer positions Q (P, N, 3) at the scattering times (eq. 1a).

    ``tx`` (P, 3) transmitter at emission, ``eta`` (P,) emission times, ``p0`` (N, 3) m the
    scatterers at t = 0 and ``vel`` (N, 3) m/s their velocities (or both (P, N, 3): each
    pulse's own N scatterers).
    """
    p0, vel = _per_pulse(p0), _per_pulse(vel)
    q_emit = p0 + vel * eta[:, None, None]
    t1 = np.linalg.norm(q_emit - tx[:, None, :], axis=-1) / c
    if stop_and_go:
        return t1, q_emit
    t1 = _fixed_point(lambda t: np.linalg.norm(q_emit + vel * t[..., None] - tx[:, None, :], axis=-1) / c,
                      t1, tol, "outgoing path")
    return t1, q_emit + vel * t1[..., None]


def _per_pulse(points: np.ndarray) -> np.ndarray:
    """Points (N, 3) shared by every pulse as (1, N, 3); each pulse's own (P, N, 3) as they are."""
    return points if points.ndim == 3 else points[None]


def incoming(receiver, eta: np.ndarray, t1: np.ndarray, q: np.ndarray, c: float, tol: float, stop_and_go: bool):
    """t2 (P, N) s and the receiver positions (P, N, 3) at reception (eq. 1b).

    ``receiver(t)`` gives the receiver's position at absolute times ``t`` (any shape + (3,)).
    """
    if stop_and_go:
        r = np.broadcast_to(receiver(eta)[:, None, :], q.shape)
        return np.linalg.norm(r - q, axis=-1) / c, r
    t_scatter = eta[:, None] + t1
    t2 = np.linalg.norm(receiver(t_scatter) - q, axis=-1) / c
    t2 = _fixed_point(lambda t: np.linalg.norm(receiver(t_scatter + t) - q, axis=-1) / c, t2, tol, "incoming path")
    return t2, receiver(t_scatter + t2)


def meet_time(d: np.ndarray, w: np.ndarray, c: float, axis: int = -1) -> np.ndarray:
    """Closed form of the fixed points above for uniform motion: the t > 0 with |d + w t| = c t.

    (c^2 - |w|^2) t^2 - 2 (d.w) t - |d|^2 = 0 has the positive root
    t = [d.w + sqrt((d.w)^2 + (c^2 - |w|^2) |d|^2)] / (c^2 - |w|^2) (no cancellation: |d.w| << c |d|).
    ``d`` and ``w`` broadcast, their 3 components along ``axis`` (..., 3 by default; 0 for
    components-first arrays); the result has that axis removed and ``d``'s dtype. The OpenCL
    kernels use the same formula (kernels/geometry.h).
    """
    d, w = np.moveaxis(d, axis, 0), np.moveaxis(w, axis, 0)
    a = c * c - (w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    b = d[0] * w[0]
    b += d[1] * w[1]
    b += d[2] * w[2]
    dd = d[0] * d[0]
    dd += d[1] * d[1]
    dd += d[2] * d[2]
    dd *= a
    dd += b * b
    np.sqrt(dd, out=dd)
    dd += b
    dd /= a
    return dd


def element_gain(length: float, direction: np.ndarray, axis: np.ndarray, wavelength: float) -> np.ndarray:
    """sinc(L sin(theta) / lambda): ``direction`` unit vectors element -> scatterer, ``axis`` the element axis."""
    if length == 0:
        return np.ones(direction.shape[:-1])
    sin_theta = np.sum(direction * axis, axis=-1)
    return np.sinc(length * sin_theta / wavelength)


def two_node_velocity(echo: EchoData, h: int, pulses: np.ndarray) -> np.ndarray:
    """(len(pulses), 3) m/s: the uniform velocity of receiver h of ``echo``, which has two position nodes."""
    pos = echo.rx_pos[h][pulses]
    return (pos[:, 1] - pos[:, 0]) / (echo.rx_tau[h][1] - echo.rx_tau[h][0])


def uniform_nodes(echo: EchoData, h: int) -> tuple[float, np.ndarray]:
    """Receiver h's position nodes as the kernels read them (kernels/geometry.h, ``node_field``):
    their spacing dtau (s) and the positions (n_pulses, n_nodes >= 2, 3) m; a single node is
    repeated (a receiver at rest during reception). ValueError unless the nodes are uniformly
    spaced from fast time 0 (as clsas.simulate makes them)."""
    nodes = echo.rx_tau[h]
    if nodes.size == 1:
        return 1.0, np.repeat(echo.rx_pos[h], 2, axis=1)
    step = nodes[1] - nodes[0]
    if nodes[0] != 0 or not np.allclose(np.diff(nodes), step, rtol=1e-9, atol=0):
        raise ValueError("the OpenCL back-projection needs receiver nodes (EchoData.rx_tau) uniformly spaced "
                         "from 0 (as clsas.simulate makes them); use backend='numpy' for other node layouts")
    return step, echo.rx_pos[h]


def legs(echo: EchoData, h: int, pulses: np.ndarray, points: np.ndarray, velocity: np.ndarray,
         stop_and_go: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The exact legs from the transmitter of ``echo``'s ``pulses`` to the M ``points`` (m, at
    t = 0, all moving at ``velocity`` m/s; (M, 3) for every pulse, or (len(pulses), M, 3) each
    pulse's own) and back to receiver h (float64): t1 (len(pulses), M) s,
    where the pulses meet the points q (len(pulses), M, 3) m, t2 (len(pulses), M) s and the
    receiver at reception (len(pulses), M, 3) m. The two-way delay is t1 + t2. With a receiver of
    two nodes (uniform motion) both legs are :func:`meet_time`'s closed form, else the fixed
    points of :func:`outgoing` and :func:`incoming` (the receiver linear between its nodes)."""
    c = echo.medium.sound_speed
    eta = echo.eta[pulses]
    if not stop_and_go and echo.rx_tau[h].size == 2:
        # the target and a two-node receiver move uniformly: both fixed points in closed form
        tx = echo.tx_pos[pulses]
        q_emit = _per_pulse(points) + velocity * eta[:, None, None]
        t1 = meet_time(q_emit - tx[:, None, :], velocity, c)
        q = q_emit + velocity * t1[..., None]
        v_r = two_node_velocity(echo, h, pulses)[:, None, :]
        r_scatter = echo.rx_position(h, t1, pulses=pulses)  # the receiver when the pulse meets the point
        t2 = meet_time(r_scatter - q, v_r, c)
        return t1, q, t2, r_scatter + v_r * t2[..., None]
    tol = iteration_tolerance(echo.waveform.f0)
    t1, q = outgoing(echo.tx_pos[pulses], eta, points, np.broadcast_to(velocity, points.shape), c, tol, stop_and_go)

    def receiver(t):
        return echo.rx_position(h, t - eta.reshape((-1,) + (1,) * (t.ndim - 1)), pulses=pulses)

    t2, r = incoming(receiver, eta, t1, q, c, tol, stop_and_go)
    return t1, q, t2, r
