"""Doppler parameters of a moving target at one receiver (Kiang & Kiang 2022)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Doppler:
    """The equivalent azimuth FM rate and Doppler centroid of a target's echo at one receiver.

    fm_rate: K_a,eq in Hz/s (Kiang & Kiang 2022, eqs. 16, 30); doppler_centroid: f_dc,eq in Hz
    (eqs. 15, 28, 33-35).
    """

    fm_rate: float
    doppler_centroid: float
