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
interpolation of the record FFT-upsampled by ``upsample`` (``interp="linear"``) or from the
8-tap Kaiser-windowed sinc of :mod:`clsas.interp` on the original samples (``interp="sinc8"``;
:func:`clsas.interp.resample_rows` in the reference, ``kernels/interp.h`` in the kernels). The
rotation exp(+j 2 pi f0 tau) undoes the carrier phase exp(-j 2 pi f0 tau) of the baseband echo
(DESIGN.md signal model), so all contributions of a scatterer add in phase at its pixel.

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
of at most ``UPLOAD_BYTES`` at a time, the per-(tile, pulse) references a block at a time; the
host keeps the tile order of the pixels (12 bytes a pixel) beside the grid. The NumPy
reference works on at most 2^20 pixels x 4 pulses at once.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from tqdm.auto import tqdm

from .. import backend as _backend
from .. import opencl
from ..data import EchoData, Grid, Image
from ..cstruct import declare_all, record_dtype
from ..geometry import NODE, legs, two_node_velocity, uniform_nodes
from ..interp import TAP_ROWS, kernel_taps, resample_rows
from .rangecomp import upsample_records

INTERPOLATORS = ("linear", "sinc8")
UPLOAD_BYTES = 64 * 2**20  # upsampled records prepared and uploaded at once
PULSE_BLOCK = 64  # pulses a kernel launch (one reference sub-block; 32 was ~4 % slower: more launches)
PIXEL_CHUNK = 2**22  # pixels on the device at once
LANES, ROWS, PULSES = 16, 2, 2  # bp_tile: a work-item holds ROWS float16 vectors of pixels, PULSES pulses a step
# (2 x 2 beat 2 x 4 by ~7 % in interleaved kernel timings: fewer registers spilled)
PHASE_BUDGET = 2e-3  # rad: the float32 geometry's share of the 0.01 rad phase budget
ERROR_FACTOR = 8.0  # float32 roundings per |delta| / c of delay (see backproject_opencl)
NODE_TOLERANCE = 1 / 2000  # of a wavelength: a receiver's allowed departure from linear motion over a tile
SPAN_FACTOR = 2.5  # a tile's delay span is +-SPAN_FACTOR * half_extent / c around its reference
REF_PULSES = 64  # pulses whose tile references are computed at once
# the records the kernels read (kernels/backprojection.cl), declared once here: bp_tile's reference
# of a (tile, pulse) and its parameters (float32), bp_block's pulse and parameters (float64)
TILE_REF = record_dtype([("leg1", "f4", 3), ("b1", "f4"), ("leg2", "f4", 3), ("b2", "f4"), ("v_rx", "f4", 3),
                         ("a2", "f4"), ("k_ref", "i4"), ("k_frac", "f4"), ("cycles", "f4"), ("range1", "f4")])
TILE_PARAMS = record_dtype([("a1", "f4"), ("fs", "f4"), ("f0", "f4"), ("velocity", "f4", 3), ("half_sin", "f4"),
                            ("c", "f4")])
PULSE = record_dtype([("tx", "f8", 3), ("eta", "f8"), ("t0_fs", "f8")])
BLOCK_PARAMS = record_dtype([("c", "f8"), ("f0", "f8"), ("fs", "f8"), ("dtau", "f8"), ("velocity", "f8", 3),
                             ("half_sin", "f8")])
RECORDS = declare_all({"node_t": NODE, "tile_ref_t": TILE_REF, "tile_params_t": TILE_PARAMS, "bp_pulse_t": PULSE,
                       "bp_block_params_t": BLOCK_PARAMS})


def _check_inputs(echo, grid, receivers, interp, upsample, aperture, target_velocity):
    if not isinstance(echo, EchoData):
        raise TypeError(f"echo must be an EchoData, got {type(echo).__name__}")
    if not echo.compressed:
        raise ValueError("echo is not range-compressed: call clsas.range_compress(echo) first "
                         "(back-projection refuses raw echoes rather than compressing them silently)")
    if not isinstance(grid, Grid):
        raise TypeError(f"grid must be a clsas.data.Grid (Grid.plane, Grid.slant or Grid.points), got "
                        f"{type(grid).__name__}")
    if interp not in INTERPOLATORS:
        raise ValueError(f"interp must be one of {INTERPOLATORS}, got {interp!r}")
    if isinstance(upsample, bool) or not isinstance(upsample, (int, np.integer)) or not 1 <= upsample <= 64:
        raise ValueError(f"upsample must be an integer in [1, 64], got {upsample!r}")
    chosen = echo.select_receivers(receivers)
    if aperture is not None and not (np.isfinite(aperture) and 0 < aperture <= np.pi):
        raise ValueError(f"aperture must be a full integration angle in (0, pi] radians, got {aperture}")
    v = np.zeros(3) if target_velocity is None else np.asarray(target_velocity, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) >= 100:
        raise ValueError(f"target_velocity must be a finite 3-vector slower than 100 m/s, got {target_velocity!r}")
    return chosen, v


def _aperture_keep(echo, pulses, q, half_sin):
    """(P, M) mask: the pixel, at ``q`` where the pulse meets it, lies within the integration
    angle, |sin theta| <= half_sin, theta the angle of transmitter -> pixel off broadside (the
    x-z plane; y is the nominal heading)."""
    d = q - echo.tx_pos[pulses][:, None, :]
    return np.abs(d[..., 1] / np.linalg.norm(d, axis=-1)) <= half_sin


def backproject_reference(echo, grid, receivers, interp, upsample, aperture, velocity, stop_and_go, progress):
    """The float64 NumPy reference (vectorised over pixels, at most 2^20 pixels and a few pulses
    at a time): image (M,) complex128."""
    pixels = grid.positions.reshape(-1, 3)
    image = np.zeros(pixels.shape[0], dtype=np.complex128)
    f0 = echo.waveform.f0
    factor = upsample if interp == "linear" else 1
    fs = echo.fs * factor
    chunk = min(pixels.shape[0], 2**20)
    block = max(1, 2**22 // chunk)
    jobs = [(h, np.arange(s, min(s + block, echo.n_pulses))) for h in receivers
            for s in range(0, echo.n_pulses, block)]
    for h, pulses in tqdm(jobs, desc="back-projection (numpy)", disable=not progress):
        records = upsample_records(echo.data[h, pulses], factor).astype(np.complex128)
        for first in range(0, pixels.shape[0], chunk):
            part = slice(first, first + chunk)
            t1, q, t2, _ = legs(echo, h, pulses, pixels[part], velocity, stop_and_go)
            tau = t1 + t2
            value = resample_rows(records, (tau - echo.t0[h]) * fs, interp) * np.exp(2j * np.pi * f0 * tau)
            if aperture is not None:
                value *= _aperture_keep(echo, pulses, q, np.sin(aperture / 2))
            image[part] += value.sum(axis=0)
    return image


def tile_half_extent(f0: float, c: float) -> float:
    """The largest distance (m) from a tile's reference point that keeps the float32 geometry's
    phase error below PHASE_BUDGET: 2 pi f0 ERROR_FACTOR eps32 |delta| / c <= PHASE_BUDGET
    (3.3 m at 150 kHz and 1500 m/s; eps32 = 1.2e-7)."""
    return PHASE_BUDGET * c / (2 * np.pi * f0 * ERROR_FACTOR * float(np.finfo(np.float32).eps))


@dataclasses.dataclass(frozen=True)
class Tiling:
    """Pixels reordered into spatial tiles for bp_tile.

    ``order`` (M_pad,): pixel index of each slot (a tile's slots padded to whole work-items of
    LANES x ROWS by repeating its last pixel), ``real`` (M_pad,) bool: the slot is not padding,
    ``tile`` (M_pad,) int: the slot's tile, ``centres`` (T, 3) m: the tiles' reference points,
    ``half_extent`` m: the largest half-diagonal of a tile's bounding box (at least every
    |pixel - its reference point|, the reference being the box's centre), ``phase_bound`` rad: the
    float32 geometry's phase error bound 2 pi f0 ERROR_FACTOR eps32 half_extent / c.
    """

    order: np.ndarray
    real: np.ndarray
    tile: np.ndarray
    centres: np.ndarray
    half_extent: float
    phase_bound: float


def plan_tiles(pixels: np.ndarray, f0: float, c: float, half_extent: float | None = None) -> Tiling:
    """Bucket the (M, 3) pixels into cubic cells whose half-diagonal is ``half_extent`` (default
    :func:`tile_half_extent`), each cell a tile with its reference point at the centre of its
    pixels' bounding box; within a tile the pixels keep their order (a raster stays a raster), so
    a work-item's 16 lanes are neighbours. The work goes one coordinate at a time (a 4096^2
    grid's float64 temporaries are then 134 MB, not 400 MB: first-touch page faults dominate at
    that size). Raises ValueError when the bound is not met (it is by construction; the check
    guards the arithmetic)."""
    pixels = np.asarray(pixels, dtype=np.float64)
    budget = tile_half_extent(f0, c) if half_extent is None else float(half_extent)
    if not budget > 0:
        raise ValueError(f"half_extent must be positive, got {half_extent}")
    side = 2 * budget / np.sqrt(3.0)
    cells = [np.floor((pixels[:, k] - pixels[:, k].min()) / side).astype(np.int64) for k in range(3)]
    key = np.ravel_multi_index(cells, tuple(int(cell.max()) + 1 for cell in cells))
    del cells
    by_key = np.argsort(key, kind="stable")
    sorted_key = key[by_key]
    first = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    count = np.diff(np.r_[first, key.size])
    width = LANES * ROWS
    padded = -(-count // width) * width
    tile = np.repeat(np.arange(count.size), padded)
    local = np.arange(tile.size) - np.repeat(np.cumsum(padded) - padded, padded)
    real = local < count[tile]
    order = by_key[first[tile] + np.minimum(local, count[tile] - 1)]
    low, high = np.empty((count.size, 3)), np.empty((count.size, 3))
    for k in range(3):
        column = pixels[by_key, k]
        low[:, k], high[:, k] = np.minimum.reduceat(column, first), np.maximum.reduceat(column, first)
    centres = 0.5 * (low + high)
    extent = float(0.5 * np.sqrt(np.max(np.sum((high - low) ** 2, axis=1))))
    if extent > budget * (1 + 1e-9):
        raise ValueError(f"tiles reach {extent:.3g} m from their reference points, beyond the {budget:.3g} m "
                         "that keeps the float32 phase error in budget")
    bound = 2 * np.pi * f0 * ERROR_FACTOR * float(np.finfo(np.float32).eps) * extent / c
    return Tiling(order, real, tile, centres, extent, float(bound))


def tile_references(echo: EchoData, h: int, pulses: np.ndarray, centres: np.ndarray, velocity: np.ndarray,
                    stop_and_go: bool, fs: float, half_extent: float) -> tuple[np.ndarray, float]:
    """bp_tile's per-(tile, pulse) references (T, P) :data:`TILE_REF` (their meaning in
    :func:`backproject_opencl` and kernels/backprojection.cl) for the T tile ``centres`` and the P ``pulses``, and the receiver's largest departure (m) from
    the linear motion the kernel assumes over the tiles' delay spans (0 for stop-and-go and for
    receivers with two nodes, whose motion is uniform)."""
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
    ref["k_ref"] = k_int
    ref["k_frac"] = np.clip(k_ref - k_int, 0.0, np.nextafter(np.float32(1), np.float32(0)))
    ref["cycles"] = cycles - np.round(cycles)
    ref["range1"] = c * t1
    return np.ascontiguousarray(ref.T), departure


def _exact_kernel(ctx, echo, h, pulses, fs, velocity, half_sin, defines, stop_and_go, double):
    """bp_block (the exact double kernel) for receiver h and ``pulses``: the kernel, its pulse and
    receiver-node buffers and its parameters (layouts in kernels/backprojection.cl)."""
    import pyopencl as cl

    dtau, pos = uniform_nodes(echo, h)
    n_nodes = pos.shape[1]
    kern = opencl.kernel("backprojection", "bp_block", double=double, preamble=RECORDS, defines=dict(
        defines, N_NODES=n_nodes, SEGMENT_PASSES=1 if n_nodes == 2 else 3, **({"STOP_AND_GO": 1} if stop_and_go else {})))
    pulse = np.zeros(pulses.size, PULSE)
    pulse["tx"], pulse["eta"], pulse["t0_fs"] = echo.tx_pos[pulses], echo.eta[pulses], echo.t0[h] * fs
    nodes = np.zeros((pulses.size, n_nodes), NODE)
    nodes["pos"] = pos[pulses]
    pulse_buf, nodes_buf = (cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=a)
                            for a in (pulse, nodes))
    params = np.zeros((), BLOCK_PARAMS)
    params["c"], params["f0"], params["fs"], params["dtau"] = echo.medium.sound_speed, echo.waveform.f0, fs, dtau
    params["velocity"], params["half_sin"] = velocity, half_sin
    return kern, pulse_buf, nodes_buf, params[()]


def _records_buffer(ctx, echo: EchoData, h: int, pulses: np.ndarray, factor: int, double: bool):
    """The device buffer of receiver h's records of ``pulses`` (consecutive), upsampled by ``factor``,
    and its samples per record. Where the echo's own block already is what the kernel reads
    (``factor`` 1, the kernel's complex type, C-contiguous) the device uses that memory in place
    (CL_MEM_USE_HOST_PTR: PoCL shares host memory, so nothing is copied; the buffer holds a view
    of the block, and the call finishes its queue before it returns), else a copy is made."""
    import pyopencl as cl

    dtype = np.complex128 if double else np.complex64
    block = echo.data[h, pulses[0]:pulses[-1] + 1]
    if factor == 1 and block.dtype == dtype and block.flags.c_contiguous:
        return cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=block), block.shape[1]
    records = np.ascontiguousarray(upsample_records(block, factor), dtype=dtype)
    return cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=records), records.shape[1]


class _Chunk:
    """The device side of slots ``first`` .. ``stop - 1`` of a :class:`Tiling`: bp_tile's pixel
    fields (delta x, y, z, |delta|^2 and, for moving pixels, delta . v; float32 (F, n)), its
    work-items' local tile indices, the tiles present (``tiles``, indices into the Tiling), the
    double image (n,), and on demand the absolute positions for bp_block (double (3, n))."""

    def __init__(self, ctx, pixels, tiling: Tiling, first: int, stop: int, v_k: np.ndarray):
        import pyopencl as cl

        mf = cl.mem_flags
        self.first, self.n = first, stop - first
        self.order, self.real = tiling.order[first:stop], tiling.real[first:stop]
        self.tiles, local = np.unique(tiling.tile[first:stop], return_inverse=True)
        moving = bool(np.any(v_k))
        fields = np.zeros((5 if moving else 4, self.n), np.float32)
        squared, along_v = np.zeros(self.n), np.zeros(self.n)
        for k in range(3):  # one coordinate at a time (temporaries of n, not 3 n, doubles)
            delta = pixels[self.order, k] - tiling.centres[tiling.tile[first:stop], k]
            fields[k] = delta
            squared += delta * delta
            along_v += delta * v_k[k]
        fields[3] = squared
        if moving:
            fields[4] = along_v
        self.pix = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=fields)
        self.tile_of = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                                 hostbuf=local[::LANES * ROWS].astype(np.int32))
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


def backproject_opencl(echo, grid, receivers, interp, upsample, aperture, velocity, stop_and_go, progress,
                       double=False):
    """The kernels/backprojection.cl launcher: image (M,) complex128 and how many (chunk, receiver,
    pulse block) jobs ran on the exact double kernel.

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
    double kernel instead (bp_block; counted in the result).
    """
    import pyopencl as cl

    rt = opencl.runtime()
    ctx, queue = rt.context, rt.queue
    mf = cl.mem_flags
    c, f0 = echo.medium.sound_speed, echo.waveform.f0
    pixels = grid.positions.reshape(-1, 3)
    m = pixels.shape[0]
    image = np.zeros(m, dtype=np.complex128)
    factor = upsample if interp == "linear" else 1
    fs = echo.fs * factor
    taps_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=kernel_taps(interp))
    defines = {"INTERP_LINEAR" if interp == "linear" else "INTERP_SINC8": 1, "TAP_ROWS": TAP_ROWS,
               **({"APERTURE": 1} if aperture is not None else {})}
    half_sin = np.sin(aperture / 2) if aperture is not None else 1.0
    v_k = np.zeros(3) if stop_and_go else velocity
    tiles = plan_tiles(pixels, f0, c)
    chunk = PIXEL_CHUNK // (LANES * ROWS) * (LANES * ROWS)
    per_pulse = 16 * echo.n_samples * factor
    upload = max(PULSE_BLOCK, int(UPLOAD_BYTES // per_pulse) // PULSE_BLOCK * PULSE_BLOCK)
    jobs = [(first, h, np.arange(s, min(s + upload, echo.n_pulses))) for first in range(0, tiles.order.size, chunk)
            for h in receivers for s in range(0, echo.n_pulses, upload)]
    tolerance = NODE_TOLERANCE * echo.waveform.wavelength(echo.medium)
    fallbacks, chunk_state = 0, None
    tile_kernel = opencl.kernel("backprojection", "bp_tile", preamble=RECORDS, defines=dict(
        defines, BP_TILE=1, ROWS=ROWS, PULSES=PULSES, **({"MOVING": 1} if np.any(v_k) else {})))
    tile_params = np.zeros((), TILE_PARAMS)
    tile_params["a1"], tile_params["fs"], tile_params["f0"] = c * c - v_k @ v_k, fs, f0
    tile_params["velocity"], tile_params["half_sin"], tile_params["c"] = v_k, half_sin, c
    for first, h, pulses in tqdm(jobs, desc="back-projection (opencl)", disable=not progress):
        if chunk_state is None or chunk_state.first != first:
            if chunk_state is not None:
                chunk_state.finish(queue, image)
            chunk_state = _Chunk(ctx, pixels, tiles, first, min(first + chunk, tiles.order.size), v_k)
        records_buf, n_samples = _records_buffer(ctx, echo, h, pulses, factor, double)
        exact = None
        for s in range(0, pulses.size, REF_PULSES):
            # a sub-block's references are computed while the previous sub-block's kernels run
            blocks = [(p0, min(PULSE_BLOCK, s + REF_PULSES - p0, pulses.size - p0))
                      for p0 in range(s, min(s + REF_PULSES, pulses.size), PULSE_BLOCK)]
            if not double:
                ref, departure = tile_references(echo, h, pulses[s:s + REF_PULSES], tiles.centres[chunk_state.tiles],
                                                 velocity, stop_and_go, fs, tiles.half_extent)
                if departure <= tolerance:
                    ref_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=ref)
                    for p0, count in blocks:
                        tile_kernel(queue, (chunk_state.n // (LANES * ROWS),), None, chunk_state.pix,
                                    chunk_state.tile_of, ref_buf, np.int32(ref.shape[1]), np.int32(s), records_buf,
                                    taps_buf, tile_params[()], np.int32(p0), np.int32(count), np.int32(n_samples),
                                    np.int32(chunk_state.n), chunk_state.image)
                    continue
                fallbacks += 1
            if exact is None:  # the exact double kernel (precision="double", or the fallback)
                exact = _exact_kernel(ctx, echo, h, pulses, fs, velocity, half_sin, defines, stop_and_go, double)
            kern, pulse_buf, nodes_buf, params = exact
            for p0, count in blocks:
                kern(queue, (chunk_state.n // 8,), None, chunk_state.absolute(ctx, pixels), pulse_buf, nodes_buf,
                     records_buf, taps_buf, params, np.int32(p0), np.int32(count), np.int32(n_samples),
                     np.int32(chunk_state.n), chunk_state.image)
    chunk_state.finish(queue, image)
    return image, fallbacks


def backproject(echo: EchoData, grid: Grid, backend: str | None = None, receivers=None, interp: str = "linear",
                upsample: int = 8, aperture: float | None = None, target_velocity=None, stop_and_go: bool = False,
                precision: str = "single", progress: bool = True) -> Image:
    """Back-project range-compressed echoes onto ``grid`` (see the module docstring).

    Parameters
    ----------
    echo : EchoData, range-compressed (:func:`clsas.range_compress`).
    grid : Grid (plane, slant plane or any 3-D points).
    backend : {"numpy", "opencl", "auto"} or None.
    receivers : indices or names of the receivers to sum coherently (default: all).
    interp : {"linear", "sinc8"}
        Linear interpolation of data FFT-upsampled by ``upsample``, or an 8-tap windowed sinc
        on the original samples. The upsampling is redone at every call: to image many grids
        from one echo, upsample once with ``range_compress(echo, upsample=8)`` and pass
        ``upsample=1`` here.
    aperture : float, optional
        Full integration angle, radians.
    target_velocity : 3-vector, optional
        Velocity (m/s) of the pixels, to focus a target moving at it.
    stop_and_go : bool
        Use stop-and-go delays (all positions at the emission time).
    precision : {"single", "double"}
        The OpenCL kernel's data path (delays and carrier cycles are double either way).

    Returns
    -------
    Image with the grid's dims and axes, ``positions`` the grid's pixels, complex64.
    """
    chosen, velocity = _check_inputs(echo, grid, receivers, interp, upsample, aperture, target_velocity)
    double = _backend.check_precision(precision)
    name = _backend.resolve(backend)
    args = (echo, grid, chosen, interp, upsample, aperture, velocity, stop_and_go, progress)
    if name == "numpy":
        flat, fallbacks = backproject_reference(*args), 0
    else:
        flat, fallbacks = backproject_opencl(*args, double=double)
    return Image(data=flat.reshape(grid.shape), dims=grid.dims, axes=grid.axes, positions=grid.positions,
                 provenance={"algorithm": "backprojection", "backend": name, "precision": precision, "interp": interp,
                             "upsample": int(upsample), "receivers": [echo.receivers[h] for h in chosen],
                             "aperture": aperture, "target_velocity": velocity.tolist(),
                             "stop_and_go": bool(stop_and_go), "exact_fallback_blocks": fallbacks,
                             "echo": dict(echo.provenance)})
