"""Scenario -> TOML document (a dict) -> TOML text, and meshes -> binary PLY files.

Floats are written by ``repr``, which reads back as the same float64, so a preset written and
read again is the same Scenario bit for bit (``tests/test_scenario_toml.py``). The text is
written here rather than by tomli_w, which puts every number of an array on its own line (a
3-vector took five lines, a 32-receiver array 160): the schema holds only scalars, strings,
numeric arrays and tables, and :func:`dumps` writes arrays as rows packed to 100 columns.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np

from ...scene.scenario import MOTION_COMPONENTS, Array, PulseSchedule, Recording, Scenario
from ...scene.seafloor import SEDIMENTS
from ...scene.targets import MeshTarget, PointTargets
from .schema import ARRAYS_OF_TABLES, SCHEMA_VERSION, TABLES, TARGET_KINDS

#: fields whose constructors take one value for all: written once when every entry is the same
_COMPACT = {Array: ("rx_length",), Recording: ("t0", "n_samples"), PointTargets: ("velocity",)}
_HEADER = ("# clsas scenario: SI units (m, s, Hz, m/s), angles in radians; schema in docs/scenario-toml.md\n"
           "# load with clsas.load_scenario(path); simulate with `clsas simulate THIS.toml -o echo.nc`\n")


def plain(value):
    """``value`` as TOML-writable Python objects (lists, floats, ints, str, bool)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (tuple, list)):
        return [plain(v) for v in value]
    return value


def _same_everywhere(arr: np.ndarray):
    """The one value (or row) ``arr`` repeats, or None."""
    if arr.size == 0:
        return None
    first = arr[0]
    return first if np.array_equal(arr, np.broadcast_to(first, arr.shape)) else None


def _fields(obj, skip=()) -> dict:
    table = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if value is None or f.name in skip:
            continue
        if f.name in _COMPACT.get(type(obj), ()):
            arr = np.asarray(value)
            if arr.size == 0:
                continue
            one = _same_everywhere(arr)
            if one is not None:
                value = one
        table[f.name] = plain(value)
    return table


def _platform(platform) -> dict:
    for name in MOTION_COMPONENTS:
        if callable(getattr(platform, name)):
            raise TypeError(f"Platform.{name} is a Python function: a TOML scenario holds motion errors as arrays "
                            f"sampled at Platform.error_times; sample it first "
                            f"(Platform(..., {name}=f(times), error_times=times))")
    return _fields(platform)


def _seafloor(floor) -> dict:
    """The [seafloor] table: the sediment by its table name when it is the table's, else as a
    [seafloor.sediment] sub-table; a height function cannot be written (sample it first)."""
    if callable(floor.heights):
        raise TypeError("Seafloor.heights is a Python function: a TOML scenario holds the relief as an array of "
                        "heights with its spacing and origin; sample it first (Seafloor(..., heights=z(x, y), "
                        "spacing=..., origin=...))")
    table = _fields(floor)
    sediment = floor.sediment
    table["sediment"] = sediment.name if SEDIMENTS.get(sediment.name) == sediment else _fields(sediment)
    return table


def _target(target, index: int, mesh_file) -> dict:
    if isinstance(target, PointTargets):
        table = {"kind": "points", **_fields(target, skip=("reflectivity",))}
        refl = target.reflectivity
        for key, part in (("reflectivity", refl.real), ("reflectivity_imag", refl.imag)):
            one = _same_everywhere(part)
            if key == "reflectivity_imag" and one is not None and one == 0 and not np.signbit(one):
                continue
            table[key] = plain(part if one is None else one)
        return {k: table[k] for k in ("kind", "positions", "reflectivity", "reflectivity_imag", "velocity") if k in table}
    if isinstance(target, MeshTarget):
        table = {"kind": "mesh"}
        if mesh_file is None:
            table.update(vertices=plain(target.mesh.vertices), faces=plain(target.mesh.faces))
        else:
            table.update(mesh=mesh_file(index, target.mesh), process=False)
        table.update(_fields(target, skip=("mesh",)))
        return table
    raise TypeError(f"Scenario.targets[{index}] is a {type(target).__name__}; a TOML scenario holds the kinds "
                    f"{sorted(TARGET_KINDS)} ({', '.join(c.__name__ for c in TARGET_KINDS.values())})")


def document(scenario: Scenario, mesh_file=None) -> dict:
    """The TOML document (dict) of ``scenario``. ``mesh_file(index, trimesh) -> str`` stores a
    mesh and returns the path to write; None writes meshes inline (vertices and faces)."""
    if not isinstance(scenario, Scenario):
        raise TypeError(f"to_toml takes a Scenario, got {type(scenario).__name__}")
    handled = set(TABLES) | set(ARRAYS_OF_TABLES)
    unknown = [f.name for f in dataclasses.fields(scenario) if f.name not in handled]
    if unknown:  # a field added to Scenario that the schema does not know yet
        raise TypeError(f"Scenario fields {unknown} have no place in the TOML schema (clsas.io.toml.schema)")
    doc = {"schema_version": SCHEMA_VERSION}
    for name in TABLES:
        part = getattr(scenario, name)
        if part is None:
            continue
        if isinstance(part, PulseSchedule) and part.exposure is not None:
            doc[name] = _fields(part, skip=("n_pulses",))  # exposure sets n_pulses
        else:
            doc[name] = {"platform": _platform, "seafloor": _seafloor}.get(name, _fields)(part)
    if scenario.sonobuoys:
        doc["sonobuoys"] = [_fields(b) for b in scenario.sonobuoys]
    if scenario.targets:
        doc["targets"] = [_target(t, i, mesh_file) for i, t in enumerate(scenario.targets)]
    return doc


_WIDTH = 100  # columns an array line is packed to
_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(name: str) -> str:
    return name if _BARE_KEY.match(name) else _string(name)


def _string(text: str) -> str:
    """A TOML basic string: JSON's escapes are TOML's, and TOML also forbids a raw DEL."""
    return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007f")


def _scalar(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _string(value)
    raise TypeError(f"a TOML scenario value must be a bool, number, string or list, got {type(value).__name__}")


def _value(value) -> str:
    """``value`` as TOML: an array on one line when it fits, else its items (each inline, e.g.
    a 3-vector) packed into lines of at most ``_WIDTH`` columns."""
    if not isinstance(value, list):
        return _scalar(value)
    items = [_value(item) for item in value]
    inline = "[" + ", ".join(items) + "]"
    if len(inline) <= _WIDTH:
        return inline
    lines = [""]
    for item in items:
        if lines[-1] and len(lines[-1]) + len(item) + 2 > _WIDTH - 4:
            lines.append("")
        lines[-1] += (" " if lines[-1] else "") + item + ","
    return "[\n" + "".join(f"    {line}\n" for line in lines) + "]"


def _is_tables(value) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _table(table: dict, name: str) -> list:
    """Lines of ``table``: its key = value pairs, then its sub-tables ``[name.key]`` and arrays
    of tables ``[[name.key]]``."""
    lines = [f"{_key(k)} = {_value(v)}\n" for k, v in table.items() if not isinstance(v, dict) and not _is_tables(v)]
    for k, v in table.items():
        path = f"{name}.{_key(k)}" if name else _key(k)
        if isinstance(v, dict):
            lines += [f"\n[{path}]\n", *_table(v, path)]
        elif _is_tables(v):
            for item in v:
                lines += [f"\n[[{path}]]\n", *_table(item, path)]
    return lines


def dumps(doc: dict) -> str:
    """The TOML text of ``doc`` (nested dicts and lists of scalars), after a comment header."""
    return _HEADER + "".join(_table(doc, ""))


def write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """A binary little-endian PLY file with float64 vertices (trimesh's own PLY export rounds
    them to float32) and int32 triangle indices; MeshLab, Blender and trimesh read it."""
    vertices = np.ascontiguousarray(vertices, dtype="<f8")
    faces = np.asarray(faces)
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices) or len(vertices) >= 2**31):
        raise ValueError(f"write_ply: faces index vertices outside 0..{len(vertices) - 1}")
    records = np.zeros(len(faces), dtype=[("n", "u1"), ("index", "<i4", (3,))])
    records["n"] = 3
    records["index"] = faces
    header = ("ply\nformat binary_little_endian 1.0\ncomment written by clsas (float64 vertices)\n"
              f"element vertex {len(vertices)}\nproperty double x\nproperty double y\nproperty double z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vertices.tobytes())
        f.write(records.tobytes())
