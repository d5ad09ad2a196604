"""Field checks shared by the scenario dataclasses: each error names the field and the allowed range."""

from __future__ import annotations

import numbers

import numpy as np


def scalar(name: str, value, *, low: float | None = None, high: float | None = None,
           low_open: bool = False, high_open: bool = False) -> float:
    """A finite real number within [low, high] (or open ends); returns it as float."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    v = float(value)
    lo_txt = "-inf" if low is None else f"{low:g}"
    hi_txt = "inf" if high is None else f"{high:g}"
    allowed = f"{'(' if low_open or low is None else '['}{lo_txt}, {hi_txt}{')' if high_open or high is None else ']'}"
    if not np.isfinite(v):
        raise ValueError(f"{name} must be finite, in {allowed}; got {value}")
    if low is not None and (v < low or (low_open and v == low)):
        raise ValueError(f"{name} must be in {allowed}, got {v:g}")
    if high is not None and (v > high or (high_open and v == high)):
        raise ValueError(f"{name} must be in {allowed}, got {v:g}")
    return v


def positive(name: str, value) -> float:
    """A finite number > 0."""
    return scalar(name, value, low=0.0, low_open=True)


def count(name: str, value, minimum: int = 1) -> int:
    """An integer >= minimum."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value}")
    return int(value)


def array(name: str, value, shape: tuple, *, nonnegative: bool = False) -> np.ndarray:
    """A finite float64 array of the given shape (-1 = any length), returned read-only.

    ``shape`` entries of -1 accept any size along that axis.
    """
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise TypeError(f"{name} must be an array of real numbers with shape {shape}: {err}") from err
    if arr.ndim != len(shape) or any(s not in (-1, n) for s, n in zip(shape, arr.shape)):
        want = "(" + ", ".join("n" if s == -1 else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite everywhere; it has NaN or inf")
    if nonnegative and np.any(arr < 0):
        raise ValueError(f"{name} must be >= 0 everywhere, got minimum {arr.min():g}")
    arr.flags.writeable = False
    return arr


def vector3(name: str, value) -> np.ndarray:
    """A finite (3,) float64 vector (x, y, z), read-only."""
    return array(name, value, (3,))
