"""The planner's reductions over the scene's skeleton seen from sub-apertures: each point's range
r = |X - O| and sine v = u . (X - O) / r (0 at r = 0) from a sub-aperture's origin O and axis u,
reduced to what :func:`.sampling.extents` needs (extremes, the points within a window of sines,
the range envelope in sine bins). Two implementations giving the same values, bit for bit:

- :class:`HostOffsets` (NumPy): the (n, K) ranges and sines of a few sub-apertures at a time
  (:meth:`.scene.Scene.offsets`, in cache), each reduction a pass over them;
- :class:`DeviceOffsets` (OpenCL, kernels/ffbp.cl's ffbp_extremes, ffbp_seen, ffbp_envelope): a
  work-item a sub-aperture loops over the skeleton, forming r and v operation by operation as
  NumPy does (no fused multiply-adds; IEEE sums, products, square roots and quotients in double),
  so the planner's extents, and with them the tree and the image, are the same whichever ran.
  It replaces about twenty NumPy passes over the (n, K) arrays by one loop a reduction.

The skeleton is finite and has at least one point (:meth:`.scene.Scene.of` refuses others): the
device's maxima and minima (fmax, and selects on < and >) skip a NaN where NumPy's propagate it,
so the two agree only on finite input.
"""

from __future__ import annotations

import numpy as np

from .scene import Scene


class HostOffsets:
    """The reductions of sub-apertures (origins (n, 3), unit axes (n, 3), m) over the scene's
    skeleton with NumPy: the ranges and sines (n, K) computed once, each reduction a pass."""

    def __init__(self, scene: Scene, origins: np.ndarray, axes: np.ndarray):
        r, v = scene.offsets(origins, axes)
        with np.errstate(divide="ignore", invalid="ignore"):
            v /= r  # the sines, in place (a point at a centre, r = 0, has none: 0)
        if not r.all():
            v[r == 0] = 0.0
        self.r, self.v, self.n = r, v, origins.shape[0]

    def extremes(self, far: bool = True) -> tuple:
        """(min r, max r (None unless ``far``), min v, max v), each (n,)."""
        return self.r.min(axis=1), self.r.max(axis=1) if far else None, self.v.min(axis=1), self.v.max(axis=1)

    def seen(self, lo, hi, a, b) -> tuple:
        """Over the points with lo <= v <= hi (each (n,)): (min r, max r (inf, -inf: none), whether
        any, the fraction of all points with a <= v <= b), each (n,)."""
        r, v = self.r, self.v
        seen = (v >= lo[:, None]) & (v <= hi[:, None])
        r_min, r_max = np.where(seen, r, np.inf).min(axis=1), np.where(seen, r, -np.inf).max(axis=1)
        return r_min, r_max, seen.any(axis=1), ((v >= a[:, None]) & (v <= b[:, None])).mean(axis=1)

    def envelope(self, start, width, n_bins: int) -> np.ndarray:
        """(n, n_bins, 2): the nearest and farthest range (inf, -inf: none) of the points in each
        sine bin floor((v - start) / width) (start, width (n,))."""
        r, n = self.r, self.n
        b = self.v - start[:, None]
        with np.errstate(invalid="ignore"):
            b /= width[:, None]
        np.floor(b, out=b)
        ok = b >= 0
        ok &= b < n_bins
        b += (np.arange(n) * n_bins)[:, None]  # the bin's index among all the grids' bins
        every = bool(ok.all())  # (no integration angle: every point in its grid's bins) no masked copies
        flat = (b.reshape(-1) if every else b[ok]).astype(np.int64)
        ranges = r.reshape(-1) if every else r[ok]
        near = np.full(n * n_bins, np.inf)
        far = np.full(n * n_bins, -np.inf)
        np.minimum.at(near, flat, ranges)
        np.maximum.at(far, flat, ranges)
        return np.stack([near, far], axis=1).reshape(n, n_bins, 2)


def device_bytes(k: int, n: int, n_bins: int) -> int:
    """Bytes of every device buffer one :class:`DeviceOffsets` of ``n`` sub-apertures over a
    skeleton of ``k`` points allocates, all its reductions together (``n_bins`` envelope bins): the
    padded skeleton (3, k + 7 at most) and the frames' centres, axes and dots; each reduction's
    parameters and result (the envelope's (n, n_bins, 2) the largest). float64 throughout. A bound on
    what it holds at once, which :func:`clsas.image.ffbp.memory_plan`'s planning part counts (with
    the results' host copies) before the plan runs."""
    padded = 3 * (k + 7)
    common = n * (3 + 3 + 1)  # centred, axes, dots
    results = n * 4 + (n * 4 + n * 4) + (n * 2 + n * n_bins * 2)  # extremes; seen's limits and out; envelope's
    return 8 * (padded + common + results)


class DeviceOffsets:
    """:class:`HostOffsets`' reductions on the OpenCL device (module docstring), for any number of
    sub-apertures at once (each reduction one launch and one read of its (n, ...) result), by
    kernels/ffbp.cl as built for ``taps`` merge taps (:func:`..program.kernel`). Its device buffers
    are bounded (:func:`device_bytes`: the caller takes at most DEVICE_CHUNK_NODES sub-apertures and
    ENVELOPE_BINS bins at a time, over a skeleton of about polar.SKELETON points).

    A work-item a sub-aperture, each its own work-group, looping over the skeleton with a global
    read-modify-write of the envelope's bin a point: shaped for a CPU device (PoCL: a work-group a
    core at a time, the envelope in cache). On a GPU that is one busy lane a warp and serialised
    global updates; measure before using it there (the NumPy reductions give the same values).
    """

    def __init__(self, scene: Scene, origins: np.ndarray, axes: np.ndarray, taps: int = 8):
        import pyopencl as cl

        from .... import opencl
        from .. import program

        rt = opencl.runtime()
        self.queue, self.n = rt.queue, origins.shape[0]
        centred = origins - scene.plane.centroid  # as Scene.offsets: about the scene's centroid
        dots = np.sum(axes * centred, axis=1)

        def buffer(array):
            return cl.Buffer(rt.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                             hostbuf=np.ascontiguousarray(array, np.float64))

        points = scene.centred_skeleton  # (3, K); padded below to whole eights (the last point repeated)
        k = points.shape[1]
        padded = np.concatenate([points, np.repeat(points[:, -1:], -k % 8, axis=1)], axis=1)
        self.count = k
        self.common = (buffer(padded), np.int32(k), np.int32(padded.shape[1]), buffer(centred), buffer(axes),
                       buffer(dots), np.int32(self.n))
        self.kernel = lambda name: program.kernel(name, taps)  # the call's program (built for its merges)
        self.buffer = buffer
        self.groups = opencl.work_groups(self.n, 1)  # a work-item a sub-aperture, each its own group

    def _run(self, name: str, extra: tuple, out: np.ndarray) -> np.ndarray:
        import pyopencl as cl

        from .... import opencl

        dest = cl.Buffer(opencl.runtime().context, cl.mem_flags.WRITE_ONLY, out.nbytes)
        self.kernel(name)(self.queue, *self.groups, *self.common, *extra, dest)
        cl.enqueue_copy(self.queue, out, dest)  # blocking: the planner needs it at once
        return out

    def extremes(self, far: bool = True) -> tuple:
        out = self._run("ffbp_extremes", (), np.empty((self.n, 4)))
        return out[:, 0].copy(), out[:, 1].copy() if far else None, out[:, 2].copy(), out[:, 3].copy()

    def seen(self, lo, hi, a, b) -> tuple:
        out = self._run("ffbp_seen", (self.buffer(np.stack([lo, hi, a, b], axis=1)),), np.empty((self.n, 4)))
        return out[:, 0].copy(), out[:, 1].copy(), out[:, 2] > 0, out[:, 3] / self.count  # as NumPy's mean

    def envelope(self, start, width, n_bins: int) -> np.ndarray:
        return self._run("ffbp_envelope", (self.buffer(np.stack([start, width], axis=1)), np.int32(n_bins)),
                         np.empty((self.n, n_bins, 2)))
