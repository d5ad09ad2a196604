"""The water and the pulse: :class:`Medium` and :class:`Waveform`.

Model floor: both travel with every EchoData and are parts of every Scenario, so they live below
the two (imports: NumPy and clsas's ground services only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import validate as v

MAX_F0 = 1e8  # Hz
MAX_FS = 1e9  # Hz
MAX_DURATION = 10.0  # s, one pulse


@dataclass(frozen=True)
class Medium:
    """The water.

    Parameters
    ----------
    sound_speed : float
        m/s, allowed [1000, 2000] (water is 1400-1600).
    temperature : float
        deg C, allowed [-2, 40]: with ``salinity``, ``depth`` and ``ph`` it sets the absorption of
        Francois & Garrison 1982 (:func:`clsas.absorption_db_per_km`; their fit holds for
        -2..22 deg C below 500 kHz, 0..30 deg C above).
    salinity : float
        ppt (psu), allowed [0, 45] (the fit: 30..35 ppt below 500 kHz, 0..40 above).
    depth : float
        m, >= 0 and at most 12 000: the depth at which the absorption is evaluated (its pressure
        terms; the fit: 0..3500 m below 500 kHz, 0..10 000 m above). One depth for the whole scene.
    ph : float
        pH of the water, allowed [6, 9] (open ocean ~8).
    """

    sound_speed: float = 1500.0
    temperature: float = 10.0
    salinity: float = 35.0
    depth: float = 0.0
    ph: float = 8.0

    def __post_init__(self):
        for name, low, high, unit in (("sound_speed", 1000.0, 2000.0, "m/s"), ("temperature", -2.0, 40.0, "deg C"),
                                      ("salinity", 0.0, 45.0, "ppt"), ("depth", 0.0, 12000.0, "m"),
                                      ("ph", 6.0, 9.0, "")):
            object.__setattr__(self, name, v.scalar(f"Medium.{name}", getattr(self, name), low=low, high=high,
                                                    unit=unit))


@dataclass(frozen=True)
class Waveform:
    """A linear FM pulse: rect(tau/T) exp(j 2 pi f0 tau) exp(j pi K tau^2), centred on tau = 0.

    Parameters
    ----------
    f0 : float
        Carrier frequency, Hz (> 0).
    bandwidth : float
        Swept bandwidth B, Hz; 0 < B < 2 f0 so that the lowest frequency f0 - B/2 is positive.
    duration : float
        Pulse length T, s (> 0).
    fs : float
        Complex baseband sampling rate, Hz; fs >= B (Nyquist for complex samples).
    chirp_sign : {+1, -1}
        +1 for an up-chirp, -1 for a down-chirp; the chirp rate is K = chirp_sign B / T.
    """

    f0: float
    bandwidth: float
    duration: float
    fs: float
    chirp_sign: int = 1

    def __post_init__(self):
        f0 = v.positive("Waveform.f0", self.f0, high=MAX_F0, unit="Hz")
        bw = v.scalar("Waveform.bandwidth", self.bandwidth, low=0.0, high=2 * f0, low_open=True, high_open=True,
                      unit="Hz", why="0 < B < 2 f0")
        dur = v.positive("Waveform.duration", self.duration, high=MAX_DURATION, unit="s")
        fs = v.scalar("Waveform.fs", self.fs, low=bw, high=MAX_FS, unit="Hz", why="at least the bandwidth")
        if dur * fs < 1:
            raise ValueError(f"Waveform.duration: a pulse of {dur:g} s sampled at fs = {fs:g} Hz spans {dur * fs:.3g} "
                             "samples; it needs at least one (duration >= 1 / fs)")
        if isinstance(self.chirp_sign, (bool, np.bool_)) or not v.is_number(self.chirp_sign, "iuf") \
                or self.chirp_sign not in (1, -1):
            raise ValueError(f"Waveform.chirp_sign: must be +1 or -1, got {self.chirp_sign!r}")
        for name, value in (("f0", f0), ("bandwidth", bw), ("duration", dur), ("fs", fs)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "chirp_sign", int(self.chirp_sign))

    @property
    def chirp_rate(self) -> float:
        """K = chirp_sign B / T, Hz/s."""
        return self.chirp_sign * self.bandwidth / self.duration

    @property
    def time_bandwidth(self) -> float:
        """B T, the compression gain."""
        return self.bandwidth * self.duration

    def wavelength(self, medium: Medium) -> float:
        """Carrier wavelength c / f0, m."""
        return medium.sound_speed / self.f0

    def baseband(self, tau) -> np.ndarray:
        """rect(tau/T) exp(j pi K tau^2): the pulse without its carrier at fast times ``tau`` (s)."""
        tau = np.asarray(tau, dtype=np.float64)
        inside = np.abs(tau) <= 0.5 * self.duration
        return np.where(inside, np.exp(1j * np.pi * self.chirp_rate * tau * tau), 0.0)
