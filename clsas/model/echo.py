"""EchoData: the recorded cube and the geometry that produced it."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .. import budget, validate
from ._describe import provenance_line, span
from .medium import Medium, Waveform

MAX_ECHO_FS = 1e11  # Hz: a waveform's largest rate (1 GHz) upsampled 64 times, with margin


class ScenarioRecord:
    """What an EchoData may carry as ``scenario``: the base of :class:`clsas.scene.Scenario`.

    The model sits below the scene, so it names the scenario's type by this base instead of
    importing the scene.
    """

    __slots__ = ()


def _geometry(name: str, value, shape: tuple) -> np.ndarray:
    """A finite float64 array of ``shape`` within the coordinate (m) and time (s) bounds."""
    return validate.array(f"EchoData.{name}", value, shape, bound=max(validate.MAX_COORDINATE, validate.MAX_TIME))


def _samples(value) -> np.ndarray:
    """The samples as a finite complex64 (n_rx, n_pulses, n_samples) array; a conversion (from
    complex128, say) is checked against the memory budget first."""
    data = np.asarray(value)
    if data.dtype.kind != "c":
        raise TypeError(f"EchoData.data: must be complex baseband samples, got dtype {data.dtype}")
    if data.ndim != 3:
        raise ValueError(f"EchoData.data: must be 3-D (rx, pulse, sample), got shape {data.shape}")
    if data.dtype != np.complex64:
        budget.check_bytes(f"EchoData.data as complex64 ({' x '.join(map(str, data.shape))} samples)",
                           8.0 * data.size, "a smaller echo")
        data = data.astype(np.complex64)
    if not validate.all_finite(data):
        raise ValueError("EchoData.data: must be finite: it has NaN or inf samples")
    return data


@dataclass(frozen=True, eq=False)
class EchoData:
    """Recorded echoes with the geometry that produced them.

    Attributes
    ----------
    data : complex64 array (n_rx, n_pulses, n_samples)
        Baseband samples; ``dims = ("rx", "pulse", "sample")``. Sample k of receiver r
        and pulse p was taken at fast time ``t0[r] + k / fs`` after the emission ``eta[p]``.
    eta : float64 (n_pulses,)
        Emission times, s.
    t0 : float64 (n_rx,)
        Fast time of sample 0 for each receiver, s.
    fs : float
        Sampling rate of the fast-time axis, Hz.
    tx_pos : float64 (n_pulses, 3)
        Transmitter phase centre at each emission, m.
    rx_pos : float64 (n_rx, n_pulses, n_nodes, 3)
        Receiver phase centres at the times ``eta[p] + rx_tau[r, k]``, m: nodes spanning the
        recording window; between nodes the position is linear (exact for uniform motion; the
        simulator picks enough nodes for motion errors). One node = a stationary receiver.
    rx_tau : float64 (n_rx, n_nodes)
        Fast times of the nodes, s, strictly increasing along the node axis.
    waveform, medium : the pulse and the water of the recording.
    receivers : tuple of str
        Receiver names.
    compressed : bool
        False for raw echoes, True after range compression.
    provenance : dict
        How the data was made (simulator or processing step and its parameters).
    scenario : Scenario or None
        The scenario the echoes were simulated from (None for recorded or hand-made data); kept
        through processing steps as a record of what was simulated, and saved with the file
        (as TOML text, :mod:`clsas.io.dataset`); any :class:`ScenarioRecord`.
    """

    data: np.ndarray
    eta: np.ndarray
    t0: np.ndarray
    fs: float
    tx_pos: np.ndarray
    rx_pos: np.ndarray
    rx_tau: np.ndarray
    waveform: Waveform
    medium: Medium
    receivers: tuple
    compressed: bool = False
    provenance: dict = field(default_factory=dict)
    scenario: ScenarioRecord | None = None

    dims: ClassVar[tuple] = ("rx", "pulse", "sample")

    def __post_init__(self):
        data = _samples(self.data)
        n_rx, n_p, _ = data.shape
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "eta", _geometry("eta", self.eta, (n_p,)))
        object.__setattr__(self, "t0", _geometry("t0", self.t0, (n_rx,)))
        fs = validate.scalar("EchoData.fs", self.fs, low=1.0, high=MAX_ECHO_FS, unit="Hz")
        object.__setattr__(self, "fs", fs)
        object.__setattr__(self, "tx_pos", _geometry("tx_pos", self.tx_pos, (n_p, 3)))
        rx_tau = _geometry("rx_tau", self.rx_tau, (n_rx, -1))
        if rx_tau.shape[1] < 1:
            raise ValueError(f"EchoData.rx_tau: must have shape ({n_rx}, n_nodes >= 1), got {rx_tau.shape}")
        if rx_tau.shape[1] > 1 and np.any(np.diff(rx_tau, axis=1) <= 0):
            raise ValueError("EchoData.rx_tau: must increase strictly along the node axis")
        object.__setattr__(self, "rx_tau", rx_tau)
        object.__setattr__(self, "rx_pos", _geometry("rx_pos", self.rx_pos, (n_rx, n_p, rx_tau.shape[1], 3)))
        if not isinstance(self.waveform, Waveform):
            raise TypeError(f"EchoData.waveform: must be a Waveform, got {type(self.waveform).__name__}")
        if not isinstance(self.medium, Medium):
            raise TypeError(f"EchoData.medium: must be a Medium, got {type(self.medium).__name__}")
        object.__setattr__(self, "receivers", validate.names("EchoData.receivers", self.receivers, n_rx))
        object.__setattr__(self, "compressed", validate.flag("EchoData.compressed", self.compressed))
        object.__setattr__(self, "provenance", validate.mapping("EchoData.provenance", self.provenance))
        if self.scenario is not None and not isinstance(self.scenario, ScenarioRecord):
            raise TypeError(f"EchoData.scenario must be a Scenario or None, got {type(self.scenario).__name__}")

    @property
    def n_rx(self) -> int:
        return self.data.shape[0]

    @property
    def n_pulses(self) -> int:
        return self.data.shape[1]

    @property
    def n_samples(self) -> int:
        return self.data.shape[2]

    def fast_time(self, rx: int) -> np.ndarray:
        """Fast times of receiver ``rx``'s samples, s, shape (n_samples,)."""
        return self.t0[rx] + np.arange(self.n_samples) / self.fs

    def rx_position(self, rx: int, tau, pulses=None) -> np.ndarray:
        """Receiver ``rx`` at fast times ``tau`` after each emission.

        ``tau`` has shape (n, ...) where row i belongs to pulse ``pulses[i]`` (default: all
        pulses, n = n_pulses); returns ``tau.shape + (3,)``. Linear between nodes, and linear
        beyond the first and last node (the nodes span the recording window, so this only
        serves delays outside it).
        """
        tau = np.asarray(tau, dtype=np.float64)
        rows_of = np.arange(self.n_pulses) if pulses is None else np.arange(self.n_pulses)[pulses]
        if tau.ndim == 0 or tau.shape[0] != rows_of.size:
            raise ValueError(f"tau must have shape (n_pulses={rows_of.size}, ...), got {tau.shape}")
        nodes = self.rx_tau[rx]
        pos = self.rx_pos[rx][rows_of]  # (n, n_nodes, 3)
        if nodes.size == 1:
            return np.broadcast_to(pos[:, 0, :].reshape((rows_of.size,) + (1,) * (tau.ndim - 1) + (3,)),
                                   tau.shape + (3,)).copy()
        seg = np.clip(np.searchsorted(nodes, tau) - 1, 0, nodes.size - 2)
        w = ((tau - nodes[seg]) / (nodes[seg + 1] - nodes[seg]))[..., None]
        rows = np.arange(rows_of.size).reshape((-1,) + (1,) * (tau.ndim - 1))
        return pos[rows, seg] * (1 - w) + pos[rows, seg + 1] * w

    def select_receivers(self, receivers=None, parameter: str = "receivers") -> list:
        """Indices of ``receivers`` (indices or names; None: all), or a ValueError naming
        ``parameter`` and what is allowed."""
        if receivers is None:
            return list(range(self.n_rx))
        chosen = []
        for r in np.atleast_1d(receivers).tolist():
            if isinstance(r, str):
                if r not in self.receivers:
                    raise ValueError(f"{parameter}: unknown receiver {r!r}; the echo has {self.receivers}")
                r = self.receivers.index(r)
            if isinstance(r, bool) or not isinstance(r, int) or not 0 <= r < self.n_rx:
                raise ValueError(f"{parameter} must be indices in [0, {self.n_rx - 1}] or names {self.receivers}, "
                                 f"got {r!r}")
            chosen.append(r)
        if not chosen:
            raise ValueError(f"{parameter} is empty: select at least one receiver")
        return chosen

    def replace(self, **changes) -> "EchoData":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def __repr__(self) -> str:
        what = "range-compressed" if self.compressed else "raw"
        names = ", ".join(self.receivers[:4]) + (", ..." if self.n_rx > 4 else "")
        return (f"<EchoData {what} {self.n_rx} rx x {self.n_pulses} pulses x {self.n_samples} samples "
                f"({self.data.nbytes / 2**20:.1f} MiB) rx=[{names}] eta={span(self.eta, 's')} "
                f"fs={self.fs:.6g} Hz f0={self.waveform.f0:.6g} Hz B={self.waveform.bandwidth:.6g} Hz "
                f"provenance={provenance_line(self.provenance)}>")
