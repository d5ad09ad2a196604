"""Where a moving target's echo lies in a range-compressed record: the cells that stand out of
the noise.

Not in Kiang & Kiang 2022; it only looks at |s(tau, eta)|, so the method keeps its "no prior
knowledge" premise. The support gates the RFRT sum (see :mod:`.sowvd`: without it the noise of
the whole record buries the echo at -15 dB SNR).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter

#: Smoothing box of the power map (pulses, samples at the base rate): a target walking up to
#: one sample a pulse (Table II case 8 walks 0.99) keeps most of its energy in it.
BOX = (9, 3)


def smoothed_power(records: np.ndarray, upsample: int = 1) -> np.ndarray:
    """|x|^2 averaged over a :data:`BOX` of (pulses, samples x ``upsample``), float32, same shape."""
    power = np.abs(records).astype(np.float32) ** 2
    return uniform_filter(power, size=(BOX[0], BOX[1] * upsample), mode="constant")


def support(power: np.ndarray, sigmas: float = 5.0, upsample: int = 1) -> np.ndarray:
    """Cells of the smoothed power map ``power`` above the noise floor: median x (1 + sigmas /
    sqrt(cells)), the noise-only average over the box's ``cells`` independent cells having that
    standard deviation relative to its mean (the median stands for the mean: the echo fills a small
    part of the record). Bool, same shape."""
    cells = BOX[0] * BOX[1]
    floor = float(np.median(power[::2, ::max(1, upsample)]))
    return power > floor * (1.0 + sigmas / np.sqrt(cells))
