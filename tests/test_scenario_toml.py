"""TOML scenarios: every preset written and read back is the same Scenario (every dataclass
field, bit for bit) and simulates to the same echo; errors name the file, key path and line."""

from __future__ import annotations

import dataclasses
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

import clsas
from clsas.errors import ScenarioFileError
from clsas.scene import presets
from clsas.scene.scenario import Platform, SamplingWarning
from clsas.io.toml import scenario_from_toml

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def assert_same(a, b, where="scenario"):
    """Every field of two scenarios equal: same types, arrays of the same dtype and values."""
    assert type(a) is type(b), f"{where}: {type(a).__name__} != {type(b).__name__}"
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b), where
    elif isinstance(a, trimesh.Trimesh):
        assert_same(a.vertices.view(np.ndarray), b.vertices.view(np.ndarray), f"{where}.vertices")
        assert_same(a.faces.view(np.ndarray), b.faces.view(np.ndarray), f"{where}.faces")
    elif isinstance(a, (tuple, list)):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def _presets():
    cases = [(name, lambda name=name: presets.sonar(name)) for name in presets.SONARS]
    cases += [(f"{name} points", lambda name=name: presets.point_scene(name)) for name in presets.POINT_LAYOUTS]
    cases += [("wu2018_inclined", presets.wu2018_inclined)]
    cases += [(f"kiang2022 case {c}", lambda c=c: presets.kiang2022_case(c)) for c in presets.KIANG_CASES]
    return cases


@pytest.mark.parametrize("name,make", _presets(), ids=[c[0] for c in _presets()])
def test_every_preset_round_trips_exactly(name, make, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SamplingWarning)  # zhang2019 as printed undersamples (its docstring)
        scenario = make()
        path = clsas.scenario_to_toml(scenario, tmp_path / "scene.toml")
        back = clsas.load_scenario(path)
    assert_same(scenario, back)
    meshes = sorted(p.name for p in tmp_path.glob("*.ply"))
    assert meshes == [f"scene.target{i}.ply" for i, t in enumerate(scenario.targets) if hasattr(t, "mesh")]


def test_inline_meshes_and_echoes_are_identical():
    """Text with the mesh inline (what a saved echo carries) reads back the same scenario, and
    both simulate to the same samples, bit for bit (points and a hull)."""
    hull = presets.kiang2022_case(5, n_pulses=2, sections=12, stations=12)
    points = presets.point_scene("huang2022", n_pulses=3)
    for scenario in (points, hull):
        text = clsas.scenario_to_toml(scenario)
        back = scenario_from_toml(text)
        assert_same(scenario, back)
        assert clsas.scenario_to_toml(back) == text
        one, two = (clsas.simulate(s, progress=False) for s in (scenario, back))
        assert np.abs(one.data).max() > 0
        np.testing.assert_array_equal(one.data, two.data)


def test_written_text_is_compact_and_strings_round_trip():
    """Vectors stay on one line, arrays pack into rows of at most 100 columns, and names with
    quotes, backslashes, non-ASCII letters or control characters read back as written."""
    from clsas.scene.scenario import Sonobuoy

    names = ('C "north"', "back\\slash", "bou\u00e9e", "tab\tand\x7fdel")
    scenario = dataclasses.replace(presets.point_scene("huang2022", n_pulses=3),
                                   sonobuoys=tuple(Sonobuoy((10.0 * i, 5.0, -2.0), name=n) for i, n in enumerate(names)))
    text = clsas.scenario_to_toml(scenario)
    assert "start = [0.0, 0.0, 0.0]" in text
    assert max(len(line) for line in text.splitlines()) <= 100
    assert len(text.splitlines()) < 80, "a 32-receiver array packs into rows"
    back = scenario_from_toml(text)
    assert_same(scenario, back)
    assert [b.name for b in back.sonobuoys] == list(names)


def test_examples_load_with_every_part(tmp_path):
    points = clsas.load_scenario(EXAMPLES / "huang2022_points.toml")
    np.testing.assert_allclose(points.array.rx_offsets, presets.huang2022().array.rx_offsets, rtol=0, atol=1e-15)
    assert_same(points.targets, presets.point_scene("huang2022").targets)
    scene = clsas.load_scenario(EXAMPLES / "sphere_and_buoy.toml")  # mesh path relative to the file
    assert scene.receiver_names == ("h0", "h1", "h2", "h3", "buoy") and scene.recording.n_samples.tolist() == [900]
    assert scene.targets[0].reflectivity[1] == 0.5 + 0.5j and scene.targets[1].n_facets == 320
    assert scene.platform.motion_error("yaw", np.array([1.5]))[0] == pytest.approx(-0.002)
    assert_same(scene, clsas.load_scenario(clsas.scenario_to_toml(scene, tmp_path / "copy.toml")))
    assert_same(scene, scenario_from_toml(clsas.scenario_to_toml(scene)))
    shutil.copy(EXAMPLES / "sphere_and_buoy.toml", tmp_path / "alone.toml")  # without its mesh file
    with pytest.raises(ScenarioFileError, match=r"alone.toml: \[\[targets\]\]\[1\].mesh: no such mesh file: .*"
                                                r"sphere.obj \(line \d+\)"):
        clsas.load_scenario(tmp_path / "alone.toml")


BASE = """schema_version = 1
[waveform]
f0 = 100e3
bandwidth = 20e3
duration = 2e-3
fs = 25e3
[platform]
speed = 1.0
[array]
rx_offsets = [[0.0, 0.1, 0.0],
              [0.0, 0.2, 0.0]]
[schedule]
prf = 5.0
n_pulses = 8
[[targets]]
kind = "points"
positions = [[10.0, 0.0, 0.0]]
[[targets]]
kind = "points"
positions = [[12.0, 0.0, 0.0]]
velocity = [0.0, 1.0, 0.0]
"""


def _error(text, tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(text)
    with pytest.raises(ScenarioFileError) as info:
        clsas.load_scenario(path)
    return str(info.value)


def _line_of(text, fragment):
    return next(n for n, line in enumerate(text.splitlines(), 1) if fragment in line)


@pytest.mark.parametrize("old,new,expected,at", [
    ("bandwidth = 20e3", "bandwidth = -2",
     r"^scene.toml: \[waveform\].bandwidth: must be in \(0, 200000\) Hz \(0 < B < 2 f0\), got -2", "bandwidth ="),
    ("speed = 1.0", "speed = \"fast\"", r"\[platform\].speed: must be a real number .* got 'fast' \(str\)", "speed ="),
    ("speed = 1.0", "speed = 1.0\nsped = 2",
     r"\[platform\].sped: unknown key 'sped' \(did you mean 'speed'\?\); known: speed, start, ", "sped ="),
    ("[schedule]", "[schedul]", r"^scene.toml: schedul: unknown key 'schedul' \(did you mean 'schedule'\?\)", "[schedul]"),
    ("n_pulses = 8", "n_pulses = 8\nexposure = 2.0",
     r"\[schedule\]: PulseSchedule needs exactly one of n_pulses and exposure", "[schedule]"),
    ("fs = 25e3\n", "", r"\[waveform\]: missing key fs", "[waveform]"),
    ("velocity = [0.0, 1.0, 0.0]", "velocity = [0.0, 1000.0, 0.0]",
     r"\[\[targets\]\]\[1\].velocity: speeds must be at most 100 m/s .* got 1000 m/s", "velocity ="),
    ("kind = \"points\"\npositions = [[12", "kind = \"plane\"\npositions = [[12",
     r"\[\[targets\]\]\[1\].kind: kind must be one of \['mesh', 'points'\], got 'plane'", "plane"),
    ("rx_offsets = [[0.0, 0.1, 0.0],", "rx_offsets = [[0.0, 0.1],",
     r"\[array\].rx_offsets: must be an array of real numbers with shape \(n, 3\)", "rx_offsets ="),
    ("schema_version = 1", "schema_version = 2", r"schema_version 2 is not one this clsas reads \(1\)", "schema_version"),
    ("schema_version = 1", "schema_version = 1\nmedium = 3", r"\[medium\]: must be a table of keys, got int 3",
     "medium ="),
    ("schema_version = 1", "schema_version = 1\nsonobuoys = 3", r"sonobuoys must be an array of tables", "sonobuoys ="),
    ("n_pulses = 8", "n_pulses = 8\n[recording]\nt0 = [0.01, 0.02, 0.03]\nn_samples = 100",
     r"\[recording\].t0: Recording.t0 has 3 values; give 1 or one per receiver \(2\)", "t0 ="),
])
def test_errors_name_the_key_path_and_line(old, new, expected, at, tmp_path):
    assert old in BASE
    text = BASE.replace(old, new, 1)
    message = _error(text, tmp_path)
    assert re.search(expected, message), message
    assert message.endswith(f"(line {_line_of(text, at)})"), message


def test_toml_syntax_errors_give_the_line(tmp_path):
    assert re.search(r"scene.toml: not valid TOML: .*line 13, column 11", _error(BASE.replace("prf = 5.0", "prf = 5.0 ]"),
                                                                             tmp_path))


def test_line_numbers_follow_the_text(tmp_path):
    text = BASE.replace("velocity = [0.0, 1.0, 0.0]", "velocity = [0.0, 1.0, 0.0]\nreflectivity = [1.0, 2.0]")
    message = _error(text, tmp_path)
    assert f"(line {_line_of(text, 'reflectivity =')})" in message and "[[targets]][1].reflectivity: must have" in message
    good = scenario_from_toml(BASE)
    assert good.targets[1].velocity.tolist() == [[0.0, 1.0, 0.0]] and good.medium.sound_speed == 1500.0


def test_what_toml_cannot_hold_is_refused(tmp_path):
    wobbly = presets.huang2022(n_pulses=4).replace(platform=Platform(speed=2.0, sway=lambda t: 0.01 * np.sin(t)))
    with pytest.raises(TypeError, match=r"Platform.sway is a Python function: .* sample it first"):
        clsas.scenario_to_toml(wobbly)
    with pytest.raises(ValueError, match="must end in .toml"):
        clsas.scenario_to_toml(presets.huang2022(), tmp_path / "scene.txt")
    hull = BASE.replace('kind = "points"\npositions = [[12.0, 0.0, 0.0]]', 'kind = "mesh"\nmesh = "hull.stl"')
    with pytest.raises(ScenarioFileError, match=r"\[\[targets\]\]\[1\].mesh: 'hull.stl' is relative, but this "
                                                r"scenario was not read from a file; give an absolute path \(line 20\)"):
        scenario_from_toml(hull)
