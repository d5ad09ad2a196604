"""Fast factorised back-projection (FFBP): back-projection's image at a fraction of its cost.

Ulander, Hellsten & Stenstrom 2003 (IEEE TAES 39(3)): the pulses are split into short
sub-apertures; each is back-projected exactly onto a coarse local polar grid centred on it,
and the sub-aperture images are merged ``factor`` at a time into the images of longer
sub-apertures on finer polar grids, until the last ones are read at the user's pixels.

1. Sub-apertures (:mod:`.tree`): blocks of ``first`` consecutive pulses, every selected receiver
   of the array (a towed array's pulse is one wide sub-aperture already); a node of the merge
   tree is ``factor`` consecutive children.
2. First stage (:mod:`.leaves`): each leaf is back-projected with back-projection's exact
   delays (non-stop-and-go, two-leg bistatic, every receiver, ``interp``/``upsample``/``aperture``
   as for :func:`clsas.backproject`, on records prepared once a batch) onto its polar grid's
   points (:mod:`.polar`), a batch of leaves a kernel launch, and demodulated by its centre
   range: J = I exp(-j 4 pi f0 r / c).
3. Merges (:mod:`.merge`, kernels/ffbp.cl): a parent's samples read in its children's polar
   images by a separable windowed sinc, the phase restored and re-demodulated, summed.
4. Final stage: the top nodes read at the grid's pixels with the full phase restored, so the
   result has back-projection's scaling and phase (``ffbp(...) - backproject(...)`` is small).

The tree stops merging where one more level would cost more than it saves at the final stage
(each node is read only at the pixels its grid covers, which the final stage's kernel tests
cheaply: with an integration angle a node sees a sector of a long scene). The error model
(``tolerance`` -> oversampling of every polar grid) is derived in :mod:`.polar`. Memory: the
tree is walked depth first (:mod:`.store`: on OpenCL the polar images stay on the device and the
image comes back once), so it holds one group of ``factor`` children's images a level and a group
of top nodes of about the image's size waiting for the final stage, besides the image, one batch
of leaves and its records: :func:`memory_plan` bounds the total from the tree.

Many echoes onto one grid (:mod:`.reuse`): the grid's Scene, its last tree and that tree's
first-stage layouts (tiles, pixel fields and references on the device, one tree's at a time, at
most reuse.limit() and what the memory budget leaves beside a call's own plan) are kept between
calls, and an echo of the same geometry with the same options uses them again (the same image,
bit for bit: the same tree, tiles and references), so such a call's host work is its records and
its launches. :func:`release` lets go of all of it.

Geometry: any track (sway, yaw, surge, circles: each sub-aperture's frame follows its own
chord) and any grid on a plane (planes, slant planes, points on a plane) are exact up to the
interpolation error; points off the grid's fitted plane are read rotated about each
sub-aperture's axis (exact for a straight sub-aperture). Sonobuoys (stationary receivers) are
refused (a receiver is taken as one when it moves less than half as far as the
transmitter over the pulses): their range does not follow the sub-aperture's centre, so a polar grid about it does
not demodulate their echoes; leave them out with ``receivers=`` and image them with
:func:`clsas.backproject`.
"""

from __future__ import annotations

import numpy as np

from ... import backend as _backend
from ... import budget, opencl, validate
from ...interp import INTERPOLATORS, TAP_ROWS
from ...model import EchoData, Grid, Image
from ...progress import Progress, stage
from ..backprojection.records import FFT_BATCH_BYTES, check_options
from .leaves import BATCH_POINTS, RECORD_BYTES, FirstStage
from .merge import CHUNK, KERNEL_TAPS
from .polar import CHUNK_NODES
from .polar.offsets import device_bytes
from .polar.sampling import DEVICE_CHUNK_NODES, ENVELOPE_BINS, SPAN_GRID_BYTES, SPAN_GRIDS, SPAN_ROW_BYTES, SPAN_ROWS
from . import reuse
from .reuse import kept, planned, release
from .scratch import GRAIN, Scratch
from .store import DeviceStore, HostStore
from .tree import MAX_LEAVES, Tree, plan

DEFAULT_TOLERANCE = 0.1
DEFAULT_FACTOR = 4  # children a merge (bench_ffbp --factors compares 2)

__all__ = ["DEFAULT_FACTOR", "DEFAULT_TOLERANCE", "ffbp", "memory_plan", "release"]

SAMPLE_BYTES = {"opencl": 8, "numpy": 16}  # a polar or image sample (complex64 on the device, complex128 on NumPy)
LEAF_BATCH_BYTES = 40  # held a polar sample of a first-stage batch (leaves.py: device image 16, fields 16, work-items:
# a work-item of 16 samples holds its item 16 B, its slot 4 B and its largest dd 4 B on the device and 4 B on the host)
LEAF_BYTES = 200  # transient a sample of the leaf being tiled (points, padded blocks, offsets; float64)
GRID_BYTES = 2 * 8 + 24 + 3 * 8  # a pixel: the image (device, host), the pixels' copy, the scene's float temporaries
# NumPy backend (tests/test_ffbp_input.py holds the traced peaks below these):
REFERENCE_PIXEL_PULSE_BYTES = 320  # back-projection's reference (a leaf): a pixel-pulse of its chunk
REFERENCE_SAMPLE_BYTES = 400  # ... and a leaf sample (its points, their Grid, image, demodulation)
MERGE_SAMPLE_BYTES = 320  # merge_reference: an output sample of its chunk (merge.CHUNK)
# planning (tree.plan), a skeleton point (polar.Scene): the track's ranges (up to 2 x 66 rows; a bound
# kept since tree._Frames takes the nearest range from the skeleton's k-d tree, polar.Scene.nearest,
# ~40 bytes a point) and CHUNK_NODES sub-apertures' ranges, sines and bins (polar.sampling._extents), float64
PLAN_BYTES = 8 * (2 * 66 + 6 * CHUNK_NODES)
# ... and on OpenCL the planner's device reductions' buffers and their results' host copies, at most
# (polar.offsets.device_bytes: DEVICE_CHUNK_NODES sub-apertures' envelopes of ENVELOPE_BINS bins, ~2 MiB)
PLAN_DEVICE_COPIES = 2
# ... and a sub-aperture whose extent the plan finds (_plan_nodes): its envelope (ENVELOPE_BINS x 2 float64, 8 KiB,
# held to the plan's end), its Extent, frame and polar grids (tests/test_ffbp_input.py holds the traced peak below)
PLAN_NODE_BYTES = 2 * 16 * ENVELOPE_BINS
# ... and a pulse of a selected receiver's position node: the phase centres and the frames' offsets from them
# (float64 (x, y, z): tree._Frames' copies and its frames' temporaries of a level's pulses)
PLAN_PULSE_BYTES = 8 * 24
TABLE_COPIES = {"knab": 8, "kaiser": 16}  # float64 temporaries of building a tap table (interp.tap_table)


def _tables(taps: int, interp: str) -> float:
    """Bytes of the tap tables a call may build and keep (interp.tap_table caches a few): the merge's
    Knab table (built, kept in float64 and float32) and, for interp="sinc8", the first stage's
    Kaiser table (built, kept)."""
    row = 8.0 * TAP_ROWS
    merge = row * taps * (TABLE_COPIES["knab"] + 1.5)
    first = 0.0 if interp == "linear" else row * INTERPOLATORS[interp] * (TABLE_COPIES["kaiser"] + 1.5)
    return merge + first


def _fixed_parts(n_pixels: int, skeleton: int, taps: int, interp: str, backend: str, echo_bytes: float, *,
                 plan_nodes: int = 0, plan_pulses: int = 0) -> dict:
    """The parts of :func:`memory_plan` that do not depend on the tree: ``image``, ``records``,
    ``tables`` and ``planning`` (the tree's plan, before any other part is allocated: :func:`_planning`)."""
    return {"image": 2 * SAMPLE_BYTES[backend] * n_pixels,
            "records": min(RECORD_BYTES, echo_bytes) + 3 * min(FFT_BATCH_BYTES, 2 * echo_bytes),
            "tables": _tables(taps, interp),
            "planning": _planning(skeleton, backend, plan_nodes, plan_pulses)}


def _planning(skeleton: int, backend: str, nodes: int = 0, pulses: int = 0) -> float:
    """Bytes of the tree's plan over a skeleton of ``skeleton`` points (0: none counted), finding the
    extents of at most ``nodes`` sub-apertures (:func:`_plan_nodes`) of ``pulses`` pulses x selected
    receivers' position nodes, and sampling their grids' rows' spans (polar.sampling.SPAN_GRIDS grids
    or SPAN_ROWS rows at a time)."""
    if skeleton == 0:
        return 0.0
    device = (PLAN_DEVICE_COPIES * device_bytes(skeleton, DEVICE_CHUNK_NODES, ENVELOPE_BINS)
              if backend == "opencl" else 0)
    spans = min(nodes, SPAN_GRIDS) * SPAN_GRID_BYTES + (SPAN_ROWS * SPAN_ROW_BYTES if nodes else 0)  # sample_grids'
    return PLAN_BYTES * skeleton + device + PLAN_NODE_BYTES * nodes + PLAN_PULSE_BYTES * pulses + spans


def _plan_nodes(n_pulses: int, first: int | None, factor: int) -> int:
    """At most how many sub-apertures' extents :func:`.tree.plan` finds: every node of the tree of
    ``first``-pulse leaves; with ``first=None`` (the rule) twice the nodes of the tree of the shortest
    leaves it considers (at most MAX_LEAVES of them: its own tree and a guessed one) and the lengths'
    middle nodes and their neighbours' spines (a few a level)."""
    def nodes(span: int) -> int:
        count = 0
        while True:
            count += -(-n_pulses // span)
            if span >= n_pulses:
                return count
            span *= factor
    if first is not None:
        return nodes(int(first))
    shortest = 1
    while -(-n_pulses // shortest) > MAX_LEAVES:
        shortest *= 2
    return 2 * nodes(shortest) + 4 * (n_pulses.bit_length() + 1)


def memory_plan(tree: Tree, n_pixels: int, factor: int, echo_bytes: float = float("inf"), *, taps: int = 8,
                interp: str = "linear", backend: str = "opencl") -> dict:
    """Bytes held at most at once by :func:`ffbp` besides the user's grid and echo, by part, from
    the tree's allocation plan (issue 15, item 6), and their ``total``:

    - ``image``: the result, n_pixels samples (SAMPLE_BYTES: complex64 on the device, complex128
      on NumPy) and its copy on the host;
    - ``tree``: the depth-first walk (store.py): building a node of level l + 1 holds one group of
      its ``factor`` children's images, at most factor x the largest node of level l, for every
      level below the top at once;
    - ``top``: the group of top nodes waiting for the final stage (closed once it holds n_pixels
      samples, so at most n_pixels + the largest top node);
    - ``first_stage``: OpenCL: a batch of leaves (leaves.BATCH_POINTS samples x LEAF_BATCH_BYTES)
      and the leaf being tiled (its samples x LEAF_BYTES); NumPy: the batch's images and one leaf's
      back-projection by the reference (a chunk of its pixel-pulses);
    - ``merge``: NumPy: the reference merge's chunk (merge.CHUNK samples) and its result;
    - ``records``: the prepared records (leaves.RECORD_BYTES, or the whole echo's prepared
      samples ``echo_bytes`` if fewer) and the upsampling's spectra
      (backprojection.records.FFT_BATCH_BYTES, three copies, or three times the echo's if fewer);
    - ``tables``: the tap tables built and kept (the merge's, and the first stage's for sinc8);
    - ``planning``: not held with the others (the plan is made first), so counted as 0 here
      (:func:`ffbp` checks it with the fixed parts before planning).

    Not counted here: what is kept between calls (:mod:`.reuse`: the first-stage layouts, the
    grids' Scenes and trees; :mod:`.scratch`: the scratch buffers the last call gave back, which
    this call takes in place of the groups', sums' and pixel fields' allocations counted above,
    their sizes rounded up by at most 1/GRAIN, counted too); :func:`ffbp` lets it take only what
    the budget leaves beside this total (:func:`.reuse.make_room`, :meth:`.scratch.Scratch.trim`).
    """
    largest = [max((g.size for g in level if g is not None), default=0) for level in tree.grids[:tree.top + 1]]
    leaf_batch = min(BATCH_POINTS, sum(g.size for g in tree.grids[0] if g is not None))
    sample = SAMPLE_BYTES[backend]
    parts = _fixed_parts(n_pixels, 0, taps, interp, backend, echo_bytes)
    grain = 1 + 1 / GRAIN if backend == "opencl" else 1  # the groups' buffers' sizes rounded up (.scratch)
    parts.update(tree=grain * sample * factor * sum(largest[:-1]), top=grain * sample * (n_pixels + largest[-1]))
    if backend == "numpy":
        chunk = min(largest[0], 2**20)  # backproject_reference's chunk of pixels, and its pulses
        pulses = min(tree.first, max(1, 2**22 // max(chunk, 1)))
        parts["first_stage"] = (sample * leaf_batch + REFERENCE_SAMPLE_BYTES * largest[0]
                                + REFERENCE_PIXEL_PULSE_BYTES * chunk * pulses)
        target = max(largest[1:] + [n_pixels])
        parts["merge"] = MERGE_SAMPLE_BYTES * min(target, CHUNK) + (sample + 4) * target  # out, spans' masks
    else:
        parts["first_stage"] = grain * LEAF_BATCH_BYTES * leaf_batch + LEAF_BYTES * largest[0]
        parts["merge"] = 0
    parts["total"] = sum(parts.values())
    return parts


def _check(echo, grid, factor, tolerance, taps, first, receivers, interp, upsample, aperture, stop_and_go):
    """The receivers chosen, or a TypeError/ValueError naming the parameter; the grid's own memory
    (the image and the pixels' copy: GRID_BYTES a pixel) against the budget."""
    chosen, _ = check_options(echo, receivers, interp, upsample, None, who="ffbp")
    if not isinstance(grid, Grid):
        raise TypeError(f"grid must be a clsas.model.Grid (Grid.plane, Grid.slant or Grid.points), got "
                        f"{type(grid).__name__}")
    if aperture is not None:
        validate.scalar("ffbp aperture", aperture, low=0.0, high=np.pi, low_open=True, unit="rad",
                        why="the full integration angle")
    validate.integer("ffbp factor", factor, low=2, high=16, why="children a merge")
    validate.scalar("ffbp tolerance", tolerance, low=0.0, high=1.0, low_open=True, high_open=True,
                    why="relative error of a sub-aperture's contribution")
    if taps not in KERNEL_TAPS or isinstance(taps, bool):
        raise ValueError(f"ffbp taps: must be one of {KERNEL_TAPS} (the merge interpolator's taps), got {taps!r}")
    if first is not None:
        validate.integer("ffbp first", first, low=1, high=echo.n_pulses, why="pulses a first-stage sub-aperture")
    validate.flag("ffbp stop_and_go", stop_and_go)
    budget.check_bytes(f"ffbp onto {grid.size} pixels", GRID_BYTES * float(grid.size),
                       "image fewer pixels at a time (tiles of the grid)")
    track = float(np.linalg.norm(np.ptp(echo.tx_pos, axis=0)))
    for h in chosen:
        moved = float(np.linalg.norm(np.ptp(echo.rx_pos[h].reshape(-1, 3), axis=0)))
        if echo.rx_tau[h].size == 1 or moved < 0.5 * track:
            raise ValueError(f"receivers: {echo.receivers[h]!r} is stationary (a sonobuoy: it does not move with the "
                             "transmitter); ffbp's polar grids follow "
                             "the platform, so leave it out with receivers=... and image it with clsas.backproject")
    return chosen


def _slots(grids: list, nodes: list) -> tuple[list, list]:
    """The nodes among ``nodes`` that have a grid, and their offsets in a group holding their images
    one after another (one more: the group's size)."""
    kids = [k for k in nodes if grids[k] is not None]
    return kids, [int(o) for o in np.cumsum([0] + [grids[k].size for k in kids])]


def _top_groups(grids: list, n_pixels: int) -> list:
    """Consecutive top nodes in groups that hold about the image's samples (the last group closed
    once it reaches n_pixels); nodes without a grid go with their neighbours."""
    groups, group, size = [], [], 0
    for node, g in enumerate(grids):
        group.append(node)
        size += 0 if g is None else g.size
        if size >= n_pixels:
            groups.append(group)
            group, size = [], 0
    return groups + ([group] if group else [])


def _group_sizes(tree: Tree, n_pixels: int) -> list:
    """The largest group of each level up to the top: a parent's children's samples (one after
    another) below the top, a group of top nodes (_top_groups) at it."""
    sizes = [max([_slots(tree.grids[level], kids)[1][-1] for kids in tree.children[level + 1]] + [0])
             for level in range(tree.top)]
    return sizes + [max(_slots(tree.grids[tree.top], nodes)[1][-1] for nodes in _top_groups(tree.grids[tree.top],
                                                                                          n_pixels))]


def ffbp(echo: EchoData, grid: Grid, *, factor: int = DEFAULT_FACTOR, tolerance: float = DEFAULT_TOLERANCE,
         taps: int = 8, first: int | None = None, interp: str = "linear", upsample: int = 8, receivers=None,
         aperture: float | None = None, stop_and_go: bool = False, backend: str | None = None,
         progress: bool = True) -> Image:
    """Fast factorised back-projection of range-compressed echoes onto ``grid`` (module docstring).

    Parameters
    ----------
    echo : EchoData, range-compressed.
    grid : Grid (plane, slant plane, or points; see the module docstring for points off a plane).
    factor : children a merge (2..16; default 4: half the stages of pairs, so each interpolation
        may err more and the polar grids need less oversampling for the same tolerance).
    tolerance : the largest relative (amplitude and phase, rad) error of a sub-aperture's
        contribution at the edge of the scene (:mod:`clsas.image.ffbp.polar`), in (0, 1).
    taps : 4 or 8, the merge interpolator's taps in range and in angle.
    first : pulses a first-stage sub-aperture (default: chosen from the array and the grid).
    interp, upsample, receivers, aperture, stop_and_go : as for :func:`clsas.backproject`
        (its first stage); stationary receivers (sonobuoys) are refused. ``aperture`` masks
        every pulse at its integration angle as back-projection does, and limits every polar
        grid to the pixels its sub-aperture sees within that angle (where FFBP saves most on a
        long track); the mask's hard edges are not band-limited, so the merges blur them and the
        image departs from back-projection's near them (bench_ffbp's aperture case reports how far).
    backend : "numpy", "opencl", "auto" or None.

    Returns
    -------
    Image on the grid (complex64) with back-projection's scaling and phase; its provenance
    records the tree (levels, oversampling, polar samples).
    """
    chosen = _check(echo, grid, factor, tolerance, taps, first, receivers, interp, upsample, aperture, stop_and_go)
    name = _backend.resolve(backend)
    scene, entry = kept(grid)
    echo_bytes = 8.0 * (upsample if interp == "linear" else 1) * echo.n_samples * echo.n_pulses * len(chosen)
    plan_pulses = echo.n_pulses * len(chosen) * echo.rx_pos.shape[2]  # a pulse of a receiver's position node
    budget.check_bytes(f"ffbp of {echo.n_pulses} pulses onto {grid.size} pixels (its image, records, tables and "
                       "plan)", sum(_fixed_parts(grid.size, scene.skeleton.shape[0], taps, interp, name, echo_bytes,
                                                 plan_nodes=_plan_nodes(echo.n_pulses, first, int(factor)),
                                                 plan_pulses=plan_pulses).values()),
                       "image fewer pixels at a time (tiles of the grid)")
    options = (int(factor), float(tolerance), int(taps), first, aperture, interp, int(upsample), bool(stop_and_go))
    made = planned(entry, echo, chosen, options,  # the tree kept for this geometry onto this grid, or a new one
                   lambda guess: plan(echo, chosen, scene, int(factor), float(tolerance), taps, first, aperture,
                                      device=name == "opencl", first_guess=guess))
    tree = made.tree
    memory = memory_plan(tree, grid.size, int(factor), echo_bytes, taps=taps, interp=interp, backend=name)["total"]
    budget.check_bytes(f"ffbp of {echo.n_pulses} pulses onto {grid.size} pixels ({tree.top + 1} levels)", memory,
                       "image fewer pixels at a time (tiles of the grid), or give a larger tolerance")
    # what is kept between calls takes only what the budget leaves beside this call (held before: let go)
    device = float(opencl.runtime().device.global_mem_size) if name == "opencl" else float("inf")
    reuse.make_room(grid, entry, made, budget.memory_budget() - memory, device)
    # the scratch buffers kept between calls (.scratch) take what is left beside the layouts' room
    room = min(reuse.limit(device), budget.memory_budget() - memory - reuse.host_bytes()
               - (0 if made.layouts is None else made.layouts.room))
    scratch = Scratch() if name == "opencl" else None
    Scratch.trim(room)
    f0, c = echo.waveform.f0, echo.medium.sound_speed
    pixels = grid.positions.reshape(-1, 3)
    leaves = tree.pulses[0]
    bar = Progress(leaves[-1][1] - leaves[0][0], "pulse", "ffbp", progress)  # pulses through the first stage
    stage1 = FirstStage(echo, tree.pulses[0], name, chosen, interp, upsample, aperture, stop_and_go, made.layouts,
                        scratch)
    store = (HostStore if name == "numpy" else DeviceStore)(stage1, pixels, f0, c, taps, tree.rho,
                                                           _group_sizes(tree, pixels.shape[0]), scratch)

    def build(level: int, node: int, group, offset: int) -> bool:
        """Node ``node`` of ``level``'s image into ``group`` from ``offset`` on; False when it has none."""
        grid_ = tree.grids[level][node]
        if grid_ is None:
            bar.done(tree.pulses[level][node][1] - tree.pulses[level][node][0])
            return False
        if level == 0:
            store.leaf(node, grid_, tree.grids[0], group, offset)
            bar.done(leaves[node][1] - leaves[node][0])
            return True
        kids, offsets = _slots(tree.grids[level - 1], tree.children[level][node])
        below = store.group(level - 1, offsets[-1])
        made = [k for k, o in zip(kids, offsets) if build(level - 1, k, below, o)]
        if not made:
            return False
        store.flush()
        store.merge([tree.grids[level - 1][k] for k in made], below, [offsets[kids.index(k)] for k in made], grid_,
                    group, offset)
        return True

    # the top nodes go to the pixels in groups of about the image's size (one pass a group)
    top = tree.top
    with stage(f"ffbp ({name})", f"{pixels.shape[0]} pixels x {leaves[-1][1] - leaves[0][0]} pulses x "
               f"{len(chosen)} receivers, {top + 1} levels, {tree.samples()} polar samples"), bar:
        try:
            for nodes in _top_groups(tree.grids[top], pixels.shape[0]):
                kids, offsets = _slots(tree.grids[top], nodes)
                group = store.group(top, offsets[-1])
                made = [k for k, o in zip(kids, offsets) if build(top, k, group, o)]
                if made:
                    store.flush()
                    store.final([tree.grids[top][k] for k in made], group, [offsets[kids.index(k)] for k in made])
            flat = store.result()
        finally:  # the first stage's last batch's kernels read host memory it holds
            stage1.settle()
            if scratch is not None:  # once the queue is finished, the scratch buffers serve the next call
                scratch.give_back(room)
    with np.errstate(over="ignore"):  # a sum past complex64's range becomes inf: finite_result names the overflow
        flat = flat.astype(np.complex64, copy=False)
    validate.finite_result("ffbp: the image", flat, "scale echo.data down", np.complex64)
    return Image.on_grid(flat.reshape(grid.shape), grid,
                         {"algorithm": "ffbp", "backend": name, "factor": int(factor), "tolerance": float(tolerance),
                          "taps": int(taps), "first": tree.first, "levels": top + 1,
                          "oversampling": tree.rho, "polar_samples": tree.samples(),
                          "memory_bytes": memory,
                          "interp": interp, "upsample": int(upsample),
                          "receivers": [echo.receivers[h] for h in chosen], "aperture": aperture,
                          "stop_and_go": bool(stop_and_go), "echo": dict(echo.provenance)})
