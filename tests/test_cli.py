"""The clsas command: info and the end-to-end demo."""

from __future__ import annotations

import json

from clsas import cli


def test_info_prints_backend(capsys):
    assert cli.main(["info"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["resolved"] in ("numpy", "opencl")


def test_demo_runs_and_writes_its_files(tmp_path, capsys, opencl_device):
    assert cli.main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "demo OK" in out
    assert (tmp_path / "demo_echo.nc").is_file()
    assert (tmp_path / "demo_image.png").stat().st_size > 1000
