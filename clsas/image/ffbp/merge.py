"""The merge of fast factorised back-projection: children's polar images read at the parent's
samples (or at the user's pixels), their phase restored and summed (NumPy reference and the
kernels/ffbp.cl launcher).

A child image J_c on its polar grid (r_c, v_c) is the sub-aperture's back-projected image I_c
demodulated by its own centre range: J_c = I_c exp(-j 4 pi f0 r_c / c). At a point X (a parent
sample or a pixel) the merge forms

    out(X) = sum_c J_c(r_c(X), v_c(X)) exp(+j 4 pi f0 (r_c(X) - r_p(X)) / c),

the child read by the separable ``taps`` x ``taps`` windowed sinc of
:func:`clsas.interp.tap_table` (Knab's window for the oversampling ``rho``; positions in
samples i = (r - r0) / dr and j = (v - v0) / dv; the taps of a fractional offset come from the
nearest of clsas.interp.TAP_ROWS table rows), zero unless all taps x taps samples exist; r_p is the
parent's centre range for a parent grid (the parent is demodulated in turn; its samples outside
its rows' spans, PolarGrid.spans, are zero) and 0 for pixels (the final stage restores the full
phase, giving back-projection's image). Phases in cycles,
2 f0 (r_c - r_p) / c, reduced to their fraction before the exponential.

The kernel computes X, r_c, v_c, the positions and the phase in double, the interpolation and
the sum in float; the reference does everything in float64.

Why one T x T read and not two passes (angle down the child's columns to the parent's rows,
then range along them: T + T reads from contiguous samples, the child's range band widened by
|dv_c/dr| W_v to keep the error model): built and held to its reference (commits 2c6580e ..
27a3d0e), it was slower on PoCL 3.1 / AVX-512, its helpers inlined or not (the same merges
both ways, interleaved):
the eight row reads are only about half of this kernel's cost; the rest (geometry, phase, the
lanes' own tap rows and their cross-lane sums) two passes pay once each over as many (sample,
child) pairs.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache

import numpy as np

from ... import opencl
from ...interp import TAP_ROWS, tap_table
from ...kernelmath import expj_cycles
from . import program
from .polar import PolarGrid

KERNEL_TAPS = (4, 8)
CHUNK = 2**16  # output samples a reference step
LANES = 16  # output samples a work-item of kernels/ffbp.cl


@dataclasses.dataclass(frozen=True)
class DevicePoints:
    """``count`` points (count, 3) float64, m, in the device buffer ``buffer``."""

    buffer: object
    count: int


def _interpolate(image: np.ndarray, grid: PolarGrid, r: np.ndarray, v: np.ndarray, table: np.ndarray) -> np.ndarray:
    """image (n_v, n_r) read at (r, v) (K,) by the separable windowed sinc of ``table``, complex128 (K,)."""
    taps = table.shape[1]
    out = np.zeros(r.shape, np.complex128)
    firsts, weights, ok = [], [], np.ones(r.shape, bool)
    for pos, n in (((v - grid.v0) / grid.dv, grid.n_v), ((r - grid.r0) / grid.dr, grid.n_r)):
        i = np.floor(pos)
        first = i.astype(np.int64) - (taps // 2 - 1)
        ok &= (first >= 0) & (first <= n - taps)
        firsts.append(np.where(ok, first, 0))
        weights.append(table[np.floor((pos - i) * (TAP_ROWS - 1) + 0.5).astype(np.int64)])
    for a in range(taps):
        for b in range(taps):
            out += weights[0][:, a] * weights[1][:, b] * image[firsts[0] + a, firsts[1] + b]
    return np.where(ok, out, 0)


def merge_reference(children, targets, f0: float, c: float, taps: int, rho: float) -> np.ndarray:
    """The float64 NumPy merge: ``children`` a list of (PolarGrid, image (n_v, n_r)); ``targets``
    the parent PolarGrid (returns its demodulated image (n_v, n_r)) or points (M, 3) m (returns
    the pixels' values (M,)). complex128."""
    table = tap_table(taps, "knab", float(rho))
    parent = targets if isinstance(targets, PolarGrid) else None
    shape = (parent.n_v, parent.n_r) if parent is not None else targets.shape[:-1]
    out = np.zeros(int(np.prod(shape)), np.complex128)
    rows_per_chunk = max(1, CHUNK // parent.n_r) if parent is not None else 0
    n_chunks = -(-shape[0] // rows_per_chunk) if parent is not None else -(-out.size // CHUNK)
    for k in range(n_chunks):
        if parent is not None:
            rows = slice(k * rows_per_chunk, min((k + 1) * rows_per_chunk, parent.n_v))
            x = parent.points(rows).reshape(-1, 3)
            r_p = np.broadcast_to(parent.ranges, (rows.stop - rows.start, parent.n_r)).reshape(-1)
            part = slice(rows.start * parent.n_r, rows.stop * parent.n_r)
        else:
            part = slice(k * CHUNK, min((k + 1) * CHUNK, out.size))
            x = targets.reshape(-1, 3)[part]
            r_p = 0.0
        for grid, image in children:
            r, v = grid.coordinates(x)
            out[part] += _interpolate(image, grid, r, v, table) * expj_cycles(2 * f0 * (r - r_p) / c)
    if parent is not None:  # zero outside the parent's rows' spans
        out *= parent.inside().reshape(-1)
    return out.reshape(shape)


def merge_opencl(children, targets, f0: float, c: float, taps: int, rho: float, out: np.ndarray | None = None):
    """The ffbp_merge launcher (kernels/ffbp.cl) on host arrays: as :func:`merge_reference` in
    float32 (geometry, positions and phases in double), complex64; for points, the result is
    *added* into ``out`` (M,) complex64 when given. The images go to the device and the result
    comes back (:func:`merge_device` is the launch itself)."""
    import pyopencl as cl

    rt = opencl.runtime()
    mf = cl.mem_flags
    images = np.concatenate([np.ascontiguousarray(img, np.complex64).reshape(-1) for _, img in children])
    offsets = np.cumsum([0] + [img.size for _, img in children])[:-1]
    parent = targets if isinstance(targets, PolarGrid) else None
    if parent is not None:
        result = np.empty((parent.n_v, parent.n_r), np.complex64)
        points = None
    else:
        result = np.zeros(targets.shape[:-1], np.complex64) if out is None else out
        flat = np.ascontiguousarray(targets.reshape(-1, 3), np.float64)
        points = DevicePoints(cl.Buffer(rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=flat), flat.shape[0])
    src = cl.Buffer(rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=images)
    dst = cl.Buffer(rt.context, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=result)
    merge_device([g for g, _ in children], src, offsets, parent if parent is not None else points, f0, c, taps, rho,
                 dst)
    cl.enqueue_copy(rt.queue, result, dst)
    return result


def merge_device(grids: list, images, offsets, targets, f0: float, c: float, taps: int, rho: float, out,
                 out_offset: int = 0, store: bool = False) -> None:
    """Enqueue ffbp_merge (kernels/ffbp.cl) on device buffers, without waiting: the children's
    polar grids ``grids`` and their complex64 images in the buffer ``images`` at element
    ``offsets``; ``targets`` the parent PolarGrid (its demodulated image is written to ``out``
    from element ``out_offset`` on, zero outside its rows' spans; a work-item wholly outside
    them only writes its zeros) or :class:`DevicePoints` (their values are *added* into
    ``out`` (count,) complex64, or with ``store`` written over it, every point)."""
    import pyopencl as cl

    if taps not in KERNEL_TAPS:
        raise ValueError(f"taps must be one of {KERNEL_TAPS} for the OpenCL merge, got {taps!r}")
    rt = opencl.runtime()
    ctx, mf = rt.context, cl.mem_flags
    if isinstance(targets, PolarGrid):
        kern = program.kernel("ffbp_merge", taps, PARENT_GRID=1)
        n_out, size = targets.size, opencl.work_groups_2d(-(-targets.n_r // LANES), targets.n_v)
        parent, points, spans = program.frames([targets])[0], images, targets.row_spans  # points unused
    else:
        kern = program.kernel("ffbp_merge", taps, **({"POINTS_STORE": 1} if store else {}))
        n_out, size = targets.count, opencl.work_groups(-(-targets.count // LANES))
        parent, points, spans = np.zeros((), program.FRAME)[()], targets.buffer, np.zeros((1, 2), np.int32)
    plane = program.plane(grids[0].plane)

    def made(a):
        return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))

    kern(rt.queue, *size, images, made(np.asarray(offsets, np.int64)), made(program.frames(grids)),
         made(_table(taps, float(rho))), points, parent, made(spans), plane, np.float64(2 * f0 / c),
         np.int32(len(grids)), np.int32(n_out), np.int64(out_offset), out)


@lru_cache(maxsize=8)
def _table(taps: int, rho: float) -> np.ndarray:
    return tap_table(taps, "knab", rho).astype(np.float32)
