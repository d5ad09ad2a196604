"""Argument checks shared by every public entry point (ground floor: imports nothing of clsas).

One style everywhere: a bad argument raises ``TypeError`` (wrong kind: a string where a number
belongs, a float where an integer belongs) or ``ValueError`` (right kind, wrong value: NaN, out of
range, wrong shape), and the message names the parameter, shows the value and says what is
allowed::

    Platform.speed: must be in (0, 100] m/s (far below the sound speed), got 2000
    range_compress taylor_nbar: must be an integer in [1, 100], got 1000000

The bounds below keep every derived quantity finite in float64 (and the records in complex64):
they are far outside any sonar's range, so they only refuse nonsense.
"""

from __future__ import annotations

import numbers

import numpy as np

MAX_COORDINATE = 1e6  # m: positions and offsets (1000 km; delays stay below ~1e3 s)
MAX_SPEED = 100.0  # m/s: platforms and targets (the delay model needs speeds << sound speed >= 1000 m/s)
MAX_TIME = 1e6  # s: emission times, recording starts
MAX_AMPLITUDE = 1e15  # reflectivities: sums of 1e20 such echoes stay below complex64's 3.4e38


class CoverageWarning(UserWarning):
    """An imager's grid lies wholly outside what was recorded (its image is all zeros)."""


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _interval(low, high, low_open, high_open, unit) -> str:
    lo = "-inf" if low is None else f"{low:g}"
    hi = "inf" if high is None else f"{high:g}"
    text = f"{'(' if low_open or low is None else '['}{lo}, {hi}{')' if high_open or high is None else ']'}"
    return f"{text} {unit}".rstrip()


def is_number(value, kinds: str = "iuf") -> bool:
    """A real (kinds "iuf") or integer ("iu") number: Python, NumPy scalar or 0-d array; not bool."""
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, np.ndarray) and value.ndim == 0:
        return value.dtype.kind in kinds
    return isinstance(value, numbers.Integral if kinds == "iu" else numbers.Real)


def scalar(name: str, value, *, low: float | None = None, high: float | None = None,
           low_open: bool = False, high_open: bool = False, unit: str = "", why: str = "") -> float:
    """A finite real number within [low, high] (``low_open`` / ``high_open`` exclude the ends);
    returns it as float. ``why`` is appended to the allowed range in the message."""
    allowed = _interval(low, high, low_open, high_open, unit) + (f" ({why})" if why else "")
    if not is_number(value, "iuf"):
        raise TypeError(f"{name}: must be a real number in {allowed}, got {_show(value)} ({type(value).__name__})")
    try:
        v = float(value)
    except OverflowError:
        raise ValueError(f"{name}: must be a finite number in {allowed}, got {_show(value)}") from None
    if not np.isfinite(v):
        raise ValueError(f"{name}: must be a finite number in {allowed}, got {value}")
    if (low is not None and (v < low or (low_open and v == low))) or \
            (high is not None and (v > high or (high_open and v == high))):
        raise ValueError(f"{name}: must be in {allowed}, got {v:g}")
    return v


def positive(name: str, value, high: float | None = None, unit: str = "", why: str = "") -> float:
    """A finite number > 0 (and <= ``high``)."""
    return scalar(name, value, low=0.0, low_open=True, high=high, unit=unit, why=why)


def integer(name: str, value, low: int = 1, high: int | None = None, why: str = "") -> int:
    """An integer (Python or NumPy, not bool) in [low, high]; returns a Python int."""
    allowed = f"an integer in [{low}, {'inf' if high is None else high}]" + (f" ({why})" if why else "")
    if not is_number(value, "iu"):
        raise TypeError(f"{name}: must be {allowed}, got {_show(value)} ({type(value).__name__})")
    v = int(value)
    if v < low or (high is not None and v > high):
        raise ValueError(f"{name}: must be {allowed}, got {_show(v)}")
    return v


def choice(name: str, value, options) -> str:
    """One of ``options`` (strings). Membership is the whole test: anything else, a string or
    not (None, a number), is a ValueError naming the options (docs/design.md: a choice is judged
    by value, not by kind)."""
    if not isinstance(value, str) or value not in options:
        raise ValueError(f"{name}: must be one of {tuple(options)}, got {_show(value)}")
    return value


def flag(name: str, value) -> bool:
    """A bool (Python or NumPy)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name}: must be True or False, got {_show(value)} ({type(value).__name__})")
    return bool(value)


def array(name: str, value, shape: tuple, *, nonnegative: bool = False, bound: float | None = None,
          dtype=np.float64, copy: bool = True) -> np.ndarray:
    """A finite array of the given shape (entries of -1 accept any size), within +-``bound``
    (and >= 0 when ``nonnegative``), as a read-only copy in ``dtype`` (float64 or complex128);
    ``copy=False`` returns an array already of that dtype as it is (for large arrays the caller
    owns)."""
    want = "(" + ", ".join("n" if s == -1 else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
    kind = "complex" if np.dtype(dtype).kind == "c" else "real"
    try:
        if value is None:
            raise TypeError("None")
        raw = np.asarray(value)
        if raw.dtype.kind not in ("iufc" if kind == "complex" else "iuf") and raw.dtype != object:
            raise TypeError(f"dtype {raw.dtype}")
        if raw.dtype == object and not all(isinstance(x, numbers.Number) and not isinstance(x, bool) for x in raw.flat):
            raise TypeError("it holds items that are not numbers")
        arr = np.array(value, dtype=dtype, copy=True if copy else None)
    except (TypeError, ValueError, OverflowError) as err:
        raise TypeError(f"{name}: must be an array of {kind} numbers with shape {want}, got {_show(value)} "
                        f"({err})") from None
    if arr.ndim != len(shape) or any(s not in (-1, n) for s, n in zip(shape, arr.shape)):
        raise ValueError(f"{name}: must have shape {want}, got shape {arr.shape}")
    if not all_finite(arr):
        raise ValueError(f"{name}: must be finite everywhere; it has NaN or inf")
    if bound is not None and arr.size:
        largest = max(np.abs(arr.real.max()), np.abs(arr.real.min())) if arr.dtype.kind == "f" else np.abs(arr).max()
        if largest > bound:
            raise ValueError(f"{name}: must be within +-{bound:g} everywhere, got {largest:g}")
    if nonnegative and arr.size and np.any(arr < 0):
        raise ValueError(f"{name}: must be >= 0 everywhere, got minimum {arr.min():g}")
    if copy:
        arr.flags.writeable = False
    return arr


def vector3(name: str, value, bound: float = MAX_COORDINATE) -> np.ndarray:
    """A finite (3,) float64 vector (x, y, z) within +-``bound``, read-only."""
    return array(name, value, (3,), bound=bound)


def all_finite(data) -> bool:
    """True when ``data`` (any numeric array) holds no NaN or inf. Reads the data once, without a
    boolean mask: a NaN or inf term makes a sum NaN or inf, so a finite sum in the data's own type
    proves every element finite. A sum that is not finite may instead have overflowed from
    finite terms: float16/32 and complex64 data are then summed again in float64 (which cannot
    overflow from such terms), float64 and complex128 data checked element by element."""
    data = np.asarray(data)
    if data.dtype.kind in "iub" or data.size == 0:
        return True
    if data.dtype.kind not in "fc":
        return bool(np.all(np.isfinite(data)))
    with np.errstate(over="ignore", invalid="ignore"):
        if np.isfinite(data.sum()):
            return True
    if np.finfo(data.dtype).bits <= 32:
        return bool(np.isfinite(data.sum(dtype=np.complex128 if data.dtype.kind == "c" else np.float64)))
    return bool(np.all(np.isfinite(data)))


def finite_result(what: str, data, advice: str, dtype=None) -> None:
    """Raise a ValueError when a result computed from finite input is not finite, or (``dtype``
    given, e.g. complex64) will not fit that type: an overflow. ``what`` names the result,
    ``advice`` says which input to scale. Reads the data in place (no temporaries)."""
    data = np.asarray(data)
    target = np.dtype(dtype if dtype is not None else data.dtype)
    largest = float(np.finfo(target).max)
    fits = all_finite(data)
    if fits and target.itemsize < data.dtype.itemsize and data.size:
        parts = (data.real, data.imag) if data.dtype.kind == "c" else (data,)
        fits = all(max(-float(part.min()), float(part.max())) <= largest for part in parts)
    if not fits:
        raise ValueError(f"{what} overflows {target.name} (|value| > {largest:.3g}): {advice}")


def seed(name: str, value):
    """A NumPy seed: None, an integer >= 0, a SeedSequence, a BitGenerator or a Generator."""
    if value is None or isinstance(value, (np.random.SeedSequence, np.random.BitGenerator, np.random.Generator)):
        return value
    return integer(name, value, low=0, why="or None, a SeedSequence or a Generator")


def names(name: str, value, count: int | None = None) -> tuple:
    """A tuple of distinct, non-empty strings (``count`` of them when given): receiver names,
    axis names."""
    if isinstance(value, str) or not isinstance(value, (tuple, list, np.ndarray)):
        raise TypeError(f"{name}: must be a tuple of strings, got {_show(value)} ({type(value).__name__})")
    items = tuple(value)
    wrong = [item for item in items if not isinstance(item, str)]
    if wrong:
        raise TypeError(f"{name}: must be a tuple of strings, got {_show(wrong[0])} ({type(wrong[0]).__name__}) "
                        "among them")
    if count is not None and len(items) != count:
        raise ValueError(f"{name}: must hold {count} names, got {len(items)}: {_show(items)}")
    if not all(items):
        raise ValueError(f"{name}: must be non-empty strings, got {_show(items)}")
    repeated = sorted({item for item in items if items.count(item) > 1})
    if repeated:
        raise ValueError(f"{name}: must be distinct, got {_show(repeated[0])} more than once in {_show(items)}")
    return items


def mapping(name: str, value, none_is_empty: bool = False) -> dict:
    """A dict copy of a mapping (``None`` as ``{}`` when ``none_is_empty``)."""
    if value is None and none_is_empty:
        return {}
    if not isinstance(value, dict):
        raise TypeError(f"{name}: must be a dict, got {_show(value)} ({type(value).__name__})")
    return dict(value)


def element_count(name: str, value) -> int:
    """How many numbers the array-like ``value`` holds, read from its shape (nothing is copied:
    a broadcast view's count is the count it would have as a copy), for a budget check before
    :func:`array` copies it. TypeError when it has no regular shape (ragged lists, scalars of
    other kinds)."""
    try:
        shape = np.shape(value)
    except (ValueError, TypeError) as err:
        raise TypeError(f"{name}: must be an array of numbers, got {_show(value)} ({err})") from None
    return int(np.prod(shape, dtype=np.float64))


def instance(name: str, value, kinds, allowed: str):
    """``value`` when it is an instance of ``kinds`` (a type or a tuple of types); otherwise a
    TypeError naming the parameter, what is ``allowed`` (in words) and what was given."""
    if not isinstance(value, kinds):
        raise TypeError(f"{name}: must be {allowed}, got {_show(value)} ({type(value).__name__})")
    return value


def compression(name: str, echo, compressed: bool = True, advice: str = "call clsas.range_compress(echo) first"):
    """The one check of an echo's range compression: ``echo.compressed`` must equal
    ``compressed``; otherwise a ValueError naming the parameter, what it must be, what it is
    and ``advice`` (what to do). Returns ``echo``."""
    if bool(echo.compressed) != compressed:
        want, got = ("range-compressed", "raw") if compressed else ("raw", "range-compressed")
        raise ValueError(f"{name}: must be a {want} echo (EchoData.compressed {compressed}), got a {got} one; {advice}")
    return echo


def peak_magnitude(data) -> float:
    """The largest |x| of a numeric array, read one slice of its first axis at a time (no
    temporary the size of ``data``)."""
    data = np.asarray(data)
    if data.size == 0:
        return 0.0
    if data.ndim < 2:
        return float(np.abs(data).max())
    return max(float(np.abs(part).max()) for part in data)


def bounded_gain(name: str, data, gain: float, dtype=np.complex64, advice: str = "") -> float:
    """Refuse ``data`` (ValueError naming ``name``) when its largest |sample| times ``gain`` (the
    most a linear processing of it can amplify a sample: FFT lengths, coherent sums) would leave
    ``dtype``'s range, so that the processing cannot return inf from finite input; returns the
    peak magnitude."""
    peak = peak_magnitude(data)
    largest = float(np.finfo(np.dtype(dtype)).max)
    if peak * float(gain) > largest:
        raise ValueError(f"{name}: samples up to {peak:.3g} would overflow {np.dtype(dtype).name} (|value| > "
                         f"{largest:.3g}) after a gain of up to {float(gain):.3g}"
                         + (f": {advice}" if advice else ": scale the data down"))
    return peak
