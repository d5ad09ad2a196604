"""A small, well-sampled scenario and its parts, shared by the scenario test modules."""

from __future__ import annotations

import re

from clsas.scene.scenario import Array, Medium, Platform, PulseSchedule, Scenario, Waveform


def field_pattern(name: str) -> str:
    """A regex matching the parameter name ``name`` literally in an error message."""
    return re.escape(name)


def small_waveform(**kw) -> Waveform:
    """A 100 kHz, 20 kHz-band, 2 ms chirp sampled at 25 kHz; ``kw`` overrides fields."""
    args = dict(f0=100e3, bandwidth=20e3, duration=2e-3, fs=25e3)
    args.update(kw)
    return Waveform(**args)


def small_scenario(**kw) -> Scenario:
    """A small, well-sampled scenario: 4 hydrophones 0.1 m apart, step V/PRF = 0.2 m = 4 x D/2."""
    args = dict(
        medium=Medium(1500.0),
        waveform=small_waveform(),
        platform=Platform(speed=1.0, start=(1.0, 2.0, -3.0)),
        array=Array.uniform_line(4, 0.1, first=0.1, rx_length=0.1),
        schedule=PulseSchedule(prf=5.0, n_pulses=8),
    )
    args.update(kw)
    return Scenario(**args)
