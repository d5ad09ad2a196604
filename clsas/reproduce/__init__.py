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

import importlib
import pkgutil
from types import ModuleType


def papers() -> dict[str, ModuleType]:
    """The reproduction modules by paper name, sorted."""
    names = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))
    return {name: importlib.import_module(f"{__name__}.{name}") for name in names}
