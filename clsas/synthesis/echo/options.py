"""How :func:`clsas.simulate` synthesizes: its flags as one frozen object, validated once."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import backend as _backend
from ... import budget
from ... import validate as v
from ...pulse import WINDOWS
from ..occlusion import DEFAULT_REUSE_TOLERANCE
from .compressed import DEFAULT_LEVEL_DB

DTYPES = (np.dtype(np.complex64), np.dtype(np.complex128))
DEFAULT_CHUNK_BYTES = 256 * 2**20
INTRA_PULSE = ("moving", "all", "none")
ACCUMULATIONS = ("auto", "direct", "grid")  # how the raw records are made (simulate's ``accumulation``)
AUTO = "auto"


def auto_flag(name: str, value):
    """True, False, or "auto" (decided by the scenario); TypeError naming ``name`` otherwise."""
    if isinstance(value, str) and value == AUTO:
        return AUTO
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f'{name}: must be True, False or "auto", got {value!r} ({type(value).__name__})')
    return bool(value)


@dataclass(frozen=True)
class SynthesisOptions:
    """The options of :func:`clsas.simulate` and :func:`clsas.synthesis.delays` (their meaning is
    documented there), checked on construction: ValueError/TypeError naming the option.

    backend : "numpy", "opencl", "auto" or None; stored resolved ("numpy" or "opencl").
    precision : "single" or "double" (the OpenCL accumulation).
    dtype : complex64 or complex128, the returned samples.
    stop_and_go, hull_occlusion, progress : bool.
    spreading, absorption : bool, or "auto": on when the scenario has a seafloor.
    multipath : 0, 1 or 2 (the most bounces a path may have), or "auto": 1 when the scenario has
    a sea surface or a seafloor. intra_pulse : "moving" (default), "all" or "none".
    accumulation : "auto" (default), "direct" (each path's samples) or "grid" (fractional-delay impulses
    on an oversampled grid and one FFT filter per record, :mod:`clsas.synthesis.echo.grid`).
    compressed : False (raw echoes), True or a window name of :func:`clsas.range_compress`
    (synthesis into the range-compressed domain; True: no window); compressed_level_db : dB in
    [-120, -10], the level re the peak below which the compressed response's taps are dropped.
    reuse_tolerance : rad, in [0, pi]. max_bytes : bytes, None for the memory budget
    (:func:`clsas.memory_budget`); chunk_bytes : bytes.
    """

    backend: str | None = None
    precision: str = "single"
    dtype: object = np.complex64
    stop_and_go: bool = False
    spreading: bool | str = "auto"
    absorption: bool | str = "auto"
    multipath: int | str = "auto"
    intra_pulse: str = "moving"
    accumulation: str = "auto"
    compressed: bool | str = False
    compressed_level_db: float = DEFAULT_LEVEL_DB
    hull_occlusion: bool = True
    reuse_tolerance: float = DEFAULT_REUSE_TOLERANCE
    max_bytes: int | None = None
    chunk_bytes: int = DEFAULT_CHUNK_BYTES
    progress: bool = True

    def __post_init__(self):
        _backend.check_precision(self.precision)
        for name in ("stop_and_go", "hull_occlusion", "progress"):
            v.flag(name, getattr(self, name))
        for name in ("spreading", "absorption"):
            object.__setattr__(self, name, auto_flag(name, getattr(self, name)))
        if self.multipath != AUTO:
            object.__setattr__(self, "multipath", v.integer("multipath", self.multipath, low=0, high=2,
                                                            why='the most bounces a path may have, or "auto"'))
        v.choice("intra_pulse", self.intra_pulse, INTRA_PULSE)
        v.choice("accumulation", self.accumulation, ACCUMULATIONS)
        if isinstance(self.compressed, (bool, np.bool_)):
            object.__setattr__(self, "compressed", "none" if self.compressed else False)
        else:
            v.choice("compressed", self.compressed, WINDOWS)
        object.__setattr__(self, "compressed_level_db", v.scalar("compressed_level_db", self.compressed_level_db,
                                                                 low=-120.0, high=-10.0, unit="dB"))
        try:
            dtype = np.dtype(self.dtype)
        except TypeError:
            dtype = None
        if dtype not in DTYPES:
            raise ValueError(f"dtype must be numpy.complex64 or numpy.complex128, got {self.dtype!r}")
        v.scalar("reuse_tolerance", self.reuse_tolerance, low=0.0, high=np.pi, unit="rad")
        max_bytes = budget.memory_budget() if self.max_bytes is None else budget.parse_bytes(self.max_bytes, "max_bytes")
        object.__setattr__(self, "max_bytes", int(max_bytes))
        object.__setattr__(self, "chunk_bytes", int(budget.parse_bytes(self.chunk_bytes, "chunk_bytes")))
        object.__setattr__(self, "dtype", dtype)
        object.__setattr__(self, "reuse_tolerance", float(self.reuse_tolerance))
        object.__setattr__(self, "backend", _backend.resolve(self.backend))

    @property
    def double(self) -> bool:
        """The OpenCL kernels accumulate in double."""
        return self.precision == "double"
