"""Plots of images and range/azimuth cuts in dB (matplotlib, the optional ``plot`` extra).

Nothing here changes matplotlib's backend: :func:`plot_image` and :func:`plot_cut` draw on the
axes given or on new pyplot axes (so they show inline in Jupyter), and :func:`image_figure`
builds a stand-alone ``matplotlib.figure.Figure`` that is not registered with pyplot (for
files written by scripts and the CLI; Jupyter displays it too).

Axes are labelled with the direction and unit of the image's dims (x across track, y along
track, m; eta slow time, tau fast time, s); two axes in the same unit are drawn to equal scale.
"""

from __future__ import annotations

import numpy as np

from .model import AXIS_UNITS, Image

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
    if image.data.ndim != 2:
        raise ValueError(f"plot_image needs a 2-D image, got dims {image.dims}")
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
    if ax is None:
        _, ax = _pyplot().subplots(figsize=(6, 3))
    mag = np.abs(np.asarray(values, dtype=np.complex128))
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
    _matplotlib()
    from matplotlib.figure import Figure

    if image.data.ndim != 2:
        raise ValueError(f"image_figure needs a 2-D image, got dims {image.dims}")
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


def save_figure(figure_or_ax, path) -> None:
    """Write a Figure (or the figure of axes ``ax``) to ``path`` (PNG, PDF, ... by extension);
    a pyplot figure is closed afterwards."""
    fig = getattr(figure_or_ax, "figure", figure_or_ax)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    import sys

    if "matplotlib.pyplot" in sys.modules:  # a no-op for figures pyplot does not manage
        sys.modules["matplotlib.pyplot"].close(fig)
