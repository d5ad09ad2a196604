"""HDF5 save/load round trips of EchoData and Image."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from clsas import EchoData, Image, Medium, Waveform, io


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


@pytest.mark.parametrize("compressed", [False, True])
def test_echo_round_trip(tmp_path, rng, compressed):
    echo = _echo(rng, compressed)
    back = io.load(io.save(echo, tmp_path / "echo.h5"))
    assert isinstance(back, EchoData)
    np.testing.assert_array_equal(back.data, echo.data)
    for name in ("eta", "t0", "tx_pos", "rx_pos", "rx_tau"):
        np.testing.assert_array_equal(getattr(back, name), getattr(echo, name))
    assert back.fs == echo.fs and back.compressed == compressed
    assert back.waveform == echo.waveform and back.medium == echo.medium
    assert back.receivers == echo.receivers
    assert back.provenance == {"simulator": "test", "targets": [0, 1, 2], "nested": {"snr_db": 10.0}}


def test_echo_file_has_named_axes(tmp_path, rng):
    path = io.save(_echo(rng), tmp_path / "echo.h5")
    with h5py.File(path) as f:
        assert [d.label for d in f["data"].dims] == ["rx", "pulse", "sample"]
        assert f["data"].dims[1][0].name == "/eta"


def test_image_round_trip(tmp_path, rng):
    img = Image(data=rng.standard_normal((4, 6)) + 1j, dims=("y", "x"),
                axes={"y": np.linspace(-1, 1, 4), "x": np.linspace(10, 20, 6)},
                provenance={"algorithm": "test"}, positions=rng.standard_normal((4, 6, 3)))
    back = io.load(io.save(img, tmp_path / "img.h5"))
    np.testing.assert_array_equal(back.data, img.data)
    assert back.dims == ("y", "x")
    np.testing.assert_array_equal(back.axes["x"], img.axes["x"])
    np.testing.assert_array_equal(back.positions, img.positions)
    assert back.provenance == {"algorithm": "test"}
    with h5py.File(tmp_path / "img.h5") as f:
        assert [d.label for d in f["data"].dims] == ["y", "x"]


def test_bad_input(tmp_path):
    with pytest.raises(TypeError, match="EchoData or an Image"):
        io.save(np.zeros(3), tmp_path / "x.h5")
    with pytest.raises(FileNotFoundError):
        io.load(tmp_path / "missing.h5")
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["x"] = 1
    with pytest.raises(ValueError, match="not a clsas file"):
        io.load(tmp_path / "other.h5")
