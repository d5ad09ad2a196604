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

Interpolators (``interp``): ``"linear"``; ``"sinc8"`` and ``"sinc16"``, windowed sincs with
``window`` ``"kaiser"`` (beta 5 for 8 taps, 8 for 16: the window's first sidelobe sits below
the interpolation error of the tap count) or ``"knab"`` (Knab's approximate-prolate window,
w(x) = cosh(pi v (N/2) sqrt(1 - (2x/N)^2)) / cosh(pi v N / 2) with v = 1 - 1/``oversampling``,
the source's sampling rate over its occupied band; the form used by SAR processors after
Knab 1979). The taps of a fractional offset w come from the nearest of ``TAP_ROWS`` rows
tabulated over w in [0, 1] (at most 1/8192 sample off: 4e-4 rad at the band edge of a
critically sampled spectrum, far below the 8-tap interpolation error), and each row is
normalised to unit sum (unit gain at DC). A position less than half a table row (``SNAP``)
below an integer reads as that integer: where the map hits integers exactly (k_u = 0 with
dkx = 4 pi df / c), rounding then cannot decide differently in the kernel and the reference
whether an edge output has all its samples. An output reads as zero unless all its source
samples exist (the spectrum must be zero-padded where the mapping needs more).

The kernel (``kernels/stolt.cl``) computes the first position of each work-item's 64 outputs
in double and the others relative to it in float (~1e-5 sample), and the interpolation in
float; the reference does everything in float64 with the same table. They differ by float
rounding, and where a position's rounding picks the neighbouring tap row (1/4096 sample
apart): relative L2 1e-6 (linear) to 3e-5 (sinc) on the bench's 4096 x 4096 axes, bounded
by 1e-4 in tests/test_stolt.py. ``resample_map`` reads its positions in double.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .. import backend as _backend
from .. import budget, opencl
from .. import validate as v

INTERPOLATORS = {"linear": 2, "sinc8": 8, "sinc16": 16}
TAP_WINDOWS = ("kaiser", "knab")
KAISER_BETA = {8: 5.0, 16: 8.0}
TAP_ROWS = 4097
SNAP = 0.5 / (TAP_ROWS - 1)  # positions this close below an integer read as the integer
ROW_BLOCK = 32  # rows a reference step (bounds its temporaries to ~ROW_BLOCK x n_out x taps)
OUTPUTS_PER_ITEM = 64  # one work-item's consecutive outputs of a row (16 x BLOCKS in kernels/stolt.cl)


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

    def index_constants(self) -> tuple[float, float, float, float]:
        """(K0, dkx, A, Bc) with idx = A sqrt((K0 + j dkx)^2 + k_u^2) + Bc (the kernel's params)."""
        k0 = 2 * np.pi * self.f0 / self.c
        return (self.kx_first + 2 * k0, self.dkx, self.c / (4 * np.pi * self.df), -(self.f0 + self.f_first) / self.df)

    def source_index(self, ku: np.ndarray) -> np.ndarray:
        """Fractional source columns (len(ku), n_out), float64."""
        k0, dkx, a, b = self.index_constants()
        k = k0 + dkx * np.arange(self.n_out)
        return a * np.sqrt(k[None, :] ** 2 + np.asarray(ku, dtype=np.float64)[:, None] ** 2) + b


def _window(x: np.ndarray, taps: int, window: str, oversampling: float) -> np.ndarray:
    u = np.clip(1 - (2 * x / taps) ** 2, 0, None)
    if window == "kaiser":
        beta = KAISER_BETA[taps]
        return np.i0(beta * np.sqrt(u)) / np.i0(beta)
    v = 1 - 1 / oversampling
    return np.cosh(np.pi * v * taps / 2 * np.sqrt(u)) / np.cosh(np.pi * v * taps / 2)


@lru_cache(maxsize=8)
def tap_table(taps: int, window: str = "kaiser", oversampling: float = 1.25) -> np.ndarray:
    """(TAP_ROWS, taps) windowed-sinc taps: row m serves the fractional offset w = m / (TAP_ROWS - 1),
    column t the sample i - taps/2 + 1 + t; rows normalised to unit sum. float64, read-only
    (cached: the Bessel window costs milliseconds)."""
    w = np.linspace(0.0, 1.0, TAP_ROWS)[:, None]
    x = w - (np.arange(taps) - (taps // 2 - 1))[None, :]
    table = np.sinc(x) * _window(x, taps, window, oversampling) * (np.abs(x) < taps / 2)
    table /= table.sum(axis=1, keepdims=True)
    table.flags.writeable = False
    return table


@lru_cache(maxsize=8)
def _kernel_taps(interp: str, window: str, oversampling: float) -> np.ndarray:
    """The kernel's tap table: float32 (TAP_ROWS, taps) (the kernel repeats each tap for re and im
    in registers: a table with the taps stored twice was slower)."""
    if interp == "linear":
        return np.zeros(8, np.float32)  # unused by the linear kernel
    return tap_table(INTERPOLATORS[interp], window, oversampling).astype(np.float32)


def check_options(interp: str, window: str, oversampling: float) -> None:
    if interp not in INTERPOLATORS:
        raise ValueError(f"interp must be one of {sorted(INTERPOLATORS)}, got {interp!r}")
    if window not in TAP_WINDOWS:
        raise ValueError(f"window must be one of {TAP_WINDOWS}, got {window!r}")
    v.scalar("oversampling", oversampling, low=1.0, low_open=True, why="source sampling rate over its band")


def _check_sizes(caller: str, src_shape: tuple, n_out: int, interp: str, out_name: str) -> None:
    """Rows long enough for the interpolator's taps, and the result within the memory budget."""
    taps = INTERPOLATORS[interp]
    if src_shape[1] < taps:
        raise ValueError(f"{caller}: rows of {src_shape[1]} samples are too short for interp={interp!r}, which reads "
                         f"{taps} samples; give at least {taps}")
    budget.check_bytes(f"{caller} of {src_shape[0]} rows onto {out_name} = {n_out} columns", 16.0 * src_shape[0] * n_out
                       + 16.0 * min(src_shape[0], ROW_BLOCK) * n_out * (taps + 2), "fewer rows or columns at a time")


def _check(spectrum: np.ndarray, ku: np.ndarray, axes: StoltAxes) -> None:
    if not isinstance(axes, StoltAxes):
        raise TypeError(f"axes must be a StoltAxes, got {type(axes).__name__}")
    if spectrum.ndim != 2 or spectrum.shape[1] != axes.n_src:
        raise ValueError(f"spectrum must have shape (n_ku, axes.n_src={axes.n_src}), got {spectrum.shape}")
    if ku.shape != (spectrum.shape[0],) or not np.all(np.isfinite(ku)):
        raise ValueError(f"ku must hold one finite wavenumber per spectrum row ({spectrum.shape[0]}), got {ku.shape}")
    if axes.n_out < 1 or not (axes.df > 0 and axes.dkx > 0):
        raise ValueError(f"axes need n_out >= 1 and positive df, dkx, got {axes}")
    if not np.all(np.isfinite(axes.index_constants())):
        raise ValueError(f"axes: must give finite source positions, got {axes}")


def _readings(idx: np.ndarray, taps: int, n: int):
    """(first sample, fractional offset, all samples present) of fractional columns ``idx``
    for an interpolator of ``taps`` taps over rows of ``n`` samples (positions within SNAP
    below an integer read as the integer)."""
    i = np.floor(idx).astype(np.int64)
    w = idx - i
    up = w >= 1 - SNAP
    i, w = i + up, w - up
    first = i - (taps // 2 - 1) if taps > 2 else i
    ok = (first >= 0) & (first <= n - taps)
    return np.where(ok, first, 0), w, ok


def _gather(block: np.ndarray, columns: np.ndarray, shared: bool) -> np.ndarray:
    """block[r, columns[r, j]]: the same columns for every row when ``shared`` (faster)."""
    return block[:, columns] if shared else np.take_along_axis(block, columns, 1)


def resample_rows(src: np.ndarray, idx: np.ndarray, interp: str = "sinc8", window: str = "kaiser",
                  oversampling: float = 1.25) -> np.ndarray:
    """Rows of ``src`` (n_rows, n) read at fractional columns ``idx``, float64: (n_rows, m) one
    row of positions per row, or (m,) the same positions for every row (then the taps are looked
    up once). The interpolator of this module (linear, or windowed sinc from the nearest
    tap-table row), zero where a source sample is missing. The NumPy definition the Stolt kernel
    is held to; the other imagers use it for their range interpolations (RCMC, micro-range
    shifts). complex128 (n_rows, m)."""
    taps = INTERPOLATORS[interp]
    table = None if interp == "linear" else tap_table(taps, window, oversampling)
    idx = np.asarray(idx, dtype=np.float64)
    shared = idx.ndim == 1
    n = src.shape[1]
    out = np.zeros((src.shape[0], idx.shape[-1]), dtype=np.complex128)
    if shared:
        start, w, ok = _readings(idx, taps, n)
    for r0 in range(0, src.shape[0], ROW_BLOCK):
        block = src[r0:r0 + ROW_BLOCK].astype(np.complex128)
        if not shared:
            start, w, ok = _readings(idx[r0:r0 + ROW_BLOCK], taps, n)
        if table is None:
            value = (1 - w) * _gather(block, start, shared) + w * _gather(block, start + 1, shared)
        else:
            weights = table[np.floor(w * (TAP_ROWS - 1) + 0.5).astype(np.int64)]
            value = sum(weights[..., t] * _gather(block, start + t, shared) for t in range(taps))
        out[r0:r0 + ROW_BLOCK] = np.where(ok, value, 0)
    return out


def stolt_reference(spectrum, ku, axes: StoltAxes, interp: str = "sinc8", window: str = "kaiser",
                    oversampling: float = 1.25, out: np.ndarray | None = None) -> np.ndarray:
    """The float64 NumPy reference: (n_ku, n_out) complex128, or written into ``out``."""
    result = resample_rows(spectrum, axes.source_index(ku), interp, window, oversampling)
    if out is None:
        return result
    out[...] = result
    return out


def _launch(kernel_name: str, src: np.ndarray, n_out: int, interp: str, window: str, oversampling: float,
            out: np.ndarray | None, make_args) -> np.ndarray:
    """Run ``kernel_name`` of kernels/stolt.cl on the rows of ``src``: (n_rows, n_out) complex64
    (into ``out`` if given). ``make_args(context)`` gives the kernel's own arguments between the
    tap table and n_src."""
    import pyopencl as cl

    rt = opencl.runtime()
    mf = cl.mem_flags
    defines = {"INTERP_LINEAR": 1} if interp == "linear" else {"TAPS": INTERPOLATORS[interp]}
    defines["TAP_ROWS"] = TAP_ROWS  # also sets the snap of positions onto integers
    knl = opencl.kernel("stolt", kernel_name, defines=defines)
    # host memory is used in place (USE_HOST_PTR: on a CPU device no copy is made) and the
    # result is read back by mapping the output buffer
    src = np.ascontiguousarray(src, dtype=np.complex64)
    src_buf = cl.Buffer(rt.context, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=src)
    tap_buf = cl.Buffer(rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=_kernel_taps(interp, window, oversampling))
    if out is None:
        out = np.empty((src.shape[0], n_out), dtype=np.complex64)
    dst = cl.Buffer(rt.context, mf.WRITE_ONLY | mf.USE_HOST_PTR, hostbuf=out)
    knl(rt.queue, (-(-n_out // OUTPUTS_PER_ITEM), src.shape[0]), None, src_buf, tap_buf, *make_args(rt.context),
        np.int32(src.shape[1]), np.int32(n_out), dst)
    mapped, _ = cl.enqueue_map_buffer(rt.queue, dst, cl.map_flags.READ, 0, out.shape, out.dtype)
    mapped.base.release()
    return out


def stolt_opencl(spectrum, ku, axes: StoltAxes, interp: str = "sinc8", window: str = "kaiser",
                 oversampling: float = 1.25, out: np.ndarray | None = None) -> np.ndarray:
    """The stolt_map launcher: (n_ku, n_out) complex64, written into ``out`` if given."""
    import pyopencl as cl

    def args(context):
        ku2 = cl.Buffer(context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                        hostbuf=np.asarray(ku, np.float64) ** 2)
        return ku2, np.array(axes.index_constants(), dtype=np.float64).view(cl.cltypes.double4)[0]

    return _launch("stolt_map", spectrum, axes.n_out, interp, window, oversampling, out, args)


def resample_opencl(src, idx, interp: str = "sinc8", window: str = "kaiser", oversampling: float = 1.25) -> np.ndarray:
    """The resample_map launcher: :func:`resample_rows` in float32, (n_rows, m) complex64."""
    import pyopencl as cl

    idx = np.ascontiguousarray(idx, dtype=np.float64)

    def args(context):
        buf = cl.Buffer(context, cl.mem_flags.READ_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=idx)
        return buf, np.int32(0 if idx.ndim == 1 else idx.shape[1])

    return _launch("resample_map", src, idx.shape[-1], interp, window, oversampling, None, args)


def resample(src, idx, interp: str = "sinc8", window: str = "kaiser", oversampling: float = 1.25,
             backend: str | None = None) -> np.ndarray:
    """Rows of ``src`` read at fractional columns ``idx``: the interpolators of this module at
    explicit positions (see :func:`resample_rows`, the NumPy reference, for the definition).

    Parameters
    ----------
    src : complex (n_rows, n).
    idx : float (n_rows, m) positions per row, or (m,) shared by every row, in samples of src.
    interp, window, oversampling : as for :func:`stolt`.
    backend : "numpy", "opencl", "auto" or None (the default backend).

    Returns
    -------
    complex (n_rows, m): complex128 from NumPy, complex64 from OpenCL.
    """
    check_options(interp, window, oversampling)
    src = np.asarray(src)
    if src.dtype.kind not in "iufc":
        raise TypeError(f"resample src: must be a 2-D array of numbers (rows, samples), got dtype {src.dtype}")
    if src.ndim != 2 or src.shape[0] < 1 or src.shape[1] < 1:
        raise ValueError(f"resample src: must be a non-empty 2-D array (rows, samples), got shape {src.shape}")
    idx = v.array("resample idx", idx, (-1,) if np.ndim(idx) == 1 else (src.shape[0], -1), bound=2**30, copy=False)
    if idx.shape[-1] < 1:
        raise ValueError(f"resample idx: must be (m,) or (n_rows={src.shape[0]}, m) positions, got shape {idx.shape}")
    _check_sizes("resample src", src.shape, idx.shape[-1], interp, "the positions of idx")
    if _backend.resolve(backend) == "numpy":
        return resample_rows(src, idx, interp, window, oversampling)
    return resample_opencl(src, idx, interp, window, oversampling)


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
    oversampling : source sampling rate over the occupied band (the Knab window's parameter).
    backend : "numpy", "opencl", "auto" or None (the default backend).
    out : optional C-contiguous (n_ku, axes.n_out) array to write the result into (complex64
        for OpenCL; complex64 or complex128 for NumPy), e.g. one reused for a stream of blocks
        of the same size: a fresh 4096 x 4096 result costs ~10 ms of page faults.

    Returns
    -------
    complex (n_ku, axes.n_out): ``out`` if given, else complex128 from NumPy, complex64 from OpenCL.
    """
    check_options(interp, window, oversampling)
    spectrum = np.asarray(spectrum)
    ku = np.asarray(ku, dtype=np.float64)
    _check(spectrum, ku, axes)
    _check_sizes("stolt spectrum", spectrum.shape, axes.n_out, interp, "axes.n_out")
    backend = _backend.resolve(backend)
    if out is not None:
        _check_out(out, backend, (spectrum.shape[0], axes.n_out))
    run = stolt_reference if backend == "numpy" else stolt_opencl
    return run(spectrum, ku, axes, interp, window, oversampling, out)
