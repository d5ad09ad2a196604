"""Local polar grids of fast factorised back-projection and the rule that samples them.

A sub-aperture (a block of consecutive pulses, every selected receiver) has a *frame*: its
centre C (the mean of its phase centres, the midpoints of transmitter and receiver), its axis
u (the unit chord of the transmitter's track over the block) and the *reference plane* of the
image (the grid's plane; for a 3-D point set the plane fitted to it). A point X has the polar
coordinates

    r = |X - C|  (m),    v = u . (X - C) / r  (the sine of the angle off broadside),

and the polar sample (r, v) stands for the point of the reference plane at that range and
angle, on the scene's side of the axis:

    X(r, v) = C + r v u + r sqrt(1 - v^2) (cos phi e1 + sin phi e2),

e2 the plane normal's part perpendicular to u, e1 = e2 x u turned towards the scene, and
sin phi = (m . (X0 - C) - r v m . u) / (r sqrt(1 - v^2) |m_perp|) from m . X = m . X0 (clipped
to [-1, 1] where the circle of (r, v) misses the plane: those samples serve no pixel).
Pixels of the plane are therefore represented exactly; a pixel off the plane is read at its
own (r, v), i.e. rotated about the axis into the plane, which is exact for phase centres on
the axis (a straight track; the delay depends on r and v alone) and approximate otherwise.

Ragged rows (the wedge). A rectangular (r, v) box around a scene wider along track than its
nearest range holds samples no pixel needs: at a sine v the scene's ranges span only
[r_near(v), r_far(v)] (a rectangle's along-track ends are the lines r v = const), so about a
quarter of a wide scene's box lies outside its wedge. Each row j keeps only its *span* of range
samples [lo_j, hi_j) (:meth:`Extent.spans`): the ranges of the scene's points whose sines lie
within the box's own padding in sine of the row's, widened by the box's padding in range, so
every sample within the box's padding distance of the scene, in both coordinates, is kept as the
box keeps it; the others are not computed and read as zero. The interpolator at any point that
needs exact values (a pixel, or a parent sample within the padding of the scene) reads only
samples within taps / 2 of it, inside the spans, so the image is the box's: the merge kernel and
the leaves skip the rest (tests/test_ffbp.py compares the two on a speckle scene).

Sampling rule (the error model). After demodulation by exp(-j 4 pi f0 r / c) a sub-aperture's
image is band-limited in r and in v; its band follows from the delay of a phase centre at
axial offset a in [-L, L] (L the sub-aperture's half-length, plus its largest offset off the
axis): d(r, v, a) = sqrt(r^2 - 2 r a v + a^2). At frequency f the phase 2 pi f 2 d / c has

    dd/dv = -r a / d,               |2 f dd/dv / c| <= W_v = 2 f_max max|r a / d| / c   cycles per unit v,
    dd/dr = (r - a v) / d,          2 f dd/dr / c - 2 f0 / c in [-W_r, W_r],
                                    W_r = B / c + 2 f_max max(1 - (r - a v) / d) / c     cycles per m,

the maxima taken over a = +-L, v over the grid's span and r = r_min (the nearest scene range;
both bounds fall with r). The first term of W_r is the pulse band (f in f0 +- B/2), the second
the range curvature of a long sub-aperture (its polar image is not band-limited to B alone).
Samples every dr = 1 / (2 W_r rho) and dv = 1 / (2 W_v rho) oversample the band by rho (dv at most
1 / pad, pad the grid's padding in samples: a one-pulse monostatic sub-aperture has W_v = 0, and a
finer step only oversamples more); a
T-tap windowed sinc (Knab's window for that oversampling, :func:`clsas.interp.tap_table`)
then interpolates a band-edge component with an error e_T(rho) (amplitude and phase, relative;
tabulated by :func:`interpolation_error`). A merge tree of S interpolation stages makes 2 S
interpolation errors (range and angle at each stage): rho is
the smallest oversampling with e_T(rho) <= tolerance / (2 S), so that each sub-aperture's
contribution to a pixel keeps its phase and relative amplitude error below ``tolerance`` up to
the edge of the scene (the band edge is the component from the scene's edge). The bound adds
the errors linearly: a band-edge component's interpolation error has the same sign at every
stage (an amplitude loss), so they do not add in power (an rss rule lets a deep tree's error
exceed its tolerance).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ...interp import tap_table

RHO_STEPS = np.round(np.arange(1.2, 6.01, 0.05), 2)  # oversamplings tried by the sampling rule
SKELETON = 8192  # at most about this many pixels stand for the grid when extents are computed
CHUNK_NODES = 8  # sub-apertures whose extents are computed at once (8 x ~8k skeleton points: 0.5 MB arrays, in cache)
ENVELOPE_BINS = 512  # sine bins of a sub-aperture's range envelope of the scene (the ragged rows)
OFFSET_ROWS = 4  # origins whose distances to the skeleton are computed at once (Scene.offsets: in cache)
RAGGED = True  # polar grids computed only within their rows' spans (False: whole rectangles, for comparison)


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

    @property
    def computed(self) -> int:
        """Samples computed (inside the rows' spans): the work of making or merging this image."""
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
    r0, dr, v0, dv = (np.array([getattr(g, k) for g in grids], np.float64) for k in ("r0", "dr", "v0", "dv"))
    return _on_plane(r0[which] + dr[which] * col, v0[which] + dv[which] * row, *(x[which] for x in _frame_terms(grids)))


def _largest_step(positions: np.ndarray, axis: int) -> float:
    """The largest distance (m) between neighbouring pixels along grid axis ``axis`` of positions
    (..., 3), a block of about 2^16 pixels at a time (a 4096^2 grid's whole difference array
    would be 400 MB)."""
    moved = np.moveaxis(positions, axis, 0)
    rows = max(2, (2**16) // max(1, moved[0].size // 3))  # blocks that stay in cache
    largest = 0.0
    for start in range(0, moved.shape[0] - 1, rows - 1):
        part = moved[start:start + rows]
        step = part[1:] - part[:-1]
        step *= step
        largest = max(largest, float((step[..., 0] + step[..., 1] + step[..., 2]).max()))
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
    def _centred(self) -> np.ndarray:
        """The skeleton about the plane's centroid, a coordinate a row (3, K) m."""
        return np.ascontiguousarray((self.skeleton - self.plane.centroid).T)

    def offsets(self, origins: np.ndarray, axes: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """The distances (n, K) m from ``origins`` (n, 3) to the skeleton's points, and with ``axes``
        (n, 3) the points' offsets along them, u . (X - origin) (n, K) m: float64 about the scene's
        centroid, a coordinate at a time and OFFSET_ROWS origins at a time (in place, in cache: no
        (n, K, 3) temporary, no matrix product's threads)."""
        points = self._centred
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
        shape = positions.shape[:-1]
        flat = positions.reshape(-1, 3)
        if flat.shape[0] <= SKELETON:
            return cls(flat.copy(), 0.0, Plane.fit(flat), flat.shape[0])
        stride = int(np.ceil((flat.shape[0] / SKELETON) ** (1 / len(shape))))
        strided = tuple(np.unique(np.r_[np.arange(0, n, stride), n - 1]) for n in shape)
        skeleton = positions[np.ix_(*strided)].reshape(-1, 3)
        # a pixel's index is within stride // 2 of a strided one along each axis; walking there one
        # neighbour at a time moves at most stride // 2 of that axis's largest step per axis
        steps = [_largest_step(positions, k) for k in range(len(shape)) if shape[k] > 1]
        margin = (stride // 2) * float(np.sum(steps)) if steps else 0.0
        return cls(skeleton, margin, Plane.fit(skeleton), flat.shape[0])


def frame_axes(axes: np.ndarray, centres: np.ndarray, plane: Plane) -> tuple[np.ndarray, np.ndarray]:
    """(e1, e2) (n, 3) of frames with unit ``axes`` and ``centres`` (n, 3): e2 the plane normal's
    part perpendicular to the axis (unit), e1 = e2 x axis turned towards the scene's centroid.
    Raises ValueError when the plane is (nearly) perpendicular to an axis (a cross-track vertical
    image plane: the polar grid would be degenerate)."""
    m = plane.normal
    perp = m[None] - (axes @ m)[:, None] * axes
    norm = np.linalg.norm(perp, axis=1)
    if np.any(norm < 0.1):
        raise ValueError("grid: its plane is within 6 degrees of perpendicular to the track, so a sub-aperture's "
                         "polar grid cannot represent it; image it with clsas.backproject")
    e2 = perp / norm[:, None]
    e1 = np.cross(e2, axes)
    e1 *= np.where(np.sum(e1 * (plane.centroid - centres), axis=1) < 0, -1.0, 1.0)[:, None]
    return e1, e2


@dataclasses.dataclass(frozen=True)
class Extent:
    """What a sub-aperture's polar grid covers, before sampling: its frame, the ranges
    [r_lo, r_hi] (m) and sines [v_lo, v_hi] of the scene it sees, its bands W_r (cycles per m)
    and W_v (cycles per unit v) (the module docstring's rule) and ``reach``, the fraction of the
    scene's skeleton (so about the fraction of its pixels) within those ranges and sines."""

    centre: np.ndarray
    axis: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    plane: Plane
    r_lo: float
    r_hi: float
    v_lo: float
    v_hi: float
    w_r: float
    w_v: float
    reach: float = 1.0
    margin: float = 0.0
    envelope: np.ndarray | None = dataclasses.field(default=None, compare=False)
    bins: tuple = (0.0, 1.0)

    def _sampling(self, rho: float, taps: int) -> tuple:
        """(r0, dr, n_r, v0, dv, n_v, pad) of the polar grid at oversampling ``rho`` (:meth:`sample`)."""
        pad = taps // 2 + 2  # the interpolator reads taps / 2 samples either side; 2 more for frame shifts
        dr = 1 / (2 * self.w_r * rho)
        # a sub-aperture of (nearly) zero length (one pulse, monostatic) has no band in v (W_v = 0):
        # any step samples it, so the step is capped to keep the padding within one unit of sine
        # of the scene's (|v| <= 2: points within twice their range of the centre)
        dv = min(1 / (2 * max(self.w_v, 1e-12) * rho), 1.0 / pad)
        n_r = int(np.ceil((self.r_hi - self.r_lo) / dr)) + 1 + 2 * pad
        n_v = int(np.ceil((self.v_hi - self.v_lo) / dv)) + 1 + 2 * pad
        return self.r_lo - pad * dr, dr, n_r, self.v_lo - pad * dv, dv, n_v, pad

    def rows(self, rho: float, taps: int) -> int:
        """The angle rows n_v of :meth:`sample`'s grid (without sampling it)."""
        return self._sampling(rho, taps)[5]

    def size(self, rho: float, taps: int) -> int:
        """The samples n_v x n_r of :meth:`sample`'s grid's (r, v) box (without sampling it)."""
        _, _, n_r, _, _, n_v, _ = self._sampling(rho, taps)
        return n_r * n_v

    def sample(self, rho: float, taps: int) -> PolarGrid:
        """The polar grid at oversampling ``rho``, padded by ``taps // 2 + 2`` samples on every side
        for the interpolator, with its rows' spans (:func:`sample_grids`) when :data:`RAGGED`."""
        return sample_grids([self], rho, taps)[0]


def sample_grids(found: list, rho: float, taps: int) -> list:
    """The polar grids of extents ``found`` at oversampling ``rho`` (:meth:`Extent.sample`), their
    rows' spans computed together (:data:`RAGGED`; extents without an envelope get none).

    Row j's span [lo, hi) of a grid r0 + i dr, v0 + j dv: the ranges of the scene's skeleton points
    whose sines lie within margin / r_lo + pad dv of the row's (the rectangle's own padding in
    sine), widened by margin + pad dr (its padding in range), so that every sample the rectangle
    holds within that distance of the scene is kept; the rest of the rectangle (the corners of the
    (r, v) box outside the scene's wedge) is not computed. The envelope's bins make the sines'
    window up to one bin wider (more kept, never less). The nearest and farthest range over a
    window of bins come from a sparse table of each envelope (extrema over 2^k bins from every
    bin; two overlapping windows of 2^k bins cover any window), all the grids' rows at once."""
    shapes = [e._sampling(rho, taps) for e in found]
    ragged = [k for k, e in enumerate(found) if RAGGED and e.envelope is not None]
    spans = dict(zip(ragged, _spans([found[k] for k in ragged], [shapes[k] for k in ragged]))) if ragged else {}
    return [PolarGrid(e.centre, e.axis, e.e1, e.e2, e.plane, r0, dr, n_r, v0, dv, n_v, spans.get(k))
            for k, (e, (r0, dr, n_r, v0, dv, n_v, _)) in enumerate(zip(found, shapes))]


def _spans(found: list, shapes: list) -> list:
    """The rows' spans (n_v, 2) int32 of each extent sampled as ``shapes`` (sample_grids)."""
    r0, dr, n_r, v0, dv, n_v, pad = (np.array(x) for x in zip(*shapes))
    node = np.repeat(np.arange(len(found)), n_v)  # each row's grid
    row = np.arange(node.size) - np.repeat(np.cumsum(n_v) - n_v, n_v)
    start, width = (np.array(x) for x in zip(*(e.bins for e in found)))
    margin = np.array([e.margin for e in found])
    envelopes = np.stack([e.envelope for e in found])  # (n, n_bins, 2): every extent's bins alike
    n_bins = envelopes.shape[1]
    reach_v = margin / np.maximum([e.r_lo for e in found], 1e-12) + pad * dv
    v = v0[node] + dv[node] * row
    b0 = np.clip(np.floor((v - reach_v[node] - start[node]) / width[node]), 0, n_bins).astype(np.int64)
    b1 = np.clip(np.floor((v + reach_v[node] - start[node]) / width[node]) + 1, 0, n_bins).astype(np.int64)
    lows, highs = [envelopes[:, :, 0]], [envelopes[:, :, 1]]
    while 2 ** len(lows) <= n_bins:
        half = 2 ** (len(lows) - 1)
        lows.append(np.minimum(lows[-1][:, :-half], lows[-1][:, half:]))
        highs.append(np.maximum(highs[-1][:, :-half], highs[-1][:, half:]))
    length = b1 - b0
    k = np.floor(np.log2(np.maximum(length, 1))).astype(np.int64)
    near, far = np.full(node.size, np.inf), np.full(node.size, -np.inf)
    for level in np.unique(k[length > 0]):
        rows = (length > 0) & (k == level)
        grid, first, last = node[rows], b0[rows], b1[rows] - 2 ** level
        near[rows] = np.minimum(lows[level][grid, first], lows[level][grid, last])
        far[rows] = np.maximum(highs[level][grid, first], highs[level][grid, last])
    seen = near <= far
    widen = (margin + pad * dr)[node]
    origin, step, count = r0[node], dr[node], n_r[node]
    with np.errstate(invalid="ignore"):
        lo = np.floor((np.where(seen, near, origin) - widen - origin) / step)
        hi = np.ceil((np.where(seen, far, origin) + widen - origin) / step) + 1
    lo, hi = np.clip(lo, 0, count), np.clip(hi, 0, count)
    spans = np.where(seen[:, None], np.stack([lo, hi], axis=1), 0).astype(np.int32)
    return np.split(spans, np.cumsum(n_v)[:-1])


def extents(centres: np.ndarray, axes: np.ndarray, half_lengths: np.ndarray, scene: Scene, windows: np.ndarray,
            bandwidth: float, f0: float, c: float, sine_limits: np.ndarray | None = None) -> list:
    """The extents of the polar grids of sub-apertures with frames (centres (n, 3) m, unit axes
    (n, 3)) and half-lengths L (n,) m, each covering the scene within its recorded range window
    ``windows`` (n, 2) m (min, max) and, with ``sine_limits`` (n,), the sines |v| <= its limit
    (the integration angle); a range span is that of the pixels within its sines (a sector of a
    long scene is nearer than the scene's far corners). A list of Extent, None where the scene
    lies wholly outside the window or the angular limit. Vectorised over CHUNK_NODES
    sub-apertures at a time (the skeleton's ranges and sines of each)."""
    found = []
    for s in range(0, len(centres), CHUNK_NODES):
        found += _extents(centres[s:s + CHUNK_NODES], axes[s:s + CHUNK_NODES], half_lengths[s:s + CHUNK_NODES],
                          scene, windows[s:s + CHUNK_NODES], bandwidth, f0, c,
                          None if sine_limits is None else sine_limits[s:s + CHUNK_NODES])
    return found


def _extents(centres, axes, half_lengths, scene, windows, bandwidth, f0, c, sine_limits) -> list:
    r, v = scene.offsets(centres, axes)
    with np.errstate(divide="ignore", invalid="ignore"):
        v /= r  # the sines, in place (a point at a centre, r = 0, has none: 0)
    if not r.all():
        v[r == 0] = 0.0
    r_nearest = r.min(axis=1)
    r_lo = np.maximum(r_nearest - scene.margin, windows[:, 0])
    v_margin = scene.margin / np.where(r_lo > 0, r_lo, 1.0)
    v_lo = np.maximum(v.min(axis=1) - v_margin, -1.0)
    v_hi = np.minimum(v.max(axis=1) + v_margin, 1.0)
    alive = r_lo > 0
    if sine_limits is not None:
        v_lo, v_hi = np.maximum(v_lo, -sine_limits), np.minimum(v_hi, sine_limits)
        seen = (v >= (v_lo - v_margin)[:, None]) & (v <= (v_hi + v_margin)[:, None])
        alive &= (v_hi > v_lo) & seen.any(axis=1)
        r_min, r_max = np.where(seen, r, np.inf).min(axis=1), np.where(seen, r, -np.inf).max(axis=1)
        reach = ((v >= v_lo[:, None]) & (v <= v_hi[:, None])).mean(axis=1)
    else:
        r_min, r_max = r_nearest, r.max(axis=1)
        reach = np.ones(len(centres))
    with np.errstate(invalid="ignore"):
        r_lo = np.maximum(r_min - scene.margin, windows[:, 0])
        r_hi = np.minimum(r_max + scene.margin, windows[:, 1])
        alive &= (r_hi >= r_lo) & (r_lo > 0)  # equal for a scene at one range (a single point)
    f_max = f0 + bandwidth / 2
    a = np.stack([-half_lengths, half_lengths], axis=1)[:, :, None]  # (n, 2, 1)
    vv = np.stack([v_lo, v_hi, np.zeros_like(v_lo)], axis=1)[:, None, :]  # (n, 1, 3)
    rr = np.where(alive, r_lo, 1.0)[:, None, None]
    dist = np.sqrt(np.maximum(rr ** 2 - 2 * rr * a * vv + a * a, 1e-30))
    w_v = 2 * f_max * np.max(np.abs(rr * a / dist), axis=(1, 2)) / c
    w_r = bandwidth / c + 2 * f_max * np.max(1 - (rr - a * vv) / dist, axis=(1, 2)) / c
    # the range envelope of the skeleton in ENVELOPE_BINS sine bins over each grid's sines (with
    # their margin): the nearest and the farthest range of the points in each bin
    v_margin = scene.margin / np.where(alive, r_lo, 1.0)
    start = np.where(alive, v_lo - v_margin, 0.0)
    width = np.where(alive, np.maximum(v_hi + v_margin - start, 1e-12), 1.0) / ENVELOPE_BINS
    b = v - start[:, None]
    with np.errstate(invalid="ignore"):
        b /= width[:, None]
    np.floor(b, out=b)
    ok = b >= 0
    ok &= b < ENVELOPE_BINS
    b += (np.arange(len(centres)) * ENVELOPE_BINS)[:, None]  # the bin's index among all the grids' bins
    every = bool(ok.all())  # (no integration angle: every point in its grid's bins) no masked copies
    flat = (b.reshape(-1) if every else b[ok]).astype(np.int64)
    ranges = r.reshape(-1) if every else r[ok]
    near = np.full(len(centres) * ENVELOPE_BINS, np.inf)
    far = np.full(len(centres) * ENVELOPE_BINS, -np.inf)
    np.minimum.at(near, flat, ranges)
    np.maximum.at(far, flat, ranges)
    envelope = np.stack([near, far], axis=1).reshape(len(centres), ENVELOPE_BINS, 2)
    found = []
    e1s, e2s = frame_axes(axes[alive], centres[alive], scene.plane)
    for k, e1, e2 in zip(np.flatnonzero(alive), e1s, e2s):
        found += [None] * (k - len(found))
        found.append(Extent(centres[k], axes[k], e1, e2, scene.plane, float(r_lo[k]), float(r_hi[k]), float(v_lo[k]),
                            float(v_hi[k]), float(w_r[k]), float(w_v[k]), float(reach[k]), scene.margin,
                            envelope[k], (float(start[k]), float(width[k]))))
    return found + [None] * (len(centres) - len(found))
