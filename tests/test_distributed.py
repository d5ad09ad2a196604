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


def _shallow_scene():
    """A platform 20 m below a flat sea surface over a sand seabed 50 m down (its mean plane
    reflects; its facets a 30 cm patch 150 m off), two receivers, one point in the water column:
    the bounce paths (D-B, B-D at about 100 m) arrive long after the direct one (about 50 m)."""
    floor = clsas.Seafloor((150.0, 150.3, -0.15, 0.15), -50.0, sediment="sand")
    scene = clsas.Scenario(clsas.Medium(1500.0), clsas.Waveform(f0=100e3, bandwidth=20e3, duration=2e-3, fs=25e3),
                           clsas.Platform(speed=2.0, start=(0.0, 0.0, -20.0)),
                           clsas.Array(rx_offsets=[[0.0, 0.0, 0.0], [0.0, 0.5, 0.0]]),
                           clsas.PulseSchedule(prf=5.0, n_pulses=6), seafloor=floor, surface=clsas.SeaSurface(0.0))
    return scene.replace(targets=(clsas.PointTargets([[45.0, 3.0, -32.0]]),))


@pytest.mark.parametrize("multipath", [1, 2])
def test_the_window_holds_the_bounces_of_a_seafloor_scene(client, multipath):
    """The workers' recording window spans every path simulate synthesizes (the seabed and
    surface bounces at the scenario's multipath order), not the direct paths alone: the echo,
    its window and its geometry are one process's, bit for bit (NumPy backend)."""
    scene = _shallow_scene()
    one = simulate(scene, backend="numpy", progress=False, multipath=multipath)
    direct = distributed.recording_window(scene, client, pulses_per_task=4, backend="numpy", multipath=0)
    assert int(np.max(one.provenance["n_valid"])) > int(np.max(direct.n_samples)) + 100  # the bounces come late
    got = distributed.simulate(scene, client, pulses_per_task=4, backend="numpy", multipath=multipath)
    _assert_same_echo(got, one)
    assert got.provenance["paths"] == one.provenance["paths"]


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


def test_a_failed_task_cancels_the_others_before_the_store_goes():
    """The review (session 4, H3): one task's error reached the caller, whose temporary store was
    then deleted, while the other tasks went on writing chunks into it. Now they are cancelled
    first (a stub client: the gather fails as dask's does when a task raises)."""
    from clsas.distributed import _gather

    class Client:
        cancelled = None

        def gather(self, futures):
            raise RuntimeError("task 0 failed")

        def cancel(self, futures):
            self.cancelled = list(futures)

    client = Client()
    with pytest.raises(RuntimeError, match="task 0 failed"):
        _gather(client, ["f0", "f1", "f2"])
    assert client.cancelled == ["f0", "f1", "f2"]


@pytest.mark.filterwarnings("ignore::clsas.scene.scenario.SamplingWarning")  # 6 pulses 10 m apart: enough here
@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_block_extents_are_simulates_window_on_a_seafloor(backend):
    """The recording window from pulse blocks is simulate's own, whatever the blocks: on a
    seafloor strip a narrow beam hears only part of, the blocks took every facet's delays
    (322 samples in one block, 192 in two, against simulate's 89: the review's H1); three blocks
    of two pulses ended 1 sample short while the window counted whole bands of facets (which
    bands depended on the facets a block drew) instead of the facets in the beam's reach."""
    floor = clsas.Seafloor((150.0, 150.3, -15.0, 15.0), -50.0, sediment="sand")
    scene = clsas.Scenario(clsas.Medium(1500.0), clsas.Waveform(f0=100e3, bandwidth=20e3, duration=2e-3, fs=25e3),
                           clsas.Platform(speed=4.0, start=(0.0, -10.0, -20.0)),
                           clsas.Array(rx_offsets=[[0.0, 0.0, 0.0]], tx_length=0.3, rx_length=0.3),
                           clsas.PulseSchedule(prf=0.4, n_pulses=6), seafloor=floor)
    one = simulate(scene, backend=backend, progress=False, multipath=0)
    fs = scene.waveform.fs
    for parts in ([(0, 6)], [(0, 3), (3, 6)], [(0, 2), (2, 4), (4, 6)], [(0, 2), (2, 5), (5, 6)]):
        ext = [distributed._block_extent(distributed.pulse_block(scene, a, b), backend, False, 0) for a, b in parts]
        window = distributed._window_of(scene, np.min([e[0] for e in ext], axis=0) / fs,
                                        np.max([e[1] for e in ext], axis=0) / fs)
        t0, n_samples = window.for_receivers(1)
        assert np.allclose(t0, one.t0) and list(n_samples) == list(one.provenance["n_valid"]), (parts, t0, n_samples)


def _strip_scene():
    """A narrow beam passing a seafloor strip: the first pulse (40 m before it) hears nothing."""
    floor = clsas.Seafloor((150.0, 150.3, -15.0, 15.0), -50.0, sediment="sand")
    return clsas.Scenario(clsas.Medium(1500.0), clsas.Waveform(f0=100e3, bandwidth=20e3, duration=2e-3, fs=25e3),
                          clsas.Platform(speed=4.0, start=(0.0, -10.0, -20.0)),
                          clsas.Array(rx_offsets=[[0.0, 0.0, 0.0]], tx_length=0.3, rx_length=0.3),
                          clsas.PulseSchedule(prf=0.4, n_pulses=6), seafloor=floor)


@pytest.mark.filterwarnings("ignore::clsas.scene.scenario.SamplingWarning")  # 6 pulses 10 m apart: enough here
def test_a_pulse_block_that_hears_nothing_is_silent(client, tmp_path):
    """A pulse block whose beam reaches none of the seafloor (and no target) records zeros, gathered
    or written by the workers, as one process records those pulses (it raised 'no seafloor'; the
    workers' store then lacked its all-zero chunk: zarr 3.1 ignores open_array's config=, so
    io.files.write.zarr_array did not write empty chunks); a run that hears nothing at all is
    refused, naming the seafloor."""
    scene = _strip_scene()
    one = simulate(scene, backend="numpy", progress=False, multipath=0)
    assert np.all(one.data[:, 0] == 0) and np.any(one.data[:, 1] != 0)
    gathered = distributed.simulate(scene, client, pulses_per_task=1, backend="numpy", multipath=0)
    stored = io.load(distributed.simulate(scene, client, pulses_per_task=1, backend="numpy", multipath=0,
                                          out=tmp_path / "echo.zarr", gather=False))
    for got in (gathered, stored):  # each block draws its own facets: same cells, another summation order
        assert got.data.shape == one.data.shape and np.array_equal(got.t0, one.t0)
        assert np.all(got.data[:, 0] == 0)
        assert _peak_error(got.data, one.data) < 1e-6  # measured 8.8e-8 (float32 records)
    silent = distributed.pulse_block(scene, 0, 1)
    with pytest.raises(ValueError, match=r"Scenario.seafloor \(extent .*\) lies outside the transmitter's beam"):
        distributed.simulate(silent, client, pulses_per_task=1, backend="numpy", multipath=0)
    with pytest.raises(ValueError, match=r"Scenario.seafloor \(extent .*\) lies outside the transmitter's beam"):
        simulate(silent, backend="numpy", progress=False, multipath=0)
