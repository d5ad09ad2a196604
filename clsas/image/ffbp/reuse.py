"""What :func:`clsas.image.ffbp.ffbp` keeps between calls onto one Grid, and when it uses it again.

Imaging many echoes onto one grid (pings of one geometry, or one echo again) repeats work that
depends only on the grid and on the echo's geometry, not on its samples:

- the grid's :class:`~.polar.Scene` (skeleton, margin, plane: a pass over every pixel);
- the merge tree (:func:`.tree.plan`: the frames, extents, sampled polar grids and their spans,
  the stop rule);
- the first stage's *layouts* (:class:`.leaves.FirstStage`: each batch's tile shape, work-items,
  pixel fields and slots on the device, and its tiles' references for each receiver).

They are kept for a Grid (weakly: they go with it) only while nothing can change its positions:
positions the Grid built or copied itself (``Grid._owned``: :meth:`~clsas.model.Grid.plane`,
``slant``, ``points``; a Grid made on the caller's own float64 array keeps nothing, since views of
that array made before may still write it), read-only, with FINGERPRINT of its pixels compared on
every call (NumPy lets an owner make them writeable again; a change to other pixels after that is
not seen). A tree is used again only for an echo of the same geometry and the same options
(:func:`geometry`: the transmitter's positions and emission times, the selected receivers'
positions, nodes and windows, the sampling, the sound speed and the waveform, compared exactly with
kept copies, not by a hash); anything else plans anew and replaces it (one tree a grid).

Memory. The layouts hold device memory (the pixel fields, 16 bytes a leaf sample, and the
references) after the call returns, so they are kept for one tree at a time and only up to
:func:`limit`: LAYOUT_BYTES, at most 1/SHARE of the memory budget (:mod:`clsas.budget`) and of the
device's memory, and never more than the call's budget leaves beside its own plan and the host
state kept (:func:`make_room`, before the call allocates: a call of another tree, or one that needs
the room, lets go of the layouts held before it starts; the pixel fields' buffers of the layouts let
go join :mod:`.scratch`'s pool, which the next call bounds by its own room). The Scenes and trees
kept (host memory: :meth:`Kept.nbytes`, the skeletons with their search trees, the fingerprints,
the trees' rows' spans and the copies of the echoes' geometry) count against the budget too: all
grids' together at most :func:`host_limit` (HOST_BYTES, 1/SHARE of the budget) and what a call's
budget leaves beside its own plan; a call lets go of other grids' trees, then their Scenes,
oldest first, then of its own tree (used once more, not kept) until they fit, and a geometry whose
copies alone exceed the limit is not kept at all (:func:`planned`). ``from clsas.image.ffbp import release;
release()`` lets go of all of it (every grid's Scene, tree and layouts); dropping the Grid lets go
of its own.
"""

from __future__ import annotations

import dataclasses
import weakref

import numpy as np

from ... import budget
from ...model import EchoData, Grid
from . import scratch
from .polar import Scene
from .tree import Tree

# trees and layouts kept between calls (tests/_ffbp_helpers.keep_plans turns it off: each call plans afresh)
KEEP_PLANS = True
FINGERPRINT = 4096  # pixels compared on every later call (every n-th one): a grid changed since is planned anew
LAYOUT_BYTES = 256 * 2**20  # device memory of the first-stage layouts kept between calls (one tree's)
SHARE = 8  # the layouts kept take at most 1/SHARE of the memory budget and of the device's memory
HOST_BYTES = 64 * 2**20  # host memory of the Scenes and trees kept (every grid's), at most 1/SHARE of the budget too
SCENE_COPIES = 4  # a kept Scene's skeleton bytes, times: itself, its centred copy, its k-d tree's copy and index/nodes
GRID_BYTES = 1024  # a kept polar grid besides its rows' spans (its frame's arrays and the objects)


class Layouts:
    """A tree's first-stage layouts by key (:class:`.leaves.FirstStage` makes and reads them), with
    their bytes; only one tree's are held at a time (:data:`_HELD`)."""

    def __init__(self):
        self.items, self.nbytes = {}, 0
        self.room = 0  # bytes they may hold (set by make_room before each call)

    def get(self, key):
        return self.items.get(key)

    def put(self, key, value, nbytes: int) -> None:
        """Keep ``value`` (of ``nbytes`` device bytes) under ``key`` if it fits :attr:`room`; the
        layouts of the tree held before are let go."""
        if self.nbytes + nbytes > self.room:
            return
        held = _held()
        if held is not None and held is not self:
            held.clear()
        _hold(self)
        self.items[key] = value
        self.nbytes += nbytes

    def add(self, nbytes: int) -> bool:
        """Whether ``nbytes`` more (a layout's references) fit :attr:`room` (then counted)."""
        if self.nbytes + nbytes > self.room:
            return False
        self.nbytes += nbytes
        return True

    def clear(self) -> None:
        self.items, self.nbytes = {}, 0


_HELD = None  # a weak reference to the Layouts holding device memory


def _hold(layouts: Layouts) -> None:
    global _HELD
    _HELD = weakref.ref(layouts)


def _held() -> Layouts | None:
    return _HELD() if _HELD is not None else None


def held_bytes() -> int:
    """Bytes of the first-stage layouts kept now (one tree's)."""
    held = _held()
    return 0 if held is None else held.nbytes


def limit(device_bytes: float = float("inf")) -> float:
    """The most the layouts may keep: LAYOUT_BYTES, 1/SHARE of the memory budget and of
    ``device_bytes`` (the device's global memory)."""
    return budget.kept_limit(LAYOUT_BYTES, SHARE, device_bytes)


def host_limit() -> float:
    """The most the Scenes and trees kept (every grid's) may hold: HOST_BYTES, 1/SHARE of the
    memory budget."""
    return budget.kept_limit(HOST_BYTES, SHARE)


def host_bytes() -> int:
    """Host bytes of the Scenes and trees kept now (every grid's, :meth:`Kept.nbytes`)."""
    return sum(entry.nbytes for entry in list(_SCENES.values()))


def _fit_host(grid: Grid, entry: "Kept | None", made: "Planned", room: float) -> int:
    """Let go of kept host state until it fits ``room``: other grids' trees, then their Scenes
    (oldest first), then this call's tree (``made``: used by this call, not kept; nor its
    layouts), then this grid's Scene (made anew next time). Returns the bytes still kept."""
    total = host_bytes()
    others = [(g, e) for g, e in list(_SCENES.items()) if e is not entry]
    for _, other in others:
        if total <= room:
            return total
        if other.planned is not None:
            total -= other.planned.nbytes
            other.planned = None
    for g, other in others:
        if total <= room:
            return total
        total -= other.nbytes
        _SCENES.pop(g, None)
    if total > room and entry is not None and entry.planned is not None:
        total -= entry.planned.nbytes
        entry.planned = None
        if made.layouts is not None and _held() is made.layouts:
            made.layouts.clear()
        made.layouts = None  # the tree is used by this call and kept by none
    if total > room and entry is not None:
        total -= entry.nbytes
        _SCENES.pop(grid, None)
    return total


def make_room(grid: Grid, entry: "Kept | None", made: "Planned", room: float,
              device_bytes: float = float("inf")) -> None:
    """Before a call on ``grid`` (what is kept for it: ``entry``) with ``made``'s tree that leaves
    ``room`` bytes of its budget beside its own plan: the host state kept is let go until it fits
    min(:func:`host_limit`, room) (:func:`_fit_host`); the layouts held for another tree are let
    go (this call makes its own, or keeps none), and this tree's too when they exceed what is left
    (then made again); this call may keep up to that, at most :func:`limit` (``device_bytes``:
    the device's global memory)."""
    host = _fit_host(grid, entry, made, min(host_limit(), room))
    room = min(limit(device_bytes), room - host)
    held = _held()
    if held is not None and ((made.layouts is not None and held is not made.layouts) or held.nbytes > room):
        held.clear()
    if made.layouts is not None:
        made.layouts.room = max(0.0, room)


def release() -> None:
    """Let go of everything ffbp keeps between calls: every grid's Scene and tree, the held
    first-stage layouts and the scratch buffers (:mod:`.scratch`; their device memory)."""
    held = _held()
    if held is not None:
        held.clear()
    _SCENES.clear()
    scratch.release()


@dataclasses.dataclass(eq=False)
class Planned:
    """A tree planned for an echo's geometry and options (``key`` scalars, ``arrays`` copies) and
    its first-stage layouts (None for a tree that is not kept)."""

    key: tuple
    arrays: tuple
    tree: Tree
    layouts: Layouts | None = dataclasses.field(default_factory=Layouts)

    @property
    def nbytes(self) -> int:
        """Host bytes kept with it: the geometry's copies and the tree's grids (their rows' spans)."""
        grids = [g for level in self.tree.grids for g in level if g is not None]
        return (sum(a.nbytes for a in self.arrays) + sum(g.row_spans.nbytes if g.spans is not None else 0 for g in grids)
                + GRID_BYTES * len(grids))

    def matches(self, key: tuple, arrays: tuple) -> bool:
        return self.key == key and all(a.shape == b.shape and np.array_equal(a, b) for a, b in zip(self.arrays, arrays))


@dataclasses.dataclass(eq=False)
class Kept:
    """A grid's Scene, the sample of its pixels it was made from, and its last tree."""

    scene: Scene
    sample: np.ndarray
    planned: Planned | None = None

    @property
    def nbytes(self) -> int:
        """Host bytes kept for the grid: the Scene (SCENE_COPIES x its skeleton), the fingerprint
        and the tree (:attr:`Planned.nbytes`)."""
        return (SCENE_COPIES * self.scene.skeleton.nbytes + self.sample.nbytes
                + (0 if self.planned is None else self.planned.nbytes))


_SCENES = weakref.WeakKeyDictionary()  # Grid -> Kept


def kept(grid: Grid) -> tuple[Scene, Kept | None]:
    """The grid's :class:`Scene` and what is kept for it (None when nothing may be: positions the
    Grid does not own (``Grid._owned``), or made writeable again); the Scene is made anew when the
    grid's fingerprint changed (and what was kept for it dropped)."""
    positions = grid.positions
    if positions.flags.writeable or not getattr(grid, "_owned", False):
        _SCENES.pop(grid, None)
        return Scene.of(positions), None
    flat = positions.reshape(-1, 3)
    sample = flat[::max(1, flat.shape[0] // FINGERPRINT)]
    entry = _SCENES.get(grid)
    if entry is None or not np.array_equal(entry.sample, sample):
        entry = _SCENES[grid] = Kept(Scene.of(positions), sample.copy())
    return entry.scene, entry


def geometry(echo: EchoData, chosen: list, options: tuple) -> tuple[tuple, tuple]:
    """(scalars, arrays) that decide a tree and its first stage besides the grid: the options
    given, the echo's sampling, sound speed and waveform, and its geometry (the transmitter's
    positions and emission times, the chosen receivers' positions, nodes and window starts)."""
    w = echo.waveform
    scalars = (options, tuple(int(h) for h in chosen), echo.n_pulses, echo.n_samples, float(echo.fs),
               float(echo.medium.sound_speed), float(w.f0), float(w.bandwidth))
    picked = np.asarray(chosen, np.int64)
    arrays = (echo.tx_pos, echo.eta, echo.rx_pos[picked], echo.rx_tau[picked], np.asarray(echo.t0)[picked])
    return scalars, arrays


def planned(entry: Kept | None, echo: EchoData, chosen: list, options: tuple, make) -> Planned:
    """The tree kept for this geometry and these options (:func:`geometry`) on the grid of
    ``entry``, or a new one from ``make(guess)`` (kept in its place when the grid may keep one and
    the geometry's copies fit :func:`host_limit`); ``guess``: the leaf length the rule chose for the
    grid's last tree (a hint for the new plan, :func:`.tree.plan`'s first_guess), or None (no last
    tree, or its length was the caller's)."""
    if not KEEP_PLANS or entry is None:
        return Planned((), (), make(None), None)  # nothing kept: no copies, no layouts
    scalars, arrays = geometry(echo, chosen, options)
    if entry.planned is not None and entry.planned.matches(scalars, arrays):
        return entry.planned
    guess = entry.planned.tree.first if entry.planned is not None and entry.planned.tree.ruled else None
    entry.planned = None  # the last tree is let go before the new one is planned
    if sum(a.nbytes for a in arrays) > host_limit():
        return Planned((), (), make(guess), None)  # a geometry too large to keep a copy of
    entry.planned = Planned(scalars, tuple(np.array(a, copy=True) for a in arrays), make(guess))
    return entry.planned
