"""Azimuth FM rate from the range-frequency reversal transform (RFRT) and the modified
second-order Wigner-Ville distribution (SoWVD): Kiang & Kiang 2022, eqs. (10)-(14).

RFRT at tau_0 = 0 (eqs. 10-11). For one pulse, let x_k be the range-compressed record and
X(f) its range spectrum. S_rfrt(f) = X(f) X(-f); its inverse FFT at lag 0 is

    s_rfrt(0, eta) = (1/N) sum_f X(f) X(-f) = sum_k x_k x_k        (no conjugate)

(write X(f) X(-f) = sum_{k,l} x_k x_l exp(-j 2 pi f (k - l) / N) and sum over f). For a point
target x_k = A sinc(B (t_k - tau(eta))) exp(-j 2 pi f0 tau(eta)), so

    s_rfrt(0, eta) = A^2 (sum_k sinc^2) exp(-j 4 pi f0 tau(eta)),

the range migration gone (eq. 11) and the azimuth phase doubled. ``weight`` restricts the sum to
the cells where the echo stands out of the noise (:func:`clsas.estimate.moving.trace.support`):
summed over a whole record of N cells, the noise term sum n_k^2 has a standard deviation sqrt(N)
times the noise power while the echo contributes one cell's worth, which at -15 dB SNR buries
the echo before the SoWVD sees it. The paper sums over the whole record; with the weight this is
the same sum restricted to where there is signal (all of it for noise-free echoes).

Modified SoWVD (eq. 12) with the lag offset p0 = q / PRF, on lags p = 2 m / PRF:

    s_wv[m, n] = s[n+m] s*[n-m] (s[n+m+q] s*[n-m-q])* = g[n+m] g[n-m-q],   g[k] = s[k] s*[k+q].

With s = exp(j phi), phi(eta) = -2 pi (2 f_dc eta + K eta^2) (the RFRT's doubled phase), the
phase of s_wv is phi(n+m) - phi(n-m) - phi(n+m+q) + phi(n-m-q) = 8 pi K p0 eta + 8 pi f_dc p0:
independent of the lag p and linear in eta, so its 2-D Fourier transform (eq. 13) peaks at
(f_p, f_eta) = (0, 4 p0 K) (eq. 14) and K = f_eta / (4 p0).

Azimuth aliasing. The four samples of each product are taken at whole pulses, so the product's
phase is the exact combination above whatever the azimuth chirp's bandwidth against the PRF
(Table I: K T_a ~ 390 Hz, doubled to ~780 Hz by the RFRT, against 80 Hz): the RFRT and the
SoWVD are not affected by azimuth aliasing. The only ambiguity is that of the peak itself:
f_eta = 4 p0 K is read modulo the PRF, so |K| < PRF / (8 p0) (100 Hz/s for p0 = 0.1 s at
80 Hz; 25 Hz/s at 20 Hz).

Long apertures. The delay's cubic and quartic terms make the line's instantaneous rate
f0 tau''(eta) vary over the aperture, so its f_eta spreads over a band rather than one bin, and
the band's largest value (what the search reads) need not be its average: on Table II case 6
(a point) the instantaneous rate runs from +11 % to -17 % of the Taylor K at A over 80 s (its
average -1.0 %, its Legendre P2 part, the rate the focus uses, -0.4 %), and the rate search
reads +7.4, +4.9, +6.7 % at A, B, C noise-free (+7.1, +4.2, +6.4 % at -15 dB; the followed
trace's curvature there, :func:`.track.trace_rate`, -0.42, -0.49, -0.34 %: the P2 part to
0.02 %). Over 25.6 s the band is +4 % to -5 % wide, a few bins, and the peak lies within ~1 %
(the paper's own 4.834 against 4.879 Hz/s in case 1). The chain's focus passes
(:func:`.located.focused_rate`) and the refocus with the model's higher-order terms
(:func:`.motion.estimate`'s refocus passes) correct the first rate.

Cross-terms (not in the paper; derived here). A target of several scatterers gives an RFRT line
s = sum_i a_i exp(j phi_i), phi_i(eta) = -2 pi (2 f_i eta + K eta^2): every scatterer of a rigid
target shares K (up to its tiny dependence on range) and has its own centroid f_i (its position
along the synthetic aperture). The fourfold product of eq. (12) then holds a term for every
choice (a, b, c, d) of the scatterers in its four factors s[n+m], s*[n-m], s*[n+m+q],
s[n-m-q]. Its phase, with the quadratic parts summed first,
(n+m)^2 - (n-m)^2 - (n+m+q)^2 + (n-m-q)^2 = -4 n q (any a, b, c, d), is

    8 pi K q n / PRF^2  -  4 pi [n (f_a - f_b - f_c + f_d) + m (f_a + f_b - f_c - f_d)] / PRF + const,

so every term peaks at f_eta = 4 p0 K - 2 (f_a - f_b - f_c + f_d), f_p = -(f_a + f_b - f_c - f_d).
The auto-terms (a = b = c = d) and the cross-terms with f_a - f_b = f_c - f_d sit at the true
f_eta = 4 p0 K; the others are shifted by twice a combination of centroid differences, which
does not depend on p0. Their strength is comparable: the auto-terms carry the constant phase
8 pi f_i p0, which differs between scatterers, so they can cancel: on three equal points 5 m
apart along the track the strongest peak of the map at p0 = 0.1 s is a cross-term at every
receiver, far from the true K (tests/test_moving_confidence.py::
test_one_sowvd_map_locks_on_a_cross_term_the_rate_search_does_not).

Hence :func:`rate_search`: maps at several lag offsets p0_j (:data:`P0_RATIOS`), each read on a
common K axis (f_eta = 4 p0_j K, modulo the PRF). A term at the true K lines up in every map; a
shifted cross-term lands at K + delta / (4 p0_j), a different K in each. The score of a K is the
mean over the maps of 20 log10 of the map's largest value over f_p at that K over the map's
median; its best local maximum is K (refined below one bin on the first map, p0 itself). On the
three points it picked 4.855, 4.830 and 3.075 Hz/s, the next candidate 1.3 to 1.8 dB lower a map
on average. The maps alias differently, so the combination also resolves the ambiguity of one
map (a K that lines up in every map modulo the PRF needs p0_j in integer ratios).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
import scipy.fft


def rfrt(records: np.ndarray, weight: np.ndarray | None = None) -> np.ndarray:
    """s_rfrt(tau_0 = 0, eta) of eq. (11) for range-compressed ``records`` (n_pulses, n_samples).

    ``weight`` (same shape, bool or real) multiplies each cell (None: every cell). Returns
    complex128 (n_pulses,).
    """
    x = np.asarray(records)
    if x.ndim != 2:
        raise ValueError(f"records must be 2-D (pulse, sample), got shape {x.shape}")
    out = np.empty(x.shape[0], dtype=np.complex128)
    for s in range(0, x.shape[0], 256):
        block = x[s:s + 256].astype(np.complex128)
        sq = block * block
        if weight is not None:
            sq *= weight[s:s + 256]
        out[s:s + 256] = sq.sum(axis=1)
    return out


@dataclass(frozen=True)
class SoWVD:
    """|S_wv(f_p, f_eta)| of eq. (13) and its strongest peak.

    magnitude : float32 (n_fp, n_feta), axes ``f_p`` (Hz, over the lag p) and ``f_eta`` (Hz),
        both ascending (FFT-shifted); ``p0`` the lag offset, s.
    peak_f_eta : Hz, the strongest peak's f_eta refined below one bin; ``fm_rate`` = that / (4 p0).
    peak_to_background : the peak over the median of ``magnitude`` (linear; noise-only maps give
        15-20 dB in 20 log10).
    """

    magnitude: np.ndarray
    f_p: np.ndarray
    f_eta: np.ndarray
    p0: float
    peak_f_eta: float
    peak_f_p: float
    peak_to_background: float

    @property
    def fm_rate(self) -> float:
        """K_a,eq = f_eta / (4 p0), Hz/s (eq. 14)."""
        return self.peak_f_eta / (4 * self.p0)


def lag_products(s: np.ndarray, q: int, n_lags: int) -> np.ndarray:
    """s_wv[m, n] = g[n+m] g[n-m-q] (eq. 12), g[k] = s[k] s*[k+q]; zero where a sample falls
    outside the record. Returns complex64 (n_lags, n_pulses)."""
    s = np.asarray(s, dtype=np.complex128)
    m_pulses = s.size
    off = n_lags + q
    g = np.zeros(m_pulses + 2 * off + 1, dtype=np.complex128)
    g[off:off + m_pulses - q] = s[:m_pulses - q] * np.conj(s[q:])
    n = np.arange(m_pulses)
    out = np.empty((n_lags, m_pulses), dtype=np.complex64)
    step = max(1, (1 << 22) // m_pulses)
    for m0 in range(0, n_lags, step):
        m = np.arange(m0, min(m0 + step, n_lags))[:, None]
        out[m0:m0 + m.shape[0]] = g[off + n + m] * g[off + n - m - q]
    return out


def _refine_peak(row: np.ndarray, prf: float, f_coarse: float, bin_hz: float) -> float:
    """The f_eta of the largest |DTFT| of ``row`` (pulse rate ``prf``) within one bin of
    ``f_coarse``: 65-point zoom, then a parabola through the best three (log magnitude)."""
    f = f_coarse + np.linspace(-bin_hz, bin_hz, 65)
    n = np.arange(row.size)
    mag = np.abs(np.exp(-2j * np.pi * np.outer(f / prf, n)) @ row)
    i = int(np.clip(np.argmax(mag), 1, f.size - 2))
    a, b, c = np.log(mag[i - 1:i + 2] + 1e-300)
    den = a - 2 * b + c
    shift = 0.5 * (a - c) / den if den < 0 else 0.0
    return float(f[i] + shift * (f[1] - f[0]))


#: Lag offsets of :func:`rate_search` relative to p0 (rounded to distinct whole pulses): not in
#: simple integer ratios, so that cross-terms and aliases land at different K in each map.
P0_RATIOS = (1.0, 1.375, 1.875, 2.375)
#: Candidates of :func:`rate_search` at most, and their least separation in K bins of the first map.
CANDIDATES = 8
CANDIDATE_SEPARATION = 3.0


def _map(s: np.ndarray, prf: float, q: int, n_lags: int, workers: int):
    """(|S_wv| float32 (n_lags, n_pulses) unshifted, f_p, f_eta, lag products) of eq. (13)."""
    products = lag_products(s, q, n_lags)
    spectrum = scipy.fft.fft2(products, workers=workers)
    magnitude = np.abs(spectrum).astype(np.float32)
    del spectrum
    return magnitude, scipy.fft.fftfreq(n_lags, d=2.0 / prf), scipy.fft.fftfreq(s.size, d=1.0 / prf), products


def _check_lag(p0: float, prf: float, m_pulses: int) -> int:
    q = int(round(p0 * prf)) if np.isfinite(p0) else 0
    if q < 1 or q > m_pulses // 4:
        raise ValueError(f"p0 must be between one pulse (1/PRF = {1 / prf:.4g} s) and a quarter of the "
                         f"aperture ({m_pulses // 4 / prf:.4g} s), got {p0}")
    return q


def _check_lags(n_lags, m_pulses: int) -> int:
    n_lags = m_pulses // 2 if n_lags is None else int(n_lags)
    if not 2 <= n_lags <= m_pulses // 2:
        raise ValueError(f"n_lags must be in [2, {m_pulses // 2}], got {n_lags}")
    return n_lags


def _refined(_, f_p, f_eta, products, prf: float, i_p: int, i_eta: int) -> float:
    """f_eta of the peak at (i_p, i_eta) refined below one bin along its f_p row."""
    p_lags = 2 * np.arange(products.shape[0]) / prf
    row = (np.exp(-2j * np.pi * f_p[i_p] * p_lags).astype(np.complex64) @ products).astype(np.complex128)
    return _refine_peak(row, prf, float(f_eta[i_eta]), prf / products.shape[1])


def _sorted(magnitude, f_p, f_eta):
    order_p, order_eta = np.argsort(f_p), np.argsort(f_eta)
    return magnitude[order_p][:, order_eta], f_p[order_p], f_eta[order_eta]


def modified_sowvd(s: np.ndarray, prf: float, p0: float, n_lags: int | None = None,
                   workers: int | None = None) -> SoWVD:
    """The modified SoWVD of the RFRT line ``s`` (n_pulses,) sampled at ``prf`` (eqs. 12-14).

    ``p0`` (s) is rounded to a whole number q >= 1 of pulses; lags p = 2 m / PRF for
    m < ``n_lags`` (default half the pulses: lags up to the whole aperture). The map is the
    2-D FFT over (m, n) of :func:`lag_products`; its strongest peak gives K = f_eta / (4 p0)
    after a sub-bin refinement along its f_p row. Cost O(n_lags n_pulses log), memory
    ~16 n_lags n_pulses bytes (Table I: 3200 x 6400, 0.3 GB). The strongest peak may be a
    cross-term on a target of several scatterers (module docstring): :func:`rate_search`.
    """
    s = np.asarray(s)
    q = _check_lag(p0, prf, s.size)
    n_lags = _check_lags(n_lags, s.size)
    workers = os.cpu_count() if workers is None else int(workers)
    magnitude, f_p, f_eta, products = _map(s, prf, q, n_lags, workers)
    i_p, i_eta = np.unravel_index(int(np.argmax(magnitude)), magnitude.shape)
    background = float(np.median(magnitude[::2, ::2]))  # a quarter of the cells: same median
    ratio = float(magnitude[i_p, i_eta] / background) if background > 0 else np.inf
    f_peak = _refined(magnitude, f_p, f_eta, products, prf, i_p, i_eta)
    magnitude, f_p_sorted, f_eta_sorted = _sorted(magnitude, f_p, f_eta)
    return SoWVD(magnitude=magnitude, f_p=f_p_sorted, f_eta=f_eta_sorted, p0=q / prf, peak_f_eta=f_peak,
                 peak_f_p=float(f_p[i_p]), peak_to_background=ratio)


@dataclass(frozen=True)
class RateSearch:
    """The azimuth FM rate from modified SoWVD maps at several lag offsets (module docstring).

    fm_rate : K_a,eq, Hz/s (the best candidate, refined: :meth:`refine`). candidates :
    (n, 2) float64, each row (K Hz/s, score dB), best first: the local maxima of the score over
    K. score_db : the best candidate's score: the mean over the maps of 20 log10 of the map's
    largest value at that K (over f_p) over its median. margin_db : its lead over the next
    candidate, dB (inf when there is none). p0 : the lag offsets, s. primary : the first map
    (p0[0]) as a :class:`SoWVD` whose peak is the chosen K (None once dropped to save memory).
    line, prf, maps, n_lags: what :meth:`refine` needs (the RFRT line; per map its lag offset in
    pulses, f_p and f_eta axes and strongest f_p row per f_eta column). trace_line : (slope in
    samples a pulse, sample) at the middle pulse of the trace the RFRT's gate followed
    (:func:`.track.bright_gate`), or None when its gate was not a followed trace. trace_rates :
    (K Hz/s, ...) read from the curvature of the traces followed while searching
    (:func:`.track.trace_rate`; :func:`.gated.sowvd` fills it), () when none was followed or
    each was followed as a straight line only (no curvature).
    """

    fm_rate: float
    candidates: np.ndarray
    score_db: float
    margin_db: float
    p0: tuple
    primary: SoWVD | None = field(default=None, repr=False)
    line: np.ndarray | None = field(default=None, repr=False)
    prf: float = float("nan")
    maps: tuple = field(default=(), repr=False)
    n_lags: int = 0
    trace_line: tuple | None = None
    trace_rates: tuple = ()

    def refine(self, k: float) -> float:
        """A candidate K (Hz/s) refined below one bin in every map, the median over them."""
        return _refine_rate(self.line, self.prf, self.maps, float(k), self.n_lags)

    @property
    def peak_to_background(self) -> float:
        """The score as a linear ratio (comparable to a single map's peak over its median)."""
        return float(10.0 ** (self.score_db / 20.0))


def _column(f_eta: np.ndarray, f: float, prf: float) -> int:
    """The index of the f_eta bin nearest ``f`` modulo the PRF."""
    return int(np.argmin(np.abs((f_eta - f + 0.5 * prf) % prf - 0.5 * prf)))


def _refine_rate(s: np.ndarray, prf: float, maps: list, k: float, n_lags: int) -> float:
    """K (Hz/s) near ``k`` refined below one bin in each map: ``maps`` holds per lag offset q
    (pulses) its f_p and f_eta axes and its strongest f_p row per f_eta column; the row at the
    bin of f_eta = 4 p0 k, its zoomed DTFT within one bin (:func:`_refine_peak`). The median over
    the maps: a cross-term next to the peak in one map does not move it."""
    found = []
    for q, f_p, f_eta, rows in maps:
        p0 = q / prf
        i_eta = _column(f_eta, 4 * p0 * k, prf)
        products = lag_products(s, q, n_lags)
        f_peak = _refined(None, f_p, f_eta, products, prf, int(rows[i_eta]), i_eta)
        del products
        period = prf / (4 * p0)  # the map reads K modulo this
        k_j = f_peak / (4 * p0)
        found.append(k_j + period * np.round((k - k_j) / period))
    return float(np.median(found))


def lag_offsets(p0: float, prf: float, m_pulses: int, ratios=P0_RATIOS) -> list[int]:
    """The distinct whole-pulse lags q_j of :func:`rate_search` (the first p0's own), each within a
    quarter of the aperture; fewer when the aperture is short."""
    q0 = _check_lag(p0, prf, m_pulses)
    out = []
    for r in ratios:
        q = max(int(round(q0 * r)), out[-1] + 1 if out else q0)
        if q <= m_pulses // 4:
            out.append(q)
    return out


def rate_search(s: np.ndarray, prf: float, p0: float, n_lags: int | None = None, workers: int | None = None,
                ratios=P0_RATIOS) -> RateSearch:
    """K_a,eq of the RFRT line ``s`` (n_pulses,) at ``prf`` from maps at the lag offsets
    :func:`lag_offsets` of ``p0`` (module docstring): robust to the cross-terms of targets made
    of several scatterers. |K| < PRF / (8 p0) is searched (the first map's unambiguous span).
    Cost: one :func:`modified_sowvd` a lag offset."""
    s = np.asarray(s)
    m_pulses = s.size
    qs = lag_offsets(p0, prf, m_pulses, ratios)
    n_lags = _check_lags(n_lags, m_pulses)
    workers = os.cpu_count() if workers is None else int(workers)
    k_max = prf * prf / (8.0 * qs[0])
    k_bin = prf * prf / (4.0 * qs[-1] * m_pulses)  # the finest map's K bin
    k_axis = np.arange(-k_max, k_max, 0.25 * k_bin)
    score = np.zeros(k_axis.size)
    first, maps = None, []
    for q in qs:
        magnitude, f_p, f_eta, products = _map(s, prf, q, n_lags, workers)
        background = float(np.median(magnitude[::2, ::2]))
        profile = magnitude.max(axis=0).astype(np.float64) / (background if background > 0 else 1.0)
        order = np.argsort(f_eta)
        wrapped = (4.0 * q / prf * k_axis + 0.5 * prf) % prf - 0.5 * prf
        score += 20.0 * np.log10(np.maximum(np.interp(wrapped, f_eta[order], profile[order], period=prf), 1e-30))
        maps.append((q, f_p, f_eta, np.argmax(magnitude, axis=0)))
        if first is None:
            first = (magnitude, f_p, f_eta, background)
        del magnitude, products
    score /= len(qs)
    # the candidates: local maxima of the score, at least CANDIDATE_SEPARATION bins of the first map apart
    sep = CANDIDATE_SEPARATION * prf * prf / (4.0 * qs[0] * m_pulses)
    peaks = np.flatnonzero((score >= np.roll(score, 1)) & (score >= np.roll(score, -1)))
    peaks = peaks[np.argsort(score[peaks])[::-1]]
    chosen = []
    for i in peaks:
        if all(abs(k_axis[i] - k_axis[j]) > sep for j in chosen):
            chosen.append(i)
        if len(chosen) == CANDIDATES:
            break
    candidates = np.array([[k_axis[i], score[i]] for i in chosen])
    k = _refine_rate(s, prf, maps, float(candidates[0, 0]), n_lags)
    magnitude, f_p, f_eta, background = first
    p0_first = qs[0] / prf
    i_eta = _column(f_eta, 4 * p0_first * k, prf)
    i_p = int(np.argmax(magnitude[:, i_eta]))
    ratio = float(magnitude[i_p, i_eta] / background) if background > 0 else np.inf
    sorted_mag, f_p_sorted, f_eta_sorted = _sorted(magnitude, f_p, f_eta)
    primary = SoWVD(magnitude=sorted_mag, f_p=f_p_sorted, f_eta=f_eta_sorted, p0=p0_first, peak_f_eta=4 * p0_first * k,
                    peak_f_p=float(f_p[i_p]), peak_to_background=ratio)
    margin = float(candidates[0, 1] - candidates[1, 1]) if len(candidates) > 1 else np.inf
    return RateSearch(fm_rate=float(k), candidates=candidates, score_db=float(candidates[0, 1]), margin_db=margin,
                      p0=tuple(q / prf for q in qs), primary=primary, line=s, prf=float(prf), maps=tuple(maps),
                      n_lags=n_lags)
