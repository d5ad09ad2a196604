"""The containers that flow between the stages: EchoData (recorded cube + geometry) and Image.

Ground floor: imports nothing of clsas but the scenario types it records.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from . import budget
from . import validate
from .scene.scenario import Medium, Scenario, Waveform

MAX_ECHO_FS = 1e11  # Hz: a waveform's largest rate (1 GHz) upsampled 64 times, with margin
GRID_BYTES_PER_PIXEL = 80  # a plane's positions (24) and their temporaries while it is built


def _geometry(name: str, value, shape: tuple) -> np.ndarray:
    """A finite float64 array of ``shape`` within the coordinate (m) and time (s) bounds."""
    return validate.array(f"EchoData.{name}", value, shape, bound=max(validate.MAX_COORDINATE, validate.MAX_TIME))


def _span(values, unit: str) -> str:
    """``"a..b unit"`` of a 1-D array (``"a unit"`` for one value)."""
    if values.size == 0:
        return "empty"
    if values.size == 1:
        return f"{values[0]:.6g} {unit}"
    return f"{values[0]:.6g}..{values[-1]:.6g} {unit}"


def _provenance_line(provenance: dict) -> str:
    keys = list(provenance)
    head = provenance.get("algorithm", provenance.get("from", ""))
    shown = ", ".join(keys[:6]) + (", ..." if len(keys) > 6 else "")
    return f"{head} ({shown})" if head else f"({shown})"


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
        (as TOML text, :mod:`clsas.dataset`).
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
    scenario: Scenario | None = None

    dims: ClassVar[tuple] = ("rx", "pulse", "sample")

    def __post_init__(self):
        data = np.asarray(self.data)
        if data.ndim != 3:
            raise ValueError(f"EchoData.data must be 3-D (rx, pulse, sample), got shape {data.shape}")
        if not np.iscomplexobj(data):
            raise TypeError(f"EchoData.data must be complex baseband samples, got dtype {data.dtype}")
        data = data.astype(np.complex64, copy=False)
        if not validate.all_finite(data):
            raise ValueError("EchoData.data must be finite: it has NaN or inf samples")
        n_rx, n_p, _ = data.shape
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "eta", _geometry("eta", self.eta, (n_p,)))
        object.__setattr__(self, "t0", _geometry("t0", self.t0, (n_rx,)))
        fs = validate.scalar("EchoData.fs", self.fs, low=1.0, high=MAX_ECHO_FS, unit="Hz")
        object.__setattr__(self, "fs", fs)
        object.__setattr__(self, "tx_pos", _geometry("tx_pos", self.tx_pos, (n_p, 3)))
        rx_tau = np.asarray(self.rx_tau, dtype=np.float64)
        if rx_tau.ndim != 2 or rx_tau.shape[0] != n_rx or rx_tau.shape[1] < 1:
            raise ValueError(f"EchoData.rx_tau must have shape ({n_rx}, n_nodes >= 1), got {rx_tau.shape}")
        object.__setattr__(self, "rx_tau", _geometry("rx_tau", rx_tau, rx_tau.shape))
        if rx_tau.shape[1] > 1 and np.any(np.diff(rx_tau, axis=1) <= 0):
            raise ValueError("EchoData.rx_tau must increase strictly along the node axis")
        object.__setattr__(self, "rx_pos", _geometry("rx_pos", self.rx_pos, (n_rx, n_p, rx_tau.shape[1], 3)))
        if not isinstance(self.waveform, Waveform) or not isinstance(self.medium, Medium):
            raise TypeError("EchoData.waveform must be a Waveform and EchoData.medium a Medium")
        receivers = tuple(self.receivers)
        if len(receivers) != n_rx:
            raise ValueError(f"EchoData.receivers must name {n_rx} receivers, got {len(receivers)}")
        object.__setattr__(self, "receivers", receivers)
        object.__setattr__(self, "compressed", bool(self.compressed))
        object.__setattr__(self, "provenance", dict(self.provenance))
        if self.scenario is not None and not isinstance(self.scenario, Scenario):
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

    def to_xarray(self):
        """An ``xarray.Dataset`` with named, united coordinates (layout: :mod:`clsas.dataset`)."""
        from .dataset import echo_to_xarray

        return echo_to_xarray(self)

    @classmethod
    def from_xarray(cls, ds) -> "EchoData":
        """The EchoData of a Dataset made by :meth:`to_xarray` (or read from a clsas file)."""
        from .dataset import echo_from_xarray

        return echo_from_xarray(ds)

    def __repr__(self) -> str:
        what = "range-compressed" if self.compressed else "raw"
        names = ", ".join(self.receivers[:4]) + (", ..." if self.n_rx > 4 else "")
        return (f"<EchoData {what} {self.n_rx} rx x {self.n_pulses} pulses x {self.n_samples} samples "
                f"({self.data.nbytes / 2**20:.1f} MiB) rx=[{names}] eta={_span(self.eta, 's')} "
                f"fs={self.fs:.6g} Hz f0={self.waveform.f0:.6g} Hz B={self.waveform.bandwidth:.6g} Hz "
                f"provenance={_provenance_line(self.provenance)}>")


@dataclass(frozen=True, eq=False)
class Image:
    """A complex image with named axes and the record of how it was formed.

    Attributes
    ----------
    data : complex64 array
        Pixel values; its axes are named by ``dims`` (e.g. ``("y", "x")``: along track by
        across track; ``("eta", "tau")`` for an image in slow/fast time).
    dims : tuple of str
    axes : dict name -> 1-D float64 array
        Coordinate of each dim (m, or s for time axes); one entry per dim, of matching length.
    provenance : dict
        Algorithm and parameters.
    positions : float64 array ``data.shape + (3,)``, optional
        World positions of the pixels (m) when they do not follow from the axes alone
        (slant planes, arbitrary 3-D pixel sets).
    """

    data: np.ndarray
    dims: tuple
    axes: dict
    provenance: dict = field(default_factory=dict)
    positions: np.ndarray | None = None

    def __post_init__(self):
        data = np.asarray(self.data)
        if data.dtype.kind not in "iufc":
            raise TypeError(f"Image.data: must be an array of numbers, got dtype {data.dtype}")
        if not np.iscomplexobj(data):
            data = data.astype(np.complex64)
        data = data.astype(np.complex64, copy=False)
        dims = tuple(self.dims)
        if len(dims) != data.ndim or len(set(dims)) != len(dims):
            raise ValueError(f"Image.dims must name each of the {data.ndim} axes once, got {dims}")
        axes = {}
        for name, n in zip(dims, data.shape):
            if name not in self.axes:
                raise ValueError(f"Image.axes lacks the coordinate of dim {name!r}")
            ax = np.asarray(self.axes[name], dtype=np.float64)
            if ax.shape != (n,) or not np.all(np.isfinite(ax)):
                raise ValueError(f"Image.axes[{name!r}] must be {n} finite values, got shape {ax.shape}")
            axes[name] = ax
        extra = set(self.axes) - set(dims)
        if extra:
            raise ValueError(f"Image.axes has coordinates for unknown dims {sorted(extra)}")
        if self.positions is not None:
            pos = np.asarray(self.positions, dtype=np.float64)
            if pos.shape != data.shape + (3,) or not np.all(np.isfinite(pos)):
                raise ValueError(f"Image.positions must be finite with shape {data.shape + (3,)}, got {pos.shape}")
            object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "dims", dims)
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "provenance", dict(self.provenance))

    @property
    def shape(self) -> tuple:
        return self.data.shape

    def db(self, floor_db: float | None = None) -> np.ndarray:
        """20 log10 |data| normalised to the peak (0 dB), optionally clipped below at ``floor_db``."""
        mag = np.abs(self.data).astype(np.float64)
        peak = mag.max() if mag.size else 0.0
        if peak == 0:
            raise ValueError("Image.db: the image is all zeros")
        with np.errstate(divide="ignore"):
            out = 20 * np.log10(mag / peak)
        return out if floor_db is None else np.maximum(out, floor_db)

    def replace(self, **changes) -> "Image":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_xarray(self):
        """An ``xarray.Dataset`` with the axes as coordinates in m or s (layout: :mod:`clsas.dataset`)."""
        from .dataset import image_to_xarray

        return image_to_xarray(self)

    @classmethod
    def from_xarray(cls, ds) -> "Image":
        """The Image of a Dataset made by :meth:`to_xarray` (or read from a clsas file)."""
        from .dataset import image_from_xarray

        return image_from_xarray(ds)

    def __repr__(self) -> str:
        axes = ", ".join(f"{d}={_span(self.axes[d], '')}".rstrip() for d in self.dims)
        where = "" if self.positions is None else " with pixel positions"
        return (f"<Image {' x '.join(map(str, self.data.shape))} ({self.data.nbytes / 2**20:.1f} MiB) {axes}{where} "
                f"provenance={_provenance_line(self.provenance)}>")


@dataclass(frozen=True, eq=False)
class Grid:
    """Pixel positions to image on: any array of 3-D points with named axes.

    Build one with :meth:`plane` (a horizontal plane at a depth), :meth:`slant` (a plane spanned
    by two direction vectors, e.g. a slant-range plane) or :meth:`points` (any ``(..., 3)``
    array, e.g. a 3-D volume).

    Attributes
    ----------
    positions : float64 ``shape + (3,)``, m
    dims : tuple of str, one name per axis of ``shape``
    axes : dict name -> 1-D float64 coordinate (m, or the index for :meth:`points`)
    """

    positions: np.ndarray
    dims: tuple
    axes: dict

    def __post_init__(self):
        pos = validate.array("Grid.positions", self.positions, (-1,) * max(2, np.ndim(self.positions)),
                             bound=validate.MAX_COORDINATE, copy=False)
        if pos.ndim < 2 or pos.shape[-1] != 3:
            raise ValueError(f"Grid.positions: must have shape (..., 3), got {pos.shape}")
        if pos.size == 0:
            raise ValueError("Grid is empty: give at least one pixel")
        dims = tuple(self.dims)
        if len(dims) != pos.ndim - 1:
            raise ValueError(f"Grid.dims must name the {pos.ndim - 1} pixel axes, got {dims}")
        axes = {}
        for name, n in zip(dims, pos.shape[:-1]):
            ax = np.asarray(self.axes.get(name, np.arange(n)), dtype=np.float64)
            if ax.shape != (n,):
                raise ValueError(f"Grid.axes[{name!r}] must have {n} values, got shape {ax.shape}")
            axes[name] = ax
        pos.flags.writeable = False
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "dims", dims)
        object.__setattr__(self, "axes", axes)

    @property
    def shape(self) -> tuple:
        return self.positions.shape[:-1]

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    @classmethod
    def plane(cls, x, y, z: float) -> "Grid":
        """Horizontal plane z = ``z`` (m, negative below the surface) on the x (across-track) and
        y (along-track) coordinates given; dims ``("y", "x")``."""
        x = validate.array("Grid.plane x", x if np.ndim(x) else [x], (-1,), bound=validate.MAX_COORDINATE)
        y = validate.array("Grid.plane y", y if np.ndim(y) else [y], (-1,), bound=validate.MAX_COORDINATE)
        if x.size == 0 or y.size == 0:
            raise ValueError(f"Grid.plane x and y: must be non-empty, got shapes {x.shape} and {y.shape}")
        z = validate.scalar("Grid.plane z", z, low=-validate.MAX_COORDINATE, high=validate.MAX_COORDINATE, unit="m")
        budget.check_bytes(f"Grid.plane of {y.size} x {x.size} pixels", GRID_BYTES_PER_PIXEL * x.size * y.size,
                           "fewer pixels (image in tiles)")
        yy, xx = np.meshgrid(y, x, indexing="ij")
        return cls(np.stack([xx, yy, np.full_like(xx, z)], axis=-1), ("y", "x"), {"y": y, "x": x})

    @classmethod
    def slant(cls, origin, u_direction, v_direction, u, v, dims=("v", "u")) -> "Grid":
        """Plane ``origin + u_i u_direction + v_j v_direction`` (unit directions, m); shape (len(v), len(u))."""
        origin = validate.vector3("Grid.slant origin", origin)
        du = validate.vector3("Grid.slant u_direction", u_direction)
        dv = validate.vector3("Grid.slant v_direction", v_direction)
        for name, vec in (("u_direction", du), ("v_direction", dv)):
            if not np.isclose(np.linalg.norm(vec), 1.0):
                raise ValueError(f"Grid.slant {name}: must be a unit 3-vector, got {vec}")
        u = validate.array("Grid.slant u", u if np.ndim(u) else [u], (-1,), bound=validate.MAX_COORDINATE)
        w = validate.array("Grid.slant v", v if np.ndim(v) else [v], (-1,), bound=validate.MAX_COORDINATE)
        budget.check_bytes(f"Grid.slant of {w.size} x {u.size} pixels", GRID_BYTES_PER_PIXEL * u.size * w.size,
                           "fewer pixels (image in tiles)")
        pos = origin + w[:, None, None] * dv + u[None, :, None] * du
        return cls(pos, tuple(dims), {dims[0]: w, dims[1]: u})

    @classmethod
    def points(cls, positions, dims=None) -> "Grid":
        """Any ``(..., 3)`` array of pixel positions (m); dims default to ``("i0", "i1", ...)``."""
        pos = validate.array("Grid.points positions", positions, (-1,) * max(1, np.ndim(positions)),
                             bound=validate.MAX_COORDINATE)
        if pos.ndim == 1:
            pos = pos[None]
        dims = tuple(dims) if dims is not None else tuple(f"i{k}" for k in range(pos.ndim - 1))
        return cls(pos, dims, {})
