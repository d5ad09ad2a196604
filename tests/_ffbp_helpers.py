"""Scenes, references and the keep_plans fixture shared by the ffbp tests (test_ffbp*.py).

Scenes: Huang & Yang 2022's 32-receiver sonar (150 kHz, B = 20 kHz, 0.08 m transmitter, 0.04 m
receivers) 10 m above a seafloor plane, a 5 x 5 grid of points 0.75 m apart 42.5-45.5 m across track
and four points near the grid's corners (0.15 m in); on a straight track, with sway 0.1 m and yaw 1 degree,
and on an arc of a circle; and a speckle scene of random scatterers. _geometry_only_echo: bench_ffbp's
monostatic sonar with records that take no memory (what ffbp's plan needs, not its data).

keep_plans is not autouse (a conftest autouse fixture would reach every test file): a module that wants
it imports it and names it in ``pytestmark = pytest.mark.usefixtures("keep_plans")``.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

import clsas
from clsas import Medium, Waveform, metrics
from clsas.model import EchoData, Grid, Image
from clsas.image.backprojection import backproject
from clsas.image.ffbp import reuse
from clsas.scene import presets
from clsas.scene.targets import PointTargets

DEPTH = -10.0


POINTS = np.array([[x, y, DEPTH] for x in (42.5, 43.25, 44.0, 44.75, 45.5) for y in (-1.5, -0.75, 0.0, 0.75, 1.5)]
                  + [[42.15, -1.85, DEPTH], [45.85, 1.85, DEPTH], [42.15, 1.85, DEPTH], [45.85, -1.85, DEPTH]])


GRID = Grid.plane(np.arange(42.0, 46.0, 0.015), np.arange(-2.0, 2.0, 0.02), DEPTH)


RANGE_CELL = 1500.0 / (2 * 20e3)


N_PULSES = 20


@pytest.fixture
def keep_plans(request, monkeypatch):
    """Every call plans its tree and lays out its first stage anew (nothing kept between calls,
    reuse.KEEP_PLANS off), so that what a test patches takes effect on its second call; tests
    parametrized with ``keep_plans`` True (KEEPING) run with it on, the default path (what was kept
    before let go first, so each such test makes and then uses its own)."""
    keep = getattr(request, "param", False)
    monkeypatch.setattr(reuse, "KEEP_PLANS", keep)
    if keep:
        reuse.release()
    return keep


KEEPING = pytest.mark.parametrize("keep_plans", [False, True], indirect=True, ids=["afresh", "kept"])


def sonar(n_pulses: int = N_PULSES, **platform):
    sc = presets.huang2022(n_pulses=n_pulses)
    return sc.replace(platform=dataclasses.replace(sc.platform, **platform))


@functools.cache
def echo_of(track: str, targets: str = "points"):
    if track == "straight":
        sc = sonar()
    elif track == "motion":  # sway 0.1 m and yaw 1 degree over the aperture, surge 2 cm
        period = 6.0
        sc = sonar(sway=lambda t: 0.1 * np.sin(2 * np.pi * t / period),
                   yaw=lambda t: np.deg2rad(1.0) * np.sin(2 * np.pi * t / period + 1.0),
                   surge=lambda t: 0.02 * np.sin(2 * np.pi * t / 3.0))
    else:  # an arc of a circle of radius 80 m turning towards the scene (heading turns with it)
        radius, speed = 80.0, sonar().platform.speed
        sc = sonar(sway=lambda t: radius * (1 - np.cos(speed * t / radius)),
                   surge=lambda t: radius * np.sin(speed * t / radius) - speed * t,
                   yaw=lambda t: speed * t / radius)
    if targets == "points":
        tg = PointTargets(POINTS)
    else:
        rng = np.random.default_rng(7)
        n = 3000
        pos = np.column_stack([rng.uniform(42.0, 46.0, n), rng.uniform(-2.0, 2.0, n), np.full(n, DEPTH)])
        tg = PointTargets(pos, reflectivity=rng.standard_normal(n) + 1j * rng.standard_normal(n))
    return clsas.range_compress(clsas.simulate(sc.replace(targets=(tg,)), backend="opencl", progress=False))


@functools.cache
def direct(track: str, targets: str = "points"):
    return backproject(echo_of(track, targets), GRID, backend="opencl", progress=False)


def compare_points(image: Image, reference: Image) -> dict:
    """The worst over POINTS of: peak shift (resolution cells: the reference's IRW along y,
    c / 2B across), peak power (dB), PSLR and ISLR (dB, both cuts) differences."""
    worst = dict(shift=0.0, power=0.0, pslr=0.0, islr=0.0)
    for p in POINTS:
        a = metrics.analyse_point(image, near=(p[1], p[0]), radius=0.1)
        b = metrics.analyse_point(reference, near=(p[1], p[0]), radius=0.1)
        shift = max(abs(a["y"].location - b["y"].location) / b["y"].irw,
                    abs(a["x"].location - b["x"].location) / RANGE_CELL)
        power = abs(20 * np.log10(abs(a["y"].peak) / abs(b["y"].peak)))
        worst["shift"] = max(worst["shift"], shift)
        worst["power"] = max(worst["power"], power)
        worst["pslr"] = max(worst["pslr"], *(abs(a[d].pslr_db - b[d].pslr_db) for d in "yx"))
        worst["islr"] = max(worst["islr"], *(abs(a[d].islr_db - b[d].islr_db) for d in "yx"))
    return worst


def _geometry_only_echo(n_pulses: int, step: float = 0.025) -> EchoData:
    """bench_ffbp's monostatic sonar (150 kHz, B = 20 kHz, records upsampled to 200 kHz over
    35-65 m) on a straight track of ``n_pulses`` pulses ``step`` apart, with all-zero records
    that take no memory (a broadcast view): what ffbp's plan needs, not its data."""
    fs, t0 = 200e3, 2 * 35.0 / 1500.0
    n_samples = int(2 * 30.0 / 1500.0 * fs)
    y = (np.arange(n_pulses) - n_pulses / 2) * step
    tx = np.column_stack([np.zeros(n_pulses), y, np.zeros(n_pulses)])
    rx = np.stack([tx, tx + [0.0, 1.0 * 0.05, 0.0]], axis=1)[None]  # two nodes, 1 m/s over 50 ms
    return EchoData(data=np.broadcast_to(np.zeros(1, np.complex64), (1, n_pulses, n_samples)), eta=y / 1.0,
                    t0=[t0], fs=fs, tx_pos=tx, rx_pos=rx, rx_tau=[[0.0, 0.05]],
                    waveform=Waveform(f0=150e3, bandwidth=20e3, duration=5e-3, fs=25e3), medium=Medium(1500.0),
                    receivers=("h0",), compressed=True)
