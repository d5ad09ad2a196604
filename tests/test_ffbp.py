"""Fast factorised back-projection against direct back-projection of the same data, and the
merge kernel and the first stage's leaves against their references.

Scenes: tests/_ffbp_helpers.py's (Huang & Yang 2022's sonar over a 4 x 4 m seafloor grid: points or speckle).
Plan reuse (what a Grid keeps): test_ffbp_reuse.py; the planner (tree, leaf length, frames,
oversampling): test_ffbp_planner.py; bad input and memory budgets: test_ffbp_input.py; the
integration angle: test_ffbp_aperture.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from _tolerances import rel_l2
from _ffbp_helpers import (  # noqa: F401 (keep_plans: a fixture, used by pytestmark)
    DEPTH, GRID, KEEPING, POINTS, compare_points, direct, echo_of, keep_plans)

import clsas
from clsas import metrics
from clsas.model import Grid
from clsas.image.backprojection import backproject, prepare
from clsas.image.ffbp import ffbp
from clsas.image.ffbp.leaves import FirstStage
from clsas.image.ffbp.merge import merge_opencl, merge_reference
from clsas.image.ffbp import polar
from clsas.image.ffbp.polar import Scene
from clsas.image.ffbp.tree import plan

pytestmark = pytest.mark.usefixtures("keep_plans")


@KEEPING
@pytest.mark.parametrize("track", ["straight", pytest.param("motion", marks=pytest.mark.slow),
                                   pytest.param("circle", marks=pytest.mark.slow)])
def test_points_match_direct_backprojection(opencl_device, track, keep_plans):
    """The issue's bars (peaks within 0.05 of a cell, 0.5 dB, PSLR and ISLR within 1 dB, SSIM
    >= 0.95); relative L2 measured 0.0049-0.0050 on the three tracks at the default tolerance and
    factor (bound 0.07; 0.0045-0.0046 with factor 2) and 0.0023 at tolerance 0.02 (bound 0.02);
    0.0048 and 0.0023 on the straight track once the receivers' motion while they record counted in
    the sub-apertures' lengths (e115a3a)."""
    ref = direct(track)
    img = ffbp(echo_of(track), GRID, backend="opencl")
    worst = compare_points(img, ref)
    err = rel_l2(img.data, ref.data)
    assert worst["shift"] < 0.05 and worst["power"] < 0.5, worst
    assert worst["pslr"] < 1.0 and worst["islr"] < 1.0, worst
    assert metrics.ssim(img, ref) >= 0.95
    assert err <= 0.07
    tight = ffbp(echo_of(track), GRID, backend="opencl", tolerance=0.02)
    assert rel_l2(tight.data, ref.data) <= 0.02
    if keep_plans:  # the default tolerance's tree planned again (one tree a grid), then used again
        assert np.array_equal(ffbp(echo_of(track), GRID, backend="opencl").data, img.data)
        assert np.array_equal(ffbp(echo_of(track), GRID, backend="opencl").data, img.data)


@KEEPING
def test_speckle_matches_direct_backprojection(opencl_device):
    """3000 random complex scatterers (a seafloor-like speckle): relative L2 measured 0.0051 (0.0047
    with factor 2); 0.0049 since e115a3a. The bound is ten times that, not the default
    tolerance's 0.1 (which a tenfold regression would still meet)."""
    ref = direct("straight", "speckle")
    img = ffbp(echo_of("straight", "speckle"), GRID, backend="opencl")
    err = rel_l2(img.data, ref.data)
    assert err <= 0.05
    assert metrics.ssim(img, ref) >= 0.95


def test_merge_kernel_matches_reference(opencl_device):
    """One merge of real first-stage images into their parent's polar grid and onto pixels:
    kernel (float32 interpolation, double geometry) against the float64 reference: relative L2
    measured 1.9e-7 (float32 rounding of 64-tap sums). On the track with motion errors: on a
    straight track every frame shares one axis, so the merge does not see where on the circle
    about it a parent sample lies (a kernel bug there went unnoticed on it)."""
    echo = echo_of("motion")
    chosen = list(range(echo.n_rx))
    tree = plan(echo, chosen, Scene.of(GRID.positions), 2, 0.1, 8, None, None)
    level = 1
    leaves = FirstStage(echo, tree.pulses[0], "opencl", chosen, "linear", 8, None, False)
    kids = [(tree.grids[0][k], leaves.image(k, tree.grids[0][k], tree.grids[0])) for k in tree.children[level][0]]
    parent = tree.grids[level][0]
    f0, c = echo.waveform.f0, echo.medium.sound_speed
    ref = merge_reference(kids, parent, f0, c, 8, tree.rho)
    got = merge_opencl(kids, parent, f0, c, 8, tree.rho)
    assert rel_l2(got, ref) < 2e-6
    pixels = GRID.positions[::4, ::4].reshape(-1, 3)
    ref = merge_reference(kids, pixels, f0, c, 8, tree.rho)
    got = merge_opencl(kids, pixels, f0, c, 8, tree.rho)
    assert rel_l2(got, ref) < 2e-6


def test_batched_leaves_match_backproject(opencl_device):
    """The first stage's batched bp_tile launches (a tile's pulses read at its leaf's row) against
    one clsas.backproject call a leaf on the same prepared records, on the track with motion
    errors and with an integration angle: relative L2 measured 0.9-1.0e-4 (their tiles differ: both
    within back-projection's float32 phase budget, 2e-3 rad)."""
    echo = echo_of("motion")
    chosen = list(range(echo.n_rx))
    tree = plan(echo, chosen, Scene.of(GRID.positions), 2, 0.1, 8, 2, 0.5)
    grids = tree.grids[0]
    batched = FirstStage(echo, tree.pulses[0], "opencl", chosen, "linear", 8, 0.5, False)
    records = prepare(echo)
    for k, (p0, p1) in enumerate(tree.pulses[0][:4]):  # the first batch holds every leaf; four are checked
        got = batched.image(k, grids[k], grids)
        one = backproject(records, Grid.points(grids[k].points()), pulses=(p0, p1), aperture=0.5, backend="opencl",
                          progress=False).data * np.exp(-4j * np.pi * echo.waveform.f0 * grids[k].ranges / echo.medium.sound_speed)
        assert rel_l2(got, one * grids[k].inside()) < 1e-3
        assert np.all(got[~grids[k].inside()] == 0)


def test_records_prepared_a_batch_at_a_time_give_the_same_image(opencl_device, monkeypatch):
    """Every pulse's records prepared once (they fit leaves.RECORD_BYTES) or a batch of leaves at a
    time on a copy of its pulses (they do not; a byte allowed here): the same leaves and image
    (measured relative L2 0: the same records, read at the same rows)."""
    from clsas.image.ffbp import leaves

    echo = echo_of("motion")
    once = ffbp(echo, GRID, backend="opencl", progress=False)
    monkeypatch.setattr(leaves, "RECORD_BYTES", 1)
    batched = ffbp(echo, GRID, backend="opencl", progress=False)
    assert once.provenance["polar_samples"] == batched.provenance["polar_samples"]
    assert rel_l2(batched.data, once.data) < 1e-6


def test_batches_left_running_and_levels_sharing_a_buffer_change_nothing(opencl_device, monkeypatch):
    """The first stage leaves a batch's kernels running (no queue finish: the next batch or the end
    settles them), each with its own records (RECORD_BYTES of a byte: a batch's records go with
    it) and one batch per leaf (BATCH_POINTS of a sample), and DeviceStore writes all groups of a
    level into one buffer: the image is bit for bit the one with a finish after every batch and a
    fresh buffer for every group."""
    from clsas.image.ffbp import leaves, store

    echo = echo_of("motion", "speckle")
    monkeypatch.setattr(leaves, "RECORD_BYTES", 1)
    monkeypatch.setattr(leaves, "BATCH_POINTS", 1)
    tree = plan(echo, list(range(echo.n_rx)), Scene.of(GRID.positions), 4, 0.1, 8, None, None)
    assert tree.top >= 1 and len(tree.children[1]) > 1  # a level with several groups
    shared = ffbp(echo, GRID, backend="opencl", progress=False).data
    launch = leaves.FirstStage._launch
    finished = []

    def finishing(self, *args):
        out = launch(self, *args)
        clsas.opencl.runtime().queue.finish()
        finished.append(self.pending is not None)
        return out

    def fresh(self, level, size):
        return self.cl.Buffer(self.rt.context, self.cl.mem_flags.READ_WRITE, 8 * max(size, 1))

    monkeypatch.setattr(leaves.FirstStage, "_launch", finishing)
    monkeypatch.setattr(store.DeviceStore, "group", fresh)
    alone = ffbp(echo, GRID, backend="opencl", progress=False).data
    assert len(finished) > 1 and all(finished)  # several batches, each left pending
    assert np.array_equal(shared, alone)


def test_leaf_references_on_the_device_match_the_hosts(opencl_device, monkeypatch):
    """The leaves' tile references computed on the device (bp_refs, a launch a leaf) where every
    receiver moves uniformly (two position nodes: the straight track), or on the host: the same
    image (measured relative L2 0 on this machine; the twins may round differently elsewhere); on
    the track with motion errors (17 nodes) the host computes them."""
    from clsas.image.ffbp import leaves

    used = []
    device = leaves.FirstStage._device_references

    def spy(self, *args):
        used.append(device(self, *args))
        return used[-1]

    monkeypatch.setattr(leaves.FirstStage, "_device_references", spy)
    echo = echo_of("straight", "speckle")
    on_device = ffbp(echo, GRID, backend="opencl", progress=False)
    assert used and all(refs is not None for refs in used)
    with monkeypatch.context() as m:
        m.setattr(leaves.FirstStage, "_device_references", lambda self, *args: None)
        on_host = ffbp(echo, GRID, backend="opencl", progress=False)
    assert rel_l2(on_device.data, on_host.data) < 1e-6
    used.clear()
    ffbp(echo_of("motion"), GRID, backend="opencl", progress=False)
    assert used and all(refs is None for refs in used)


def test_leaves_no_tile_can_hold_go_through_backproject(opencl_device, monkeypatch):
    """Leaves whose polar samples lie so far apart that even bp_tile's smallest tile (ROWS x
    LANES samples) leaves the float32 budget (a very short leaf's coarse angles; here the budget
    is made 1 mm) are imaged by clsas.backproject one by one, not refused: the same images as
    the direct call (measured relative L2 0, the same code)."""
    from clsas.image.backprojection import TileKernel

    monkeypatch.setattr(TileKernel, "half_extent", staticmethod(lambda f0, c: 1e-3))
    echo = echo_of("straight")
    chosen = [0, 1, 2, 3]
    tree = plan(echo, chosen, Scene.of(GRID.positions), 2, 0.1, 8, 5, None)
    grids = tree.grids[0]
    stage = FirstStage(echo, tree.pulses[0], "opencl", chosen, "linear", 8, None, False)
    records = prepare(echo, receivers=chosen)
    for k, (p0, p1) in enumerate(tree.pulses[0][:2]):
        got = stage.image(k, grids[k], grids)
        one = backproject(records, Grid.points(grids[k].points()), pulses=(p0, p1), backend="opencl",
                          progress=False).data * np.exp(-4j * np.pi * echo.waveform.f0 * grids[k].ranges / echo.medium.sound_speed)
        assert rel_l2(got, one * grids[k].inside()) < 1e-6


@pytest.mark.parametrize("budget", [1.0, 0.5])
def test_tile_shapes_passed_over_by_their_estimate_would_have_failed(opencl_device, monkeypatch, budget):
    """The first stage passes over tile shapes whose estimated half-diagonal exceeds the budget
    (leaves.TILE_SLACK) without computing their fields: with a budget that makes the launcher
    halve its tiles (1 m: 16 x 128 -> 4 x 64 samples; 0.5 m: -> 4 x 16), the image is the one
    every shape checked gives (TILE_SLACK infinite), bit for bit: the same tiles."""
    from clsas.image.backprojection import TileKernel
    from clsas.image.ffbp import leaves

    monkeypatch.setattr(TileKernel, "half_extent", staticmethod(lambda f0, c: budget))
    echo = echo_of("straight")
    skipping = ffbp(echo, GRID, backend="opencl", progress=False).data
    monkeypatch.setattr(leaves, "TILE_SLACK", float("inf"))
    checked = ffbp(echo, GRID, backend="opencl", progress=False).data
    assert np.array_equal(skipping, checked)


def test_ragged_grids_skip_the_wedge_and_change_nothing(opencl_device, monkeypatch):
    """Polar grids computed only within their rows' spans (polar.sampling.RAGGED: the (r, v) box's corners
    outside the scene's wedge skipped) give the image of whole rectangles: relative L2 measured
    7e-9 on the speckle scene with and without motion errors, with 11 % fewer polar samples."""
    for track in ("straight", "motion"):
        echo = echo_of(track, "speckle")
        ragged = ffbp(echo, GRID, backend="opencl", progress=False)
        with monkeypatch.context() as m:
            m.setattr(polar.sampling, "RAGGED", False)
            whole = ffbp(echo, GRID, backend="opencl", progress=False)
        assert ragged.provenance["levels"] == whole.provenance["levels"]
        assert rel_l2(ragged.data, whole.data) < 1e-7
        assert sum(ragged.provenance["polar_samples"]) < 0.93 * sum(whole.provenance["polar_samples"])


@KEEPING
def test_numpy_and_opencl_agree(opencl_device):
    """The whole method on both backends (NumPy back-projection and merges in float64) on a
    small patch around one point: relative L2 measured 3.2e-6 (the float32 kernels' rounding)."""
    echo = echo_of("straight")
    grid = Grid.plane(np.arange(43.7, 44.3, 0.015), np.arange(-0.3, 0.3, 0.02), DEPTH)
    a = ffbp(echo, grid, backend="numpy")
    b = ffbp(echo, grid, backend="opencl")
    assert rel_l2(b.data, a.data) < 3e-5


def test_the_final_stage_writes_its_first_group_and_adds_the_others(opencl_device, monkeypatch):
    """On OpenCL the final stage's first group of top nodes writes the image (no zero fill) and
    the later groups add into it: the test grid's top nodes come in two groups, and the image is
    bit for bit the one of a zero-filled image every group adds into; it agrees with the NumPy
    backend's to relative L2 4.9e-5 measured (float32 kernels)."""
    from clsas.image.ffbp import _top_groups
    from clsas.image.ffbp.store import DeviceStore

    echo = echo_of("straight")
    tree = plan(echo, list(range(echo.n_rx)), Scene.of(GRID.positions), 4, 0.1, 8, None, None)
    assert len(_top_groups(tree.grids[tree.top], GRID.size)) == 2
    written = ffbp(echo, GRID, backend="opencl", progress=False).data
    opened = DeviceStore.__init__

    def zero_filled(self, *args):
        opened(self, *args)
        self.cl.enqueue_fill_buffer(self.rt.queue, self.flat, np.zeros(1, np.complex64), 0, self.flat.size)
        self.written = True  # every group adds

    monkeypatch.setattr(DeviceStore, "__init__", zero_filled)
    added = ffbp(echo, GRID, backend="opencl", progress=False).data
    assert np.array_equal(written, added)
    assert rel_l2(written, ffbp(echo, GRID, backend="numpy", progress=False).data) < 5e-4


def test_points_off_the_plane(opencl_device):
    """A 3-D point grid (two planes 0.5 m apart around a point) on a straight track: pixels off the
    fitted plane are read rotated about each sub-aperture's axis, exact for a straight track:
    relative L2 measured 0.0048 (both planes alike)."""
    echo = echo_of("straight")
    x, y = np.arange(43.8, 44.2, 0.015), np.arange(-0.2, 0.2, 0.02)
    pos = np.stack([Grid.plane(x, y, z).positions for z in (DEPTH, DEPTH + 0.5)])
    grid = Grid.points(pos, dims=("z", "y", "x"))
    ref = backproject(echo, grid, backend="opencl", progress=False)
    img = ffbp(echo, grid, backend="opencl")
    assert rel_l2(img.data, ref.data) < 0.05


def test_a_single_point_is_imaged_as_backproject_images_it(opencl_device):
    """A grid of one point (zero extent in range and angle) used to be refused as 'never seen'."""
    echo = echo_of("straight")
    grid = Grid.points([POINTS[12]])
    ref = backproject(echo, grid, backend="opencl", progress=False)
    img = ffbp(echo, grid, backend="opencl", progress=False)
    assert abs(ref.data[0]) > 0
    assert abs(img.data[0] - ref.data[0]) / abs(ref.data[0]) < 3e-6  # measured 1.0e-7 (2.3e-7 before e115a3a; one level: leaves to the point)


@pytest.mark.parametrize("first, factor", [(1, 2), (1, 4), (None, 4)])
def test_one_receiver_moving_while_it_records(opencl_device, first, factor):
    """One receiver of the array (it moves 0.17 m while it records a pulse: its phase centre moves
    with the echo's delay, so a one-pulse leaf has a length): one-pulse leaves (first=1, issue 27:
    their polar grids used to hold sines far outside [-1, 1]) and the default tree, merged, match
    back-projection. Relative L2 measured 0.0050-0.0061 (OpenCL and NumPy alike); 0.22-1.15 with
    first=1 and 0.008-0.014 by default before the receiver's motion counted in the sub-apertures'
    lengths."""
    echo = echo_of("straight")
    patch = Grid.plane(np.arange(43.7, 44.3, 0.015), np.arange(-0.3, 0.3, 0.02), DEPTH)
    for grid, backends in ((patch, ("numpy", "opencl")), (GRID, ("opencl",))):
        ref = backproject(echo, grid, receivers=[0], backend="opencl", progress=False)
        for backend in backends:
            img = ffbp(echo, grid, receivers=[0], first=first, factor=factor, backend=backend, progress=False)
            assert img.provenance["levels"] >= (2 if first == 1 else 1)
            assert rel_l2(img.data, ref.data) < 0.05
