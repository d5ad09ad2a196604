"""Scenarios as TOML files: :func:`load_scenario`, :func:`scenario_to_toml` (``clsas.scenario_to_toml``).

The schema (docs/scenario-toml.md): one table per part of the :class:`~clsas.scene.scenario.Scenario`
(``[medium]``, ``[waveform]``, ``[platform]`` with its motion errors, ``[array]``, ``[schedule]``,
optional ``[recording]``), arrays of tables for ``[[sonobuoys]]`` and ``[[targets]]`` (``kind =
"points"`` or ``"mesh"``; a mesh by file path, relative to the TOML file, or inline). Keys are the
classes' field names, in SI units and radians. Every preset of :mod:`clsas.scene.presets` writes
and reads back as the same Scenario, bit for bit.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from ... import budget, validate
from ...errors import ScenarioFileError
from ...scene.scenario import Scenario
from ... import atomic
from .read import parse
from .write import document, dumps, write_ply

#: bytes in memory per byte of TOML text while it is parsed (Python objects for its numbers)
TEXT_BYTES_FACTOR = 40

__all__ = ["load_scenario", "scenario_from_toml", "scenario_to_toml"]


def load_scenario(path: str | os.PathLike) -> Scenario:
    """The Scenario of the TOML file ``path``; mesh files are found relative to its folder.

    Raises TypeError for a path that is not a str or os.PathLike, FileNotFoundError when
    ``path`` is not a file, or :class:`clsas.errors.ScenarioFileError` (a ValueError) naming
    the file, the key path, what is wrong and the line: ``scene.toml: [waveform].bandwidth:
    must be in (0, 3e+05) Hz (0 < B < 2 f0), got -2 (line 7)``; a file that is not UTF-8 text
    (an echo file given by mistake), nested too deeply or over the memory budget is named too.
    """
    path = _path("load_scenario path", path)
    return parse(_read_text(path), source=path.name, base=path.resolve().parent)


def _path(name: str, value) -> Path:
    if not isinstance(value, (str, os.PathLike)) or isinstance(value, bytes):
        raise TypeError(f"{name}: must be a file name (str or os.PathLike), got {value!r:.60} ({type(value).__name__})")
    return Path(value)


def _read_text(path: Path) -> str:
    """The UTF-8 text of the regular file ``path`` (a FIFO is refused without being read)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
        raise FileNotFoundError(f"no such scenario file: {path}") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):  # a folder opens too (read-only): refused before fdopen reads it
        os.close(fd)
        raise FileNotFoundError(f"no such scenario file: {path} is not a regular file")
    with os.fdopen(fd, "rb") as f:
        budget.check_bytes(f"load_scenario {path} ({info.st_size} bytes of TOML)", TEXT_BYTES_FACTOR * info.st_size,
                           "a smaller scenario file (meshes in PLY files beside it)")
        raw = f.read()
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ScenarioFileError(f"{path.name}: not a TOML scenario: not UTF-8 text (byte {raw[err.start]:#04x} at "
                                f"offset {err.start}; an echo or image file? those load with clsas.load)") from None


def scenario_from_toml(text: str, base: str | os.PathLike | None = None) -> Scenario:
    """The Scenario of a TOML text (``base``: the folder relative mesh paths start from)."""
    if base is not None:
        base = _path("scenario_from_toml base", base)
    return parse(text, base=base)


def scenario_to_toml(scenario: Scenario, path: str | os.PathLike | None = None,
                     inline_meshes: bool | None = None) -> str | Path:
    """Write ``scenario`` as TOML to ``path`` (returns the Path), or return the text (``path=None``).

    Meshes: written beside ``path`` as ``<stem>.target<i>.ply`` (binary PLY, float64 vertices,
    referenced by file name with ``process = false`` so they read back exactly), or inline as
    ``vertices`` and ``faces`` arrays when ``inline_meshes`` (the default without a path: the
    text then stands alone). Files are written under a temporary name and renamed (the mode
    the umask gives, as any new file). A platform whose motion errors are Python functions
    raises TypeError (sample them first).
    """
    if inline_meshes is not None:
        validate.flag("scenario_to_toml inline_meshes", inline_meshes)
    if path is None:
        if inline_meshes is False:
            raise ValueError("scenario_to_toml inline_meshes: False needs a path to write the mesh files beside")
        return dumps(document(scenario))
    path = _path("scenario_to_toml path", path)
    if path.suffix != ".toml":
        raise ValueError(f"scenario_to_toml path: the file name must end in .toml, got {path.name!r}")
    _check_target(path)
    text = dumps(document(scenario, None if inline_meshes else lambda index, mesh: _mesh_file(path, index, mesh)))
    _write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return path


def _check_target(path: Path) -> None:
    """FileNotFoundError / ValueError / IsADirectoryError naming ``path`` before anything is written."""
    if not path.parent.is_dir():
        raise FileNotFoundError(f"scenario_to_toml path: the folder {str(path.parent)!r} does not exist")
    longest = len(os.fsencode(f"{path.stem}.target0000.ply"))
    if longest > atomic.name_max(path.parent):
        raise ValueError(f"scenario_to_toml path: the file name {path.name[:40]!r}... is too long for the folder "
                         f"{str(path.parent)!r} (at most {atomic.name_max(path.parent)} bytes with its mesh files' "
                         "suffix)")
    if path.exists() and not path.is_file():
        raise IsADirectoryError(f"scenario_to_toml path: {str(path)!r} exists and is not a regular file; not replaced")


def _mesh_file(path: Path, index: int, mesh) -> str:
    name = f"{path.stem}.target{index}.ply"
    _write_atomic(path.parent / name, lambda tmp: write_ply(tmp, mesh.vertices, mesh.faces))
    return name


def _write_atomic(path: Path, write) -> None:
    with atomic.temporary(path) as tmp:
        write(tmp)
        atomic.replace(tmp, path)
