"""The interpolators of clsas: rows of samples read at fractional positions (NumPy reference and
OpenCL launcher), and the windowed-sinc tap table every interpolating kernel shares.

One definition serves back-projection (:mod:`clsas.image.backprojection`, its records read at
the delays of the pixels), the Stolt map (:mod:`clsas.image.stolt`), range-cell-migration
correction and the micro-range shifts of the multireceiver conversion. Its kernel twin is
``kernels/interp.h`` (tap lookup and the sixteen-lane interpolation), whose ``resample_map``
kernel (``kernels/interp.cl``) :func:`resample` launches.

Interpolators (``interp``): ``"linear"``, (1 - w) s[i] + w s[i + 1]; ``"sinc8"`` and
``"sinc16"``, windowed sincs sum_t w_t s[i - taps/2 + 1 + t] with ``window`` ``"kaiser"``
(beta 5 for 8 taps, 8 for 16: the window's first sidelobe sits below the interpolation error of
the tap count; :func:`clsas.kernelmath.kaiser_sinc_tap`) or ``"knab"`` (Knab's
approximate-prolate window, w(x) = cosh(pi v (N/2) sqrt(1 - (2x/N)^2)) / cosh(pi v N / 2) with
v = 1 - 1/``oversampling``, the source's sampling rate over its occupied band; the form used by
SAR processors after Knab 1979); i = floor(position), w = position - i. The taps of a
fractional offset w come from the nearest of ``TAP_ROWS`` rows tabulated over w in [0, 1] (at
most 1/8192 sample off: 4e-4 rad at the band edge of a critically sampled spectrum, far below
the 8-tap interpolation error), each row normalised to unit sum (unit gain at DC). A position
less than half a table row (``SNAP``) below an integer reads as that integer: where positions
hit integers exactly (the Stolt map at k_u = 0), rounding then cannot decide differently in a
kernel and the reference whether an edge output has all its samples. An output reads as zero
unless all its source samples exist.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from . import backend as _backend
from . import budget, opencl
from . import validate as v
from .kernelmath import kaiser_sinc_tap

INTERPOLATORS = {"linear": 2, "sinc8": 8, "sinc16": 16}
TAP_WINDOWS = ("kaiser", "knab")
KAISER_BETA = {8: 5.0, 16: 8.0}
TAP_ROWS = 4097
SNAP = 0.5 / (TAP_ROWS - 1)  # positions this close below an integer read as the integer
ROW_BLOCK = 32  # rows a reference step (bounds its temporaries to ~ROW_BLOCK x m)
BLOCKS = 4  # blocks of 16 consecutive outputs a work-item of the row kernels (kernels/interp.h)
OUTPUTS_PER_ITEM = 16 * BLOCKS


def _window(x: np.ndarray, taps: int, window: str, oversampling: float) -> np.ndarray:
    """The Knab window at offsets x (samples) of a ``taps``-tap interpolator."""
    u = np.clip(1 - (2 * x / taps) ** 2, 0, None)
    v = 1 - 1 / oversampling
    return np.cosh(np.pi * v * taps / 2 * np.sqrt(u)) / np.cosh(np.pi * v * taps / 2)


@lru_cache(maxsize=8)
def tap_table(taps: int, window: str = "kaiser", oversampling: float = 1.25) -> np.ndarray:
    """(TAP_ROWS, taps) windowed-sinc taps: row m serves the fractional offset w = m / (TAP_ROWS - 1),
    column t the sample i - taps/2 + 1 + t; rows normalised to unit sum. float64, read-only
    (cached: the Bessel window costs milliseconds)."""
    w = np.linspace(0.0, 1.0, TAP_ROWS)[:, None]
    x = w - (np.arange(taps) - (taps // 2 - 1))[None, :]
    if window == "kaiser":
        table = kaiser_sinc_tap(x, taps / 2, KAISER_BETA[taps])
    else:
        table = np.sinc(x) * _window(x, taps, window, oversampling) * (np.abs(x) < taps / 2)
    table /= table.sum(axis=1, keepdims=True)
    table.flags.writeable = False
    return table


@lru_cache(maxsize=8)
def kernel_taps(interp: str, window: str = "kaiser", oversampling: float = 1.25) -> np.ndarray:
    """The kernels' tap table: float32 (TAP_ROWS, taps), or a placeholder for ``"linear"``. The
    kernels repeat each tap for the real and the imaginary part of a sample in registers
    (kernels/interp.h ``TAP_ROW8``): a table with the taps stored twice was slower in the Stolt
    map and no faster in back-projection."""
    if interp == "linear":
        return np.zeros(8, np.float32)
    return tap_table(INTERPOLATORS[interp], window, oversampling).astype(np.float32)


def check_options(interp: str, window: str, oversampling: float, who: str = "resample",
                  window_name: str = "window") -> None:
    """The interpolator's choices, named as the caller ``who`` calls them (``window_name``: its
    name for the tap window)."""
    v.choice(f"{who} interp", interp, sorted(INTERPOLATORS))
    v.choice(f"{who} {window_name}", window, TAP_WINDOWS)
    v.scalar(f"{who} oversampling", oversampling, low=1.0, low_open=True, why="source sampling rate over its band")


def check_sizes(caller: str, src_shape: tuple, n_out: int, interp: str, out_name: str) -> None:
    """Rows long enough for the interpolator's taps, and the result within the memory budget."""
    taps = INTERPOLATORS[interp]
    if src_shape[1] < taps:
        raise ValueError(f"{caller}: rows of {src_shape[1]} samples are too short for interp={interp!r}, which reads "
                         f"{taps} samples; give at least {taps}")
    budget.check_bytes(f"{caller} of {src_shape[0]} rows onto {out_name} = {n_out} columns", 16.0 * src_shape[0] * n_out
                       + 16.0 * min(src_shape[0], ROW_BLOCK) * n_out * (taps + 2), "fewer rows or columns at a time")


def _window_start(i: np.ndarray, taps: int, n: int):
    """(first sample read, all samples present) of an interpolator of ``taps`` taps at integer
    samples ``i`` over rows of ``n`` samples (the first sample is 0 where some are missing)."""
    first = i - (taps // 2 - 1) if taps > 2 else i
    ok = (first >= 0) & (first <= n - taps)
    return np.where(ok, first, 0), ok


def _readings(idx: np.ndarray, taps: int, n: int):
    """(first sample, fractional offset, all samples present) of fractional columns ``idx``
    (positions within SNAP below an integer read as the integer)."""
    i = np.floor(idx).astype(np.int64)
    w = idx - i
    up = w >= 1 - SNAP
    i, w = i + up, w - up
    first, ok = _window_start(i, taps, n)
    return first, w, ok


def _gather(block: np.ndarray, columns: np.ndarray, shared: bool) -> np.ndarray:
    """block[r, columns[r, j]]: the same columns for every row when ``shared`` (faster)."""
    return block[:, columns] if shared else np.take_along_axis(block, columns, 1)


def _interpolate(block: np.ndarray, first: np.ndarray, w: np.ndarray, ok: np.ndarray, shared: bool, taps: int,
                 table: np.ndarray | None) -> np.ndarray:
    """The rows of ``block`` (complex128) read from samples ``first`` at fractional offsets ``w``:
    linear, or the taps of the nearest table row; zero where not ``ok``."""
    if table is None:
        value = (1 - w) * _gather(block, first, shared) + w * _gather(block, first + 1, shared)
    else:
        row = np.floor(w * (TAP_ROWS - 1) + 0.5).astype(np.int64)
        value = sum(table[row, t] * _gather(block, first + t, shared) for t in range(taps))
    return np.where(ok, value, 0)


def _table(interp: str, window: str, oversampling: float):
    return None if interp == "linear" else tap_table(INTERPOLATORS[interp], window, oversampling)


def resample_rows(src: np.ndarray, idx: np.ndarray, interp: str = "sinc8", window: str = "kaiser",
                  oversampling: float = 1.25) -> np.ndarray:
    """Rows of ``src`` (n_rows, n) read at fractional columns ``idx``, float64: (n_rows, m) one
    row of positions per row, or (m,) the same positions for every row (then the taps are looked
    up once). The interpolators of this module, zero where a source sample is missing: the NumPy
    definition the kernels are held to. complex128 (n_rows, m)."""
    taps, table = INTERPOLATORS[interp], _table(interp, window, oversampling)
    idx = np.asarray(idx, dtype=np.float64)
    shared = idx.ndim == 1
    n = src.shape[1]
    out = np.zeros((src.shape[0], idx.shape[-1]), dtype=np.complex128)
    if shared:
        first, w, ok = _readings(idx, taps, n)
    for r0 in range(0, src.shape[0], ROW_BLOCK):
        if not shared:
            first, w, ok = _readings(idx[r0:r0 + ROW_BLOCK], taps, n)
        out[r0:r0 + ROW_BLOCK] = _interpolate(src[r0:r0 + ROW_BLOCK].astype(np.complex128), first, w, ok, shared,
                                              taps, table)
    return out


def read_rows(src: np.ndarray, i: np.ndarray, frac: np.ndarray, interp: str = "sinc8", window: str = "kaiser",
              oversampling: float = 1.25) -> np.ndarray:
    """Rows of ``src`` (n_rows, n) read at integer samples ``i`` plus fractions ``frac`` in [0, 1)
    (both (n_rows, m)): :func:`resample_rows` for positions already split (as a kernel splits
    them before taking off a record's integer offset, so that the fraction is the same whatever
    the offset), without the snap onto integers. complex128 (n_rows, m)."""
    taps, table = INTERPOLATORS[interp], _table(interp, window, oversampling)
    n = src.shape[1]
    out = np.zeros(np.shape(i), dtype=np.complex128)
    for r0 in range(0, src.shape[0], ROW_BLOCK):
        rows = slice(r0, r0 + ROW_BLOCK)
        first, ok = _window_start(np.asarray(i[rows], dtype=np.int64), taps, n)
        out[rows] = _interpolate(src[rows].astype(np.complex128), first, frac[rows], ok, False, taps, table)
    return out


def launch_rows(program: str, kernel_name: str, src: np.ndarray, n_out: int, interp: str, window: str,
                oversampling: float, out: np.ndarray | None, make_args) -> np.ndarray:
    """Run a row kernel (``resample_map`` of kernels/interp.cl, ``stolt_map`` of kernels/stolt.cl:
    work-items (ceil(n_out / OUTPUTS_PER_ITEM), n_rows) in fixed work-groups
    (:func:`clsas.opencl.work_groups_2d`: the kernel is compiled once whatever the shape), arguments
    src, taps, the kernel's own, n_src, n_out, n_rows, dst) on the rows of ``src``: (n_rows, n_out)
    complex64, into ``out`` if given. ``make_args(context)`` gives the kernel's own arguments."""
    import pyopencl as cl

    rt = opencl.runtime()
    mf = cl.mem_flags
    defines = {"INTERP_LINEAR": 1} if interp == "linear" else {"TAPS": INTERPOLATORS[interp]}
    defines.update(TAP_ROWS=TAP_ROWS, BLOCKS=BLOCKS)  # TAP_ROWS also sets the snap of positions onto integers
    knl = opencl.kernel(program, kernel_name, defines=defines)
    # host memory is used in place (USE_HOST_PTR: on a CPU device no copy is made) and the
    # result is read back by mapping the output buffer
    src = np.ascontiguousarray(src, dtype=np.complex64)
    src_buf = cl.Buffer(rt.context, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=src)
    tap_buf = cl.Buffer(rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=kernel_taps(interp, window, oversampling))
    if out is None:
        out = np.empty((src.shape[0], n_out), dtype=np.complex64)
    dst = cl.Buffer(rt.context, mf.WRITE_ONLY | mf.USE_HOST_PTR, hostbuf=out)
    knl(rt.queue, *opencl.work_groups_2d(-(-n_out // OUTPUTS_PER_ITEM), src.shape[0]), src_buf, tap_buf,
        *make_args(rt.context), np.int32(src.shape[1]), np.int32(n_out), np.int32(src.shape[0]), dst)
    mapped, _ = cl.enqueue_map_buffer(rt.queue, dst, cl.map_flags.READ, 0, out.shape, out.dtype)
    mapped.base.release()
    return out


def resample_opencl(src, idx, interp: str = "sinc8", window: str = "kaiser", oversampling: float = 1.25) -> np.ndarray:
    """The resample_map launcher: :func:`resample_rows` in float32, (n_rows, m) complex64."""
    import pyopencl as cl

    idx = np.ascontiguousarray(idx, dtype=np.float64)

    def args(context):
        buf = cl.Buffer(context, cl.mem_flags.READ_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=idx)
        return buf, np.int32(0 if idx.ndim == 1 else idx.shape[1])

    return launch_rows("interp", "resample_map", src, idx.shape[-1], interp, window, oversampling, None, args)


def resample(src, idx, interp: str = "sinc8", window: str = "kaiser", oversampling: float = 1.25,
             backend: str | None = None) -> np.ndarray:
    """Rows of ``src`` read at fractional columns ``idx`` (see the module docstring and
    :func:`resample_rows`, the NumPy reference, for the definition).

    Parameters
    ----------
    src : complex (n_rows, n).
    idx : float (n_rows, m) positions per row, or (m,) shared by every row, in samples of src.
    interp : "linear", "sinc8" or "sinc16"; window : "kaiser" or "knab" (sinc only).
    oversampling : source sampling rate over the occupied band (the Knab window's parameter).
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
    check_sizes("resample src", src.shape, idx.shape[-1], interp, "the positions of idx")
    return resample_prechecked(src, idx, interp, window, oversampling, backend)


def resample_prechecked(src: np.ndarray, idx: np.ndarray, interp: str = "sinc8", window: str = "kaiser",
                        oversampling: float = 1.25, backend: str | None = None) -> np.ndarray:
    """:func:`resample` without its checks, for a caller that makes ``src`` and ``idx`` itself and
    calls it many times (one call per receiver and sub-block in :func:`clsas.ptrs_image`): the
    caller has checked once what :func:`resample` checks on every call, ``interp``, ``window``
    and ``oversampling`` (:func:`check_options`), rows of at least the interpolator's taps and
    the memory budget of its largest call (:func:`check_sizes`), and made ``idx`` finite
    float64 positions within +-2**30 (:func:`resample` scans every position again on each call).
    ``src`` complex (n_rows, n); ``idx`` (n_rows, m) or (m,). Returns what :func:`resample`
    returns."""
    if _backend.resolve(backend) == "numpy":
        return resample_rows(src, idx, interp, window, oversampling)
    return resample_opencl(src, idx, interp, window, oversampling)
