"""The direct paths of a scenario: exact delays and amplitudes of every (receiver, pulse, scatterer).

The float64 reference the echo kernel is held to; the delay and amplitude laws are those of
:mod:`clsas.geometry` (docs/design.md, non-stop-and-go).
"""

from __future__ import annotations

import numpy as np

from ..geometry import element_gain, incoming, iteration_tolerance, outgoing
from ..scene.scenario import Scenario
from ..scene.targets import Scatterers


def direct_paths(scenario: Scenario, eta: np.ndarray, scat: Scatterers, receivers, stop_and_go: bool = False,
          spreading: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Exact delays and amplitudes of every (receiver, pulse, scatterer) path.

    Parameters
    ----------
    scenario : Scenario
    eta : (P,) emission times, s
    scat : Scatterers (N)
    receivers : sequence of receiver indices (H)

    Returns
    -------
    tau : float64 (H, P, N), two-way delays, s
    amp : complex128 (H, P, N), path amplitudes (reflectivity x patterns [x spreading]),
        without the carrier phase and without occlusion.
    """
    c = scenario.medium.sound_speed
    wavelength = scenario.waveform.wavelength(scenario.medium)
    tol = iteration_tolerance(scenario.waveform.f0)
    eta = np.asarray(eta, dtype=np.float64)
    tx = scenario.tx_position(eta)
    t1, q = outgoing(tx, eta, scat.p0, scat.vel, c, tol, stop_and_go)
    out_dir = q - tx[:, None, :]
    r1 = np.linalg.norm(out_dir, axis=-1)
    tx_axis = scenario.platform.rotation(eta)[..., :, 1]
    amp_tx = scat.refl[None, :] * element_gain(scenario.array.tx_length, out_dir / r1[..., None],
                                               tx_axis[:, None, :], wavelength)
    lengths = scenario.receiver_lengths
    taus, amps = [], []
    for h in receivers:
        t2, r = incoming(lambda t, h=h: scenario.receiver_position(h, t), eta, t1, q, c, tol, stop_and_go)
        back = q - r
        r2 = np.linalg.norm(back, axis=-1)
        t_rx = eta[:, None] + (0.0 if stop_and_go else t1 + t2)
        axis = scenario.receiver_axis(h, np.broadcast_to(t_rx, t2.shape))
        amp = amp_tx * element_gain(lengths[h], back / r2[..., None], axis, wavelength)
        if spreading:
            amp = amp / (r1 * r2)
        taus.append(t1 + t2)
        amps.append(amp)
    return np.stack(taus), np.stack(amps)
