"""clsas.distributed on a LocalCluster of 2 worker processes against one process.

Measured (heremans2009, 15 receivers, 10 pulses): NumPy backend bit for bit (echo with its
noise and geometry, image), whether the workers write the zarr store or the client gathers;
OpenCL echo within 1.0e-7 of the peak (float32 rounding), OpenCL image within 1.3e-4 of the
peak (each band's tile plan keeps its float32 geometry within the 2e-3 rad PHASE_BUDGET).
"""

from __future__ import annotations

import numpy as np
import pytest

import clsas
from clsas import Grid, Recording, backproject, distributed, io, range_compress, simulate
from clsas.scene import presets

dask_distributed = pytest.importorskip("dask.distributed")


@pytest.fixture(scope="module")
def client():
    with dask_distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                       memory_limit="2GiB") as cluster, dask_distributed.Client(cluster) as c:
        yield c


def _scene(n_pulses=10):
    return presets.point_scene("heremans2009", n_pulses=n_pulses)


def _grid(scene):
    return Grid.plane(np.linspace(94, 106, 48), np.linspace(-6, 6, 40), scene.platform.start[2])


def _peak_error(got, ref):
    return float(np.max(np.abs(got - ref)) / np.max(np.abs(ref)))


def _assert_same_echo(got, one):
    for name in ("data", "eta", "t0", "tx_pos", "rx_pos", "rx_tau"):
        np.testing.assert_array_equal(getattr(got, name), getattr(one, name), err_msg=name)
    assert clsas.scenario_to_toml(got.scenario) == clsas.scenario_to_toml(one.scenario)


def test_workers_write_the_store_as_one_process_would(client, tmp_path):
    """NumPy backend: pulse blocks written by the workers into echo.zarr (window and nodes
    derived from the workers' delays, noise added in the store by the client), image bands
    written by the workers into image.zarr; the echo gathered by the client too: all bit for bit."""
    scene = _scene()
    one = simulate(scene, backend="numpy", progress=False, snr_db=10, seed=4)
    path = distributed.simulate(scene, client, pulses_per_task=3, backend="numpy", snr_db=10, seed=4,
                                out=tmp_path / "echo.zarr", gather=False)
    got = io.load(path)
    assert got.provenance["distributed"] == {"tasks": 4, "pulses_per_task": 3, "written_by": "workers"}
    _assert_same_echo(got, one)
    gathered = distributed.simulate(scene, client, pulses_per_task=5, backend="numpy", snr_db=10, seed=4)
    assert gathered.provenance["distributed"]["written_by"] == "client"
    _assert_same_echo(gathered, one)
    echo = range_compress(one, upsample=4)
    ref = backproject(echo, _grid(scene), backend="numpy", upsample=1, progress=False).data
    image = distributed.backproject(echo, _grid(scene), client, rows_per_task=7, backend="numpy", upsample=1,
                                    out=tmp_path / "image.zarr")
    assert image.provenance["distributed"] == {"tasks": 6, "rows_per_task": 7, "written_by": "workers"}
    assert image.dims == ("y", "x")
    np.testing.assert_array_equal(image.data, ref)
    np.testing.assert_array_equal(image.positions, _grid(scene).positions)
    assert not list(tmp_path.glob(".*"))  # no temporary store left behind


@pytest.mark.slow
def test_two_workers_on_opencl(client, opencl_device):
    scene = _scene()
    one = simulate(scene, backend="opencl", progress=False)
    rec = scene.replace(recording=Recording(one.t0, np.array(one.provenance["n_valid"])))
    got = distributed.simulate(rec, client, pulses_per_task=3, backend="opencl")
    assert _peak_error(got.data, one.data) < 1e-6
    echo = range_compress(one, upsample=4)
    image = distributed.backproject(echo, _grid(scene), client, rows_per_task=7, backend="opencl", upsample=1)
    assert _peak_error(image.data, backproject(echo, _grid(scene), backend="opencl", upsample=1,
                                                progress=False).data) < 1.5e-3


def test_bad_arguments(tmp_path):
    scene = _scene(2)
    with pytest.raises(TypeError, match="dask.distributed.Client"):
        distributed.simulate(scene, object())
    with pytest.raises(TypeError, match="dask.distributed.Client"):
        distributed.backproject(None, None, "localhost")
    with pytest.raises(ValueError, match="block size must be an integer >= 1, got 0"):
        distributed._blocks(5, 0)
    with pytest.raises(ValueError, match=r"gather=False needs out=... ending in .zarr"):
        distributed.simulate(scene, _NoClient(), out=tmp_path / "echo.nc", gather=False)


class _NoClient:
    """Has a client's methods; a test that reaches them has not checked its arguments first."""

    def submit(self, *args, **kwargs):
        raise AssertionError("submitted work before checking the arguments")

    gather = scatter = submit
