"""Progress bars that count finished work, and the stage log of ``logging.getLogger("clsas")``.

A bar counts work in real units (pulses, pixel x pulses) when it is done, not when it is
handed to the device: the callers count a block after its results are read back (echo
synthesis) or after the OpenCL events of its kernels have completed (back-projection, which
keeps at most one upload block in flight), so the bar and its ETA follow the device.

Bars are off with ``progress=False`` or the environment variable ``TQDM_DISABLE=1``.

:func:`stage` logs a stage's start (with its sizes and, when a rate is known, its estimated
cost: at INFO, and at WARNING when the estimate is over a minute) and its time when it ends.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time

log = logging.getLogger("clsas")

LONG_CALL_S = 60.0  # an estimate above this is logged as a warning before the call starts

#: Work units a second for the cost estimates of :func:`stage`, by (stage, backend): measured
#: on a 2-core AVX2 machine (PoCL pthread device), so an estimate is a rough guide that a
#: faster machine beats. Back-projection: pixel x pulse x receiver products
#: (bench_backprojection: 0.4-0.6 G/s on OpenCL, linear or sinc8; the NumPy reference ~1 M/s).
NOMINAL_RATES = {
    ("backprojection", "opencl"): 4e8,
    ("backprojection", "numpy"): 1e6,
}


def enabled(progress: bool) -> bool:
    """``progress`` unless ``TQDM_DISABLE`` is set (to anything but "", "0", "false")."""
    return bool(progress) and os.environ.get("TQDM_DISABLE", "").lower() not in ("1", "true", "yes")


class Progress:
    """A tqdm bar of ``total`` units of work named ``unit`` (or nothing when disabled)."""

    def __init__(self, total: int, unit: str, desc: str, progress: bool = True, leave: bool = True):
        self._bar = None
        if enabled(progress):
            from tqdm.auto import tqdm

            self._bar = tqdm(total=int(total), unit=f" {unit}", unit_scale=True, desc=desc, leave=leave,
                             smoothing=0.1)

    def done(self, n) -> None:
        """``n`` more units are finished."""
        if self._bar is not None:
            self._bar.update(int(n))

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@contextlib.contextmanager
def stage(name: str, sizes: str, work: float | None = None, rate: float | None = None):
    """Log ``name`` with its ``sizes``; with ``work`` units at ``rate`` units/s, the estimated
    cost (a warning when over :data:`LONG_CALL_S`); then its time when the block ends."""
    if work is not None and rate:
        estimate = work / rate
        level = logging.WARNING if estimate > LONG_CALL_S else logging.INFO
        log.log(level, "%s: %s; estimated %s", name, sizes, _duration(estimate))
    else:
        log.info("%s: %s", name, sizes)
    t = time.perf_counter()
    yield
    log.info("%s: done in %s", name, _duration(time.perf_counter() - t))


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.3g} s"
    if seconds < 3600:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"
