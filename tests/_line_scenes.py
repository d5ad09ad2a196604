"""Shared scenes and checks for the frequency-domain imagers (omega-k, range-Doppler, chirp
scaling, the multireceiver conversion): each is compared with back-projection on the same data."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

import clsas
from clsas import metrics
from clsas.model import Image
from clsas.reproduce._points import backprojected, patch
from clsas.scene import presets
from clsas.scene.scenario import (
    Array,
    Medium,
    Platform,
    PulseSchedule,
    Scenario,
    Waveform,
)
from clsas.scene.targets import PointTargets

MONO_D = 0.2  # nominal aperture of the monostatic scene (its processed band is 4 pi / D), m


@functools.cache
def mono_grid():
    """A monostatic 3 x 3 point grid 95-105 m across, -3..3 m along track (f0 50 kHz, B 10 kHz,
    sampled every D / 4 along track), and its range-compressed echoes. The elements are
    omnidirectional so that the imagers' band |k_u| <= 2 pi / D and back-projection's
    integration angle sin(theta) <= lambda / (2 D) cut the same flat spectrum (unweighted
    sidelobes near -13 dB on both, compared like for like)."""
    points = np.array([[x, y, 0.0] for x in (95.0, 100.0, 105.0) for y in (-3.0, 0.0, 3.0)])
    sc = Scenario(medium=Medium(1500.0), waveform=Waveform(f0=50e3, bandwidth=10e3, duration=10e-3, fs=20e3),
                  platform=Platform(speed=0.5), array=Array(rx_offsets=[[0.0, 0.0, 0.0]]),
                  schedule=PulseSchedule(prf=10.0, n_pulses=720), targets=(PointTargets(points),))
    return sc, clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


@functools.cache
def huang_six(n_pulses: int = 32):
    """Huang & Yang 2022's 32-receiver sonar and six points (40-80 m), sampled at 2 B, with
    omnidirectional elements (as :func:`mono_grid`; the band is set by the 0.08 m transmitter)."""
    sc = presets.point_scene("huang2022", n_pulses=n_pulses)
    sc = sc.replace(waveform=dataclasses.replace(sc.waveform, fs=2 * sc.waveform.bandwidth),
                    array=dataclasses.replace(sc.array, tx_length=0.0, rx_length=0.0))
    return sc, clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


def compare_with_backprojection(image: Image, echo, points, band_length: float):
    """Per point: location differences along y and x (in resolution cells D / 2 and c / (2 B)),
    the largest PSLR and ISLR differences (dB) over both cuts, and the SSIM of ``image``
    against back-projection of ``echo`` on the same pixels, integrating the angle
    sin(theta) <= lambda / (2 D) that matches the imagers' band |k_u| <= 2 pi / D
    (D = ``band_length``)."""
    lam = echo.medium.sound_speed / echo.waveform.f0
    aperture = 2 * np.arcsin(lam / (2 * band_length))
    cell_y, cell_x = band_length / 2, echo.medium.sound_speed / (2 * echo.waveform.bandwidth)
    rows = []
    for p in points:
        mine = patch(image, p, (6 * cell_y, 6 * cell_x))
        bp = backprojected(echo, mine, aperture)
        a = metrics.analyse_point(mine, near=(p[1], p[0]), radius=cell_y)
        b = metrics.analyse_point(bp, near=(p[1], p[0]), radius=cell_y)
        rows.append({
            "dy": abs(a["y"].location - b["y"].location) / cell_y,
            "dx": abs(a["x"].location - b["x"].location) / cell_x,
            "pslr": max(abs(a[d].pslr_db - b[d].pslr_db) for d in ("y", "x")),
            "islr": max(abs(a[d].islr_db - b[d].islr_db) for d in ("y", "x")),
            "ssim": metrics.ssim(mine, bp),
        })
    return rows


def assert_agrees_with_backprojection(imager, scene: str) -> None:
    """The bar for the strip-map imagers: every peak within 1/10 of a
    resolution cell of back-projection's, PSLR and ISLR within 1 dB, SSIM > 0.9; ``scene`` is
    "mono" (the 3 x 3 grid) or "huang" (six points, 32 receivers through the PCA conversion)."""
    from clsas.image.multireceiver import pca_record

    if scene == "mono":
        sc, echo = mono_grid()
        record, elements = echo, (MONO_D, MONO_D)
    else:
        sc, echo = huang_six()
        record, elements = pca_record(echo), (0.08, 0.04)
    image = imager(record, elements=elements, deconvolve=False, window="none")
    rows = compare_with_backprojection(image, echo, sc.targets[0].positions, max(elements))
    assert len(rows) == len(sc.targets[0].positions)
    for row in rows:
        assert row["dy"] < 0.1 and row["dx"] < 0.1, row
        assert row["pslr"] < 1.0 and row["islr"] < 1.0, row
        assert row["ssim"] > 0.9, row


@functools.cache
def wide_swath():
    """Zhang 2019's sonar (f0 150 kHz, B 20 kHz, 30 receivers interleaved by PCA: 0.01 m
    along-track samples) and three points across a 160 m swath (44, 122 and 200 m), 32 pulses:
    the frequency-domain imagers' range-variant terms (SRC, residual phase) far from the
    reference range. Returns (points, record)."""
    import warnings

    from clsas.image.multireceiver import pca_record

    points = np.array([[44.0, -1.0, 0.0], [122.0, 0.5, 0.0], [200.0, 1.0, 0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the reproduction's PRF overlaps pulses (SamplingWarning)
        sc = presets.zhang2019(n_pulses=32, receivers=30, pri=0.15).replace(targets=(PointTargets(points),))
        echo = clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))
    return points, pca_record(echo, backend="opencl")


def compare_with_range_doppler(image: Image, record, points) -> list[dict]:
    """Per point: the peak (dB) and the along-track and across-track PSLR (dB) of ``image``
    minus those of range-Doppler on the same record, and the location difference (m)."""
    reference = clsas.range_doppler(record, elements=(0.04, 0.02), deconvolve=False, backend="opencl")
    rows = []
    for p in points:
        a = metrics.analyse_point(image, near=(p[1], p[0]), radius=0.05)
        b = metrics.analyse_point(reference, near=(p[1], p[0]), radius=0.05)
        rows.append({"peak_db": 20 * np.log10(abs(a["y"].peak) / abs(b["y"].peak)),
                     "pslr_y": a["y"].pslr_db - b["y"].pslr_db, "pslr_x": a["x"].pslr_db - b["x"].pslr_db,
                     "dy": a["y"].location - b["y"].location, "dx": a["x"].location - b["x"].location})
    return rows
