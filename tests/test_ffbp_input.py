"""ffbp's refusals (issue 27's reproducers): bad input named by parameter, an image that overflows
complex64, and memory budgets checked before ffbp plans or allocates.

Scenes: tests/_ffbp_helpers.py's (Huang & Yang 2022's sonar over a 4 x 4 m seafloor grid: points or speckle).
"""

from __future__ import annotations

import numpy as np
import pytest
from _ffbp_helpers import DEPTH, GRID, _geometry_only_echo, echo_of, keep_plans  # noqa: F401 (keep_plans: a fixture)

import clsas
from clsas.model import Grid
from clsas.image.backprojection import backproject
from clsas.image.ffbp import ffbp
from clsas.scene import presets
from clsas.scene.targets import PointTargets

pytestmark = pytest.mark.usefixtures("keep_plans")


def test_bad_input_is_refused():
    echo = echo_of("straight")
    far = Grid.plane(np.arange(900.0, 901.0, 0.1), np.arange(-1.0, 1.0, 0.1), DEPTH)
    with pytest.raises(ValueError, match="never sees"):
        ffbp(echo, far, backend="numpy")
    for tol in (0.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="tolerance"):
            ffbp(echo, GRID, tolerance=tol, backend="numpy")
    with pytest.raises(ValueError, match="factor"):
        ffbp(echo, GRID, factor=1, backend="numpy")
    with pytest.raises(ValueError, match="taps"):
        ffbp(echo, GRID, taps=6, backend="numpy")
    with pytest.raises(ValueError, match="aperture"):
        ffbp(echo, GRID, aperture=0.0, backend="numpy")
    kiang = presets.kiang2022(n_pulses=4)
    buoy = clsas.range_compress(clsas.simulate(kiang.replace(targets=(PointTargets([100.0, 0.0, -43.0]),)),
                                               backend="numpy", progress=False))
    with pytest.raises(ValueError, match="'C' is stationary"):
        ffbp(buoy, Grid.plane([100.0, 100.1], [0.0, 0.1], -43.0), backend="numpy")


def test_an_overflowing_image_raises(opencl_device):
    """Finite records near complex64's largest value sum past it: ffbp raises on both backends, as
    backproject does (review 9 R7), instead of returning inf."""
    echo = echo_of("straight")
    grid = Grid.plane(np.arange(43.7, 44.3, 0.015), np.arange(-0.3, 0.3, 0.02), DEPTH)  # around a point
    peak = np.abs(ffbp(echo, grid, backend="opencl", progress=False).data).max()
    # the image's peak 1.5 times complex64's largest value (a leaf's image, 8 of the 20 pulses, below
    # it: the NumPy backend's leaves go through backproject, which would raise first)
    huge = echo.replace(data=(echo.data * (1.5 * float(np.finfo(np.float32).max) / float(peak))).astype(np.complex64))
    for backend in ("numpy", "opencl"):
        with pytest.raises(ValueError, match="ffbp: the image overflows complex64"):
            ffbp(huge, grid, backend=backend, progress=False)


@pytest.mark.parametrize("pixels", ["all in the skeleton", "a strided skeleton"])
@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_a_non_finite_position_written_under_a_grid_is_refused(opencl_device, pixels, value):
    """A Grid on the caller's array images what the array holds now (tests/test_ffbp_reuse.py): a NaN
    or inf written there after the Grid was made is refused by name on both backends, whichever
    pixel holds it (a skeleton point, or one the planner's strided skeleton skips), before the
    planner's reductions (review 11 R5: the device maxima skip a NaN that NumPy's propagate; it
    used to end in a LinAlgError, an IndexError or an overflow error)."""
    echo = echo_of("straight")
    step = 0.05 if pixels == "all in the skeleton" else 0.03  # 80 x 80 pixels <= polar.SKELETON < 133 x 133
    x, y = np.arange(42.0, 46.0, step), np.arange(-2.0, 2.0, step)
    yy, xx = np.meshgrid(y, x, indexing="ij")
    for backend in ("numpy", "opencl"):
        positions = np.stack([xx, yy, np.full_like(xx, DEPTH)], axis=-1)
        alias = positions[:]  # a writable view made before the Grid (which makes its array read-only)
        grid = Grid(positions, ("y", "x"), {"y": y, "x": x})
        alias[1, 1, 0] = value  # not a strided skeleton point (stride 2), nor the last row or column
        with pytest.raises(ValueError, match="Grid.positions: must be finite"):
            ffbp(echo, grid, backend=backend, progress=False)


def test_a_scene_of_no_pixel_is_refused():
    """A Grid has at least one pixel, and Scene.of says so by name if ever given none (review 11 R5)."""
    from clsas.image.ffbp.polar import Scene

    with pytest.raises(ValueError, match="Grid.positions: no pixel"):
        Scene.of(np.zeros((0, 3)))


@pytest.mark.parametrize("aperture", [None, 0.2])
def test_the_planners_device_buffers_are_within_the_planning_part(opencl_device, monkeypatch, aperture):
    """The planner's device reductions (polar.offsets.DeviceOffsets) run before the call's memory plan
    is checked, so the planning part the budget checks first counts them (review 11 R4): each
    DeviceOffsets allocates at most offsets.device_bytes of device buffers (all its reductions
    together: the envelope's (n, ENVELOPE_BINS, 2) the largest), and the planning part on OpenCL
    holds PLAN_BYTES a skeleton point plus twice the bound (the results' host copies)."""
    import pyopencl as cl

    import importlib

    from clsas.image.ffbp.polar import offsets, sampling

    ffbp_package = importlib.import_module("clsas.image.ffbp")

    echo = echo_of("motion")  # yawed: with an aperture, aperture_windows' reductions across y too
    scene = Grid.plane(np.arange(42.0, 46.0, 0.03), np.arange(-2.0, 2.0, 0.03), DEPTH)
    scene = ffbp_package.reuse.kept(scene)[0]
    k = scene.skeleton.shape[0]
    made = []  # [sub-apertures, bytes of device buffers] of each DeviceOffsets
    buffer, starting = cl.Buffer, offsets.DeviceOffsets.__init__

    def counted(context, flags, size=0, hostbuf=None):
        made[-1][1] += hostbuf.nbytes if hostbuf is not None else size
        return buffer(context, flags, size, hostbuf)

    def start(self, scene_, origins, *args):
        made.append([origins.shape[0], 0])
        starting(self, scene_, origins, *args)

    monkeypatch.setattr(offsets.DeviceOffsets, "__init__", start)
    with monkeypatch.context() as m:
        m.setattr(cl, "Buffer", counted)
        ffbp_package.plan(echo, [0], scene, 4, 0.1, 8, None, aperture, device=True)
    assert made and all(0 < n <= sampling.DEVICE_CHUNK_NODES for n, _ in made)
    assert all(0 < nbytes <= offsets.device_bytes(k, n, sampling.ENVELOPE_BINS) for n, nbytes in made)
    largest = max(nbytes for _, nbytes in made)
    planning = ffbp_package._fixed_parts(GRID.size, k, 8, "linear", "opencl", 1.0)["planning"]
    assert planning >= ffbp_package.PLAN_BYTES * k + 2 * largest
    assert ffbp_package._fixed_parts(GRID.size, k, 8, "linear", "numpy", 1.0)["planning"] == ffbp_package.PLAN_BYTES * k


@pytest.mark.parametrize("device", [False, True])
def test_the_planners_host_memory_is_within_the_planning_part(opencl_device, device):
    """tree.plan's traced peak on the host stays within the planning part ffbp checks before it plans
    (PLAN_NODE_BYTES a sub-aperture whose extent it finds, PLAN_PULSE_BYTES a pulse of a receiver's
    position node): first=1 over 512 pulses, 1023 sub-apertures, each with its envelope and polar
    grids. Session 15 noted these uncounted; the rows' spans' sparse tables of every grid sampled at
    once (80 kB a grid) then took a traced 76 MB here against a part of 3.3 MB (sampling.SPAN_GRIDS
    bounds them now). Measured 19.7 MB against 36.0 MB (NumPy) and 40.4 MB (OpenCL)."""
    import importlib
    import tracemalloc

    ffbp_package = importlib.import_module("clsas.image.ffbp")

    echo = _geometry_only_echo(512)
    grid = Grid.plane(np.linspace(45.0, 47.0, 48), np.linspace(-0.4, 0.4, 48), DEPTH)
    scene = ffbp_package.polar.Scene.of(grid.positions)
    scene.nearest(scene.skeleton[:1])  # the Scene's k-d tree (kept with it, PLAN_BYTES) and scipy's import
    ffbp_package.plan(_geometry_only_echo(64), [0], scene, 2, 0.1, 8, None, None, device=device)  # the program
    tracemalloc.start()
    try:
        tree = ffbp_package.plan(echo, [0], scene, 2, 0.1, 8, 1, None, device=device)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    nodes = ffbp_package._plan_nodes(echo.n_pulses, 1, 2)
    assert nodes == sum(len(level) for level in tree.pulses) == 1023
    planning = ffbp_package._fixed_parts(grid.size, scene.skeleton.shape[0], 8, "linear",
                                         "opencl" if device else "numpy", 1.0, plan_nodes=nodes,
                                         plan_pulses=echo.n_pulses * echo.rx_pos.shape[2])["planning"]
    assert peak <= planning


@pytest.mark.parametrize("n_pulses", [1, 5, 64, 300, 2048, 5000])
@pytest.mark.parametrize("factor", [2, 4, 7])
def test_the_rules_plan_finds_no_more_extents_than_counted(n_pulses, factor):
    """With first=None the planner finds the extents of the candidates' middle nodes and spines and
    of the trees it sizes: at most _plan_nodes(n_pulses, None, factor) of them, the count the
    planning part takes (each distinct node framed once: the planner keeps what it found)."""
    import importlib

    ffbp_package = importlib.import_module("clsas.image.ffbp")
    tree_module = importlib.import_module("clsas.image.ffbp.tree")

    echo = _geometry_only_echo(n_pulses)
    scene = ffbp_package.polar.Scene.of(Grid.plane(np.linspace(45.0, 47.0, 48), np.linspace(-0.4, 0.4, 48),
                                                   DEPTH).positions)
    framed, framing = [], tree_module._Frames.frames

    def counted(self, nodes, *args, **kwargs):
        framed.extend(nodes)
        return framing(self, nodes, *args, **kwargs)

    with pytest.MonkeyPatch.context() as m:
        m.setattr(tree_module._Frames, "frames", counted)
        tree = ffbp_package.plan(echo, [0], scene, factor, 0.1, 8, None, None)
    assert len(framed) == len(set(framed))  # each node framed once
    assert len(framed) <= ffbp_package._plan_nodes(n_pulses, None, factor)
    assert sum(len(level) for level in tree.pulses) <= ffbp_package._plan_nodes(n_pulses, tree.first, factor)


def test_memory_budget_refuses_before_allocating():
    """ffbp on a 300 x 300 grid under a 2 MB budget refuses with the budget's error before it
    plans or allocates (it used to allocate ~20 MiB)."""
    echo = echo_of("straight")
    grid = Grid.plane(np.linspace(42.0, 46.0, 300), np.linspace(-2.0, 2.0, 300), DEPTH)
    with clsas.use_memory_budget("2M"):
        with pytest.raises(clsas.budget.MemoryBudgetError, match="ffbp onto 90000 pixels"):
            ffbp(echo, grid, backend="opencl")


def test_a_string_for_a_flag_is_refused():
    echo = echo_of("straight")
    with pytest.raises(TypeError, match="ffbp stop_and_go"):
        ffbp(echo, GRID, stop_and_go="no", backend="numpy")
    with pytest.raises(TypeError, match="backproject stop_and_go"):
        backproject(echo, GRID, stop_and_go="no", backend="numpy")


@pytest.mark.parametrize("name, value, error", [("aperture", "a", TypeError), ("factor", 2.5, TypeError),
                                                 ("tolerance", "0.1", TypeError), ("first", 0, ValueError),
                                                 ("taps", True, ValueError)])
def test_messages_name_the_parameter(name, value, error):
    with pytest.raises(error, match=f"ffbp {name}"):
        ffbp(echo_of("straight"), GRID, backend="numpy", **{name: value})


@pytest.mark.parametrize("options", [dict(first=1, factor=2), dict(first=2), dict(interp="sinc8", first=4), dict()])
def test_numpy_memory_stays_within_the_plan(options):
    """The NumPy backend's traced peak (its first stage by back-projection's reference, its merges
    by merge_reference, the tap tables built afresh) stays within the memory plan the budget is
    checked against. Measured 8.8-70 MB against plans of 39-178 MB."""
    import tracemalloc

    from clsas.interp import tap_table

    echo = _geometry_only_echo(64)
    grid = Grid.plane(np.linspace(45.0, 47.0, 48), np.linspace(-0.4, 0.4, 48), DEPTH)
    tap_table.cache_clear()
    tracemalloc.start()
    try:
        img = ffbp(echo, grid, backend="numpy", progress=False, **options)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= img.provenance["memory_bytes"]


@pytest.mark.parametrize("options", [dict(backend="numpy", interp="sinc8"), dict(backend="opencl", tolerance=0.37),
                                     dict(backend="numpy", first=3)])
def test_a_small_budget_refuses_before_planning(opencl_device, options):
    """Under a 64 KiB budget ffbp refuses (the tap tables, the plan's temporaries, the records)
    before it builds a table or plans (it used to build 1.6-4.1 MB first, issue 27)."""
    import tracemalloc

    from clsas.interp import tap_table

    echo = echo_of("straight")
    grid = Grid.plane(np.linspace(43.9, 44.1, 6), np.linspace(-0.1, 0.1, 6), DEPTH)  # its own bytes fit
    tap_table.cache_clear()
    with clsas.use_memory_budget(1 << 16):
        tracemalloc.start()
        try:
            with pytest.raises(clsas.budget.MemoryBudgetError, match="tables and plan"):
                ffbp(echo, grid, progress=False, **options)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
    assert peak < 1 << 16
