"""The propagation paths of a scenario: exact delays, amplitudes and in-pulse laws of every
(receiver, pulse, scatterer) path, direct or bouncing (the float64 reference the echo kernel,
kernels/echo_paths.cl ``echo_paths``, is held to).

Delay and amplitude laws: :mod:`clsas.geometry` (docs/design.md, non-stop-and-go). A path that
bounces is the direct path between an image transmitter and image receivers
(:mod:`clsas.synthesis.propagation`), times the reflection coefficients at its grazing angles.

Intra-pulse Doppler. The pulse leaves the transmitter over T seconds while everything moves:
the wavelet emitted u seconds after the pulse centre (from T(eta + u)) arrives after its own
two-way delay D(u) = t1(u) + t2(u), with

    c t1 = |Q(eta + u + t1) - T(eta + u)|,   c t2 = |R(eta + s + t2) - Q(eta + s)|,  s = u + t1.

For uniform motion over the pulse (transmitter velocity V_T, scatterer V_Q, receiver V_R) each
leg is a meeting time |D + A x + W t| = c t (leg 1: x = u, A = V_Q - V_T, W = V_Q; leg 2:
x = s, A = V_R - V_Q, W = V_R); implicit differentiation of F = |r|^2 - c^2 t^2 = 0, r = D + A
x + W t, gives at x = 0

    t' = -(r.A) / (r.W - c^2 t),   t'' = -(|A|^2 + 2 (A.W) t' + (|W|^2 - c^2) t'^2) / (r.W - c^2 t),

and D1 = D'(0) = t1' + t2_s (1 + t1'), 2 D2 = D''(0) = t1'' + t2_ss (1 + t1')^2 + t2_s t1''
(chain rule through s(u) = u + t1(u)). With D(u) = D0 + D1 u + D2 u^2 the sample at fast time
tau receives the wavelet u(tau) solving u + D(u) = tau; with eps = tau - D0 and s = 1 / (1 + D1),
u = s eps - D2 s^3 eps^2 + O(eps^3), and the baseband sample is

    a rect(u / T) exp(j pi K u^2) exp(-j 2 pi f0 (tau - u))
      = a exp(-j 2 pi f0 D0) exp(j 2 pi [(K s^2 / 2 - f0 D2 s^3) eps^2 - f0 D1 s eps]) + O(eps^3)

(the terms of order eps^3, K D2 s^4 eps^3 and f0 D2^2 eps^3, are below 1e-3 cycles for speeds
under 10 m/s at 10 m and pulses under 20 ms), on the support
eps in [-T/2 (1 + D1) + D2 T^2 / 4, T/2 (1 + D1) + D2 T^2 / 4]: the echo is time-scaled
(chirp rate K s^2) and Doppler-shifted (-f0 D1 s). D1 = D2 = 0 gives the single-delay echo.
tests/test_propagation.py holds this against the exact solution of u + D(u) = tau, sample by
sample, with every position taken from the scenario's trajectories.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import element_gain, incoming, iteration_tolerance, outgoing
from ..scene.scenario import Scenario
from ..scene.targets import Scatterers
from .propagation import BOTTOM, DIRECT, SURFACE, BandAbsorption, PathKind, surface_log_coefficient

VELOCITY_STEP = 1e-3  # s: central differences of the trajectories for the velocities


@dataclass(frozen=True)
class Paths:
    """Every (receiver, pulse, scatterer) path of one kind, float64, each (H, P, N).

    tau : two-way delay D0, s. amp : complex amplitude (reflectivity, element patterns,
    spreading, reflection coefficients and absorption at f0; no carrier, no path weights).
    d1, d2 : the in-pulse delay law D(u) = D0 + d1 u + d2 u^2 (0 without intra-pulse Doppler).
    lnf1, lnf2 : the log-amplitude over the band, ln H(f0 + df) - ln H(f0) = lnf1 df + lnf2 df^2
    (Np per Hz, per Hz^2; absorption and surface roughness).
    """

    tau: np.ndarray
    amp: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    lnf1: np.ndarray
    lnf2: np.ndarray


def _velocity(position, t: np.ndarray) -> np.ndarray:
    """d/dt of ``position(t)`` (t.shape + (3,)) by central differences."""
    return (position(t + VELOCITY_STEP) - position(t - VELOCITY_STEP)) / (2 * VELOCITY_STEP)


def meet_derivatives(r: np.ndarray, t: np.ndarray, a: np.ndarray, w: np.ndarray, c: float):
    """(t', t'') of the meeting time of |D + A x + W t| = c t at x = 0 (module docstring), with
    r = D + W t the separation there; vectors (..., 3)."""
    ft = np.sum(r * w, axis=-1) - c * c * t
    t1 = -np.sum(r * a, axis=-1) / ft
    t2 = -(np.sum(a * a, axis=-1) + 2 * np.sum(a * w, axis=-1) * t1 + (np.sum(w * w, axis=-1) - c * c) * t1 * t1) / ft
    return t1, t2


def _bounces(planes, normals, direction, length, f0, c, amp, lnf1, lnf2):
    """Apply a leg's reflection coefficients (``planes`` and their unfolded ``normals``) in place."""
    for plane, n in zip(planes, normals):
        sin_g = np.abs(direction @ n) / length
        if plane.law == SURFACE:
            q = surface_log_coefficient(plane.rms_height, sin_g, c)
            amp *= -np.exp(-q * f0 * f0)
            lnf1 -= 2 * q * f0
            lnf2 -= q
        elif plane.law == BOTTOM:
            amp *= bottom_coefficient(plane, sin_g)


def bottom_coefficient(plane, sin_grazing) -> np.ndarray:
    """The seabed's reflection coefficient at sin(grazing) (any shape), complex."""
    return np.asarray(plane.coefficient(np.arcsin(np.clip(sin_grazing, 0.0, 1.0))), dtype=np.complex128)


def paths(scenario: Scenario, eta: np.ndarray, scat: Scatterers, receivers, kind: PathKind = DIRECT,
          stop_and_go: bool = False, spreading: bool = False, intra_pulse: str = "none",
          absorption: BandAbsorption | None = None) -> Paths:
    """Exact delays, amplitudes and in-pulse laws of every (receiver, pulse, scatterer) path of
    ``kind``.

    eta : (P,) emission times, s. scat : Scatterers (N). receivers : receiver indices (H).
    intra_pulse : "none", "moving" (scatterers with a velocity) or "all": which paths get their
    in-pulse delay law D1, D2 (module docstring; none with ``stop_and_go``).
    absorption : the band's absorption (None: no absorption).
    """
    c = scenario.medium.sound_speed
    f0 = scenario.waveform.f0
    wavelength = scenario.waveform.wavelength(scenario.medium)
    tol = iteration_tolerance(f0)
    eta = np.asarray(eta, dtype=np.float64)
    out_image, back_image = kind.out.image, kind.back.image
    tx = out_image.points(scenario.tx_position(eta))
    t1, q = outgoing(tx, eta, scat.p0, scat.vel, c, tol, stop_and_go)
    out_dir = q - tx[:, None, :]
    r1 = np.linalg.norm(out_dir, axis=-1)
    tx_axis = out_image.vectors(scenario.platform.rotation(eta)[..., :, 1])
    amp_tx = scat.refl[None, :] * element_gain(scenario.array.tx_length, out_dir / r1[..., None],
                                               tx_axis[:, None, :], wavelength)
    lnf1_tx, lnf2_tx = np.zeros_like(r1), np.zeros_like(r1)
    _bounces(kind.out.planes, kind.out.normals, out_dir, r1, f0, c, amp_tx, lnf1_tx, lnf2_tx)
    doppler = intra_pulse != "none" and not stop_and_go
    if doppler:
        v_tx = out_image.vectors(_velocity(scenario.tx_position, eta))
        t1d, t1dd = meet_derivatives(out_dir, t1, scat.vel[None] - v_tx[:, None, :], scat.vel[None], c)
    lengths = scenario.receiver_lengths
    out = {name: [] for name in ("tau", "amp", "d1", "d2", "lnf1", "lnf2")}
    for h in receivers:
        def position(t, h=h):
            return back_image.points(scenario.receiver_position(h, t))

        t2, r = incoming(position, eta, t1, q, c, tol, stop_and_go)
        back = q - r
        r2 = np.linalg.norm(back, axis=-1)
        t_rx = eta[:, None] + (0.0 if stop_and_go else t1 + t2)
        axis = back_image.vectors(scenario.receiver_axis(h, np.broadcast_to(t_rx, t2.shape)))
        amp = amp_tx * element_gain(lengths[h], back / r2[..., None], axis, wavelength)
        lnf1, lnf2 = lnf1_tx.copy(), lnf2_tx.copy()
        _bounces(kind.back.planes, kind.back.normals, back, r2, f0, c, amp, lnf1, lnf2)
        if spreading:
            amp = amp / (r1 * r2)
        tau = (r1 + r2) / c if stop_and_go else t1 + t2
        if absorption is not None:
            length = c * tau
            amp = amp * np.exp(-absorption.a0 * length)
            lnf1 = lnf1 - absorption.a1 * length
            lnf2 = lnf2 - absorption.a2 * length
        d1 = np.zeros_like(tau)
        d2 = np.zeros_like(tau)
        if doppler:
            v_rx = _velocity(position, t_rx)
            t2s, t2ss = meet_derivatives(-back, t2, v_rx - scat.vel[None], v_rx, c)
            sd = 1.0 + t1d
            d1 = t1d + t2s * sd
            d2 = 0.5 * (t1dd + t2ss * sd * sd + t2s * t1dd)
            if intra_pulse == "moving":
                still = ~np.any(scat.vel != 0, axis=1)[None, :]
                d1 = np.where(still, 0.0, d1)
                d2 = np.where(still, 0.0, d2)
        for name, value in (("tau", tau), ("amp", amp), ("d1", d1), ("d2", d2), ("lnf1", lnf1), ("lnf2", lnf2)):
            out[name].append(np.broadcast_to(value, tau.shape))
    return Paths(**{name: np.stack(values) for name, values in out.items()})


def direct_paths(scenario: Scenario, eta: np.ndarray, scat: Scatterers, receivers, stop_and_go: bool = False,
                 spreading: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Exact delays (s) and amplitudes of the direct paths, each (H, P, N): :func:`paths`'s
    ``tau`` and ``amp`` for the direct kind without absorption."""
    p = paths(scenario, eta, scat, receivers, DIRECT, stop_and_go, spreading)
    return p.tau, p.amp
