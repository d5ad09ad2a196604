"""Whether one velocity explains every receiver (issue 26; not in Kiang & Kiang 2022).

Why. With three receivers and the position given, the three centroid equations (eqs. 33-35) fix
the three velocity components exactly: any three centroids give a velocity with a zero residual,
so the residual cannot tell a wrong centroid. The FM rates can: each receiver's K_a,eq is a
fourth, independent reading of the same velocity (K grows with the relative speed squared over
the range, eqs. 5, 6, 25), which the velocity solve does not fit. A receiver whose SoWVD locked on
a cross-term of several scatterers (:mod:`.sowvd`) has a K far from the one the velocity
predicts, and its centroid is wrong too (RCMC with the wrong K bends the trace the Radon
transform fits). So after the solve, every receiver's measured K is compared with the model's
at the solution:

    z_h = (K~_h - K_h(v)) / sigma_K,h,        chi2 = sum_h z_h^2  (dof = the number of receivers),

K_h(v) the rate the SoWVD reads, averaged over the aperture
(:func:`.closedforms.aperture_fm_rate`), sigma_K = :data:`RATE_SIGMA`. With the position
estimated the rates are in the joint fit; its normalised residual plays the same part (dof = 3n - 6).

What follows from it (:func:`check`):

- a receiver with |z_h| > :data:`OUTLIER_SIGMAS`, or whose Radon slope ran to its search's
  edge, is an outlier: :func:`.motion.estimate` predicts its (K, f_dc) from the other receivers
  alone (:func:`predict_without`) and re-runs its chain with the candidate of its rate search
  nearest that K, when one lies within :data:`OUTLIER_SIGMAS` of it;
- ``sigma`` is scaled by the Birge ratio sqrt(max(1, chi2 / dof)) (errors larger than the
  centroids' own spread show in the rates), and ``confidence`` multiplied by
  min(1, p / :data:`P_FLOOR`), p the chi2 probability of so large a misfit: a consistent
  estimate (p above 1 %, which 99 % of correct ones reach) keeps its confidence, a clearly
  inconsistent one falls towards 0. The problems are listed by receiver and why
  (:attr:`.motion.MotionEstimate.problems`);
- a receiver whose record the focus confirmed at two rates that disagree
  (:attr:`.chain.ReceiverEstimate.rate_problem`: two objects, the brighter kept) is listed too,
  and the confidence divided by the number of rates it confirmed (:attr:`Consistency.rate_ambiguity`:
  one of two equally confirmed objects is the target's, as :func:`.velocity.confidence` divides by
  the number of velocities that fit equally well).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2 as chi2_distribution

from ... import validate
from .chain import P0
from .closedforms import aperture_fm_rate, delay_terms
from .layout import Layout

#: 1-sigma of a measured FM rate against the model's aperture average: (relative, fraction of
#: the rate search's K bin 1 / (4 p0 T_a)). On one point the rate search reads the average to a
#: small fraction of a bin (tests/test_moving.py); on a target of several scatterers the peak is
#: a mix of theirs (K varies as 1 / range across the target, and their cross-terms with the same
#: K skew the peak within its bin).
RATE_SIGMA = (0.01, 0.15)
#: |z| beyond which a receiver's rate is an outlier.
OUTLIER_SIGMAS = 5.0
#: The chi2 probability below which the confidence is scaled down (by p / P_FLOOR).
P_FLOOR = 0.01


def rate_sigma(k: float, layout: Layout, p0: float) -> float:
    """1-sigma (Hz/s) of a measured FM rate ``k`` against the model (:data:`RATE_SIGMA`), for the
    rate search's first lag offset ``p0`` (s) over the layout's aperture."""
    return RATE_SIGMA[0] * abs(k) + RATE_SIGMA[1] / (4.0 * p0 * layout.aperture)


def record_times(layout: Layout) -> np.ndarray:
    """The emission times (n_pulses,) s of the layout's record: T_a PRF pulses centred on eta_ref."""
    n = max(2, int(round(layout.aperture * layout.prf)))
    return layout.eta_ref + (np.arange(n) - 0.5 * (n - 1)) / layout.prf


def _p0(rx) -> float:
    """The first lag offset of a receiver estimate's rate search (the default for the closed forms)."""
    p0 = getattr(rx, "p0", None)
    return float(p0) if p0 is not None and np.isfinite(p0) and p0 > 0 else P0


@dataclass(frozen=True)
class Consistency:
    """The receivers' FM rates against one velocity (module docstring).

    model_rates : {name: K_h(v), Hz/s} at the solution; z : {name: (K~ - K_h(v)) / sigma_K};
    chi2, dof : their sum of squares and its degrees of freedom (or the joint fit's); p_value :
    the chi2 probability of a misfit at least this large; outliers : names with |z| >
    :data:`OUTLIER_SIGMAS` or a Radon slope at its search's edge, worst first; problems :
    {name: why} for each outlier and each receiver whose focus confirmed two rates;
    rate_ambiguity : the product over the receivers of the number of rates each confirmed (1
    when none confirmed more than one).
    """

    model_rates: dict
    z: dict
    chi2: float
    dof: int
    p_value: float
    outliers: tuple
    problems: dict
    rate_ambiguity: int = 1

    @property
    def birge(self) -> float:
        """sqrt(max(1, chi2 / dof)): how much larger the errors are than the stated sigmas."""
        return float(np.sqrt(max(1.0, self.chi2 / max(self.dof, 1))))

    @property
    def factor(self) -> float:
        """min(1, p / :data:`P_FLOOR`) / :attr:`rate_ambiguity`: what the confidence is multiplied by."""
        return float(min(1.0, self.p_value / P_FLOOR)) / self.rate_ambiguity


def check(layout: Layout, receivers: dict, position, velocity, fit_chi2: float | None = None,
          fit_dof: int | None = None) -> Consistency:
    """The :class:`Consistency` of ``receivers`` (name -> estimate with fm_rate, and optionally
    slope_limited) with ``velocity`` at ``position``. ``fit_chi2``, ``fit_dof``: a joint fit's own
    misfit (position estimated, the rates in the fit), used in place of the rates' chi2."""
    eta = record_times(layout)
    model, z, problems, ambiguity = {}, {}, {}, 1
    for name, rx in receivers.items():
        model[name] = aperture_fm_rate(layout, name, position, velocity, eta)
        z[name] = (float(rx.fm_rate) - model[name]) / rate_sigma(model[name], layout, _p0(rx))
    chi2 = float(sum(v * v for v in z.values())) if fit_chi2 is None else float(fit_chi2)
    dof = len(z) if fit_dof is None else int(fit_dof)
    p = float(chi2_distribution.sf(chi2, dof)) if dof > 0 else 1.0
    outliers = []
    for name in sorted(z, key=lambda n: -abs(z[n])):
        rx = receivers[name]
        why = []
        if abs(z[name]) > OUTLIER_SIGMAS:
            why.append(f"its FM rate {float(rx.fm_rate):.4g} Hz/s is {abs(z[name]):.0f} sigma from the "
                       f"{model[name]:.4g} Hz/s that the velocity predicts (its SoWVD peak may be a cross-term "
                       "of several scatterers)")
        if getattr(rx, "slope_limited", False):
            why.append("its Radon slope ran to the edge of its search (no straight trace after RCMC)")
        outlier = bool(why)
        if getattr(rx, "rate_problem", ""):
            why.append(rx.rate_problem)
            ambiguity *= 1 + len(rx.fm_rate_rivals)
        if why:
            problems[name] = f"receiver {name}: " + "; ".join(why)
        if outlier:
            outliers.append(name)
    return Consistency(model_rates=model, z=z, chi2=chi2, dof=dof, p_value=p, outliers=tuple(outliers),
                       problems=problems, rate_ambiguity=ambiguity)


def predict_without(layout: Layout, receivers: dict, centroids: dict, centroid_sigmas: dict, exclude: str,
                    position, velocity, delays: dict | None = None, delay_sigma: float | None = None):
    """(K Hz/s, f_dc Hz) at receiver ``exclude`` predicted from the other receivers alone: their
    centroids and FM rates (and, when ``delays`` is given, their delays tau_c, with the position
    fitted too) by least squares from ``velocity`` (and ``position``); K as the SoWVD reads it
    (:func:`.closedforms.aperture_fm_rate`). Also returns the fit's chi2 per degree of freedom
    (inf when the others fix the unknowns exactly)."""
    names = [n for n in receivers if n != exclude]
    eta = record_times(layout)
    p0 = np.asarray(position, dtype=np.float64)
    # the velocity kept within the delay model's speeds (+-MAX_SPEED): the others may fix it
    # poorly, and their fit must not leave the model's domain (:func:`culprit` asks it about a
    # solution beyond it)
    v0 = np.clip(np.asarray(velocity, dtype=np.float64), -0.9 * validate.MAX_SPEED, 0.9 * validate.MAX_SPEED)
    # the Taylor rates scaled to the aperture's average at the start (the ratio barely moves)
    ratio = {}
    for n in names:
        taylor = float(delay_terms(layout, n, p0, v0)[2])
        ratio[n] = aperture_fm_rate(layout, n, p0, v0, eta) / taylor if abs(taylor) > 1e-9 else 1.0
    f = np.array([centroids[n] for n in names])
    sf = np.array([centroid_sigmas[n] for n in names])
    k = np.array([float(receivers[n].fm_rate) for n in names])
    sk = np.array([rate_sigma(x, layout, _p0(receivers[n])) for x, n in zip(k, names)])
    joint = delays is not None
    tau = np.array([delays[n] for n in names]) if joint else None
    st = (delay_sigma if delay_sigma is not None else 0.1 / layout.bandwidth) if joint else None

    def residual(x):
        p, v = (x[:3], x[3:]) if joint else (p0, x)
        terms = [delay_terms(layout, n, p, v) for n in names]
        out = [(np.array([t[1] for t in terms]) - f) / sf,
               (np.array([t[2] * ratio[n] for t, n in zip(terms, names)]) - k) / sk]
        if joint:
            out.append((np.array([t[0] for t in terms]) - tau) / st)
        return np.concatenate(out)

    start = np.concatenate([p0, v0]) if joint else v0
    bound = np.concatenate([np.full(3, np.inf), np.full(3, validate.MAX_SPEED)]) if joint else validate.MAX_SPEED
    fit = least_squares(residual, start, x_scale=np.array([10.0] * 3 + [1.0] * 3) if joint else 1.0,
                        bounds=(-bound, bound))
    p, v = (fit.x[:3], fit.x[3:]) if joint else (p0, fit.x)
    dof = fit.fun.size - fit.x.size
    per_dof = float(np.sum(fit.fun ** 2) / dof) if dof > 0 else np.inf
    k_pred = aperture_fm_rate(layout, exclude, p, v, eta)
    return k_pred, float(delay_terms(layout, exclude, p, v)[1]), per_dof


def culprit(layout: Layout, receivers: dict, centroids: dict, centroid_sigmas: dict, position, velocity,
            delays: dict | None = None) -> tuple[str, float, float, float]:
    """The receiver whose (K, f_dc) sits furthest from the others' consensus: the one without
    which the other receivers agree best (their fit's chi2 per degree of freedom in
    :func:`predict_without`, from ``velocity`` and ``position``: with one velocity fitted to all,
    dropping the receiver that lowers the misfit most). Returns its name, the distance
    z = sqrt(z_K^2 + z_f^2) of its K and f_dc from what the others predict (sigma_K
    :func:`rate_sigma`, sigma_f its centroid's) and that prediction (K Hz/s, f_dc Hz)."""
    best = None
    for name, rx in receivers.items():
        k_pred, f_pred, per_dof = predict_without(layout, receivers, centroids, centroid_sigmas, name, position,
                                                  velocity, delays)
        if best is None or per_dof < best[0]:
            z = float(np.hypot((float(rx.fm_rate) - k_pred) / rate_sigma(k_pred, layout, _p0(rx)),
                               (centroids[name] - f_pred) / centroid_sigmas[name]))
            best = (per_dof, name, z, k_pred, f_pred)
    return best[1:]
