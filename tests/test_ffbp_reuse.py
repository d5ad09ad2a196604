"""What ffbp keeps between calls (clsas.image.ffbp.reuse): a Grid's Scene only while nothing can
change its positions, a grid's last tree and first-stage layouts for echoes of the same geometry, all
of it within the memory budget; kept or not, the images are the same.

Scenes: tests/_ffbp_helpers.py's (Huang & Yang 2022's sonar over a 4 x 4 m seafloor grid: points or speckle).
"""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest
from _ffbp_helpers import DEPTH, GRID, echo_of, keep_plans  # noqa: F401 (keep_plans: a fixture)

import clsas
from clsas.model import Grid, Image
from clsas.image.backprojection import TileKernel
from clsas.image.ffbp import ffbp
from clsas.image.ffbp import reuse
from clsas.image.ffbp.polar import Scene

pytestmark = pytest.mark.usefixtures("keep_plans")


def test_a_grid_scene_is_kept_only_while_nothing_can_change_it():
    """ffbp keeps a Grid's Scene (skeleton, margin, plane) for later calls on it only for positions
    the Grid built or copied itself (read-only, and no other array shares them); positions given as
    the caller's own array (which a view made before the Grid may still write), or as a view of
    someone's array, are read again on every call."""
    assert reuse.kept(GRID)[0] is reuse.kept(GRID)[0]
    base = GRID.positions.copy()
    view = Grid(base[::2], GRID.dims, {})  # a read-only view of a writable array
    first = reuse.kept(view)[0]
    base[..., 2] += 1.0
    assert reuse.kept(view)[0] is not first
    assert np.allclose(reuse.kept(view)[0].plane.centroid[2], first.plane.centroid[2] + 1.0)
    # the caller's own array (it owns its memory), written through a view made before the Grid
    # (the review's B1: every pixel but the fingerprint's moved; the Scene, tree and layouts were kept)
    positions = GRID.positions.copy()
    alias = positions.reshape(-1, 3)[:]
    given = Grid(positions, GRID.dims, GRID.axes)
    assert given.positions is positions and not given.positions.flags.writeable and alias.flags.writeable
    scene, entry = reuse.kept(given)
    assert entry is None  # nothing kept for it
    moved = np.ones(len(alias), bool)
    moved[::max(1, len(alias) // reuse.FINGERPRINT)] = False
    alias[moved, 2] += 1.0
    again, entry = reuse.kept(given)
    assert entry is None and again is not scene
    assert np.array_equal(again.plane.centroid, Scene.of(np.array(positions)).plane.centroid)
    # a Grid's own positions made writeable again by their owner (NumPy allows it) and changed
    own = Grid.plane(np.arange(42.0, 43.0, 0.1), np.arange(-1.0, 1.0, 0.1), DEPTH)
    kept = reuse.kept(own)[0]
    own.positions.flags.writeable = True
    own.positions[..., 2] += 1.0
    assert reuse.kept(own)[0] is not kept  # writeable: read again
    own.positions.flags.writeable = False
    again = reuse.kept(own)[0]
    assert np.allclose(again.plane.centroid[2], kept.plane.centroid[2] + 1.0)
    assert reuse.kept(own)[0] is again


def test_a_grid_owns_the_positions_it_builds_or_converts():
    """Grid.plane, slant and points build their positions (nothing else holds them), as does a Grid
    converting what it was given; a Grid on the caller's float64 array, or on a view, does not own
    them (ffbp then keeps nothing for it, .reuse.kept)."""
    assert GRID._owned
    assert Grid.slant([40.0, 0.0, -5.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], np.arange(3.0), np.arange(2.0))._owned
    points = np.array([[40.0, 0.0, -5.0], [41.0, 0.0, -5.0]])
    assert Grid.points(points)._owned and Grid.points(points[0])._owned
    assert not Grid(points, ("i",), {})._owned
    assert not Grid(points[::1], ("i",), {})._owned
    assert Grid(points.tolist(), ("i",), {})._owned and Grid(points.astype(np.float32), ("i",), {})._owned
    assert not dataclasses.replace(GRID, dims=("a", "b"), axes={})._owned  # given the Grid's array: not a copy


def test_a_grid_on_the_callers_array_images_what_it_holds_now(opencl_device, monkeypatch):
    """The review's reproducer (B1), keeping on: the caller's array under a Grid is moved across
    track through a view made before the Grid (every pixel but those the fingerprint samples); the
    next call images the moved pixels as a new Grid of them does, bit for bit (it imaged the old
    Scene and tree before: the targets missing)."""
    monkeypatch.setattr(reuse, "KEEP_PLANS", True)
    echo = echo_of("straight")
    x, y = np.arange(32.0, 36.0, 0.03), np.arange(-2.0, 2.0, 0.04)
    yy, xx = np.meshgrid(y, x, indexing="ij")
    positions = np.stack([xx, yy, np.full_like(xx, DEPTH)], axis=-1)
    alias = positions.reshape(-1, 3)[:]
    grid = Grid(positions, ("y", "x"), {"y": y, "x": x})
    ffbp(echo, grid, backend="opencl", progress=False)
    moved = np.ones(len(alias), bool)
    moved[::max(1, len(alias) // reuse.FINGERPRINT)] = False
    alias[moved, 0] += 10.0  # 42-46 m: onto the targets
    got = ffbp(echo, grid, backend="opencl", progress=False).data
    fresh = ffbp(echo, Grid.points(np.array(positions), grid.dims), backend="opencl", progress=False).data
    assert np.linalg.norm(fresh.reshape(-1)[moved]) > 0
    assert np.array_equal(got, fresh)


@pytest.mark.parametrize("track", ["motion", "circle"])
def test_kept_trees_and_layouts_give_the_images_of_fresh_calls(opencl_device, monkeypatch, track):
    """Keeping on (the default) on tracks whose leaves' references are computed on the host: a
    first call, and a second echo of the same geometry (other samples) through the kept tree,
    layouts and references, give the images of calls that keep nothing, bit for bit (measured
    identical)."""
    from clsas.image.ffbp import leaves

    echo = echo_of(track)
    other = echo.replace(data=np.ascontiguousarray(echo.data[..., ::-1]))  # the same geometry, other samples
    grid = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(-2.0, 2.0, 0.04), DEPTH)
    afresh = [ffbp(e, grid, backend="opencl", progress=False).data for e in (echo, other)]
    monkeypatch.setattr(reuse, "KEEP_PLANS", True)
    laying_out, counts = leaves.FirstStage._layout, []
    monkeypatch.setattr(leaves.FirstStage, "_layout", lambda self, *a: counts.append(1) or laying_out(self, *a))
    first = ffbp(echo, grid, backend="opencl", progress=False).data
    made = len(counts)
    second = ffbp(other, grid, backend="opencl", progress=False).data
    assert made >= 1 and len(counts) == made  # the second call laid out nothing
    assert np.array_equal(first, afresh[0]) and np.array_equal(second, afresh[1])


def test_kept_layouts_count_against_the_memory_budget(opencl_device, monkeypatch):
    """The layouts kept after a call take at most what the memory budget leaves beside a call's
    own plan and 1/SHARE of the budget (review R1): a later call that needs the room lets go of
    them before it allocates (then keeps only what fits), a call of another tree lets go of the
    last tree's before it starts, and release() lets go of everything; the images are unchanged."""
    from clsas.image.ffbp import leaves

    monkeypatch.setattr(reuse, "KEEP_PLANS", True)
    reuse.release()
    echo = echo_of("straight")
    grid = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(-2.0, 2.0, 0.04), DEPTH)
    image = ffbp(echo, grid, backend="opencl", progress=False)
    kept = reuse.held_bytes()
    assert 0 < kept <= reuse.limit()
    memory = image.provenance["memory_bytes"]  # the call's own plan (memory_plan's total)
    # a budget that leaves less than the layouts beside the call's own plan: let go, then kept within it
    laying_out, counts = leaves.FirstStage._layout, []
    monkeypatch.setattr(leaves.FirstStage, "_layout", lambda self, *a: counts.append(1) or laying_out(self, *a))
    room = kept // 2
    ffbp_package = importlib.import_module("clsas.image.ffbp")
    monkeypatch.setattr(ffbp_package, "_planning", lambda *args: 0.0)  # the planning's pre-check set aside (plan kept)
    with clsas.use_memory_budget(memory + room):
        assert np.array_equal(ffbp(echo, grid, backend="opencl", progress=False).data, image.data)
        assert counts and reuse.held_bytes() <= room
    # another tree (another tolerance) lets go of the kept layouts before its call, even when its own
    # do not fit (none kept)
    ffbp(echo, grid, backend="opencl", progress=False)
    assert reuse.held_bytes() == kept
    monkeypatch.setattr(reuse, "LAYOUT_BYTES", 1)
    held = []
    monkeypatch.setattr(leaves.FirstStage, "_layout", lambda self, *a: held.append(reuse.held_bytes())
                        or laying_out(self, *a))
    ffbp(echo, grid, backend="opencl", tolerance=0.05, progress=False)
    assert held and max(held) == 0 and reuse.held_bytes() == 0
    monkeypatch.setattr(reuse, "LAYOUT_BYTES", 256 * 2**20)
    ffbp(echo, grid, backend="opencl", progress=False)
    assert reuse.held_bytes() == kept and reuse.kept(grid)[1] is not None
    importlib.import_module("clsas.image.ffbp").release()
    assert reuse.held_bytes() == 0 and grid not in reuse._SCENES


def test_kept_scenes_and_trees_count_against_the_memory_budget(opencl_device, monkeypatch):
    """The Scenes and trees kept (host memory, review 9) count: Kept.nbytes bounds the arrays they
    hold; every grid's together stay within reuse.host_limit(), a call letting go of other grids'
    trees, then their Scenes, then its own tree (used once more, not kept) until they fit; a
    geometry whose copies alone exceed the limit is not kept; the images are unchanged throughout."""
    ffbp_package = importlib.import_module("clsas.image.ffbp")
    monkeypatch.setattr(reuse, "KEEP_PLANS", True)
    reuse.release()
    plans, planning = [], ffbp_package.plan
    monkeypatch.setattr(ffbp_package, "plan", lambda *a, **k: plans.append(1) or planning(*a, **k))
    echo = echo_of("straight")
    a = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(-2.0, 0.0, 0.04), DEPTH)
    b = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(0.0, 2.0, 0.04), DEPTH)
    image_a = ffbp(echo, a, backend="opencl", progress=False).data
    image_b = ffbp(echo, b, backend="opencl", progress=False).data
    entry_a, entry_b = reuse.kept(a)[1], reuse.kept(b)[1]
    for entry in (entry_a, entry_b):
        tree = entry.planned.tree
        held = (entry.scene.skeleton.nbytes + entry.sample.nbytes + sum(x.nbytes for x in entry.planned.arrays)
                + sum(g.spans.nbytes for level in tree.grids for g in level if g is not None))
        assert entry.nbytes >= held and entry.planned.arrays[2].nbytes == echo.rx_pos.nbytes
    assert reuse.host_bytes() == entry_a.nbytes + entry_b.nbytes
    # room for b's alone: a call on b (its tree used again) lets go of a's tree, then of a's Scene
    monkeypatch.setattr(reuse, "HOST_BYTES", entry_b.nbytes + entry_a.nbytes - entry_a.planned.nbytes // 2)
    assert np.array_equal(ffbp(echo, b, backend="opencl", progress=False).data, image_b) and len(plans) == 2
    assert entry_a.planned is None and a in reuse._SCENES and reuse.host_bytes() <= reuse.HOST_BYTES
    monkeypatch.setattr(reuse, "HOST_BYTES", entry_b.nbytes)
    assert np.array_equal(ffbp(echo, b, backend="opencl", progress=False).data, image_b) and len(plans) == 2
    assert a not in reuse._SCENES and reuse.host_bytes() == entry_b.nbytes
    # less than b's own: its tree serves this call and is let go (with its layouts), then planned anew
    monkeypatch.setattr(reuse, "HOST_BYTES", entry_b.nbytes - 1)
    assert np.array_equal(ffbp(echo, b, backend="opencl", progress=False).data, image_b) and len(plans) == 2
    assert reuse.kept(b)[1].planned is None and reuse.held_bytes() == 0
    assert np.array_equal(ffbp(echo, b, backend="opencl", progress=False).data, image_b) and len(plans) == 3
    # a geometry whose copies exceed the limit is not copied, nor kept
    monkeypatch.setattr(reuse, "HOST_BYTES", echo.rx_pos.nbytes)
    assert np.array_equal(ffbp(echo, a, backend="opencl", progress=False).data, image_a)
    assert reuse.kept(a)[1].planned is None
    # the limit is 1/SHARE of the budget where that is less than HOST_BYTES
    monkeypatch.setattr(reuse, "HOST_BYTES", 64 * 2**20)
    with clsas.use_memory_budget(reuse.SHARE * 2**20):
        assert reuse.host_limit() == 2**20
    reuse.release()
    assert reuse.host_bytes() == 0


def test_a_tree_is_used_again_only_for_its_geometry(opencl_device, monkeypatch):
    """ffbp keeps a grid's last tree and its first stage's layouts (.reuse) for echoes of the
    same geometry and options: a second call plans and lays out nothing and gives the same image
    bit for bit, and twice the echo's samples give twice the image (the same geometry, other
    data); an echo moved 1 mm across track, or another tolerance, is planned anew and gives the
    image of a call that keeps nothing."""
    from clsas.image.ffbp import leaves

    ffbp_package = importlib.import_module("clsas.image.ffbp")  # the package (clsas.image.ffbp is also the function)
    monkeypatch.setattr(reuse, "KEEP_PLANS", True)
    reuse.release()
    counts = {"plan": 0, "layout": 0}
    planning, laying_out = ffbp_package.plan, leaves.FirstStage._layout

    def plan_counted(*args, **kwargs):
        counts["plan"] += 1
        return planning(*args, **kwargs)

    def layout_counted(self, *args):
        counts["layout"] += 1
        return laying_out(self, *args)

    monkeypatch.setattr(ffbp_package, "plan", plan_counted)
    monkeypatch.setattr(leaves.FirstStage, "_layout", layout_counted)
    grid = Grid.plane(np.arange(42.0, 46.0, 0.015), np.arange(-2.0, 2.0, 0.02), DEPTH)  # nothing kept for it yet
    echo = echo_of("straight", "speckle")
    first = ffbp(echo, grid, backend="opencl", progress=False).data
    made = dict(counts)
    assert made["plan"] == 1 and made["layout"] >= 1
    assert np.array_equal(ffbp(echo, grid, backend="opencl", progress=False).data, first)
    assert np.array_equal(ffbp(echo.replace(data=2 * echo.data), grid, backend="opencl", progress=False).data,
                          2 * first)
    assert counts == made
    moved = echo.replace(tx_pos=echo.tx_pos + [1e-3, 0.0, 0.0], rx_pos=echo.rx_pos + [1e-3, 0.0, 0.0])
    kept_moved = ffbp(moved, grid, backend="opencl", progress=False).data
    assert counts == {"plan": 2, "layout": 2 * made["layout"]}
    kept_tight = ffbp(moved, grid, backend="opencl", tolerance=0.05, progress=False).data
    assert counts["plan"] == 3
    monkeypatch.setattr(reuse, "KEEP_PLANS", False)
    assert np.array_equal(ffbp(moved, grid, backend="opencl", progress=False).data, kept_moved)
    assert np.array_equal(ffbp(moved, grid, backend="opencl", tolerance=0.05, progress=False).data, kept_tight)
    assert not np.array_equal(kept_moved, first)


def test_the_next_plans_guess_is_the_leaf_length_the_rule_chose(opencl_device, monkeypatch):
    """A new geometry on a grid plans with the last tree's leaf length as first_guess only when the
    rule chose it (first=None): a length the caller gave is no hint for the rule (review 11 S5)."""
    ffbp_package = importlib.import_module("clsas.image.ffbp")
    monkeypatch.setattr(reuse, "KEEP_PLANS", True)
    reuse.release()
    guesses, planning = [], ffbp_package.plan
    monkeypatch.setattr(ffbp_package, "plan", lambda *a, **k: guesses.append(k.get("first_guess")) or planning(*a, **k))
    grid = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(-2.0, 2.0, 0.04), DEPTH)
    echo = echo_of("straight")

    def moved(mm):
        return echo.replace(tx_pos=echo.tx_pos + [mm * 1e-3, 0.0, 0.0], rx_pos=echo.rx_pos + [mm * 1e-3, 0.0, 0.0])

    given = ffbp(echo, grid, first=2, backend="opencl", progress=False)
    ruled = ffbp(moved(1), grid, backend="opencl", progress=False)
    ffbp(moved(2), grid, backend="opencl", progress=False)
    assert given.provenance["first"] == 2 != ruled.provenance["first"]
    assert guesses == [None, None, ruled.provenance["first"]]
    reuse.release()


def test_an_image_on_a_grid_equals_the_one_its_constructor_makes():
    """Image.on_grid (the imagers' path, no second pass over the positions) sets every field as the
    constructor does, and the private path it takes refuses a set of fields that is not complete."""
    data = (np.arange(GRID.size) * (1 + 1j)).astype(np.complex64).reshape(GRID.shape)
    fast = Image.on_grid(data, GRID, {"algorithm": "x"})
    made = Image(data, GRID.dims, GRID.axes, {"algorithm": "x"}, GRID.positions)
    for field in dataclasses.fields(Image):
        a, b = getattr(fast, field.name), getattr(made, field.name)
        if isinstance(a, dict):
            assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a), field.name
        else:
            assert type(a) is type(b) and np.array_equal(a, b), field.name
    with pytest.raises(TypeError, match="positions"):
        Image._checked(data=data, dims=GRID.dims, axes=GRID.axes, provenance={})


def test_scratch_buffers_go_to_the_next_call_within_the_budget(opencl_device, monkeypatch):
    """The scratch device buffers a call gives back (clsas.image.ffbp.scratch: the first batch's
    sums, the levels' groups) are taken by the next call on the same tree, which allocates none
    (the image bit for bit the same); they are kept only within what the memory budget leaves
    beside a call's plan and the layouts' room (a budget of the plan alone keeps none), and
    release() lets go of them."""
    from clsas.image.ffbp import scratch

    reuse.release()
    echo = echo_of("straight")
    grid = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(-2.0, 2.0, 0.04), DEPTH)
    first = ffbp(echo, grid, backend="opencl", progress=False)
    assert scratch.held_bytes() > 0
    kept = {id(b) for _, b in scratch._FREE}
    taking, taken = scratch.Scratch.take, []
    monkeypatch.setattr(scratch.Scratch, "take", lambda self, n: taken.append(taking(self, n)) or taken[-1])
    second = ffbp(echo, grid, backend="opencl", progress=False)
    assert second.data.tobytes() == first.data.tobytes()
    assert len(taken) >= 2 and all(id(b) in kept for b in taken)
    # the planning's pre-check set aside
    monkeypatch.setattr(importlib.import_module("clsas.image.ffbp"), "_planning", lambda *args: 0.0)
    from clsas.image.ffbp import leaves

    laying_out, held = leaves.FirstStage._layout, []  # kept and not taken while the call runs: none
    monkeypatch.setattr(leaves.FirstStage, "_layout", lambda self, *a: held.append(scratch.held_bytes())
                        or laying_out(self, *a))
    with clsas.use_memory_budget(first.provenance["memory_bytes"] + 1024):  # 1 KiB beside the plan: no room
        assert ffbp(echo, grid, backend="opencl", progress=False).data.tobytes() == first.data.tobytes()
        assert held == [0] and scratch.held_bytes() == 0
    ffbp(echo, grid, backend="opencl", progress=False)
    assert scratch.held_bytes() > 0
    importlib.import_module("clsas.image.ffbp").release()
    assert scratch.held_bytes() == 0


def test_a_batchs_scratch_sums_serve_a_later_batch_only_once_its_leaves_are_demodulated(opencl_device, monkeypatch):
    """With batches of a few leaves (a merge's group of leaves spans batches), the first stage's sums
    buffers are recycled within the call (scratch.Scratch.recycle) only once no leaf still waits to
    be demodulated from them, and the pixel fields of layouts not kept once their bp_tile is done:
    fewer buffers of each than batches, and the image bit for bit that of a call that takes new
    buffers every batch."""
    from clsas.image.ffbp import leaves, scratch

    reuse.release()
    echo = echo_of("straight")
    grid = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(-2.0, 2.0, 0.04), DEPTH)
    tree = importlib.import_module("clsas.image.ffbp").plan(echo, [0], reuse.kept(grid)[0], 4, 0.1, 8, 2, None)
    sizes = sorted(g.size for g in tree.grids[0] if g is not None)
    monkeypatch.setattr(leaves, "BATCH_POINTS", sizes[-1] + sizes[-2])  # at most two leaves a batch
    batches, taking, taken, sums, fields = [], scratch.Scratch.take, [], set(), set()
    real_batch, launch = leaves.FirstStage._batch, TileKernel.launch
    monkeypatch.setattr(leaves.FirstStage, "_batch", lambda self, *a: batches.append(1) or real_batch(self, *a))
    monkeypatch.setattr(scratch.Scratch, "take", lambda self, n: taken.append(taking(self, n)) or taken[-1])

    def launched(self, *args, **kwargs):  # the bp_tile launches' sums and pixel fields
        sums.add(id(kwargs["image"]))
        fields.add(id(kwargs["pixels"]))
        return launch(self, *args, **kwargs)

    monkeypatch.setattr(TileKernel, "launch", launched)
    recycled = ffbp(echo, grid, first=2, backend="opencl", progress=False)
    assert sums and fields and sums | fields <= {id(b) for b in taken}  # all scratch buffers
    # the layouts are not kept (keep_plans: off), so their fields' buffers serve later batches too
    assert len(batches) >= 4 and len(sums) < len(batches) and len(fields) < len(batches)
    reuse.release()
    monkeypatch.setattr(scratch.Scratch, "recycle", lambda self, b: None)  # a new buffer every batch
    fresh = ffbp(echo, grid, first=2, backend="opencl", progress=False)
    assert recycled.data.tobytes() == fresh.data.tobytes()


def test_scratch_buffers_serve_only_calls_on_the_context_that_made_them(opencl_device, monkeypatch):
    """A process may image on two OpenCL contexts (the default device is read from the environment
    at each call): a call on the second context takes none of the scratch buffers the first
    context's call gave back (review 14 M2: a buffer of another context in a command aborts the
    process on PoCL), gives the same image, and the first context's next call finds its own again."""
    import pyopencl as cl

    from clsas import opencl
    from clsas.image.ffbp import scratch

    reuse.release()
    echo = echo_of("straight")
    grid = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(-2.0, 2.0, 0.04), DEPTH)
    first = ffbp(echo, grid, backend="opencl", progress=False)
    held = {id(b) for _, b in scratch._FREE}
    assert held
    taking, taken = scratch.Scratch.take, []

    def take(self, nbytes):
        buffer = taking(self, nbytes)
        # checked before any kernel uses it: a buffer of another context would abort the process
        assert buffer.context.int_ptr == opencl.runtime().context.int_ptr, "a scratch buffer of another context"
        taken.append(buffer)
        return buffer

    monkeypatch.setattr(scratch.Scratch, "take", take)
    context = cl.Context([opencl_device.device])
    other = opencl.Runtime(device=opencl_device.device, context=context,
                           queue=cl.CommandQueue(context, properties=cl.command_queue_properties.PROFILING_ENABLE))
    with monkeypatch.context() as m:  # the second context, its own programs and kernels
        m.setattr(opencl, "runtime", lambda device=None: other)
        for cache in ("_programs", "_kernels", "_kernel_calls"):
            m.setattr(opencl, cache, {})
        second = ffbp(echo, grid, backend="opencl", progress=False)
    assert len(taken) >= 2 and not {id(b) for b in taken} & held
    assert second.data.tobytes() == first.data.tobytes()
    taken.clear()
    assert ffbp(echo, grid, backend="opencl", progress=False).data.tobytes() == first.data.tobytes()
    assert taken and {id(b) for b in taken} <= held
    reuse.release()


@pytest.mark.parametrize("keep_plans", [True], indirect=True, ids=["kept"])
def test_a_kept_layouts_fields_serve_the_next_geometrys_call_once_let_go(opencl_device, monkeypatch, keep_plans):
    """The first stage's pixel fields are a scratch buffer (clsas.image.ffbp.scratch): a layout that
    reuse keeps holds its own (not in the pool while kept: no other call can take it), and a call on a
    new geometry, which lets go of that layout, takes its buffers from the pool and that layout's
    (no fresh buffer for its fields, the sums or the groups); its image is bit for bit that of a call
    that kept nothing before it."""
    from clsas.image.ffbp import scratch

    reuse.release()
    echo = echo_of("straight")
    grid = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(-2.0, 2.0, 0.04), DEPTH)
    ffbp(echo, grid, backend="opencl", progress=False)
    fields = {id(layout.pix) for layout in reuse._held().items.values()}
    pool = {id(b) for _, b in scratch._FREE}
    assert fields and not fields & pool
    taking, taken = scratch.Scratch.take, []
    monkeypatch.setattr(scratch.Scratch, "take", lambda self, n: taken.append(taking(self, n)) or taken[-1])
    shifted = echo.replace(tx_pos=echo.tx_pos + [0.002, 0.0, 0.0], rx_pos=echo.rx_pos + [0.002, 0.0, 0.0])
    second = ffbp(shifted, grid, backend="opencl", progress=False)
    now = {id(layout.pix) for layout in reuse._held().items.values()}
    assert now and now <= pool | fields and {id(b) for b in taken} <= pool | fields
    reuse.release()
    assert ffbp(shifted, grid, backend="opencl", progress=False).data.tobytes() == second.data.tobytes()
