"""TOML text -> Scenario: key checks, then the classes' own validation, errors mapped to key paths.

Nothing is checked twice: a value goes to its class's constructor (:mod:`clsas.validate`
rules), and a ValueError / TypeError it raises ("Waveform.bandwidth: must be in (0, 3e+05) Hz
..., got -2") is re-raised as a :class:`clsas.errors.ScenarioFileError` that names the file,
the key path and the line ("scene.toml: [waveform].bandwidth: must be in ..., got -2 (line 7)").
Only what the classes cannot know is checked here: unknown and missing keys, the shape of the
document (tables where tables belong), the targets' kind and the mesh source.
"""

from __future__ import annotations

import difflib
import functools
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ... import validate as v
from ...errors import ScenarioFileError
from ...scene.scenario import Array, Medium, Scenario
from ...scene.seafloor import Seafloor, Sediment
from .lines import KeyLines

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the same parser as a package
    import tomli as tomllib
from .schema import (
    ARRAYS_OF_TABLES,
    SCHEMA_VERSION,
    TABLES,
    TARGET_KINDS,
    TOP_KEYS,
    required_fields,
    table_keys,
)

_PREFIX = re.compile(r"^(?P<cls>[A-Za-z]\w*)(?:\([^)]*\))?\.(?P<field>\w+)(?P<sep>:?)\s*(?P<rest>.*)$", re.S)


@dataclass(frozen=True)
class _Where:
    table: str
    index: int | None = None

    @property
    def label(self) -> str:
        return f"[{self.table}]" if self.index is None else f"[[{self.table}]][{self.index}]"


class _Reader:
    def __init__(self, text: str, source: str, base: Path | None):
        self.source, self.base, self.text = source, base, text
        try:
            self.doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise ScenarioFileError(f"{source}: not valid TOML: {err}") from None

    @functools.cached_property
    def lines(self) -> KeyLines:
        return KeyLines(self.text)  # scanned only when a message needs a line

    def fail(self, where: _Where | None, key: str | None, message: str, cause=None):
        path = (key or "") if where is None else where.label + (f".{key}" if key else "")
        line = self.lines.line(where.table, where.index, key) if where else self.lines.line("", None, key)
        text = f"{self.source}: {path + ': ' if path else ''}{message}{f' (line {line})' if line else ''}"
        raise ScenarioFileError(text) from cause

    def check_keys(self, table: dict, allowed, where: _Where | None) -> None:
        unknown = [k for k in table if k not in allowed]
        if unknown:
            hints = {k: difflib.get_close_matches(k, allowed, n=1) for k in unknown}
            said = ", ".join(f"{k!r}" + (f" (did you mean {hints[k][0]!r}?)" if hints[k] else "") for k in unknown)
            self.fail(where, unknown[0], f"unknown key{'s' if len(unknown) > 1 else ''} {said}; "
                      f"known: {', '.join(allowed)}")

    def build(self, cls, values: dict, where: _Where | None, classes: dict | None = None):
        """``cls(**values)``, its ValueError/TypeError mapped to a key of ``where`` (or, for a
        Scenario, to the table of the class the message names: ``classes``)."""
        try:
            return cls(**values)
        except (ValueError, TypeError) as err:
            message = " ".join(str(err).split())
            found = _PREFIX.match(message)
            target, key = where, None
            if found and classes and found["cls"] in classes:
                target = classes[found["cls"]]
            if found and (found["cls"] == cls.__name__ or (classes and found["cls"] in classes)):
                key = found["field"]
                if found["sep"]:
                    message = found["rest"]
            self.fail(target, key, message, err)

    def table(self, name: str, index: int | None = None, value=None) -> tuple[dict, _Where]:
        where = _Where(name, index)
        if not isinstance(value, dict):
            self.fail(where, None, f"must be a table of keys, got {type(value).__name__} {value!r:.40}")
        return value, where

    def part(self, name: str, cls, value, index: int | None = None):
        values, where = self.table(name, index, value)
        self.check_keys(values, table_keys(cls), where)
        self.require(values, cls, where)
        if cls is Array and values.get("rx_offsets") == []:  # an array-less scenario (sonobuoys only)
            values = dict(values, rx_offsets=np.zeros((0, 3)))
        if cls is Seafloor and isinstance(values.get("sediment"), dict):  # [seafloor.sediment]
            inner = _Where("seafloor.sediment")
            self.check_keys(values["sediment"], table_keys(Sediment), inner)
            values = dict(values, sediment=self.build(Sediment, values["sediment"], inner))
        return self.build(cls, values, where)

    def require(self, values: dict, cls, where: _Where) -> None:
        missing = [k for k in required_fields(cls) if k not in values]
        if missing:
            self.fail(where, None, f"missing key{'s' if len(missing) > 1 else ''} {', '.join(missing)}")

    def entries(self, name: str) -> list:
        value = self.doc.get(name, [])
        if not isinstance(value, list):
            self.fail(None, name, f"{name} must be an array of tables ([[{name}]] entries), got {type(value).__name__}")
        return value

    def target(self, index: int, value):
        values, where = self.table("targets", index, value)
        kind = values.get("kind")
        if kind not in TARGET_KINDS:
            self.fail(where, "kind" if "kind" in values else None,
                      f"kind must be one of {sorted(TARGET_KINDS)}, got {kind!r}")
        cls = TARGET_KINDS[kind]
        self.check_keys(values, table_keys(cls, kind), where)
        values = {k: val for k, val in values.items() if k != "kind"}
        if kind == "points":
            self.require(values, cls, where)
            if "reflectivity_imag" in values:
                values["reflectivity"] = self.complex_reflectivity(values, where)
        else:
            values["mesh"] = self.mesh(values, where)
        return self.build(cls, values, where)

    def complex_reflectivity(self, values: dict, where: _Where) -> np.ndarray:
        parts = []
        for key in ("reflectivity", "reflectivity_imag"):
            raw = values.pop(key, 1.0 if key == "reflectivity" else 0.0)
            try:
                parts.append(v.array(f"PointTargets.{key}", raw, (-1,) if np.ndim(raw) else (), bound=v.MAX_AMPLITUDE))
            except (ValueError, TypeError) as err:
                self.fail(where, key, " ".join(str(err).split()).split(": ", 1)[-1], err)
        try:
            real, imag = np.broadcast_arrays(*parts)
        except ValueError:
            self.fail(where, "reflectivity_imag", f"has {parts[1].size} values but reflectivity has {parts[0].size}")
        out = np.empty(real.shape, np.complex128)
        out.real, out.imag = real, imag
        return out

    def mesh(self, values: dict, where: _Where):
        import trimesh

        inline = [k for k in ("vertices", "faces") if k in values]
        if "mesh" in values and inline:
            self.fail(where, inline[0], "give either mesh (a file) or vertices and faces, not both")
        if "mesh" not in values:
            if len(inline) != 2:
                self.fail(where, None, "a mesh target needs mesh = \"FILE\" (relative to this file) or both "
                          "vertices and faces")
            if "process" in values:
                self.fail(where, "process", "applies to a mesh file only")
            try:
                vertices = v.array("vertices", values.pop("vertices"), (-1, 3), bound=v.MAX_COORDINATE)
            except (ValueError, TypeError) as err:
                self.fail(where, "vertices", str(err).split(": ", 1)[-1], err)
            allowed = f"must be triangles: (n >= 1, 3) integers indexing the {len(vertices)} vertices from 0"
            try:
                faces = np.asarray(values.pop("faces"))
            except ValueError:  # rows of different lengths
                self.fail(where, "faces", f"{allowed}; its rows have different lengths")
            if faces.dtype.kind not in "iu" or faces.ndim != 2 or faces.shape[1] != 3 or faces.size == 0 \
                    or faces.min() < 0 or faces.max() >= len(vertices):
                self.fail(where, "faces", f"{allowed}, got shape {faces.shape} of {faces.dtype}")
            return trimesh.Trimesh(vertices, faces, process=False)
        name, process = values.pop("mesh"), values.pop("process", True)
        if not isinstance(name, str) or not name:
            self.fail(where, "mesh", f"must be a file name (relative to this file), got {name!r}")
        if not isinstance(process, bool):
            self.fail(where, "process", f"must be true or false, got {process!r}")
        path = Path(name)
        if not path.is_absolute():
            if self.base is None:
                self.fail(where, "mesh", f"{name!r} is relative, but this scenario was not read from a file; give "
                          "an absolute path")
            path = self.base / path
        if not path.is_file():
            self.fail(where, "mesh", f"no such mesh file: {path}")
        try:
            return trimesh.load(path, force="mesh", process=process)
        except Exception as err:  # noqa: BLE001 - trimesh raises many types for unreadable files
            self.fail(where, "mesh", f"cannot load {path} as a triangle mesh ({type(err).__name__}: {err})", err)

    def scenario(self) -> Scenario:
        doc = self.doc
        self.check_keys(doc, TOP_KEYS, None)
        version = doc.get("schema_version", SCHEMA_VERSION)
        if version != SCHEMA_VERSION or isinstance(version, bool):
            self.fail(None, "schema_version", f"schema_version {version!r} is not one this clsas reads "
                      f"({SCHEMA_VERSION})")
        missing = [n for n in ("waveform", "platform", "array", "schedule") if n not in doc]
        if missing:
            self.fail(None, None, f"missing table{'s' if len(missing) > 1 else ''} "
                      f"{', '.join(f'[{n}]' for n in missing)}")
        parts = {name: self.part(name, cls, doc[name]) for name, cls in TABLES.items() if name in doc}
        parts.setdefault("medium", Medium())
        parts["sonobuoys"] = tuple(self.part("sonobuoys", ARRAYS_OF_TABLES["sonobuoys"], b, i)
                                   for i, b in enumerate(self.entries("sonobuoys")))
        parts["targets"] = tuple(self.target(i, t) for i, t in enumerate(self.entries("targets")))
        classes = {cls.__name__: _Where(name) for name, cls in TABLES.items()}
        return self.build(Scenario, parts, None, classes)


def parse(text: str, source: str = "<scenario>", base: Path | None = None) -> Scenario:
    """The Scenario of a TOML text; ``base`` is the folder relative mesh paths start from."""
    if not isinstance(text, str):
        raise TypeError(f"a TOML scenario must be text (str), got {type(text).__name__}")
    try:
        return _Reader(text, source, base).scenario()
    except RecursionError:  # tomllib and the checks recurse into nested arrays and tables
        raise ScenarioFileError(f"{source}: not a scenario: its arrays or tables are nested too deeply") from None
