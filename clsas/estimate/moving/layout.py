"""The sonar's geometry as the moving-target estimators see it: one transmitter and named receivers
in uniform motion (Kiang & Kiang 2022, section II: transceiver A and towed receiver B move at
V_p along y, sonobuoy C is fixed).

A :class:`Layout` holds, at the reference slow time ``eta_ref``, the transmitter's position and
velocity and every receiver's position and velocity, fitted as straight lines (least squares)
to the positions a Scenario or an EchoData gives over the exposure. The closed forms and the
velocity solver take all their geometry from it, so another sonobuoy position, more sonobuoys or
another tow work unchanged: receivers are looked up by name.

Range-Doppler coupling. The echo of a scatterer whose delay changes during the pulse (the
target and the receivers keep moving while it is emitted and received: intra-pulse Doppler) is
the chirp shifted in frequency by -f_dc: an LFM shifted in frequency by f_d is the chirp shifted
in time by -f_d / K_r, so its matched-filter peak lies f_dc / K_r after the delay at the pulse's
centre (K_r = chirp_sign B / T; up to 150 us, three range cells, in Table II cases 6 and 8: the
test ``test_intra_pulse_doppler_shifts_the_compressed_peak_by_f_dc_over_k_r`` measures it). The
chain measures delays in the compressed record, so :attr:`Layout.range_doppler` (= 1 / K_r, or 0
for an echo synthesized without intra-pulse Doppler, ``provenance["intra_pulse"] == "none"``)
says how to take them back to the delay at the pulse's centre, tau = tau_peak - f_dc range_doppler.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np


def _line_fit(times: np.ndarray, positions: np.ndarray, at: float) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares straight line through ``positions`` (n, 3) at ``times`` (n,): its position at
    ``at`` and its velocity (3,). One time (or all equal): that position, zero velocity."""
    times = np.asarray(times, dtype=np.float64).ravel()
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    centre = times.mean()
    dt = times - centre
    spread = float(np.dot(dt, dt))
    mean = positions.mean(axis=0)
    if spread <= 1e-18 * max(1.0, centre * centre):
        return mean, np.zeros(3)
    velocity = dt @ (positions - mean) / spread
    return mean + velocity * (at - centre), velocity


@dataclass(frozen=True)
class Layout:
    """Uniform-motion geometry at the reference slow time ``eta_ref`` (s).

    Attributes
    ----------
    tx_position, tx_velocity : (3,) m, m/s: the transmitter at ``eta_ref`` and its velocity.
    receivers : dict name -> ((3,) position at ``eta_ref``, (3,) velocity), m and m/s.
    sound_speed : m/s; f0 : carrier, Hz; bandwidth : Hz; prf : Hz; aperture : the exposure
    T_a = n_pulses / prf, s; eta_ref : s. range_doppler : s/Hz, the compressed peak's delay per
    Hz of Doppler centroid (1 / K_r, or 0 without intra-pulse Doppler; module docstring).
    """

    tx_position: np.ndarray
    tx_velocity: np.ndarray
    receivers: dict
    sound_speed: float
    f0: float
    bandwidth: float
    prf: float
    aperture: float
    eta_ref: float = 0.0
    range_doppler: float = 0.0

    @property
    def names(self) -> tuple:
        return tuple(self.receivers)

    @property
    def platform_speed(self) -> float:
        """Along-track (y) speed of the transmitter, m/s: V_p of the paper."""
        return float(self.tx_velocity[1])

    def receiver(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        if name not in self.receivers:
            raise ValueError(f"receiver {name!r} is not in the layout; it has {self.names}")
        return self.receivers[name]

    def at(self, eta_ref: float) -> "Layout":
        """The same uniform motion referred to the slow time ``eta_ref`` (s): every position moved
        along its velocity."""
        dt = float(eta_ref) - self.eta_ref
        return dataclasses.replace(self, tx_position=self.tx_position + self.tx_velocity * dt, eta_ref=float(eta_ref),
                                   receivers={n: (p + v * dt, v) for n, (p, v) in self.receivers.items()})


def range_doppler(echo) -> float:
    """1 / K_r (s/Hz) when ``echo``'s records carry the range-Doppler coupling of intra-pulse
    Doppler, 0 when clsas synthesized it without (its provenance says ``intra_pulse`` "none" or
    predates the option): module docstring. Recorded data carry the coupling."""
    prov = echo.provenance or {}
    if prov.get("algorithm") == "clsas.simulate" and prov.get("intra_pulse", "none") == "none":
        return 0.0
    wf = echo.waveform
    return float(wf.chirp_sign * wf.duration / wf.bandwidth)


def layout_of(source, eta_ref: float | None = None) -> Layout:
    """The :class:`Layout` of a :class:`~clsas.scene.scenario.Scenario` or an
    :class:`~clsas.model.EchoData` (or a Layout, returned as is or referred to ``eta_ref``).

    ``eta_ref`` defaults to the middle of the pulse schedule (0 for the paper's exposure,
    centred on eta = 0). Positions are fitted by straight lines over the whole exposure
    (platform motion errors average out; the closed forms assume uniform motion).
    """
    from ...model import EchoData
    from ...scene.scenario import Scenario

    if isinstance(source, Layout):
        return source if eta_ref is None or float(eta_ref) == source.eta_ref else source.at(eta_ref)
    if isinstance(source, Scenario):
        eta = source.eta
        ref = float(0.5 * (eta[0] + eta[-1])) if eta_ref is None else float(eta_ref)
        tx = _line_fit(eta, source.tx_position(eta), ref)
        receivers = {name: _line_fit(eta, source.receiver_position(h, eta), ref)
                     for h, name in enumerate(source.receiver_names)}
        return Layout(tx[0], tx[1], receivers, source.medium.sound_speed, source.waveform.f0,
                      source.waveform.bandwidth, source.schedule.prf, eta.size / source.schedule.prf, ref)
    if isinstance(source, EchoData):
        eta = source.eta
        ref = float(0.5 * (eta[0] + eta[-1])) if eta_ref is None else float(eta_ref)
        tx = _line_fit(eta, source.tx_pos, ref)
        receivers = {}
        for h, name in enumerate(source.receivers):
            times = eta[:, None] + source.rx_tau[h][None, :]
            receivers[name] = _line_fit(times, source.rx_pos[h], ref)
        prf = 1.0 / float(np.median(np.diff(eta))) if eta.size > 1 else np.inf
        return Layout(tx[0], tx[1], receivers, source.medium.sound_speed, source.waveform.f0,
                      source.waveform.bandwidth, prf, eta.size / prf, ref, range_doppler(source))
    raise TypeError(f"expected a Scenario, an EchoData or a Layout, got {type(source).__name__}")
