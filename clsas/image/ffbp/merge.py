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

Two passes (children sampled for it, PolarGrid.separable, all of them on the parent's axis:
C_c = C_p + a u; polar.py's "Two-pass merge" gives the band this needs). Pass 1 (angle) reads
each child column i (range r_i) at the sine v_c(r_i) where the parent's row j meets it,

    T_c[j, i] = J_c(r_i, v_c),   r_p = a v_j + sqrt(r_i^2 - a^2 (1 - v_j^2)),   v_c = (r_p v_j - a) / r_i,

by ``taps`` angle taps down the column (zero unless the row meets that range, r_i^2 >= a^2
(1 - v_j^2), and every tap exists); pass 2 (range) reads the row T_c[j, :] at the child range of
each parent sample, r_c = sqrt(r_p^2 - 2 a r_p v_j + a^2), by ``taps`` range taps (zero unless
every tap exists), and restores the phase as above. ``taps`` + ``taps`` reads an output and
child instead of ``taps`` x ``taps``, each pass from contiguous samples (the pass-1 rows of a
work-item's columns, the pass-2 row).
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
SEPARABLE_TAPS = (8,)  # interpolators with the two-pass kernels (ffbp_angle, ffbp_range)
TWO_PASS = True  # False: every merge T x T and no child widened (for comparison: bench_ffbp --passes, tests)
CHUNK = 2**16  # output samples a reference step
LANES = 16  # output samples a work-item of kernels/ffbp.cl


@dataclasses.dataclass(frozen=True)
class DevicePoints:
    """``count`` points (count, 3) float64, m, in the device buffer ``buffer``."""

    buffer: object
    count: int


def _window(pos: np.ndarray, n: int, table: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The interpolator's window at positions ``pos`` (samples) of an axis of n samples: its first
    sample (0 where it does not fit), the taps (pos.shape + (taps,)) of the nearest table row, and
    whether every tap exists."""
    taps = table.shape[1]
    i = np.floor(pos)
    first = i.astype(np.int64) - (taps // 2 - 1)
    ok = (first >= 0) & (first <= n - taps)
    return np.where(ok, first, 0), table[np.floor((pos - i) * (TAP_ROWS - 1) + 0.5).astype(np.int64)], ok


def _interpolate(image: np.ndarray, grid: PolarGrid, r: np.ndarray, v: np.ndarray, table: np.ndarray) -> np.ndarray:
    """image (n_v, n_r) read at (r, v) (K,) by the separable windowed sinc of ``table``, complex128 (K,)."""
    taps = table.shape[1]
    out = np.zeros(r.shape, np.complex128)
    first_v, w_v, ok_v = _window((v - grid.v0) / grid.dv, grid.n_v, table)
    first_r, w_r, ok_r = _window((r - grid.r0) / grid.dr, grid.n_r, table)
    for a in range(taps):
        for b in range(taps):
            out += w_v[:, a] * w_r[:, b] * image[first_v + a, first_r + b]
    return np.where(ok_v & ok_r, out, 0)


def separable(grids: list, taps: int) -> bool:
    """Whether a merge of children ``grids`` goes in two passes (module docstring): every child
    sampled for it (PolarGrid.separable, which the plan sets only for children on their parent's
    axis) and an interpolator the kernel has it for."""
    return taps in SEPARABLE_TAPS and all(g.separable for g in grids)


def offset_along(grid: PolarGrid, parent: PolarGrid) -> float:
    """a = u . (C_c - C_p) (m): the child's centre along its parent's axis (on it: two passes)."""
    return float(parent.axis @ (grid.centre - parent.centre))


def _two_pass(image: np.ndarray, grid: PolarGrid, parent: PolarGrid, rows: slice, table: np.ndarray, cycles_per_m: float
              ) -> np.ndarray:
    """One child's contribution to the parent's rows ``rows`` by the two passes (module
    docstring), phase restored and re-demodulated, complex128 (rows, n_r)."""
    taps = table.shape[1]
    a = offset_along(grid, parent)
    v = parent.sines[rows][:, None]
    r = grid.ranges[None, :]
    disc = r * r - a * a * (1 - v * v)
    r_p = a * v + np.sqrt(np.maximum(disc, 0.0))
    first, w, ok = _window(((r_p * v - a) / r - grid.v0) / grid.dv, grid.n_v, table)  # pass 1: down each column
    cols = np.arange(grid.n_r)[None, :]
    t = np.zeros(first.shape, np.complex128)
    for k in range(taps):
        t += w[..., k] * image[first + k, cols]
    t = np.where(ok & (disc >= 0), t, 0)
    r_p = parent.ranges[None, :]
    r_c = np.sqrt(r_p * r_p - 2 * a * r_p * v + a * a)
    first, w, ok = _window((r_c - grid.r0) / grid.dr, grid.n_r, table)  # pass 2: along each row
    row = np.arange(t.shape[0])[:, None]
    out = np.zeros(first.shape, np.complex128)
    for k in range(taps):
        out += w[..., k] * t[row, first + k]
    return np.where(ok, out, 0) * expj_cycles(cycles_per_m * (r_c - r_p))


def merge_reference(children, targets, f0: float, c: float, taps: int, rho: float) -> np.ndarray:
    """The float64 NumPy merge: ``children`` a list of (PolarGrid, image (n_v, n_r)); ``targets``
    the parent PolarGrid (returns its demodulated image (n_v, n_r)) or points (M, 3) m (returns
    the pixels' values (M,)). complex128."""
    table = tap_table(taps, "knab", float(rho))
    parent = targets if isinstance(targets, PolarGrid) else None
    shape = (parent.n_v, parent.n_r) if parent is not None else targets.shape[:-1]
    two_pass = parent is not None and separable([g for g, _ in children], taps)
    out = np.zeros(int(np.prod(shape)), np.complex128)
    widest = max([parent.n_r] + [g.n_r for g, _ in children]) if two_pass else parent.n_r if parent is not None else 0
    rows_per_chunk = max(1, CHUNK // widest) if parent is not None else 0
    n_chunks = -(-shape[0] // rows_per_chunk) if parent is not None else -(-out.size // CHUNK)
    for k in range(n_chunks):
        if parent is not None:
            rows = slice(k * rows_per_chunk, min((k + 1) * rows_per_chunk, parent.n_v))
            x = None if two_pass else parent.points(rows).reshape(-1, 3)
            r_p = np.broadcast_to(parent.ranges, (rows.stop - rows.start, parent.n_r)).reshape(-1)
            part = slice(rows.start * parent.n_r, rows.stop * parent.n_r)
        else:
            part = slice(k * CHUNK, min((k + 1) * CHUNK, out.size))
            x = targets.reshape(-1, 3)[part]
            r_p = 0.0
        for grid, image in children:
            if two_pass:
                out[part] += _two_pass(image, grid, parent, rows, table, 2 * f0 / c).reshape(-1)
                continue
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
                 out_offset: int = 0, store: bool = False, scratch: "Scratch | None" = None) -> None:
    """Enqueue ffbp_merge (kernels/ffbp.cl) on device buffers, without waiting: the children's
    polar grids ``grids`` and their complex64 images in the buffer ``images`` at element
    ``offsets``; ``targets`` the parent PolarGrid (its demodulated image is written to ``out``
    from element ``out_offset`` on, zero outside its rows' spans; a work-item wholly outside
    them only writes its zeros) or :class:`DevicePoints` (their values are *added* into
    ``out`` (count,) complex64, or with ``store`` written over it, every point). A parent whose
    children are :func:`separable` is merged in two passes instead (ffbp_angle into ``scratch``'s
    buffer, then ffbp_range; the queue is in order, so one scratch serves every merge)."""
    import pyopencl as cl

    if taps not in KERNEL_TAPS:
        raise ValueError(f"taps must be one of {KERNEL_TAPS} for the OpenCL merge, got {taps!r}")
    rt = opencl.runtime()
    ctx, mf = rt.context, cl.mem_flags
    if isinstance(targets, PolarGrid) and separable(grids, taps):
        _two_pass_device(grids, images, offsets, targets, f0, c, taps, rho, out, out_offset,
                         scratch if scratch is not None else Scratch())
        return
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


class Scratch:
    """A device buffer for the two-pass merge's intermediate rows, grown as merges need it and
    reused by the next (the in-order queue runs one merge's passes before the next one's)."""

    def __init__(self):
        self.buffer, self.bytes = None, 0

    def get(self, nbytes: int):
        import pyopencl as cl

        if nbytes > self.bytes:
            rt = opencl.runtime()
            self.buffer, self.bytes = cl.Buffer(rt.context, cl.mem_flags.READ_WRITE, nbytes), nbytes
        return self.buffer


def scratch_samples(grids: list, parent: PolarGrid) -> int:
    """Samples of the two-pass merge's intermediate rows: each child's n_r for each parent row."""
    return parent.n_v * sum(g.n_r for g in grids)


def _two_pass_device(grids, images, offsets, parent, f0, c, taps, rho, out, out_offset, scratch: Scratch) -> None:
    """Enqueue ffbp_angle (children's columns down to the parent's rows, into ``scratch``) and
    ffbp_range (those rows along range to the parent's samples, phase restored, into ``out``)."""
    import pyopencl as cl

    rt = opencl.runtime()
    ctx, mf = rt.context, cl.mem_flags

    def made(a):
        return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))

    rows = np.cumsum([0] + [parent.n_v * g.n_r for g in grids])
    buffer = scratch.get(8 * int(rows[-1]))
    frames, table = made(program.frames(grids)), made(_table(taps, float(rho)))
    parent_frame, spans, starts = program.frames([parent])[0], made(parent.row_spans), made(rows[:-1].astype(np.int64))
    group = opencl.WORK_GROUP
    size = ((-(-parent.n_v // group) * group, len(grids)), (group, 1))
    program.kernel("ffbp_angle", taps)(rt.queue, *size, images, made(np.asarray(offsets, np.int64)), frames, table,
                                       parent_frame, spans, starts, buffer)
    program.kernel("ffbp_range", taps)(rt.queue, *opencl.work_groups(parent.n_v), buffer,
                                       starts, frames, table, parent_frame, spans, np.float64(2 * f0 / c),
                                       np.int32(len(grids)), np.int64(out_offset), out)
