"""Progress bars count finished work; TQDM_DISABLE and progress=False are honoured; stages are logged."""

from __future__ import annotations

import logging

import numpy as np
import pyopencl as cl
import pytest

from clsas import Grid, backproject, progress, range_compress, simulate
from clsas.scene import presets


class _Event:
    """An OpenCL event stand-in: finishes when waited on (as an in-order queue's oldest launch)."""

    def __init__(self, done=False):
        self.done = done

    @property
    def command_execution_status(self):
        return cl.command_execution_status.COMPLETE if self.done else cl.command_execution_status.RUNNING

    def wait(self):
        self.done = True


def test_bar_counts_launches_when_they_finish(monkeypatch):
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    bar = progress.Progress(100, "pixel-pulses", "test")
    events = [_Event() for _ in range(progress.IN_FLIGHT)]
    for event in events:
        bar.after(event, 10)
    assert bar._bar.n == 0  # enqueued, none finished: nothing counted
    events[0].done = True
    bar.after(_Event(), 10)  # the finished oldest launch is counted, the rest wait
    assert bar._bar.n == 10
    bar.after(_Event(), 10)  # one over IN_FLIGHT: the host waits for the oldest
    assert bar._bar.n == 20 and events[1].done
    bar.close()
    assert bar._bar.n == 60
    assert bar._bar.unit == " pixel-pulses"


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
