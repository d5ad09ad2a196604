"""Where a moving target's echo lies in a range-compressed record: the cells that stand out of
the noise.

Not in Kiang & Kiang 2022; it only looks at |s(tau, eta)|, so the method keeps its "no prior
knowledge" premise. The support gates the RFRT sum (see :mod:`.sowvd`): summed over a whole
record the noise term sum n_k^2 grows as sqrt(cells) while the echo adds one range cell, which at
-15 dB SNR buries the echo before the SoWVD sees it.

The power |x|^2 is averaged over :data:`PULSES` pulses along each range cell (a slowly walking
trace keeps its energy there) and compared with the noise floor of its range cell, the median
over the pulses: the noise after range compression is not flat across a short recording window
(near its ends the matched filter overlaps fewer noisy samples: ten times less power at the ends
of Table I's windows). A target that keeps its range cell in most pulses (Table II case 7 at A)
would be its own floor, so a cell's floor is capped at 4x the median floor of all cells. The
threshold is :data:`SIGMAS` standard deviations of the average over the floor; the gate is
widened by one range resolution cell each side.

The band. Near the method's noise floor the echo stands out in only some of the pulses, and a pulse left out of the RFRT sum is a gap
in every lag product of the SoWVD that reaches it. The target's trace is smooth: its delay is
tau_0 + (f_dc / f0) eta + (K / 2 f0) eta^2 to within a fraction of a cell over the aperture. So
the cells that stand out are fitted by a parabola in the pulse index (each pulse by the
power-weighted middle of its cells, weighted by their excess power; points further than
:data:`BAND_REJECT` median absolute deviations from the fit dropped and the fit repeated), and
every pulse gets the band of cells within the gated cells' spread about it (:func:`band`). The
gate is then the band together with the cells that stood out (another target's trace stays in).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import maximum_filter1d, uniform_filter1d

PULSES = 9
SIGMAS = 5.0
#: Robust fit of the band: points beyond this many median absolute deviations are dropped.
BAND_REJECT = 4.0
#: Passes of the band's fit.
BAND_PASSES = 4


#: A range cell's noise floor is kept above this fraction of the median floor of the cells that
#: record noise: near the ends of a recording window the compressed noise is ~10x weaker (the
#: matched filter overlaps fewer noisy samples).
FLOOR_MIN = 0.05
#: Cells whose floor is below this fraction of the largest are not recording (a receiver's records
#: are zero-padded to the echo's length beyond its own window) and do not count in the median:
#: counted, they made it the padding's and every recorded cell stood out of its floor capped at
#: 4x that (sonobuoy C, whose window is shorter than A's and B's, gated almost every recorded
#: cell in noise and its SoWVD score fell to the whole record's).
RECORDING = 1e-3


def floor(power: np.ndarray) -> np.ndarray:
    """The noise floor of each range cell of a (n_pulses, n_samples) map: its median over the
    pulses, capped at 4x the median over the recording cells (:data:`RECORDING`) and kept above
    :data:`FLOOR_MIN` of it (module docstring). float32 (n_samples,)."""
    level = np.median(power[::2], axis=0).astype(np.float32)
    live = level[level > RECORDING * float(level.max())] if level.size else level
    if live.size == 0:
        return level
    typical = float(np.median(live))
    return np.clip(level, FLOOR_MIN * typical, 4 * typical)


def support(records: np.ndarray, upsample: int = 1) -> np.ndarray:
    """Bool (n_pulses, n_samples): the cells of ``records`` (range-compressed, ``upsample`` x the
    bandwidth) where the echo stands out of the noise (module docstring)."""
    power = uniform_filter1d(np.abs(records).astype(np.float32) ** 2, PULSES, axis=0, mode="constant")
    level = floor(power) * (1.0 + SIGMAS / np.sqrt(PULSES))
    gate = power > level
    return maximum_filter1d(gate, 1 + 2 * upsample, axis=1)


def band(records: np.ndarray, gate: np.ndarray, upsample: int = 1) -> np.ndarray:
    """Bool (n_pulses, n_samples): ``gate`` (:func:`support`) together with the band around the
    parabola its cells follow over the pulses (module docstring); ``gate`` unchanged when fewer
    than a quarter of the pulses hold a gated cell."""
    n_pulses, n_samples = gate.shape
    rows = np.flatnonzero(gate.any(axis=1))
    if rows.size < max(8, n_pulses // 4):
        return gate
    power = np.abs(records[rows]).astype(np.float32) ** 2 * gate[rows]
    weight = power.sum(axis=1)
    keep = weight > 0
    rows, power, weight = rows[keep], power[keep], weight[keep]
    middle = power @ np.arange(n_samples, dtype=np.float64) / weight
    x = (rows - 0.5 * (n_pulses - 1)) / max(n_pulses - 1, 1)
    fit = robust_polyfit(x, middle, np.sqrt(weight), np.ones(rows.size, bool), reject=BAND_REJECT, mad_floor=0.5,
                         passes=BAND_PASSES, min_points=8, too_few="fail", readmit=True)
    if fit is None:
        return gate
    coef, use = fit
    centre = np.polyval(coef, (np.arange(n_pulses) - 0.5 * (n_pulses - 1)) / max(n_pulses - 1, 1))
    # the half-width: the gated cells' spread about the fit where it holds, and a resolution cell
    cells = np.nonzero(gate[rows[use]])
    spread = np.abs(cells[1] - centre[rows[use]][cells[0]])
    half = float(np.percentile(spread, 90)) + upsample if spread.size else 2.0 * upsample
    k = np.arange(n_samples)
    return gate | (np.abs(k[None, :] - centre[:, None]) <= half)


def robust_polyfit(x: np.ndarray, y: np.ndarray, w: np.ndarray, use: np.ndarray, *, reject: float,
                   mad_floor: float, passes: int, min_points: int, too_few: str, readmit: bool,
                   degree: int = 2) -> tuple[np.ndarray, np.ndarray] | None:
    """A weighted polynomial fit of ``y`` over ``x`` (each (m,); weights ``w`` as np.polyfit's)
    that drops outliers: fitted to the points ``use`` (bool (m,)), the points further than
    ``reject`` median absolute deviations of the fitted points' residuals (plus ``mad_floor``, in
    y's units: a near-perfect fit must not reject everything) are dropped and the fit repeated, at
    most ``passes`` times (``passes`` >= 1), and not again once the kept points stop changing.

    The stopping rule when fewer than ``min_points`` would be kept: ``too_few="fail"`` returns
    None, ``too_few="keep"`` keeps the last fit and its points. ``readmit``: a point dropped in one
    pass may come back in the next when the new fit passes near it (else the points kept only
    shrink). Returns (the last fit's coefficients, highest power first; the points its residuals
    keep: those it was fitted to when it stopped on too few or on no change)."""
    use = np.asarray(use, bool)
    for _ in range(passes):
        coef = np.polyfit(x[use], y[use], degree, w=w[use])
        residual = y - np.polyval(coef, x)
        mad = float(np.median(np.abs(residual[use]))) + mad_floor
        keep = np.abs(residual) <= reject * mad
        if not readmit:
            keep &= use
        if keep.sum() < min_points:
            return None if too_few == "fail" else (coef, use)
        if np.array_equal(keep, use):  # the next fit would be this one
            return coef, use
        use = keep
    return coef, use
