"""Plots of images and range/azimuth cuts in dB (matplotlib, the optional ``plot`` extra).

Nothing here changes matplotlib's backend: :func:`plot_image` and :func:`plot_cut` draw on the
axes given or on new pyplot axes (so they show inline in Jupyter), and :func:`image_figure`
builds a stand-alone ``matplotlib.figure.Figure`` that is not registered with pyplot (for
files written by scripts and the CLI; Jupyter displays it too).

Axes are labelled with the direction and unit of the image's dims (x across track, y along
track, m; eta slow time, tau fast time, s); two axes in the same unit are drawn to equal scale.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import atomic, validate
from .model import AXIS_UNITS, Image

#: the picture formats :func:`save_figure` writes (matplotlib picks the format by the suffix)
PICTURE_SUFFIXES = (".png", ".pdf", ".svg")

LABELS = {
    "x": "across track x", "y": "along track y", "z": "height z", "u": "slant plane u", "v": "slant plane v",
    "r": "slant range r", "eta": "slow time η", "tau": "fast time τ",
}


def _matplotlib():
    try:
        import matplotlib  # noqa: F401
    except ImportError as err:
        raise ImportError("plotting needs matplotlib: pip install 'clsas[plot]'") from err


def _pyplot():
    _matplotlib()
    import matplotlib.pyplot as plt

    return plt


def axis_label(dim: str) -> str:
    """``"across track x (m)"`` for dim ``x``; unknown dims are shown by name with their unit."""
    unit = AXIS_UNITS.get(dim, ("1", ""))[0]
    return f"{LABELS.get(dim, dim)}" + ("" if unit == "1" else f" ({unit})")


def _unit(dim: str) -> str:
    return AXIS_UNITS.get(dim, ("1", ""))[0]


def plot_image(image: Image, floor_db: float = -50.0, ax=None, title: str | None = None, colorbar: bool = True):
    """Show a 2-D ``Image`` in dB (0 dB at the peak, clipped at ``floor_db``); returns the axes.

    The first dim runs vertically, the second horizontally, labelled with direction and unit;
    equal aspect when both are in the same unit (m by m).
    """
    _check_image("plot_image", image, floor_db)
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6, 5))
    rows, cols = image.dims
    ext = [image.axes[cols][0], image.axes[cols][-1], image.axes[rows][0], image.axes[rows][-1]]
    same = _unit(rows) == _unit(cols) and _unit(rows) != "1"
    shown = ax.imshow(image.db(floor_db), extent=ext, origin="lower", aspect="equal" if same else "auto",
                      cmap="viridis", vmin=floor_db, vmax=0, interpolation="nearest")
    ax.set_xlabel(axis_label(cols))
    ax.set_ylabel(axis_label(rows))
    ax.set_title(title if title is not None else image.provenance.get("algorithm", ""))
    if colorbar:
        ax.figure.colorbar(shown, ax=ax, label="dB re peak")
    return ax


def plot_cut(axis, values, ax=None, label: str | None = None, floor_db: float = -60.0, xlabel: str | None = None):
    """Plot a 1-D cut ``values`` against ``axis`` in dB relative to its peak; returns the axes."""
    values = validate.array("plot_cut values", values, (-1,), dtype=np.complex128)
    axis = validate.array("plot_cut axis", axis, (values.size,))
    validate.scalar("plot_cut floor_db", floor_db, low=-1000.0, high=0.0, high_open=True, unit="dB")
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6, 3))
    mag = np.abs(values)
    peak = mag.max() if mag.size else 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        db = np.maximum(20 * np.log10(mag / peak), floor_db) if peak > 0 else np.full(mag.shape, floor_db)
    ax.plot(axis, db, label=label)
    ax.set_ylabel("dB re peak")
    if xlabel:
        ax.set_xlabel(xlabel)
    ax.grid(True, alpha=0.3)
    if label:
        ax.legend()
    return ax


def image_figure(image: Image, floor_db: float = -50.0, title: str | None = None):
    """A Figure of the image in dB with the cuts through its peak: along the second dim
    (range, for ``("y", "x")`` images) below, along the first (azimuth) to the right.
    Not registered with pyplot; write it with :func:`save_figure`."""
    _check_image("image_figure", image, floor_db)
    _matplotlib()
    from matplotlib.figure import Figure

    rows, cols = image.dims
    fig = Figure(figsize=(9, 7), layout="constrained")
    grid = fig.add_gridspec(2, 2, width_ratios=(3, 1), height_ratios=(3, 1))
    ax = fig.add_subplot(grid[0, 0])
    plot_image(image, floor_db=floor_db, ax=ax, title=title, colorbar=False)
    i, j = np.unravel_index(np.argmax(np.abs(image.data)), image.data.shape)
    ax.axhline(image.axes[rows][i], color="w", lw=0.5, alpha=0.6)
    ax.axvline(image.axes[cols][j], color="w", lw=0.5, alpha=0.6)
    below = fig.add_subplot(grid[1, 0])
    plot_cut(image.axes[cols], image.data[i, :], ax=below, floor_db=floor_db, xlabel=axis_label(cols))
    below.set_title(f"cut at {rows} = {image.axes[rows][i]:.4g}", fontsize=9)
    right = fig.add_subplot(grid[0, 1])
    mag = np.abs(image.data[:, j].astype(np.complex128))
    with np.errstate(divide="ignore", invalid="ignore"):
        db = np.maximum(20 * np.log10(mag / mag.max()), floor_db) if mag.max() > 0 else np.full(mag.shape, floor_db)
    right.plot(db, image.axes[rows])
    right.set_xlabel("dB re peak")
    right.set_ylabel(axis_label(rows))
    right.set_title(f"cut at {cols} = {image.axes[cols][j]:.4g}", fontsize=9)
    right.grid(True, alpha=0.3)
    return fig


def save_figure(figure_or_ax, path) -> Path:
    """Write a Figure (or the figure of axes ``ax``) to ``path`` (PNG, PDF or SVG by its suffix)
    under a temporary name, renamed when complete (:mod:`clsas.atomic`); a pyplot figure is
    closed afterwards. Returns the Path."""
    fig = getattr(figure_or_ax, "figure", figure_or_ax)
    if not hasattr(fig, "savefig"):
        raise TypeError(f"save_figure figure_or_ax: must be a matplotlib Figure or Axes, got {type(fig).__name__}")
    path = check_picture("save_figure path", path)
    with atomic.temporary(path) as tmp:
        fig.savefig(tmp, dpi=120, bbox_inches="tight")
        atomic.replace(tmp, path)
    import sys

    if "matplotlib.pyplot" in sys.modules:  # a no-op for figures pyplot does not manage
        sys.modules["matplotlib.pyplot"].close(fig)
    return path


def check_picture(name: str, value, overwrite: bool = True) -> Path:
    """The Path of a picture to write, checked before anything is drawn
    (:func:`clsas.atomic.check_output` with :data:`PICTURE_SUFFIXES`)."""
    return atomic.check_output(name, value, PICTURE_SUFFIXES, overwrite)


def _check_image(caller: str, image, floor_db) -> None:
    if not isinstance(image, Image):
        raise TypeError(f"{caller} image: must be a clsas Image, got {type(image).__name__}")
    if image.data.ndim != 2:
        raise ValueError(f"{caller} image: must be 2-D, got dims {image.dims}")
    validate.scalar(f"{caller} floor_db", floor_db, low=-1000.0, high=0.0, high_open=True, unit="dB")
