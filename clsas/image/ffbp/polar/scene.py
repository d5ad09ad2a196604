"""The scene every sub-aperture sees: a skeleton of the grid's pixels, its plane, and the
sub-apertures' frames on it."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from .... import validate
from .grids import Plane

SKELETON = 8192  # at most about this many pixels stand for the grid when extents are computed
OFFSET_ROWS = 4  # origins whose distances to the skeleton are computed at once (Scene.offsets: in cache)


def _not_finite() -> ValueError:
    return ValueError("Grid.positions: must be finite everywhere; it has NaN or inf (written into the caller's "
                      "array under the Grid after the Grid was made?)")


def _largest_step(positions: np.ndarray, axis: int) -> float:
    """The largest distance (m) between neighbouring pixels along grid axis ``axis`` of positions
    (..., 3), a block of about 2^16 pixels at a time (a 4096^2 grid's whole difference array
    would be 400 MB). Every pixel is in a difference (when the axis has two or more): a NaN or
    inf among them raises ValueError."""
    moved = np.moveaxis(positions, axis, 0)
    rows = max(2, (2**16) // max(1, moved[0].size // 3))  # blocks that stay in cache
    largest = 0.0
    for start in range(0, moved.shape[0] - 1, rows - 1):
        part = moved[start:start + rows]
        step = part[1:] - part[:-1]
        step *= step
        block = float((step[..., 0] + step[..., 1] + step[..., 2]).max())
        if not np.isfinite(block):
            raise _not_finite()
        largest = max(largest, block)
    return float(np.sqrt(largest))


@dataclasses.dataclass(frozen=True)
class Scene:
    """What every sub-aperture needs to know of the grid: a skeleton of its pixels (K, 3) (every
    ``stride``-th pixel along each grid axis, and the last), the distance ``margin`` (m) within
    which every pixel has a skeleton point, the reference plane and the number of pixels."""

    skeleton: np.ndarray
    margin: float
    plane: Plane
    pixels: int

    @functools.cached_property
    def centred_skeleton(self) -> np.ndarray:
        """The skeleton about the plane's centroid, a coordinate a row (3, K) m."""
        return np.ascontiguousarray((self.skeleton - self.plane.centroid).T)

    def offsets(self, origins: np.ndarray, axes: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """The distances (n, K) m from ``origins`` (n, 3) to the skeleton's points, and with ``axes``
        (n, 3) the points' offsets along them, u . (X - origin) (n, K) m: float64 about the scene's
        centroid, a coordinate at a time and OFFSET_ROWS origins at a time (in place, in cache: no
        (n, K, 3) temporary, no matrix product's threads)."""
        points = self.centred_skeleton
        origins = origins - self.plane.centroid
        r = np.empty((origins.shape[0], points.shape[1]))
        along = None if axes is None else np.empty_like(r)
        term = np.empty((OFFSET_ROWS, points.shape[1]))
        for s in range(0, origins.shape[0], OFFSET_ROWS):
            rows = slice(s, min(s + OFFSET_ROWS, origins.shape[0]))
            square, part = r[rows], term[:rows.stop - s]
            for k in range(3):
                np.subtract(points[k][None], origins[rows, k:k + 1], out=square if k == 0 else part)
                if k == 0:
                    square *= square
                else:
                    part *= part
                    square += part
            np.sqrt(square, out=square)
            if axes is not None:
                a = along[rows]
                np.multiply(axes[rows, 0:1], points[0][None], out=a)
                for k in (1, 2):
                    np.multiply(axes[rows, k:k + 1], points[k][None], out=part)
                    a += part
                a -= np.sum(axes[rows] * origins[rows], axis=1)[:, None]
        return r, along

    @functools.cached_property
    def _search_tree(self):
        """A k-d tree of the skeleton (built once a Scene, which ffbp keeps a Grid's lifetime)."""
        from scipy.spatial import cKDTree

        return cKDTree(self.skeleton)

    def nearest(self, points: np.ndarray) -> np.ndarray:
        """The distance (n,) m from each of ``points`` (n, 3) to its nearest skeleton point (exact:
        a k-d tree's nearest neighbour, not a scan of every pair)."""
        return self._search_tree.query(points)[0]

    @classmethod
    def of(cls, positions: np.ndarray) -> "Scene":
        """The Scene of a grid's positions (..., 3) m (at least one pixel: a Grid has one). Raises
        ValueError when a position is NaN or inf: a Grid checks its positions when made, but one on
        the caller's array (read again every call, :mod:`..reuse`) images what the array holds now,
        and the planner's device maxima would skip a NaN where NumPy's propagate it."""
        shape = positions.shape[:-1]
        flat = positions.reshape(-1, 3)
        if flat.shape[0] == 0:
            raise ValueError("Grid.positions: no pixel; a Scene needs at least one")
        if flat.shape[0] <= SKELETON:
            if not validate.all_finite(flat):
                raise _not_finite()
            return cls(flat.copy(), 0.0, Plane.fit(flat), flat.shape[0])
        stride = int(np.ceil((flat.shape[0] / SKELETON) ** (1 / len(shape))))
        strided = tuple(np.unique(np.r_[np.arange(0, n, stride), n - 1]) for n in shape)
        skeleton = positions[np.ix_(*strided)].reshape(-1, 3)
        # a pixel's index is within stride // 2 of a strided one along each axis; walking there one
        # neighbour at a time moves at most stride // 2 of that axis's largest step per axis
        steps = [_largest_step(positions, k) for k in range(len(shape)) if shape[k] > 1]
        margin = (stride // 2) * float(np.sum(steps)) if steps else 0.0  # (finite: every pixel checked)
        return cls(skeleton, margin, Plane.fit(skeleton), flat.shape[0])


def frame_axes(axes: np.ndarray, centres: np.ndarray, plane: Plane) -> tuple[np.ndarray, np.ndarray]:
    """(e1, e2) (n, 3) of frames with unit ``axes`` and ``centres`` (n, 3): e2 the plane normal's
    part perpendicular to the axis (unit), e1 = e2 x axis turned towards the scene's centroid.
    Raises ValueError when the plane is (nearly) perpendicular to an axis (a cross-track vertical
    image plane: the polar grid would be degenerate)."""
    m = plane.normal
    # m . axis lane-wise in one rounding order (``axes @ m`` goes through BLAS, whose one-row path
    # rounds otherwise: a node's frame would depend on the nodes framed with it)
    along = axes[:, 0] * m[0] + axes[:, 1] * m[1] + axes[:, 2] * m[2]
    perp = m[None] - along[:, None] * axes
    norm = np.linalg.norm(perp, axis=1)
    if np.any(norm < 0.1):
        raise ValueError("grid: its plane is within 6 degrees of perpendicular to the track, so a sub-aperture's "
                         "polar grid cannot represent it; image it with clsas.backproject")
    e2 = perp / norm[:, None]
    e1 = np.cross(e2, axes)
    e1 *= np.where(np.sum(e1 * (plane.centroid - centres), axis=1) < 0, -1.0, 1.0)[:, None]
    return e1, e2
