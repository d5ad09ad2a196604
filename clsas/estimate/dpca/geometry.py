"""DPCA geometry: the nominal pairing of eq. (50), the phase-centre errors of eqs. (48)-(49)
and the beam's mean look angle they depend on."""

from __future__ import annotations

import numpy as np

from ...scene.scenario import Array


def nominal_shift(array: Array, speed: float, prf: float) -> tuple[int, np.ndarray]:
    """The nominal pairing of eq. (50): (s, phase-centre along-track offsets o_h / 2 in m).

    s = v PRT / Delta_PC rounded; hydrophone i + s at ping p and i at ping p + 1 coincide."""
    pc = 0.5 * (array.rx_offsets[:, 1] + array.tx_offset[1])
    order = np.argsort(pc)
    if np.any(order != np.arange(pc.size)):
        raise ValueError("dpca: the hydrophones must be numbered along the track (increasing body y)")
    steps = np.diff(pc)
    if pc.size < 3 or not np.allclose(steps, steps[0], rtol=1e-6):
        raise ValueError(f"dpca needs a uniform line of >= 3 hydrophones, got phase-centre offsets {pc}")
    shift = speed / prf / steps[0]
    s = int(round(shift))
    return s, pc


def _beam(array: Array, f0: float, c: float):
    """(sin theta, P(theta)) over the half-space in front of the array, P the two-way power
    pattern of the transmitter and the hydrophones, sinc^2(L_tx sin(theta) / lambda)
    sinc^2(L_rx sin(theta) / lambda) (clsas's element directivity, squared once for the transmit
    leg and once for the receive leg): the weight of a scatterer at look angle theta in the
    couples' correlations, over a seafloor that fills the beam. None if both elements are
    omnidirectional (length 0: the beam is then the scene's, which the array cannot know)."""
    lam = c / f0
    lengths = (array.tx_length, float(np.mean(array.rx_length)))
    if max(lengths) == 0:
        return None
    sin_t = np.sin(np.linspace(-np.pi / 2, np.pi / 2, 4001))
    return sin_t, np.prod([np.sinc(length * sin_t / lam) ** 2 for length in lengths], axis=0)


def beam_sin2(array: Array, f0: float, c: float) -> float:
    """<sin^2 theta> over the two-way power pattern (see :func:`_beam`); 0 for omnidirectional
    elements. Heremans' 21.88 cm elements at 3 cm: 1.42e-3, (lambda / L)^2 3 / (4 pi^2) in the
    small-angle limit (the second moment of sinc^4)."""
    beam = _beam(array, f0, c)
    if beam is None:
        return 0.0
    sin_t, power = beam
    return float(np.sum(sin_t**2 * power) / np.sum(power))


def xlag_offset(q: np.ndarray, array: Array, f0: float, c: float, step: float) -> np.ndarray:
    """The x-lag peak's offset from the best lag, in lags (-0.5 .. 0.5), from the three beam
    peaks' ratio q (:func:`clsas.estimate.dpca.correlate.peak_ratio`).

    Two phase centres displaced by e along the track see a scatterer at look angle theta
    2 k e sin(theta) apart in phase (two-way), so over the beam their coherence is
    rho(e) = sum P(theta) cos(2 k e sin theta) / sum P(theta), P the two-way power pattern
    (:func:`_beam`): the Fourier transform of sinc^4, a cubic B-spline in e / L for equal
    elements, rounded at its peak and 1/4 at e = L / 2 (the x-lag step for hydrophones one
    element length apart). The beam peaks at lags -1, 0, 1 sample rho((k - eps) step); q(eps)
    is tabulated and inverted. For omnidirectional elements the V of linear decorrelation,
    eps = q / (1 + |q|), is used. (The V applied to the B-spline read 0.85 of a 37 mm surge on
    noise-free speckle; a parabola reads half of it.)"""
    beam = _beam(array, f0, c)
    if beam is None:
        return np.clip(q / (1 + np.abs(q)), -0.5, 0.5)
    sin_t, power = beam
    k = 2 * np.pi * f0 / c
    eps = np.linspace(-0.5, 0.5, 101)
    lags = (np.arange(-1, 2)[:, None] - eps[None, :]) * step                       # (3, eps)
    rho = (np.cos(2 * k * lags[..., None] * sin_t) @ power) / np.sum(power)       # (3, eps)
    q_model = (rho[2] - rho[0]) / (2 * rho[1] - rho[2] - rho[0])
    return np.interp(q, q_model, eps)


def pca_delay(array: Array, i: np.ndarray, j: np.ndarray, r: np.ndarray, speed: float, c: float,
               sin2: float) -> np.ndarray:
    """dt_pca, s (couple,) + r.shape: the difference, ping p + 1 minus ping p, of the couple
    members' phase-centre errors at range r (m, any shape) (eqs. 48-49). Two-way path of a
    transmitter and a hydrophone a separation sigma apart along the track, to a scatterer at
    range r and look angle theta off broadside: 2 |S - M| + sigma^2 cos^2(theta) / (4 r), M
    their midpoint (the phase centre; the sigma^3 terms cancel between the two legs). sigma_h
    is the separation of the transmitter at emission and hydrophone h at reception,
    o_h - o_tx + v 2 r / c: the platform moves on while the echo travels. A range block
    mixes scatterers across the beam, so cos^2 is replaced by its mean over the beam,
    1 - ``sin2`` (:func:`beam_sin2`).

    Left in, the difference reads as a yaw (its part linear along the couples: 1.53 m x 2 u / r
    at Heremans' geometry, 7.7 mrad at 100 m) and as a sway (its constant part, through the
    v 2 r / c term: 0.65 mm a ping pair there). Taken at the block's centre range instead of
    each sample's, it leaves 7.7 mrad x (r_scatterer - r_block) / r: tens of urad for a bright
    point off the block centre. Left at broadside (sin2 = 0), it leaves D <sin^2 theta> / r per
    ping pair as a yaw (D = v PRT, the couples' separation; 9 urad a pair at Heremans' 100 m),
    which integrates into a quadratic cross-track error along the track."""
    sigma = (array.rx_offsets[:, 1] - array.tx_offset[1]).reshape((-1,) + (1,) * r.ndim) + speed * 2 * r / c
    return (sigma[i] ** 2 - sigma[j] ** 2) * (1 - sin2) / (4 * r * c)
