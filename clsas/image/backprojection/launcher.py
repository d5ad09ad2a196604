"""Back-projection on OpenCL: the grid in chunks of tiles, the records in upload blocks, the pulses
in launches of bp_tile (:class:`.tile_kernel.TileKernel`) or, for ``precision="double"`` and
receivers whose motion is not linear over a tile, bp_block (:class:`.exact_kernel.ExactKernel`).

Memory: the pixels are processed in chunks of at most ``PIXEL_CHUNK`` (2^22) slots on the device,
whose fields bp_fields computes there (16 bytes a slot, 20 for moving pixels: TileKernel.PIXELS; a grid
of one chunk keeps them, with its slots' pixel indices, in its :class:`.tiles.GridPlan` for the calls after its
first: :class:`_Inputs`); the kernels
add into a double image of the chunk's slots (16 bytes a slot: a work-item's rows are contiguous,
written as whole vectors; with records longer than ``records.LAUNCH_RECORD_BYTES`` a block, also its
float sums carried between launches, 8 bytes a slot), put in the grid's order once the chunk's
kernels have finished: by bp_order on the device into the complex64 image for a grid of one chunk,
by the host into a complex128 image for several; the records a block
of at most ``records.UPLOAD_BYTES`` at a time (jobs of a receiver's block in flight up to
records.IN_FLIGHT_BYTES of records, at least two and at most records.MAX_IN_FLIGHT: the host waits for the
kernels of the job that many before; small jobs, a small grid's, then queue up far enough that
the device does not wait for the host between them), the per-(tile, pulse) references REF_PULSES pulses at a
time, for consecutive receivers of the same legs at once (one bp_refs launch; a group's references
for every pulse of the call within ``REF_BYTES``, each kept until its last receiver's bp_tile
launch: :func:`_groups`). Records prepared with :func:`.records.prepare` are held whole instead, and a
:class:`.tiles.GridPlan` keeps the grid's tiling. A block of PULSE_BLOCK pulses whose records exceed
``records.LAUNCH_RECORD_BYTES`` is summed over several bp_tile launches that carry its float sums
(:func:`.records.launch_pulses`; the same image bit for bit; a block cut by a job's or a reference
sub-block's end is added in parts instead: :func:`_launches`): each launch reads records that fit in
cache (jobs of fewer pulses, so that the FIR's output would also stay in cache, were no faster: a
job's host work, its FIR launch among it, costs what the cache saves).
"""

from __future__ import annotations

import numpy as np

from ... import opencl
from ...progress import Progress
from .exact_kernel import ExactKernel
from .records import PreparedRecords, jobs_in_flight, launch_pulses
from .spans import reach
from .tile_kernel import TileKernel
from .tiles import GridPlan

PIXEL_CHUNK = 2**22  # slots on the device at once
REF_PULSES = 1024  # pulses whose tile references are computed at once (a 1024-pulse upload job: one bp_refs launch)
REF_BYTES = 16 * 2**20  # a group of receivers' references (every pulse of the call) held at once (_groups)
# a chunk of at most TWO_LANE_SLOTS slots with several jobs runs every other job on a second queue (_Chunk.lane), into
# its own sums and carry (24 bytes a slot: at most 6 MB) and the FIR's scratch buffer of that queue (records.py): a
# small grid's launches are short, so a thread idle at a launch's end and the ~25 us between commands are a large
# share of them, and the second queue's next command fills both (the fixed-cost echo's 128^2 call 8 % faster; 512^2
# unchanged, so left on one queue)
TWO_LANES, TWO_LANE_SLOTS = True, 2**18
# such a chunk's bp_tile launches read up to SMALL_LAUNCH_RECORDS x records.LAUNCH_RECORD_BYTES of records (its
# launches have few work-groups, which reread the records less than a large grid's: the fixed-cost echo's x8 records,
# 108 kB a pulse, then go 64 pulses a launch instead of 16 at 128^2, 6 % faster; 256^2 unchanged)
SMALL_LAUNCH_RECORDS = 4
# a lane's first bp_tile launch without CARRY stores its sums (BP_STORE) where they were zeroed first (_Lane.start)
FIRST_LAUNCH_STORES = True
ORDER_RUN = 64  # pixels a bp_order work-item puts in the grid's order (and checks: _Chunk.in_grid_order's seen)
_SECOND_QUEUES: dict = {}  # context -> the second lane's queue (opencl.runtime's contexts, which live as long)


class _Inputs:
    """The device inputs of slots ``first`` .. ``stop - 1`` of a tiling: their pixel indices
    (``index``, -1 for padding), the work-items' tiles relative to the chunk's first tile
    (``tile_of``), those tiles (``tiles``, a range of the tiling's) and their reference points
    (``centres``), and bp_tile's pixel fields (``pixels``, computed on the device by bp_fields:
    16 bytes a slot, 20 for moving pixels). A grid of one chunk keeps them with its plan
    (:meth:`.tiles.GridPlan.kept`, within a bound for all plans), so that a call on a grid imaged
    before makes none of them."""

    def __init__(self, ctx, queue, tiling, tile: TileKernel, positions, first: int, stop: int):
        import pyopencl as cl

        mf = cl.mem_flags
        width = tile.LANES * tile.rows
        self.first, self.n = first, stop - first
        slots = tiling.order[first:stop]
        owner = tiling.tile[first // width:stop // width]
        self.tiles = np.arange(owner[0], owner[-1] + 1)
        self.pixels_here = int(np.count_nonzero(slots >= 0))
        self.slots = slots

        def made(a):
            return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))

        self.index = made(slots.astype(np.int32))
        self.tile_of = made(owner - owner[0])
        self.centres = made(tiling.centres[self.tiles])
        self.pixels = tile.fields(queue, positions=positions(), index=self.index, tile_of=self.tile_of,
                                  centres=self.centres, n_slots=self.n)

    @staticmethod
    def nbytes(tiling, tile: TileKernel, first: int, stop: int) -> int:
        """Device bytes of the inputs of slots ``first`` .. ``stop - 1``: the pixel indices and
        fields (4 + 16 bytes a slot, 4 + 20 for moving pixels), the work-items' tiles and the tiles'
        reference points."""
        width = tile.LANES * tile.rows
        n_tiles = int(tiling.tile[(stop - 1) // width]) - int(tiling.tile[first // width]) + 1
        return (stop - first) * (4 + tile.pixels.itemsize // tile.LANES) + 4 * ((stop - first) // width) + 24 * n_tiles

    @staticmethod
    def key(ctx, tiling, tile: TileKernel, first: int, stop: int) -> tuple:
        """What the inputs depend on besides the plan's grid: the context, the tiling, the slots
        and bp_fields' configuration (rows, the pixels' motion)."""
        return (int(ctx.int_ptr), id(tiling), first, stop, tuple(sorted(tile.field_defines.items())),
                tuple(float(v) for v in tile.v_k))


class _Lane:
    """One lane of a chunk's bp_tile launches: its queue, the slots' sums it adds into (double2 a
    slot: started by its first launch, :meth:`start`) and bp_tile's CARRY buffer (float sums, 8 bytes
    a slot, made on first use)."""

    def __init__(self, ctx, queue, n: int):
        import pyopencl as cl

        self.queue, self._ctx, self._n = queue, ctx, n
        self.sums = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 16 * n)
        self.started = False
        self._carry = None

    def start(self, stores: bool) -> bool:
        """Before a kernel into the sums on the lane's queue: whether it is the lane's first and
        ``stores`` (a bp_tile launch that may store its sums, BP_STORE: one without CARRY), so that
        it stores them and the sums need no zeroing (FIRST_LAUNCH_STORES); the first of any other
        kind finds them zeroed (a fill queued before it)."""
        if self.started:
            return False
        self.started = True
        if stores and FIRST_LAUNCH_STORES:
            return True
        import pyopencl as cl

        cl.enqueue_fill_buffer(self.queue, self.sums, np.zeros(1, np.complex128), 0, 16 * self._n)
        return False

    @property
    def carry(self):
        if self._carry is None:
            import pyopencl as cl

            self._carry = cl.Buffer(self._ctx, cl.mem_flags.READ_WRITE, 8 * self._n)
        return self._carry


class _Chunk:
    """A chunk of slots of the plan's tiling on the device: its :class:`_Inputs` (``inputs``) and
    its lanes (:meth:`lane`): the first lane's sums (``sums``, double2 a slot, started by its first kernel)
    hold the image once a second lane's, if any, are added into them (:meth:`merged`, before
    they are read)."""

    def __init__(self, ctx, queue, inputs: _Inputs, tile: TileKernel):
        import pyopencl as cl

        self.inputs = inputs
        self._ctx, self._tile = ctx, tile
        self._lanes = [_Lane(ctx, queue, self.inputs.n)]
        self.sums = self._lanes[0].sums  # the slots' double image
        # the inputs' end on the first lane's queue (bp_fields, when made now), for a second lane to wait for
        self._ready = cl.enqueue_marker(queue)

    def lane(self, k: int, queue) -> _Lane:
        """Lane ``k`` (0, or 1 made on first use on ``queue``, whose later commands then wait for the
        chunk's inputs on the first lane's queue): the jobs of a lane run in order on its queue, two
        lanes side by side (the device's threads take the next command's
        work-groups while a command's last ones finish, and the next command is ready)."""
        if k == len(self._lanes):
            import pyopencl as cl

            cl.enqueue_barrier(queue, wait_for=[self._ready])  # the pixel fields the first lane's queue makes
            self._lanes.append(_Lane(self._ctx, queue, self.inputs.n))
        return self._lanes[k]

    def merged(self, queue) -> "_Chunk":
        """The chunk, the second lane's sums, if any, added into the first's (bp_add_sums on ``queue``,
        the first lane's, queued behind a barrier on the second lane's kernels) and dropped (first lane's sums
        no kernel wrote: zeroed): ``sums`` then hold the chunk's image (:meth:`in_grid_order`, :meth:`add_into`)."""
        self._lanes[0].start(False)  # (zeroed, if no kernel wrote the sums)
        if len(self._lanes) > 1 and self._lanes[-1].started:
            import pyopencl as cl

            other = self._lanes.pop()
            cl.enqueue_barrier(queue, wait_for=[cl.enqueue_marker(other.queue)])  # the second lane's kernels
            opencl.kernel("bp_fields", "bp_add_sums", preamble=self._tile.preamble,
                          defines=self._tile.field_defines)(
                queue, *opencl.work_groups(self.inputs.n), self.sums, other.sums, np.int32(self.inputs.n))
        del self._lanes[1:]  # (a second lane that ran no kernel adds nothing)
        return self

    def in_grid_order(self, queue, tiling, tile: TileKernel, seen=None) -> np.ndarray:
        """The image (M,) complex64 of a chunk of the whole ``tiling`` (after the chunk's kernels): bp_order
        puts each pixel's slot sum (:attr:`.tiles.Tiling.slot_of`) in the grid's order on the device,
        rounded once to float as numpy's astype(complex64) rounds (the host path's image bit for bit).
        ``seen``, a list when given, gets what bp_order saw on the way (one int): bit 1 set when a pixel
        is not zero, bit 2 when one is not finite (numpy's ``np.any`` and ``np.isfinite`` of the image)."""
        import pyopencl as cl

        mf = cl.mem_flags
        slot_of = tiling.slot_of
        out = np.empty(slot_of.size, np.complex64)
        flags = np.empty(-(-slot_of.size // ORDER_RUN), np.int32)  # bp_order's, a work-item's run of pixels each
        out_buf = cl.Buffer(queue.context, mf.WRITE_ONLY | mf.USE_HOST_PTR, hostbuf=out)
        flags_buf = cl.Buffer(queue.context, mf.WRITE_ONLY | mf.USE_HOST_PTR, hostbuf=flags)
        slot_buf = cl.Buffer(queue.context, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=slot_of)
        opencl.kernel("bp_fields", "bp_order", preamble=tile.preamble, defines=tile.field_defines)(
            queue, *opencl.work_groups(flags.size), self.sums, slot_buf, np.int32(slot_of.size), np.int32(ORDER_RUN),
            out_buf, flags_buf)
        # both mapped (the host arrays in sync) by one wait: the second map blocks, after the first in queue order
        mapped = [cl.enqueue_map_buffer(queue, buf, cl.map_flags.READ, 0, host.shape, host.dtype, is_blocking=last)[0]
                  for buf, host, last in ((out_buf, out, False), (flags_buf, flags, True))]
        for m in mapped:
            m.base.release()
        if seen is not None:
            seen.append(int(np.bitwise_or.reduce(flags)) if flags.size else 0)
        return out

    def add_into(self, queue, image: np.ndarray, tiling) -> None:
        """Add the slots' sums into ``image`` (M,) complex128 at their pixels (after the chunk's
        kernels: the blocking map waits for them on the in-order queue). A chunk of the whole
        ``tiling`` reads them in the grid's order by one take (:attr:`.tiles.Tiling.slot_of`); a
        part of it scatters its real slots."""
        import pyopencl as cl

        sums, _ = cl.enqueue_map_buffer(queue, self.sums, cl.map_flags.READ, 0, (self.inputs.n,), np.complex128)
        try:
            if self.inputs.first == 0 and self.inputs.n == tiling.order.size:
                image += sums[tiling.slot_of]
            else:
                real = self.inputs.slots >= 0
                image[self.inputs.slots[real]] += sums[real]
        finally:
            sums.base.release()


STAGE_SHARE = 0.5  # held records are staged when a grid reaches at least this share of their fast times


def _stage_worth_it(records: PreparedRecords, plan: GridPlan, velocity, reached=None) -> bool:
    """Whether a call stages its jobs' held records (records.PreparedRecords.buffer): only when the
    grid reaches at least STAGE_SHARE of the fast times the records hold (:func:`.spans.reach`, a
    bound, over every receiver: ``reached`` (len(records.receivers), 2) s as records.records_for
    computed it for the call, or computed here when None). A patch reads a narrow span of each
    row, which stays in cache when read in place, where a copy moves whole rows
    (bench/bench_backprojection.py's fixed-cost patch rows on records prepared whole). Either way
    the image is the same bit for bit; records not held are never staged."""
    if not records.materialised:
        return False
    spans = reach(records.echo, records.receivers, None, velocity, plan.box) if reached is None else reached
    lo, hi = np.maximum(spans[:, 0], records.span[:, 0]), np.minimum(spans[:, 1], records.span[:, 1])
    share = np.sum(np.maximum(hi - lo, 0.0)) / max(float(np.sum(records.span[:, 1] - records.span[:, 0])), 1e-30)
    return bool(share >= STAGE_SHARE)


def backproject_opencl(records: PreparedRecords, plan: GridPlan, aperture, velocity, stop_and_go, progress,
                       span: tuple[int, int], double=False, reached=None):
    """The kernels/bp_tile.cl launcher: image (M,) complex64 (a grid of one chunk: put in the grid's
    order on the device, :meth:`_Chunk.in_grid_order`) or complex128 (several chunks: added on the
    host), how many (chunk, receiver, pulse block) jobs ran on the exact double kernel, the
    back-projection kernels' own time (s, from the queues' profiling events: the time some bp_tile
    or bp_block ran, two lanes' overlapping ones counted once), and what bp_order saw of a grid of
    one chunk's image (bit 1: a pixel not zero, bit 2: one not finite; None for several chunks:
    :meth:`_Chunk.in_grid_order`). ``reached``: the grid's reach over the records' receivers when
    the caller computed it (records.records_for), for the staging choice (:func:`_stage_worth_it`).
    When the call raises, the commands it queued are finished first: they read host arrays
    (USE_HOST_PTR) that unwind with the call."""
    rt = opencl.runtime()
    try:
        return _launched(rt, records, plan, aperture, velocity, stop_and_go, progress, span, double, reached)
    except BaseException:
        rt.queue.finish()
        if int(rt.context.int_ptr) in _SECOND_QUEUES:
            _SECOND_QUEUES[int(rt.context.int_ptr)].finish()
        raise


def _launched(rt, records: PreparedRecords, plan: GridPlan, aperture, velocity, stop_and_go, progress,
              span: tuple[int, int], double, reached):
    """:func:`backproject_opencl` on the runtime ``rt``."""
    import pyopencl as cl

    ctx, queue = rt.context, rt.queue
    mf = cl.mem_flags
    START, END = cl.profiling_info.START, cl.profiling_info.END
    upload = records.upload_pulses()
    # the first job's records (jobs[0] below: chunk 0, receiver 0, the first upload block) before
    # anything else: their upsampling runs on the device while the host makes the call's kernels,
    # tiling and groups, which otherwise left the device idle
    # the call's buffers held records are staged into (records.PreparedRecords.buffer), or None: read in place
    staging: dict | None = {} if _stage_worth_it(records, plan, velocity, reached) else None
    early = records.buffer(ctx, 0, np.arange(span[0], min(span[0] + upload, span[1])), double, staged=staging)
    echo, fs = records.echo, records.fs
    c, f0 = echo.medium.sound_speed, echo.waveform.f0
    pixels = np.ascontiguousarray(plan.grid.positions.reshape(-1, 3), np.float64)
    image = None  # complex128, made when a chunk's sums are added on the host

    def positions():  # bp_fields' input (a buffer of the host array in place), for the chunks not kept
        return cl.Buffer(ctx, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=pixels)
    tiles = plan.tiling(f0, c)
    tile = TileKernel(records.interp, aperture, velocity, stop_and_go, rows=tiles.rows)
    kernels = {h: tile.for_receiver(echo, h) for h in records.receivers}  # each receiver's legs (TileKernel.legs_for)
    taps = tile.taps(ctx)
    params = tile.params(c, f0, fs)
    chunk = PIXEL_CHUNK // (tile.LANES * tile.rows) * (tile.LANES * tile.rows)
    job_bytes = 16 * max(1, int(np.max(records.length))) * min(upload, span[1] - span[0])  # as upload_pulses counts
    keep = jobs_in_flight(job_bytes) - 1  # jobs left in flight by retire
    jobs = [(first, i, np.arange(s, min(s + upload, span[1]))) for first in range(0, tiles.order.size, chunk)
            for i in range(len(records.receivers)) for s in range(span[0], span[1], upload)]
    group_of = {i: g for g in _groups(records, kernels, tile, tiles, span) for i in g}
    shared = {}  # (chunk, group, first pulse of the sub-block): the group's references, until its last member's
    fallbacks, chunk_state, in_flight, work, busy = 0, None, [], [], []
    bar = Progress(pixels.shape[0] * len(records.receivers) * (span[1] - span[0]), "pixel-pulses",
                   "back-projection (opencl)", progress)

    def retire(keep: int) -> None:
        """Wait for all but the last ``keep`` jobs' kernels (so that the host, which prepares
        records faster than the kernels read them, holds at most ``keep`` + 1 upload blocks) and
        note their (start, end) in ``busy``; their events are dropped (PoCL keeps a command's
        buffers while its event lives)."""
        while len(in_flight) > keep:
            done = in_flight.pop(0)
            if done:  # a job's kernels run in order on its lane's queue: its last one ends last
                done[-1].wait()
            busy.extend((e.get_profiling_info(START), e.get_profiling_info(END)) for e in done)
            bar.done(work.pop(0))  # the progress bar counts finished kernels' pixel-pulses

    per_chunk = len(jobs) // len(range(0, tiles.order.size, chunk))
    two = TWO_LANES and per_chunk > 1 and not double and min(chunk, tiles.order.size) <= TWO_LANE_SLOTS
    queues = [queue] + ([_second_queue(ctx)] if two else [])
    for j, (first, i, pulses) in enumerate(jobs):
        h, offset = records.receivers[i], int(records.offset[i])
        k = j % per_chunk % len(queues)  # the job's lane: every other job of a chunk on the second queue
        q = queues[k]
        retire(keep)
        if early is not None:  # jobs[0]
            (records_buf, n_samples, base), early = early, None
        else:
            records_buf, n_samples, base = records.buffer(ctx, i, pulses, double, q, staged=staging)
        if chunk_state is None or chunk_state.inputs.first != first:
            if chunk_state is not None:
                retire(0)
                image = _added(queue, chunk_state, image, tiles)
            stop = min(first + chunk, tiles.order.size)
            if first == 0 and stop == tiles.order.size:  # a grid of one chunk: its inputs kept with the plan
                inputs = plan.kept(_Inputs.key(ctx, tiles, tile, first, stop),
                                   lambda: _Inputs(ctx, queue, tiles, tile, positions, first, stop),
                                   _Inputs.nbytes(tiles, tile, first, stop), rt.device.global_mem_size)
            else:
                inputs = _Inputs(ctx, queue, tiles, tile, positions, first, stop)
            chunk_state = _Chunk(ctx, queue, inputs, tile)
        lane = chunk_state.lane(k, q)
        skip = int(pulses[0] - base)  # the job's first pulse in the buffer (which may hold earlier pulses)
        in_flight.append(events := [])
        work.append(inputs.pixels_here * pulses.size)
        exact = None
        for s in range(0, pulses.size, REF_PULSES):
            # a sub-block's references are computed while the previous sub-block's kernels run
            end = min(s + REF_PULSES, pulses.size)  # the sub-block's pulses: s .. end - 1 of the job's
            if not double:
                part, kernel = pulses[s:s + REF_PULSES], kernels[h]
                group = group_of[i]
                ref_stride, ref_first = part.size * len(group), skip + s - part.size * group.index(i)
                if len(group) > 1:  # every member's references from one bp_refs launch, (T, members, P)
                    key = (first, group, int(part[0]))
                    if key not in shared:  # (buffer, the lane that computes it, its end on that lane's queue)
                        made = kernel.references_on_device(
                            q, echo, [records.receivers[m] for m in group], part, inputs.centres,
                            inputs.tiles.size, fs, tiles.half_extent, records.offset[list(group)])
                        shared[key] = (made, k, cl.enqueue_marker(q) if len(queues) > 1 and made else None)
                    ref_buf, made_on, done = shared[key] if i != group[-1] else shared.pop(key)
                    if made_on != k and done is not None:  # computed on the other lane's queue: wait for it
                        cl.enqueue_barrier(q, wait_for=[done])
                else:
                    ref_buf = kernel.references_on_device(q, echo, h, part, inputs.centres,
                                                          inputs.tiles.size, fs, tiles.half_extent, offset)
                if ref_buf is None:  # a receiver followed between several nodes: on the host
                    ref, linear = kernel.references(echo, h, part, tiles.centres[inputs.tiles], fs,
                                                    tiles.half_extent, offset)
                    ref_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=ref) if linear else None
                if ref_buf is not None:
                    spans = None
                    if tile.pulse_span:
                        ref, _ = cl.enqueue_map_buffer(q, ref_buf, cl.map_flags.READ, 0,
                                                       (inputs.tiles.size, ref_stride), kernel.reference_dtype)
                        mine = ref[:, skip + s - ref_first:][:, :part.size]  # this receiver's (T, P)
                        spans = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                                          hostbuf=tile.spans(mine, tiles.half_extent, c, skip + s))
                        ref.base.release()
                    # (a small chunk's records counted at 1 / SMALL_LAUNCH_RECORDS against LAUNCH_RECORD_BYTES)
                    sub = launch_pulses(-(-n_samples // SMALL_LAUNCH_RECORDS) if two else n_samples, tile.PULSE_BLOCK)
                    for q0, n_q, mode in _launches(int(pulses[s]), int(pulses[end - 1]) + 1, span,
                                                   tile.PULSE_BLOCK, sub):
                        q0 -= int(pulses[0])  # the job's pulse index
                        events.append(kernel.launch(
                            q, store=lane.start(mode is None), pixels=inputs.pixels, tile_of=inputs.tile_of,
                            refs=ref_buf, ref_stride=ref_stride, ref_first=ref_first, records=records_buf,
                            n_samples=n_samples, taps=taps, params=params, p_first=skip + q0, p_count=n_q,
                            image=lane.sums, spans=spans, carry=mode and lane.carry, carry_mode=mode or 0))
                    continue
                fallbacks += 1
            if exact is None:  # the exact double kernel (precision="double", or the fallback)
                # pulse and node buffers indexed like the records buffer (from its first pulse); a
                # padding slot images pixel 0 and is dropped
                slot_pixels = pixels[np.maximum(inputs.slots, 0)]
                exact = ExactKernel(ctx, slot_pixels, echo, h, np.arange(base, pulses[-1] + 1), fs, offset,
                                    velocity, records.interp, aperture, stop_and_go, double)
            lane.start(False)
            for p0 in range(s, end, tile.PULSE_BLOCK):
                count = min(tile.PULSE_BLOCK, end - p0)
                events.append(exact.launch(q, records=records_buf, n_samples=n_samples, taps=taps,
                                           p_first=skip + p0, p_count=count, image=lane.sums))
    seen: list = []  # what bp_order saw (a grid of one chunk)
    # the last chunk's sums read (queued behind its kernels, which the blocking map waits for: the device
    # goes on to bp_order without waiting for the host to see them end), then the kernels' events
    if chunk_state is not None and chunk_state.inputs.first == 0 and chunk_state.inputs.n == tiles.order.size \
            and tiles.slot_of.dtype == np.int32:  # one chunk: the image in the grid's order on the device
        image = chunk_state.merged(queue).in_grid_order(queue, tiles, tile, seen)
    elif chunk_state is not None:
        image = _added(queue, chunk_state, image, tiles)
    retire(0)
    bar.close()
    image = np.zeros(pixels.shape[0], np.complex128) if image is None else image
    return image, fallbacks, _union_seconds(busy), (seen[0] if seen else None)


def _union_seconds(intervals: list) -> float:
    """The time (s) covered by the (start, end) intervals (ns; the kernels' profiling events): the
    kernels of two lanes overlap, and their time is counted once."""
    total, last = 0, None
    for start, end in sorted(intervals):
        if last is not None and start < last:
            start = last
        if end > start:
            total += end - start
        last = end if last is None else max(last, end)
    return 1e-9 * total


def _second_queue(ctx):
    """A second in-order queue (profiling enabled) of the context ``ctx``, made once."""
    import pyopencl as cl

    key = int(ctx.int_ptr)
    if key not in _SECOND_QUEUES:
        _SECOND_QUEUES[key] = cl.CommandQueue(ctx, properties=cl.command_queue_properties.PROFILING_ENABLE)
    return _SECOND_QUEUES[key]


def _added(queue, chunk_state: _Chunk, image, tiles) -> np.ndarray:
    """``image`` (M,) complex128 (made zero when None) with ``chunk_state``'s sums added (:meth:`_Chunk.add_into`)."""
    if image is None:
        image = np.zeros(tiles.slot_of.size, np.complex128)
    chunk_state.merged(queue).add_into(queue, image, tiles)
    return image


def _groups(records: PreparedRecords, kernels: dict, tile: TileKernel, tiles, span: tuple[int, int]) -> list[tuple]:
    """The receivers (indices into ``records.receivers``, in their order) whose references one
    bp_refs launch computes (a launch a pulse sub-block and chunk instead of one a receiver):
    consecutive receivers with the same legs whose references bp_refs computes
    (:meth:`.tile_kernel.TileKernel.on_device`), as many as keep their references for every pulse
    of the call within REF_BYTES. bp_tile still
    runs a receiver a launch: all of its work-items then read the same receiver's records, which
    stay in cache (several receivers a launch, each work-item sweeping their records in turn, was
    slower: the commit d486032 gives the figures)."""
    echo = records.echo
    per_receiver = tiles.centres.shape[0] * (span[1] - span[0]) * tile.reference_dtype.itemsize
    limit = max(1, int(REF_BYTES // max(per_receiver, 1)))
    groups: list[list] = []
    joins_last = False
    for i, h in enumerate(records.receivers):
        joins = limit > 1 and kernels[h].on_device(echo, h)
        if (joins and joins_last and len(groups[-1]) < limit
                and kernels[records.receivers[groups[-1][0]]].legs == kernels[h].legs):
            groups[-1].append(i)
        else:
            groups.append([i])
        joins_last = joins
    return [tuple(g) for g in groups]


def _launches(first: int, stop: int, span: tuple[int, int], block: int, sub: int):
    """bp_tile's launches over pulses ``first`` .. ``stop`` - 1 (a job's sub-block of references):
    (first pulse, count, carry_mode or None without CARRY) each. Pulses are summed in blocks of
    ``block`` from ``span[0]`` (as one launch a block would sum them), each over launches of at
    most ``sub`` pulses that carry the float sums (carry_mode bit 1: start from the carry, bit 2:
    store into it instead of adding into the image). A block is carried only within
    ``first`` .. ``stop``: one cut by them (a sub-block or job not aligned to the blocks) is added
    into the image in parts (the same sum to float rounding, not bit for bit), so that no stored
    sums wait for a launch that never comes (the next sub-block may run on the exact kernel) and no
    launch starts from sums another left. With REF_PULSES and the upload jobs multiples of
    ``block`` (as they are) no block is cut."""
    at = first
    while at < stop:
        b0 = span[0] + (at - span[0]) // block * block
        b1 = min(b0 + block, span[1])
        lo, hi = max(b0, first), min(b1, stop)  # the part of the block carried here
        n = min(sub, hi - at)
        yield at, n, (int(at > lo) | 2 * int(at + n < hi)) or None  # a part in one launch: no CARRY
        at += n
