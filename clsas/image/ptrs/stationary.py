"""Stationary points of the multireceiver phase history (Zhang, Tan & Ying 2019, eqs. 1 and 3-9).

Geometry (seed 003, Fig. 1): the transmitter moves along y at speed v, receiver i rides d_i
ahead of it, a stationary point target sits at perpendicular (slant) range r from the track
line and at y = 0; t is the emission time, zero when the transmitter passes the target. The
exact two-way delay tau_i(t; r) of eq. (1) is clsas's non-stop-and-go delay: the outgoing leg
c t1 = sqrt(r^2 + v^2 t^2), then the receiver, moving on while the echo travels, is met by
the echo after :func:`clsas.geometry.meet_time` (the closed form of eq. 1).

Implicit derivatives (from c tau = A + B, A = sqrt(r^2 + v^2 t^2), B = sqrt(r^2 + X^2),
X = v t + d + v tau the receiver's y at reception, a = X / B):

    tau'  = (v^2 t / A + v a) / (c - v a)                                          (eq. 6)
    tau'' = (v^2 r^2 / A^3 + v^2 (1 + tau')^2 r^2 / B^3) / (c - v a)  > 0

Stationary phase (eq. 5): tau_i'(t) = s with s = -f_t / (f0 + f_tau). The stationary point
therefore depends on (f_tau, f_t) only through the slope s, and so does the PTRS (eq. 7):

    Psi_i(f_tau, f_t; r) = -2 pi (f0 + f_tau) G_i(s; r),   G_i(s; r) = tau_i(T_i(s)) - s T_i(s)

with T_i(s) the stationary point; G is the Legendre transform of tau_i, with dG/ds = -T(s)
exactly (the envelope theorem). The azimuth modulation (eqs. 8-9) is the same function at
f_tau = 0: phi_ac_i(f_t; r) = -2 pi f0 G_i(-f_t / f0; r). (Sign convention: the phase of the
echo's spectrum, exp(-j 2 pi (f0 + f_tau) tau - j 2 pi f_t t) integrated over t, as in eq. 3.)

:func:`stationary_points` solves eq. (5) by Newton's method, vectorised over any array of
slopes (tau'' > 0: tau' is increasing, the root unique), to |dt| < 1e-12 s (or 8 ulp of T).
:class:`StationaryPoints` is the paper's "second scheme": it tabulates T and G per receiver
and range on a uniform grid of s covering the processed band, once, and serves the phase of
any (f_tau, f_t) by cubic Hermite interpolation of G (with its exact derivative -T;
tests/test_ptrs.py measures the phase error against Newton at random slopes).
"""

from __future__ import annotations

import numpy as np

from ...geometry import meet_time

NEWTON_TOLERANCE = 1e-12  # s, largest Newton update at convergence
NEWTON_ITERATIONS = 40


def delay(t, r, d, v: float, c: float) -> np.ndarray:
    """Exact two-way delay tau_i(t; r) (Zhang et al. 2019 eq. 1), s, broadcast over t (s),
    r (m) and d (m)."""
    t, r, d = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (t, r, d)))
    t1 = np.sqrt(r * r + (v * t) ** 2) / c
    # the receiver when the wave leaves the target, relative to the target, and its velocity
    rel = np.stack([-r, v * t + d + v * t1, np.zeros_like(r)])
    return t1 + meet_time(rel, np.array([0.0, v, 0.0]).reshape(3, *(1,) * r.ndim), c, axis=0)


def delay_derivatives(t, r, d, v: float, c: float):
    """(tau, tau', tau'') at slow times t (s) for ranges r and receiver offsets d (broadcast)."""
    tau = delay(t, r, d, v, c)
    t, r, d = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (t, r, d)))
    a_len = np.sqrt(r * r + (v * t) ** 2)
    x = v * t + d + v * tau
    b_len = np.sqrt(r * r + x * x)
    cos_b = x / b_len
    denom = c - v * cos_b
    d1 = (v * v * t / a_len + v * cos_b) / denom
    d2 = (v * v * r * r / a_len**3 + v * v * (1 + d1) ** 2 * r * r / b_len**3) / denom
    return tau, d1, d2


def stationary_points(s, r, d, v: float, c: float) -> np.ndarray:
    """T with tau'(T; r, d) = s (eq. 5 with s = -f_t / (f0 + f_tau)), s; Newton's method from
    the monostatic phase-centre guess, vectorised over the broadcast of s, r and d, iterated
    until every update is below 1e-12 s (or 8 ulp of T, which far ranges make larger).

    Raises ValueError when a slope is outside what the geometry can produce (|s| must stay
    below ~2 v / c) and RuntimeError if Newton does not converge.
    """
    s, r, d = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (s, r, d)))
    x = c * s / (2 * v)  # sine of the squint seen from the phase centre
    if np.any(np.abs(x) >= 0.95):
        raise ValueError(f"Doppler slopes up to |s| = {np.abs(s).max():.3g} need squints beyond 72 deg "
                         f"(|s| < 1.9 v / c = {1.9 * v / c:.3g}); limit the processed Doppler band")
    t = -(d / 2 + v * r / c) / v + r * x / (v * np.sqrt(1 - x * x))
    for _ in range(NEWTON_ITERATIONS):
        _, d1, d2 = delay_derivatives(t, r, d, v, c)
        step = (d1 - s) / d2
        t = t - step
        # converged: every update below 1e-12 s, or below 8 ulp of T itself (far ranges: T ~ 1e4 s)
        if np.all(np.abs(step) <= np.maximum(NEWTON_TOLERANCE, 8 * np.spacing(np.abs(t)))):
            return t
    raise RuntimeError(f"Newton's method for the stationary points did not converge in {NEWTON_ITERATIONS} "
                       f"iterations (last update {np.max(np.abs(step)):.3g} s)")


def legendre_phase(s, r, d, v: float, c: float):
    """(T, G): the stationary points and G = tau(T) - s T (s), the PTRS divided by
    -2 pi (f0 + f_tau) (eq. 7), at the broadcast of s, r and d."""
    t = stationary_points(s, r, d, v, c)
    return t, delay(t, r, d, v, c) - np.asarray(s) * t


class StationaryPoints:
    """Stationary points of every receiver at chosen ranges, solved once and kept (seed 003's
    "second scheme": the numerical PSPs are computed ahead of the focusing and reused).

    Make one empty and pass it to :func:`clsas.ptrs_image` as ``points``: the first image binds
    it to its geometry (receiver offsets, m ahead of the transmitter; speed, m/s; sound speed,
    m/s; the largest Doppler slope of its band) and fills it; later images of the same geometry
    reuse what it holds and solve only ranges not seen before (:attr:`solved` counts the ranges
    solved so far). It holds, for every (receiver, range), T(s) and G(s) on the uniform slope
    grid ``s_first + k ds``, k < ``n_s``.
    """

    def __init__(self, n_s: int = 257):
        if isinstance(n_s, bool) or not isinstance(n_s, (int, np.integer)) or n_s < 8:
            raise ValueError(f"n_s must be an integer >= 8 (slope samples), got {n_s!r}")
        self.n_s = int(n_s)
        self.offsets = None
        self._rows: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self.solved = 0

    def bind(self, offsets, speed: float, sound_speed: float, s_max: float) -> "StationaryPoints":
        """Tie an empty cache to a geometry and a band up to slope ``s_max`` (s/s); a bound
        one must match (same offsets, speed and sound speed; its band at least as wide), else a
        ValueError: a cache serves one array."""
        offsets = np.asarray(offsets, dtype=np.float64).reshape(-1)
        if not (np.isfinite(s_max) and s_max > 0):
            raise ValueError(f"s_max must be a positive Doppler slope, got {s_max}")
        if self.offsets is None:
            self.offsets, self.speed, self.sound_speed = offsets, float(speed), float(sound_speed)
            self.s_first = -float(s_max)
            self.ds = 2 * float(s_max) / (self.n_s - 1)
            return self
        same = (offsets.shape == self.offsets.shape and np.array_equal(offsets, self.offsets)
                and float(speed) == self.speed and float(sound_speed) == self.sound_speed)
        if not same or s_max > -self.s_first:
            raise ValueError("points holds the stationary points of another geometry or a narrower Doppler band "
                             f"(offsets {self.offsets.size}, speed {self.speed} m/s, slopes up to {-self.s_first:.4g}); "
                             "pass a new StationaryPoints()")
        return self

    @property
    def slopes(self) -> np.ndarray:
        return self.s_first + self.ds * np.arange(self.n_s)

    def tables(self, ranges) -> tuple[np.ndarray, np.ndarray]:
        """(T, G) float64 (n_receivers, len(ranges), n_s): solved now for new ranges, else kept."""
        if self.offsets is None:
            raise ValueError("points is not bound to a geometry yet: call bind() (ptrs_image does)")
        ranges = np.asarray(ranges, dtype=np.float64).reshape(-1)
        if not np.all(np.isfinite(ranges)) or np.any(ranges <= 0):
            raise ValueError("ranges must be positive and finite (m)")
        new = [r for r in np.unique(ranges) if float(r) not in self._rows]
        if new:
            t, g = legendre_phase(self.slopes[None, None, :], np.asarray(new)[None, :, None],
                                  self.offsets[:, None, None], self.speed, self.sound_speed)
            for j, r in enumerate(new):
                self._rows[float(r)] = (t[:, j], g[:, j])
            self.solved += len(new)
        t = np.stack([self._rows[float(r)][0] for r in ranges], axis=1)
        g = np.stack([self._rows[float(r)][1] for r in ranges], axis=1)
        return t, g


def hermite(g: np.ndarray, t: np.ndarray, s_first: float, ds: float, s, slope: bool = False):
    """G at slopes ``s`` by cubic Hermite interpolation of the table ``g`` (last axis, uniform
    slopes s_first + k ds) with its exact derivative dG/ds = -T (``t``, same shape as ``g``).
    Returns float64 of shape ``g.shape[:-1] + s.shape``; with ``slope``, (G, dG/ds) of the same
    interpolant (its derivative equals -T at the table's slopes)."""
    pos = (np.asarray(s, dtype=np.float64) - s_first) / ds
    n = g.shape[-1]
    if np.any(pos < -1e-9) or np.any(pos > n - 1 + 1e-9):
        raise ValueError("a slope lies outside the tabulated band")
    k = np.clip(np.floor(pos).astype(np.int64), 0, n - 2)
    u = pos - k
    u2 = u * u
    u3 = u2 * u
    g0, g1, t0, t1 = g[..., k], g[..., k + 1], t[..., k], t[..., k + 1]
    value = (2 * u3 - 3 * u2 + 1) * g0 - ds * (u3 - 2 * u2 + u) * t0 + (-2 * u3 + 3 * u2) * g1 - ds * (u3 - u2) * t1
    if not slope:
        return value
    return value, (6 * (u2 - u) * (g0 - g1) / ds - (3 * u2 - 4 * u + 1) * t0 - (3 * u2 - 2 * u) * t1)


def migration(g: np.ndarray, t: np.ndarray, s_first: float, ds: float, s, r, c: float) -> np.ndarray:
    """The range cell migration m(s; r) = tau(T(s); r) - 2 r / c = G - s dG/ds - 2 r / c, s, at
    slopes ``s`` from the tables (g, t) of range(s) ``r`` (broadcast against g's leading axes):
    the group delay -(1 / 2 pi) d phi_de / d f_tau at f_tau = 0 of seed 003's eq. (11), i.e.
    where, relative to 2 r / c, a point at range r sits in the range-Doppler row f_t = -s f0."""
    value, dg = hermite(g, t, s_first, ds, s, slope=True)
    r = np.asarray(r, dtype=np.float64).reshape(np.shape(r) + (1,) * np.ndim(s))
    return value - np.asarray(s) * dg - 2 * r / c
