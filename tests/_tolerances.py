"""Tolerances and error measures the tests share, stated from the precision budget.

float32 carries a 24-bit mantissa (unit roundoff 6e-8); a kernel that sums N float32 terms
accumulates at most about sqrt(N) * 6e-8 relative error in the typical case. Phases are
computed from cycles reduced to their fractional part, so their error is set by how
precisely the cycle count itself is represented (see each test).
"""

from __future__ import annotations

import numpy as np

FLOAT32_EPS = float(np.finfo(np.float32).eps)
FLOAT64_EPS = float(np.finfo(np.float64).eps)


def rel_l2(actual, expected) -> float:
    """||actual - expected||_2 / ||expected||_2."""
    actual = np.asarray(actual, dtype=np.complex128)
    expected = np.asarray(expected, dtype=np.complex128)
    norm = np.linalg.norm(expected)
    if norm == 0:
        raise ValueError("rel_l2: the expected array is all zeros")
    return float(np.linalg.norm(actual - expected) / norm)


def max_abs(actual, expected) -> float:
    """max |actual - expected| (L-infinity)."""
    return float(np.max(np.abs(np.asarray(actual) - np.asarray(expected))))


def phase_error(actual, expected) -> np.ndarray:
    """|angle(actual / expected)| in radians, element-wise."""
    return np.abs(np.angle(np.asarray(actual, np.complex128) * np.conj(np.asarray(expected, np.complex128))))
