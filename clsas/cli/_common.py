"""What the sub-commands share: the usage error, argument parsers, the picture writer."""

from __future__ import annotations

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
    return Grid.plane(x, y, z)


def write_png(image, path, floor_db: float, title: str) -> None:
    """The image in dB with its range and along-track cuts, written to ``path``."""
    from .. import plot

    fig = plot.image_figure(image, floor_db=floor_db, title=title)
    plot.save_figure(fig, path)
