"""The memory budget: the largest working set one clsas call may allocate, checked before it does.

Every entry point that allocates in proportion to its arguments (Grid, simulate,
Array.uniform_line, PulseSchedule, range_compress, the imagers, loading a file) first works out
how many bytes it will need and calls :func:`check_bytes`, which refuses a request above the
budget with a :class:`clsas.errors.MemoryBudgetError` (a ValueError) saying what was asked,
how much it needs and how to raise the budget. The budget is:

- the last :func:`use_memory_budget` choice of the current thread (a plain call keeps it; as a
  context manager the previous one comes back on exit), else
- the ``CLSAS_MEMORY_BUDGET`` environment variable (bytes, or with a K/M/G/T suffix, binary:
  ``"16G"``), else
- half of the machine's physical memory.

::

    clsas.memory_budget()                      # bytes allowed now
    with clsas.use_memory_budget("64G"):
        echo = clsas.simulate(big_scene)

The choice is a context variable (:mod:`contextvars`), as :func:`clsas.use_backend`'s: a
``with`` block in one thread does not change another thread's budget, and a new thread starts
from the environment variable or the default.
"""

from __future__ import annotations

import contextvars
import os
import re

from .errors import MemoryBudgetError
from .thread_setting import ThreadSetting

ENV = "CLSAS_MEMORY_BUDGET"
DEFAULT_FRACTION = 0.5  # of physical memory
_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}

#: set by use_memory_budget in the current context; None defers to the environment, then the default
_choice: contextvars.ContextVar = contextvars.ContextVar("clsas_memory_budget", default=None)


def physical_memory() -> int:
    """Bytes of physical memory (8 GiB when the system does not say)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 8 * 2**30


def parse_bytes(value, what: str) -> int:
    """A positive byte count from an int, a float or a string such as ``"512M"``, ``"16G"``."""
    if isinstance(value, bool):
        raise TypeError(f"{what}: must be a positive number of bytes (or a string like '16G'), got {value!r}")
    if isinstance(value, str):
        match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([KMGT]?)(?:i?B)?\s*", value, re.IGNORECASE)
        if not match:
            raise ValueError(f"{what}: must be a positive number of bytes, optionally with a K/M/G/T suffix "
                             f"(e.g. '16G'), got {value!r}")
        number = float(match.group(1)) * _UNITS[match.group(2).upper()]
    else:
        try:
            number = float(value)
        except (TypeError, ValueError, OverflowError):
            raise TypeError(f"{what}: must be a positive number of bytes (or a string like '16G'), "
                            f"got {value!r}") from None
    if not (number >= 1 and number < 2**63):
        raise ValueError(f"{what}: must be a number of bytes in [1, 2^63), got {value!r}")
    return int(number)


def memory_budget() -> int:
    """The bytes one call may allocate now (see the module docstring)."""
    chosen = _choice.get()
    if chosen is not None:
        return chosen
    env = os.environ.get(ENV)
    if env:
        return parse_bytes(env, f"the {ENV} environment variable")
    return int(DEFAULT_FRACTION * physical_memory())


class use_memory_budget(ThreadSetting):
    """Set the memory budget of the current thread (context): bytes, or a string like ``"16G"``;
    as a context manager, restore the previous one on exit. ``None`` goes back to the
    environment variable or the default."""

    def __init__(self, nbytes):
        self.nbytes = None if nbytes is None else parse_bytes(nbytes, "use_memory_budget nbytes")
        super().__init__(_choice, self.nbytes)

    def __repr__(self) -> str:
        return f"use_memory_budget({self.nbytes!r})"


def kept_limit(cap: float, share: float, device_bytes: float = float("inf")) -> float:
    """The most a cache kept between calls may hold (bytes): ``cap``, 1/``share`` of the memory
    budget and of ``device_bytes`` (the device's memory, for a cache of device buffers)."""
    return min(cap, memory_budget() / share, device_bytes / share)


def _size(nbytes: float) -> str:
    for unit, scale in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes:.0f} bytes"


def check_bytes(what: str, nbytes: float, advice: str = "") -> None:
    """Refuse ``what`` (a phrase naming the parameters it follows from) needing ``nbytes`` when
    that is over the budget; call before allocating. ``advice`` says how to ask for less."""
    budget = memory_budget()
    if nbytes > budget:
        raise MemoryBudgetError(
            f"{what} would need {_size(nbytes)}, over the memory budget of {_size(budget)}"
            f"{': ' + advice if advice else ''}; to allow more, raise the budget with "
            f"clsas.use_memory_budget(...) or the {ENV} environment variable")
