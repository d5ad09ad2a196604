"""The tiles of a grid for bp_tile: pixels grouped so that each group's float32 geometry relative to
its reference point stays within the phase budget (:mod:`.tile_kernel` derives the bound).

:func:`plan_tiles` groups a grid's pixels into tiles of at most ``half_extent`` (default
:func:`tile_half_extent`) from their reference points, each tile's slots padded to whole
work-items of LANES x ROWS pixels. A grid with two pixel axes (``Grid.plane``, ``Grid.slant``, a
2-D ``Grid.points``) is cut in index space into rectangles of nearly equal sides (:func:`_blocks`:
no sort, and squares in metres hold more pixels than the cubes of the general rule); any other
set of points is bucketed into cubic cells. :class:`GridPlan` keeps a grid's tiling for calls
that image the same grid again; :func:`aperture_spans` bounds the pulses a tile can see within
an integration angle.
"""

from __future__ import annotations

import dataclasses
import functools
import threading
import weakref

import numpy as np

from ... import budget, validate
from ...model import Grid

# bp_tile: a work-item holds rows float16 vectors of LANES pixels (tiles padded to LANES x rows); ROWS for
# direct back-projection's tilings (six rows: more independent chains for the out-of-order core, fewer
# pulse-loop overheads a pixel than four; bench/bench_backprojection.py's "rows" part compares them)
LANES, ROWS = 16, 6
PHASE_BUDGET = 2e-3  # rad: the float32 geometry's share of the 0.01 rad phase budget
ERROR_FACTOR = 8.0  # float32 roundings per |delta| / c of delay (tile_kernel's docstring)
EPS32 = float(np.finfo(np.float32).eps)
# the device inputs GridPlan.kept holds, all plans together: at most KEPT_BYTES, 1/KEPT_SHARE of the memory budget and
# of the device's memory; a plan keeping more lets go of the others' (least recently used first)
KEPT_BYTES, KEPT_SHARE = 256 * 2**20, 8
_KEPT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # plan -> bytes kept, least recently used first
_KEPT_LOCK = threading.RLock()  # calls on several threads: _KEPT's bookkeeping one at a time


def tile_half_extent(f0: float, c: float) -> float:
    """The largest distance (m) from a tile's reference point that keeps the float32 geometry's
    phase error below PHASE_BUDGET: 2 pi f0 ERROR_FACTOR eps32 |delta| / c <= PHASE_BUDGET
    (3.3 m at 150 kHz and 1500 m/s; eps32 = 1.2e-7)."""
    return PHASE_BUDGET * c / (2 * np.pi * f0 * ERROR_FACTOR * EPS32)


@dataclasses.dataclass(frozen=True)
class Tiling:
    """Pixels reordered into spatial tiles for bp_tile.

    ``order`` (M_pad,): pixel index of each slot, -1 for padding (each tile's slots are padded to
    whole work-items of LANES x ROWS), ``tile`` (M_pad / (LANES ROWS),) int32: each work-item's
    tile, ``centres`` (T, 3) m: the tiles' reference points (the centres of their bounding boxes),
    ``half_extent`` m: the largest half-diagonal of a tile's bounding box (at least every
    |pixel - its reference point|), ``phase_bound`` rad: the float32 geometry's phase error bound
    2 pi f0 ERROR_FACTOR eps32 half_extent / c, ``rows``: the rows of LANES pixels a work-item.
    """

    order: np.ndarray
    tile: np.ndarray
    centres: np.ndarray
    half_extent: float
    phase_bound: float
    rows: int = ROWS

    @property
    def real(self) -> np.ndarray:
        """(M_pad,) bool: the slot holds a pixel (not padding)."""
        return self.order >= 0

    @functools.cached_property
    def slot_of(self) -> np.ndarray:
        """(M,) int32 (int64 past 2^31 slots): each pixel's slot (the inverse of ``order`` on its real
        slots), made on first use and kept (4 bytes a pixel): a launch's slot sums read into the grid's
        order by one take, or on the device by bp_order (launcher: a grid of one chunk)."""
        real = np.flatnonzero(self.order >= 0)
        slot = np.empty(real.size, np.int32 if self.order.size < 2**31 else np.int64)
        slot[self.order[real]] = real
        return slot


def _padded_order(parts: list, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """(order, work-items' tiles) of tiles given as arrays of pixel indices, each padded with -1 to
    whole work-items of ``rows`` x LANES."""
    width = LANES * rows
    counts = np.array([p.size for p in parts])
    padded = -(-counts // width) * width
    order = np.full(int(padded.sum()), -1, np.int64)
    starts = np.cumsum(padded) - padded
    for start, part in zip(starts, parts):
        order[start:start + part.size] = part
    return order, np.repeat(np.arange(len(parts), dtype=np.int32), padded // width)


def _largest_steps(positions: np.ndarray, lines: int | None = 3) -> list[float]:
    """The largest distance (m) between neighbouring pixels along each of a 2-D grid's axes, over
    ``lines`` lines of the other axis (its first, middle and last: an estimate that guides the
    cut; the tiles' boxes are checked) or over all of them (None)."""
    steps = []
    for k in range(2):
        moved = np.moveaxis(positions, k, 0)  # (n_k, n_other, 3)
        other = moved.shape[1]
        if lines is not None:
            moved = moved[:, np.unique(np.linspace(0, other - 1, lines).astype(int))]
        steps.append(float(np.sqrt(np.max(np.sum(np.diff(moved, axis=0) ** 2, axis=-1), initial=0.0))))
    return steps


def _splits(n: int, parts: int) -> np.ndarray:
    """Boundaries of ``n`` indices cut into ``parts`` runs of nearly equal length."""
    return (np.arange(parts + 1) * n) // parts


def _blocks(positions: np.ndarray, budget: float, lines: int | None = 3):
    """Tiles of a 2-D grid (n0, n1, 3) as rectangles of its index space, each axis cut into runs of
    nearly equal length: the fewest tiles whose runs span at most 2 budget in metres by the
    largest neighbour steps (sqrt((step0 (b0 - 1))^2 + (step1 (b1 - 1))^2) <= 2 budget; steps over
    ``lines`` lines, then over all of them if a box exceeds the budget); (parts, low, high) with
    parts the pixel indices of each tile and low/high its bounding box, or None when a tile's box
    still exceeds the budget (a sheared or curved grid: the caller buckets)."""
    n0, n1 = positions.shape[:2]
    step0, step1 = _largest_steps(positions, lines)
    best = None
    for t0 in range(1, n0 + 1):
        span0 = step0 * (-(-n0 // t0) - 1)
        if span0 > 2 * budget:
            continue
        room = np.sqrt(max((2 * budget) ** 2 - span0 ** 2, 0.0))
        b1 = n1 if step1 == 0 else min(n1, int(room / step1) + 1)
        t1 = -(-n1 // b1)
        if best is None or t0 * t1 < best[0] * best[1]:
            best = (t0, t1)
        if step0 == 0 or span0 == 0:
            break
    if best is None:
        return None
    rows, cols = _splits(n0, best[0]), _splits(n1, best[1])
    index = np.arange(n0 * n1).reshape(n0, n1)
    parts, low, high = [], [], []
    for a in range(best[0]):
        band = positions[rows[a]:rows[a + 1]]
        lo_band, hi_band = band.min(axis=0), band.max(axis=0)  # (n1, 3) over the band's rows
        low.append(np.minimum.reduceat(lo_band, cols[:-1], axis=0))
        high.append(np.maximum.reduceat(hi_band, cols[:-1], axis=0))
        parts += [index[rows[a]:rows[a + 1], cols[b]:cols[b + 1]].ravel() for b in range(best[1])]
    low, high = np.concatenate(low), np.concatenate(high)
    if 0.5 * np.sqrt(np.max(np.sum((high - low) ** 2, axis=1))) > budget * (1 + 1e-9):
        return None if lines is None else _blocks(positions, budget, None)
    return parts, low, high


def _cells(pixels: np.ndarray, budget: float):
    """Tiles of any (M, 3) points: cubic cells whose half-diagonal is the budget, each cell's pixels
    in their own order (a raster stays a raster); (parts, low, high) as :func:`_blocks`."""
    side = 2 * budget / np.sqrt(3.0)
    cells = [np.floor((pixels[:, k] - pixels[:, k].min()) / side).astype(np.int64) for k in range(3)]
    key = np.ravel_multi_index(cells, tuple(int(cell.max()) + 1 for cell in cells))
    del cells
    by_key = np.argsort(key, kind="stable")
    sorted_key = key[by_key]
    first = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    low, high = np.empty((first.size, 3)), np.empty((first.size, 3))
    for k in range(3):  # one coordinate at a time (a 4096^2 grid's temporaries: 134 MB, not 400 MB)
        column = pixels[by_key, k]
        low[:, k], high[:, k] = np.minimum.reduceat(column, first), np.maximum.reduceat(column, first)
    return np.split(by_key, first[1:]), low, high


def plan_tiles(positions: np.ndarray, f0: float, c: float, half_extent: float | None = None,
               rows: int = ROWS) -> Tiling:
    """The tiles of the pixels ``positions`` (a grid's (..., 3) array, m; see the module docstring)
    whose pixels lie within ``half_extent`` (default :func:`tile_half_extent`) of their reference
    points, the centres of their bounding boxes, in work-items of ``rows`` x LANES. Raises
    ValueError when the bound is not met (it is by construction; the check guards the arithmetic)."""
    positions = np.asarray(positions, dtype=np.float64)
    budget = tile_half_extent(f0, c) if half_extent is None else float(half_extent)
    if not budget > 0:
        raise ValueError(f"half_extent must be positive, got {half_extent}")
    found = _blocks(positions, budget) if positions.ndim == 3 else None
    if found is None:
        found = _cells(positions.reshape(-1, 3), budget)
    parts, low, high = found
    order, tile = _padded_order(parts, rows)
    extent = float(0.5 * np.sqrt(np.max(np.sum((high - low) ** 2, axis=1))))
    if extent > budget * (1 + 1e-9):
        raise ValueError(f"tiles reach {extent:.3g} m from their reference points, beyond the {budget:.3g} m "
                         "that keeps the float32 phase error in budget")
    bound = 2 * np.pi * f0 * ERROR_FACTOR * EPS32 * extent / c
    for a in (order, tile):
        a.flags.writeable = False
    return Tiling(order, tile, 0.5 * (low + high), extent, float(bound), rows)


def pixel_box(positions: np.ndarray) -> np.ndarray:
    """(2, 3) m: the smallest and largest coordinates of the pixels ``positions`` (..., 3) (a
    coordinate at a time: NumPy's reduction over the first axis of (M, 3) is slow)."""
    pts = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    return np.array([[pts[:, k].min() for k in range(3)], [pts[:, k].max() for k in range(3)]])


class GridPlan:
    """A grid and its tile plan (:func:`plan_tiles`), made on first use for a carrier and sound
    speed and kept. Pass it to :func:`backproject` in place of the grid to image the same grid
    again without tiling it again (e.g. re-imaging an echo at several target velocities or after
    autofocus). It holds 12 bytes a pixel once used (the tile order and its inverse) and, after an
    OpenCL call on a grid of one chunk (at most ``launcher.PIXEL_CHUNK`` slots), that chunk's
    device inputs (:meth:`kept`: 20 bytes a slot, 24 for moving pixels, i.e. a target velocity
    without stop-and-go; on a CPU device in host memory) until :meth:`release`, while all plans'
    together fit :func:`kept_limit`. ``rows``: the rows of LANES pixels a bp_tile work-item
    holds (default ROWS; a tuning knob the benches compare)."""

    def __init__(self, grid: Grid, rows: int = ROWS):
        if not isinstance(grid, Grid):
            raise TypeError(f"grid must be a clsas.model.Grid, got {type(grid).__name__}")
        self.rows = validate.integer("rows", rows, 1, 16, why="rows of 16 pixels a bp_tile work-item")
        self.grid = grid
        self._tilings = {}
        self._box = None
        self._kept = None  # (key, value): the launcher's device inputs of the latest configuration

    def kept(self, key, make, nbytes: int, device_bytes: float = float("inf")):
        """``make()``'s value for ``key``, made on first use and kept with the plan: the launcher's
        device inputs of a grid of one chunk (its slots' pixel indices, tiles and bp_tile's pixel
        fields, ``nbytes`` of device memory), for a key of what else they depend on (the context,
        the tiling, the pixels' motion). One key at a time: another key's value replaces it (a
        call at another target velocity makes its own and keeps that one). All plans' kept values
        stay within :func:`kept_limit` (``device_bytes``: the device's memory): other plans'
        are let go, least recently used first, and a value larger than the limit is not kept."""
        with _KEPT_LOCK:
            held = self._kept
            if held is not None and held[0] == key:
                _KEPT.pop(self, None)
                _KEPT[self] = nbytes  # the most recently used
                return held[1]
            self.release()  # the old value goes before the new one is made
        value = make()
        room = kept_limit(device_bytes)
        keep = nbytes <= room
        with _KEPT_LOCK:
            for other in list(_KEPT.keys()):  # least recently used first
                if kept_bytes() + keep * nbytes <= room:
                    break
                other.release()
            if keep:
                self._kept = (key, value)
                _KEPT[self] = nbytes
        return value

    def release(self) -> None:
        """Drop the device inputs :meth:`kept` holds (the next OpenCL call makes them again)."""
        with _KEPT_LOCK:
            self._kept = None
            _KEPT.pop(self, None)

    @property
    def box(self) -> np.ndarray:
        """The grid's :func:`pixel_box` (2, 3) m, made on first use and kept (read-only)."""
        if self._box is None:
            self._box = pixel_box(self.grid.positions)
            self._box.flags.writeable = False
        return self._box

    def tiling(self, f0: float, c: float) -> Tiling:
        key = (float(f0), float(c))
        if key not in self._tilings:
            self._tilings[key] = plan_tiles(self.grid.positions, f0, c, rows=self.rows)
        return self._tilings[key]


def kept_limit(device_bytes: float = float("inf")) -> float:
    """The most all GridPlans may keep (:meth:`GridPlan.kept`): KEPT_BYTES, 1/KEPT_SHARE of the memory
    budget (:mod:`clsas.budget`) and of ``device_bytes`` (the device's memory)."""
    return budget.kept_limit(KEPT_BYTES, KEPT_SHARE, device_bytes)


def kept_bytes() -> int:
    """Bytes of device inputs all live GridPlans keep now (:meth:`GridPlan.kept`)."""
    with _KEPT_LOCK:
        return int(sum(_KEPT.values()))


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
