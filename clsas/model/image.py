"""Image: a complex image with named axes and how it was formed."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .. import budget, validate
from ._describe import provenance_line, span

#: (units, long_name) of image axes by dim name; other dims get ("1", "<name> coordinate").
AXIS_UNITS = {
    "x": ("m", "across-track position x"),
    "y": ("m", "along-track position y"),
    "z": ("m", "height z (negative below the surface)"),
    "u": ("m", "slant-plane coordinate u"),
    "v": ("m", "slant-plane coordinate v"),
    "r": ("m", "slant range"),
    "eta": ("s", "slow time (emission time)"),
    "tau": ("s", "fast time after emission"),
}


@dataclass(frozen=True, eq=False)
class Image:
    """A complex image with named axes and the record of how it was formed.

    Attributes
    ----------
    data : complex64 array
        Pixel values; its axes are named by ``dims`` (e.g. ``("y", "x")``: along track by
        across track; ``("eta", "tau")`` for an image in slow/fast time).
    dims : tuple of str
    axes : dict name -> 1-D float64 array
        Coordinate of each dim (m, or s for time axes); one entry per dim, of matching length.
    provenance : dict
        Algorithm and parameters.
    positions : float64 array ``data.shape + (3,)``, optional
        World positions of the pixels (m) when they do not follow from the axes alone
        (slant planes, arbitrary 3-D pixel sets).
    """

    data: np.ndarray
    dims: tuple
    axes: dict
    provenance: dict = field(default_factory=dict)
    positions: np.ndarray | None = None

    def __post_init__(self):
        data = np.asarray(self.data)
        if data.dtype.kind not in "iufc":
            raise TypeError(f"Image.data: must be an array of numbers, got dtype {data.dtype}")
        if data.dtype != np.complex64:
            budget.check_bytes(f"Image.data as complex64 ({' x '.join(map(str, data.shape))} pixels)",
                               8.0 * data.size, "a smaller image")
            data = data.astype(np.complex64)
        dims = validate.names("Image.dims", self.dims)
        if len(dims) != data.ndim:
            raise ValueError(f"Image.dims: must name each of the {data.ndim} axes once, got {dims}")
        given = validate.mapping("Image.axes", self.axes)
        extra = sorted(set(given) - set(dims), key=str)
        if extra:
            raise ValueError(f"Image.axes: has coordinates for unknown dims {extra}")
        axes = {}
        for name, n in zip(dims, data.shape):
            if name not in given:
                raise ValueError(f"Image.axes: lacks the coordinate of dim {name!r}")
            axes[name] = validate.array(f"Image.axes[{name!r}]", given[name], (n,))
        if self.positions is not None:
            pos = validate.array("Image.positions", self.positions, data.shape + (3,), copy=False)
            object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "dims", dims)
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "provenance", validate.mapping("Image.provenance", self.provenance))

    @classmethod
    def on_grid(cls, data: np.ndarray, grid, provenance: dict) -> "Image":
        """An imager's result on ``grid``'s pixels (a :class:`clsas.model.Grid`): ``data``
        complex64 of the grid's shape, the grid's dims, axes and positions as the Grid holds them
        (checked when it was made, so not again: a pass over every pixel's position) and
        ``provenance`` (checked)."""
        data = np.asarray(data)
        if data.dtype != np.complex64 or data.shape != grid.shape:
            raise ValueError(f"Image.on_grid data: must be complex64 of the grid's shape {grid.shape}, got "
                             f"{data.dtype} {data.shape}")
        return cls._checked(data=data, dims=tuple(grid.dims), axes=dict(grid.axes), positions=grid.positions,
                            provenance=validate.mapping("Image.provenance", provenance))

    @classmethod
    def _checked(cls, **values) -> "Image":
        """An Image of values checked already, as :meth:`__post_init__` would leave them: every field
        must be given (a TypeError naming those missing or unknown, so a field added to Image
        later cannot be left unset on this path)."""
        names = [f.name for f in dataclasses.fields(cls)]
        if sorted(values) != sorted(names):
            raise TypeError(f"Image._checked: needs exactly the fields {names}, got {sorted(values)}")
        image = object.__new__(cls)
        for name in names:
            object.__setattr__(image, name, values[name])
        return image

    @property
    def shape(self) -> tuple:
        return self.data.shape

    def db(self, floor_db: float | None = None) -> np.ndarray:
        """20 log10 |data| normalised to the peak (0 dB), optionally clipped below at ``floor_db``."""
        mag = np.abs(self.data).astype(np.float64)
        peak = mag.max() if mag.size else 0.0
        if peak == 0:
            raise ValueError("Image.db: the image is all zeros")
        with np.errstate(divide="ignore"):
            out = 20 * np.log10(mag / peak)
        return out if floor_db is None else np.maximum(out, floor_db)

    def replace(self, **changes) -> "Image":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def __repr__(self) -> str:
        axes = ", ".join(f"{d}={span(self.axes[d], '')}".rstrip() for d in self.dims)
        where = "" if self.positions is None else " with pixel positions"
        return (f"<Image {' x '.join(map(str, self.data.shape))} ({self.data.nbytes / 2**20:.1f} MiB) {axes}{where} "
                f"provenance={provenance_line(self.provenance)}>")
