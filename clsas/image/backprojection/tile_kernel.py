"""bp_tile, back-projection's float32 kernel, and :class:`TileKernel`, the one object that owns it.

A :class:`TileKernel` holds everything kernels/backprojection.cl's bp_tile reads besides the
records and the grid: its options (the ``-D`` defines), its records (declared here once as
structured dtypes; :mod:`clsas.cstruct` puts them in front of the source as C structs), the
per-(tile, pulse) references and the parameters it is given, the layout of its pixel fields,
and its launch. Direct back-projection (:mod:`.launcher`) and the first stage of factorised
back-projection (:mod:`clsas.image.ffbp.leaves`) both use it. Here too: the tiles of a grid
(:func:`plan_tiles`: the pixels reordered into spatial tiles, each small enough that the float32
geometry relative to its reference point stays within the phase budget) and :class:`GridPlan`,
which keeps a grid's tile plan and pixel fields for calls that image the same grid again.

Derivation (``precision="single"``: float32 geometry relative to a reference per (tile, pulse)).
Let the tile's reference point meet pulse p at t1_ref, at q_ref (exact, float64,
:func:`clsas.geometry.legs`), and its echo reach the receiver at T_ref = t1_ref + t2_ref, at
R_ref; let B = q_ref - tx (|B| = c t1_ref) and C = R_ref - q_ref (|C| = c t2_ref). A pixel of
the tile sits at delta from the reference point and moves with it at v, so it meets the pulse
at q = q_ref + delta + v s1 with s1 = t1 - t1_ref; c t1 = |q - tx| gives
|B + delta + v s1|^2 = c^2 (t1_ref + s1)^2, and subtracting |B|^2 = c^2 t1_ref^2:

    (c^2 - |v|^2) s1^2 + 2 b1 s1 - N1 = 0,  N1 = 2 B.delta + |delta|^2,  b1 = c^2 t1_ref - (B + delta).v,

whose root near 0 is s1 = N1 / (b1 + sqrt(b1^2 + (c^2 - |v|^2) N1)) (no cancellation: b1 ~ c |B|
> 0). The receiver moves linearly over the tile's delay span, R = R_ref + v_r (s1 + s2) with
s2 = t2 - t2_ref, so R - q = C + e + v_r s2 with e = (v_r - v) s1 - delta, and c t2 = |R - q|
gives likewise

    (c^2 - |v_r|^2) s2^2 + 2 b2 s2 - N2 = 0,  N2 = 2 C.e + |e|^2,  b2 = c^2 t2_ref - (C + e).v_r,

s2 = N2 / (b2 + sqrt(b2^2 + (c^2 - |v_r|^2) N2)). The delay is T_ref + s1 + s2 (docs/design.md's
exact non-stop-and-go delay; stop-and-go is the same with v = v_r = 0 and references at eta);
the sample index (T_ref - t0) fs + (s1 + s2) fs is K_ref + (frac_ref + (s1 + s2) fs) and the
carrier cycles f0 T_ref (reduced in double) + f0 (s1 + s2). Nothing of size |B| is subtracted
in float: every term carries a relative error of a few eps32 of a quantity of size |delta|
(N1, N2, s1, s2 ~ |delta| / c; B, C, b1, b2 enter as ratios), and f0 (s1 + s2) ~ 2 f0 |delta| / c
cycles is rounded once more; counting about ERROR_FACTOR = 8 roundings of |delta| / c of delay,
the phase error is below 2 pi f0 8 eps32 |delta| / c, kept below PHASE_BUDGET by the tile size
(:func:`plan_tiles`; tests/test_backprojection.py measures it). The receiver's velocity
v_r is the secant of its track over T_ref +- SPAN_FACTOR |delta|_max / c (which contains every
pixel's delay); where the track departs from that line by more than NODE_TOLERANCE wavelengths
(motion errors: kinks at its nodes), :meth:`TileKernel.references` says so and the caller runs
that receiver's pulses on the exact double kernel instead (:mod:`.exact_kernel`). The records'
offset (their first sample, an integer) is taken off the reference's integer sample index
K_ref, so the fraction, hence the image, does not depend on the span prepared.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ... import opencl
from ...cstruct import declare_all, record_dtype
from ...geometry import legs, two_node_velocity, uniform_nodes
from ...interp import TAP_ROWS, kernel_taps
from ...model import Grid

LANES, ROWS = 16, 4  # bp_tile: a work-item holds ROWS float16 vectors of pixels (tiles padded to LANES x ROWS)
PHASE_BUDGET = 2e-3  # rad: the float32 geometry's share of the 0.01 rad phase budget
ERROR_FACTOR = 8.0  # float32 roundings per |delta| / c of delay (the module docstring)


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




class GridPlan:
    """A grid and what imaging it needs besides the echo: its tile plan (:func:`plan_tiles`) and
    bp_tile's float32 pixel fields of its chunks (offsets from the tiles' reference points:
    :meth:`clsas.image.backprojection.tile_kernel.TileKernel.fields`), made on first use for a
    carrier and sound speed (and, for the fields, a target velocity) and kept. Pass it to
    :func:`backproject` in place of the grid to image the same grid again without redoing them
    (e.g. re-imaging an echo at several target velocities or after autofocus). It holds ~16 +
    20 bytes a pixel once used (tile order and fields; a 4096^2 grid: ~600 MB).
    """

    def __init__(self, grid: Grid):
        if not isinstance(grid, Grid):
            raise TypeError(f"grid must be a clsas.model.Grid, got {type(grid).__name__}")
        self.grid = grid
        self._tilings, self._kept = {}, {}

    def tiling(self, f0: float, c: float) -> Tiling:
        key = (float(f0), float(c))
        if key not in self._tilings:
            self._tilings[key] = plan_tiles(self.grid.positions.reshape(-1, 3), f0, c)
        return self._tilings[key]

    def kept(self, key, make):
        """``make()``, made once for ``key`` and kept (the pixel fields of a chunk of the tiling)."""
        if key not in self._kept:
            self._kept[key] = make()
        return self._kept[key]


def aperture_spans(leg1_y: np.ndarray, range1: np.ndarray, half_sin: float, half_extent: float, speed: float,
                   c: float, first: int) -> np.ndarray:
    """bp_tile's PULSE_SPAN: for each of T tiles the pulses [start, stop) that can see it within
    the aperture, int32 (T, 2), from its references' along-track leg B_y and range |B| = c t1_ref
    (m, (T, P)) for the P pulses ``first`` .. ``first + P - 1``; a tile that sees none gets (0, 0).

    The kernel keeps pixel q = q_ref + delta + v s1 of a pulse when
    |B_y + delta_y + v_y s1| <= h (|B| + c s1), h = sin(aperture / 2). With |delta| <= E (the
    tiles' half extent) and c t1 = |B + delta + v s1|: c |s1| <= E + |v| |s1|, so
    |v| |s1| <= E |v| / (c - |v|) and both |delta_y + v_y s1| and c s1 are at most
    M = E c / (c - |v|). A pulse with |B_y| - M > h (|B| + M) therefore keeps no pixel of the
    tile; the span runs from the first to the last pulse that may keep one (the mask still decides
    every pixel in it). M gets 1 cm more for the float32 comparison (eps32 x 10 km = 1.2 mm).
    """
    margin = half_extent * c / (c - speed) + 0.01
    seen = np.abs(leg1_y) - margin <= half_sin * (range1 + margin)
    start = np.argmax(seen, axis=1)
    stop = seen.shape[1] - np.argmax(seen[:, ::-1], axis=1)
    return np.where(seen.any(axis=1)[:, None], np.stack([start, stop], axis=1) + first, 0).astype(np.int32)


PULSES = 1  # pulses a work-item step (with ROWS vectors of LANES pixels; bench/bench_backprojection.py --variants)
PULSE_BLOCK = 64  # pulses a launch: the float sums' block (relative error below 64 x 6e-8)
NODE_TOLERANCE = 1 / 2000  # of a wavelength: a receiver's allowed departure from linear motion over a tile
SPAN_FACTOR = 2.5  # a tile's delay span is +-SPAN_FACTOR * half_extent / c around its reference

# bp_tile's records: the reference of a (tile, pulse), the launch's parameters, and a row of
# LANES pixels (the offsets from the tile's reference point, |delta|^2, and delta . v for moving pixels)
TILE_REF = record_dtype([("leg1", "f4", 3), ("b1", "f4"), ("leg2", "f4", 3), ("b2", "f4"), ("v_rx", "f4", 3),
                         ("a2", "f4"), ("k_ref", "i4"), ("k_frac", "f4"), ("cycles", "f4"), ("range1", "f4")])
TILE_PARAMS = record_dtype([("a1", "f4"), ("fs", "f4"), ("f0", "f4"), ("velocity", "f4", 3), ("half_sin", "f4"),
                            ("c", "f4")])
_OFFSETS = [("dx", "f4", LANES), ("dy", "f4", LANES), ("dz", "f4", LANES), ("dd", "f4", LANES)]
PIXELS = record_dtype(_OFFSETS)
MOVING_PIXELS = record_dtype(_OFFSETS + [("dv", "f4", LANES)])


class TileKernel:
    """bp_tile for one configuration: the interpolator ``interp`` ("linear" or "sinc8"), the full
    integration angle ``aperture`` (rad, or None), the pixels' ``velocity`` (m/s), ``stop_and_go``,
    ``row_shift`` (ffbp's first stage: each tile reads its own leaf's rows of the records), and
    ``same_legs`` (with stop-and-go, a receiver at the transmitter: :meth:`same_legs_for`; the
    kernel then computes one leg, t2 = t1).

    A work-item is ROWS rows of LANES pixels of one tile (:attr:`items_per_slot`: a tile's
    slots come in whole work-items); slot m = LANES (ROWS g + r) + lane of work-item g.
    """

    LANES, ROWS, PULSE_BLOCK = LANES, ROWS, PULSE_BLOCK

    def __init__(self, interp: str, aperture: float | None = None, velocity=(0.0, 0.0, 0.0),
                 stop_and_go: bool = False, row_shift: bool = False, same_legs: bool = False):
        self.interp, self.aperture, self.stop_and_go = interp, aperture, bool(stop_and_go)
        self.velocity = np.asarray(velocity, dtype=np.float64)
        self.v_k = np.zeros(3) if stop_and_go else self.velocity  # the pixels' motion the legs see
        self.half_sin = 1.0 if aperture is None else float(np.sin(aperture / 2))
        self.moving = bool(np.any(self.v_k))
        self.pixels = MOVING_PIXELS if self.moving else PIXELS
        self.pulse_span = aperture is not None and not row_shift  # a tile sums only the pulses that can see it
        self.defines = {"INTERP_LINEAR" if interp == "linear" else "INTERP_SINC8": 1, "TAP_ROWS": TAP_ROWS,
                        "BP_TILE": 1, "ROWS": ROWS, "PULSES": PULSES, **({"APERTURE": 1} if aperture is not None else {}),
                        **({"MOVING": 1} if self.moving else {}), **({"ROW_SHIFT": 1} if row_shift else {}),
                        **({"SAME_LEGS": 1} if same_legs and self.stop_and_go else {}),
                        **({"PULSE_SPAN": 1} if self.pulse_span else {})}
        self.preamble = declare_all({"tile_ref_t": TILE_REF, "tile_params_t": TILE_PARAMS, "bp_pixels_t": self.pixels})

    def same_legs_for(self, echo, h: int) -> bool:
        """True when, with stop-and-go, receiver h of ``echo`` sits at the transmitter at every
        emission (a monostatic sonar), to 1e-6 of a wavelength: its return leg is its outgoing one."""
        if not self.stop_and_go or echo.rx_tau[h][0] != 0:
            return False
        apart = np.max(np.linalg.norm(echo.rx_pos[h][:, 0] - echo.tx_pos, axis=-1))
        return bool(apart <= 1e-6 * echo.waveform.wavelength(echo.medium))

    @staticmethod
    def half_extent(f0: float, c: float) -> float:
        """The largest distance (m) of a pixel from its tile's reference point within the phase
        budget (:func:`tile_half_extent`)."""
        return tile_half_extent(f0, c)

    def params(self, c: float, f0: float, fs: float) -> np.void:
        """The launch's parameters (TILE_PARAMS) for sound speed ``c``, carrier ``f0`` and the
        records' rate ``fs``."""
        params = np.zeros((), TILE_PARAMS)
        params["a1"], params["fs"], params["f0"] = c * c - self.v_k @ self.v_k, fs, f0
        params["velocity"], params["half_sin"], params["c"] = self.v_k, self.half_sin, c
        return params[()]

    def taps(self, ctx):
        """The interpolator's tap table as a device buffer."""
        import pyopencl as cl

        return cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=kernel_taps(self.interp))

    def references(self, echo, h: int, pulses: np.ndarray, centres: np.ndarray, fs: float, half_extent: float,
                   offset: int = 0) -> tuple[np.ndarray, bool]:
        """The references (T, P) :data:`TILE_REF` of the T tile ``centres`` ((T, 3), or (P, T, 3):
        each pulse's own) for receiver h of ``echo`` and the P ``pulses`` (the module docstring),
        and whether the receiver moves linearly within NODE_TOLERANCE of a wavelength over the
        tiles' delay spans (always for stop-and-go and for receivers with two nodes, whose motion
        is uniform; where it does not, the pulses belong on the exact kernel). ``offset``: the
        first sample of the records the kernel reads, counted at ``fs`` from the window start t0
        (taken off the integer part only)."""
        c, f0 = echo.medium.sound_speed, echo.waveform.f0
        t1, q, t2, r = legs(echo, h, pulses, centres, self.velocity, self.stop_and_go)
        big_t = t1 + t2
        b_vec = q - echo.tx_pos[pulses][:, None, :]
        c_vec = r - q
        v_r = np.zeros_like(c_vec)
        departure = 0.0
        if not self.stop_and_go and echo.rx_tau[h].size == 2:
            # uniform motion: the secant over any span is the receiver's velocity
            v_r[:] = two_node_velocity(echo, h, pulses)[:, None, :]
        elif not self.stop_and_go and echo.rx_tau[h].size > 2:
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
        k_ref = (big_t - echo.t0[h]) * fs
        k_int = np.clip(np.floor(k_ref), -2**30, 2**30)
        cycles = f0 * big_t
        ref = np.empty(big_t.shape, dtype=TILE_REF)
        ref["leg1"] = b_vec
        ref["b1"] = c * c * t1 - b_vec @ self.v_k
        ref["leg2"] = c_vec
        ref["b2"] = c * c * t2 - np.einsum("...i,...i->...", c_vec, v_r)
        ref["v_rx"] = v_r
        ref["a2"] = c * c - np.einsum("...i,...i->...", v_r, v_r)
        ref["k_ref"] = k_int - offset
        ref["k_frac"] = np.clip(k_ref - k_int, 0.0, np.nextafter(np.float32(1), np.float32(0)))
        ref["cycles"] = cycles - np.round(cycles)
        ref["range1"] = c * t1
        linear = departure <= NODE_TOLERANCE * echo.waveform.wavelength(echo.medium)
        return np.ascontiguousarray(ref.T), linear

    def spans(self, ref: np.ndarray, half_extent: float, c: float, first: int) -> np.ndarray:
        """PULSE_SPAN's pulses [start, stop) each tile of the references ``ref`` (T, P) (pulses
        ``first`` .. ``first + P - 1``) can see within the aperture (:func:`aperture_spans`)."""
        return aperture_spans(ref["leg1"][..., 1], ref["range1"], self.half_sin, half_extent,
                              float(np.linalg.norm(self.v_k)), c, first)

    def fields(self, plan: GridPlan, f0: float, c: float, first: int, stop: int):
        """Slots ``first`` .. ``stop - 1`` of ``plan``'s tiling: the pixel fields (n / LANES,)
        :attr:`pixels` records, the work-items' local tile indices (int32) and the tiles present
        (indices into the tiling); made once and kept by the plan."""
        key = ("bp_tile fields", float(f0), float(c), first, stop, tuple(self.v_k))
        return plan.kept(key, lambda: self._fields(plan, f0, c, first, stop))

    def _fields(self, plan: GridPlan, f0: float, c: float, first: int, stop: int):
        tiling, pixels = plan.tiling(f0, c), plan.grid.positions.reshape(-1, 3)
        n = stop - first
        tiles, local = np.unique(tiling.tile[first:stop], return_inverse=True)
        fields = np.zeros(n // LANES, self.pixels)
        squared, along_v = np.zeros(n), np.zeros(n)
        for k, name in enumerate(("dx", "dy", "dz")):  # one coordinate at a time (temporaries of n, not 3 n, doubles)
            delta = pixels[tiling.order[first:stop], k] - tiling.centres[tiling.tile[first:stop], k]
            fields[name] = delta.reshape(-1, LANES)
            squared += delta * delta
            along_v += delta * self.v_k[k]
        fields["dd"] = squared.reshape(-1, LANES)
        if self.moving:
            fields["dv"] = along_v.reshape(-1, LANES)
        for a in (fields, local):
            a.flags.writeable = False
        return fields, local[::LANES * ROWS].astype(np.int32), tiles

    def launch(self, queue, *, pixels, tile_of, refs, ref_stride: int, ref_first: int, records, n_samples: int, taps,
               params, p_first: int, p_count: int, image, row_shift=None, spans=None):
        """Enqueue bp_tile over the work-items of ``tile_of`` (a device buffer of one int32 a
        work-item; ``pixels`` ROWS records a work-item): add pulses p_first .. p_first + p_count
        - 1 of the ``records`` (rows of ``n_samples`` samples) into the double ``image`` of its
        slots; ``refs`` holds tile t's reference of pulse p at t * ref_stride + p - ref_first.
        ``row_shift`` (with row_shift=True) and ``spans`` (with an aperture) as in the kernel's
        comment. Returns the event."""
        extra = (row_shift,) if "ROW_SHIFT" in self.defines else ()
        extra += (spans,) if self.pulse_span else ()
        n_items = tile_of.size // 4
        return self._kernel()(queue, *opencl.work_groups(n_items), pixels, tile_of, refs, np.int32(ref_stride),
                              np.int32(ref_first), records, taps, params, np.int32(p_first), np.int32(p_count),
                              np.int32(n_samples), np.int32(n_items), image, *extra)

    def _kernel(self):
        return opencl.kernel("backprojection", "bp_tile", preamble=self.preamble, defines=self.defines)
