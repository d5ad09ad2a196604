"""Stolt mapping (the interpolation at the heart of omega-k): NumPy reference and OpenCL launcher.

Heremans et al. 2009, eq. (41): the wavenumber data measured on the (omega, k_u) grid lie at
k_x = sqrt(4 k^2 - k_u^2) (k = omega / c, the paper's "- 2 k_0" belongs outside the root: it
makes k_x baseband, k_x' = sqrt(4 k^2 - k_u^2) - 2 k_0, as Fig. 9 and eq. (45) show); the map
resamples every k_u row onto a uniform k_x' grid. Inverting the map for output column
k_x' gives the source frequency exactly (no nearest-neighbour shortcut; the source columns are
uniform in baseband frequency f_b, the output ones uniform in k_x', so the source positions
are non-uniformly spaced):

    f_b(k_x', k_u) = c / (4 pi) sqrt((k_x' + 2 k_0)^2 + k_u^2) - f_0,
    idx = (f_b - f_first) / df                      (fractional source column).

The interpolators (``interp``, ``window``, ``oversampling``) are those of :mod:`clsas.interp`
(linear, or 8/16-tap windowed sincs from its shared tap table; an output reads as zero unless
all its source samples exist, so the spectrum must be zero-padded where the mapping needs more).

The kernel (``kernels/stolt.cl``) computes the first position of each work-item's 64 outputs
in double and the others relative to it in float (~1e-5 sample), and the interpolation in
float; the reference does everything in float64 with the same table. They differ by float
rounding, and where a position's rounding picks the neighbouring tap row (1/4096 sample
apart): bench/bench_stolt.py reports the difference on its axes, tests/test_stolt.py bounds it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import backend as _backend
from .. import validate as v
from ..interp import check_options, check_sizes, launch_rows, resample_rows

MAX_AXIS = 1e12  # bound of the axes' frequencies (Hz), wavenumbers (rad/m) and sound speed: only nonsense beyond


@dataclass(frozen=True)
class StoltAxes:
    """The source and output grids of a Stolt map.

    f_first, df : baseband frequency of source column 0 and the column spacing, Hz
    n_src : source columns
    kx_first, dkx : baseband range wavenumber k_x' of output column 0 and the spacing, rad/m
    n_out : output columns
    f0 : carrier, Hz; c : sound speed, m/s
    """

    f_first: float
    df: float
    n_src: int
    kx_first: float
    dkx: float
    n_out: int
    f0: float
    c: float

    def __post_init__(self):
        for name in ("f_first", "kx_first"):
            object.__setattr__(self, name, v.scalar(f"StoltAxes.{name}", getattr(self, name), low=-MAX_AXIS, high=MAX_AXIS))
        for name in ("df", "dkx", "f0"):
            object.__setattr__(self, name, v.positive(f"StoltAxes.{name}", getattr(self, name), high=MAX_AXIS))
        object.__setattr__(self, "c", v.positive("StoltAxes.c", self.c, high=MAX_AXIS, unit="m/s"))
        for name in ("n_src", "n_out"):
            object.__setattr__(self, name, v.integer(f"StoltAxes.{name}", getattr(self, name), low=1, high=2**31 - 1))

    def index_constants(self) -> tuple[float, float, float, float]:
        """(K0, dkx, A, Bc) with idx = A sqrt((K0 + j dkx)^2 + k_u^2) + Bc (the kernel's params)."""
        k0 = 2 * np.pi * self.f0 / self.c
        return (self.kx_first + 2 * k0, self.dkx, self.c / (4 * np.pi * self.df), -(self.f0 + self.f_first) / self.df)

    def source_index(self, ku: np.ndarray) -> np.ndarray:
        """Fractional source columns (len(ku), n_out), float64."""
        k0, dkx, a, b = self.index_constants()
        k = k0 + dkx * np.arange(self.n_out)
        return a * np.sqrt(k[None, :] ** 2 + np.asarray(ku, dtype=np.float64)[:, None] ** 2) + b


def _check(spectrum: np.ndarray, ku: np.ndarray, axes: StoltAxes) -> np.ndarray:
    """The checks of :func:`stolt` on its arrays; returns ``ku`` as float64."""
    v.instance("stolt axes", axes, StoltAxes, "a StoltAxes")
    if spectrum.dtype.kind not in "iufc":
        raise TypeError(f"stolt spectrum: must be an array of numbers, got dtype {spectrum.dtype}")
    if spectrum.ndim != 2 or spectrum.shape[0] < 1 or spectrum.shape[1] != axes.n_src:
        raise ValueError(f"stolt spectrum: must have shape (n_ku >= 1, axes.n_src={axes.n_src}), got {spectrum.shape}")
    ku = v.array("stolt ku", ku, (spectrum.shape[0],), bound=MAX_AXIS)
    if not np.all(np.isfinite(axes.index_constants())):
        raise ValueError(f"stolt axes: must give finite source positions, got {axes}")
    return ku


def stolt_reference(spectrum, ku, axes: StoltAxes, interp: str = "sinc8", window: str = "kaiser",
                    oversampling: float = 1.25, out: np.ndarray | None = None) -> np.ndarray:
    """The float64 NumPy reference: (n_ku, n_out) complex128, or written into ``out``."""
    result = resample_rows(spectrum, axes.source_index(ku), interp, window, oversampling)
    if out is None:
        return result
    out[...] = result
    return out


def stolt_opencl(spectrum, ku, axes: StoltAxes, interp: str = "sinc8", window: str = "kaiser",
                 oversampling: float = 1.25, out: np.ndarray | None = None) -> np.ndarray:
    """The stolt_map launcher: (n_ku, n_out) complex64, written into ``out`` if given."""
    import pyopencl as cl

    def args(context):
        ku2 = cl.Buffer(context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                        hostbuf=np.asarray(ku, np.float64) ** 2)
        return ku2, np.array(axes.index_constants(), dtype=np.float64).view(cl.cltypes.double4)[0]

    return launch_rows("stolt", "stolt_map", spectrum, axes.n_out, interp, window, oversampling, out, args)


def _check_out(out, backend: str, shape: tuple[int, int]) -> None:
    allowed = (np.complex64,) if backend == "opencl" else (np.complex64, np.complex128)
    if not isinstance(out, np.ndarray) or out.shape != shape or out.dtype not in allowed \
            or not out.flags.c_contiguous or not out.flags.writeable:
        got = (f"{type(out).__name__} {getattr(out, 'shape', '')} {getattr(out, 'dtype', '')}"
               + ("" if not isinstance(out, np.ndarray) or out.flags.c_contiguous else " (not C-contiguous)"))
        raise ValueError(f"out must be a writeable C-contiguous {' or '.join(np.dtype(d).name for d in allowed)} "
                         f"array of shape {shape} for backend {backend!r}, got {got}")


def stolt(spectrum, ku, axes: StoltAxes, interp: str = "sinc8", window: str = "kaiser",
          oversampling: float = 1.25, backend: str | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """Resample each row of ``spectrum`` (n_ku, axes.n_src), uniform in baseband frequency,
    onto the uniform baseband range wavenumbers of ``axes`` (Heremans 2009 eq. 41).

    Parameters
    ----------
    spectrum : complex (n_ku, n_src), row r at along-track wavenumber ``ku[r]`` (rad/m).
    ku : float (n_ku,), rad/m.
    axes : StoltAxes, the source and output grids.
    interp : "linear", "sinc8" or "sinc16"; window : "kaiser" or "knab" (sinc only).
    oversampling : source sampling rate over the occupied band (the Knab window's parameter);
        the interpolators are :mod:`clsas.interp`'s.
    backend : "numpy", "opencl", "auto" or None (the default backend).
    out : optional C-contiguous (n_ku, axes.n_out) array to write the result into (complex64
        for OpenCL; complex64 or complex128 for NumPy), e.g. one reused for a stream of blocks
        of the same size (a fresh result is page-faulted in during the call; bench/bench_stolt.py
        times both).

    Returns
    -------
    complex (n_ku, axes.n_out): ``out`` if given, else complex128 from NumPy, complex64 from OpenCL.
    """
    check_options(interp, window, oversampling, who="stolt")
    spectrum = np.asarray(spectrum)
    ku = _check(spectrum, ku, axes)
    check_sizes("stolt spectrum", spectrum.shape, axes.n_out, interp, "axes.n_out")
    backend = _backend.resolve(backend)
    if out is not None:
        _check_out(out, backend, (spectrum.shape[0], axes.n_out))
    run = stolt_reference if backend == "numpy" else stolt_opencl
    return run(spectrum, ku, axes, interp, window, oversampling, out)
