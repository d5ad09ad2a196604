"""DPCA geometry: the nominal pairing of eq. (50), the phase-centre errors of eqs. (48)-(49)
and the beam's mean look angle they depend on."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ... import validate
from ...scene.scenario import Array
from ...scene.seafloor.facets import reach_slope
from ...scene.targets import PointTargets


def nominal_shift(array: Array, speed: float, prf: float) -> tuple[int, np.ndarray]:
    """The nominal pairing of eq. (50): (s, phase-centre along-track offsets o_h / 2 in m).

    s = v PRT / Delta_PC rounded; hydrophone i + s at ping p and i at ping p + 1 coincide.
    speed : m/s (> 0); prf : Hz (> 0)."""
    if not isinstance(array, Array):
        raise TypeError(f"nominal_shift: array must be a clsas Array (the hydrophone layout), got {type(array).__name__}")
    speed = validate.positive("nominal_shift speed", speed, unit="m/s", why="the nominal platform speed")
    prf = validate.positive("nominal_shift prf", prf, unit="Hz", why="the pulse repetition frequency")
    pc = 0.5 * (array.rx_offsets[:, 1] + array.tx_offset[1])
    order = np.argsort(pc)
    if np.any(order != np.arange(pc.size)):
        raise ValueError("dpca: the hydrophones must be numbered along the track (increasing body y)")
    steps = np.diff(pc)
    if pc.size < 3 or not np.allclose(steps, steps[0], rtol=1e-6) or steps[0] <= 0:
        raise ValueError(f"dpca needs a uniform line of >= 3 hydrophones, got phase-centre offsets {pc}")
    shift = speed / prf / steps[0]
    if not shift < pc.size:
        raise ValueError(f"dpca: at speed {speed:g} m/s and PRF {prf:g} Hz the platform advances {shift:.3g} "
                         f"phase-centre spacings a ping, more than the {pc.size} hydrophones span: no "
                         "overlapping phase centres between pings; lower the speed")
    s = int(round(shift))
    return s, pc


def pairing(array: Array, speed: float, prf: float, lags: int) -> tuple[int, np.ndarray, int]:
    """(s, phase-centre offsets, couples common to every x-lag -lags..lags): :func:`nominal_shift`,
    refused when fewer than three couples remain (eq. 50 leaves H - s overlapping phase centres)."""
    s, pc = nominal_shift(array, speed, prf)
    h = array.n_receivers
    n_couples = h - s - lags
    if s < 1 or n_couples < 3:
        raise ValueError(f"dpca: at speed {speed} m/s and PRF {prf:g} Hz the platform advances {s} phase-centre "
                         f"spacings a ping: the {h} hydrophones leave {h - s} overlapping phase centres, "
                         f"{max(n_couples, 0)} couples at x-lag +-{lags} (needs >= 3); lower the speed or lags")
    return s, pc, n_couples


def _elements(array: Array) -> tuple[float, float]:
    """(transmitter length, mean hydrophone length), m."""
    return float(array.tx_length), float(np.mean(array.rx_length))


def _pattern(array: Array, f0: float, c: float, sin_t: np.ndarray) -> np.ndarray:
    """The two-way power pattern P at along-track direction cosines ``sin_t``:
    sinc^2(L_tx sin(theta) / lambda) sinc^2(L_rx sin(theta) / lambda) (clsas's element
    directivity, squared once for the transmit leg and once for the receive leg)."""
    lam = c / f0
    return np.prod([np.sinc(length * sin_t / lam) ** 2 for length in _elements(array)], axis=0)


def _beam(array: Array, f0: float, c: float):
    """(sin theta, P(theta)) over the half-space in front of the array, theta uniform in
    [-90, 90] deg (a range block of a flat seafloor in the track's plane holds its scatterers
    uniformly in theta: area r dr dtheta), P the two-way power pattern (:func:`_pattern`): the
    weight of a scatterer at look angle theta in the couples' correlations, over a seafloor that
    fills the beam. None if both elements are omnidirectional (length 0: the beam is then the
    scene's, which the array cannot know)."""
    if max(_elements(array)) == 0:
        return None
    sin_t = np.sin(np.linspace(-np.pi / 2, np.pi / 2, 4001))
    return sin_t, _pattern(array, f0, c, sin_t)


def _check_beam_args(caller: str, array, f0, c) -> tuple[float, float]:
    if not isinstance(array, Array):
        raise TypeError(f"{caller}: array must be a clsas Array (the hydrophone layout), got {type(array).__name__}")
    f0 = validate.positive(f"{caller} f0", f0, unit="Hz", why="the carrier frequency")
    c = validate.positive(f"{caller} c", c, unit="m/s", why="the sound speed")
    return f0, c


def beam_sin2(array: Array, f0: float, c: float) -> float:
    """<sin^2 theta> over the two-way power pattern (see :func:`_beam`) for a seafloor that fills
    the beam out to +-90 deg; 0 for omnidirectional elements. (lambda / L)^2 3 / (4 pi^2) for
    two equal elements of length L in the small-angle limit (the second moment of sinc^4).
    f0 : carrier, Hz (> 0); c : sound speed, m/s (> 0). For a seafloor of known extent,
    :func:`look_moments` gives the value range block by range block."""
    f0, c = _check_beam_args("beam_sin2", array, f0, c)
    beam = _beam(array, f0, c)
    if beam is None:
        return 0.0
    sin_t, power = beam
    return float(np.sum(sin_t**2 * power) / np.sum(power))


def main_lobe_sin2(array: Array, f0: float, c: float) -> float:
    """<sin^2 theta> over the two-way pattern's main lobe only (|sin theta| < :func:`main_lobe`):
    a seafloor that fills the main lobe and no more; 0 for omnidirectional elements."""
    f0, c = _check_beam_args("main_lobe_sin2", array, f0, c)
    beam = _beam(array, f0, c)
    if beam is None:
        return 0.0
    sin_t, power = beam
    power = np.where(np.abs(sin_t) < main_lobe(array, f0, c), power, 0.0)
    return float(np.sum(sin_t**2 * power) / np.sum(power))


def main_lobe(array: Array, f0: float, c: float) -> float:
    """The two-way main lobe's half-width as a direction cosine: lambda / L at the longer
    element's first null (1 for omnidirectional elements: no main lobe narrower than the
    half-space)."""
    longest = max(_elements(array))
    return 1.0 if longest == 0 else float(min(1.0, c / f0 / longest))


@dataclass(frozen=True)
class SeafloorExtent:
    """Where the seafloor scatters, for :func:`clsas.estimate.dpca.estimate`: a flat rectangle,
    scene frame (clsas axes: x across track towards the imaged side, y along track, z up).

    x : (x_min, x_max), m, its across-track edges (horizontal; x_max may be inf)
    y : (y_min, y_max), m, its along-track edges (either may be inf)
    z : m, its height (the track's height comes from the echo's transmitter positions;
        0 with a track at z = 0 is the papers' 2-D geometry)
    reach : the largest along-track direction cosine |sin theta|, seen from the transmitter,
        at which it scatters (in (0, 1]; 1: everywhere): a clsas Seafloor's facets answer a
        pulse out to its ``beam_nulls``-th null of the transmitter's beam only

    A real seafloor fills the beam (``extent=None`` in the estimator); a simulated patch (random
    point scatterers, a clsas Seafloor) may be narrower or wider than the beam, and the
    phase-centre correction depends on which look angles it holds (:func:`look_moments`).
    :func:`scenario_extent` reads it from the scenario a simulated echo carries (the
    estimator's default).
    """

    x: tuple = (0.0, np.inf)
    y: tuple = (-np.inf, np.inf)
    z: float = 0.0
    reach: float = 1.0

    def __post_init__(self):
        for name in ("x", "y"):
            edges = getattr(self, name)
            if isinstance(edges, (str, bytes)) or not hasattr(edges, "__len__") or len(edges) != 2:
                raise TypeError(f"SeafloorExtent {name}: must be a pair (min, max) in m, got {edges!r}")
            lo, hi = (validate.scalar(f"SeafloorExtent {name}[{k}]", v, low=-np.inf, high=np.inf, unit="m")
                      if validate.is_number(v) and np.isfinite(float(v)) else self._infinite(name, k, v)
                      for k, v in enumerate(edges))
            if not lo < hi:
                raise ValueError(f"SeafloorExtent {name}: must have min < max, got ({lo:g}, {hi:g})")
            object.__setattr__(self, name, (lo, hi))
        if self.x[1] <= 0:
            raise ValueError(f"SeafloorExtent x: the seafloor must reach the imaged side (x_max > 0), got {self.x}")
        object.__setattr__(self, "z", validate.scalar("SeafloorExtent z", self.z, unit="m"))
        object.__setattr__(self, "reach", validate.scalar("SeafloorExtent reach", self.reach, low=0.0, high=1.0,
                                                          low_open=True))

    @staticmethod
    def _infinite(name: str, k: int, value) -> float:
        """+-inf where an edge may be open (x_max, y_min, y_max); anything else is refused."""
        if not validate.is_number(value):
            raise TypeError(f"SeafloorExtent {name}[{k}]: must be a number of m, got {value!r} "
                            f"({type(value).__name__})")
        v = float(value)
        open_ok = {("x", 1): np.inf, ("y", 0): -np.inf, ("y", 1): np.inf}.get((name, k))
        if v != open_ok:
            raise ValueError(f"SeafloorExtent {name}[{k}]: must be finite"
                             f"{'' if open_ok is None else f' or {open_ok}'} m, got {value!r}")
        return v


ANGLES = 2001   # look angles phi over [-90, 90] deg in the tables of look_moments


SUB_RANGES = 8  # ranges per block at which look_moments cuts the seafloor


def look_moments(array: Array, f0: float, c: float, r: np.ndarray, centre: np.ndarray,
                 extent: SeafloorExtent | None, span: float = 0.0,
                 ahead: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What each range block sees of the seafloor: (<sin^2 theta>, main-lobe fraction, content),
    each of shape (pair, block), weighted by the two-way power pattern P (:func:`_pattern`).

    r : m (block,), the blocks' centre ranges; span : m, their length in range (the rectangle
    is cut at SUB_RANGES ranges across it and the weights added: a block across the swath's
    edge holds broadside echoes from its near part only); centre : m (pair, 3), where the
    couples' phase centres are (scene frame) when the blocks' echoes return; extent : the seafloor's
    rectangle, None for a seafloor that fills the beam at the track's depth (then every block
    reads :func:`beam_sin2`, fraction and content of the whole half-space); ahead : m, how far
    along the track the phase centres are ahead of the transmitter (the extent's ``reach`` is
    seen from the transmitter: a scatterer a along track and b across it in slant, counted from
    the transmitter, scatters when |a| <= b tan(asin(reach))).

    A range block at slant range r of a flat seafloor h below the phase centres is the ring of
    ground range rho = sqrt(r^2 - h^2), its scatterers uniform in the ground azimuth phi
    (area rho d rho d phi); a scatterer there is at along-track direction cosine
    sin theta = (rho / r) sin phi. The rectangle cuts the ring to the phi with
    rho cos(phi) in [x_min, x_max] - x_c and rho sin(phi) in [y_min, y_max] - y_c: at most two
    arcs. <sin^2 theta> = int P sin^2 theta dphi / int P dphi over them (from cumulative tables
    per block); main-lobe fraction: the part of int P dphi with |sin theta| < :func:`main_lobe`;
    content: int P dphi / pi (0 where the block holds no seafloor: <sin^2> is then NaN)."""
    f0, c = _check_beam_args("look_moments", array, f0, c)
    r = np.asarray(r, dtype=np.float64)
    centre = np.asarray(centre, dtype=np.float64)
    phi = np.linspace(-np.pi / 2, np.pi / 2, ANGLES)
    omni = max(_elements(array)) == 0
    if extent is None:
        # the whole half-space at the track's depth (theta = phi): the same for every block
        beam = _beam(array, f0, c)
        sin_t, power = (np.sin(phi), np.ones_like(phi)) if beam is None else beam
        sin2 = 0.0 if omni else float(np.sum(sin_t**2 * power) / np.sum(power))
        inside = np.abs(sin_t) < main_lobe(array, f0, c)
        shape = (centre.shape[0], r.size)
        return (np.full(shape, sin2), np.full(shape, float(np.sum(power * inside) / np.sum(power))),
                np.full(shape, float(np.mean(power))))
    sub = (np.arange(SUB_RANGES) + 0.5) / SUB_RANGES - 0.5
    r_blocks, r = r, (r[:, None] + span * sub[None, :]).ravel()               # (block x sub-range,)
    h = float(np.median(centre[:, 2])) - extent.z      # the track's height above the floor (nominal)
    rho = np.sqrt(np.maximum(r**2 - h**2, 0.0))                               # (block,)
    a = np.divide(rho, r, out=np.zeros_like(rho), where=r > 0)
    sin_t = a[:, None] * np.sin(phi)                                          # (block, angle)
    power = np.ones_like(sin_t) if omni else _pattern(array, f0, c, sin_t)
    if extent.reach < 1:
        slope = extent.reach / np.sqrt(1 - extent.reach**2)
        along = rho[:, None] * np.sin(phi) + ahead
        power = np.where(np.abs(along) <= slope * np.hypot(rho[:, None] * np.cos(phi), h), power, 0.0)
    step = phi[1] - phi[0]

    def cumulative(values):
        """int_{-pi/2}^{phi} values dphi (trapezoids), (block, angle)."""
        return np.concatenate([np.zeros(values.shape[:-1] + (1,)),
                               np.cumsum(0.5 * (values[..., 1:] + values[..., :-1]) * step, axis=-1)], axis=-1)

    tables = [cumulative(power), cumulative(power * sin_t**2),
              cumulative(power * (np.abs(sin_t) < main_lobe(array, f0, c)))]
    with np.errstate(divide="ignore", invalid="ignore"):
        x0 = (extent.x[0] - centre[:, 0][:, None]) / rho[None, :]                # (pair, block)
        x1 = (extent.x[1] - centre[:, 0][:, None]) / rho[None, :]
        y0 = (extent.y[0] - centre[:, 1][:, None]) / rho[None, :]
        y1 = (extent.y[1] - centre[:, 1][:, None]) / rho[None, :]
    near = np.arccos(np.clip(np.nan_to_num(x1, nan=-1.0, posinf=1.0, neginf=-1.0), 0.0, 1.0))   # |phi| >= near
    far = np.arccos(np.clip(np.nan_to_num(x0, nan=1.0, posinf=1.0, neginf=0.0), 0.0, 1.0))     # |phi| <= far
    lo = np.arcsin(np.clip(np.nan_to_num(y0, nan=1.0, posinf=1.0, neginf=-1.0), -1.0, 1.0))
    hi = np.arcsin(np.clip(np.nan_to_num(y1, nan=-1.0, posinf=1.0, neginf=-1.0), -1.0, 1.0))
    totals = [np.zeros(x0.shape) for _ in tables]
    for arc_lo, arc_hi in ((np.maximum(lo, -far), np.minimum(hi, -near)), (np.maximum(lo, near), np.minimum(hi, far))):
        arc_hi = np.maximum(arc_hi, arc_lo)
        k_lo, k_hi = (np.clip((edge + np.pi / 2) / step, 0, ANGLES - 1) for edge in (arc_lo, arc_hi))
        for total, table in zip(totals, tables):
            total += _at(table, k_hi) - _at(table, k_lo)
    empty = np.broadcast_to(rho[None, :] <= 0, x0.shape)
    # each sub-range's ring weighs its area, r dr dphi
    sub_weights = [np.where(empty, 0.0, t * r[None, :]).reshape(x0.shape[0], r_blocks.size, SUB_RANGES) for t in totals]
    weight, second, main = (t.sum(axis=-1) for t in sub_weights)
    empty = weight <= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        sin2 = np.where(empty, np.nan, second / weight)
        fraction = np.where(empty, 0.0, main / weight)
    return sin2, fraction, np.where(empty, 0.0, weight / (np.pi * SUB_RANGES * r_blocks[None, :]))


def across_cosine(r: np.ndarray, centre: np.ndarray, extent: SeafloorExtent | None,
                  sin2: np.ndarray) -> np.ndarray:
    """(pair, block): the mean over a range block's seafloor of x . l, the line of sight l's
    component along the horizontal across-track axis x, by which a horizontal displacement of the
    phase centres across the track (a sway gamma; a yaw xi moves the couple at u by -u xi) changes
    the two-way path: by -2 gamma (x . l), not -2 gamma (the estimator's plane geometry).

    r : m (block,), the blocks' centre slant ranges; centre : m (pair, 3), the phase centres
    (:func:`look_moments`); extent : the seafloor (its height sets the depression), None for one
    at the track's depth; sin2 : (pair, block), the blocks' <sin^2 theta> (:func:`look_moments`,
    NaN where a block holds no seafloor: 0 is taken). A scatterer at slant range r, ground range
    rho = sqrt(r^2 - h^2) (h the track's height above the floor) and ground azimuth phi has
    x . l = rho cos(phi) / r = sqrt(a^2 - sin^2 theta), a = rho / r the depression's cosine and
    sin theta = a sin(phi) its along-track direction cosine; averaged over the block's scatterers
    (weighted by the two-way power, as <sin^2 theta>), to first order in sin^2 theta / a^2:
    sqrt(a^2 - <sin^2 theta>). A block's sway and yaw read from the couples' delays are the
    horizontal ones times it (at Heremans' 15 m over 100 m: 0.989). 0 where <sin^2 theta> reaches
    a^2 (the model fails there: :data:`.pairs.MIN_ACROSS` leaves such blocks out)."""
    r = np.asarray(r, dtype=np.float64)
    if extent is None:
        a = np.ones_like(r)
    else:
        h = float(np.median(np.asarray(centre, dtype=np.float64)[:, 2])) - extent.z
        a = np.sqrt(np.maximum(1 - (h / np.maximum(r, abs(h) + 1e-9)) ** 2, 0.0))
    s2 = np.nan_to_num(np.asarray(sin2, dtype=np.float64), nan=0.0)
    return np.sqrt(np.maximum(a[None, :] ** 2 - s2, 0.0))


# A block whose seafloor weight the extent's near or far edge cuts by more than this fraction
# is left out of the estimate (see :func:`inside_swath`).
RANGE_EDGE = 0.02


def inside_swath(array: Array, f0: float, c: float, r: np.ndarray, centre: np.ndarray,
                 extent: SeafloorExtent | None, span: float = 0.0, ahead: float = 0.0,
                 content: np.ndarray | None = None, guard: float = 0.0) -> np.ndarray:
    """(pair, block) bool: True where the seafloor's near and far edges (``extent.x``) leave a
    range block's rings whole over the beam, i.e. its :func:`look_moments` content is within
    RANGE_EDGE of the content of the same seafloor open in range (its near edge moved to the
    track, its far edge to infinity), and where the block's span (``r`` +- ``span`` / 2, m) keeps
    ``guard`` m of slant range from both edges (the slant ranges of x_min and x_max from the
    track at the extent's depth); all True without an extent. A block that holds no seafloor
    at all (before the nearest return, beyond the swath) has no edge in it and reads True
    unless the guard takes it out: :func:`look_moments`' content says whether it holds any.

    A block that holds a range edge of the seafloor holds it unevenly: at the near edge only
    the look angles near broadside reach it at its nearest ranges, at the far edge the wide
    look angles reach beyond the broadside ones. The yaw is biased further in than that: on a
    motionless platform, blocks within a few metres of the near edge read a negative yaw
    (bench/bench_dpca.py --edges; PingPairs.block_yaw shows it on any data). What is known of
    it (issue #30's reports):

    - It is a range edge, not the cut of the rings. A half annulus of seafloor around the track
      has range edges that cut no ring (every ring between them is whole at every look angle);
      its blocks just inside the near edge read a negative yaw and those just inside the far
      edge a positive one, as the rectangles' do, and a rectangle drawn again reaching nearer
      the track takes its zone along (bench_dpca.py --edge-cut). (The near edge of a
      rectangle parallel to the track also cuts the rings, at the along-track direction cosine
      (rho / r) sin(acos(x_0 / rho)), through the main lobe and the first sidelobe within a
      few metres of it; that cut is in :func:`look_moments`, which a Monte Carlo over the
      rectangle reproduces.)
    - It is in each scatterer's own contribution, not in the interference between scatterers:
      simulated one scatterer at a time (nothing to interfere; 4096 Sobol points over the 1x
      seafloor, bench_dpca.py --self-terms) and summed through the estimator's processing, the
      blocks read what the estimator reads on whole seafloors.
    - What makes it is the compressed pulse's range sidelobes, which reach half a pulse length
      c T / 2 from a scatterer (the matched filter's support). A block's correlation holds,
      besides its own scatterers, the sidelobes of scatterers up to c T / 2 away, and those
      carry a yaw error odd in the offset D = r - r_k of the sample from its scatterer: (1)
      the carrier part of :func:`pca_delay` is taken at the sample's range r, right for a
      scatterer's main lobe and wrong by dt_n(r_k) - dt_n(r) ~ -dt_n'(r) D in its sidelobes, a
      phase linear along the couples (about D / r times the uncorrected phase-centre yaw per
      sidelobe sample); (2) a chirp sampled barely above its band folds its spectral skirt into a
      pedestal about -43 dB a sample flat out to +-c T / 2, at frequencies the carrier and
      envelope corrections do not assume. Measured on single scatterers: sidelobes from 2-6 m
      away read hundreds to two thousand urad of yaw, of opposite sign before and after. Where
      the seafloor's energy is even in range, the sidelobes from nearer and farther scatterers
      cancel; within c T / 2 of a range edge they come from one side only: at 1 m and 3 m inside
      the near edge they carry 0.8 % and 2 % of the block's energy and -5.4 and -2.3 urad of
      yaw (the block's own scatterers read as the diagonal model does). The two parts are about
      equal: with the correction at each scatterer's own range half the zone is left, sampled at
      2 B (no fold) the second block's zone goes (bench_dpca.py --self-terms has the figures).

    What removes it, measured and not applied: a Hamming taper of the records' range spectrum
    (sidelobes two orders lower beyond a metre) takes the second block's zone to its noise, but
    widens the pulse: 25-40 % more yaw noise a pair on the seed-004 scene, whose image test then
    fails (tapering only the blocks within c T / 2 of an edge keeps most of that cost there and
    moves the 4x mean by +0.06 +- 0.08 only). A first-order correction of the sidelobes' phase,
    g exp(j psi) -> (g - j psi' h) exp(j psi) with psi the per-sample correction, psi' its time
    derivative and h the records filtered by Q / P (P the compressed pulse's spectrum, Q that of
    x p(x): each sample's sidelobe offsets), removes about two thirds of the zone on the
    single-scatterer sums (the folded skirt's part stays). A guard of c T / 2 leaves the zone
    out, and the 4x seafloors' mean then reads +0.3..+0.6 urad: not a bias of the blocks
    further in but of the yaw's OUTLIER-MAD trim, a selection that moves the 4x seafloors' mean
    by about +0.33 urad (trimmed minus plain mean of the same blocks, paired: +0.33 +- 0.06 on
    72 seafloors of the 1x transmitter, +0.33 +- 0.09 on 40 of the 2x; their block yaws are
    skewed negative) and so offsets part of the zone, which moves the plain mean by +0.40 +- 0.07
    / +0.34 +- 0.15 when the c T / 2 guard leaves it out; the plain mean of the blocks c T / 2
    clear of the edges reads -0.13 +- 0.12 / -0.12 +- 0.23 (issue #30's session-7 report). So
    the ``guard`` (the estimator gives a block's length) stays a measured rule for now. (That
    trim is gone: the skew it cut is a block yaw's ratio bias, which the estimator now pools
    away, package docstring "Pooling the blocks' yaws"; the edge zone's part of the block
    yaws stays, of either sign at the two edges, and about cancels over the 4x seafloors'
    blocks inside a block's guard.)
    ``content``: the blocks' content from :func:`look_moments` if already computed (same arguments)."""
    if extent is None:
        shape = (np.asarray(centre).shape[0], np.asarray(r).size)
        return np.ones(shape, dtype=bool)
    if content is None:
        content = look_moments(array, f0, c, r, centre, extent, span, ahead)[2]
    track_x = float(np.min(np.asarray(centre)[:, 0]))
    open_range = replace(extent, x=(min(extent.x[0], track_x), np.inf))
    whole = look_moments(array, f0, c, r, centre, open_range, span, ahead)[2]
    height = float(np.median(np.asarray(centre)[:, 2])) - extent.z
    near = np.hypot(max(extent.x[0] - track_x, 0.0), height)
    far = np.hypot(extent.x[1] - track_x, height)
    clear = (np.asarray(r) - span / 2 >= near + guard) & (np.asarray(r) + span / 2 <= far - guard)
    return (content >= (1 - RANGE_EDGE) * whole) & clear[None, :]


MIN_POINTS = 100  # static point scatterers a scenario needs for scenario_extent to take them as its seafloor


def scenario_extent(scenario) -> SeafloorExtent | None:
    """Where a simulated echo's seafloor scatters (``EchoData.scenario``), for
    :func:`clsas.estimate.dpca.estimate`'s default ``extent="auto"``: the scenario's clsas
    Seafloor (its extent's rectangle and mean height, flat; ``reach`` its facets' beam_nulls-th
    null of the transmitter's beam, :func:`clsas.scene.seafloor.facets.reach_slope`), else the
    rectangle around its stationary point scatterers when there are at least MIN_POINTS of them
    (a random-point seafloor: taken to be uniform over that rectangle; a few bright points on it
    change its edges little), else None (no scenario, recorded data: a real seafloor fills the
    beam)."""
    if scenario is None:
        return None
    floor = getattr(scenario, "seafloor", None)
    if floor is not None:
        slope = reach_slope(floor, scenario)
        reach = 1.0 if not np.isfinite(slope) else float(slope / np.hypot(1.0, slope))
        x0, x1, y0, y1 = (float(e) for e in floor.extent)
        return SeafloorExtent(x=(x0, x1), y=(y0, y1), z=float(floor.z), reach=reach)
    points = [t.positions[np.all(t.velocity == 0, axis=1)] for t in getattr(scenario, "targets", ())
              if isinstance(t, PointTargets)]
    points = np.concatenate(points) if points else np.zeros((0, 3))
    if points.shape[0] < MIN_POINTS:
        return None
    lo, hi = points.min(axis=0), points.max(axis=0)
    # the edges of a uniform draw, unbiased: n points fall short of them by (hi - lo) / (n - 1)
    lo, hi = lo - (hi - lo) / (points.shape[0] - 1), hi + (hi - lo) / (points.shape[0] - 1)
    if not (lo[0] < hi[0] and lo[1] < hi[1] and hi[0] > 0):
        return None
    return SeafloorExtent(x=(float(lo[0]), float(hi[0])), y=(float(lo[1]), float(hi[1])),
                          z=float(np.median(points[:, 2])))


def _at(table: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``table`` (block, angle) linearly interpolated at fractional angle indices ``k`` (pair, block)."""
    i = np.minimum(np.floor(k).astype(int), table.shape[-1] - 2)
    f = k - i
    block = np.arange(table.shape[0])[None, :]
    lo, hi = table[block, i], table[block, i + 1]
    return lo + f * (hi - lo)


def xlag_offset(q: np.ndarray, array: Array, f0: float, c: float, step: float) -> np.ndarray:
    """The x-lag peak's offset from the best lag, in lags (-0.5 .. 0.5), from the three beam
    peaks' ratio q (:func:`clsas.estimate.dpca.correlate.peak_ratio`).

    Two phase centres displaced by e along the track see a scatterer at look angle theta
    2 k e sin(theta) apart in phase (two-way), so over the beam their coherence is
    rho(e) = sum P(theta) cos(2 k e sin theta) / sum P(theta), P the two-way power pattern
    (:func:`_beam`): the Fourier transform of sinc^4, a cubic B-spline in e / L for equal
    elements, rounded at its peak and 1/4 at e = L / 2 (the x-lag step for hydrophones one
    element length apart). The beam peaks at lags -1, 0, 1 sample rho((k - eps) step); q(eps)
    is tabulated and inverted. For omnidirectional elements the V of linear decorrelation,
    eps = q / (1 + |q|), is used. (The V or a parabola applied to the B-spline read a fraction of
    the surge only.)"""
    beam = _beam(array, f0, c)
    if beam is None:
        return np.clip(q / (1 + np.abs(q)), -0.5, 0.5)
    sin_t, power = beam
    k = 2 * np.pi * f0 / c
    eps = np.linspace(-0.5, 0.5, 101)
    lags = (np.arange(-1, 2)[:, None] - eps[None, :]) * step                       # (3, eps)
    # one lag at a time: the (3, eps, angle) table at once was ~20 MB of temporaries
    rho = np.array([np.cos(2 * k * lag * sin_t) @ power for lag in lags.ravel()]).reshape(lags.shape) / np.sum(power)
    q_model = (rho[2] - rho[0]) / (2 * rho[1] - rho[2] - rho[0])
    return np.interp(q, q_model, eps)


def pca_delay(array: Array, i: np.ndarray, j: np.ndarray, r: np.ndarray, speed: float, c: float,
               sin2: float) -> np.ndarray:
    """dt_pca, s (couple,) + r.shape: the difference, ping p + 1 minus ping p, of the couple
    members' phase-centre errors at range r (m, any shape) (eqs. 48-49). Two-way path of a
    transmitter and a hydrophone a separation sigma apart along the track, to a scatterer at
    range r and look angle theta off broadside: 2 |S - M| + sigma^2 cos^2(theta) / (4 r), M
    their midpoint (the phase centre; the sigma^3 terms cancel between the two legs). sigma_h
    is the separation of the transmitter at emission and hydrophone h at reception,
    o_h - o_tx + v 2 r / c: the platform moves on while the echo travels. A range block
    mixes scatterers across the beam, so cos^2 is replaced by its mean over the beam,
    1 - ``sin2`` (:func:`beam_sin2`).

    The next term of the two-way path, from sqrt(r^2 + eps) = r + eps / (2 r) - eps^2 / (8 r^3)
    + eps^3 / (16 r^5) - 5 eps^4 / (128 r^7) with eps = -+ r sigma sin(theta) + sigma^2 / 4 per
    leg (odd powers of sin(theta) cancel between the legs), is
    -sigma^4 (1 - 6 sin^2 theta + 5 sin^4 theta) / (64 r^3); it is kept with 1 - 6 ``sin2``
    (sin^4 dropped). Its difference between the couple members is cubic in sigma: left out, it
    reads as a yaw of about 3 sigma^2 D / (16 r^3) a pair (positive on every scatterer, a bias,
    not speckle: fractions of a urad at tens of metres for a 1.2 m array, tests/test_dpca_bias.py).

    Left in, the difference reads as a yaw (its part linear along the couples: 1.53 m x 2 u / r
    at Heremans' geometry, 7.7 mrad at 100 m) and as a sway (its constant part, through the
    v 2 r / c term: 0.65 mm a ping pair there). Taken at the block's centre range instead of
    each sample's, it leaves 7.7 mrad x (r_scatterer - r_block) / r: tens of urad for a bright
    point off the block centre. Left at broadside (sin2 = 0), it leaves D <sin^2 theta> / r per
    ping pair as a yaw (D = v PRT, the couples' separation; 9 urad a pair at Heremans' 100 m),
    which integrates into a quadratic cross-track error along the track."""
    sigma = (array.rx_offsets[:, 1] - array.tx_offset[1]).reshape((-1,) + (1,) * r.ndim) + speed * 2 * r / c
    second = (sigma[i] ** 2 - sigma[j] ** 2) * (1 - sin2) / (4 * r)
    fourth = -(sigma[i] ** 4 - sigma[j] ** 4) * (1 - 6 * sin2) / (64 * r**3)
    return (second + fourth) / c
