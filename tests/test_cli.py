"""The clsas command, run as a user runs it (in a subprocess): workflow, info, errors, demo."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import clsas
from clsas import cli, io
from clsas.scene import presets

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _clsas(*args, env=None, cwd=None):
    full_env = dict(os.environ, TQDM_DISABLE="1", **(env or {}))
    return subprocess.run([sys.executable, "-m", "clsas", *args], capture_output=True, text=True, env=full_env,
                          cwd=cwd, timeout=300)


def test_version_and_plain_text_help(capsys):
    for args in (["--version"], ["--help"]):
        try:
            cli.main(args)
        except SystemExit as stop:
            assert stop.code == 0
    out = capsys.readouterr().out
    assert out.startswith("clsas ")
    for command in ("simulate", "image", "plot", "bench", "info", "reproduce"):
        assert command in out
    assert "``" not in out and ":func:" not in out
    from clsas import reproduce

    with pytest.raises(SystemExit):  # the papers' help lines are read from their sources, not imported
        cli.main(["reproduce", "--help"])
    out = capsys.readouterr().out
    for name in reproduce.paper_names():
        assert f"    {name}" in out and reproduce.summary(name)[:30] in out
    with pytest.raises(SystemExit):  # the paper named is imported, with its own options
        cli.main(["reproduce", "heremans2009", "--help"])
    assert "--pings" in capsys.readouterr().out


def test_info_prints_version_backend_device_and_its_source(opencl_device, capsys):
    assert cli.main(["info", "--check"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["resolved"] == "opencl" and info["device"] and info["clsas"]
    assert info["kernel_check"] == "ok" and info["opencl_source"]


def test_opencl_source_names_pip_or_the_distribution(monkeypatch):
    from clsas.cli import info

    debian = "OpenCL 3.0 PoCL 3.1+debian  Linux, None+Asserts, RELOC, SPIR, LLVM 15.0.6, SLEEF, DISTRO, POCL_DEBUG"
    pip = "OpenCL 3.0 PoCL 3.0-rc2  Linux, Release, RELOC, LLVM 14.0.6, SLEEF, DISTRO, POCL_DEBUG"
    assert info.opencl_source(debian) == "distribution package (pocl-opencl-icd)"
    monkeypatch.setattr(info.importlib.metadata, "version", lambda name: "3.0")
    assert info.opencl_source(pip) == "pip (pocl-binary-distribution 3.0)"
    assert info.opencl_source("OpenCL 1.2 CUDA 12.0") == "system ICD"


def test_mistakes_print_one_line_not_a_traceback(tmp_path, capsys, monkeypatch):
    out = _clsas("info", env={"CLSAS_BACKEND": "bogus"})  # as a user meets it: a fresh process
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.strip().splitlines() == ["clsas: error: the CLSAS_BACKEND environment variable must be one of "
                                               "('numpy', 'opencl', 'auto'), got 'bogus'"]
    existing = tmp_path / "file.txt"
    existing.write_text("x")
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text((EXAMPLES / "sphere_and_buoy.toml").read_text().replace("bandwidth = 20e3", "bandwidth = -2"))
    cases = [
        (["demo", "--out", str(existing)], "is an existing file"),
        (["simulate", "nosuch", "-o", str(tmp_path / "e.nc")], "unknown preset 'nosuch'"),
        (["simulate", "nosuch.toml", "-o", str(tmp_path / "e.nc")], "no such scenario file: nosuch.toml"),
        (["simulate", str(bad_toml), "-o", str(tmp_path / "e.nc")],
         "bad.toml: [waveform].bandwidth: must be in (0, 200000) Hz (0 < B < 2 f0), got -2 (line 12)"),
        (["image", str(existing), "-o", str(tmp_path / "i.nc")], "not a NetCDF4/HDF5 clsas file"),
        (["image", str(existing), "--grid", "1:0:1,0:1:1,0", "-o", str(tmp_path / "x.nc")],
         "need finite START < STOP"),  # the arguments before the file is read
        (["plot", str(tmp_path / "missing.nc")], "no such clsas file"),
    ]
    for args, message in cases:
        assert cli.main(args) == 2, args
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("clsas: error:") and message in err, err


def test_simulate_image_plot_workflow(tmp_path, opencl_device, monkeypatch):
    """The README's two commands as a user runs them (fresh processes: the entry point, exit
    status, output), then the other imagers, a TOML scenario and plot in this process through
    the same main() (a fresh process pays 3-10 s of imports and kernel builds)."""
    out = _clsas("simulate", "huang2022", "--pulses", "8", "--snr", "30", "--seed", "3", "-o", "echo.nc",
                 cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "32 receivers x 8 pulses" in out.stdout
    with xr.open_dataset(tmp_path / "echo.nc", engine="h5netcdf") as ds:
        assert ds["echo"].dims == ("rx", "pulse", "sample") and ds["eta"].attrs["units"] == "s"
        assert json.loads(ds.attrs["provenance"])["seed"] == 3
        assert ds.attrs["scenario"] == clsas.scenario_to_toml(presets.point_scene("huang2022", n_pulses=8))  # the whole scenario
    out = _clsas("image", "echo.nc", "--algorithm", "omegak", "-o", "wk.zarr", "--png", "wk.png", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "elements from the file's scenario: L_tx = 0.08 m, L_rx = 0.04 m" in out.stdout
    assert io.load(tmp_path / "wk.zarr").dims == ("y", "x") and (tmp_path / "wk.png").stat().st_size > 10_000
    monkeypatch.chdir(tmp_path)
    assert cli.main(["--no-progress", "image", "echo.nc", "--algorithm", "bp", "--grid", "38:42:0.05,-2.5:2.5:0.05,0",
                     "-o", "bp.nc", "--png", "bp.png"]) == 0
    image = io.load(tmp_path / "bp.nc")
    assert image.shape == (100, 80) and (tmp_path / "bp.png").stat().st_size > 10_000
    peak = np.unravel_index(np.argmax(np.abs(image.data)), image.shape)
    assert abs(image.axes["x"][peak[1]] - 40) < 0.1  # the near row of points
    assert cli.main(["--no-progress", "image", "echo.nc", "-a", "ffbp", "--grid", "39.5:40.5:0.05,1.5:2.5:0.05,0",
                     "-o", "ffbp.nc"]) == 0
    assert io.load(tmp_path / "ffbp.nc").shape == (20, 20)
    assert cli.main(["plot", "echo.nc"]) == 0
    assert (tmp_path / "echo.png").stat().st_size > 10_000
    scene = EXAMPLES / "huang2022_points.toml"
    assert cli.main(["--no-progress", "simulate", str(scene), "--pulses", "4", "-o", "toml.nc"]) == 0
    echo = io.load(tmp_path / "toml.nc")
    assert echo.n_rx == 32 and echo.n_pulses == 4 and echo.scenario.schedule.n_pulses == 4
    assert clsas.scenario_to_toml(echo.scenario) == clsas.scenario_to_toml(clsas.load_scenario(scene).replace(schedule=echo.scenario.schedule))


def test_demo_runs_and_writes_its_files(tmp_path, capsys, opencl_device):
    """``make demo``'s command; its files reload and its picture is written."""
    assert cli.main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "demo OK" in out
    assert io.load(tmp_path / "demo_echo.nc").compressed
    assert (tmp_path / "demo_image.png").stat().st_size > 1000


def _workdir_with_an_echo(tmp_path):
    """A small echo file (4 pulses) in ``tmp_path``, made through the API (no subprocess)."""
    echo = clsas.simulate(presets.point_scene("heremans2009", n_pulses=4), progress=False, backend="numpy")
    io.save(echo, tmp_path / "s.nc")
    return tmp_path / "s.nc"


def test_window_reaches_the_strip_map_imagers_and_ncs_images(tmp_path, capsys, monkeypatch):
    """--window weights the strip-map imagers' processed band (and, for rda/csa/ncs on raw
    echoes, the range compression; omega-k weights range in its own band); --algorithm ncs is
    nonlinear chirp scaling: each image is the API's, bit for bit (NumPy backend)."""
    from clsas.image.multireceiver import pca_record

    source = io.save(clsas.simulate(presets.point_scene("huang2022", n_pulses=8), progress=False), tmp_path / "s.nc")
    monkeypatch.chdir(tmp_path)
    raw = io.load(source)
    array = raw.scenario.array
    elements = (float(array.tx_length), float(array.rx_length.max()))
    cases = [("ncs", "hamming", clsas.nonlinear_chirp_scaling, "hamming"), ("omegak", "taylor", clsas.omega_k, "none"),
             ("rda", "kaiser", clsas.range_doppler, "kaiser"), ("ncs", None, clsas.nonlinear_chirp_scaling, "none")]
    for algorithm, window, imager, range_window in cases:
        out = f"{algorithm}-{window}.nc"
        assert cli.main(["--no-progress", "image", "s.nc", "-a", algorithm, *(["--window", window] if window else []),
                         "--backend", "numpy", "-o", out]) == 0
        printed = capsys.readouterr().out
        assert (f", {window} window" in printed) == (window is not None), printed
        record = pca_record(clsas.range_compress(raw, window=range_window), backend="numpy")
        expected = imager(record, elements=elements, window=window or "none", backend="numpy")
        got = io.load(tmp_path / out)
        np.testing.assert_array_equal(got.data, expected.data, err_msg=f"{algorithm} {window}")
        assert got.provenance["window"] == (window or "none")
    compressed = clsas.range_compress(raw)
    io.save(compressed, tmp_path / "rc.nc")
    assert cli.main(["--no-progress", "image", "rc.nc", "-a", "csa", "--window", "hamming", "--backend", "numpy",
                     "-o", "csa.nc"]) == 0
    expected = clsas.chirp_scaling(pca_record(compressed, backend="numpy"), elements=elements, window="hamming",
                                   backend="numpy")
    np.testing.assert_array_equal(io.load(tmp_path / "csa.nc").data, expected.data)
    capsys.readouterr()
    assert cli.main(["--no-progress", "image", "rc.nc", "-a", "bp", "--window", "hamming", "-o", "bp.nc"]) == 2
    assert "already range-compressed; --window applies to raw echoes with --algorithm bp" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse: one of the windows
        cli.main(["image", "s.nc", "-a", "ncs", "--window", "blackman", "-o", "x.nc"])
    assert "invalid choice: 'blackman'" in capsys.readouterr().err


def test_outputs_are_checked_before_any_work_and_never_replace_the_input(tmp_path, capsys, monkeypatch):
    """The issue's CLI reproducers, each one line and exit status 2, nothing written."""
    source = _workdir_with_an_echo(tmp_path)
    monkeypatch.chdir(tmp_path)
    before = source.read_bytes()
    long_name = "a" * 300 + ".nc"
    (tmp_path / "taken.nc").write_bytes(b"x")
    os.mkfifo(tmp_path / "pipe.nc")
    cases = [
        (["image", "s.nc", "-a", "omegak", "-o", "s.nc"], "-o s.nc: that is the input file; clsas never writes over"),
        (["image", "s.nc", "-a", "omegak", "-o", "./sub/../s.nc"], "that is the input file"),
        (["image", "s.nc", "-a", "omegak", "-o", "s.nc", "--overwrite"], "that is the input file"),
        (["image", "s.nc", "-o", "x.txt"], "-o: 'x.txt' must end in .nc, .nc4, .h5 (NetCDF4) or .zarr"),
        (["image", "s.nc", "-o", long_name], "-o: the file name is 303 bytes long"),
        (["image", "s.nc", "-o", "i.nc", "--png", "s.nc/x.png"], "--png: the folder 's.nc' is a file, not a folder"),
        (["image", "s.nc", "-o", "/nonexistent/i.nc"], "-o: the folder '/nonexistent' does not exist"),
        (["image", "s.nc", "-o", "taken.nc"], "-o: 'taken.nc' exists; give --overwrite"),
        (["image", "s.nc", "--png", "x.bmp"], "--png: 'x.bmp' must end in .png, .pdf, .svg"),
        (["image", "s.nc", "-o", "i.nc", "--png", "i.nc"], "--png i.nc: -o writes that file already"),
        (["image", "pipe.nc", "-o", "j.nc"], "pipe.nc: not a regular file or a zarr store"),
        (["simulate", "heremans2009", "--pulses", "2", "-o", "taken.nc"], "-o: 'taken.nc' exists; give --overwrite"),
        (["simulate", "heremans2009", "--pulses", "2", "-o", "x.txt"], "must end in .nc"),
        (["plot", "s.nc", "-o", "s.nc"], "that is the input file"),
        (["plot", "s.nc", "-o", "/nonexistent/x.png"], "-o: the folder '/nonexistent' does not exist"),
        (["plot", "s.nc", "--floor", "nan"], "--floor: must be a number of dB"),
        # the fresh-clone trial (session 4): options that did nothing, or failed only after the work
        (["image", "s.nc", "-o", "e.nc", "--elements", "a,b"], "--elements applies to --algorithm omegak, rda"),
        (["image", "s.nc", "-a", "omegak", "-o", "e.nc", "--elements", "a,b"], "--elements: expected LTX,LRX"),
        (["image", "s.nc", "-a", "omegak", "-o", "e.nc", "--elements", "0,nan"], "must be finite and > 0 m"),
        (["image", "s.nc", "-a", "omegak", "-o", "e.nc", "--grid", "1:2:1,0:1:1,0"], "--grid applies to"),
        (["image", "s.nc", "-o", "e.nc", "--grid", "1e300:2e300:1e299,0:1:1,0"],
         "--grid 1e300:2e300:1e299,0:1:1,0: Grid.plane x: must be within"),
        (["demo", "-o", "/nonexistent/demo"], "the folder /nonexistent does not exist"),
        (["reproduce", "wu2018", "--json", "taken.nc"], "--json: 'taken.nc' must end in .json"),
        (["reproduce", "wu2018", "--json", "/nonexistent/r.json"], "--json: the folder '/nonexistent' does not exist"),
    ]
    for args, message in cases:
        assert cli.main(["--no-progress", *args]) == 2, args
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("clsas: error:") and message in err, (args, err)
        assert ".clsas-tmp" not in err
    assert source.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe.nc", "s.nc", "taken.nc"]


def test_overwrite_replaces_and_plot_takes_o(tmp_path, capsys, monkeypatch):
    _workdir_with_an_echo(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["plot", "s.nc", "-o", "p.png"]) == 0
    assert cli.main(["plot", "s.nc", "-o", "p.png"]) == 2
    assert "give --overwrite" in capsys.readouterr().err
    first = (tmp_path / "p.png").stat().st_mtime_ns
    assert cli.main(["plot", "s.nc", "-o", "p.png", "--floor", "-30", "--overwrite"]) == 0
    assert (tmp_path / "p.png").stat().st_mtime_ns >= first
    assert cli.main(["plot", "s.nc", "--png", "q.svg"]) == 0 and (tmp_path / "q.svg").stat().st_size > 1000
    assert not [p for p in tmp_path.iterdir() if ".clsas-tmp" in p.name]


def test_a_reproductions_json_is_replaced_only_with_overwrite(tmp_path, capsys, monkeypatch):
    """`clsas reproduce wu2018 --json mine.txt` wrote over a user's file after the whole run (the
    fresh-clone trial, session 4): its --json is now checked first, as every output is."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "r.json").write_text("mine")
    assert cli.main(["reproduce", "wu2018", "--json", "r.json"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--json: 'r.json' exists; give --overwrite to replace it" in err, err
    assert (tmp_path / "r.json").read_text() == "mine"
    argv = ["reproduce", "wu2018", "--json", "r.json", "--overwrite"]
    args = cli.build_parser(argv).parse_args(argv)
    assert cli._reproduce(lambda a: 7, args) == 7  # the reproduction runs (and its write_json replaces the file)


def test_simulate_refuses_a_cube_over_the_budget_up_front(tmp_path):
    """The issue's 10.5 GiB cube (huang2022, 2048 pulses) under a 10 GiB budget: refused after
    the delays, before the cube is allocated, in one line; nothing is written."""
    out = _clsas("simulate", "huang2022", "--pulses", "2048", "-o", "keep.nc", cwd=tmp_path,
                 env={"CLSAS_MEMORY_BUDGET": "10G"})
    assert out.returncode == 2
    assert out.stderr.startswith("clsas: error: the echo cube would need 10.3 GiB".replace("10.3", "10.27"))
    assert "lower --pulses or raise CLSAS_MEMORY_BUDGET" in out.stderr and out.stderr.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_prints_one_line_and_exits_130(tmp_path):
    """SIGINT while `clsas simulate` works: `clsas: interrupted`, status 130, no file left."""
    import signal
    import time

    child = subprocess.Popen([sys.executable, "-m", "clsas", "-v", "--no-progress", "simulate", "huang2022",
                              "--pulses", "4096", "-o", "big.nc", "--backend", "numpy"], cwd=tmp_path,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=dict(os.environ, CLSAS_MEMORY_BUDGET="64G"))
    try:
        seen = []
        while not any("echo delays" in line for line in seen):  # the work has started
            seen.append(child.stderr.readline())
            assert seen[-1] or child.poll() is None, "".join(seen)
        time.sleep(0.5)
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=120)
    finally:
        if child.poll() is None:
            child.kill()
    assert child.returncode == 130, err
    assert err.strip().splitlines()[-1] == "clsas: interrupted" and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, message", [(["reproduce", "kiang2022", "--cases", "99"], "--cases must be among"),
                                           (["reproduce", "heremans2009", "--pings", "0"], "--pings must be >= 8")])
def test_a_reproduction_refusing_its_options_ends_in_one_error_line(capsys, args, message):
    """The reproductions refuse their options with SystemExit("message"): that was status 1 and a
    bare line; now the one "clsas: error:" line and status 2 of every other command."""
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("clsas: error:") and message in err, err

