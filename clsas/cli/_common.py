"""What the sub-commands share: the usage error, argument parsers, output checks, the picture writer."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np


class UsageError(Exception):
    """A command-line mistake: printed as one line, exit status 2."""


def parse_range(text: str, what: str) -> np.ndarray:
    """``"START:STOP:STEP"`` in metres -> the coordinates ``arange(START, STOP, STEP)``."""
    try:
        start, stop, step = (float(v) for v in text.split(":"))
    except ValueError:
        raise UsageError(f"{what}: expected START:STOP:STEP in metres, got {text!r}") from None
    if not (np.isfinite([start, stop, step]).all() and step > 0 and stop > start):
        raise UsageError(f"{what}: need finite START < STOP and STEP > 0, got {text!r}")
    n = int(np.ceil((stop - start) / step))
    if n > 65536:
        raise UsageError(f"{what}: {n} pixels along one axis (at most 65536); raise STEP")
    return start + step * np.arange(n)


def parse_grid(text: str):
    """``"X0:X1:DX,Y0:Y1:DY,Z"`` (m) -> a horizontal Grid.plane."""
    from ..model import Grid

    parts = text.split(",")
    if len(parts) != 3:
        raise UsageError(f"--grid: expected X0:X1:DX,Y0:Y1:DY,Z in metres, got {text!r}")
    x = parse_range(parts[0], "--grid across track (x)")
    y = parse_range(parts[1], "--grid along track (y)")
    try:
        z = float(parts[2])
    except ValueError:
        raise UsageError(f"--grid: the plane's height Z must be a number of metres, got {parts[2]!r}") from None
    try:
        return Grid.plane(x, y, z)
    except ValueError as err:  # coordinates beyond the model's bounds (+-1e6 m), a NaN height
        raise UsageError(f"--grid {text}: {err}") from None


def check_json(option: str, value, overwrite: bool) -> Path:
    """A JSON output (the reproductions' ``--json``), checked before any work as every other
    output is (:func:`clsas.atomic.check_output`: a .json name in an existing folder, an existing
    regular file only with ``overwrite``)."""
    from ..atomic import check_output

    return check_output(option, value, (".json",), overwrite)


def add_overwrite_argument(parser) -> None:
    parser.add_argument("--overwrite", action="store_true",
                        help="replace output files that exist (without it, an existing output is an error)")


def same_file(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` name one file or folder (through links and relative paths)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def check_outputs(data: dict, pictures: dict | None = None, inputs: tuple = (), overwrite: bool = False) -> dict:
    """Every output path checked before any work (option -> value; None skipped): data files
    (.nc, .zarr) by :func:`clsas.io.files.check_target`, pictures (.png, .pdf, .svg) by
    :func:`clsas.plot.check_picture`; none may be an input or another output (UsageError), an
    existing one only with ``overwrite``. Returns option -> Path."""
    from ..io.files import check_target
    from ..plot import check_picture

    checked = {}
    for check, outputs in ((check_target, data), (check_picture, pictures or {})):
        for option, value in outputs.items():
            if value is None:
                continue
            path = Path(value)
            for given in inputs:
                if given is not None and same_file(path, Path(given)):
                    raise UsageError(f"{option} {value}: that is the input file; clsas never writes over its input")
            for other, earlier in checked.items():
                if same_file(path, earlier):
                    raise UsageError(f"{option} {value}: {other} writes that file already")
            checked[option] = check(option, value, overwrite)
    return checked


def write_png(image, path, floor_db: float, title: str) -> None:
    """The image in dB with its range and along-track cuts, written to ``path``."""
    from .. import plot

    fig = plot.image_figure(image, floor_db=floor_db, title=title)
    plot.save_figure(fig, path)
