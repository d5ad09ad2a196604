"""simulate()'s argument checks (before anything is allocated) and the pulse-overlap warning.

Kept apart from the synthesis so that :mod:`.echo` calls one function at its top and one after
its delay pass.
"""

from __future__ import annotations

import warnings

import numpy as np

from .. import budget
from .. import validate as v
from ..scene.scenario import SamplingWarning, Scenario

SNR_DB_RANGE = (-100.0, 200.0)  # dB: noise standard deviations stay within float32 for unit echoes
NODE_BYTES = 2 * 48  # a pulse's two receiver nodes per receiver: positions and axes, float64 (3,) each


def check_arguments(scenario, snr_db, seed, max_bytes, chunk_bytes, reuse_tolerance, flags: dict) -> tuple[int, int]:
    """Validate simulate()'s arguments; returns (max_bytes, chunk_bytes) as ints (``max_bytes``
    None: the memory budget, :func:`clsas.memory_budget`). Refuses a scenario whose smallest
    possible echo cube (each receiver's record at least one pulse long) is over ``max_bytes``
    before any delay is computed."""
    if not isinstance(scenario, Scenario):
        raise TypeError(f"simulate scenario: must be a Scenario, got {type(scenario).__name__}")
    if snr_db is not None:
        v.scalar("simulate snr_db", snr_db, low=SNR_DB_RANGE[0], high=SNR_DB_RANGE[1], unit="dB", why="or None")
    v.seed("simulate seed", seed)
    v.scalar("simulate reuse_tolerance", reuse_tolerance, low=0.0, high=np.pi, unit="rad")
    for name, value in flags.items():
        v.flag(f"simulate {name}", value)
    limit = budget.memory_budget() if max_bytes is None else budget.parse_bytes(max_bytes, "simulate max_bytes")
    chunk = budget.parse_bytes(chunk_bytes, "simulate chunk_bytes")
    wf = scenario.waveform
    least = scenario.n_receivers * scenario.schedule.n_pulses * (8.0 * (wf.duration * wf.fs + 1) + NODE_BYTES)
    if least > limit:
        raise budget.MemoryBudgetError(
            f"simulate: {scenario.n_receivers} receivers x {scenario.schedule.n_pulses} pulses (PulseSchedule) x at "
            f"least {int(wf.duration * wf.fs) + 1} samples (one pulse, Waveform.duration x fs) need "
            f"{least / 2**30:.3g} GiB but max_bytes allows {limit / 2**30:.3g} GiB"
            + ("" if max_bytes is not None else " (the memory budget: raise it with clsas.use_memory_budget or "
               f"{budget.ENV}, or give simulate max_bytes)"))
    return limit, chunk


def warn_pulse_overlap(scenario: Scenario, synth) -> None:
    """Warn (:class:`~clsas.scene.scenario.SamplingWarning`) when one pulse's echoes, their spread
    in delay over the scene plus the pulse length, outlast the pulse interval 1 / PRF at some
    receiver: a real sonar would record them overlapped with the next pulse's echoes. The spread
    is taken at the first, middle and last pulses over the scatterers heard then (``synth.spread``:
    the seafloor's facets in the beam's reach; either backend). The record
    window of the whole aperture may span many pulse intervals (range migration): that is no fault
    and is not checked."""
    n = scenario.schedule.n_pulses
    interval = 1.0 / scenario.schedule.prf
    worst, where = 0.0, (0, 0)
    for p in sorted({0, n // 2, n - 1}):
        spread = synth.spread(p)  # (H,) s
        h = int(np.argmax(spread))
        if spread[h] > worst:
            worst, where = float(spread[h]), (h, p)
    span = worst + scenario.waveform.duration
    if span > interval:
        h, p = where
        warnings.warn(
            f"PulseSchedule.prf = {scenario.schedule.prf:g} Hz: one pulse's echoes at receiver "
            f"{scenario.receiver_names[h]!r} (pulse {p}) span {span * 1e3:.4g} ms (delay spread over the scene "
            f"{worst * 1e3:.4g} ms + pulse length {scenario.waveform.duration * 1e3:.4g} ms), longer than the pulse "
            f"interval {interval * 1e3:.4g} ms: a real recording would overlap them with the next pulse's echoes. "
            f"Lower the PRF below {1 / span:.4g} Hz or make the scene more compact.",
            SamplingWarning, stacklevel=4)
