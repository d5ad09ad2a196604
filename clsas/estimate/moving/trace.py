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
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import maximum_filter1d, uniform_filter1d

PULSES = 9
SIGMAS = 5.0


def floor(power: np.ndarray) -> np.ndarray:
    """The noise floor of each range cell of a (n_pulses, n_samples) map: its median over the
    pulses, capped at 4x the median over the cells and kept above 1e-3 of it (module
    docstring). float32 (n_samples,)."""
    level = np.median(power[::2], axis=0).astype(np.float32)
    live = level[level > 0]
    if live.size == 0:
        return level
    typical = float(np.median(live))
    return np.clip(level, 1e-3 * typical, 4 * typical)


def support(records: np.ndarray, upsample: int = 1) -> np.ndarray:
    """Bool (n_pulses, n_samples): the cells of ``records`` (range-compressed, ``upsample`` x the
    bandwidth) where the echo stands out of the noise (module docstring)."""
    power = uniform_filter1d(np.abs(records).astype(np.float32) ** 2, PULSES, axis=0, mode="constant")
    gate = power > floor(power) * (1.0 + SIGMAS / np.sqrt(PULSES))
    return maximum_filter1d(gate, 1 + 2 * upsample, axis=1)
