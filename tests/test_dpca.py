"""DPCA micronavigation (clsas.estimate.dpca) on Heremans 2009's sonar with injected motion.

Truth: DPCA compares transmit-and-receive paths, so what it measures of the platform is the
mean of its place at emission and at reception; the tests compare with the injected motion at
each ping's emission time plus half the two-way travel time to the scene centre (100 m).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import clsas
from clsas import metrics
from clsas.estimate import dpca
from clsas.scene import presets
from clsas.scene.scenario import Platform
from clsas.scene.targets import PointTargets

HALF_TWO_WAY = 100.0 / 1500.0   # s, half the two-way time to 100 m


def _speckle(rng, n: int, amplitude: float) -> PointTargets:
    """A seafloor-like patch: n random scatterers over 88-112 m across and +-18 m along track."""
    pos = np.stack([rng.uniform(88, 112, n), rng.uniform(-18, 18, n), np.zeros(n)], -1)
    return PointTargets(pos, reflectivity=amplitude * (rng.normal(size=n) + 1j * rng.normal(size=n)) / np.sqrt(2))


def _moving(scene, sway, yaw, surge=None):
    return scene.replace(platform=Platform(speed=scene.platform.speed, sway=sway, yaw=yaw, surge=surge))


@pytest.fixture(scope="module")
def seafloor():
    """Speckle only, 16 pings, sway 3 cm / 7 s, yaw 4 mrad / 9 s, surge 2 cm / 11 s (fast motion)."""
    scene = presets.heremans2009(n_pulses=16).replace(targets=(_speckle(np.random.default_rng(1), 3000, 1.0),))
    motion = {"sway": lambda t: 0.03 * np.sin(2 * np.pi * t / 7.0),
              "yaw": lambda t: 0.004 * np.sin(2 * np.pi * t / 9.0 + 0.3),
              "surge": lambda t: 0.02 * np.sin(2 * np.pi * t / 11.0 + 1.0)}
    echo = clsas.range_compress(clsas.simulate(_moving(scene, **motion), progress=False))
    return scene, motion, echo, dpca.estimate(echo, scene.array, scene.platform.speed)


@pytest.fixture(scope="module")
def nine_points():
    """Heremans 2009's nine points on a weak seafloor (speckle 26 dB below a point), 24 pings,
    sway 5 cm / 40 s and yaw 3 mrad / 30 s from zero at the first ping; with and without motion."""
    scene = presets.point_scene("heremans2009", n_pulses=24)
    scene = scene.replace(waveform=dataclasses.replace(scene.waveform, fs=2 * scene.waveform.bandwidth),
                          targets=scene.targets + (_speckle(np.random.default_rng(5), 3000, 0.05),))
    t0 = scene.eta[0]
    motion = {"sway": lambda t: 0.05 * np.sin(2 * np.pi * (t - t0) / 40.0),
              "yaw": lambda t: 0.003 * np.sin(2 * np.pi * (t - t0) / 30.0)}
    clean = clsas.range_compress(clsas.simulate(scene, progress=False), upsample=4)
    echo = clsas.range_compress(clsas.simulate(_moving(scene, **motion), progress=False), upsample=4)
    return scene, motion, clean, echo


def _pair_truth(motion, eta, array, speed):
    """What a ping pair's sway, yaw and surge are in the model of dpca.integrate, from the
    injected motion at the mid times."""
    t = eta + HALF_TWO_WAY
    prf = 1 / np.diff(eta)[0]
    s, pc = dpca.nominal_shift(array, speed, prf)
    u = pc[:array.n_receivers - s - 2].mean()
    x, th = motion["sway"](t), motion["yaw"](t)
    surge = motion.get("surge")
    ds = np.diff(surge(t)) if surge else np.zeros(eta.size - 1)
    return np.diff(x) + u * np.diff(th) - speed / prf * th[:-1], np.diff(th), ds


def test_ping_pairs_on_a_seafloor(seafloor):
    scene, motion, echo, pairs = seafloor
    sway, yaw, surge = _pair_truth(motion, echo.eta, scene.array, scene.platform.speed)
    rms = lambda e: float(np.sqrt(np.mean(e**2)))  # noqa: E731
    # measured: sway RMS 0.13 mm (max 0.25), yaw RMS 0.12 mrad, surge max 1.3 mm; coherence >= 0.94
    assert rms(pairs.sway - sway) < 1e-3          # the issue: <= 2 mm RMS (lambda / 15)
    assert rms(pairs.yaw - yaw) < 1e-3 * 1.0      # the issue: ~1e-4 rad
    assert np.max(np.abs(pairs.surge - surge)) < 0.01
    assert np.all(pairs.coherence > 0.85) and np.all(pairs.blocks >= 1)
    assert np.all(np.isfinite(pairs.sway_std)) and np.all(pairs.sway_std < 1e-3)


def test_trajectory_on_a_seafloor(seafloor):
    scene, motion, echo, pairs = seafloor
    t = echo.eta + HALF_TWO_WAY
    speed = scene.platform.speed
    track = dpca.integrate(pairs, echo.eta, speed, scene.array, heading0=motion["yaw"](t[0]))
    error = track.cross - (motion["sway"](t) - motion["sway"](t[0]))
    # A heading error e tilts the track (a drift of D e a ping: a slight rotation of the image,
    # no defocus): what is left after the best tilt is what blurs.
    tilt = np.polyval(np.polyfit(t, error, 1), t)
    # measured: 5.8 mm raw, 0.47 mm after the tilt; heading within 0.77 mrad
    assert np.max(np.abs(error - tilt)) < 5e-3
    assert np.max(np.abs(track.heading - motion["yaw"](t))) < 3e-3
    assert np.allclose(track.times, t, atol=0.02)
    assert track.cross_std[0] == 0 and np.all(np.diff(track.cross_std) >= 0)   # eq. (73): errors accumulate
    platform = track.platform(speed)
    assert np.allclose(platform.motion_error("sway", track.times), track.cross)


def test_compensation_focuses_the_nine_points(nine_points):
    scene, motion, clean, echo = nine_points
    speed = scene.platform.speed
    track = dpca.integrate(dpca.estimate(echo, scene.array, speed), echo.eta, speed, scene.array)
    d = scene.array.rx_length[0]
    rres = scene.medium.sound_speed / (2 * scene.waveform.bandwidth)
    grid = clsas.Grid.plane(np.arange(97.0, 103.0, rres / 4), np.arange(-3.0, 3.0, d / 8), 0.0)

    def centre(e):
        return metrics.analyse_point(clsas.backproject(e, grid, progress=False), near=(0.0, 100.0), radius=d)

    truth, blind = centre(clean), centre(dpca.with_track(echo, scene))
    compensated = centre(dpca.compensate(echo, track, scene))
    along_track = centre(dpca.with_track(echo, scene.replace(platform=track.platform(speed, surge=False))))
    # measured: motion-free PSLR -26.7 dB; nominal track +0.3 dB (unfocused); compensated -25.1,
    # back-projected along the DPCA track -24.9; peaks within 6 mm of the truth (cell d / 2 = 11 cm)
    assert blind["y"].pslr_db > truth["y"].pslr_db + 20
    for result in (compensated, along_track):
        assert abs(result["y"].pslr_db - truth["y"].pslr_db) < 2.5
        assert abs(result["y"].location - truth["y"].location) < 0.1 * d / 2
        assert abs(result["x"].location - truth["x"].location) < 0.1 * rres


def test_correlations_are_normalised_and_find_a_delay(rng):
    f = (rng.normal(size=(3, 256)) + 1j * rng.normal(size=(3, 256))).astype(np.complex64)
    c = dpca.correlations(f, f, 4)
    assert np.allclose(np.abs(c[:, 4]), 1.0, atol=1e-6)
    g = np.roll(f, 2, axis=-1)                                     # ping p + 1 two samples late
    assert np.all(np.argmax(np.abs(dpca.correlations(f, g, 4)), axis=-1) == 4 - 2)


def test_bad_input(seafloor):
    scene, _, echo, _ = seafloor
    v = scene.platform.speed
    with pytest.raises(ValueError, match="overlapping phase centres"):
        dpca.estimate(echo, scene.array, 2.5 * v)
    with pytest.raises(ValueError, match="at least 2 pings"):
        dpca.estimate(echo.replace(data=echo.data[:, :1], eta=echo.eta[:1], tx_pos=echo.tx_pos[:1],
                                   rx_pos=echo.rx_pos[:, :1]), scene.array, v)
    with pytest.raises(ValueError, match="range-compressed"):
        dpca.estimate(echo.replace(compressed=False), scene.array, v)
    with pytest.raises(ValueError, match="speed"):
        dpca.estimate(echo, scene.array, float("nan"))
    with pytest.raises(TypeError, match="Array"):
        dpca.estimate(echo, "array", v)
    with pytest.raises(ValueError, match="t_lags"):
        dpca.estimate(echo, scene.array, v, t_lags=100, block=64)
    with pytest.raises(ValueError, match="receivers and emission times"):
        dpca.with_track(echo, presets.heremans2009(n_pulses=4))


@pytest.mark.slow
def test_reproduce_heremans2009_runs(tmp_path, capsys):
    from clsas import cli

    assert cli.main(["reproduce", "heremans2009", "--pings", "24", "--out", str(tmp_path), "--kiang-cases", "5"]) == 0
    out = capsys.readouterr().out
    assert "sway error" in out and "compensated (eqs. 74-75)" in out
    assert (tmp_path / "compensated.png").stat().st_size > 1000
    # case 5's point target: PGA takes its azimuth PSLR from about -2 dB to about -13 dB (measured)
    row = next(line.split() for line in out.splitlines() if line.split()[:2] == ["5", "A"])
    assert float(row[7]) < -12 and float(row[3]) < float(row[2])
