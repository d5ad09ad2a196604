"""Issue #27's model reproducers, each a regression test: what used to crash or be accepted."""

from __future__ import annotations

import numpy as np
import pytest

import clsas
from clsas.errors import MemoryBudgetError
from clsas.scene import presets


def test_a_grid_without_axes_is_a_grid_of_points():
    grid = clsas.Grid(np.zeros((2, 3)), ("i",), None)  # was an AttributeError
    assert grid.shape == (2,) and set(grid.axes) == {"i"}  # an index axis


@pytest.mark.parametrize("make, name", [
    (lambda: clsas.Grid(np.zeros((2, 3)), ("i",), {"i": np.array([np.nan, 1.0])}), "Grid.axes['i']"),
    (lambda: clsas.Grid.plane([np.nan, 1.0], [0.0], 0.0), "Grid.plane x"),
    (lambda: clsas.Grid.plane([0.0, 1.0], [np.inf], 0.0), "Grid.plane y"),
])
def test_grid_axes_must_be_finite(make, name):
    with pytest.raises(ValueError, match=name.replace("[", r"\[").replace("]", r"\]") + ": must be finite"):
        make()


def test_grid_points_of_a_broadcast_input_count_in_full_against_the_budget():
    view = np.broadcast_to(1.0, (1000, 1000, 3))  # 24 bytes of data, 23 MiB once copied
    with clsas.use_memory_budget("2M"), pytest.raises(MemoryBudgetError, match="Grid.points positions of 1000000"):
        clsas.Grid.points(view)


@pytest.fixture(scope="module")
def echo():
    return clsas.simulate(presets.point_scene("heremans2009", n_pulses=2), progress=False, backend="numpy")


def test_echo_flags_are_bools_and_receiver_names_distinct(echo):
    with pytest.raises(TypeError, match="EchoData.compressed: must be True or False, got 'no'"):
        echo.replace(compressed="no")  # was read as True
    names = list(echo.receivers)
    names[1] = names[0]
    with pytest.raises(ValueError, match="EchoData.receivers"):
        echo.replace(receivers=tuple(names))


def test_load_of_none_names_the_parameter():
    with pytest.raises(TypeError, match=r"load path: must be a file name \(str or os.PathLike\), got None"):
        clsas.load(None)
