"""Issue #27's leftovers (session 3), each a regression test: prepare's thread count and its
messages, the inclined-array correction's angles, DPCA's EstimationError and memory budget, and
the choice rule (docs/design.md: a choice is judged by membership, a ValueError for any kind)."""

from __future__ import annotations

import tracemalloc
import warnings

import numpy as np
import pytest
from test_properties_api import compressed
from test_properties_dpca import small as dpca_small
from test_properties_papers import wu_echo

import clsas
from clsas import validate
from clsas.errors import EstimationError, MemoryBudgetError
from clsas.estimate import dpca
from clsas.image.backprojection import prepare
from clsas.image.inclined import correct_inclined_array


@pytest.mark.parametrize("workers, error", [(2**64, ValueError), (10**30, ValueError), (0, ValueError),
                                            ("a", TypeError), (2.0, TypeError), (2.5, TypeError),
                                            (object(), TypeError), (True, TypeError)])
def test_prepare_refuses_thread_counts_by_name(workers, error):
    """2**64 reached scipy's c2c as an unnamed TypeError; 'a' and 2.0 were ValueErrors."""
    with pytest.raises(error, match="prepare workers"):
        prepare(compressed(), workers=workers)


def test_prepare_names_itself_and_ffbp_itself():
    """Their messages said "backproject interp" / "backproject upsample"."""
    with pytest.raises(ValueError, match="^prepare interp: must be one of"):
        prepare(compressed(), interp="cubic")
    with pytest.raises(TypeError, match="^prepare upsample: must be an integer"):
        prepare(compressed(), upsample=2.0)
    grid = clsas.Grid.plane(np.linspace(29, 31, 4), np.linspace(-1, 1, 4), 0.0)
    with pytest.raises(ValueError, match="^ffbp upsample: must be an integer"):
        clsas.ffbp(compressed(), grid, upsample=100, progress=False)
    with pytest.raises(ValueError, match="^backproject interp"):
        clsas.backproject(compressed(), grid, interp="cubic", progress=False)
    assert prepare(compressed(), workers=-1).nbytes > 0  # negative counts back from the cores, as scipy.fft


@pytest.mark.parametrize("name", ["yaw", "pitch"])
@pytest.mark.parametrize("value, error", [(1j, TypeError), (object(), TypeError), (True, TypeError), ("a", TypeError),
                                          (np.nan, ValueError), (1.0, ValueError), ([0.0, 0.1], ValueError),
                                          (["a"] * 8, TypeError)])
def test_inclined_angles_are_refused_by_name(opencl_device, name, value, error):
    """1j and object() were unnamed float() TypeErrors, True was read as 1 rad (a ValueError)."""
    with pytest.raises(error, match=f"correct_inclined_array {name}"):
        correct_inclined_array(wu_echo(), **{name: value})


def test_inclined_angles_as_one_value_or_one_per_pulse_agree(opencl_device):
    echo = wu_echo()
    one = correct_inclined_array(echo, yaw=0.01, pitch=np.float64(0.02))
    per_pulse = correct_inclined_array(echo, yaw=[0.01] * echo.n_pulses, pitch=np.full(echo.n_pulses, 0.02))
    np.testing.assert_array_equal(one.data, per_pulse.data)


def test_dpca_finding_no_range_block_is_an_estimation_error():
    """Pings that do not correlate (independent noise) were a ValueError (and NumPy's "All-NaN
    slice" RuntimeWarning came first): now the EstimationError alone."""
    echo, array, speed, _ = dpca_small()
    rng = np.random.default_rng(5)
    noise = (rng.standard_normal(echo.data.shape) + 1j * rng.standard_normal(echo.data.shape)).astype(np.complex64)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(EstimationError, match="has no range block"):
            dpca.estimate(echo.replace(data=noise), array, speed, min_coherence=0.9)


@pytest.mark.parametrize("extent", [None, dpca.SeafloorExtent(x=(0.0, 200.0), z=-20.0, reach=0.5)])
def test_dpca_estimate_keeps_the_budget(extent):
    """Under 2.3 MB it allocated 19.5 MB (the x-lag table) without refusing; with an extent,
    look_moments' 4 MB tables were not counted."""
    echo, array, speed, _ = dpca_small()
    dpca.estimate(echo, array, speed, extent=extent)  # the process's cached tables built
    for limit in (int(2.3e6), 8 << 20):
        with clsas.use_memory_budget(limit):
            tracemalloc.start()
            try:
                dpca.estimate(echo, array, speed, extent=extent)
            except MemoryBudgetError:
                pass
            finally:
                peak = tracemalloc.get_traced_memory()[1]
                tracemalloc.stop()
        assert peak <= limit, (limit, peak)


@pytest.mark.parametrize("value", [None, 1, 1.5, True, 1j, "", "HAMMING"])
def test_a_choice_is_judged_by_membership(value):
    with pytest.raises(ValueError, match=r"^range_compress window: must be one of \('none', 'hamming'"):
        validate.choice("range_compress window", value, ("none", "hamming"))


@pytest.mark.parametrize("value", [None, 1.0, "a", object(), {"attrs": {}}])
def test_from_xarray_refuses_what_is_not_a_dataset_by_name(value):
    """These were AttributeErrors ('float' object has no attribute 'attrs')."""
    with pytest.raises(TypeError, match="^from_xarray ds: must be an xarray.Dataset"):
        clsas.from_xarray(value)
    with pytest.raises(TypeError, match="^to_xarray obj: must be an EchoData or an Image"):
        clsas.to_xarray(value)


def test_from_xarray_names_a_dataset_of_another_kind():
    ds = clsas.to_xarray(compressed())
    ds.attrs["clsas_kind"] = "Scenario"
    with pytest.raises(ValueError, match="^from_xarray ds: the dataset's clsas_kind attribute is 'Scenario'"):
        clsas.from_xarray(ds)


@pytest.mark.parametrize("name", [None, "", "cuda", 3])
def test_use_backend_names_its_parameter(name):
    """The message said "backend must be one of" without naming use_backend's ``name``."""
    with pytest.raises(ValueError, match=r"^use_backend name: the backend must be one of \('numpy', 'opencl'"):
        clsas.use_backend(name)
