"""Progress bars count finished work; TQDM_DISABLE and progress=False are honoured; stages are logged."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from clsas import Grid, backproject, progress, range_compress, simulate
from clsas.scene import presets


def test_backprojection_bar_counts_finished_pixel_pulses(opencl_device, monkeypatch):
    """The OpenCL bar is counted as each upload block's kernels complete (their events are
    waited on first) and ends at pixels x receivers x pulses, in pixel-pulses."""
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    bars, counted = [], []
    original = progress.Progress.done

    def done(self, n):
        counted.append(n)
        original(self, n)

    monkeypatch.setattr(progress.Progress, "done", done)
    monkeypatch.setattr(progress.Progress, "close", lambda self: self._bar is not None and bars.append(self._bar))
    scene = presets.point_scene("heremans2009", n_pulses=8)
    echo = range_compress(simulate(scene, backend="numpy", progress=False))
    grid = Grid.plane(np.linspace(99, 101, 16), np.linspace(-1, 1, 8), scene.platform.start[2])
    counted.clear()
    backproject(echo, grid, backend="opencl")
    (bar,) = bars
    assert bar.unit == " pixel-pulses" and bar.n == bar.total == 128 * 15 * 8 == sum(counted)
    bar.close()


@pytest.mark.parametrize("env, flag", [("1", True), ("", False)])
def test_bars_off_with_tqdm_disable_or_progress_false(monkeypatch, env, flag):
    monkeypatch.setenv("TQDM_DISABLE", env)
    assert progress.Progress(10, "pulses", "x", progress=flag)._bar is None


def test_stage_logs_sizes_estimate_and_time(caplog):
    with caplog.at_level(logging.INFO, logger="clsas"):
        with progress.stage("long thing", "4096 x 4096 pixels", work=1e12, rate=1e9):
            pass
        with progress.stage("short thing", "8 pixels", work=8, rate=1e9):
            pass
    messages = [(r.levelname, r.getMessage()) for r in caplog.records]
    assert messages[0] == ("WARNING", "long thing: 4096 x 4096 pixels; estimated 16.7 min")
    assert messages[1][0] == "INFO" and messages[1][1].startswith("long thing: done in")
    assert messages[2] == ("INFO", "short thing: 8 pixels; estimated 8e-09 s")


def test_simulate_and_backproject_log_their_stages(backend, caplog, capsys, monkeypatch):
    monkeypatch.setenv("TQDM_DISABLE", "1")
    scene = presets.point_scene("heremans2009", n_pulses=8)
    with caplog.at_level(logging.INFO, logger="clsas"):
        echo = range_compress(simulate(scene, backend=backend))
        backproject(echo, Grid.plane(np.linspace(99, 101, 16), np.linspace(-1, 1, 8), scene.platform.start[2]),
                    backend=backend)
    text = "\n".join(r.getMessage() for r in caplog.records)
    assert f"echo synthesis ({backend}): 15 receivers x 8 pulses x" in text
    assert f"back-projection ({backend}, linear): 128 pixels x 15 receivers x 8 pulses" in text
    assert text.count("done in") >= 3
    assert capsys.readouterr().err == ""  # TQDM_DISABLE: no bar


def test_ffbp_bar_counts_pulses_through_the_first_stage_and_logs(backend, caplog, monkeypatch):
    """ffbp's bar ends at the echo's pulses (counted as each leaf's image is formed), honours
    TQDM_DISABLE through clsas.progress, and its stage is logged with the tree's sizes."""
    from clsas import ffbp

    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    bars, counted = [], []
    original = progress.Progress.done
    monkeypatch.setattr(progress.Progress, "done",  # the bars of the leaves' own back-projections are off
                        lambda self, n: (self._bar is not None and counted.append(n), original(self, n)))
    monkeypatch.setattr(progress.Progress, "close", lambda self: self._bar is not None and bars.append(self._bar))
    scene = presets.point_scene("heremans2009", n_pulses=128)
    echo = range_compress(simulate(scene, backend="numpy", progress=False))
    grid = Grid.plane(np.linspace(98, 102, 32), np.linspace(-4, 4, 32), scene.platform.start[2])
    counted.clear()
    with caplog.at_level(logging.INFO, logger="clsas"):
        image = ffbp(echo, grid, first=8, backend=backend)
    (bar,) = bars
    assert bar.unit == " pulse" and bar.n == bar.total == 128 == sum(counted) and len(counted) == 16
    bar.close()
    levels = image.provenance["levels"]
    assert f"ffbp ({backend}): 1024 pixels x 128 pulses x 15 receivers, {levels} levels" in caplog.text
    assert "ffbp: done in" not in caplog.text and f"ffbp ({backend}): done in" in caplog.text
