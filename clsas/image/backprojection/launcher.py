"""Back-projection on OpenCL: the grid in chunks of tiles, the records in upload blocks, the pulses
in launches of bp_tile (:class:`.tile_kernel.TileKernel`) or, for ``precision="double"`` and
receivers whose motion is not linear over a tile, bp_block (:class:`.exact_kernel.ExactKernel`).

Memory: the pixels are processed in chunks of at most ``PIXEL_CHUNK`` (2^22) pixels on the
device (a 4096^2 image is four chunks of ~150 MB of device buffers each), the records a block
of at most ``records.UPLOAD_BYTES`` at a time (at most two blocks in flight: the host waits
for the kernels of the block before last), the per-(tile, pulse) references REF_PULSES pulses
at a time; the host keeps the tile order of the pixels (12 bytes a pixel) beside the grid.
Records prepared with :func:`.records.prepare` are held whole instead, and a
:class:`.tile_kernel.GridPlan` keeps the grid's tile plan and pixel fields.
"""

from __future__ import annotations

import numpy as np

from ... import opencl
from ...progress import Progress
from .exact_kernel import ExactKernel
from .records import PreparedRecords
from .tile_kernel import GridPlan, TileKernel

PIXEL_CHUNK = 2**22  # pixels on the device at once
REF_PULSES = 64  # pulses whose tile references are computed at once


class _Chunk:
    """The device side of slots ``first`` .. ``stop - 1`` of the plan's tiling: bp_tile's pixel
    fields and work-items' tile indices (:meth:`TileKernel.fields`), the tiles present
    (``tiles``) and the double image (n,)."""

    def __init__(self, ctx, plan: GridPlan, tile: TileKernel, f0, c, first: int, stop: int):
        import pyopencl as cl

        mf = cl.mem_flags
        tiling = plan.tiling(f0, c)
        self.first, self.n = first, stop - first
        self.order, self.real = tiling.order[first:stop], tiling.real[first:stop]
        fields, tile_of, self.tiles = tile.fields(plan, f0, c, first, stop)
        self.pixels = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=fields)
        self.tile_of = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=tile_of)
        self.image = cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=np.zeros(self.n, np.complex128))

    def finish(self, queue, image: np.ndarray) -> None:
        """Wait for the chunk and put its pixels (not the padding) into the flat image."""
        import pyopencl as cl

        out = np.empty(self.n, np.complex128)
        cl.enqueue_copy(queue, out, self.image)
        image[self.order[self.real]] = out[self.real]


def backproject_opencl(records: PreparedRecords, plan: GridPlan, aperture, velocity, stop_and_go, progress,
                       span: tuple[int, int], double=False):
    """The kernels/backprojection.cl launcher: image (M,) complex128, how many (chunk, receiver,
    pulse block) jobs ran on the exact double kernel, and the kernels' own time (s, from the
    queue's profiling events)."""
    import pyopencl as cl

    rt = opencl.runtime()
    ctx, queue = rt.context, rt.queue
    mf = cl.mem_flags
    echo, fs = records.echo, records.fs
    c, f0 = echo.medium.sound_speed, echo.waveform.f0
    pixels = plan.grid.positions.reshape(-1, 3)
    image = np.zeros(pixels.shape[0], dtype=np.complex128)
    tile = TileKernel(records.interp, aperture, velocity, stop_and_go)
    kernels = {h: TileKernel(records.interp, aperture, velocity, stop_and_go, same_legs=tile.same_legs_for(echo, h))
               for h in records.receivers}  # each receiver's variant of bp_tile (one leg for a monostatic one)
    taps = tile.taps(ctx)
    params = tile.params(c, f0, fs)
    tiles = plan.tiling(f0, c)
    chunk = PIXEL_CHUNK // (tile.LANES * tile.ROWS) * (tile.LANES * tile.ROWS)
    upload = records.upload_pulses()
    jobs = [(first, i, np.arange(s, min(s + upload, span[1]))) for first in range(0, tiles.order.size, chunk)
            for i in range(len(records.receivers)) for s in range(span[0], span[1], upload)]
    fallbacks, chunk_state, in_flight, work, kernel_seconds = 0, None, [], [], 0.0
    bar = Progress(pixels.shape[0] * len(records.receivers) * (span[1] - span[0]), "pixel-pulses",
                   "back-projection (opencl)", progress)

    def retire(keep: int) -> float:
        """Wait for all but the last ``keep`` jobs' kernels (so that the host, which prepares
        records faster than the kernels read them, holds at most ``keep`` + 1 upload blocks) and
        return their time (s); their events are dropped (PoCL keeps a command's buffers while
        its event lives)."""
        seconds = 0.0
        while len(in_flight) > keep:
            for e in in_flight.pop(0):
                e.wait()
                seconds += 1e-9 * (e.profile.end - e.profile.start)
            bar.done(work.pop(0))  # the progress bar counts finished kernels' pixel-pulses
        return seconds

    for first, i, pulses in jobs:
        h, offset = records.receivers[i], int(records.offset[i])
        kernel_seconds += retire(1)
        records_buf, n_samples, base = records.buffer(ctx, i, pulses, double)
        if chunk_state is None or chunk_state.first != first:
            if chunk_state is not None:
                chunk_state.finish(queue, image)
            chunk_state = _Chunk(ctx, plan, tile, f0, c, first, min(first + chunk, tiles.order.size))
        skip = int(pulses[0] - base)  # the job's first pulse in the buffer (which may hold earlier pulses)
        in_flight.append(events := [])
        work.append(int(np.count_nonzero(chunk_state.real)) * pulses.size)
        exact = None
        for s in range(0, pulses.size, REF_PULSES):
            # a sub-block's references are computed while the previous sub-block's kernels run
            blocks = [(p0, min(tile.PULSE_BLOCK, s + REF_PULSES - p0, pulses.size - p0))
                      for p0 in range(s, min(s + REF_PULSES, pulses.size), tile.PULSE_BLOCK)]
            if not double:
                ref, linear = tile.references(echo, h, pulses[s:s + REF_PULSES], tiles.centres[chunk_state.tiles], fs,
                                              tiles.half_extent, offset)
                if linear:
                    ref_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=ref)
                    spans = None if not tile.pulse_span else cl.Buffer(
                        ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=tile.spans(ref, tiles.half_extent, c, skip + s))
                    for p0, count in blocks:
                        events.append(kernels[h].launch(
                            queue, pixels=chunk_state.pixels, tile_of=chunk_state.tile_of, refs=ref_buf,
                            ref_stride=ref.shape[1], ref_first=skip + s, records=records_buf, n_samples=n_samples,
                            taps=taps, params=params, p_first=skip + p0, p_count=count, image=chunk_state.image,
                            spans=spans))
                    continue
                fallbacks += 1
            if exact is None:  # the exact double kernel (precision="double", or the fallback)
                # pulse and node buffers indexed like the records buffer (from its first pulse)
                exact = ExactKernel(ctx, pixels[chunk_state.order], echo, h, np.arange(base, pulses[-1] + 1), fs, offset,
                                    velocity, records.interp, aperture, stop_and_go, double)
            for p0, count in blocks:
                events.append(exact.launch(queue, records=records_buf, n_samples=n_samples, taps=taps,
                                           p_first=skip + p0, p_count=count, image=chunk_state.image))
    kernel_seconds += retire(0)
    chunk_state.finish(queue, image)
    bar.close()
    return image, fallbacks, kernel_seconds
