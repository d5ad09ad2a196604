"""Time-domain back-projection for any geometry (NumPy reference and OpenCL launcher).

For every pixel P (its position at t = 0; with ``target_velocity`` v it moves, P(t) = P + v t,
which focuses a moving target, Kiang & Kiang 2022), every selected receiver h and pulse p:

    tau   = t1 + t2, the exact two-way delay: transmitter at its emission position T(eta),
            the pixel met at eta + t1 with c t1 = |P(eta + t1) - T(eta)|, the receiver at
            eta + t1 + t2 with c t2 = |R_h(eta + t1 + t2) - P(eta + t1)| (the receiver's
            positions come from EchoData: linear between its nodes);
            ``stop_and_go=True`` evaluates all positions at eta;
    image(P) += s_h,p(tau) exp(+j 2 pi f0 tau),

s the range-compressed record sampled at ``t0_h + k / fs``: its value at tau comes from linear
interpolation of the record FFT-upsampled by ``upsample`` in blocks (``interp="linear"``;
:mod:`clsas.image.backprojection.records`: only the fast-time span the grid reaches) or from an
8-tap Kaiser-windowed sinc of :mod:`clsas.interp` on the original samples (``interp="sinc8"``;
:func:`clsas.interp.read_rows` in the reference, ``kernels/interp.h`` in the kernels). The
rotation exp(+j 2 pi f0 tau) undoes the carrier phase exp(-j 2 pi f0 tau) of the baseband echo
(docs/design.md signal model), so all contributions of a scatterer add in phase at its pixel.

Aperture: ``aperture`` (radians, full integration angle) keeps only the pulses that see the
pixel within +-aperture/2 of broadside: |sin theta| <= sin(aperture / 2) with sin theta the
along-track (y) component of the unit vector from the transmitter to the pixel.

Precision (OpenCL). ``precision="single"``: the geometry runs in float32 *relative to a
reference point per spatial tile and pulse* whose exact legs the host computes in float64
(derivation and error bound at :func:`backproject_opencl`); the phase error this leaves is
below ``PHASE_BUDGET`` = 2e-3 rad by construction of the tiles (at any range: it scales with the
tile's size, not with the range), well inside the 0.01 rad budget at 2 km and 150 kHz. Where a
receiver's motion is not linear within lambda / 2000 over a tile's delay span (motion errors
with kinks between its position nodes) that receiver's pulse block falls back to the exact
double kernel (delays and carrier cycles in double per pixel). The interpolation, the phase
factor (fractional cycles, polynomial sin/cos, error < 1e-6) and the accumulation are float.
Sums are blocked: float over a block of at most ``PULSE_BLOCK`` = 64 pulses (relative error
below 64 x 6e-8 = 4e-6 even if every rounding adds up), then added into a double image, so
10^5 pulses x receivers add at most another 10^5 x 1.1e-16 relative. ``precision="double"``
runs the exact double kernel with the data path in double as well.

Memory: the pixels are processed in chunks of at most ``PIXEL_CHUNK`` (2^22) pixels on the
device (a 4096^2 image is four chunks of ~150 MB of device buffers each), the records a block
of at most ``records.UPLOAD_BYTES`` at a time (at most two blocks in flight: the
host waits for the kernels of the block before last), the per-(tile, pulse) references a block
at a time; the host keeps the tile order of the pixels (12 bytes a pixel) beside the grid.
Records prepared with :func:`prepare` are held whole instead (host and device: see that
module), and a :class:`GridPlan` keeps the grid's tile plan and pixel fields. The NumPy
reference works on at most 2^20 pixels x 4 pulses at once.

Fixed cost per call, and how to pay it once: the records' upsampling and upload
(:func:`prepare`), the grid's tile plan (:class:`GridPlan`); the per-(tile, pulse) references
depend on both and are computed in every call (a few per cent of the kernels' time).
"""

from __future__ import annotations

import warnings

import numpy as np

from ...progress import NOMINAL_RATES, Progress, stage
from ... import backend as _backend
from ... import budget, opencl, validate
from ...model import EchoData, Grid, Image
from ...cstruct import declare_all, record_dtype
from ...geometry import NODE, legs, two_node_velocity, uniform_nodes
from ...interp import TAP_ROWS, kernel_taps, read_rows
from .records import PreparedRecords, check_options, fast_time_spans, prepare, reach
from .tiles import (ERROR_FACTOR, LANES, PHASE_BUDGET, ROWS, GridPlan, Tiling, aperture_spans, plan_tiles,
                                   tile_half_extent)

__all__ = ["ERROR_FACTOR", "PHASE_BUDGET", "GridPlan", "PreparedRecords", "Tiling", "backproject", "plan_tiles", "prepare",
           "reach", "tile_half_extent"]

PULSE_BLOCK = 64  # pulses a kernel launch (one reference sub-block; 32 was ~4 % slower: more launches)
PIXEL_CHUNK = 2**22  # pixels on the device at once
PULSES = 2  # bp_tile: pulses a work-item step (with LANES x ROWS pixels, .tiles)
NODE_TOLERANCE = 1 / 2000  # of a wavelength: a receiver's allowed departure from linear motion over a tile
SPAN_FACTOR = 2.5  # a tile's delay span is +-SPAN_FACTOR * half_extent / c around its reference
REF_PULSES = 64  # pulses whose tile references are computed at once
# the records the kernels read (kernels/backprojection.cl), declared once here: bp_tile's reference
# of a (tile, pulse) and its parameters (float32), bp_block's pulse and parameters (float64)
TILE_REF = record_dtype([("leg1", "f4", 3), ("b1", "f4"), ("leg2", "f4", 3), ("b2", "f4"), ("v_rx", "f4", 3),
                         ("a2", "f4"), ("k_ref", "i4"), ("k_frac", "f4"), ("cycles", "f4"), ("range1", "f4")])
TILE_PARAMS = record_dtype([("a1", "f4"), ("fs", "f4"), ("f0", "f4"), ("velocity", "f4", 3), ("half_sin", "f4"),
                            ("c", "f4")])
PULSE = record_dtype([("tx", "f8", 3), ("eta", "f8"), ("t0_fs", "f8"), ("first", "i4")])
BLOCK_PARAMS = record_dtype([("c", "f8"), ("f0", "f8"), ("fs", "f8"), ("dtau", "f8"), ("velocity", "f8", 3),
                             ("half_sin", "f8")])
RECORDS = declare_all({"node_t": NODE, "tile_ref_t": TILE_REF, "tile_params_t": TILE_PARAMS, "bp_pulse_t": PULSE,
                       "bp_block_params_t": BLOCK_PARAMS})
BYTES_PER_PIXEL = 80  # what a call adds a pixel (tests/test_backprojection.py measures it)


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
        raise ValueError(f"pulses must be None, (start, stop), a range or a slice of consecutive pulses, got {pulses!r}")
    ok = all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in (start, stop, step))
    if not ok or step != 1 or not 0 <= start < stop <= n_pulses:
        raise ValueError(f"pulses must select consecutive pulses start < stop within [0, {n_pulses}], got {pulses!r}")
    return int(start), int(stop)


def _check_call(grid, aperture):
    if not isinstance(grid, (Grid, GridPlan)):
        raise TypeError(f"grid must be a clsas.model.Grid (Grid.plane, Grid.slant or Grid.points) or a GridPlan, got "
                        f"{type(grid).__name__}")
    if aperture is not None:
        validate.scalar("backproject aperture", aperture, low=0.0, high=np.pi, low_open=True, unit="rad",
                        why="the full integration angle")
    size = grid.size if isinstance(grid, Grid) else grid.grid.size
    budget.check_bytes(f"backproject onto {size} pixels", BYTES_PER_PIXEL * float(size),
                       "image fewer pixels at a time (tiles of the grid)")


def _aperture_keep(echo, pulses, q, half_sin):
    """(P, M) mask: the pixel, at ``q`` where the pulse meets it, lies within the integration
    angle, |sin theta| <= half_sin, theta the angle of transmitter -> pixel off broadside (the
    x-z plane; y is the nominal heading)."""
    d = q - echo.tx_pos[pulses][:, None, :]
    return np.abs(d[..., 1] / np.linalg.norm(d, axis=-1)) <= half_sin


def backproject_reference(records: PreparedRecords, plan: "GridPlan", aperture, velocity, stop_and_go, progress,
                          span: tuple[int, int]):
    """The float64 NumPy reference (vectorised over pixels, at most 2^20 pixels and a few pulses
    at a time): image (M,) complex128. The sample index of a delay tau is k = (tau - t0) fs,
    split into floor(k) and its fraction before the records' offset (an integer) is taken off,
    as the kernels do, so that records prepared over any span covering the grid read alike."""
    echo = records.echo
    pixels = plan.grid.positions.reshape(-1, 3)
    image = np.zeros(pixels.shape[0], dtype=np.complex128)
    f0, fs = echo.waveform.f0, records.fs
    chunk = min(pixels.shape[0], 2**20)
    block = max(1, 2**22 // chunk)
    jobs = [(i, h, np.arange(s, min(s + block, span[1]))) for i, h in enumerate(records.receivers)
            for s in range(span[0], span[1], block)]
    bar = Progress(pixels.shape[0] * len(records.receivers) * (span[1] - span[0]), "pixel-pulses",
                   "back-projection (numpy)", progress)
    for i, h, pulses in jobs:
        samples = records.samples(i, pulses).astype(np.complex128)
        for first in range(0, pixels.shape[0], chunk):
            part = slice(first, first + chunk)
            t1, q, t2, _ = legs(echo, h, pulses, pixels[part], velocity, stop_and_go)
            tau = t1 + t2
            k = (tau - echo.t0[h]) * fs
            whole = np.floor(k)
            value = read_rows(samples, whole.astype(np.int64) - records.offset[i], k - whole, records.interp)
            value *= np.exp(2j * np.pi * f0 * tau)
            if aperture is not None:
                value *= _aperture_keep(echo, pulses, q, np.sin(aperture / 2))
            image[part] += value.sum(axis=0)
            bar.done(value.size)
    bar.close()
    return image




def tile_references(echo: EchoData, h: int, pulses: np.ndarray, centres: np.ndarray, velocity: np.ndarray,
                    stop_and_go: bool, fs: float, half_extent: float, offset: int = 0) -> tuple[np.ndarray, float]:
    """bp_tile's per-(tile, pulse) references (T, P) :data:`TILE_REF` (their meaning in
    :func:`backproject_opencl` and kernels/backprojection.cl) for the T tile ``centres`` ((T, 3), or
    (P, T, 3): each pulse's own) and the P ``pulses``, and the receiver's largest departure (m) from
    the linear motion the kernel assumes over the tiles' delay spans (0 for stop-and-go and for
    receivers with two nodes, whose motion is uniform). ``offset``: the first sample of the records
    the kernel reads, counted at ``fs`` from the window start t0 (taken off the integer part only)."""
    c, f0 = echo.medium.sound_speed, echo.waveform.f0
    t1, q, t2, r = legs(echo, h, pulses, centres, velocity, stop_and_go)
    big_t = t1 + t2
    b_vec = q - echo.tx_pos[pulses][:, None, :]
    c_vec = r - q
    v_r = np.zeros_like(c_vec)
    departure = 0.0
    if not stop_and_go and echo.rx_tau[h].size == 2:
        # uniform motion: the secant over any span is the receiver's velocity
        v_r[:] = two_node_velocity(echo, h, pulses)[:, None, :]
    elif not stop_and_go and echo.rx_tau[h].size > 2:
        # secant of the receiver over the delay span T_ref +- span; the kernel's line passes through R_ref
        span = SPAN_FACTOR * half_extent / c
        ends = echo.rx_position(h, big_t[..., None] + [-span, span], pulses=pulses)
        v_r = (ends[..., 1, :] - ends[..., 0, :]) / (2 * span)
        dtau, _ = uniform_nodes(echo, h)
        # the piecewise-linear track departs from the line most at its nodes or the span's ends
        steps = np.arange(int(np.ceil(2 * span / dtau)) + 2)
        times = np.clip((np.floor((big_t - span) / dtau)[..., None] + steps) * dtau,
                        (big_t - span)[..., None], (big_t + span)[..., None])
        line = r[..., None, :] + v_r[..., None, :] * (times - big_t[..., None])[..., None]
        departure = float(np.max(np.linalg.norm(echo.rx_position(h, times, pulses=pulses) - line, axis=-1)))
    v_k = np.zeros(3) if stop_and_go else velocity
    k_ref = (big_t - echo.t0[h]) * fs
    k_int = np.clip(np.floor(k_ref), -2**30, 2**30)
    cycles = f0 * big_t
    ref = np.empty(big_t.shape, dtype=TILE_REF)
    ref["leg1"] = b_vec
    ref["b1"] = c * c * t1 - b_vec @ v_k
    ref["leg2"] = c_vec
    ref["b2"] = c * c * t2 - np.einsum("...i,...i->...", c_vec, v_r)
    ref["v_rx"] = v_r
    ref["a2"] = c * c - np.einsum("...i,...i->...", v_r, v_r)
    ref["k_ref"] = k_int - offset
    ref["k_frac"] = np.clip(k_ref - k_int, 0.0, np.nextafter(np.float32(1), np.float32(0)))
    ref["cycles"] = cycles - np.round(cycles)
    ref["range1"] = c * t1
    return np.ascontiguousarray(ref.T), departure


def _exact_kernel(ctx, echo, h, pulses, fs, offset, velocity, half_sin, defines, stop_and_go, double):
    """bp_block (the exact double kernel) for receiver h and ``pulses``: the kernel, its pulse and
    receiver-node buffers and its parameters (layouts in kernels/backprojection.cl)."""
    import pyopencl as cl

    dtau, pos = uniform_nodes(echo, h)
    n_nodes = pos.shape[1]
    kern = opencl.kernel("backprojection", "bp_block", double=double, preamble=RECORDS, defines=dict(
        defines, N_NODES=n_nodes, SEGMENT_PASSES=1 if n_nodes == 2 else 3, **({"STOP_AND_GO": 1} if stop_and_go else {})))
    pulse = np.zeros(pulses.size, PULSE)
    pulse["tx"], pulse["eta"], pulse["t0_fs"] = echo.tx_pos[pulses], echo.eta[pulses], echo.t0[h] * fs
    pulse["first"] = offset
    nodes = np.zeros((pulses.size, n_nodes), NODE)
    nodes["pos"] = pos[pulses]
    pulse_buf, nodes_buf = (cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=a)
                            for a in (pulse, nodes))
    params = np.zeros((), BLOCK_PARAMS)
    params["c"], params["f0"], params["fs"], params["dtau"] = echo.medium.sound_speed, echo.waveform.f0, fs, dtau
    params["velocity"], params["half_sin"] = velocity, half_sin
    return kern, pulse_buf, nodes_buf, params[()]


class _Chunk:
    """The device side of slots ``first`` .. ``stop - 1`` of a :class:`Tiling`: bp_tile's pixel
    fields and work-items' tile indices (:meth:`GridPlan.fields`), the tiles present (``tiles``),
    the double image (n,), and on demand the absolute positions for bp_block (double (3, n))."""

    def __init__(self, ctx, plan: GridPlan, f0, c, first: int, stop: int, v_k: np.ndarray):
        import pyopencl as cl

        mf = cl.mem_flags
        tiling = plan.tiling(f0, c)
        self.first, self.n = first, stop - first
        self.order, self.real = tiling.order[first:stop], tiling.real[first:stop]
        fields, tile_of, self.tiles = plan.fields(f0, c, first, stop, v_k)
        self.pix = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=fields)
        self.tile_of = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=tile_of)
        self.image = cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=np.zeros(self.n, np.complex128))
        self._absolute = None

    def absolute(self, ctx, pixels):
        if self._absolute is None:
            import pyopencl as cl

            self._absolute = cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                                       hostbuf=np.ascontiguousarray(pixels[self.order].T))
        return self._absolute

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
    queue's profiling events).

    ``precision="single"`` (bp_tile): float32 geometry relative to a reference per (tile, pulse).
    Derivation. Let the tile's reference point meet pulse p at t1_ref, at q_ref (exact, float64,
    :func:`clsas.geometry.legs`), and its echo reach the receiver at T_ref = t1_ref + t2_ref, at R_ref; let
    B = q_ref - tx (|B| = c t1_ref) and C = R_ref - q_ref (|C| = c t2_ref). A pixel of the tile
    sits at delta from the reference point and moves with it at v, so it meets the pulse at
    q = q_ref + delta + v s1 with s1 = t1 - t1_ref; c t1 = |q - tx| gives
    |B + delta + v s1|^2 = c^2 (t1_ref + s1)^2, and subtracting |B|^2 = c^2 t1_ref^2:

        (c^2 - |v|^2) s1^2 + 2 b1 s1 - N1 = 0,  N1 = 2 B.delta + |delta|^2,  b1 = c^2 t1_ref - (B + delta).v,

    whose root near 0 is s1 = N1 / (b1 + sqrt(b1^2 + (c^2 - |v|^2) N1)) (no cancellation: b1 ~ c |B|
    > 0). The receiver moves linearly over the tile's delay span, R = R_ref + v_r (s1 + s2) with
    s2 = t2 - t2_ref, so R - q = C + e + v_r s2 with e = (v_r - v) s1 - delta, and
    c t2 = |R - q| gives likewise

        (c^2 - |v_r|^2) s2^2 + 2 b2 s2 - N2 = 0,  N2 = 2 C.e + |e|^2,  b2 = c^2 t2_ref - (C + e).v_r,

    s2 = N2 / (b2 + sqrt(b2^2 + (c^2 - |v_r|^2) N2)). The delay is T_ref + s1 + s2 (DESIGN.md's
    exact non-stop-and-go delay; stop-and-go is the same with v = v_r = 0 and references at eta);
    the sample index (T_ref - t0) fs + (s1 + s2) fs is K_ref + (frac_ref + (s1 + s2) fs) and the
    carrier cycles f0 T_ref (reduced in double) + f0 (s1 + s2). Nothing of size |B| is subtracted
    in float: every term carries a relative error of a few eps32 of a quantity of size |delta|
    (N1, N2, s1, s2 ~ |delta| / c; B, C, b1, b2 enter as ratios), and f0 (s1 + s2) ~ 2 f0 |delta| / c
    cycles is rounded once more; counting about ERROR_FACTOR = 8 roundings of |delta| / c of delay,
    the phase error is below 2 pi f0 8 eps32 |delta| / c, kept below PHASE_BUDGET by the tile
    size (:func:`plan_tiles`; tests/test_backprojection.py measures it). The receiver's velocity
    v_r is the secant of its track over T_ref +- SPAN_FACTOR |delta|_max / c (which contains
    every pixel's delay); where the track departs from that line by more than NODE_TOLERANCE
    wavelengths (motion errors: kinks at its nodes), the receiver's pulse block runs on the exact
    double kernel instead (bp_block; counted in the result). The records' offset (their first
    sample, an integer) is taken off the reference's integer sample index K_ref (and bp_block's
    after its floor), so the fraction, hence the image, does not depend on the span prepared.
    """
    import pyopencl as cl

    rt = opencl.runtime()
    ctx, queue = rt.context, rt.queue
    mf = cl.mem_flags
    echo, interp, fs = records.echo, records.interp, records.fs
    c, f0 = echo.medium.sound_speed, echo.waveform.f0
    pixels = plan.grid.positions.reshape(-1, 3)
    image = np.zeros(pixels.shape[0], dtype=np.complex128)
    taps_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=kernel_taps(interp))
    defines = {"INTERP_LINEAR" if interp == "linear" else "INTERP_SINC8": 1, "TAP_ROWS": TAP_ROWS,
               **({"APERTURE": 1} if aperture is not None else {})}
    half_sin = np.sin(aperture / 2) if aperture is not None else 1.0
    v_k = np.zeros(3) if stop_and_go else velocity
    tiles = plan.tiling(f0, c)
    chunk = PIXEL_CHUNK // (LANES * ROWS) * (LANES * ROWS)
    upload = records.upload_pulses()
    jobs = [(first, i, np.arange(s, min(s + upload, span[1]))) for first in range(0, tiles.order.size, chunk)
            for i in range(len(records.receivers)) for s in range(span[0], span[1], upload)]
    tolerance = NODE_TOLERANCE * echo.waveform.wavelength(echo.medium)
    fallbacks, chunk_state, in_flight, kernel_seconds = 0, None, [], 0.0

    def retire(keep: int) -> float:
        """Wait for all but the last ``keep`` jobs' kernels (so that the host, which prepares
        records faster than the kernels read them, holds at most ``keep`` + 1 upload blocks) and
        return their time (s); their events are dropped (PoCL keeps a command's buffers while
        its event lives)."""
        seconds = 0.0
        while len(in_flight) > keep:
            done = in_flight.pop(0)
            for e in done:
                e.wait()
                seconds += 1e-9 * (e.profile.end - e.profile.start)
            bar.done(work.pop(0))  # the progress bar counts finished kernels' pixel-pulses
        return seconds

    tile_kernel = opencl.kernel("backprojection", "bp_tile", preamble=RECORDS, defines=dict(
        defines, BP_TILE=1, ROWS=ROWS, PULSES=PULSES, **({"MOVING": 1} if np.any(v_k) else {}),
        **({"PULSE_SPAN": 1} if aperture is not None else {})))
    tile_params = np.zeros((), TILE_PARAMS)
    tile_params["a1"], tile_params["fs"], tile_params["f0"] = c * c - v_k @ v_k, fs, f0
    tile_params["velocity"], tile_params["half_sin"], tile_params["c"] = v_k, half_sin, c
    bar = Progress(pixels.shape[0] * len(records.receivers) * (span[1] - span[0]), "pixel-pulses", "back-projection (opencl)",
                   progress)
    work = []
    for first, i, pulses in jobs:
        h, offset = records.receivers[i], int(records.offset[i])
        if chunk_state is None or chunk_state.first != first:
            if chunk_state is not None:
                chunk_state.finish(queue, image)
            chunk_state = _Chunk(ctx, plan, f0, c, first, min(first + chunk, tiles.order.size), v_k)
        kernel_seconds += retire(1)
        records_buf, n_samples, base = records.buffer(ctx, i, pulses, double)
        skip = int(pulses[0] - base)  # the job's first pulse in the buffer (which may hold earlier pulses)
        in_flight.append(events := [])
        work.append(int(np.count_nonzero(chunk_state.real)) * pulses.size)
        exact = None
        for s in range(0, pulses.size, REF_PULSES):
            # a sub-block's references are computed while the previous sub-block's kernels run
            blocks = [(p0, min(PULSE_BLOCK, s + REF_PULSES - p0, pulses.size - p0))
                      for p0 in range(s, min(s + REF_PULSES, pulses.size), PULSE_BLOCK)]
            if not double:
                ref, departure = tile_references(echo, h, pulses[s:s + REF_PULSES], tiles.centres[chunk_state.tiles],
                                                 velocity, stop_and_go, fs, tiles.half_extent, offset)
                if departure <= tolerance:
                    ref_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=ref)
                    spans = () if aperture is None else (cl.Buffer(  # a tile sums only the pulses that can see it
                        ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=aperture_spans(
                            ref["leg1"][..., 1], ref["range1"], half_sin, tiles.half_extent, float(np.linalg.norm(v_k)), c,
                            skip + s)),)
                    for p0, count in blocks:
                        events.append(tile_kernel(
                            queue, (chunk_state.n // (LANES * ROWS),), None, chunk_state.pix, chunk_state.tile_of,
                            ref_buf, np.int32(ref.shape[1]), np.int32(skip + s), records_buf, taps_buf, tile_params[()],
                            np.int32(skip + p0), np.int32(count), np.int32(n_samples), np.int32(chunk_state.n),
                            chunk_state.image, *spans))
                    continue
                fallbacks += 1
            if exact is None:  # the exact double kernel (precision="double", or the fallback)
                # pulse and node buffers indexed like the records buffer (from its first pulse)
                exact = _exact_kernel(ctx, echo, h, np.arange(base, pulses[-1] + 1), fs, offset, velocity, half_sin,
                                      defines, stop_and_go, double)
            kern, pulse_buf, nodes_buf, params = exact
            for p0, count in blocks:
                events.append(kern(queue, (chunk_state.n // 8,), None, chunk_state.absolute(ctx, pixels), pulse_buf,
                                   nodes_buf, records_buf, taps_buf, params, np.int32(skip + p0), np.int32(count),
                                   np.int32(n_samples), np.int32(chunk_state.n), chunk_state.image))
    kernel_seconds += retire(0)
    chunk_state.finish(queue, image)
    bar.close()
    return image, fallbacks, kernel_seconds


def backproject(echo, grid, backend: str | None = None, receivers=None, interp: str | None = None,
                upsample: int | None = None, aperture: float | None = None, target_velocity=None,
                stop_and_go: bool = False, precision: str = "single", progress: bool = True,
                pulses=None) -> Image:
    """Back-project range-compressed echoes onto ``grid`` (see the module docstring).

    Parameters
    ----------
    echo : EchoData, range-compressed (:func:`clsas.range_compress`), or PreparedRecords
        (:func:`prepare`): records prepared once for many calls; the image is bit-identical to
        the one the echo gives with the records' ``interp``, ``upsample`` and ``receivers``.
    grid : Grid (plane, slant plane or any 3-D points), or a :class:`GridPlan` of one to image
        the same grid again without redoing its tile plan.
    backend : {"numpy", "opencl", "auto"} or None.
    receivers : indices or names of the receivers to sum coherently (default: all; with prepared
        records: theirs, of which a subset may be chosen).
    interp : {"linear", "sinc8"}
        Linear interpolation of data FFT-upsampled by ``upsample`` (in blocks:
        :mod:`clsas.image.backprojection.records`), or an 8-tap windowed sinc on the original
        samples. Default "linear", or the prepared records' (which a different value contradicts).
    upsample : int in [1, 64], default 8 (or the prepared records'). A call on an echo upsamples
        only the fast-time span the grid reaches; to image many grids from one echo, prepare the
        records once with :func:`prepare`.
    aperture : float, optional
        Full integration angle, radians.
    target_velocity : 3-vector, optional
        Velocity (m/s) of the pixels, to focus a target moving at it.
    stop_and_go : bool
        Use stop-and-go delays (all positions at the emission time).
    precision : {"single", "double"}
        The OpenCL kernel's data path (delays and carrier cycles are double either way).
    pulses : (start, stop), range or slice of consecutive pulses, optional
        Sum only pulses start .. stop - 1 (a sub-aperture, e.g. the first stage of a factorised
        back-projection: prepare the records once, image each sub-aperture on its own grid).
        Default: all.

    Returns
    -------
    Image with the grid's dims and axes, ``positions`` the grid's pixels, complex64; its
    provenance records the options and, for OpenCL, ``kernel_seconds`` (the kernels' own time).
    """
    _check_call(grid, aperture)
    plan = grid if isinstance(grid, GridPlan) else GridPlan(grid)
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
        covered = [True] if records.whole else records.covers(reach(records.echo, records.receivers,
                                                                    plan.grid.positions, velocity))
        if not np.all(covered):
            names = [records.echo.receivers[h] for h, ok in zip(records.receivers, covered) if not ok]
            raise ValueError(f"grid: the prepared records do not cover the fast times this grid reaches "
                             f"(receivers {names}); prepare them with grid=None or with this grid")
    else:
        interp = "linear" if interp is None else interp
        upsample = 8 if upsample is None else upsample
        chosen, velocity = check_options(echo, receivers, interp, upsample, target_velocity)
        upsample = int(upsample)
        records = PreparedRecords(echo, chosen, interp, upsample, fast_time_spans(echo, chosen, plan.grid, velocity),
                                  materialise=False)
    span = _pulse_span(pulses, records.echo.n_pulses)
    double = _backend.check_precision(precision)
    name = _backend.resolve(backend)
    args = (records, plan, aperture, velocity, stop_and_go, progress, span)
    g = plan.grid
    with stage(f"back-projection ({name}, {records.interp})", f"{g.size} pixels x {len(records.receivers)} receivers x "
               f"{span[1] - span[0]} pulses x {records.echo.n_samples} samples",
               g.size * len(records.receivers) * (span[1] - span[0]), NOMINAL_RATES.get(("backprojection", name))):
        if name == "numpy":
            flat, fallbacks, kernel_seconds = backproject_reference(*args), 0, None
        else:
            flat, fallbacks, kernel_seconds = backproject_opencl(*args, double=double)
    source = records.echo
    validate.finite_result("backproject: the image", flat, "scale echo.data down", np.complex64)
    if not np.any(flat) and any(np.any(source.data[h]) for h in records.receivers):
        warnings.warn("backproject: the image is all zeros: no pixel of the grid lies within the recorded fast-time "
                      "windows of the selected receivers (the swath); move the grid", validate.CoverageWarning,
                      stacklevel=2)
    return Image(data=flat.reshape(g.shape), dims=g.dims, axes=g.axes, positions=g.positions,
                 provenance={"algorithm": "backprojection", "backend": name, "precision": precision,
                             "interp": records.interp, "upsample": records.upsample,
                             "receivers": [source.receivers[h] for h in records.receivers],
                             "aperture": aperture, "target_velocity": velocity.tolist(),
                             "stop_and_go": bool(stop_and_go), "exact_fallback_blocks": fallbacks,
                             "prepared_records": records.materialised, "kernel_seconds": kernel_seconds,
                             "pulses": list(span),
                             "echo": dict(source.provenance)})
