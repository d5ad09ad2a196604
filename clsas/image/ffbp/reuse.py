"""What :func:`clsas.image.ffbp.ffbp` keeps between calls onto one Grid, and when it uses it again.

Imaging many echoes onto one grid (pings of one geometry, or one echo again) repeats work that
depends only on the grid and on the echo's geometry, not on its samples:

- the grid's :class:`~.polar.Scene` (skeleton, margin, plane: a pass over every pixel);
- the merge tree (:func:`.tree.plan`: the frames, extents, sampled polar grids and their spans,
  the stop rule);
- the first stage's *layouts* (:class:`.leaves.FirstStage`: each batch's tile shape, work-items,
  pixel fields and slots on the device, and its tiles' references for each receiver).

They are kept for a Grid (weakly: they go with it) only while nothing can change its positions:
read-only and their own memory, with FINGERPRINT of its pixels compared on every call (NumPy lets
an owner make them writeable again; a change to other pixels after that is not seen). A tree is
used again only for an echo of the same geometry and the same options (:func:`geometry`: the
transmitter's positions and emission times, the selected receivers' positions, nodes and windows,
the sampling, the sound speed and the waveform, compared exactly with kept copies, not by a hash);
anything else plans anew and replaces it (one tree a grid). The layouts hold device memory (the
pixel fields, 16 bytes a leaf sample, and the references), so they are kept for one tree at a time
(the last that made them, dropped when another tree makes its own) and only up to LAYOUT_BYTES;
every call still prepares its own records and allocates its own images.
"""

from __future__ import annotations

import dataclasses
import weakref

import numpy as np

from ...model import EchoData, Grid
from .polar import Scene
from .tree import Tree

KEEP_PLANS = True  # trees and layouts kept between calls (tests/test_ffbp.py turns it off: each call plans afresh)
FINGERPRINT = 4096  # pixels compared on every later call (every n-th one): a grid changed since is planned anew
LAYOUT_BYTES = 256 * 2**20  # device memory of the first-stage layouts kept between calls (one tree's)


class Layouts:
    """A tree's first-stage layouts by key (:class:`.leaves.FirstStage` makes and reads them), with
    their bytes; only one tree's are held at a time (:data:`_HELD`)."""

    def __init__(self):
        self.items, self.nbytes = {}, 0

    def get(self, key):
        return self.items.get(key) if KEEP_PLANS else None

    def put(self, key, value, nbytes: int) -> None:
        """Keep ``value`` (of ``nbytes`` device bytes) under ``key`` if it fits LAYOUT_BYTES; the
        layouts of the tree held before are let go."""
        if not KEEP_PLANS or self.nbytes + nbytes > LAYOUT_BYTES:
            return
        held = _HELD() if _HELD is not None else None
        if held is not None and held is not self:
            held.clear()
        _hold(self)
        self.items[key] = value
        self.nbytes += nbytes

    def add(self, nbytes: int) -> bool:
        """Whether ``nbytes`` more (a layout's references) fit LAYOUT_BYTES (then counted)."""
        if self.nbytes + nbytes > LAYOUT_BYTES:
            return False
        self.nbytes += nbytes
        return True

    def clear(self) -> None:
        self.items, self.nbytes = {}, 0


_HELD = None  # a weak reference to the Layouts holding device memory


def _hold(layouts: Layouts) -> None:
    global _HELD
    _HELD = weakref.ref(layouts)


@dataclasses.dataclass(eq=False)
class Planned:
    """A tree planned for an echo's geometry and options (``key`` scalars, ``arrays`` copies) and
    its first-stage layouts (None for a tree that is not kept)."""

    key: tuple
    arrays: tuple
    tree: Tree
    layouts: Layouts | None = dataclasses.field(default_factory=Layouts)

    def matches(self, key: tuple, arrays: tuple) -> bool:
        return self.key == key and all(a.shape == b.shape and np.array_equal(a, b) for a, b in zip(self.arrays, arrays))


@dataclasses.dataclass(eq=False)
class Kept:
    """A grid's Scene, the sample of its pixels it was made from, and its last tree."""

    scene: Scene
    sample: np.ndarray
    planned: Planned | None = None


_SCENES = weakref.WeakKeyDictionary()  # Grid -> Kept


def kept(grid: Grid) -> tuple[Scene, Kept | None]:
    """The grid's :class:`Scene` and what is kept for it (None when nothing may be: its positions
    writeable, or a view of another array); the Scene is made anew when the grid's fingerprint
    changed (and what was kept for it dropped)."""
    positions = grid.positions
    if positions.flags.writeable or not positions.flags.owndata:
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
    ``entry``, or a new one from ``make()`` (kept in its place when the grid may keep one)."""
    if not KEEP_PLANS or entry is None:
        return Planned((), (), make(), None)  # nothing kept: no copies, no layouts
    scalars, arrays = geometry(echo, chosen, options)
    if entry.planned is not None and entry.planned.matches(scalars, arrays):
        return entry.planned
    entry.planned = Planned(scalars, tuple(np.array(a, copy=True) for a in arrays), make())
    return entry.planned
