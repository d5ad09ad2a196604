"""Grid: the pixel positions an imager forms its image on."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import budget
from .. import validate

GRID_BYTES_PER_PIXEL = 80  # a plane's positions (24) and their temporaries while it is built
POSITION_BYTES_PER_PIXEL = 24  # one float64 (x, y, z): a checked copy of given positions


@dataclass(frozen=True, eq=False)
class Grid:
    """Pixel positions to image on: any array of 3-D points with named axes.

    Build one with :meth:`plane` (a horizontal plane at a depth), :meth:`slant` (a plane spanned
    by two direction vectors, e.g. a slant-range plane) or :meth:`points` (any ``(..., 3)``
    array, e.g. a 3-D volume).

    Attributes
    ----------
    positions : float64 ``shape + (3,)``, m
    dims : tuple of str, one name per axis of ``shape``
    axes : dict name -> 1-D float64 coordinate (m, or the index for :meth:`points`)
    """

    positions: np.ndarray
    dims: tuple
    axes: dict
    #: positions built by :meth:`plane`, :meth:`slant` or :meth:`points` (or converted here): no other
    #: array shares their memory, so only their owner (this Grid) can change them; positions given
    #: as an array the caller holds may still change through the caller's views of it (clsas.image.ffbp.reuse)
    _owned: bool = field(default=False, init=False, repr=False)

    def __post_init__(self):
        if not (isinstance(self.positions, np.ndarray) and self.positions.dtype == np.float64):
            _check_position_bytes("Grid.positions", self.positions)  # converted: a copy
        pos = validate.array("Grid.positions", self.positions, (-1,) * max(2, np.ndim(self.positions)),
                             bound=validate.MAX_COORDINATE, copy=False)
        if pos.ndim < 2 or pos.shape[-1] != 3:
            raise ValueError(f"Grid.positions: must have shape (..., 3), got {pos.shape}")
        if pos.size == 0:
            raise ValueError("Grid is empty: give at least one pixel")
        dims = validate.names("Grid.dims", self.dims)
        if len(dims) != pos.ndim - 1:
            raise ValueError(f"Grid.dims: must name the {pos.ndim - 1} pixel axes, got {dims}")
        given = validate.mapping("Grid.axes", self.axes, none_is_empty=True)
        unknown = sorted(set(given) - set(dims), key=str)
        if unknown:
            raise ValueError(f"Grid.axes: has coordinates for {unknown!r}, which are not dims {dims}")
        axes = {}
        for name, n in zip(dims, pos.shape[:-1]):
            axes[name] = validate.array(f"Grid.axes[{name!r}]", given.get(name, np.arange(n)), (n,),
                                        bound=validate.MAX_COORDINATE)
        pos.flags.writeable = False
        if pos is not self.positions and pos.base is None:  # converted: a copy only this Grid holds
            object.__setattr__(self, "_owned", True)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "dims", dims)
        object.__setattr__(self, "axes", axes)

    @property
    def shape(self) -> tuple:
        return self.positions.shape[:-1]

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    @classmethod
    def plane(cls, x, y, z: float) -> "Grid":
        """Horizontal plane z = ``z`` (m, negative below the surface) on the x (across-track) and
        y (along-track) coordinates given; dims ``("y", "x")``."""
        x, y = _axis("Grid.plane x", x), _axis("Grid.plane y", y)
        if x.size == 0 or y.size == 0:
            raise ValueError(f"Grid.plane x and y: must be non-empty, got shapes {x.shape} and {y.shape}")
        z = validate.scalar("Grid.plane z", z, low=-validate.MAX_COORDINATE, high=validate.MAX_COORDINATE, unit="m")
        budget.check_bytes(f"Grid.plane of {y.size} x {x.size} pixels", GRID_BYTES_PER_PIXEL * x.size * y.size,
                           "fewer pixels (image in tiles)")
        yy, xx = np.meshgrid(y, x, indexing="ij")
        return cls._built(np.stack([xx, yy, np.full_like(xx, z)], axis=-1), ("y", "x"), {"y": y, "x": x})

    @classmethod
    def slant(cls, origin, u_direction, v_direction, u, v, dims=("v", "u")) -> "Grid":
        """Plane ``origin + u_i u_direction + v_j v_direction`` (unit directions, m); shape (len(v), len(u))."""
        origin = validate.vector3("Grid.slant origin", origin)
        du = validate.vector3("Grid.slant u_direction", u_direction)
        dv = validate.vector3("Grid.slant v_direction", v_direction)
        for name, vec in (("u_direction", du), ("v_direction", dv)):
            if not np.isclose(np.linalg.norm(vec), 1.0):
                raise ValueError(f"Grid.slant {name}: must be a unit 3-vector, got {vec}")
        u, w = _axis("Grid.slant u", u), _axis("Grid.slant v", v)
        budget.check_bytes(f"Grid.slant of {w.size} x {u.size} pixels", GRID_BYTES_PER_PIXEL * u.size * w.size,
                           "fewer pixels (image in tiles)")
        pos = origin + w[:, None, None] * dv + u[None, :, None] * du
        return cls._built(pos, tuple(dims), {dims[0]: w, dims[1]: u})

    @classmethod
    def points(cls, positions, dims=None) -> "Grid":
        """Any ``(..., 3)`` array of pixel positions (m); dims default to ``("i0", "i1", ...)``."""
        _check_position_bytes("Grid.points positions", positions)
        pos = validate.array("Grid.points positions", positions, (-1,) * max(1, np.ndim(positions)),
                             bound=validate.MAX_COORDINATE)
        if pos.ndim == 1:
            pos = pos[None]
        if pos.shape[-1] != 3:
            raise ValueError(f"Grid.points positions: must have shape (..., 3) (x, y, z in m), got {pos.shape}")
        dims = tuple(dims) if dims is not None else tuple(f"i{k}" for k in range(pos.ndim - 1))
        return cls._built(pos, dims, {})

    @classmethod
    def _built(cls, positions: np.ndarray, dims, axes) -> "Grid":
        """A Grid of positions just built here (nothing else holds them): marked as its own."""
        grid = cls(positions, dims, axes)
        object.__setattr__(grid, "_owned", True)
        return grid


def _axis(name: str, value) -> np.ndarray:
    """A 1-D coordinate axis (m) from an array or one number."""
    try:
        one = np.ndim(value) == 0
    except (ValueError, TypeError):  # ragged nested lists: validate.array names them
        one = False
    return validate.array(name, [value] if one else value, (-1,), bound=validate.MAX_COORDINATE)


def _check_position_bytes(name: str, positions) -> None:
    """The budget of a checked float64 copy of ``positions`` (from their shape: a broadcast view
    costs its full size once copied), before anything is copied."""
    count = validate.element_count(name, positions)
    budget.check_bytes(f"{name} of {count // 3} pixels", POSITION_BYTES_PER_PIXEL / 3 * count,
                       "fewer pixels (image in tiles)")
