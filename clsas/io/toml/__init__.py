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
import tempfile
from pathlib import Path

from ...scene.scenario import Scenario
from .read import parse
from .write import document, dumps, write_ply

__all__ = ["load_scenario", "scenario_from_toml", "scenario_to_toml"]


def load_scenario(path: str | os.PathLike) -> Scenario:
    """The Scenario of the TOML file ``path``; mesh files are found relative to its folder.

    Raises FileNotFoundError, or :class:`clsas.errors.ScenarioFileError` (a ValueError) naming
    the file, the key path, what is wrong and the line: ``scene.toml: [waveform].bandwidth:
    must be in (0, 3e+05) Hz (0 < B < 2 f0), got -2 (line 7)``.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such scenario file: {path}")
    return parse(path.read_text(encoding="utf-8"), source=path.name, base=path.resolve().parent)


def scenario_from_toml(text: str, base: str | os.PathLike | None = None) -> Scenario:
    """The Scenario of a TOML text (``base``: the folder relative mesh paths start from)."""
    return parse(text, base=None if base is None else Path(base))


def scenario_to_toml(scenario: Scenario, path: str | os.PathLike | None = None,
                     inline_meshes: bool | None = None) -> str | Path:
    """Write ``scenario`` as TOML to ``path`` (returns the Path), or return the text (``path=None``).

    Meshes: written beside ``path`` as ``<stem>.target<i>.ply`` (binary PLY, float64 vertices,
    referenced by file name with ``process = false`` so they read back exactly), or inline as
    ``vertices`` and ``faces`` arrays when ``inline_meshes`` (the default without a path: the
    text then stands alone). Files are written under a temporary name and renamed.
    A platform whose motion errors are Python functions raises TypeError (sample them first).
    """
    if path is None:
        if inline_meshes is False:
            raise ValueError("scenario_to_toml: inline_meshes=False needs a path to write the mesh files beside")
        return dumps(document(scenario))
    path = Path(path)
    if path.suffix != ".toml":
        raise ValueError(f"scenario_to_toml: the file name must end in .toml, got {path.name!r}")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"scenario_to_toml: the folder {path.parent} does not exist")

    def mesh_file(index: int, mesh) -> str:
        name = f"{path.stem}.target{index}.ply"
        _atomic(path.parent / name, lambda tmp: write_ply(tmp, mesh.vertices, mesh.faces))
        return name

    text = dumps(document(scenario, None if inline_meshes else mesh_file))
    _atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return path


def _atomic(path: Path, write) -> None:
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
