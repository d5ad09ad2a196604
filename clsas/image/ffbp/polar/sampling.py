"""What each sub-aperture's polar grid covers (ranges, sines, bands, reach) and its sampling, with
the ragged rows' spans (the package docstring has the rule)."""

from __future__ import annotations

import dataclasses

import numpy as np

from .grids import PolarGrid
from .offsets import DeviceOffsets, HostOffsets
from .scene import Scene, frame_axes

CHUNK_NODES = 8  # sub-apertures whose extents are computed at once (8 x ~8k skeleton points: 0.5 MB arrays, in cache)
DEVICE_CHUNK_NODES = 256  # ... on the device (one launch a reduction; envelopes of 256 x 8 kB on the device at most)
ENVELOPE_BINS = 512  # sine bins of a sub-aperture's range envelope of the scene (the ragged rows)
RAGGED = True  # polar grids computed only within their rows' spans (False: whole rectangles, for comparison)
# sample_grids' rows' spans this many grids, or rows, at a time (each grid's its own; one call of the bench's
# plans, as many costs ~0.2 ms more): the sparse tables hold ENVELOPE_BINS x 2 float64 a level and grid
# (SPAN_GRID_BYTES), the rows' windows SPAN_ROW_BYTES a row (both counted by ffbp's planning part)
SPAN_GRIDS = 128
SPAN_ROWS = 1 << 14
SPAN_GRID_BYTES = 16 * ENVELOPE_BINS * (ENVELOPE_BINS.bit_length() + 1)
SPAN_ROW_BYTES = 256


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


def sample_grids(found: list, rho, taps: int) -> list:
    """The polar grids of extents ``found`` at oversampling ``rho`` (:meth:`Extent.sample`; one for all
    or one an extent), their rows' spans computed together (:data:`RAGGED`; extents without an
    envelope get none).

    Row j's span [lo, hi) of a grid r0 + i dr, v0 + j dv: the ranges of the scene's skeleton points
    whose sines lie within margin / r_lo + pad dv of the row's (the rectangle's own padding in
    sine), widened by margin + pad dr (its padding in range), so that every sample the rectangle
    holds within that distance of the scene is kept; the rest of the rectangle (the corners of the
    (r, v) box outside the scene's wedge) is not computed. The envelope's bins make the sines'
    window up to one bin wider (more kept, never less). The nearest and farthest range over a
    window of bins come from a sparse table of each envelope (extrema over 2^k bins from every
    bin; two overlapping windows of 2^k bins cover any window), the rows of SPAN_GRIDS grids (at
    most SPAN_ROWS rows, or one grid's) at once: the temporaries stay bounded however many grids
    are sampled, and each grid's spans are its own.""" 
    rhos = [rho] * len(found) if np.ndim(rho) == 0 else rho
    shapes = [e._sampling(float(r), taps) for e, r in zip(found, rhos, strict=True)]
    ragged = [k for k, e in enumerate(found) if RAGGED and e.envelope is not None]
    spans, start = {}, 0
    while start < len(ragged):  # SPAN_GRIDS grids or SPAN_ROWS rows at a time (at least one grid)
        stop, rows = start + 1, shapes[ragged[start]][5]
        while stop < len(ragged) and stop - start < SPAN_GRIDS and rows + shapes[ragged[stop]][5] <= SPAN_ROWS:
            rows += shapes[ragged[stop]][5]
            stop += 1
        part = ragged[start:stop]
        spans.update(zip(part, _spans([found[k] for k in part], [shapes[k] for k in part])))
        start = stop
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
            bandwidth: float, f0: float, c: float, sine_limits: np.ndarray | None = None,
            device_taps: int | None = None) -> list:
    """The extents of the polar grids of sub-apertures with frames (centres (n, 3) m, unit axes
    (n, 3)) and half-lengths L (n,) m, each covering the scene within its recorded range window
    ``windows`` (n, 2) m (min, max) and, with ``sine_limits`` (n, 2), the sines lo <= v <= hi
    (the integration angle); a range span is that of the pixels within its sines (a sector of a
    long scene is nearer than the scene's far corners). A list of Extent, None where the scene
    lies wholly outside the window or the angular limit. The skeleton's ranges and sines are
    reduced (:mod:`.offsets`, the same values either way) by NumPy, CHUNK_NODES sub-apertures at a
    time, or with ``device_taps`` on the OpenCL device, DEVICE_CHUNK_NODES at a time (by ffbp's
    program built for that many merge taps: the call's own, no other build)."""
    step = CHUNK_NODES if device_taps is None else DEVICE_CHUNK_NODES
    found = []
    for s in range(0, len(centres), step):
        part = slice(s, s + step)
        reduced = (HostOffsets(scene, centres[part], axes[part]) if device_taps is None
                   else DeviceOffsets(scene, centres[part], axes[part], device_taps))
        found += _extents(centres[part], axes[part], half_lengths[part], scene, windows[part], bandwidth, f0, c,
                          None if sine_limits is None else sine_limits[part], reduced)
    return found


def _extents(centres, axes, half_lengths, scene, windows, bandwidth, f0, c, sine_limits, reduced) -> list:
    r_nearest, r_far, v_min, v_max = reduced.extremes(far=sine_limits is None)
    r_lo = np.maximum(r_nearest - scene.margin, windows[:, 0])
    v_margin = scene.margin / np.where(r_lo > 0, r_lo, 1.0)
    v_lo = np.maximum(v_min - v_margin, -1.0)
    v_hi = np.minimum(v_max + v_margin, 1.0)
    alive = r_lo > 0
    if sine_limits is not None:
        v_lo, v_hi = np.maximum(v_lo, sine_limits[:, 0]), np.minimum(v_hi, sine_limits[:, 1])
        r_min, r_max, any_seen, reach = reduced.seen(v_lo - v_margin, v_hi + v_margin, v_lo, v_hi)
        alive &= (v_hi > v_lo) & any_seen
    else:
        r_min, r_max = r_nearest, r_far
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
    envelope = reduced.envelope(start, width, ENVELOPE_BINS)
    found = []
    e1s, e2s = frame_axes(axes[alive], centres[alive], scene.plane)
    for k, e1, e2 in zip(np.flatnonzero(alive), e1s, e2s):
        found += [None] * (k - len(found))
        found.append(Extent(centres[k], axes[k], e1, e2, scene.plane, float(r_lo[k]), float(r_hi[k]), float(v_lo[k]),
                            float(v_hi[k]), float(w_r[k]), float(w_v[k]), float(reach[k]), scene.margin,
                            envelope[k], (float(start[k]), float(width[k]))))
    return found + [None] * (len(centres) - len(found))


APERTURE_SLACK = 0.01  # m: the float32 aperture mask's rounding allowance (as backprojection.tiles.aperture_spans)
YAWED = 1e-3  # |w| (an axis' part off y) above which aperture_windows reduces the scene across y (below: at most
# that much sine to gain, not worth a reduction)


def axis_tilt(axes: np.ndarray) -> np.ndarray:
    """min(|u - y|, |u + y|) of each unit axis u (N, 3): how far a sub-aperture's axis turns from the
    y axis, either way along it, which bounds how far a direction's |sine| off u departs from its
    |sine| off y (bp_tile's aperture mask takes the sine off y; a track heading along -y is limited
    as one along +y)."""
    y = np.array([0.0, 1.0, 0.0])
    return np.minimum(np.linalg.norm(axes - y, axis=1), np.linalg.norm(axes + y, axis=1))


def aperture_sines(half_sin: float, tilt: np.ndarray, reach: np.ndarray, r_near: np.ndarray) -> np.ndarray:
    """The largest |v| (n,) (the sine off a sub-aperture's axis, seen from its centre C) of a point at
    a range of at least ``r_near`` (n,) m from C that a pulse of the sub-aperture sees within the
    integration angle, its transmitters within ``reach`` (n,) m of C and its axis turned ``tilt``
    (n,) from the y axis (:func:`axis_tilt`): half_sin + tilt + (E + APERTURE_SLACK) / (r_near - E),
    E = reach (the bound of :func:`within_aperture`'s docstring, solved for the sine), at most 1 (1
    where r_near <= E)."""
    reach = np.asarray(reach, np.float64)
    gap = r_near - reach
    with np.errstate(divide="ignore"):
        turn = np.where(gap > 0, (reach + APERTURE_SLACK) / np.where(gap > 0, gap, 1.0), np.inf)
    return np.minimum(1.0, half_sin + tilt + turn)


def aperture_windows(scene: Scene, centres: np.ndarray, axes: np.ndarray, half_sin: float, reach: np.ndarray,
                     r_near: np.ndarray, device_taps: int | None = None) -> np.ndarray:
    """The sines [lo, hi] (n, 2) off each sub-aperture's axis u (centres C (n, 3), unit axes (n, 3))
    of the scene's points that a pulse of it sees within the integration angle (transmitters within
    ``reach`` (n,) m of C; every point at least ``r_near`` (n,) m from C: the planner passes
    scene.nearest(C) - scene.margin, a bound for every pixel since each lies within the margin of a
    skeleton point, where the nearest phase centre's range would not bound a centre between the
    pulses or inside a turned track's bend): |v| <= :func:`aperture_sines`
    and, for an axis off the y axis, the tighter window from u = (u . y) y + w: v = (u . y) s + |w| t,
    s = y . d the point's sine off y seen from C (|s| <= the sine of aperture_sines without tilt) and
    t = (w / |w|) . d within the skeleton's extremes along w / |w| widened by scene.margin / r_near
    (a reduction as :func:`extents`', ``device_taps`` as there). A track heading along y gets the
    first alone (|w| <= YAWED); one yawed 45 deg the second (the first bounds |v| by nearly 1 there)."""
    limit = aperture_sines(half_sin, axis_tilt(axes), reach, r_near)
    window = np.stack([-limit, limit], axis=1)
    off_y = axes.copy()
    off_y[:, 1] = 0.0
    w = np.linalg.norm(off_y, axis=1)
    yawed = np.flatnonzero(w > YAWED)
    if yawed.size:
        across = off_y[yawed] / w[yawed, None]
        step = CHUNK_NODES if device_taps is None else DEVICE_CHUNK_NODES
        t_min, t_max = np.empty(yawed.size), np.empty(yawed.size)
        for s in range(0, yawed.size, step):
            part, nodes = slice(s, s + step), yawed[s:s + step]
            reduced = (HostOffsets(scene, centres[nodes], across[part]) if device_taps is None
                       else DeviceOffsets(scene, centres[nodes], across[part], device_taps))
            _, _, t_min[part], t_max[part] = reduced.extremes(far=False)
        near = r_near[yawed]
        with np.errstate(divide="ignore"):
            margin = np.where(near > 0, scene.margin / np.where(near > 0, near, 1.0), np.inf)
        sine = np.abs(axes[yawed, 1]) * aperture_sines(half_sin, np.zeros(yawed.size), reach[yawed], near)
        window[yawed, 0] = np.maximum(window[yawed, 0], -sine + w[yawed] * (t_min - margin))
        window[yawed, 1] = np.minimum(window[yawed, 1], sine + w[yawed] * (t_max + margin))
    return window


def within_aperture(grids: list, transmitters: np.ndarray, half_sin: float) -> list:
    """The leaves' polar ``grids`` with their rows' spans cut to the samples that one of their
    pulses may see within the integration angle (the others are zero in a leaf's image: bp_tile's
    mask drops every pulse there), so the first stage does not back-project them;
    ``transmitters`` (L, P, 3) m the transmitter of each leaf's P pulses at emission, ``half_sin``
    = sin(aperture / 2).

    bp_tile keeps a pulse of transmitter T at a sample X when |y . d| <= h |d|, d = X - T (the
    sine off broadside taken off the y axis, h = half_sin), in float32. With C the grid's centre,
    D = X - C (|D| = r, the sample's range, where |v| <= 1: X(r, v) is at range r from C whether or
    not its circle meets the plane; a padding row past |v| = 1 has |D| = r |v| and u . D / |D| =
    +-1, so w = min(|v|, 1) below) and e = T - C, |e| <= E: the gradient of y . z / |z| is at most
    1 / |z| <= 1 / (r - E) along the segment from D to d = D - e, so
    |y . d / |d| - y . D / |D|| <= E / (r - E); and ||y . D / |D|| - |u . D / |D||| <= t =
    min(|y - u|, |y + u|) (u the grid's axis, |u . D / |D|| = w; the second for a track heading
    along -y). So every pulse drops X when w - t - E / (r - E) > h + APERTURE_SLACK / (r - E) (the
    slack covers the float32 test's rounding, as direct back-projection's pulse spans allow), i.e.
    at the ranges r > E + (E + APERTURE_SLACK) / (w - t - h) of a row where the denominator is
    positive (a row's far part outside the cone: its padding rows and the wedge's far corners)."""
    if not grids:
        return []
    centres = np.array([g.centre for g in grids])
    reach = np.sqrt(np.max(np.sum((transmitters - centres[:, None]) ** 2, axis=2), axis=1))  # E (L,)
    tilt = axis_tilt(np.array([g.axis for g in grids]))
    n_v = np.array([g.n_v for g in grids])
    grid = np.repeat(np.arange(len(grids)), n_v)  # each row's grid
    row = np.arange(grid.size) - np.repeat(np.cumsum(n_v) - n_v, n_v)
    v0, dv, r0, dr, n_r = (np.array([getattr(g, k) for g in grids], np.float64)
                           for k in ("v0", "dv", "r0", "dr", "n_r"))
    excess = np.minimum(np.abs(v0[grid] + dv[grid] * row), 1.0) - tilt[grid] - half_sin
    with np.errstate(divide="ignore"):
        cut = np.where(excess > 0, reach[grid] + (reach[grid] + APERTURE_SLACK) / np.where(excess > 0, excess, 1.0),
                       np.inf)
        # the samples i <= (cut - r0) / dr may be seen (one more for the rounding of r0 + i dr)
        last = np.floor(np.minimum((cut - r0[grid]) / dr[grid], n_r[grid])) + 2
    spans = np.concatenate([g.row_spans for g in grids])
    spans[:, 1] = np.minimum(spans[:, 1], np.maximum(last, 0.0)).astype(np.int32)
    spans[spans[:, 1] <= spans[:, 0]] = 0
    return [dataclasses.replace(g, spans=s) for g, s in zip(grids, np.split(spans, np.cumsum(n_v)[:-1]))]
