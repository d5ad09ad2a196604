"""Where fast factorised back-projection keeps its polar images while it walks the merge tree.

The walk (:func:`clsas.image.ffbp.ffbp`) gives every node a slot in a *group*: the images of a
parent's children, one after another, so that the parent's merge reads them where its children
wrote them. :class:`HostStore` holds groups in NumPy arrays and merges with the float64 reference
(the NumPy backend); :class:`DeviceStore` holds them in OpenCL buffers, one a level, and only
enqueues (the leaves' demodulation, the merges and the final stage run on the device one after
another, and the image comes back once, at the end).
"""

from __future__ import annotations

import numpy as np

from ... import opencl
from .merge import DevicePoints, merge_device, merge_reference


class HostStore:
    """Groups in complex128 arrays; leaves, merges and the final stage by the NumPy reference."""

    def __init__(self, stage1, pixels: np.ndarray, f0: float, c: float, taps: int, rho: float, sizes: list):
        self.stage1, self.pixels, self.args = stage1, pixels, (f0, c, taps, rho)
        self.flat = np.zeros(pixels.shape[0], np.complex128)

    def group(self, level: int, size: int) -> np.ndarray:
        return np.empty(size, np.complex128)

    def leaf(self, node: int, grid, grids: list, group: np.ndarray, offset: int) -> None:
        group[offset:offset + grid.size] = self.stage1.image(node, grid, grids).reshape(-1)

    def flush(self) -> None:
        """Nothing: the reference makes each leaf's image when it is taken."""

    def merge(self, grids: list, group: np.ndarray, offsets: list, parent, out: np.ndarray, offset: int) -> None:
        out[offset:offset + parent.size] = merge_reference(_views(grids, group, offsets), parent, *self.args).reshape(-1)

    def final(self, grids: list, group: np.ndarray, offsets: list) -> None:
        self.flat += merge_reference(_views(grids, group, offsets), self.pixels, *self.args)

    def result(self) -> np.ndarray:
        return self.flat


def _views(grids, group, offsets):
    return [(g, group[o:o + g.size].reshape(g.n_v, g.n_r)) for g, o in zip(grids, offsets)]


class DeviceStore:
    """Groups in complex64 OpenCL buffers; the leaves' images by
    :meth:`clsas.image.ffbp.leaves.FirstStage.image_into`, merges and the final stage by
    :func:`clsas.image.ffbp.merge.merge_device`, all enqueued; the image is read back by
    :meth:`result`. The pixels' positions are read in place (the grid outlives the call).

    One buffer a level serves all its groups, one after another (``sizes``: the largest group of
    each level, as the memory plan counts): the walk is depth first, so a level holds one group
    at a time, and the queue runs in order, so a group's merge has read it before the next group
    of its level is written there. (A buffer a group cost page faults for every group's fresh
    memory.) Nothing is kept between calls: keeping the levels', the image's and the first stage's
    buffers for the next call of the same size was measured to save no CPU time (the allocator
    hands a call the memory the last one freed; the fresh pages a call touches are mostly those of
    the image it returns, which must be its own)."""

    def __init__(self, stage1, pixels: np.ndarray, f0: float, c: float, taps: int, rho: float, sizes: list):
        import pyopencl as cl

        self.cl, self.rt = cl, opencl.runtime()
        self.stage1, self.args = stage1, (f0, c, taps, rho)
        mf = cl.mem_flags
        self.host_pixels = np.ascontiguousarray(pixels, np.float64)
        self.pixels = DevicePoints(cl.Buffer(self.rt.context, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=self.host_pixels),
                                   pixels.shape[0])
        # the image: the final stage writes the host array in place (USE_HOST_PTR: on a CPU device no
        # copy is made, and a blocking map at the end makes it the host's), as direct back-projection's
        self.image = np.empty(pixels.shape[0], np.complex64)
        self.flat = cl.Buffer(self.rt.context, mf.READ_WRITE | mf.USE_HOST_PTR, hostbuf=self.image)
        self.written = False  # the first final stage writes the image (no zero fill), later ones add
        self.sizes, self.levels = sizes, {}

    def group(self, level: int, size: int):
        if level not in self.levels or self.levels[level].size < 8 * size:
            self.levels[level] = self.cl.Buffer(self.rt.context, self.cl.mem_flags.READ_WRITE,
                                                8 * max(self.sizes[level], size, 1))
        return self.levels[level]

    def leaf(self, node: int, grid, grids: list, group, offset: int) -> None:
        self.stage1.image_into(node, grid, grids, group, offset)

    def flush(self) -> None:
        """Enqueue the leaves' images taken since the last flush (before a merge or the final stage
        reads them)."""
        self.stage1.flush()

    def merge(self, grids: list, group, offsets: list, parent, out, offset: int) -> None:
        merge_device(grids, group, offsets, parent, *self.args, out, offset)

    def final(self, grids: list, group, offsets: list) -> None:
        merge_device(grids, group, offsets, self.pixels, *self.args, self.flat, store=not self.written)
        self.written = True

    def result(self) -> np.ndarray:
        if not self.written:  # no top node saw a pixel
            return np.zeros(self.host_pixels.shape[0], np.complex64)
        mapped, _ = self.cl.enqueue_map_buffer(self.rt.queue, self.flat, self.cl.map_flags.READ, 0,
                                               (self.image.size,), np.complex64)
        mapped.base.release()  # the blocking map waits for the last final stage; self.image holds the image
        return self.image
