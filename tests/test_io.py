"""clsas files: NetCDF4 / zarr round trips, what xarray sees, atomic save, validated load."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr

import clsas
from clsas import EchoData, Grid, Image, Medium, Platform, Waveform, io, load_scenario
from clsas.errors import DataFileError, MemoryBudgetError
from clsas.io.toml import scenario_from_toml

SUFFIXES = [".nc", ".zarr"]
ENGINES = {".nc": "h5netcdf", ".zarr": "zarr"}


def _echo(rng, compressed=False):
    n_rx, n_p, n_s, nodes = 3, 5, 64, 2
    return EchoData(
        data=(rng.standard_normal((n_rx, n_p, n_s)) + 1j * rng.standard_normal((n_rx, n_p, n_s))),
        eta=np.arange(n_p) / 10.0, t0=[0.1, 0.2, 0.3], fs=40e3, tx_pos=rng.standard_normal((n_p, 3)),
        rx_pos=rng.standard_normal((n_rx, n_p, nodes, 3)), rx_tau=[[0.1, 0.2], [0.2, 0.3], [0.3, 0.4]],
        waveform=Waveform(f0=100e3, bandwidth=20e3, duration=5e-3, fs=40e3, chirp_sign=-1),
        medium=Medium(1510.0), receivers=("A", "B", "C"), compressed=compressed,
        provenance={"simulator": "test", "targets": np.arange(3), "nested": {"snr_db": 10.0}},
    )


def _plane_image(rng):
    grid = Grid.plane(np.linspace(10, 20, 6), np.linspace(-1, 1, 4) / 3, -3.1)
    return Image(data=rng.standard_normal(grid.shape) + 1j * rng.standard_normal(grid.shape), dims=grid.dims,
                 axes=grid.axes, positions=grid.positions, provenance={"algorithm": "test"})


def _slant_image(rng):
    grid = Grid.slant((40, 0, -5), (0.8, 0, -0.6), (0, 1, 0), np.linspace(0, 1, 5), np.linspace(-1, 1, 3))
    return Image(data=rng.standard_normal(grid.shape) + 1j, dims=grid.dims, axes=grid.axes,
                 positions=grid.positions, provenance={"algorithm": "slant"})


def _assert_same_echo(back, echo):
    assert isinstance(back, EchoData)
    for name in ("data", "eta", "t0", "tx_pos", "rx_pos", "rx_tau"):
        np.testing.assert_array_equal(getattr(back, name), getattr(echo, name))
    assert back.data.dtype == np.complex64
    assert back.fs == echo.fs and back.compressed == echo.compressed
    assert back.waveform == echo.waveform and back.medium == echo.medium
    assert back.receivers == echo.receivers


@pytest.mark.parametrize("suffix", SUFFIXES)
@pytest.mark.parametrize("compressed", [False, True])
def test_echo_round_trip_is_exact(tmp_path, rng, suffix, compressed):
    echo = _echo(rng, compressed)
    back = io.load(io.save(echo, tmp_path / f"echo{suffix}"))
    _assert_same_echo(back, echo)
    assert back.provenance == {"simulator": "test", "targets": [0, 1, 2], "nested": {"snr_db": 10.0}}


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_uncompressed_files_round_trip(tmp_path, rng, suffix):
    echo = _echo(rng)
    _assert_same_echo(io.load(io.save(echo, tmp_path / f"raw{suffix}", compression=0)), echo)
    with pytest.raises(ValueError, match=r"save compression: must be an integer in \[0, 9\] \(a gzip level\), got 10"):
        io.save(echo, tmp_path / f"raw{suffix}", compression=10)


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_xarray_opens_an_echo_file_with_named_united_coordinates(tmp_path, rng, suffix):
    echo = _echo(rng)
    path = io.save(echo, tmp_path / f"echo{suffix}")
    with xr.open_dataset(path, engine=ENGINES[suffix]) as ds:
        assert ds["echo"].dims == ("rx", "pulse", "sample")
        assert list(ds["rx"].values) == ["A", "B", "C"]
        np.testing.assert_array_equal(ds["eta"].values, echo.eta)
        np.testing.assert_array_equal(ds["tau"].values[1], echo.fast_time(1))
        for dim in ds.dims:
            assert dim in ds.coords
        for name, var in ds.variables.items():
            assert "long_name" in var.attrs, name
            if var.dtype.kind not in "OUS":
                assert "units" in var.attrs, name
        assert ds["eta"].attrs["units"] == "s" and ds["tx_pos"].attrs["units"] == "m"
        assert json.loads(ds.attrs["provenance"])["simulator"] == "test"
        assert clsas.from_xarray(ds).receivers == ("A", "B", "C")


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_plane_image_stores_axes_not_positions(tmp_path, rng, suffix):
    img = _plane_image(rng)
    path = io.save(img, tmp_path / f"img{suffix}")
    with xr.open_dataset(path, engine=ENGINES[suffix]) as ds:
        assert "positions" not in ds.variables
        assert ds["image"].dims == ("y", "x")
        assert ds["x"].attrs["units"] == "m" and "across-track" in ds["x"].attrs["long_name"]
        assert float(ds["z"]) == -3.1
    back = io.load(path)
    np.testing.assert_array_equal(back.data, img.data)
    np.testing.assert_array_equal(back.positions, img.positions)
    assert back.dims == ("y", "x") and back.provenance == {"algorithm": "test"}


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_slant_image_keeps_its_positions(tmp_path, rng, suffix):
    img = _slant_image(rng)
    path = io.save(img, tmp_path / f"img{suffix}")
    with xr.open_dataset(path, engine=ENGINES[suffix]) as ds:
        assert ds["positions"].dims == ("v", "u", "xyz") and ds["positions"].attrs["units"] == "m"
    back = io.load(path)
    np.testing.assert_array_equal(back.positions, img.positions)
    np.testing.assert_array_equal(back.axes["u"], img.axes["u"])


def test_image_without_positions(tmp_path, rng):
    img = Image(data=rng.standard_normal((3, 4)) + 0j, dims=("eta", "tau"),
                axes={"eta": np.arange(3.0), "tau": np.arange(4) * 1e-5})
    back = io.load(io.save(img, tmp_path / "t.nc"))
    assert back.positions is None
    with xr.open_dataset(tmp_path / "t.nc") as ds:
        assert ds["tau"].attrs["units"] == "s"


def test_repr_is_short(rng):
    echo = _echo(rng)
    assert len(repr(echo)) < 300 and "3 rx x 5 pulses x 64 samples" in repr(echo)
    assert len(repr(_plane_image(rng))) < 300


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_failed_save_leaves_the_old_file_intact(tmp_path, rng, suffix, monkeypatch):
    echo = _echo(rng)
    path = io.save(echo, tmp_path / f"r{suffix}")
    with pytest.raises(TypeError, match="cannot store a object"):
        io.save(echo.replace(provenance={"x": object()}), path)
    with pytest.raises(ValueError, match="cannot name a variable"):
        io.save(Image(data=np.ones((2, 2)), dims=("a/b", "c"), axes={"a/b": [0, 1], "c": [0, 1]}), path)

    def broken(ds, target, level):  # a write that dies part-way (disk full, killed process)
        original(ds, target, level)
        raise OSError(f"No space left on device: {target}")

    original = io.files.write.write
    monkeypatch.setattr(io.files.write, "write", broken)
    with pytest.raises(OSError, match="No space") as caught:
        io.save(_echo(np.random.default_rng(7)), path)
    assert str(path) in str(caught.value) and "clsas-tmp" not in str(caught.value)  # the target, not the temporary
    monkeypatch.undo()
    _assert_same_echo(io.load(path), echo)
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"r{suffix}"]  # no temporary left behind


def test_truncated_foreign_and_huge_files_raise_data_file_error(tmp_path, rng):
    path = io.save(_echo(rng), tmp_path / "e.nc")
    raw = path.read_bytes()
    for cut in (4, 200, len(raw) // 2):
        (tmp_path / "cut.nc").write_bytes(raw[:cut])
        with pytest.raises(DataFileError, match="cut.nc"):
            io.load(tmp_path / "cut.nc")
    (tmp_path / "text.nc").write_text("hello")
    with pytest.raises(DataFileError, match="text.nc: not a NetCDF4/HDF5"):
        io.load(tmp_path / "text.nc")
    (tmp_path / "empty.nc").write_bytes(b"")
    with pytest.raises(DataFileError, match="empty"):
        io.load(tmp_path / "empty.nc")
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["x"] = 1
    with pytest.raises(DataFileError, match="not a clsas file"):
        io.load(tmp_path / "other.h5")
    with h5py.File(tmp_path / "huge.h5", "w") as f:  # 0.1 layout declaring 128 TiB, nothing written
        f.attrs["kind"] = "EchoData"
        f.create_dataset("data", shape=(2**17, 2**17, 2**10), dtype=np.complex64, chunks=(1, 1, 1024))
    with pytest.raises(MemoryBudgetError, match="huge.h5: its arrays declare 1.31e\\+05 GiB"):
        io.load(tmp_path / "huge.h5")
    with clsas.use_memory_budget(1000), pytest.raises(MemoryBudgetError, match="e.nc: its arrays declare .* over the "
                                                                               "memory budget of 1000 bytes"):
        io.load(path)
    with pytest.raises(FileNotFoundError):
        io.load(tmp_path / "missing.nc")
    with pytest.raises(TypeError, match="save obj: must be an EchoData or an Image"):
        io.save(np.zeros(3), tmp_path / "x.nc")


def test_wrong_structure_names_what_is_missing(tmp_path, rng):
    ds = clsas.to_xarray(_echo(rng)).drop_vars("rx_pos")
    ds.to_netcdf(tmp_path / "partial.nc", engine="h5netcdf")
    with pytest.raises(DataFileError, match=r"partial.nc: the EchoData dataset lacks \['rx_pos'\]"):
        io.load(tmp_path / "partial.nc")


def _save_v01(obj, path):
    """clsas 0.1's writer (h5py, /data with dimension scales), kept to test reading old files."""
    with h5py.File(path, "w") as f:
        f.attrs["provenance"] = json.dumps({"algorithm": "old"})
        f.create_dataset("data", data=obj.data)
        if isinstance(obj, EchoData):
            f.attrs.update(kind="EchoData", fs=obj.fs, compressed=obj.compressed,
                           receivers=json.dumps(list(obj.receivers)),
                           waveform=json.dumps(obj.waveform.__dict__), medium=json.dumps(obj.medium.__dict__))
            for name in ("eta", "t0", "tx_pos", "rx_pos", "rx_tau"):
                f.create_dataset(name, data=getattr(obj, name))
        else:
            f.attrs.update(kind="Image", dims=json.dumps(list(obj.dims)))
            for name in obj.dims:
                f.create_dataset(f"axes/{name}", data=obj.axes[name])
            f.create_dataset("positions", data=obj.positions)


def test_files_of_clsas_0_1_still_load(tmp_path, rng):
    echo, img = _echo(rng), _plane_image(rng)
    _save_v01(echo, tmp_path / "old_echo.h5")
    _save_v01(img, tmp_path / "old_image.h5")
    _assert_same_echo(io.load(tmp_path / "old_echo.h5"), echo)
    back = io.load(tmp_path / "old_image.h5")
    np.testing.assert_array_equal(back.positions, img.positions)
    assert back.provenance == {"algorithm": "old"}
    io.save(back, tmp_path / "new.nc")  # the conversion the module docstring gives
    with h5py.File(tmp_path / "old_echo.h5", "a") as f:
        del f["rx_tau"]
    with pytest.raises(DataFileError, match="old_echo.h5: a clsas 0.1 HDF5 file with a missing"):
        io.load(tmp_path / "old_echo.h5")


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_echo_files_carry_the_whole_scenario(tmp_path, rng, suffix, caplog):
    """The scenario (here every part of the TOML schema, a mesh included) is stored as TOML text
    in the attribute ``scenario`` and rebuilt on load; one TOML cannot hold is left out, saying why."""
    scenario = load_scenario(Path(__file__).resolve().parents[1] / "examples" / "sphere_and_buoy.toml")
    path = io.save(_echo(rng).replace(scenario=scenario), tmp_path / f"echo{suffix}")
    back = io.load(path)
    assert clsas.scenario_to_toml(back.scenario) == clsas.scenario_to_toml(scenario) and back.scenario.targets[1].n_facets == 320
    with xr.open_dataset(path, engine=ENGINES[suffix]) as ds:
        assert scenario_from_toml(ds.attrs["scenario"]).receiver_names == ("h0", "h1", "h2", "h3", "buoy")
    wobbly = scenario.replace(platform=Platform(speed=1.0, sway=lambda t: 0 * t))
    with caplog.at_level("WARNING", logger="clsas"):
        back = io.load(io.save(_echo(rng).replace(scenario=wobbly), tmp_path / f"wobbly{suffix}"))
    assert back.scenario is None and "Platform.sway is a Python function" in caplog.text
    with pytest.raises(TypeError, match="EchoData.scenario must be a Scenario or None, got str"):
        _echo(rng).replace(scenario="scene.toml")
