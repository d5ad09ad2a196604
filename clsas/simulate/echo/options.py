"""How :func:`clsas.simulate` synthesizes: its flags as one frozen object, validated once."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import backend as _backend
from ..occlusion import DEFAULT_REUSE_TOLERANCE
from ..window import DEFAULT_MAX_BYTES

DTYPES = (np.dtype(np.complex64), np.dtype(np.complex128))
DEFAULT_CHUNK_BYTES = 256 * 2**20


@dataclass(frozen=True)
class SynthesisOptions:
    """The options of :func:`clsas.simulate` and :func:`clsas.simulate.delays` (their meaning is
    documented there), checked on construction: ValueError/TypeError naming the option.

    backend : "numpy", "opencl", "auto" or None; stored resolved ("numpy" or "opencl").
    precision : "single" or "double" (the OpenCL accumulation).
    dtype : complex64 or complex128, the returned samples.
    stop_and_go, spreading, hull_occlusion, progress : bool.
    reuse_tolerance : rad, >= 0. max_bytes, chunk_bytes : positive integers of bytes.
    """

    backend: str | None = None
    precision: str = "single"
    dtype: object = np.complex64
    stop_and_go: bool = False
    spreading: bool = False
    hull_occlusion: bool = True
    reuse_tolerance: float = DEFAULT_REUSE_TOLERANCE
    max_bytes: int = DEFAULT_MAX_BYTES
    chunk_bytes: int = DEFAULT_CHUNK_BYTES
    progress: bool = True

    def __post_init__(self):
        _backend.check_precision(self.precision)
        for name in ("stop_and_go", "spreading", "hull_occlusion", "progress"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise TypeError(f"{name} must be True or False, got {getattr(self, name)!r}")
        try:
            dtype = np.dtype(self.dtype)
        except TypeError:
            dtype = None
        if dtype not in DTYPES:
            raise ValueError(f"dtype must be numpy.complex64 or numpy.complex128, got {self.dtype!r}")
        for name in ("max_bytes", "chunk_bytes"):
            value = getattr(self, name)
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value <= 0:
                raise ValueError(f"{name} must be a positive integer number of bytes, got {value!r}")
        if isinstance(self.reuse_tolerance, (bool, np.bool_)) or not isinstance(self.reuse_tolerance, (int, float, np.number)) \
                or not (np.isfinite(self.reuse_tolerance) and self.reuse_tolerance >= 0):
            raise ValueError(f"reuse_tolerance must be a finite angle >= 0 rad, got {self.reuse_tolerance!r}")
        object.__setattr__(self, "dtype", dtype)
        object.__setattr__(self, "max_bytes", int(self.max_bytes))
        object.__setattr__(self, "chunk_bytes", int(self.chunk_bytes))
        object.__setattr__(self, "reuse_tolerance", float(self.reuse_tolerance))
        object.__setattr__(self, "backend", _backend.resolve(self.backend))

    @property
    def double(self) -> bool:
        """The OpenCL kernels accumulate in double."""
        return self.precision == "double"
