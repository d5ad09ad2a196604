"""Recording windows, receiver position nodes and the memory budget of echo synthesis."""

from __future__ import annotations

import numpy as np

from ..errors import MemoryBudgetError
from ..scene.scenario import MOTION_COMPONENTS


def has_motion_errors(platform) -> bool:
    return any(getattr(platform, c) is not None for c in MOTION_COMPONENTS)


def node_span(scenario, eta: np.ndarray, tau_hi: float) -> float:
    """``tau_hi`` clamped so that eta + tau_hi stays within sampled motion errors (which are not
    extrapolated): the nodes never ask the platform outside ``Platform.error_times``."""
    times = scenario.platform.error_times
    if times is None:
        return float(tau_hi)
    return float(max(min(tau_hi, times[-1] - np.max(eta)), 1e-6))


def receiver_nodes(scenario, eta: np.ndarray, tau_hi: float, max_error: float | None = None, strict: bool = True):
    """Receiver positions and element axes at uniformly spaced fast times 0 .. ``tau_hi``.

    Between nodes the receiver is taken to move linearly (the OpenCL kernels and
    :meth:`clsas.model.EchoData.rx_position` interpolate). Two nodes are exact for a straight
    track without motion errors; with motion errors the node count doubles until linear
    interpolation is within ``max_error`` (default lambda / 10^4, i.e. 6e-4 rad of two-way
    phase) of the exact position at every segment midpoint of every pulse, up to 4097 nodes;
    beyond that ``strict`` raises, otherwise the 4097-node grid is returned as it is (for
    uses that do not need the accuracy: the NumPy reference evaluates exact trajectories).

    Returns ``rx_tau`` (K,) s, ``positions`` (H, P, K, 3) m, ``axes`` (H, P, K, 3) and the
    largest midpoint interpolation error, m.
    """
    eta = np.asarray(eta, dtype=np.float64)
    if max_error is None:
        max_error = scenario.waveform.wavelength(scenario.medium) * 1e-4
    n_nodes = 2

    def sample(taus):
        t = eta[:, None] + taus[None, :]
        pos = np.stack([scenario.receiver_position(h, t) for h in range(scenario.n_receivers)])
        axes = np.stack([scenario.receiver_axis(h, t) for h in range(scenario.n_receivers)])
        return pos, axes

    while True:
        taus = np.linspace(0.0, tau_hi, n_nodes)
        pos, axes = sample(taus)
        if not has_motion_errors(scenario.platform):
            return taus, pos, axes, 0.0
        mid_pos, _ = sample(0.5 * (taus[1:] + taus[:-1]))
        error = float(np.max(np.linalg.norm(0.5 * (pos[:, :, 1:] + pos[:, :, :-1]) - mid_pos, axis=-1)))
        if error <= max_error:
            return taus, pos, axes, error
        if n_nodes >= 4096:
            if not strict:
                return taus, pos, axes, error
            raise ValueError(f"the platform's motion errors vary too fast for the OpenCL kernel: 4097 receiver nodes "
                             f"over {tau_hi:.3g} s still leave {error:.3g} m of interpolation error (allowed "
                             f"{max_error:.3g} m); use backend='numpy' (exact trajectories)")
        n_nodes = 2 * n_nodes - 1


def check_cube_size(n_rx: int, n_pulses: int, n_samples: int, max_bytes: int, origin: str, n_nodes: int = 2) -> None:
    """Refuse an echo cube (complex64) and its receiver nodes (float64) larger than ``max_bytes``
    before allocating them: a :class:`clsas.errors.MemoryBudgetError` (a ValueError)."""
    need = 8 * n_rx * n_pulses * n_samples + 24 * n_rx * n_pulses * n_nodes
    if need > max_bytes:
        raise MemoryBudgetError(
            f"the echo cube would need {need / 2**30:.2f} GiB ({n_rx} receivers x {n_pulses} pulses x "
            f"{n_samples} samples of complex64 and {n_nodes} receiver nodes a pulse; window {origin}) but max_bytes allows "
            f"{max_bytes / 2**30:.2f} GiB. Reduce it: fewer pulses (PulseSchedule), fewer receivers, a "
            "shorter recording window (Scenario.recording), a more compact scene, or raise max_bytes "
            "(by default the memory budget: clsas.use_memory_budget)."
        )
