"""Where an extended target's centre lies in its focused tau-eta image: the middle of the image's
extent (not in Kiang & Kiang 2022; derived here for the hull of section II-B).

Why. The chain's Radon slope and focus follow the strongest track in a receiver's record, and on a
hull that is a different scatterer at each receiver (the glint of the near side where the surface
faces that receiver's bistatic bisector: on the scaled Albacore metres apart along the hull
between A, B and C). Each receiver's centroid is then the centroid of another point, and eqs.
(33)-(35) solved at one common position are inconsistent: velocity errors of several % with the
hull's centre given, above the paper's 3 % in some Table II cases.

Derivation. A scatterer displaced by dp from the reference point q has, at receiver h, the
centroid f_h(q + dp) = f_h(q) + g_h.dp (g_h = d f_dc,eq / d p; only the part of dp across the
line of sight counts) and the delay tau_h(q) + (u1 + u2).dp / c (:mod:`.mapping`). After RWC
with the chain's f~ and azimuth compression with its K~, it focuses at

    eta = -(f_h(q + dp) - f~) / K~,        tau = tau_h(q + dp).

So the image of a rigid target is an affine image of the target itself, and the image of its
centre q sits at the centre of the image of the whole target when the target is seen end to end
(the visible near side of a hull spans its whole length; only the far side is hidden). Taking
eta_mid, tau_mid, the middle of the image's extent, in place of the strongest point's,

    f_h(q) = f~ - K~ eta_mid,      tau_h(q) = tau_mid,

gives every receiver the centroid and delay of the same point (the centre) whichever glint
dominates it. For a point target the extent is its symmetric main lobe, so eta_mid and tau_mid
are its peak.

Extent. The image's power is smoothed over :data:`SMOOTH_CELLS` resolution cells each way
(speckle), and the target is every part of the image down to :data:`EXTENT_DB` below its
maximum: a hull's glints and the points of a rigid group alike, however far apart (a group of
points 5 m apart along the track images as separate spots 0.7 s apart at A in Table II case 1;
taking only the spot around the maximum took one point's centroid for the centre's). Another
target moving differently is not focused by this receiver's K and f_dc and stays far below the
level. The extent in eta is the span of what is above the level; in tau, from the first to the
last sample of the range profile above the same level, taken on a copy Hann-weighted over the
band in range (the unweighted range sidelobes, -13 to -21 dB, would reach the level unevenly and
move a point's middle by a fraction of a sample). Each end is interpolated (in dB) between
samples to where it crosses the level. -20 dB lies
between a hull's body (0 to -15 dB: glints over diffuse facets) and the floor around it (blur
skirts and other echoes, -30 dB and below on the eight Table II cases), and below the near
sidelobes of the unweighted compression (-13, -18 dB), which are symmetric about the peak.
(The velocity errors on the hull: tests/test_moving.py::test_submarine_velocity_within_the_papers_bound
and ``clsas reproduce kiang2022``.)

Noise. A point echo at -15 dB SNR per raw sample compresses to ~35 dB over the noise on 1024
pulses (:func:`clsas.synthesis.echo.noise.add_noise`), and the smoothing, which spreads a
point's peak over its 5 x 5 cells, leaves it ~20 dB over the smoothed noise: a level 20 dB below
the peak alone then lies in the noise, and the extent filled the window. So each range column's noise floor (its median over the rows: the target
fills a small part of the period) is taken off first, and its spread measured (1.4826 x the
median absolute deviation, per column: columns near or beyond the ends of the recording window
hold less noise or none); a cell is part of the target when it is above the level and
:data:`NOISE_SIGMAS` spreads out of its column's noise, in a connected region that reaches
:data:`DETECT_SIGMAS` somewhere (or holds the maximum). In range, a sample of the profile counts
when the weighted image is also :data:`DETECT_SIGMAS` out of its noise in one of the region's
rows. In a noise-free image the spread is ~0 and the extent is the level's alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import label, uniform_filter

#: The extent's level below the profile's maximum, dB (module docstring).
EXTENT_DB = 20.0
#: Smoothing of the image, resolution cells.
SMOOTH_CELLS = 5.0
#: A cell of the target stands this many robust standard deviations of the smoothed noise out of
#: its column's floor (module docstring, "Noise").
NOISE_SIGMAS = 4.0
#: A region above the level is part of the target only when it reaches this many (or holds the
#: image's maximum): noise crosses :data:`NOISE_SIGMAS` in places, not this.
DETECT_SIGMAS = 12.0


@dataclass(frozen=True)
class Extent:
    """A target's extent in its focused image: ``eta`` = (start, end) s and ``tau`` = (start,
    end) s, both at :data:`EXTENT_DB` below their profile's maximum; ``eta_mid`` and ``tau_mid``
    their middles. ``peak_db``: the image's largest |value|^2 over its median, dB (a focused
    target stands far out of its noise; a record focused with a wrong rate does not)."""

    eta: tuple
    tau: tuple
    peak_db: float = float("nan")

    @property
    def eta_mid(self) -> float:
        return 0.5 * (self.eta[0] + self.eta[1])

    @property
    def tau_mid(self) -> float:
        return 0.5 * (self.tau[0] + self.tau[1])


def _ends(profile: np.ndarray, axis: np.ndarray, first: int, last: int, level: float) -> tuple[float, float]:
    """The run ``first``..``last`` of ``profile`` (>= ``level`` inside) on ``axis``, each end moved
    to where the profile crosses ``level`` between it and its outer neighbour (linearly in dB)."""

    def crossing(inside: int, outside: int) -> float:
        if outside < 0 or outside >= profile.size:
            return float(axis[inside])
        a, b = np.log(profile[inside]), np.log(max(float(profile[outside]), 1e-30 * level))
        t = float(np.clip((a - np.log(level)) / (a - b), 0.0, 1.0)) if a > b else 0.0
        return float(axis[inside] + t * (axis[outside] - axis[inside]))

    return crossing(first, first - 1), crossing(last, last + 1)


def extent(image: np.ndarray, eta: np.ndarray, tau: np.ndarray, eta_cell: float, tau_cell: float,
           level_db: float = EXTENT_DB, smooth_cells: float = SMOOTH_CELLS, noise_sigmas: float = NOISE_SIGMAS,
           detect_sigmas: float = DETECT_SIGMAS) -> Extent:
    """The extent of the target in a focused image (module docstring).

    Parameters
    ----------
    image : (n_eta, n_tau) complex or real, the focused target (azimuth-compressed after RCMC and
        RWC) and its neighbourhood.
    eta, tau : (n_eta,), (n_tau,) s, ascending, uniformly spaced.
    eta_cell, tau_cell : the azimuth and range resolution cells, s (1 / (|K| T_a), 1 / B).
    level_db, smooth_cells, noise_sigmas, detect_sigmas : see :data:`EXTENT_DB`,
        :data:`SMOOTH_CELLS`, :data:`NOISE_SIGMAS`, :data:`DETECT_SIGMAS`.
    """
    if image.ndim != 2 or image.shape != (eta.size, tau.size) or min(image.shape) < 2:
        raise ValueError(f"image must be (n_eta, n_tau) = ({eta.size}, {tau.size}) with both >= 2, got {image.shape}")
    widths = _odd_widths(smooth_cells, (eta_cell, eta), (tau_cell, tau))
    # the range extent on a copy Hann-weighted over the band (sidelobes -31 dB): the unweighted
    # range sidelobes (-13 to -21 dB) reach the level and would move a point's ends unevenly
    f = np.fft.fftfreq(tau.size, float(tau[1] - tau[0]))
    weight = np.where(np.abs(f) <= 0.5 / tau_cell, 0.5 * (1 + np.cos(2 * np.pi * f * tau_cell)), 0.0)
    # the azimuth compression's image is one period of a DFT in eta: smoothed round it ("nearest"
    # repeated the first and last rows, whose smoothed noise then spread wider than the rest and
    # stood 13.6 robust sigmas out at the period's edge in a noise-only record: Table II case 6 at
    # A, -17 dB, seed 21, where that edge joined the extent and the velocity went 49 % off)
    modes = ("wrap", "nearest")
    weighted = uniform_filter(np.abs(np.fft.ifft(np.fft.fft(image, axis=1) * weight, axis=1)).astype(np.float32) ** 2,
                              widths, mode=modes)
    smooth = uniform_filter(np.abs(image).astype(np.float32) ** 2, widths, mode=modes)
    smooth, z = _above_floor(smooth)
    weighted, weighted_z = _above_floor(weighted)
    peak = np.unravel_index(int(np.argmax(smooth)), smooth.shape)
    level = float(smooth[peak]) * 10.0 ** (-level_db / 10.0)
    # a hull's glints, a rigid group's points: every region above the level and out of the noise
    # that reaches the detection level (a target that does not stand out of the noise is its
    # maximum alone)
    blob = _detected(smooth >= level, z, peak, noise_sigmas, detect_sigmas)
    rows, cols = np.flatnonzero(blob.any(axis=1)), np.flatnonzero(blob.any(axis=0))
    masked = np.where(blob, smooth, 0.0)
    # outside the blob the profiles take the smoothed image over the blob's columns / rows, so
    # that each end is interpolated towards its (below-level) neighbour
    eta_profile = np.maximum(masked.max(axis=1), np.where(blob.any(axis=1), 0.0, smooth[:, cols].max(axis=1)))
    # in range: the weighted image over the region's rows, from the first to the last sample at
    # the level below its maximum and out of the noise
    tau_profile = weighted[rows].max(axis=0)
    k = int(np.argmax(tau_profile))
    cut = float(tau_profile[k]) * 10.0 ** (-level_db / 10.0)
    near = np.flatnonzero((tau_profile >= cut) & (weighted_z[rows].max(axis=0) >= detect_sigmas))
    first, last = (int(near[0]), int(near[-1])) if near.size else (k, k)
    return Extent(eta=_ends(eta_profile, eta, rows[0], rows[-1], level), tau=_ends(tau_profile, tau, first, last, cut),
                  peak_db=peak_db(image))


def peak_db(image: np.ndarray) -> float:
    """The image's peak power over its median power, dB (:attr:`Extent.peak_db`)."""
    power = np.abs(image).astype(np.float32) ** 2
    return float(10 * np.log10(max(float(power.max()), 1e-30) / max(float(np.median(power)), 1e-30)))


#: The noise's spread is kept above this fraction of the image's maximum (a noise-free image).
SPREAD_FLOOR = 1e-6


def _above_floor(power: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(``power`` less its noise floor, that in robust standard deviations of the noise), both
    float32 like ``power``: each range column's floor is its median over the rows (the target
    fills a small part of the period), its spread 1.4826 x the median absolute deviation about it
    (per column: columns near or beyond the ends of the recording window hold less noise or
    none), kept above :data:`SPREAD_FLOOR` of the maximum."""
    floor = np.median(power, axis=0)
    excess = (power - floor).astype(np.float32)
    spread = 1.4826 * np.median(np.abs(excess), axis=0)
    spread = np.maximum(spread, SPREAD_FLOOR * max(float(excess.max()), 1e-30))
    return excess, excess / spread


def _detected(above: np.ndarray, z: np.ndarray, peak: tuple, noise_sigmas: float, detect_sigmas: float) -> np.ndarray:
    """Bool mask: the connected regions of ``above`` & (z >= ``noise_sigmas``) that reach z >=
    ``detect_sigmas`` or hold ``peak``: a noise fluctuation that crosses the level is not part
    of the target."""
    candidates = above & (z >= noise_sigmas)
    candidates[peak] = True
    labels, n = label(candidates)
    keep = np.zeros(n + 1, bool)
    keep[np.unique(labels[candidates & (z >= detect_sigmas)])] = True
    keep[labels[peak]] = True
    keep[0] = False
    return keep[labels]

def _odd_widths(cells: float, *axes) -> tuple:
    """The odd number of samples nearest ``cells`` resolution cells along each (cell s, axis (n,) s)
    of ``axes``: an even uniform or maximum filter is centred half a sample off, which would move
    the extent."""
    return tuple(2 * int(round(0.5 * cells * cell / float(axis[1] - axis[0]))) + 1 for cell, axis in axes)
