"""Tiles of a back-projection grid: the pixels reordered into spatial tiles for bp_tile, each small
enough that the float32 geometry relative to its reference point stays within the phase budget
(derivation at :func:`clsas.image.backprojection.backproject_opencl`), and :class:`GridPlan`,
which keeps a grid's tile plan and pixel fields for calls that image the same grid again.
Measured on the Huang scene grids (x 35-85 m, y +-6 m; 52 tiles): plan and pixel fields take
~2 ms at 128^2 and ~30-110 ms at 512^2 (busy machine), against the 512^2 kernels' ~0.5-2 s.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...model import Grid

LANES, ROWS = 16, 2  # bp_tile: a work-item holds ROWS float16 vectors of pixels (tiles padded to LANES x ROWS)
# (2 rows x 2 pulses a step beat 2 x 4 by ~7 % in interleaved kernel timings: fewer registers spilled)
PHASE_BUDGET = 2e-3  # rad: the float32 geometry's share of the 0.01 rad phase budget
ERROR_FACTOR = 8.0  # float32 roundings per |delta| / c of delay (see backproject_opencl)


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
    """A grid and what imaging it needs besides the echo: its tile plan (:func:`plan_tiles`) and the
    float32 pixel fields of its chunks (bp_tile's offsets from the tiles' reference points), made
    on first use for a carrier and sound speed (and, for the fields, a target velocity) and kept.
    Pass it to :func:`backproject` in place of the grid to image the same grid again without
    redoing them (e.g. re-imaging an echo at several target velocities or after autofocus). It
    holds ~16 + 20 bytes a pixel once used (tile order and fields; a 4096^2 grid: ~600 MB).
    """

    def __init__(self, grid: Grid):
        if not isinstance(grid, Grid):
            raise TypeError(f"grid must be a clsas.model.Grid, got {type(grid).__name__}")
        self.grid = grid
        self._tilings, self._fields = {}, {}

    def tiling(self, f0: float, c: float) -> Tiling:
        key = (float(f0), float(c))
        if key not in self._tilings:
            self._tilings[key] = plan_tiles(self.grid.positions.reshape(-1, 3), f0, c)
        return self._tilings[key]

    def fields(self, f0: float, c: float, first: int, stop: int, v_k: np.ndarray):
        """Slots ``first`` .. ``stop - 1`` of the tiling: bp_tile's pixel fields (delta x, y, z,
        |delta|^2 and, for moving pixels, delta . v; float32 (F, n)), the work-items' local tile
        indices (int32) and the tiles present (indices into the tiling)."""
        key = (float(f0), float(c), first, stop, tuple(np.asarray(v_k, dtype=float)))
        if key not in self._fields:
            tiling, pixels = self.tiling(f0, c), self.grid.positions.reshape(-1, 3)
            n = stop - first
            tiles, local = np.unique(tiling.tile[first:stop], return_inverse=True)
            moving = bool(np.any(v_k))
            fields = np.zeros((5 if moving else 4, n), np.float32)
            squared, along_v = np.zeros(n), np.zeros(n)
            for k in range(3):  # one coordinate at a time (temporaries of n, not 3 n, doubles)
                delta = pixels[tiling.order[first:stop], k] - tiling.centres[tiling.tile[first:stop], k]
                fields[k] = delta
                squared += delta * delta
                along_v += delta * v_k[k]
            fields[3] = squared
            if moving:
                fields[4] = along_v
            for a in (fields, local):
                a.flags.writeable = False
            self._fields[key] = (fields, local[::LANES * ROWS].astype(np.int32), tiles)
        return self._fields[key]


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
