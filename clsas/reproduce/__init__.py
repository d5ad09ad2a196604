"""Reproductions of the source papers' tables, run by ``clsas reproduce PAPER``.

Each paper is one module here, named by its preset (``kiang2022``, ``zhang2019``, ``wu2018``,
``heremans2009``, ...). A module provides

- ``add_arguments(parser: argparse.ArgumentParser) -> None``: its own options;
- ``run(args: argparse.Namespace) -> int``: prints the table beside the paper's values, writes
  its figures, returns the process exit code.

Its docstring's first line is the help text. Modules are found by name, so a paper joins the
command by adding its module; nothing here lists them.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import pkgutil
from types import ModuleType


NOT_PAPERS = ("report",)  # modules here that serve the reproductions


def paper_names() -> list[str]:
    """The reproduction modules' names, sorted (nothing imported)."""
    return sorted(m.name for m in pkgutil.iter_modules(__path__)
                  if not m.name.startswith("_") and m.name not in NOT_PAPERS)


def paper(name: str) -> ModuleType:
    """The reproduction module of ``name`` (one of :func:`paper_names`)."""
    names = paper_names()
    if not isinstance(name, str) or name not in names:
        raise ValueError(f"paper: must be one of {tuple(names)}, got {name!r}")
    return importlib.import_module(f"{__name__}.{name}")


def summary(name: str) -> str:
    """The first line of ``name``'s docstring, read from its source (the module is not imported)."""
    origin = importlib.util.find_spec(f"{__name__}.{name}").origin
    with open(origin, encoding="utf-8") as f:
        doc = ast.get_docstring(ast.parse(f.read())) or name
    return doc.strip().splitlines()[0]


def papers() -> dict[str, ModuleType]:
    """The reproduction modules by paper name, sorted."""
    return {name: paper(name) for name in paper_names()}
