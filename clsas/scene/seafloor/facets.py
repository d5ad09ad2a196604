"""Speckle facets: the seafloor as many small random scatterers, drawn where the beam reaches.

The x-y plane is cut into square cells of side s (the facet spacing) on a lattice anchored at
x = y = 0. Each cell holds one facet at a uniformly random point of the cell, with a uniformly
random phase; its draws come from a counter-based generator (SplitMix64 of the cell's indices
and the seed), so a cell looks the same whatever part of the seafloor a scenario needs. The
facet sits on the seafloor (its height and normal there) and stands for the surface area of its
cell, A = s^2 sqrt(1 + |grad z|^2); its reflectivity is sqrt(A) exp(i phi), and the echo
synthesis multiplies it per path by sqrt(sigma(theta)) (the sediment's law at the path's
grazing angle: :mod:`clsas.synthesis.occlusion`), so that the mean power of a cell is sigma A.
With ``scatterers_per_cell`` facets in a resolution cell the sum is near a complex Gaussian:
fully developed (Rayleigh) speckle.

Where the beam reaches: only cells within ``extent`` whose along-track distance from the
transmitter's track is at most tan(psi) times their distance from it, for some pulse, are drawn,
with sin(psi) = ``beam_nulls`` lambda / L_tx (the transmitter's sinc beam out to that null; the
whole extent for an omnidirectional transmitter). Cost: one facet per s^2 of the reached area,
about 100 bytes each (position, normal, area, reflectivity, zero velocity) plus the echo
synthesis's per-path work; checked against the memory budget before drawing.

Order: the facets are sorted by along-track band (y in bands of BAND_FACETS facet spacings),
then across track (x) within a band: the facets a pulse's beam reaches are then one contiguous
index range (whole bands, :meth:`Facets.reach_span`), and consecutive facets lie close in range,
so a run of them spans few samples of the echo (the echo synthesis skips whole runs).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ... import budget
from ..targets import Scatterers
from .floor import Seafloor

BYTES_PER_FACET = 160  # the arrays kept (~100 bytes) and the temporaries while drawing
BAND_FACETS = 16  # an along-track band's width, in facet spacings (module docstring)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _splitmix64(x: np.ndarray) -> np.ndarray:
    """SplitMix64's output function of uint64 ``x`` (Steele, Lea & Flood 2014)."""
    with np.errstate(over="ignore"):
        z = x + _GOLDEN
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


def cell_uniforms(i: np.ndarray, j: np.ndarray, seed: int, streams: int) -> np.ndarray:
    """``streams`` uniform numbers in [0, 1) for each cell (i, j) (int arrays of one shape):
    shape ``(streams,) + i.shape``; the same cell and seed give the same numbers."""
    with np.errstate(over="ignore"):
        key = _splitmix64(np.asarray(i).astype(np.int64).view(np.uint64) * np.uint64(0xD6E8FEB86659FD93)
                          ^ _splitmix64(np.asarray(j).astype(np.int64).view(np.uint64)) ^ np.uint64(seed))
        out = np.empty((streams,) + key.shape)
        for s in range(streams):
            key = _splitmix64(key + np.uint64(s + 1))
            out[s] = (key >> np.uint64(11)).astype(np.float64) * 2.0**-53
    return out


def resolution_cell(scenario) -> tuple[float, float]:
    """(c / 2B, along-track resolution) of a scenario's sonar, m: D / 2 with D its shortest
    non-zero element, lambda / 4 when every element is omnidirectional."""
    c = scenario.medium.sound_speed
    wf = scenario.waveform
    lengths = np.concatenate([[scenario.array.tx_length], np.asarray(scenario.receiver_lengths)])
    lengths = lengths[lengths > 0]
    along = 0.5 * lengths.min() if lengths.size else 0.25 * c / wf.f0
    return c / (2 * wf.bandwidth), along


def facet_spacing(seafloor: Seafloor, scenario) -> float:
    """The facet grid's spacing, m: ``facet_spacing``, or sqrt(cell area / scatterers_per_cell)."""
    if seafloor.facet_spacing is not None:
        return seafloor.facet_spacing
    across, along = resolution_cell(scenario)
    return float(np.sqrt(across * along / seafloor.scatterers_per_cell))


def reach_slope(seafloor: Seafloor, scenario) -> float:
    """tan(psi): a facet is in reach of a pulse when its along-track distance from the
    transmitter is at most this times its distance across (inf: everywhere)."""
    length = scenario.array.tx_length
    if seafloor.beam_nulls == 0 or length == 0:
        return np.inf
    s = seafloor.beam_nulls * scenario.waveform.wavelength(scenario.medium) / length
    return np.inf if s >= 1 else float(s / np.sqrt(1 - s * s))


@dataclass(frozen=True, eq=False)
class Facets:
    """A seafloor's facets, sorted by along-track band, then by x (module docstring).

    positions (N, 3) m; normals (N, 3) float32 unit upward; refl (N,) complex128 =
    sqrt(area) exp(i phi); spacing (m); reach (tan psi, :func:`reach_slope`); bands (N,) int64,
    each facet's band floor(y / (BAND_FACETS spacing)), non-decreasing.
    """

    positions: np.ndarray
    normals: np.ndarray
    refl: np.ndarray
    spacing: float
    reach: float
    bands: np.ndarray

    @property
    def count(self) -> int:
        return self.positions.shape[0]

    def scatterers(self) -> Scatterers:
        return Scatterers(self.positions, np.zeros_like(self.positions), self.refl)

    def in_reach(self, tx: np.ndarray, first: int = 0, stop: int | None = None) -> np.ndarray:
        """bool (stop - first,): which facets of ``positions[first:stop]`` are in the beam's
        reach of a transmitter at ``tx`` (3,)."""
        p = self.positions[first:stop]
        if not np.isfinite(self.reach):
            return np.ones(p.shape[0], dtype=bool)
        d = p - tx
        return np.abs(d[:, 1]) <= self.reach * np.hypot(d[:, 0], d[:, 2])

    def across(self, track: np.ndarray) -> float:
        """m: a bound of every facet's distance across track (in x and z) from any transmitter
        position of ``track`` (P, 3), plus 1 m (the ``across`` of :meth:`reach_span`)."""
        if self.count == 0:
            return 0.0
        p = self.positions
        dx = max(abs(a - b) for a in (p[:, 0].min(), p[:, 0].max()) for b in (track[:, 0].min(), track[:, 0].max()))
        dz = max(abs(a - b) for a in (p[:, 2].min(), p[:, 2].max()) for b in (track[:, 2].min(), track[:, 2].max()))
        return float(np.hypot(dx, dz)) + 1.0

    def reach_spans(self, tx: np.ndarray, across: float) -> np.ndarray:
        """int64 (P, 2): :meth:`reach_span` of each transmitter position of ``tx`` (P, 3)."""
        return np.array([self.reach_span(t, across) for t in tx], dtype=np.int64).reshape(-1, 2)

    def reach_span(self, tx: np.ndarray, across: float) -> tuple[int, int]:
        """Index range [first, stop) of the facets that can be in reach of a transmitter at
        ``tx`` (3,), given that no facet is farther than ``across`` (m) from it across track:
        the whole bands that meet |y - tx_y| <= tan(psi) across."""
        if not np.isfinite(self.reach):
            return 0, self.count
        half = self.reach * across
        width = BAND_FACETS * self.spacing
        lo, hi = np.floor((tx[1] - half) / width), np.floor((tx[1] + half) / width)
        return int(np.searchsorted(self.bands, lo, "left")), int(np.searchsorted(self.bands, hi, "right"))


def _column_limits(seafloor: Seafloor, x0: np.ndarray, x1: np.ndarray, track: np.ndarray,
                   reach: float) -> tuple[np.ndarray, np.ndarray]:
    """The y interval (lo, hi) of each facet column [x0, x1] that the beam can reach."""
    ext = seafloor.extent
    lo, hi = np.full(x0.shape, ext[2]), np.full(x0.shape, ext[3])
    if np.isfinite(reach):
        z_lo, z_hi = seafloor.height_range()
        dx = np.maximum.reduce([np.abs(x - track[:, 0].min()) for x in (x0, x1)]
                               + [np.abs(x - track[:, 0].max()) for x in (x0, x1)])
        dz = max(abs(z_lo - track[:, 2].min()), abs(z_lo - track[:, 2].max()),
                 abs(z_hi - track[:, 2].min()), abs(z_hi - track[:, 2].max()))
        half = reach * np.hypot(dx, dz)
        lo = np.maximum(lo, track[:, 1].min() - half)
        hi = np.minimum(hi, track[:, 1].max() + half)
    return lo, hi


@functools.lru_cache(maxsize=1)
def generate(seafloor: Seafloor, scenario) -> Facets:
    """The facets of ``seafloor`` that ``scenario``'s transmitter beam reaches (module docstring),
    read-only. The last result is kept (the echo synthesis asks twice: for the scatterers and
    for their path weights)."""
    s = facet_spacing(seafloor, scenario)
    reach = reach_slope(seafloor, scenario)
    track = scenario.tx_position(scenario.eta)
    ext = seafloor.extent
    cols = np.arange(int(np.floor(ext[0] / s)), int(np.ceil(ext[1] / s)))
    lo, hi = _column_limits(seafloor, cols * s, (cols + 1) * s, track, reach)
    j0 = np.floor(lo / s).astype(np.int64)
    j1 = np.maximum(j0, np.ceil(hi / s).astype(np.int64))
    counts = j1 - j0
    total = int(counts.sum())
    budget.check_bytes(f"Seafloor facets ({total:.3g} at a spacing of {s:.3g} m over the reached part of extent "
                       f"{seafloor.extent.tolist()})", BYTES_PER_FACET * float(total),
                       "a smaller extent, fewer scatterers_per_cell or a larger facet_spacing")
    i = np.repeat(cols, counts)
    j = np.repeat(j0 - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts) + np.arange(total)
    u = cell_uniforms(i, j, seafloor.seed, 3)
    x = (i + u[0]) * s
    y = (j + u[1]) * s
    col_lo, col_hi = np.repeat(lo, counts), np.repeat(hi, counts)
    keep = (x >= ext[0]) & (x <= ext[1]) & (y >= col_lo) & (y <= col_hi)
    x, y = x[keep], y[keep]
    bands = np.floor(y / (BAND_FACETS * s)).astype(np.int64)
    order = np.lexsort((x, bands))
    x, y, phase, bands = x[order], y[order], u[2][keep][order], bands[order]
    del u, i, j, keep, order, col_lo, col_hi
    gx, gy = seafloor.gradient(x, y)
    area = s * s * np.sqrt(1.0 + gx * gx + gy * gy)
    normals = np.stack([-gx, -gy, np.ones_like(gx)], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    positions = np.stack([x, y, seafloor.height(x, y)], axis=-1)
    refl = np.sqrt(area) * np.exp(2j * np.pi * phase)
    normals = normals.astype(np.float32)
    for arr in (positions, normals, refl, bands):
        arr.flags.writeable = False
    return Facets(positions, normals, refl, s, reach, bands)
