"""Records prepared for back-projection: the interpolator's samples of the fast-time span a grid reaches.

:func:`prepare` pays once what every :func:`clsas.backproject` call on an echo otherwise pays
again: the upsampling of each record (``interp="linear"``) and its upload to the device.
The :class:`PreparedRecords` it returns is accepted by ``backproject`` in place of the echo and
gives the bit-identical image, on both backends::

    records = prepare(compressed, upsample=8)            # every sample, once
    for grid in grids:                                   # e.g. the sub-images of a factorised back-projection
        image = backproject(records, grid)

Spans. With ``grid=`` a Grid, only the fast-time span that grid can reach is prepared (per
receiver, over all pulses; :func:`.spans.reach`), which makes one call on a small patch cheap; with a
``(start, stop)`` fast-time span (seconds), that span; with None, the whole records. Records that
are not upsampled (sinc8, or upsample=1) are the echo's own, read in place whole.
``backproject`` refuses a grid whose reach the records do not cover.

Upsampling. Records whose occupied band fits the FIR's (B / (2 fs) <= ``upsample.MAX_BAND``
= 0.4, i.e. fs >= 1.25 B) are upsampled by a 24-tap Kaiser-windowed-sinc polyphase FIR
(:mod:`clsas.image.upsample`), which departs from exact band-limited (FFT) upsampling by at most
3.2e-4 a unit tone in that band (a fortieth of the linear interpolator's own error on x8
records, (2 pi 0.4 / 8)^2 / 8 = 1.2e-2 at fs = 1.25 B; records also carry a little energy beyond
B / 2, the chirp's spectral skirts, which the FIR passes less faithfully: tests/test_upsample.py
holds both departures). An output depends only on the samples around it, so any span gives the
same samples, bit for bit. The FIR runs on the OpenCL device when the default backend is OpenCL
(:func:`clsas.use_backend`; "auto" with a device found), whichever backend the back-projection
itself runs on, and as its NumPy twin otherwise: the host samples of :func:`prepare` and of the
NumPy reference are then those a plain OpenCL call makes on the device (it upsamples each upload
block there, the records never leaving the device), and prepared records give a plain call's
image bit for bit on both backends.

Records sampled nearer their Nyquist rate (fs < 1.25 B: no short FIR holds there) are
FFT-upsampled on the host, block by block (:func:`clsas.image.upsample.upsample_blocks`), the
spans rounded out to whole blocks so that a prepared sample depends on its block only.

Device memory. A PreparedRecords holds its samples on the host (complex64, read-only); its device
buffers are made on first OpenCL use, one per receiver (and one complex128 copy per receiver for
``precision="double"``, made on first use of that precision), and live as long as the object or
until :meth:`PreparedRecords.release`. On PoCL CPU devices a complex64 buffer uses the host array
in place (CL_MEM_USE_HOST_PTR: no copy); on a GPU it is a copy in device memory. A call's own
buffers for its records (a job's upsampled records a lane, held rows staged, complex128 copies:
:func:`record_bytes`) count with its pixels against the memory budget, checked before the call makes them.
"""

from __future__ import annotations

import numpy as np

from ... import backend as _backend
from ... import budget, opencl, validate
from ...model import EchoData, Grid
from .. import upsample as fir
from ..rangecomp import check_workers
# (FFT_BATCH_BYTES: ffbp's budget; UPSAMPLE_BLOCK: the tests')
from ..upsample import FFT_BATCH_BYTES, UPSAMPLE_BLOCK, upsample_blocks  # noqa: F401
from .spans import MIN_SAMPLES, reach, samples_for_span

INTERPOLATORS = ("linear", "sinc8")
UPLOAD_BYTES = 64 * 2**20  # records prepared and uploaded at once when a call prepares its own
# records one bp_tile launch reads at most (about a core's L2): a block of pulses whose records are
# longer is summed over several launches of fewer pulses (:func:`launch_pulses`), whose records then
# stay in cache while the launch's work-items read them (long upsampled records on a small grid:
# 6.9 MB a block of 64 pulses x8 otherwise come from L3 for every work-group)
LAUNCH_RECORD_BYTES = 2 * 2**20
IN_FLIGHT_BYTES = 2 * UPLOAD_BYTES  # records (upload_pulses' bytes a pulse) of a call's jobs in flight at once
MAX_IN_FLIGHT = 8  # jobs in flight at most (:func:`jobs_in_flight`)
STAGE_BYTES = 8 * 2**20  # held records staged for a job at most (buffer): here jobs of 6.9-15 MB gained, 27-44 MB lost


def launch_pulses(n_samples: int, block: int) -> int:
    """Pulses a bp_tile launch sums: ``block``, or for records of ``n_samples`` complex64 samples
    whose block exceeds LAUNCH_RECORD_BYTES the largest power of two (at least 4, below ``block``)
    whose records fit in it."""
    per_pulse = 8 * max(int(n_samples), 1)
    if per_pulse * block <= LAUNCH_RECORD_BYTES:
        return block
    sub = 4
    while 2 * sub * per_pulse <= LAUNCH_RECORD_BYTES and 2 * sub < block:
        sub *= 2
    return sub


def check_options(echo, receivers, interp, upsample, target_velocity, who: str = "backproject"):
    """(receiver indices, velocity (3,)) or a ValueError/TypeError naming the parameter as
    ``"<who> <parameter>"`` (who: the public function checked, e.g. "prepare", "ffbp")."""
    if not isinstance(echo, EchoData):
        raise TypeError(f"{who} echo: must be an EchoData (or records from clsas.image.backprojection.prepare), "
                        f"got {type(echo).__name__}")
    validate.compression(f"{who} echo", echo, advice="call clsas.range_compress(echo) first (back-projection "
                         "refuses raw echoes rather than compressing them silently)")
    validate.choice(f"{who} interp", interp, INTERPOLATORS)
    validate.integer(f"{who} upsample", upsample, low=1, high=64)
    need = 8 if interp == "sinc8" else 2
    if echo.n_samples < need or echo.n_pulses < 1:
        raise ValueError(f"{who} echo: has {echo.n_pulses} pulses of {echo.n_samples} samples; interp={interp!r} "
                         f"needs at least one pulse of {need} samples")
    chosen = echo.select_receivers(receivers)
    v = np.zeros(3) if target_velocity is None else validate.vector3(f"{who} target_velocity", target_velocity)
    if np.linalg.norm(v) > validate.MAX_SPEED:
        raise ValueError(f"{who} target_velocity: must be at most {validate.MAX_SPEED:g} m/s, got "
                         f"{np.linalg.norm(v):g} m/s")
    return chosen, v


class PreparedRecords:
    """The samples ``backproject`` reads, prepared once (see the module docstring; make one with
    :func:`prepare`).

    Attributes
    ----------
    echo : EchoData, the source (its geometry serves every call; its samples are not read again).
    receivers : tuple of int, the echo's receivers prepared (indices), summed by default.
    interp : {"linear", "sinc8"}; upsample : int as asked; factor : int, the upsampling applied
        (``upsample`` for linear, 1 for sinc8); fs : float, Hz, the prepared samples' rate.
    upsampler : {"fir", "fft", None}, how the records are upsampled (module docstring; None when
        ``factor`` is 1).
    offset : (len(receivers),) int, the prepared records' first sample, counted in samples at
        ``fs`` from the echo's window start t0: receiver i's prepared sample j lies at fast time
        ``t0 + (offset[i] + j) / fs``.
    length : (len(receivers),) int, prepared samples per record.
    span : (len(receivers), 2) s, the fast times the prepared samples cover.
    """

    def __init__(self, echo: EchoData, receivers, interp: str, upsample: int, spans: np.ndarray,
                 materialise: bool = True, workers: int | None = None):
        self.echo = echo
        self.receivers = tuple(int(h) for h in receivers)
        self.interp, self.upsample = interp, int(upsample)
        self.factor = self.upsample if interp == "linear" else 1
        self.fs = echo.fs * self.factor
        self.upsampler = upsampler_for(echo, self.factor)
        self._workers = workers
        self._fir_device = None  # the FIR runs on the device (decided on first use: the default backend)
        bounds = self._samples_for(spans)
        self._bounds = bounds  # original samples [first, stop) per receiver
        self.offset = bounds[:, 0] * self.factor
        self.length = (bounds[:, 1] - bounds[:, 0]) * self.factor
        t0 = np.asarray(echo.t0)[list(self.receivers)]
        self.span = np.column_stack([t0 + self.offset / self.fs, t0 + (self.offset + self.length) / self.fs])
        self._device = {}
        self._scratch = {}  # per (context, queue): the buffer a call's upload blocks are upsampled into, in turn
        self._host = None
        if materialise and self.factor > 1:  # records not upsampled are views of the echo: nothing to hold
            held = 8.0 * echo.n_pulses * float(np.sum(np.maximum(self.length, MIN_SAMPLES)))
            spectra = min(FFT_BATCH_BYTES, 4 * held / max(len(self.receivers), 1))
            budget.check_bytes(f"prepare: {len(self.receivers)} receivers x {echo.n_pulses} pulses x up to "
                               f"{int(np.max(self.length))} samples (upsample={self.upsample})", held + spectra,
                               "prepare fewer receivers, a smaller upsample or only the span a grid reaches (grid=)")
        if materialise:
            self._host = [self._make(i, np.arange(echo.n_pulses)) for i in range(len(self.receivers))]
            for held in self._host:
                held.flags.writeable = False

    def _samples_for(self, spans: np.ndarray) -> np.ndarray:
        """(len(receivers), 2) int64: the original samples [first, stop) to prepare for the fast-time
        ``spans`` (len(receivers), 2) s (:func:`.spans.samples_for_span`)."""
        echo = self.echo
        blocks = self.upsampler == "fft"
        bounds = [samples_for_span(spans[i], echo.t0[h], echo.fs, echo.n_samples, self.interp, self.factor, blocks)
                  for i, h in enumerate(self.receivers)]
        return np.asarray(bounds, dtype=np.int64).reshape(-1, 2)

    @property
    def materialised(self) -> bool:
        """True when every prepared sample is held (records from :func:`prepare`); False for the
        records a plain ``backproject`` call prepares block by block and drops."""
        return self._host is not None

    @property
    def nbytes(self) -> int:
        """Host bytes held (0 when not materialised)."""
        return 0 if self._host is None else int(sum(a.nbytes for a in self._host))

    def _make(self, i: int, pulses: np.ndarray) -> np.ndarray:
        h = self.receivers[i]
        first, stop = (int(b) for b in self._bounds[i])
        block = self.echo.data[h, pulses[0]:pulses[-1] + 1]
        if stop <= first:  # the grid reaches nothing of this record: zeros the kernels may load safely
            return np.zeros((pulses.size, MIN_SAMPLES), np.complex64)
        if self.factor == 1:
            return np.ascontiguousarray(block[:, first:stop], dtype=np.complex64)  # a view when it already is
        if self.upsampler == "fft":
            return upsample_blocks(block, self.factor, first, stop, self._workers)
        if self.fir_on_device:
            return fir.upsample_fir(block, self.factor, first, stop)
        return fir.upsample_reference(block, self.factor, first, stop)

    @property
    def fir_on_device(self) -> bool:
        """True when the FIR upsampler runs on the OpenCL device (the default backend is OpenCL)."""
        if self._fir_device is None:
            self._fir_device = self.upsampler == "fir" and _backend.resolve(None) == "opencl"
        return self._fir_device

    def samples(self, i: int, pulses: np.ndarray) -> np.ndarray:
        """Receiver ``receivers[i]``'s prepared records of the consecutive ``pulses``, complex64
        (len(pulses), length[i]) (MIN_SAMPLES zeros when the grid reaches nothing of the record)."""
        if self._host is not None:
            return self._host[i][pulses[0]:pulses[-1] + 1]
        return self._make(i, pulses)

    def buffer(self, ctx, i: int, pulses: np.ndarray, double: bool, queue=None, staged: dict | None = None):
        """(device buffer of receiver ``receivers[i]``'s records (complex128 when ``double``),
        samples per record, the buffer's first pulse). Materialised records keep one buffer of all
        pulses per (receiver, precision) (``staged``, a call's own dict of buffers: the complex64 rows of
        ``pulses``, up to STAGE_BYTES, copied from it in order into the call's buffer for ``queue``, where the
        kernels' scattered reads find them in cache instead of memory; the buffers go with the call, as
        threads share held records and queues); others build one for the consecutive ``pulses`` (FIR-
        upsampled on ``queue``, default the runtime's, into that queue's scratch buffer)."""
        import pyopencl as cl

        mf = cl.mem_flags
        dtype = np.complex128 if double else np.complex64
        if self._host is not None:
            key = (int(ctx.int_ptr), self.receivers[i], bool(double))
            if key not in self._device:
                host = self._host[i] if not double else self._host[i].astype(np.complex128)
                host.flags.writeable = False
                self._device[key] = (cl.Buffer(ctx, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=host), host)
            n = self._host[i].shape[1]
            row = 8 * n  # complex64
            if staged is None or double or row * pulses.size > STAGE_BYTES:
                return self._device[key][0], n, 0
            queue = opencl.runtime().queue if queue is None else queue
            dst = self._scratch_of(ctx, queue, row * pulses.size, staged, lambda: self.staged_bytes(pulses.size))
            cl.enqueue_copy(queue, dst, self._device[key][0], byte_count=row * pulses.size,
                            src_offset=row * int(pulses[0]), dst_offset=0)
            return dst, n, int(pulses[0])
        if self.fir_on_device and not double and self._bounds[i, 1] > self._bounds[i, 0]:
            return self._upsampled_on_device(ctx, i, pulses, queue), int(self.length[i]), int(pulses[0])
        records = self.samples(i, pulses)
        if records.dtype == dtype and records.flags.c_contiguous and records.base is not None:
            # a view of the echo itself (no upsampling, no cut): the device reads it in place; the
            # call finishes its queue before it returns, and the echo outlives the call
            return cl.Buffer(ctx, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=records), records.shape[1], int(pulses[0])
        # an array made for this call is copied: the launcher drops a block's buffer while its
        # kernels may still be queued, and a USE_HOST_PTR buffer's array would go with it
        records = np.ascontiguousarray(records, dtype=dtype)
        return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=records), records.shape[1], int(pulses[0])

    def _upsampled_on_device(self, ctx, i: int, pulses: np.ndarray, queue=None):
        """A device buffer of receiver ``receivers[i]``'s records of the consecutive ``pulses``,
        upsampled by the FIR on the device (the kernel enqueued on ``queue``, default the runtime's,
        which the back-projection kernels then read in order; one scratch buffer a queue)."""
        import pyopencl as cl

        mf = cl.mem_flags
        first, stop = (int(b) for b in self._bounds[i])
        rows = self.echo.data[self.receivers[i], pulses[0]:pulses[-1] + 1]
        src = np.ascontiguousarray(rows, np.complex64)
        # the echo's own rows are read in place (the call finishes its queue before it returns and
        # the echo outlives it); a converted copy is copied, as it goes with this function
        flags = mf.USE_HOST_PTR if np.shares_memory(src, self.echo.data) else mf.COPY_HOST_PTR
        src_buf = cl.Buffer(ctx, mf.READ_ONLY | flags, hostbuf=src)
        queue = opencl.runtime().queue if queue is None else queue
        dst = self._scratch_of(ctx, queue, 8 * src.shape[0] * int(self.length[i]), block=self._largest_block)
        fir.enqueue(queue, src_buf, src.shape[1], src.shape[0], first, stop, self.factor, dst)
        return dst

    def _largest_block(self) -> int:
        """Bytes of a call's largest upload block upsampled (complex64, the longest record)."""
        return 8 * min(self.upload_pulses(), self.echo.n_pulses) * int(np.max(self.length))

    def _scratch_of(self, ctx, queue, size: int, mine: dict | None = None, block=None):
        """The buffer on ``queue`` (>= ``size`` bytes) a call's blocks are upsampled (staged) into in turn, kept
        in ``mine`` (default this object's): an in-order queue runs a block's command after the kernels reading
        the previous one (a fresh buffer costs its page faults each time). Made at ``block()`` bytes at least
        (the call's largest block; asked only when a buffer is made), so that it does not grow: a lane then
        holds one buffer, as the memory budget counts it (:func:`record_bytes`)."""
        import pyopencl as cl

        in_order = not queue.properties & cl.command_queue_properties.OUT_OF_ORDER_EXEC_MODE_ENABLE
        key, mine = (int(ctx.int_ptr), int(queue.int_ptr)), self._scratch if mine is None else mine
        if not in_order or key not in mine or mine[key].size < size:
            mine[key] = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, size=max(size, block() if block else 0))
        return mine[key]

    def subset(self, chosen) -> "PreparedRecords":
        """The same records for the receivers ``chosen`` (echo indices, all prepared), in that
        order: shares the samples and the device buffers."""
        rows = [self.receivers.index(h) for h in chosen]
        part = object.__new__(PreparedRecords)
        part.__dict__.update(self.__dict__)
        part.receivers = tuple(self.receivers[r] for r in rows)
        part._bounds, part.offset, part.length, part.span = (a[rows] for a in
                                                             (self._bounds, self.offset, self.length, self.span))
        part._host = None if self._host is None else [self._host[r] for r in rows]
        return part

    def staged_bytes(self, n_pulses: int) -> int:
        """Bytes of the buffer a lane stages held rows of ``n_pulses`` pulses into (:meth:`buffer`): the
        largest receiver's rows within STAGE_BYTES (0 when none fits, or the records are not held)."""
        rows = [8 * held.shape[1] * int(n_pulses) for held in self._host or ()]
        return max([r for r in rows if r <= STAGE_BYTES], default=0)

    def double_copy_bytes(self) -> int:
        """Bytes of the complex128 copies of held records that a ``precision="double"`` call makes and
        keeps (:meth:`buffer`), for the receivers whose copy is not made yet (0 for records not held)."""
        made = {h for (_, h, double) in self._device if double}
        return sum(16 * held.size for h, held in zip(self.receivers, self._host or ()) if h not in made)

    def upload_pulses(self) -> int:
        """Pulses a call's job covers: all for materialised records (their buffers hold every
        pulse), else as many as fill UPLOAD_BYTES (at least 64)."""
        if self._host is not None:
            return self.echo.n_pulses
        per_pulse = 16 * max(1, int(np.max(self.length)))
        return max(64, int(UPLOAD_BYTES // per_pulse) // 64 * 64)

    @property
    def whole(self) -> bool:
        """True when every receiver's whole record is prepared (they cover any grid)."""
        return bool(np.all(self._bounds[:, 0] == 0) and np.all(self._bounds[:, 1] == self.echo.n_samples))

    def covers(self, spans: np.ndarray) -> np.ndarray:
        """(len(receivers),) bool: the prepared samples hold every sample the interpolator reads
        for delays within ``spans`` (len(receivers), 2) s."""
        need = self._samples_for(spans)
        empty = need[:, 1] <= need[:, 0]
        return empty | ((need[:, 0] >= self._bounds[:, 0]) & (need[:, 1] <= self._bounds[:, 1]))

    def release(self) -> None:
        """Free the device buffers now (the host samples stay; buffers are made again on next use)."""
        for buf, _ in self._device.values():
            buf.release()
        self._device.clear()

    def __repr__(self) -> str:
        kind = f"{self.nbytes / 2**20:.1f} MB held" if self.materialised else "prepared per call"
        return (f"PreparedRecords({len(self.receivers)} receivers x {self.echo.n_pulses} pulses, "
                f"interp={self.interp!r}, upsample={self.upsample}, "
                f"samples per record {int(self.length.min())}..{int(self.length.max())}, {kind})")


def prepare(compressed: EchoData, upsample: int = 8, interp: str = "linear", receivers=None, grid=None,
            target_velocity=None, workers: int | None = None) -> PreparedRecords:
    """Prepare range-compressed records for any number of :func:`clsas.backproject` calls.

    Parameters
    ----------
    compressed : EchoData, range-compressed (:func:`clsas.range_compress`).
    upsample : int in [1, 64]
        Upsampling of the records for ``interp="linear"`` (the FIR, or FFT blocks for echoes
        sampled below 1.25 B: module docstring; ignored by sinc8, which reads the original samples).
    interp : {"linear", "sinc8"}, the interpolator the calls will use.
    receivers : indices or names of the receivers to prepare (default: all).
    grid : None, Grid, or a fast-time span
        Which samples to prepare: None, every sample of the records; a :class:`clsas.model.Grid`,
        the span it can reach (:func:`.spans.reach`; ``target_velocity`` the pixels' velocity); a pair
        ``(start, stop)`` in seconds (fast time after emission), the same for every receiver, or
        an array (len(receivers), 2), one span per receiver.
    target_velocity : 3-vector, m/s, optional; the velocity the calls will give, for ``grid``'s reach.
    workers : int, scipy.fft threads of the FFT blocks (default: all cores).

    Returns
    -------
    PreparedRecords: pass it to ``backproject`` in place of the echo (``interp``, ``upsample``
    and ``receivers`` then come from it). Its host memory is that of the prepared samples
    (``nbytes``: 8 bytes a sample, ``upsample`` samples per original one for linear); device
    buffers, see the module docstring.
    """
    chosen, velocity = check_options(compressed, receivers, interp, upsample, target_velocity, who="prepare")
    upsample = int(upsample)
    if workers is not None:
        workers = check_workers(workers, "prepare workers")
    spans = fast_time_spans(compressed, chosen, grid, velocity)
    return PreparedRecords(compressed, chosen, interp, upsample, spans, materialise=True, workers=workers)


def upsampler_for(echo: EchoData, factor: int):
    """How records of ``echo`` are upsampled by ``factor``: "fir" when the echo's band fits the
    FIR's (B / (2 fs) <= upsample.MAX_BAND), "fft" nearer the Nyquist rate, None for factor 1."""
    if factor == 1:
        return None
    return "fir" if echo.waveform.bandwidth / (2.0 * echo.fs) <= fir.MAX_BAND * (1 + 1e-9) else "fft"


def fast_time_spans(echo: EchoData, chosen, grid, velocity, box=None) -> np.ndarray:
    """(len(chosen), 2) s: the spans to prepare for ``grid`` (see :func:`prepare`; ``box``: a
    Grid's pixel box when known, :func:`.spans.reach`)."""
    if grid is None:
        t0 = np.asarray(echo.t0)[list(chosen)]
        return np.column_stack([t0, t0 + echo.n_samples / echo.fs])
    if isinstance(grid, Grid):
        return reach(echo, chosen, grid.positions, velocity, box)
    try:
        spans = np.asarray(grid, dtype=np.float64)
    except (TypeError, ValueError):
        spans = None
    if spans is None or spans.shape not in ((2,), (len(chosen), 2)):
        raise TypeError(f"grid must be None, a clsas.model.Grid or a fast-time span (start, stop) in seconds "
                        f"(or one per receiver, shape ({len(chosen)}, 2)), got {grid!r:.80}")
    spans = np.broadcast_to(spans, (len(chosen), 2))
    if not np.all(np.isfinite(spans)) or np.any(spans[:, 1] <= spans[:, 0]):
        raise ValueError(f"grid as a fast-time span needs finite start < stop (s), got {grid!r:.80}")
    return np.array(spans)


def jobs_in_flight(job_bytes: int) -> int:
    """Jobs of ``job_bytes`` (16 bytes a sample, as upload_pulses counts) whose records a call holds at once."""
    return int(min(MAX_IN_FLIGHT, max(2, IN_FLIGHT_BYTES // job_bytes)))


def record_bytes(records: PreparedRecords, span: tuple[int, int], double: bool) -> int:
    """Bytes a call on pulses ``span`` makes for ``records`` beyond their held samples (a bound, checked
    against the memory budget before the call: :mod:`.direct`; the launcher makes them). Held records:
    the buffers two lanes stage rows into (single), or the complex128 copies a double call makes and
    keeps, where not made yet. Records made per call: with the FIR on the device (single), one scratch
    buffer a lane (two), each a job's records; otherwise the jobs in flight (:func:`jobs_in_flight`, at
    most a chunk's) each in a buffer of its own (16 bytes a sample for double), and the host arrays of
    the one being made (complex64, and its complex128 copy for double). Records of the echo read in
    place (not upsampled, single): none."""
    if records.materialised:
        return records.double_copy_bytes() if double else 2 * records.staged_bytes(span[1] - span[0])
    if records.factor > 1 and not double and records.fir_on_device:
        return 2 * records._largest_block()  # the lanes' scratch buffers, each made at that size (_scratch_of)
    longest = max(1, int(np.max(records.length)))
    if records.factor == 1 and not double:
        return 0
    upload = records.upload_pulses()
    job = min(upload, span[1] - span[0]) * longest  # samples
    jobs = min(jobs_in_flight(16 * job), len(records.receivers) * -(-(span[1] - span[0]) // upload))
    return jobs * (16 if double else 8) * job + (24 if double else 8) * job


def _pulse_span(pulses, n_pulses: int) -> tuple[int, int]:
    """(start, stop) of the consecutive pulses to sum, or a ValueError naming ``pulses``."""
    if pulses is None:
        return 0, n_pulses
    if isinstance(pulses, (range, slice)):
        step = 1 if pulses.step is None else pulses.step
        start, stop = pulses.start or 0, n_pulses if pulses.stop is None else pulses.stop
    elif isinstance(pulses, (tuple, list)) and len(pulses) == 2:
        (start, stop), step = pulses, 1
    else:
        raise ValueError(f"pulses must be None, (start, stop), a range or a slice of consecutive pulses, "
                         f"got {pulses!r}")
    ok = all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in (start, stop, step))
    if not ok or step != 1 or not 0 <= start < stop <= n_pulses:
        raise ValueError(f"pulses must select consecutive pulses start < stop within [0, {n_pulses}], got {pulses!r}")
    return int(start), int(stop)


def records_for(echo, grid: Grid, receivers, interp, upsample, target_velocity, pulses, box=None) -> tuple:
    """What one :func:`clsas.backproject` call reads: (records, the pixels' velocity (3,), the
    pulses (start, stop) to sum, the grid's reach (len(records.receivers), 2) s when computed here, else
    None). ``echo`` an EchoData (its records are then prepared for ``grid``'s reach block by block during
    the call) or :class:`PreparedRecords` (checked against the options and the grid; ``box``: the grid's
    pixel box when known, :func:`.spans.reach`: computed once a call, for the coverage of records not
    whole, and handed on for the launcher's staging choice); ValueError/TypeError naming the parameter."""
    if isinstance(echo, PreparedRecords):
        records = echo
        for name, asked, held in (("interp", interp, records.interp), ("upsample", upsample, records.upsample)):
            if asked is not None and asked != held:
                raise ValueError(f"{name}={asked!r} contradicts the prepared records' {name}={held!r}: "
                                 f"prepare the records with {name}={asked!r}, or leave {name} out")
        _, velocity = check_options(records.echo, None, records.interp, records.upsample, target_velocity)
        if receivers is not None:
            chosen = records.echo.select_receivers(receivers)
            missing = [records.echo.receivers[h] for h in chosen if h not in records.receivers]
            if missing:
                raise ValueError(f"receivers {missing} were not prepared; the records hold "
                                 f"{[records.echo.receivers[h] for h in records.receivers]}")
            records = records.subset(chosen)
        reached = None if records.whole else reach(records.echo, records.receivers, grid.positions, velocity, box)
        covered = [True] if reached is None else records.covers(reached)
        if not np.all(covered):
            names = [records.echo.receivers[h] for h, ok in zip(records.receivers, covered) if not ok]
            raise ValueError(f"grid: the prepared records do not cover the fast times this grid reaches "
                             f"(receivers {names}); prepare them with grid=None or with this grid")
    else:
        interp = "linear" if interp is None else interp
        upsample = 8 if upsample is None else upsample
        chosen, velocity = check_options(echo, receivers, interp, upsample, target_velocity)
        # records not upsampled are read whole, in place (spans.samples_for_span): the grid's reach would only tell a
        # record it misses entirely, whose samples the kernels then never read (they read none outside a record)
        spans = fast_time_spans(echo, chosen, grid if (int(upsample) if interp == "linear" else 1) > 1 else None,
                                velocity, box)
        records, reached = PreparedRecords(echo, chosen, interp, int(upsample), spans, materialise=False), None
    return records, velocity, _pulse_span(pulses, records.echo.n_pulses), reached
