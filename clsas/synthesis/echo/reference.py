"""The float64 NumPy reference of echo synthesis (the twin of ``kernels/echo_paths.cl`` and ``kernels/echo_accumulate.cl``, whose launcher
is :mod:`.launch`).

Signal model (docs/design.md): the baseband echo of path (receiver h, pulse p, scatterer n) is

    s(tau) = a rect((tau - tau_n) / T) exp(-j 2 pi f0 tau_n) exp(j pi K (tau - tau_n)^2),

tau_n the exact two-way delay and a the path amplitude of :mod:`clsas.geometry`
(times the occlusion factor). Fast time is sampled at ``t0_h + k / fs``; with
``u = (tau_n - t0_h) fs`` (the echo centre in samples) and ``d = k - u``, sample k receives
``a exp(-j 2 pi f0 tau_n) exp(j 2 pi alpha d^2)`` when ``|d| <= T fs / 2``, with
``alpha = K / (2 fs^2)`` cycles per sample^2 (:func:`accumulate_reference`). The reference
evaluates the scenario's trajectories exactly (:mod:`clsas.synthesis.paths`).
"""

from __future__ import annotations

import numpy as np

from ..paths import Paths, paths
from .blocks import BlockSynth
from .physics import on_floor


def in_pulse_laws(p: Paths, waveform) -> dict:
    """Each path's echo as the kernel writes it (module docstring, :mod:`clsas.synthesis.paths`):
    chirp (cycles a sample^2), lin (cycles a sample), beta (Np a sample), gamma (Np a sample^2),
    lo, hi (samples about the centre), each (H, P, N)."""
    k, fs, f0, half = waveform.chirp_rate, waveform.fs, waveform.f0, 0.5 * waveform.duration
    s = 1.0 / (1.0 + p.d1)
    kfs = k * s / fs
    centre = p.d2 * half * half
    return {"chirp": (0.5 * k * s * s - f0 * p.d2 * s ** 3) / fs ** 2, "lin": -f0 * p.d1 * s / fs,
            "beta": p.lnf1 * kfs, "gamma": p.lnf2 * kfs * kfs,
            "lo": (centre - half * (1.0 + p.d1)) * fs, "hi": (centre + half * (1.0 + p.d1)) * fs}


def accumulate_reference(start, frac, amp, alpha: float, half_len: float, n_samples: int,
                         laws: dict | None = None) -> np.ndarray:
    """The echoes of every path added into records of ``n_samples`` samples (float64 reference).

    Parameters
    ----------
    start : int (R, N), frac : float (R, N)
        Echo centres u = start + frac in samples (0 <= frac < 1) for R records and N paths.
    amp : complex (R, N)
        Path amplitudes including the carrier phase.
    alpha : float
        Chirp phase rate, cycles per sample^2 (K / (2 fs^2)).
    half_len : float
        Half the pulse length in samples (T fs / 2).
    laws : dict of (R, N) arrays, optional
        Each path's own chirp, lin, beta, gamma, lo, hi (:func:`in_pulse_laws`) instead of
        alpha, 0, 0, 0, -half_len, half_len.

    Returns complex128 (R, n_samples): sample k of record r holds
    sum_n amp exp(j 2 pi (chirp d^2 + lin d) + gamma d^2 + beta d) [lo <= d <= hi],
    d = k - start[r, n] - frac[r, n].
    """
    start = np.asarray(start)
    reach = half_len if laws is None else max(np.max(np.abs(laws["lo"]), initial=0.0),
                                              np.max(np.abs(laws["hi"]), initial=0.0))
    span = int(reach) + 2
    offsets = np.arange(-span, span + 1)
    out = np.zeros((start.shape[0], n_samples), dtype=np.complex128)
    for r in range(start.shape[0]):
        k = start[r][:, None] + offsets[None, :]
        d = offsets[None, :] - frac[r][:, None]
        if laws is None:
            keep = (np.abs(d) <= half_len) & (k >= 0) & (k < n_samples)
            vals = (amp[r][:, None] * np.exp(2j * np.pi * alpha * d * d))[keep]
        else:
            law = {name: value[r][:, None] for name, value in laws.items()}
            keep = (d >= law["lo"]) & (d <= law["hi"]) & (k >= 0) & (k < n_samples)
            exponent = 2j * np.pi * (law["chirp"] * d + law["lin"]) * d + (law["gamma"] * d + law["beta"]) * d
            vals = (amp[r][:, None] * np.exp(exponent))[keep]
        out[r] = np.bincount(k[keep], weights=vals.real, minlength=n_samples) \
            + 1j * np.bincount(k[keep], weights=vals.imag, minlength=n_samples)
    return out


def _split(tau: np.ndarray, t0: np.ndarray, fs: float):
    """Echo centres as (floor(u), u - floor(u)) with u = tau fs - t0 fs; ``t0`` per receiver (H,)."""
    u = tau * fs - (t0 * fs)[:, None, None]
    start = np.floor(u)
    return start.astype(np.int64), u - start


def sample_extents(u: np.ndarray, heard: np.ndarray | None = None):
    """Echo-centre extents per (receiver, scatterer) over the pulses of ``u`` (H, P, N), in samples
    from t = 0, rounded outwards to whole samples: (floor(min u), floor(max u) + 1), over the
    pulses where ``heard`` (P, N) (inf, -inf where none). Both backends report extents this way
    (the OpenCL kernel returns floor(u) directly), so that they derive the same recording window."""
    if heard is None:
        return np.floor(u.min(axis=1)), np.floor(u.max(axis=1)) + 1
    return np.floor(np.where(heard, u, np.inf).min(axis=1)), np.floor(np.where(heard, u, -np.inf).max(axis=1)) + 1



class NumpySynth(BlockSynth):
    """float64 reference: exact trajectories (clsas.synthesis.paths) and accumulate_reference."""

    def _paths(self, pulses: slice, kind) -> Paths:
        ph = self.physics
        p = paths(self.scenario, self.eta[pulses], self.scat, range(self.n_rx), kind, ph.stop_and_go,
                  ph.spreading, ph.intra_pulse if ph.doppler else "none", ph.absorption)
        if ph.touches_floor(kind):
            p.amp[:, :, on_floor(self.scat, ph.floor_first, ph.kinds)] = 0.0
        return p

    def delays(self, pulses: slice, kind: int = 0) -> np.ndarray:
        """Delays (H, P, N), s, of the paths of ``physics.kinds[kind]`` (0: direct)."""
        return self._paths(pulses, self.physics.kinds[kind]).tau

    def extents(self, pulses: slice, lo: np.ndarray, hi: np.ndarray) -> None:
        """Widen ``lo``, ``hi`` (H, N), in place, to the block's extents (:func:`sample_extents`) over
        every path kind."""
        heard = self.heard(pulses)
        for kind in self.physics.kinds:
            a, b = sample_extents(self._paths(pulses, kind).tau * self.scenario.waveform.fs, heard)
            np.minimum(lo, a, out=lo)
            np.maximum(hi, b, out=hi)

    def spread(self, pulse: int) -> np.ndarray:
        """(H,) s: the spread of the direct paths' delays at ``pulse`` over the scatterers heard then
        (0 when none is)."""
        tau = self._paths(slice(pulse, pulse + 1), self.physics.kinds[0]).tau[:, 0, self.heard(slice(pulse, pulse + 1))[0]]
        if tau.shape[1] == 0:  # the beam reaches no facet then
            return np.zeros(self.n_rx)
        return tau.max(axis=1) - tau.min(axis=1)

    def records(self, pulses: slice, t0: np.ndarray, n_samples: int) -> np.ndarray:
        wf = self.scenario.waveform
        w = self.weights(pulses)
        out = 0.0
        for kind in self.physics.kinds:
            p = self._paths(pulses, kind)
            amp = p.amp * np.exp(-2j * np.pi * wf.f0 * p.tau)
            if w is not None:
                amp = amp * w
            start, frac = _split(p.tau, t0, wf.fs)
            h, n_p, n = p.tau.shape
            laws = {k: v.reshape(h * n_p, n) for k, v in in_pulse_laws(p, wf).items()} \
                if self.physics.extended else None
            args = (start.reshape(h * n_p, n), frac.reshape(h * n_p, n), amp.reshape(h * n_p, n))
            if self.physics.grid is not None:
                plan = self.physics.grid
                out = out + plan.finish(*plan.spread(*args, n_samples, laws), n_samples)
            elif self.physics.writes_taps:
                out = out + self.physics.response.accumulate(*args, n_samples, laws)
            else:
                out = out + accumulate_reference(*args, self.alpha, self.half_len, n_samples, laws)
        return out.reshape(self.n_rx, -1, n_samples)

