"""Polar grids: the interpolator's error and the oversampling rule, the image plane, a sub-aperture's
(r, v) grid and its points (the package docstring has the rule)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ....interp import tap_table

RHO_STEPS = np.round(np.arange(1.2, 6.01, 0.05), 2)  # oversamplings tried by the sampling rule


@functools.lru_cache(maxsize=2 * RHO_STEPS.size)  # both interpolators, every oversampling
def interpolation_error(taps: int, rho: float) -> float:
    """The largest error |interpolated - exact| of a unit complex exponential at the band edge
    (1 / (2 rho) cycles a sample) over all fractional offsets, for the ``taps``-tap Knab-windowed
    sinc of the tap table at oversampling ``rho``. The table is built and dropped (the uncached
    :func:`clsas.interp.tap_table`: the rule walks many oversamplings, whose tables would push the
    ones in use out of its cache); only the error is kept."""
    table = tap_table.__wrapped__(taps, "knab", float(rho))
    f = 1 / (2 * rho)
    w = np.linspace(0.0, 1.0, table.shape[0])
    x = np.arange(taps) - (taps // 2 - 1)
    return float(np.abs(table @ np.exp(2j * np.pi * f * x) - np.exp(2j * np.pi * f * w)).max())


def oversampling(taps: int, tolerance: float, stages: int) -> float:
    """The smallest rho of RHO_STEPS with interpolation_error(taps, rho) <= tolerance / (2 stages)
    (the rule of the module docstring); a ValueError when no oversampling up to RHO_STEPS[-1]
    reaches it with this interpolator."""
    budget = tolerance / (2 * max(stages, 1))
    for rho in RHO_STEPS:
        if interpolation_error(taps, float(rho)) <= budget:
            return float(rho)
    best = interpolation_error(taps, float(RHO_STEPS[-1]))
    advice = "a larger tolerance" if taps == 8 else "taps=8 or a larger tolerance"
    raise ValueError(f"ffbp tolerance: {tolerance} needs an interpolation error below {budget:.2g} at each of {stages} "
                     f"stages, which the {taps}-tap interpolator does not reach ({best:.2g} at oversampling "
                     f"{RHO_STEPS[-1]}); use {advice}")


@dataclasses.dataclass(frozen=True)
class Plane:
    """The reference plane m . X = offset (m unit normal) and the scene's centroid (m)."""

    normal: np.ndarray
    offset: float
    centroid: np.ndarray

    @classmethod
    def fit(cls, skeleton: np.ndarray) -> "Plane":
        """The plane of the points (K, 3): for points on a plane (within 1e-6 of their extent) that
        plane; for a volume the least-squares plane among those containing the nominal track
        direction y (so that every sub-aperture's circles of (r, v) cross it); a single point or
        a line gets the horizontal plane through them."""
        centroid = skeleton.mean(axis=0)
        spread = skeleton - centroid
        _, s, vt = np.linalg.svd(spread, full_matrices=False)
        if s.size < 2 or s[1] <= 1e-9 * max(s[0], 1e-30):
            normal = np.array([0.0, 0.0, 1.0])
        elif s.size == 3 and s[2] > 1e-6 * s[0]:
            _, _, vt_xz = np.linalg.svd(spread[:, [0, 2]], full_matrices=False)
            normal = np.array([vt_xz[-1][0], 0.0, vt_xz[-1][1]])
        else:
            normal = vt[-1] if s.size == 3 else np.cross(vt[0], vt[1])
        normal = normal / np.linalg.norm(normal)
        if normal[2] < 0:
            normal = -normal
        return cls(normal, float(normal @ centroid), centroid)


@dataclasses.dataclass(frozen=True)
class PolarGrid:
    """A sub-aperture's local polar grid: frame (centre, axis, e1, e2), reference plane, and the
    samples r0 + i dr (i < n_r), v0 + j dv (j < n_v). Images on it are (n_v, n_r), range fastest.
    ``spans`` (n_v, 2) int32: row j's samples lo <= i < hi are computed and the others are zero
    (the ragged wedge of the module docstring; None: every sample of every row)."""

    centre: np.ndarray
    axis: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    plane: Plane
    r0: float
    dr: float
    n_r: int
    v0: float
    dv: float
    n_v: int
    spans: np.ndarray | None = dataclasses.field(default=None, compare=False)

    @property
    def size(self) -> int:
        """Samples stored (n_v x n_r: an image's layout)."""
        return self.n_r * self.n_v

    @property
    def row_spans(self) -> np.ndarray:
        """(n_v, 2) int32: each row's computed samples [lo, hi)."""
        if self.spans is None:
            return np.tile(np.array([0, self.n_r], np.int32), (self.n_v, 1))
        return self.spans

    @functools.cached_property
    def computed(self) -> int:
        """Samples computed (inside the rows' spans): the work of making or merging this image (counted
        once a grid: the planner and the call's provenance ask it of every grid again and again; a
        grid's spans are not changed in place, a grid with other spans is another PolarGrid)."""
        return self.size if self.spans is None else int(np.sum(self.spans[:, 1] - self.spans[:, 0]))

    def inside(self) -> np.ndarray:
        """(n_v, n_r) bool: the samples inside their rows' spans (an image is zero elsewhere)."""
        spans = self.row_spans
        i = np.arange(self.n_r)[None, :]
        return (i >= spans[:, :1]) & (i < spans[:, 1:])

    @property
    def ranges(self) -> np.ndarray:
        return self.r0 + self.dr * np.arange(self.n_r)

    @property
    def sines(self) -> np.ndarray:
        return self.v0 + self.dv * np.arange(self.n_v)

    def points(self, rows=slice(None), cols=slice(None)) -> np.ndarray:
        """The 3-D points X(r, v) of the samples (n_v, n_r, 3) (or of the v rows ``rows`` and the
        range samples ``cols``, slices or index arrays), m, float64."""
        return _on_plane(self.ranges[cols][None, :], self.sines[rows][:, None], *_frame_terms([self]))

    def coordinates(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(r, v) of points x (..., 3) in this frame, float64."""
        d = x - self.centre
        r = np.linalg.norm(d, axis=-1)
        return r, (d @ self.axis) / np.where(r > 0, r, 1.0)


def _frame_terms(grids: list) -> tuple:
    """Frames of polar grids on one plane (normal m) as :func:`_on_plane` takes them, a row a grid:
    centre, axis, e1, e2 (n, 3), offset - m . centre, m . axis and m . e2 (n,)."""
    m, offset = grids[0].plane.normal, grids[0].plane.offset
    return tuple(np.array(x, np.float64) for x in zip(*[(g.centre, g.axis, g.e1, g.e2, offset - m @ g.centre,
                                                          m @ g.axis, float(m @ g.e2)) for g in grids]))


def _on_plane(r, v, centre, axis, e1, e2, offset, along, across) -> np.ndarray:
    """X(r, v) (..., 3) on the reference plane (module docstring) of ranges r and sines v (broadcast
    together, shape ...) in frames (:func:`_frame_terms`, broadcast with them, or one frame's), element
    by element: a sample gets the same point however many are computed at once."""
    if centre.shape[0] == 1:  # one frame for every sample
        centre, axis, e1, e2, offset, along, across = (x[0] for x in (centre, axis, e1, e2, offset, along, across))
    rho = r * np.sqrt(np.clip(1 - v * v, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_phi = np.clip((offset - r * v * along) / (rho * across), -1.0, 1.0)
    sin_phi = np.where(rho > 0, sin_phi, 0.0)
    cos_phi = np.sqrt(1 - sin_phi * sin_phi)
    return centre + (r * v)[..., None] * axis + (rho * cos_phi)[..., None] * e1 + (rho * sin_phi)[..., None] * e2


def points_of(grids: list, rows: list, cols: list) -> np.ndarray:
    """:meth:`PolarGrid.points` of the samples rows[k] x cols[k] (index arrays) of grids k (on one
    plane), all at once: (sum of their counts, 3) m, grid by grid, row-major (the same values)."""
    which = np.repeat(np.arange(len(grids)), [len(a) * len(b) for a, b in zip(rows, cols)])
    row = np.concatenate([np.repeat(np.asarray(a, np.int64), len(b)) for a, b in zip(rows, cols)])
    col = np.concatenate([np.tile(np.asarray(b, np.int64), len(a)) for a, b in zip(rows, cols)])
    return points_at(grids, which, row, col)


def points_at(grids: list, which: np.ndarray, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """:meth:`PolarGrid.points` of the samples (row[i], col[i]) of grids[which[i]] (on one plane;
    int64 index arrays (n,)): (n, 3) m, the same values."""
    r0, dr, v0, dv = (np.array([getattr(g, k) for g in grids], np.float64) for k in ("r0", "dr", "v0", "dv"))
    return _on_plane(r0[which] + dr[which] * col, v0[which] + dv[which] * row, *(x[which] for x in _frame_terms(grids)))
