"""The target's velocity vector (and, when not given, its position) from the receivers' Doppler
parameters (Kiang & Kiang 2022, section V, eqs. 33-35).

The paper grid-searches v for chi_alpha(v) = f_dc,alpha,eq(v) - f~_dc,alpha,eq = 0 at the three
receivers (Fig. 8: three surfaces meeting at v). Here:

1. **bracket**: the misfit sum_h ((f_dc,h(v) - f~_h) / sigma_h)^2 on a coarse grid (|v_i| <=
   ``v_max``, spacing ``step``: 17^3 points by default, 2 m/s apart up to 16 m/s; the Albacore
   tops 12.9 m/s), its local minima as starting points;
2. **refine**: each start by least squares (``scipy.optimize.least_squares``) on the centroid
   equations, with the exact closed forms (:mod:`.closedforms`) as the model; distinct roots
   are kept and ranked by the misfit including the FM rates when they are given (three
   surfaces can meet more than once; the FM rates, which grow with |v - V|^2, tell the roots
   apart);
3. **report**: ``residual``, the RMS centroid misfit at the root (Hz; ~0 when three receivers
   fix three unknowns exactly, larger with more receivers or inconsistent estimates), the
   linearised 1-sigma velocity error ``sigma`` (m/s) propagated from the centroid
   uncertainties through the Jacobian, (J^T W J)^-1, and ``confidence``: the probability,
   under that Gaussian error, that |v error| stays within the paper's 3 % bound
   (max(0.03 |v|, 0.1 m/s)), divided by the number of roots that fit as well as the best
   (misfit within 1 + the best; an ambiguity halves it).

Centroid uncertainties default to ``0.5 Hz + 0.5 %`` of |f~| (the spread of the paper's
estimates about its truth in Table II and section VII-C) unless a receiver estimate carries
``doppler_centroid_sigma``.

Position. The paper takes the target's initial position as known;
:func:`solve_motion` estimates it jointly with v from the delays tau_c (the range line after
RCMC and RWC, eq. 17) of all receivers, their centroids (the range walks) and FM rates:
first the position from the delays alone (trilateration of the bistatic ellipsoids, starting
on the imaged side, +x, at several depression angles, keeping the root under the surface),
then v bracketed and refined as above at that position, then all nine (or more) equations
together by least squares.

How well it works: on point targets the position comes out with the velocity as good as with the
position given, the depth the weakest component (A and B are at one depth;
tests/test_moving.py::test_point_target_position_and_velocity_estimated and
test_point_target_on_another_layout_position_estimated). On the submarine the delays are those
of the middle of the hull's image at each receiver (:mod:`.extent`), which is its centre only
when the receiver sees the hull along its length; it fails where a receiver cannot: Table II
case 7 (A and B cannot focus: no along-track history) and case 8 (A and B see the hull end-on,
only its nose, and the depth, fixed by the small difference of C's and A's depression angles,
moves far). The solve does not detect this by itself (its residuals absorb it);
:func:`.motion.estimate` widens the position's sigma by the target's size in its images and
flags it (:attr:`.motion.MotionEstimate.position_problem`); give the position for extended
targets when it is known (``clsas reproduce kiang2022 --position both``
prints both estimates).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import minimum_filter
from scipy.optimize import least_squares

from ... import budget, validate
from .closedforms import delay_terms
from .layout import Layout

SPEED_BOUND = 0.03  # the paper's velocity error bound, |dv| / |v|
SPEED_FLOOR = 0.1  # m/s: the bound's floor for slow targets


def centroid_sigma(f: float) -> float:
    """Default 1-sigma uncertainty of an estimated Doppler centroid ``f`` (Hz)."""
    return 0.5 + 0.005 * abs(f)


def fm_rate_sigma(k: float) -> float:
    """Default 1-sigma uncertainty of an estimated FM rate ``k`` (Hz/s): 3 % + 0.02 Hz/s (the
    SoWVD estimates of the paper are 1 % off; the rate averaged over the aperture differs from
    the Taylor coefficient by ~1 %)."""
    return 0.02 + 0.03 * abs(k)


@dataclass(frozen=True)
class MotionSolution:
    """A solved velocity (and position).

    velocity, position : (3,) m/s, m. position_estimated : whether it was solved for.
    residual : RMS centroid misfit at the solution, Hz. sigma : (3,) 1-sigma velocity error, m/s.
    confidence : in [0, 1], see the module docstring. alternatives : other roots, (k, 3) m/s.
    position_sigma : (3,) 1-sigma position error, m (NaN when the position was given).
    covariance : (3, 3) the velocity's covariance, (m/s)^2. ambiguity : the number of roots that
    fit as well as the best (the confidence is divided by it). fit_chi2, fit_dof : the joint
    fit's sum of squared normalised residuals and its degrees of freedom (position estimated;
    NaN and 0 otherwise).
    """

    velocity: np.ndarray
    position: np.ndarray
    residual: float
    sigma: np.ndarray
    confidence: float
    position_estimated: bool = False
    position_sigma: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    alternatives: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    covariance: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))
    ambiguity: int = 1
    fit_chi2: float = float("nan")
    fit_dof: int = 0


def _check_measurements(layout: Layout, values: dict, what: str, at_least: int = 3, positive: bool = False) -> list:
    """The receiver names of ``values`` (name -> finite number; > 0 when ``positive``), each in
    the layout, at least ``at_least`` of them."""
    if not isinstance(values, dict) or len(values) < at_least:
        raise ValueError(f"{what} must map at least {at_least} receiver names to values"
                         f"{' (3 unknowns)' if at_least == 3 else ''}, got {values!r}")
    for name, value in values.items():
        layout.receiver(name)
        if positive:
            validate.positive(f"{what}[{name!r}]", value)
        else:
            validate.scalar(f"{what}[{name!r}]", value)
    return list(values)


#: Bytes a point of the velocity bracketing grid takes (its velocity, the model's centroids per
#: receiver and the misfit, with NumPy's temporaries).
GRID_BYTES_PER_POINT = 400


def _within_bound(velocity: np.ndarray, cov: np.ndarray) -> float:
    """P(|dv| <= max(0.03 |v|, 0.1 m/s)) for dv ~ N(0, cov) (fixed-seed Monte Carlo, 20000 draws)."""
    if not np.all(np.isfinite(cov)):
        return 0.0
    bound = max(SPEED_BOUND * float(np.linalg.norm(velocity)), SPEED_FLOOR)
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    draws = np.random.default_rng(0).standard_normal((20000, 3)) * np.sqrt(np.clip(vals, 0, None))
    return float(np.mean(np.linalg.norm(draws, axis=1) <= bound))


def _covariance(jac: np.ndarray) -> np.ndarray:
    jtj = jac.T @ jac
    if np.linalg.cond(jtj) > 1e14:
        return np.full(jtj.shape, np.inf)
    return np.linalg.inv(jtj)


def solve_velocity(layout: Layout, position, centroids: dict, sigmas: dict | None = None,
                   fm_rates: dict | None = None, v_max: float = 16.0, step: float = 2.0,
                   model: str = "exact") -> MotionSolution:
    """Velocity vector from the Doppler centroids of >= 3 receivers at a known ``position``.

    Parameters
    ----------
    layout : :class:`~clsas.estimate.moving.layout.Layout`
    position : (3,) m, the target at slow time 0.
    centroids : dict name -> f~_dc,eq (Hz), at least three receivers.
    sigmas : dict name -> 1-sigma of each centroid (Hz); default :func:`centroid_sigma`.
    fm_rates : dict name -> K~_a,eq (Hz/s), optional: ranks multiple roots.
    v_max, step : the bracketing grid, m/s.
    """
    position = _position(position)
    v_max = validate.positive("solve_velocity v_max", v_max, high=validate.MAX_SPEED, unit="m/s")
    step = validate.positive("solve_velocity step", step, high=v_max, unit="m/s", why="at most v_max")
    names = _check_measurements(layout, centroids, "centroids")
    if sigmas is not None:
        _check_measurements(layout, sigmas, "sigmas", at_least=0, positive=True)
    if fm_rates is not None:
        _check_measurements(layout, fm_rates, "fm_rates", at_least=0)
    n_axis = int(np.floor(2 * v_max / step + 0.5)) + 1
    budget.check_bytes(f"solve_velocity's bracketing grid (v_max={v_max:g} m/s, step={step:g} m/s: {n_axis}^3 points)",
                       GRID_BYTES_PER_POINT * (1 + len(names)) * float(n_axis) ** 3,
                       "a larger step or a smaller v_max")
    f_meas = np.array([centroids[n] for n in names], dtype=np.float64)
    sig = np.array([(sigmas or {}).get(n, centroid_sigma(f)) for n, f in zip(names, f_meas)])

    def model_f(p, v):
        return np.stack([delay_terms(layout, n, p, v, model)[1] for n in names], axis=-1)

    axis = np.arange(-v_max, v_max + 0.5 * step, step)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1)
    cost = np.sum(((model_f(position, grid) - f_meas) / sig) ** 2, axis=-1)
    minima = np.argwhere(minimum_filter(cost, size=3, mode="nearest") == cost)
    starts = grid[tuple(minima.T)][np.argsort(cost[tuple(minima.T)])][:8]

    def residual(v):
        return (model_f(position, v) - f_meas) / sig

    roots = []
    for start in starts:
        fit = least_squares(residual, start, x_scale=1.0, xtol=1e-12, ftol=1e-12, gtol=1e-12)
        if not any(np.linalg.norm(fit.x - r.x) < 1e-3 for r in roots):
            roots.append(fit)

    def rank(fit):
        total = float(np.sum(fit.fun ** 2))
        if fm_rates:
            for n in fm_rates:
                k = delay_terms(layout, n, position, fit.x, model)[2]
                total += ((k - fm_rates[n]) / fm_rate_sigma(fm_rates[n])) ** 2
        return total

    scores = np.array([rank(r) for r in roots])
    order = np.argsort(scores)
    best = roots[order[0]]
    tied = int(np.sum(scores <= scores[order[0]] + 1.0))
    cov = _covariance(best.jac)
    return MotionSolution(
        velocity=best.x.copy(), position=position.copy(),
        residual=float(np.sqrt(np.mean((best.fun * sig) ** 2))),
        sigma=np.sqrt(np.abs(np.diag(cov))), confidence=confidence(best.x, cov, tied),
        alternatives=np.array([roots[i].x for i in order[1:]]).reshape(-1, 3), covariance=cov, ambiguity=tied)


def confidence(velocity: np.ndarray, cov: np.ndarray, ambiguity: int = 1) -> float:
    """P(|dv| within the paper's 3 % bound) for dv ~ N(0, ``cov``), divided by ``ambiguity``
    (the roots that fit as well; module docstring)."""
    return _within_bound(np.asarray(velocity), np.asarray(cov)) / max(int(ambiguity), 1)


def _position(position) -> np.ndarray:
    return np.array(validate.vector3("position", position), dtype=np.float64)


def _trilaterate(layout: Layout, names: list, tau: np.ndarray, sig_tau: np.ndarray, model: str) -> np.ndarray:
    """Position (at slow time 0) of a stationary point with the delays ``tau`` (s), under the surface."""
    ref = names[0]
    r0 = 0.5 * layout.sound_speed * tau[0]
    origin = layout.receiver(ref)[0]
    zero = np.zeros(3)

    def residual(p):
        return np.array([delay_terms(layout, n, p, zero, model)[0] for n in names]).ravel() / sig_tau - tau / sig_tau

    best = None
    for dep in np.deg2rad([0.0, 10.0, 25.0, 45.0]):
        start = origin + r0 * np.array([np.cos(dep), 0.0, -np.sin(dep)])
        fit = least_squares(residual, start, x_scale=10.0)
        if fit.x[2] < 0 and (best is None or fit.cost < best.cost):
            best = fit
    if best is None:
        raise ValueError("the delays tau_c put the target above the surface at every start: inconsistent delays")
    return best.x


def solve_motion(layout: Layout, delays: dict, centroids: dict, fm_rates: dict | None = None,
                 sigmas: dict | None = None, delay_sigma: float | None = None, v_max: float = 16.0,
                 step: float = 2.0, model: str = "exact", prior=None, prior_sigma: float | None = None,
                 start_velocity=None) -> MotionSolution:
    """Position and velocity jointly from the receivers' delays tau_c (s), centroids (Hz) and,
    optionally, FM rates (Hz/s), each a dict name -> value over >= 3 receivers.

    ``delay_sigma`` (s) defaults to a tenth of a range resolution cell, 0.1 / B (the range line
    is located to a fraction of a cell). The position is the target's at slow time 0, with the
    delays taken at ``layout.eta_ref``.

    ``prior`` (3,) m with ``prior_sigma`` (m, each axis): a known position the point measured is
    near (:func:`.motion.estimate` with a given position on an extended target: the centroids and
    delays are those of the middle of its image, within the target's size of the given point).
    The fit then starts there (at ``start_velocity``, or the velocity solved at the prior), adds
    (p - prior) / prior_sigma to its residuals and leaves the FM rates out (they only rank the
    roots of the bracketing solve); ``position_estimated`` is False.
    """
    names = _check_measurements(layout, delays, "delays", positive=True)
    _check_measurements(layout, centroids, "centroids")
    if set(centroids) != set(names):
        raise ValueError(f"delays and centroids must name the same receivers, got {sorted(delays)} and {sorted(centroids)}")
    if fm_rates is not None:
        _check_measurements(layout, fm_rates, "fm_rates", at_least=0)
    if sigmas is not None:
        _check_measurements(layout, sigmas, "sigmas", at_least=0, positive=True)
    if delay_sigma is not None:
        delay_sigma = validate.positive("solve_motion delay_sigma", delay_sigma, high=1.0, unit="s")
    tau = np.array([delays[n] for n in names], dtype=np.float64)
    sig_tau = float(delay_sigma) if delay_sigma is not None else 0.1 / layout.bandwidth
    f_meas = np.array([centroids[n] for n in names], dtype=np.float64)
    sig_f = np.array([(sigmas or {}).get(n, centroid_sigma(f)) for n, f in zip(names, f_meas)])
    k_names = [n for n in names if fm_rates and n in fm_rates]
    k_meas = np.array([fm_rates[n] for n in k_names], dtype=np.float64)
    sig_k = np.array([fm_rate_sigma(k) for k in k_meas])

    if prior is not None:
        prior = _position(prior)
        prior_sigma = validate.positive("solve_motion prior_sigma", prior_sigma, high=1e4, unit="m")
        p0 = prior
        if start_velocity is not None:
            first = MotionSolution(velocity=validate.vector3("solve_motion start_velocity", start_velocity,
                                                             bound=validate.MAX_SPEED),
                                   position=p0, residual=np.nan, sigma=np.full(3, np.nan), confidence=np.nan)
        else:
            first = solve_velocity(layout, p0, dict(zip(names, f_meas)), dict(zip(names, sig_f)),
                                   dict(zip(k_names, k_meas)) or None, v_max, step, model)
        k_names, k_meas, sig_k = [], k_meas[:0], sig_k[:0]
    else:
        p0 = _trilaterate(layout, names, tau, np.full(tau.size, sig_tau), model)
        first = solve_velocity(layout, p0, dict(zip(names, f_meas)), dict(zip(names, sig_f)),
                               dict(zip(k_names, k_meas)) or None, v_max, step, model)

    def residual(x):
        p, v = x[:3], x[3:]
        terms = {n: delay_terms(layout, n, p, v, model) for n in names}
        out = [(np.array([terms[n][0] for n in names]) - tau) / sig_tau,
               (np.array([terms[n][1] for n in names]) - f_meas) / sig_f]
        if k_names:
            out.append((np.array([terms[n][2] for n in k_names]) - k_meas) / sig_k)
        if prior is not None:
            out.append((p - prior) / prior_sigma)
        return np.concatenate(out)

    fit = least_squares(residual, np.concatenate([p0, first.velocity]), x_scale=np.array([10.0] * 3 + [1.0] * 3),
                        xtol=1e-12, ftol=1e-12, gtol=1e-12)
    cov = _covariance(fit.jac)
    n = len(names)
    return MotionSolution(
        velocity=fit.x[3:].copy(), position=fit.x[:3].copy(),
        residual=float(np.sqrt(np.mean((fit.fun[n:2 * n] * sig_f) ** 2))),
        sigma=np.sqrt(np.abs(np.diag(cov)[3:])), confidence=confidence(fit.x[3:], cov[3:, 3:]),
        position_estimated=prior is None, position_sigma=np.sqrt(np.abs(np.diag(cov)[:3])),
        alternatives=first.alternatives, covariance=cov[3:, 3:], fit_chi2=float(np.sum(fit.fun ** 2)),
        fit_dof=int(fit.fun.size - fit.x.size))
