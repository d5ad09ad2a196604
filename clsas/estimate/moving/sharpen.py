"""The residual phase of a focused moving target, by image sharpness: what the velocity estimate
cannot give over Table I's 80 s apertures.

Why. :func:`.motion.focus` compensates the model's whole delay history at the estimated position
and velocity (:func:`.closedforms.delay_history`). Its error grows with the aperture: the
quadratic phase left at the ends of an aperture T_a is pi dK (T_a / 2)^2 with
dK / K ~ 2 |dv| / |v - V_h| (K = 2 f0 |w|^2 / (c R), w the relative velocity). Over 80 s,
a velocity error of 0.1 % (Table II case 6 at C: K = 5.19 Hz/s, dK = 5.4e-3 Hz/s) leaves ~27 rad
and widens the point's azimuth response five times (11 ms against 2.1 ms); a radian needs
|dv| / |v| ~ 4e-5, which neither the centroids nor the SoWVD's rate give (4-7 % above the
Taylor K over 80 s: :mod:`.sowvd`, "Long apertures"). The data do: the record, once aligned
in range with the model, carries the residual phase of the target, and the compressed image is
sharpest when that phase is removed.

What. With u = (eta - eta_ref) / (T_a / 2) in [-1, 1] and the residual phase written as

    phi(u) = p2 u^2 + p3 u^3 + p4 u^4          (cycles at the aperture's ends),

:func:`residual_phase` finds p2, p3, p4 that maximise the image's sharpness sum |I|^4 (I the
deramp-FFT compression of the aligned record times exp(j 2 pi phi), :func:`.filters.compress`;
the compression is unitary, so sum |I|^2 is the same for every phi and sum |I|^4 alone measures
the concentration). The compression is zero-padded twice (:data:`PAD`): unpadded, sum |I|^4
scallops with the peak's place between bins, which the cubic term (it moves the peak) followed:
0.3 cycles off on Table II case 6 at C. The linear term is left out: it only moves the image, which is how the
chain measures the centroid (:func:`.motion.refined_centroid`). The monomials are Taylor terms
at eta_ref, not orthogonal polynomials, on purpose: a cubic term (with its linear
least-squares part 3/5 u) would also move the peak, and the peak must stay where the Taylor
centroid at eta_ref puts it. The Taylor FM rate of the data is K + 2 p2 / (T_a / 2)^2.

How. The search runs on the Legendre polynomials P2, P3, P4 of u (coefficients a2, a3, a4,
cycles at the ends), converted at the end to the monomials (p2 = 3/2 a2 - 15/4 a4, p3 = 5/2 a3,
p4 = 35/8 a4, their constant and linear parts dropped: they do not change the sharpness).
For small errors the loss of peak intensity is the variance of the phase error after its best
constant and linear fit (1 - |mean exp(j phi)|^2 ~ var phi), and on the Legendre basis, orthogonal
on [-1, 1] to 1, u and each other, that variance is a sum of one square per term: the search
separates into one coordinate at a time near focus. Each coordinate (a2, a3, a4) is bracketed
by a zoomed grid: :data:`GRID` points over +-span, the best kept, the span divided by
:data:`ZOOM`, until the grid step is below :data:`STEP` cycles. A grid, not a local optimiser:
far from focus, sum |I|^4 has Fresnel ripples that a gradient would stop on; the grid's best
point stays on the main slope (sum |I|^4 ~ 1 / |phi| there). With errors of a radian or more the
terms are not independent (a 0.5-cycle P3 error moves the best a2 by 0.4 cycles: the grids alone
ended 0.7 cycles off on a synthetic record), so a Nelder-Mead search of all three together
(log sum |I|^4, simplex 0.25 cycles, to STEP / 4) finishes from the grids' point. The sharpness
is summed over the :data:`BINS` strongest range bins of the window (a point's main lobe and
sidelobes; a hull's brightest rows): ~300 evaluations of one FFT each. Fewer rows let a hull's
strongest glint decide (on the scaled Albacore a few rows sharpen that glint and blur the rest
of the hull; 64 or 128 rows keep the whole hull's entropy at the model history's).

Spans (derived from the error budget above): p2 over +-``rate_span`` |K| (T_a / 2)^2 / 2 cycles
(the default 3 % of K: a velocity error of ~1.5 %, the hull's worst), p3 and p4 over
+-(``order_span`` max |f0 h| + 1) cycles, h the model's higher-order delay (the default 10 % of
it: a velocity error of a few %).

The residual is also a delay error, and its range walk (the linear part, which the centroid's
error leaves) is compensated in range by :func:`.azimuth.sharpened_bins`, which runs this search.
"""

from __future__ import annotations

import numpy as np
import scipy.fft
from scipy.optimize import minimize

from ...kernelmath import unit_phasor

#: Grid points of one zoom step.
GRID = 17
#: Span reduction per zoom step (the new span is two grid steps of the old grid).
ZOOM = 4.0
#: Stop when the grid step is below this, cycles at the aperture's ends.
STEP = 0.02
#: Range bins the sharpness is summed over (the strongest of the window; module docstring).
BINS = 64
#: Zero padding of the compression the sharpness is measured on.
PAD = 2
#: Default span of the quadratic term: this fraction of K (a velocity error of ~1.5 %).
RATE_SPAN = 0.03
#: Default span of the cubic and quartic terms: this fraction of the model's higher-order
#: phase, plus one cycle.
ORDER_SPAN = 0.1


def polynomial_phase(eta: np.ndarray, eta_ref: float, coefficients) -> np.ndarray:
    """phi(eta) = sum_k p_k u^k (cycles), u = (eta - eta_ref) / (T_a / 2), for ``coefficients``
    (p2, p3, p4) in cycles at the aperture's ends; (n_pulses,)."""
    u = aperture_time(eta, eta_ref)
    return sum(p * u ** (k + 2) for k, p in enumerate(coefficients))


def aperture_time(eta: np.ndarray, eta_ref: float) -> np.ndarray:
    """u = (eta - eta_ref) / (T_a / 2): slow time (s) in half-apertures about eta_ref, float64."""
    eta = np.asarray(eta, dtype=np.float64)
    return (eta - eta_ref) / (0.5 * float(np.ptp(eta)))


def fm_rate_correction(eta: np.ndarray, p2: float) -> float:
    """dK (Hz/s) of a quadratic term p2 (cycles at the ends): 2 p2 / (T_a / 2)^2."""
    half = 0.5 * float(np.ptp(eta))
    return 2.0 * p2 / half**2


def _zoom(score, centre: float, span: float) -> float:
    while True:
        grid = centre + np.linspace(-span, span, GRID)
        centre = float(grid[int(np.argmax([score(g) for g in grid]))])
        if 2 * span / (GRID - 1) < STEP:
            return centre
        span /= ZOOM


def residual_phase(aligned: np.ndarray, eta: np.ndarray, fm_rate: float, eta_ref: float = 0.0,
                   higher_order_cycles: float = 0.0, rate_span: float = RATE_SPAN,
                   order_span: float = ORDER_SPAN) -> np.ndarray:
    """(p2, p3, p4), cycles at the aperture's ends: the residual phase of the target in
    ``aligned`` (n_pulses, n_bins), a window of the record after RCMC, RWC and the model's
    higher-order terms (:func:`.filters.migration`), that maximises the sharpness of its
    compression with ``fm_rate`` (module docstring). ``eta`` (n_pulses,) s; ``eta_ref`` the
    Taylor reference, s; ``higher_order_cycles`` max |f0 h| of the model's higher-order terms,
    cycles (sets the cubic and quartic spans)."""
    if aligned.ndim != 2 or aligned.shape[0] != np.size(eta):
        raise ValueError(f"aligned must be (n_pulses={np.size(eta)}, n_bins), got shape {aligned.shape}")
    energy = np.sum(np.abs(aligned) ** 2, axis=0)
    eta = np.asarray(eta, dtype=np.float64)
    # the deramp of :func:`.filters.compress` once; |FFT|^4 summed is its image's sum |I|^4
    # (the bins' order and the phase of eta_0 do not change it)
    deramp = np.exp(1j * np.pi * fm_rate * (eta - eta_ref) ** 2)
    sub = (aligned[:, np.argsort(energy)[-BINS:]] * deramp[:, None]).astype(np.complex64)
    n_eta = scipy.fft.next_fast_len(PAD * eta.size)
    half = 0.5 * float(np.ptp(eta))
    u = aperture_time(eta, eta_ref)
    legendre = [(3 * u**2 - 1) / 2, (5 * u**3 - 3 * u) / 2, (35 * u**4 - 30 * u**2 + 3) / 8]
    a = [0.0, 0.0, 0.0]

    def sharpness(q):
        ph = unit_phasor(2 * np.pi * sum(c * w for c, w in zip(q, legendre)))
        mag2 = np.abs(scipy.fft.fft(sub * ph[:, None], n=n_eta, axis=0)) ** 2
        return float(np.sum(mag2 * mag2))

    def score(k, value):
        q = list(a)
        q[k] = value
        return sharpness(q)

    order = order_span * higher_order_cycles + 1.0
    spans = [rate_span * abs(fm_rate) * half**2 / 3, order / 2.5, order / 4.375]
    for k in range(3):
        a[k] = _zoom(lambda x: score(k, x), a[k], spans[k])
    # then all three together: with errors of a radian or more the terms are not independent
    # (a 0.5-cycle P3 error moves the best a2 by 0.4 cycles), a local search finishes
    simplex = np.array(a) + np.vstack([np.zeros(3), 0.25 * np.eye(3)])
    best = minimize(lambda q: -np.log(sharpness(q)), a, method="Nelder-Mead",
                    options={"initial_simplex": simplex, "xatol": STEP / 4, "fatol": 1e-7, "maxfev": 400})
    a = list(best.x)
    # the Legendre terms as Taylor monomials, their constant and linear parts dropped
    return np.array([1.5 * a[0] - 3.75 * a[2], 2.5 * a[1], 4.375 * a[2]])
