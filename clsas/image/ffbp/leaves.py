"""The first stage of fast factorised back-projection: the leaves' polar images.

Each leaf (``first`` consecutive pulses, every selected receiver) is back-projected with
back-projection's exact delays onto its polar grid's points and demodulated by its centre range,
J = I exp(-j 4 pi f0 r / c). Records are prepared once (:func:`clsas.image.backprojection.prepare`)
for a *batch* of consecutive leaves (at most BATCH_POINTS polar samples and RECORD_BYTES of
prepared samples), and on OpenCL the whole batch is one bp_tile launch a receiver and block of
pulses (kernels/backprojection.cl built with ROW_SHIFT: a tile's pulse j reads record row
j + row_shift[tile], the first pulse of its leaf), so a leaf costs its kernel work and no call of
its own (a :func:`clsas.backproject` call a leaf cost ~10-40 ms of host work, measured, against
~3 ms of kernel for a leaf of 16 pulses x 30k samples).

Tiles. bp_tile's float32 geometry is relative to a reference point per tile (derivation at
:func:`clsas.image.backprojection.backproject_opencl`); a polar grid (n_v, n_r) is a raster, so
its tiles are blocks of ``bv`` rows x ``br`` range samples (``bv`` a multiple of ROWS, ``br`` of
LANES: every tile is whole work-items) whose reference point is the block's middle sample,
halved until every sample lies within :func:`clsas.image.backprojection.tiles.tile_half_extent`
of its reference (the same phase budget as back-projection's own tiles), which the launcher
checks on the offsets the ffbp_fields kernel computes for bp_tile anyway. Slots past the grid's
edge repeat its last sample and are dropped.

Leaves the batch cannot take go through :func:`clsas.backproject` one by one on the same
prepared records (the same image up to float32 rounding): a leaf shorter than ``first`` (the
last), a receiver whose motion is not linear over a tile's delay span (where
back-projection falls back to its exact double kernel), and a batch whose samples lie so far
apart (a very short leaf's coarse angles) that even a tile of ROWS x LANES of them leaves the
budget (back-projection tiles those points its own way). The NumPy backend always does.
"""

from __future__ import annotations

import numpy as np

from ... import opencl
from ...model import Grid
from ...interp import TAP_ROWS, kernel_taps
from ...kernelmath import expj_cycles
from ..backprojection.direct import (NODE_TOLERANCE, PULSE_BLOCK, PULSES, RECORDS, TILE_PARAMS, GridPlan, backproject, prepare,
                              tile_references)
from ..backprojection.tiles import LANES, ROWS, tile_half_extent
from .polar import PolarGrid

BATCH_POINTS = 2**21  # polar samples of a batch of leaves (ffbp.memory_plan: ~40 bytes each held)
RECORD_BYTES = 256 * 2**20  # prepared records held at once
TILE_ROWS, TILE_SAMPLES = 8, 128  # the largest tile tried (rows x range samples)
REF_CHUNK = 2**18  # (pulse, tile) pairs whose references are computed at once (~100 bytes each held)


def polar_tiles(grids: list, bv: int, br: int):
    """bp_tile's tiles of polar grids (module docstring), blocks of bv rows x br range samples
    (those at a grid's edge cut to it):
    their work-items (I, 4) int32 (grid, row, first of sixteen consecutive range samples of that
    row, tile; grid by grid, tile by tile, row by row), the tiles' reference points (T, 3) m (each
    block's middle sample) and the number of tiles of each grid (L,)."""
    tv_of = np.array([-(-g.n_v // bv) for g in grids])
    tr_of = np.array([-(-g.n_r // br) for g in grids])
    tv, tr = int(tv_of.max()), int(tr_of.max())
    real = (np.arange(tv)[None, :, None] < tv_of[:, None, None]) & (np.arange(tr)[None, None, :] < tr_of[:, None, None])
    tile = np.cumsum(real.reshape(-1)).reshape(real.shape) - 1  # grid by grid, row-major within a grid
    # work-items tile by tile, within a tile row by row, LANES samples each
    # a tile at the grid's edge keeps only its rows inside the grid (rounded up to whole work-items
    # of ROWS rows) and its sixteen-sample groups that start inside it
    shape = (len(grids), tv, tr, bv, br // LANES)
    l, a, b, j, q = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij", sparse=True)
    n_v = np.array([g.n_v for g in grids])[:, None, None, None, None]
    n_r = np.array([g.n_r for g in grids])[:, None, None, None, None]
    keep = real[:, :, :, None, None] & (j < -(-(n_v - a * bv) // ROWS) * ROWS) & (b * br + q * LANES < n_r)
    items = np.stack([np.broadcast_to(x, shape)[keep] for x in (l, a * bv + j, b * br + q * LANES,
                                                                 tile[:, :, :, None, None])], axis=1)
    centres = []
    for g in grids:
        j0, i0 = np.arange(0, g.n_v, bv), np.arange(0, g.n_r, br)
        middle_v = (j0 + np.minimum(j0 + bv, g.n_v) - 1) // 2
        middle_r = (i0 + np.minimum(i0 + br, g.n_r) - 1) // 2
        centres.append(g.points(rows=middle_v, cols=middle_r).reshape(-1, 3))
    return items.astype(np.int32), np.concatenate(centres), tv_of * tr_of


def _row_step(grid: PolarGrid) -> float:
    """The largest distance (m) between neighbouring angle rows of a polar grid: at its far range r,
    r dv / cos(theta) with the largest |v| = sin(theta) (cos(theta) bounded below by 1e-3)."""
    sine = max(abs(grid.v0), abs(grid.v0 + (grid.n_v - 1) * grid.dv))
    return (grid.r0 + (grid.n_r - 1) * grid.dr) * grid.dv / np.sqrt(max(1.0 - sine * sine, 1e-6))


class FirstStage:
    """The leaves' demodulated polar images, made a batch at a time on first request
    (:meth:`image`; module docstring)."""

    def __init__(self, echo, pulses: list, backend: str, chosen, interp: str, upsample: int, aperture,
                 stop_and_go: bool):
        self.echo, self.leaves, self.backend = echo, pulses, backend
        self.first = max(p1 - p0 for p0, p1 in pulses)
        self.options = dict(receivers=chosen, interp=interp, upsample=upsample)
        self.aperture, self.stop_and_go = aperture, stop_and_go
        factor = upsample if interp == "linear" else 1
        self.per_pulse = 8 * factor * echo.n_samples * len(chosen)
        self.demodulate = 2 * echo.waveform.f0 / echo.medium.sound_speed
        self.ready = {}

    def image(self, node: int, grid: PolarGrid, grids: list) -> np.ndarray:
        """Leaf ``node``'s image on its polar grid ``grid``, demodulated: (n_v, n_r) (complex64 on
        OpenCL, complex128 on NumPy); ``grids`` all leaves' grids (None: a leaf that sees nothing),
        from which the batch starting at ``node`` is taken."""
        if self.backend == "opencl":
            import pyopencl as cl

            rt = opencl.runtime()
            out = cl.Buffer(rt.context, cl.mem_flags.READ_WRITE, 8 * grid.size)
            self.image_into(node, grid, grids, out, 0)
            image = np.empty((grid.n_v, grid.n_r), np.complex64)
            cl.enqueue_copy(rt.queue, image, out)
            return image
        if node not in self.ready:
            self._batch(node, grids)
        return self._demodulated(self.ready.pop(node), grid).astype(np.complex128)

    def image_into(self, node: int, grid: PolarGrid, grids: list, out, offset: int) -> None:
        """OpenCL: enqueue leaf ``node``'s demodulated complex64 image (as :meth:`image`) into the
        device buffer ``out`` from element ``offset`` on."""
        import pyopencl as cl

        if node not in self.ready:
            self._batch(node, grids)
        made = self.ready.pop(node)
        rt = opencl.runtime()
        if isinstance(made, np.ndarray):  # a leaf made by clsas.backproject
            cl.enqueue_copy(rt.queue, out, np.ascontiguousarray(self._demodulated(made, grid), np.complex64),
                            dst_offset=8 * offset)
            return
        image, items, first, count = made
        kern = opencl.kernel("ffbp", "ffbp_leaf", defines={"TAPS": 8, "TAP_ROWS": TAP_ROWS})
        frame = cl.Buffer(rt.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=grid.record())
        kern(rt.queue, (count,), None, image, items, np.int32(first), frame, np.float64(self.demodulate),
             np.int64(offset), out)

    def _demodulated(self, image: np.ndarray, grid: PolarGrid) -> np.ndarray:
        return image * expj_cycles(-self.demodulate * grid.ranges)[None, :]

    def _batch(self, node: int, grids: list) -> None:
        batch, points, last = [], 0, node
        for k in range(node, len(self.leaves)):
            if grids[k] is None:
                continue
            if batch and (points + grids[k].size > BATCH_POINTS or
                          (self.leaves[k][1] - self.leaves[node][0]) * self.per_pulse > RECORD_BYTES):
                break
            batch.append(k)
            points += grids[k].size
            last = k
        b0, b1 = self.leaves[node][0], self.leaves[last][1]
        e = self.echo
        sub = e.replace(data=e.data[:, b0:b1], eta=e.eta[b0:b1], tx_pos=e.tx_pos[b0:b1], rx_pos=e.rx_pos[:, b0:b1])
        # only the fast times the leaves' polar grids reach (prepare's reach of their boundary: the
        # first and last range at every angle row bound a sector's box up to an arc's sagitta
        # between rows, r dv^2 / 8, micrometres, inside the sample prepare adds for rounding)
        edges = np.concatenate([grids[k].points(cols=[0, grids[k].n_r - 1]).reshape(-1, 3) for k in batch])
        records = prepare(sub, **self.options, grid=Grid.points(edges))
        alone = [k for k in batch if self.leaves[k][1] - self.leaves[k][0] != self.first]
        if self.backend == "opencl":
            together = [k for k in batch if k not in alone]
            alone += self._launch(records, together, grids, b0) if together else []
        else:
            alone = batch
        for k in alone:
            p0, p1 = self.leaves[k]
            self.ready[k] = backproject(records, GridPlan(Grid.points(grids[k].points())), pulses=(p0 - b0, p1 - b0),
                                        backend=self.backend, aperture=self.aperture, stop_and_go=self.stop_and_go,
                                        progress=False).data.astype(np.complex128)

    def _references(self, records, batch: list, centres: np.ndarray, first_tile: np.ndarray, b0: int,
                    half_extent: float) -> tuple[list, bool]:
        """bp_tile's tile references of every receiver (a list a receiver of (T, first) arrays: the
        batch's tiles leaf by leaf, each for its leaf's pulses), for tiles whose samples lie within
        ``half_extent`` of their references, and whether a receiver's motion departs from linear
        over a tile's delay span by more than NODE_TOLERANCE of a wavelength (then the batch goes
        to clsas.backproject). Computed for REF_CHUNK (pulse, tile) pairs at a time, each leaf's
        tiles padded to the batch's largest count by repeating its last."""
        echo = records.echo
        tolerance = NODE_TOLERANCE * echo.waveform.wavelength(echo.medium)
        counts = np.diff(first_tile)
        widest = int(counts.max())
        slot = np.minimum(np.arange(widest)[None, :], counts[:, None] - 1) + first_tile[:-1, None]  # (L, widest)
        real = np.arange(widest)[None, :] < counts[:, None]
        starts = np.array([self.leaves[k][0] - b0 for k in batch])
        step = max(1, REF_CHUNK // (widest * self.first))  # leaves a chunk
        refs = []
        for i, h in enumerate(records.receivers):
            parts = []
            for s in range(0, len(batch), step):
                leaves = slice(s, min(s + step, len(batch)))
                pulses = (starts[leaves, None] + np.arange(self.first)).reshape(-1)
                points = np.repeat(centres[slot[leaves]], self.first, axis=0)  # (leaves x first, widest, 3)
                ref, departure = tile_references(echo, h, pulses, points, np.zeros(3), self.stop_and_go, records.fs,
                                                 half_extent, int(records.offset[i]))
                if departure > tolerance:
                    return refs, True
                parts.append(ref.reshape(widest, -1, self.first).transpose(1, 0, 2)[real[leaves]])
            refs.append(np.concatenate(parts))
        return refs, False

    def _launch(self, records, batch: list, grids: list, b0: int) -> list:
        """The images of the leaves ``batch`` (all ``first`` pulses long) by bp_tile launches into
        self.ready; returns the leaves it left to :func:`clsas.backproject` (a receiver's motion not
        linear over a tile, or polar samples so far apart that even a tile of ROWS x LANES of them
        spans more than bp_tile's float32 geometry allows)."""
        import pyopencl as cl

        rt = opencl.runtime()
        ctx, queue, mf = rt.context, rt.queue, cl.mem_flags
        echo = records.echo
        f0, c, fs = echo.waveform.f0, echo.medium.sound_speed, records.fs
        budget = tile_half_extent(f0, c)

        def made(a, flags=mf.READ_ONLY):
            return cl.Buffer(ctx, flags | mf.COPY_HOST_PTR, hostbuf=a)

        plane = made(np.r_[grids[batch[0]].plane.normal, grids[batch[0]].plane.offset])
        frames = made(np.stack([grids[k].record() for k in batch]))
        bv, br = TILE_ROWS, TILE_SAMPLES
        leaves = [grids[k] for k in batch]
        while True:  # the largest tiles whose samples all lie within the budget of their references
            items, centres, n_tiles = polar_tiles(leaves, bv, br)
            m_pad = LANES * items.shape[0]
            pix = cl.Buffer(ctx, mf.READ_WRITE, 4 * 4 * m_pad)
            items_buf = made(items)
            opencl.kernel("ffbp", "ffbp_fields", defines={"TAPS": 8, "TAP_ROWS": TAP_ROWS})(
                queue, (items.shape[0],), None, items_buf, frames, plane, made(centres), np.int32(m_pad), pix)
            square = np.empty(m_pad, np.float32)
            cl.enqueue_copy(queue, square, pix, src_offset=3 * 4 * m_pad)  # |delta|^2
            extent = float(np.sqrt(square.max()))
            if extent <= budget:
                break
            if br == LANES and bv == ROWS:  # samples too far apart for any tile (a short leaf's coarse angles)
                return batch
            # halve the tiles' longer side
            along_r = br * max(g.dr for g in leaves)
            along_v = bv * max(_row_step(g) for g in leaves)
            if br > LANES and (along_r >= along_v or bv == ROWS):
                br //= 2
            else:
                bv //= 2
        first_tile = np.cumsum(np.r_[0, n_tiles])
        refs, failed = self._references(records, batch, centres, first_tile, b0, extent)
        if failed:
            return batch
        row_shift = np.repeat(np.array([self.leaves[k][0] - b0 for k in batch], np.int32), n_tiles)
        tile_of = np.ascontiguousarray(items[::ROWS, 3])
        defines = {"INTERP_LINEAR" if records.interp == "linear" else "INTERP_SINC8": 1, "TAP_ROWS": TAP_ROWS,
                   "BP_TILE": 1, "ROWS": ROWS, "PULSES": PULSES, "ROW_SHIFT": 1,
                   **({"APERTURE": 1} if self.aperture is not None else {})}
        kern = opencl.kernel("backprojection", "bp_tile", preamble=RECORDS, defines=defines)
        params = np.zeros((), TILE_PARAMS)
        params["a1"], params["fs"], params["f0"], params["c"] = c * c, fs, f0, c
        params["half_sin"] = np.sin(self.aperture / 2) if self.aperture is not None else 1.0
        tile_buf, shift_buf = made(tile_of), made(row_shift)
        taps = made(kernel_taps(records.interp))
        image = cl.Buffer(ctx, mf.READ_WRITE, 16 * m_pad)
        cl.enqueue_fill_buffer(queue, image, np.zeros(1, np.complex128), 0, 16 * m_pad)
        for i, h in enumerate(records.receivers):
            data, n_samples, _ = records.buffer(ctx, i, np.arange(echo.n_pulses), False)  # all pulses: row 0 first
            ref_buf = made(refs[i])
            for s in range(0, self.first, PULSE_BLOCK):
                kern(queue, (m_pad // (LANES * ROWS),), None, pix, tile_buf, ref_buf, np.int32(self.first), np.int32(0),
                     data, taps, params[()], np.int32(s), np.int32(min(PULSE_BLOCK, self.first - s)),
                     np.int32(n_samples), np.int32(m_pad), image, shift_buf)
        rt.queue.finish()  # the records' buffers may use host memory that the caller drops
        ends = np.searchsorted(items[:, 0], np.arange(len(batch) + 1))
        for j, k in enumerate(batch):  # the leaf's work-items ends[j] .. ends[j + 1] - 1 of image
            self.ready[k] = (image, items_buf, int(ends[j]), int(ends[j + 1] - ends[j]))
        return []
