"""The first stage of fast factorised back-projection: the leaves' polar images.

Each leaf (``first`` consecutive pulses, every selected receiver) is back-projected with
back-projection's exact delays onto its polar grid's points and demodulated by its centre range,
J = I exp(-j 4 pi f0 r / c), a *batch* of consecutive leaves at a time (at most BATCH_POINTS polar
samples and RECORD_BYTES of prepared samples). Records are prepared
(:func:`clsas.image.backprojection.prepare`) once for every leaf when all pulses' prepared records
fit RECORD_BYTES, else once a batch; on OpenCL the whole batch is one bp_tile launch a receiver and block of
pulses (kernels/bp_tile.cl built with ROW_SHIFT: a tile's pulse j reads record row
j + row_shift[tile], the first pulse of its leaf), so a leaf costs its kernel work and no call of
its own (a :func:`clsas.backproject` call a leaf costs many times the leaf's kernel time in host work).
A batch's *layout* (its tiles, work-items, pixel fields and slots, :class:`.layout.Layout`) and its
references depend only on the tree and the echo's geometry: a call on a kept tree (:mod:`.reuse`)
takes them from the last call's, so its first stage is the bp_tile launches alone.

Tiles. bp_tile (:class:`clsas.image.backprojection.TileKernel`, which this stage uses for its
options, records, references, parameters and launch) computes in float32 relative to a
reference point per tile; a polar grid (n_v, n_r) is a raster, so its tiles are blocks of ``bv``
rows x ``br`` range samples (``bv`` a multiple of ROWS, ``br`` of LANES: every tile is whole
work-items) whose reference point is the block's middle sample, halved until every sample lies
within :meth:`~clsas.image.backprojection.TileKernel.half_extent` of its reference (the same
phase budget as back-projection's own tiles), which the launcher checks on the offsets the
ffbp_fields kernel computes for bp_tile anyway (shapes whose half-diagonal estimated from the
grids' largest steps exceeds the budget by more than TILE_SLACK are passed over unchecked: a
short leaf's coarse angles no longer cost a round of fields a halving). The tiles' references (a leaf's tiles for its
pulses) are computed on the device (TileKernel's bp_refs, a launch a leaf) where the receivers
move uniformly, else on the host (which checks that the motion is linear over a tile). Slots
past the grid's edge repeat its last sample and are dropped; a tile's groups of LANES range
samples that miss the spans of their rows (:attr:`PolarGrid.spans`: the ragged wedge, the
corners of the (r, v) box outside the scene) are not back-projected at all, and the leaf's image
is zero there; with an ``aperture``, nor are those no pulse of the leaf sees within it
(:func:`.polar.within_aperture`: zero there too, bit for bit; they are laid out all the same, so
the tiles and their references are those of the whole grid).

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
from ...kernelmath import expj_cycles
from ...model import Grid
from ..backprojection import GridPlan, TileKernel, backproject, prepare
from . import program
from .layout import LANES, ROWS, Layout, cl_buffer, polar_tiles, row_step, slot_firsts
from .polar import PolarGrid, points_at, within_aperture

BATCH_POINTS = 2**21  # polar samples of a batch of leaves (ffbp.memory_plan: ~40 bytes each held)
RECORD_BYTES = 256 * 2**20  # prepared records held at once
TILE_ROWS, TILE_SAMPLES = 16, 128  # the largest tile tried (rows x range samples)
TILE_SLACK = 1.1  # a tile shape is tried when its estimated half-diagonal is within this of the budget
REF_CHUNK = 2**18  # (pulse, tile) pairs whose references are computed at once (~100 bytes each held)


class FirstStage:
    """The leaves' demodulated polar images, made a batch at a time on first request
    (:meth:`image`; module docstring)."""

    def __init__(self, echo, pulses: list, backend: str, chosen, interp: str, upsample: int, aperture,
                 stop_and_go: bool, layouts=None, scratch=None):
        self.echo, self.leaves, self.backend = echo, pulses, backend
        self.layouts = layouts  # the tree's batches' layouts kept between calls (.reuse.Layouts), or None
        self.scratch = scratch  # the call's .scratch.Scratch, for the batches' sums and fields (None: own buffers)
        self.sums = []  # the scratch buffers holding sums that leaves not yet demodulated may still read
        self.loose = []  # the fields' scratch buffers of layouts not kept, which the last batch's bp_tile reads
        self.first = max(p1 - p0 for p0, p1 in pulses)
        self.options = dict(receivers=chosen, interp=interp, upsample=upsample)
        self.aperture, self.stop_and_go = aperture, stop_and_go
        factor = upsample if interp == "linear" else 1
        self.per_pulse = 8 * factor * echo.n_samples * len(chosen)
        self.demodulate = 2 * echo.waveform.f0 / echo.medium.sound_speed
        self.ready = {}
        self.records = None  # every pulse's prepared records, when they fit RECORD_BYTES
        self.pending = None  # what the last batch's queued kernels read: its records and layout (settle)
        self.queued = []  # leaves whose demodulation waits for flush(): (made, grid, out, offset)

    def image(self, node: int, grid: PolarGrid, grids: list) -> np.ndarray:
        """Leaf ``node``'s image on its polar grid ``grid``, demodulated: (n_v, n_r) (complex64 on
        OpenCL, complex128 on NumPy); ``grids`` all leaves' grids (None: a leaf that sees nothing),
        from which the batch starting at ``node`` is taken."""
        if self.backend == "opencl":
            import pyopencl as cl

            rt = opencl.runtime()
            out = cl.Buffer(rt.context, cl.mem_flags.READ_WRITE, 8 * grid.size)
            self.image_into(node, grid, grids, out, 0)
            self.flush()
            image = np.empty((grid.n_v, grid.n_r), np.complex64)
            cl.enqueue_copy(rt.queue, image, out)
            return image
        if node not in self.ready:
            self._batch(node, grids)
        return self._demodulated(self.ready.pop(node), grid).astype(np.complex128)

    def image_into(self, node: int, grid: PolarGrid, grids: list, out, offset: int) -> None:
        """OpenCL: leaf ``node``'s demodulated complex64 image (as :meth:`image`) into the device
        buffer ``out`` from element ``offset`` on, enqueued by the next :meth:`flush` (the leaves
        of a merge's group in one ffbp_leaf launch; a leaf made by clsas.backproject at once)."""
        import pyopencl as cl

        if node not in self.ready:
            self._batch(node, grids)
        made = self.ready.pop(node)
        if isinstance(made, np.ndarray):  # a leaf made by clsas.backproject
            cl.enqueue_copy(opencl.runtime().queue, out, np.ascontiguousarray(self._demodulated(made, grid),
                                                                              np.complex64), dst_offset=8 * offset)
            return
        self.queued.append((made, grid, out, offset))

    def flush(self) -> None:
        """Enqueue the demodulation of the leaves :meth:`image_into` took since the last flush: one
        ffbp_leaf launch for those of one batch going to one buffer (a merge's group)."""
        runs = {}
        for made, grid, out, offset in self.queued:
            runs.setdefault((id(made[0]), id(out)), []).append((made, grid, out, offset))
        self.queued = []
        for run in runs.values():
            (image, slots, _, spans, _), _, out, _ = run[0]
            grids = [grid for _, grid, _, _ in run]

            def made(values):
                return cl_buffer(np.array(values, np.int64))

            rows = -(-max(g.n_v for g in grids) // opencl.WORK_GROUP) * opencl.WORK_GROUP
            program.kernel("ffbp_leaf")(opencl.runtime().queue, (max(-(-g.n_r // LANES) for g in grids), rows, len(run)),
                                        (1, opencl.WORK_GROUP, 1), image, slots, made([m[2] for m, *_ in run]), spans,
                                        made([m[4] for m, *_ in run]), cl_buffer(program.frames(grids)),
                                        np.float64(self.demodulate), made([o for *_, o in run]), out)

    def _demodulated(self, image: np.ndarray, grid: PolarGrid) -> np.ndarray:
        """The leaf's image demodulated by its ranges, zero outside its rows' spans."""
        return image * expj_cycles(-self.demodulate * grid.ranges)[None, :] * grid.inside()

    def settle(self) -> None:
        """Wait for the last batch's kernels, then let go of what they read (its records, host
        memory; its layout, whose pixel fields' scratch buffer may serve others once no one holds
        it): the walk enqueues its leaves' merges meanwhile, and the next batch settles the last
        one before it allocates its own (so one batch's are held at a time, as the memory plan
        counts). :func:`clsas.image.ffbp.ffbp` settles at its end."""
        if self.pending is not None:
            opencl.runtime().queue.finish()
            self.pending = None

    def _batch(self, node: int, grids: list) -> None:
        self.settle()
        for fields in self.loose:  # the queue is finished: no bp_tile reads them now
            self.scratch.recycle(fields)
        self.loose = []
        if self.sums:  # the queue is finished: sums no leaf waiting for its demodulation reads go back
            reading = {id(m[0]) for m in self.ready.values() if not isinstance(m, np.ndarray)}
            reading |= {id(made[0]) for made, *_ in self.queued}
            for sums in [b for b in self.sums if id(b) not in reading]:
                self.sums.remove(sums)
                self.scratch.recycle(sums)
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
        e, made = self.echo, []
        b0 = 0 if e.n_pulses * self.per_pulse <= RECORD_BYTES else self.leaves[node][0]

        def records_of():
            """The batch's records, prepared on first use (while the device lays out a new batch)."""
            if not made and b0 == 0:  # every leaf's records prepared once, kept for all batches
                if self.records is None:
                    self.records = self._prepare(e, [k for k, g in enumerate(grids) if g is not None], grids)
                made.append(self.records)
            elif not made:  # each batch its pulses' records (a copy of the echo's pulses, validated)
                b1 = self.leaves[last][1]
                made.append(self._prepare(e.replace(data=e.data[:, b0:b1], eta=e.eta[b0:b1], tx_pos=e.tx_pos[b0:b1],
                                                    rx_pos=e.rx_pos[:, b0:b1]), batch, grids))
            return made[0]

        alone = [k for k in batch if self.leaves[k][1] - self.leaves[k][0] != self.first]
        if self.backend == "opencl":
            together = [k for k in batch if k not in alone]
            alone += self._launch(records_of, together, grids, b0) if together else []
        else:
            alone = batch
        records = records_of() if alone else None
        for k in alone:
            p0, p1 = self.leaves[k]
            self.ready[k] = backproject(records, GridPlan(Grid.points(grids[k].points())), pulses=(p0 - b0, p1 - b0),
                                        backend=self.backend, aperture=self.aperture, stop_and_go=self.stop_and_go,
                                        progress=False).data.astype(np.complex128)

    def _prepare(self, echo, leaves: list, grids: list):
        """The records of ``echo`` (every pulse of ``leaves``) prepared for only the fast times the
        leaves' polar grids reach (prepare's reach of their boundary: the first and last range at
        every angle row bound a sector's box up to an arc's sagitta between rows, r dv^2 / 8,
        micrometres, inside the sample prepare adds for rounding)."""
        chosen = [grids[k] for k in leaves]
        rows = np.array([g.n_v for g in chosen])
        which = np.repeat(np.arange(len(chosen)), rows)  # each row's grid; its first and last sample
        row = np.arange(which.size) - np.repeat(np.cumsum(rows) - rows, rows)
        last = np.array([g.n_r - 1 for g in chosen])[which]
        edges = points_at(chosen, np.repeat(which, 2), np.repeat(row, 2),
                          np.stack([np.zeros_like(last), last], axis=1).reshape(-1))
        return prepare(echo, **self.options, grid=Grid.points(edges))

    def _device_references(self, tile: TileKernel, records, batch: list, centres: np.ndarray, first_tile: np.ndarray,
                           b0: int, half_extent: float) -> list | None:
        """The references of :meth:`_references` computed on the device (TileKernel's bp_refs, its
        twin), a buffer a receiver of (T, first) records: the batch's tiles leaf by leaf, each for
        its leaf's pulses, in one launch a receiver (each tile's first pulse within the batch's);
        None when a receiver needs the host's (exact delays on a track of more than two nodes:
        the host checks its linearity)."""
        echo, out = records.echo, []
        starts = np.array([self.leaves[k][0] - b0 for k in batch])
        pulses = np.arange(starts.min(), starts.max() + self.first)
        firsts = np.repeat(starts - starts.min(), np.diff(first_tile))  # each tile's leaf's first pulse among them
        for i, h in enumerate(records.receivers):
            refs = tile.for_receiver(echo, h).references_on_device(
                opencl.runtime().queue, echo, h, pulses, cl_buffer(centres), centres.shape[0], records.fs,
                half_extent, int(records.offset[i]), tile_first=firsts)
            if refs is None:
                return None
            out.append(refs)
        return out

    def _references(self, tile: TileKernel, records, batch: list, centres: np.ndarray, first_tile: np.ndarray,
                    b0: int, half_extent: float) -> list | None:
        """bp_tile's tile references of every receiver (a list a receiver of (T, first) arrays: the
        batch's tiles leaf by leaf, each for its leaf's pulses), for tiles whose samples lie within
        ``half_extent`` of their references; None when a receiver's motion is not linear over a
        tile's delay span (then the batch goes to clsas.backproject). Computed for REF_CHUNK
        (pulse, tile) pairs at a time, each leaf's tiles padded to the batch's largest count by
        repeating its last."""
        echo = records.echo
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
                ref, linear = tile.for_receiver(echo, h).references(echo, h, pulses, points, records.fs, half_extent,
                                                                    int(records.offset[i]))
                if not linear:
                    return None
                parts.append(ref.reshape(widest, -1, self.first).transpose(1, 0, 2)[real[leaves]])
            refs.append(np.concatenate(parts))
        return refs

    def _layout(self, tile: TileKernel, batch: list, grids: list, budget: float, meanwhile) -> Layout | None:
        """The batch's tiles (the largest whose samples all lie within ``budget`` of their
        references), their pixel fields on the device and the images' slots; None when even a
        tile of ROWS x LANES samples spans more than the budget. ``meanwhile()`` is called once
        while the device computes the first fields (the host's own work: the records)."""
        import pyopencl as cl

        rt = opencl.runtime()
        ctx, queue, mf = rt.context, rt.queue, cl.mem_flags

        plane = program.plane(grids[batch[0]].plane)
        frames = cl_buffer(program.frames([grids[k] for k in batch]))
        leaves, seen = [grids[k] for k in batch], None
        if self.aperture is not None:  # the samples no pulse sees within the aperture: zero, not back-projected
            pulses = np.array([self.leaves[k][0] for k in batch])[:, None] + np.arange(self.first)
            seen = within_aperture(leaves, self.echo.tx_pos[pulses], float(np.sin(self.aperture / 2)))
        step_r, step_v = max(g.dr for g in leaves), max(row_step(g) for g in leaves)

        def halved(bv: int, br: int) -> tuple[int, int]:
            """The tiles' longer side halved."""
            if br > LANES and (br * step_r >= bv * step_v or bv == ROWS):
                return bv, br // 2
            return bv // 2, br

        # shapes whose half-diagonal (from the largest steps) exceeds the budget by a margin are
        # passed over without computing their fields; the fields decide the rest
        bv, br = TILE_ROWS, TILE_SAMPLES
        while (bv, br) != (ROWS, LANES) and 0.5 * np.hypot(br * step_r, bv * step_v) > TILE_SLACK * budget:
            bv, br = halved(bv, br)
        slot_first = slot_firsts(leaves)  # the images' slots: ffbp_fields writes those of its items
        slots = cl.Buffer(ctx, mf.READ_WRITE, 4 * max(int(slot_first[-1]), 1))
        firsts = cl_buffer(slot_first)
        while True:  # the largest tiles whose samples all lie within the budget of their references
            items, centres, n_tiles, n_items = polar_tiles(leaves, bv, br, seen)
            n_items = max(n_items, ROWS)  # at least one work-item (a launch of none is not allowed)
            nbytes = tile.pixels.itemsize * items.size  # the pixel fields: one record a item (LANES samples)
            pix = self.scratch.take(nbytes) if self.scratch is not None else cl.Buffer(ctx, mf.READ_WRITE, nbytes)
            items_buf = cl_buffer(items)
            largest = np.empty(items.size, np.float32)  # each item's largest dd (the fields' own, float32)
            largest_buf = cl.Buffer(ctx, mf.WRITE_ONLY, largest.nbytes)
            cl.enqueue_fill_buffer(queue, slots, np.int32(-1), 0, 4 * max(int(slot_first[-1]), 1))
            program.kernel("ffbp_fields")(queue, *opencl.work_groups(items.size), items_buf, frames, plane,
                                          cl_buffer(centres), np.int32(items.size), pix, largest_buf, slots, firsts,
                                          np.int32(n_items))
            copied = cl.enqueue_copy(queue, largest, largest_buf, is_blocking=False)
            if meanwhile is not None:
                meanwhile()
                meanwhile = None
            copied.wait()
            extent = float(np.sqrt(largest.max()))
            if extent <= budget:
                break
            if self.scratch is not None:  # ffbp_fields is done (the copy after it is): no kernel reads them
                self.scratch.recycle(pix)
            if br == LANES and bv == ROWS:  # samples too far apart for any tile (a short leaf's coarse angles)
                return None
            bv, br = halved(bv, br)
        first_tile = np.cumsum(np.r_[0, n_tiles])
        row_shift = np.repeat(np.array([self.leaves[k][0] for k in batch], np.int32), n_tiles)  # less b0 at launch
        spans = cl_buffer(np.concatenate([g.row_spans for g in (leaves if seen is None else seen)]))
        return Layout(n_items, centres, first_tile, extent, pix, row_shift,
                      cl_buffer(items["tile"][:n_items:ROWS]), slots, slot_first,
                      spans, np.cumsum([0] + [g.n_v for g in leaves]))

    def _launch(self, records_of, batch: list, grids: list, b0: int) -> list:
        """The images of the leaves ``batch`` (all ``first`` pulses long) by bp_tile launches into
        self.ready; returns the leaves it left to :func:`clsas.backproject` (a receiver's motion not
        linear over a tile, or polar samples so far apart that even a tile of ROWS x LANES of them
        spans more than bp_tile's float32 geometry allows). The batch's layout and references come
        from :attr:`layouts` when a call on the same tree made them (:mod:`.reuse`); ``records_of()``
        its records (prepared while the device computes a new layout's fields)."""
        import pyopencl as cl

        rt = opencl.runtime()
        ctx, queue, mf = rt.context, rt.queue, cl.mem_flags
        f0, c = self.echo.waveform.f0, self.echo.medium.sound_speed
        tile = TileKernel(self.options["interp"], self.aperture, stop_and_go=self.stop_and_go, row_shift=True)
        budget = tile.half_extent(f0, c)

        key = (ctx.int_ptr, tuple(batch), budget, TILE_ROWS, TILE_SAMPLES, TILE_SLACK)
        layout = self.layouts.get(key) if self.layouts is not None else None
        new = layout is None
        if new:
            layout = self._layout(tile, batch, grids, budget, records_of)
            if layout is None:
                return batch
        records = records_of()
        echo = records.echo
        refs_key = (b0, records.fs, tuple(int(o) for o in records.offset), tuple(records.receivers))
        refs = layout.refs.get(refs_key)
        if refs is None:
            refs = self._device_references(tile, records, batch, layout.centres, layout.first_tile, b0, layout.extent)
            if refs is None:
                refs = self._references(tile, records, batch, layout.centres, layout.first_tile, b0, layout.extent)
            if refs is None:
                return batch
            refs = [r if isinstance(r, cl.Buffer) else cl_buffer(r) for r in refs]
        row_shift = cl_buffer(layout.row_shift - np.int32(b0))
        params, taps = tile.params(c, f0, records.fs), tile.taps(ctx)
        # the sums (the first launch stores, later ones add), in a scratch buffer: kept between calls, and
        # recycled within the call once no leaf reads it (:meth:`_batch`)
        nbytes = 16 * LANES * layout.n_items
        if self.scratch is not None:
            image = self.scratch.take(nbytes)
            self.sums.append(image)
        else:
            image = cl.Buffer(ctx, mf.READ_WRITE, nbytes)
        self.pending = (records, layout)  # read in place by the kernels queued below until settle()
        for i, h in enumerate(records.receivers):
            data, n_samples, _ = records.buffer(ctx, i, np.arange(echo.n_pulses), False)  # all pulses: row 0 first
            kern = tile.for_receiver(echo, h)  # the receiver's legs (TileKernel.legs_for)
            for s in range(0, self.first, tile.PULSE_BLOCK):
                kern.launch(queue, pixels=layout.pix, tile_of=layout.tile_of, refs=refs[i], ref_stride=self.first,
                            ref_first=0, records=data, n_samples=n_samples, taps=taps, params=params, p_first=s,
                            p_count=min(tile.PULSE_BLOCK, self.first - s), image=image, row_shift=row_shift,
                            store=i == 0 and s == 0)
        if new and self.layouts is not None:  # kept with its references (.reuse)
            self.layouts.put(key, layout, layout.nbytes)
        kept = self.layouts is not None and self.layouts.get(key) is layout
        if new and self.scratch is not None:  # its fields' buffer goes with it (back once it is let go), or back
            # to the pool once this batch's bp_tile is done (the next batch's settle)
            (self.scratch.hand_over(layout.pix, layout) if kept else self.loose.append(layout.pix))
        if kept and refs_key not in layout.refs and self.layouts.add(sum(r.size for r in refs)):
            layout.refs[refs_key] = refs
        for j, k in enumerate(batch):  # the leaf's slots and spans from slot_first[j] and span_first[j] on
            self.ready[k] = (image, layout.slots, int(layout.slot_first[j]), layout.spans, int(layout.span_first[j]))
        return []
