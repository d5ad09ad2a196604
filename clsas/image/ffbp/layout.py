"""The first stage's layout of a batch of leaves for bp_tile (:mod:`.leaves` makes and launches it):
its work-items over the leaves' polar grids (:func:`polar_tiles`: tiles of rows x range samples,
the groups of LANES samples within the rows' spans), the images' slots (written on the device by
kernels/ffbp.cl's ffbp_fields with the pixel fields; :func:`_slots` is their NumPy twin) and the
record a batch's launch reads (:class:`Layout`), kept between calls by :mod:`.reuse`."""

from __future__ import annotations

import dataclasses

import numpy as np

from ... import opencl
from ..backprojection import TileKernel
from . import program
from .polar import PolarGrid, points_at

LANES, ROWS = TileKernel.LANES, TileKernel.ROWS  # bp_tile's work-item: ROWS rows of LANES samples


def cl_buffer(array: np.ndarray):
    """A read-only device buffer holding a copy of ``array``."""
    import pyopencl as cl

    return cl.Buffer(opencl.runtime().context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                     hostbuf=np.ascontiguousarray(array))


def polar_tiles(grids: list, bv: int, br: int, seen: list | None = None):
    """bp_tile's tiles of polar grids (module docstring), blocks of bv rows x br range samples
    (those at a grid's edge cut to it): their items (I,) :data:`program.ITEM` (leaf, row, the
    first of LANES consecutive range samples of that row, tile; grid by grid, then column of
    tiles by column (their range samples), group of LANES range samples by group, and down all the
    grid's rows of that group, tile after tile; ROWS items, ROWS rows of one group and one tile,
    make a work-item), the tiles' reference points (T, 3) m (each block's middle sample), the
    number of tiles of each grid (L,) and the number of items to back-project: with ``seen`` (the
    grids with narrower spans, :func:`.polar.within_aperture`) those meeting them come first, in
    the same order, and the others after (laid out, so the tiles' budget is checked on every
    sample as before, but not back-projected: zero); else all of them. ``bv`` must be a positive
    multiple of ROWS and ``br`` of LANES (a work-item's rows and samples; ValueError otherwise)."""
    if bv <= 0 or br <= 0 or bv % ROWS or br % LANES:
        raise ValueError(f"polar_tiles: tiles of {bv} rows x {br} range samples; the rows must be a positive "
                         f"multiple of ROWS ({ROWS}) and the samples of LANES ({LANES})")
    tv_of = np.array([-(-g.n_v // bv) for g in grids])
    tr_of = np.array([-(-g.n_r // br) for g in grids])
    tv, tr = int(tv_of.max()), int(tr_of.max())
    real = (np.arange(tv)[None, :, None] < tv_of[:, None, None]) & (np.arange(tr)[None, None, :] < tr_of[:, None, None])
    tile = np.cumsum(real.reshape(-1)).reshape(real.shape) - 1  # grid by grid, row-major within a grid
    n_v = np.array([g.n_v for g in grids])
    n_r = np.array([g.n_r for g in grids])
    # each tile's reference point: its block's middle sample (a block at the grid's edge cut to it)
    which, a, b = np.nonzero(real)  # the tiles in that order
    centres = points_at(grids, which, (a * bv + np.minimum(a * bv + bv, n_v[which]) - 1) // 2,
                        (b * br + np.minimum(b * br + br, n_r[which]) - 1) // 2)
    # items group by group of LANES range samples, within a group row by row down the whole grid
    # (its tiles of that column one after another): a work-item is ROWS rows of the same LANES
    # ranges, and the work-items after it the next rows of them (a short sub-aperture's delay
    # hardly depends on the angle, so they read the same records' samples, still in cache: bp_tile
    # is bound by those reads; tile by tile, the rows of a group came back only after the tile's
    # other groups); a tile at the grid's edge keeps only its rows inside the grid (rounded up to
    # whole work-items of ROWS rows) and its sixteen-sample groups that start inside it
    # (every item of a work-item, its ROWS rows, is kept or dropped alike: the selection is made a
    # work-item at a time, j its group of ROWS rows within the tile, and expanded to its rows after)
    shape = (len(grids), tr, br // LANES, tv, bv // ROWS)
    l, b, q, a, j = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij", sparse=True)
    n_v, n_r = n_v[:, None, None, None, None], n_r[:, None, None, None, None]
    block = a * (bv // ROWS) + j  # the work-item's block of ROWS rows within its grid
    start = b * br + q * LANES
    real, tile = (x.transpose(0, 2, 1)[:, :, None, :, None] for x in (real, tile))  # as (l, b, q, a, j)
    inside = real & (j < -(-(n_v - a * bv) // ROWS)) & (start < n_r)
    keep = np.broadcast_to(inside & _meets(grids, -(-tv * bv // ROWS), l, block, start), shape)
    if seen is not None:  # the work-items meeting the seen spans first, then the others
        first = keep & _meets(seen, -(-tv * bv // ROWS), l, block, start)
        order = (first, keep & ~first)
    else:
        order = (keep,)
    # each kept work-item's (leaf, first row, first sample, tile), in order, then its ROWS items (its
    # rows one after another) as one int32 array that the ITEM records view
    picked = [np.broadcast_to(x, shape) for x in (l, block * ROWS, start, tile)]
    kept = [int(np.count_nonzero(k)) for k in order]
    work = np.empty((sum(kept), 4), np.int32)
    for f, x in enumerate(picked):
        work[:, f] = np.concatenate([x[k] for k in order])
    fields = np.repeat(work, ROWS, axis=0)
    fields.reshape(-1, ROWS, 4)[:, :, 1] += np.arange(ROWS, dtype=np.int32)  # each work-item's rows
    items = fields.view(program.ITEM).reshape(-1)
    return items, centres, tv_of * tr_of, ROWS * kept[0]


def _meets(grids: list, blocks: int, l, block, start) -> np.ndarray:
    """Whether a group of LANES samples from ``start`` meets the span of its block ``block`` of ROWS
    rows of grid ``l`` (the union of the rows' spans: a work-item's ROWS items then stay in one
    tile), broadcast over polar_tiles' (l, b, q, a, j)."""
    none = np.iinfo(np.int32).max
    lo = np.full((len(grids), blocks * ROWS), none, np.int64)
    hi = np.zeros((len(grids), blocks * ROWS), np.int64)
    n_v = np.array([g.n_v for g in grids])
    grid = np.repeat(np.arange(len(grids)), n_v)  # every grid's rows, grid by grid
    row = np.arange(grid.size) - np.repeat(np.cumsum(n_v) - n_v, n_v)
    spans = np.concatenate([g.row_spans for g in grids]).astype(np.int64)
    empty = spans[:, 1] <= spans[:, 0]
    lo[grid, row] = np.where(empty, none, spans[:, 0])
    hi[grid, row] = np.where(empty, 0, spans[:, 1])
    lo = lo.reshape(len(grids), blocks, ROWS).min(axis=2)
    hi = hi.reshape(len(grids), blocks, ROWS).max(axis=2)
    return (start + LANES > lo[l, block]) & (start < hi[l, block])


def slot_firsts(grids: list) -> np.ndarray:
    """Where each grid's groups of LANES range samples start among the images' slots (grid by grid,
    row by row: n_v x ceil(n_r / LANES) a grid), and their total: (len(grids) + 1,) int64."""
    groups = np.array([-(-g.n_r // LANES) for g in grids], np.int64)
    return np.cumsum(np.r_[0, groups * np.array([g.n_v for g in grids], np.int64)])


def _slots(grids: list, items: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The work-item of ``items`` (:func:`polar_tiles`) that holds each group of LANES range samples
    of each grid's rows, or -1 (a group no tile computed: zero): (sum of n_v x ceil(n_r / LANES),)
    int32, grid by grid and row by row, and where each grid's groups start (len(grids) + 1,)
    (:func:`slot_firsts`). The NumPy twin of the slots ffbp_fields writes (the first stage's)."""
    groups = np.array([-(-g.n_r // LANES) for g in grids])
    first = slot_firsts(grids)
    slots = np.full(int(first[-1]), -1, np.int32)
    leaf, row, sample = (items[name].astype(np.int64) for name in ("leaf", "row", "sample"))  # contiguous copies
    inside = row < np.array([g.n_v for g in grids])[leaf]  # rows past a grid's edge (whole work-items) dropped
    at = first[leaf] + row * groups[leaf] + sample // LANES
    slots[at[inside]] = np.flatnonzero(inside)
    return slots, first


def row_step(grid: PolarGrid) -> float:
    """The largest distance (m) between neighbouring angle rows of a polar grid: at its far range r,
    r dv / cos(theta) with the largest |v| = sin(theta) (cos(theta) bounded below by 1e-3)."""
    sine = max(abs(grid.v0), abs(grid.v0 + (grid.n_v - 1) * grid.dv))
    return (grid.r0 + (grid.n_r - 1) * grid.dr) * grid.dv / np.sqrt(max(1.0 - sine * sine, 1e-6))


@dataclasses.dataclass(eq=False)
class Layout:
    """What a batch's bp_tile launch needs besides its records and references, the same for every
    echo of one geometry (:meth:`FirstStage._layout`; kept between calls by :mod:`.reuse`): its
    work-items' count, the tiles' reference points (T, 3) m and each leaf's first tile (L + 1,),
    the tiles' largest half-extent (m), the pixel fields (a device buffer of a
    :attr:`TileKernel.pixels` record a item, one of the call's scratch buffers), each tile's first
    pulse (int32, from the echo's first), the work-items' tiles, the images' slots (a device
    buffer, ffbp_fields') and each leaf's first slot, the rows' spans (a device buffer) and each
    leaf's first row; and its references by records (``refs``: a device buffer a receiver, filled
    by :meth:`FirstStage._launch`)."""

    n_items: int
    centres: np.ndarray
    first_tile: np.ndarray
    extent: float
    pix: object
    row_shift: np.ndarray
    tile_of: object
    slots: object
    slot_first: np.ndarray
    spans: object
    span_first: np.ndarray
    refs: dict = dataclasses.field(default_factory=dict)

    @property
    def nbytes(self) -> int:
        return int(self.pix.size + self.tile_of.size + self.slots.size + self.spans.size)
