"""Plots of images and range/azimuth cuts in dB (matplotlib, the optional ``plot`` extra)."""

from __future__ import annotations

import numpy as np

from .data import Image


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError as err:
        raise ImportError("plotting needs matplotlib: pip install 'clsas[plot]'") from err
    return plt


def plot_image(image: Image, floor_db: float = -50.0, ax=None, title: str | None = None):
    """Show a 2-D ``Image`` in dB (0 dB at the peak, clipped at ``floor_db``); returns the axes.

    The first dim runs vertically, the second horizontally; the axes are labelled with the
    dim names and their coordinates (m or s).
    """
    if image.data.ndim != 2:
        raise ValueError(f"plot_image needs a 2-D image, got dims {image.dims}")
    plt = _pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 5))
    rows, cols = image.dims
    ext = [image.axes[cols][0], image.axes[cols][-1], image.axes[rows][0], image.axes[rows][-1]]
    shown = ax.imshow(image.db(floor_db), extent=ext, origin="lower", aspect="auto", cmap="viridis",
                      vmin=floor_db, vmax=0)
    ax.set_xlabel(cols)
    ax.set_ylabel(rows)
    ax.set_title(title or image.provenance.get("algorithm", ""))
    ax.figure.colorbar(shown, ax=ax, label="dB")
    return ax


def plot_cut(axis, values, ax=None, label: str | None = None, floor_db: float = -60.0):
    """Plot a 1-D cut ``values`` against ``axis`` in dB relative to its peak; returns the axes."""
    plt = _pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 3))
    mag = np.abs(np.asarray(values, dtype=np.complex128))
    with np.errstate(divide="ignore"):
        db = np.maximum(20 * np.log10(mag / mag.max()), floor_db)
    ax.plot(axis, db, label=label)
    ax.set_ylabel("dB")
    ax.grid(True, alpha=0.3)
    if label:
        ax.legend()
    return ax


def save_figure(ax, path) -> None:
    """Write the figure of ``ax`` to ``path`` (PNG, PDF, ... by extension)."""
    ax.figure.savefig(path, dpi=120, bbox_inches="tight")
    _pyplot().close(ax.figure)
