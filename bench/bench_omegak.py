"""Whole omega-k imaging time against back-projection (OpenCL) of the same scene and pixels.

Scene: a monostatic straight track (0.5 m/s, 10 Hz PRF: 0.05 m along-track samples), 150 kHz,
B = 20 kHz sampled at 40 kHz, range-compressed records of 1024 samples (random content: the
rates do not depend on it). omega-k images the whole record (FFTs, Stolt with the OpenCL
sinc8 kernel, weighting, inverse FFTs); back-projection forms the same pixels (the omega-k
image's positions). The rate is pixels x pulses / s for both, so their ratio is the speedup.
"""

from __future__ import annotations

import numpy as np
from _harness import arguments, measure, report

from clsas import EchoData, Medium, Waveform
from clsas.model import Grid
from clsas.image.backprojection import backproject
from clsas.image.omegak import omega_k


def scene(n_pulses: int, n_samples: int) -> EchoData:
    wf = Waveform(f0=150e3, bandwidth=20e3, duration=5e-3, fs=40e3)
    eta = (np.arange(n_pulses) - n_pulses / 2) / 10.0
    tx = np.column_stack([np.zeros(n_pulses), 0.5 * eta, np.zeros(n_pulses)])
    rx = np.stack([tx, tx + [0.0, 0.05, 0.0]], axis=1)[None]  # moves on at 0.5 m/s during 0.1 s
    rng = np.random.default_rng(0)
    data = rng.standard_normal((1, n_pulses, n_samples)) + 1j * rng.standard_normal((1, n_pulses, n_samples))
    return EchoData(data=data, eta=eta, t0=[2 * 40.0 / 1500.0], fs=wf.fs, tx_pos=tx, rx_pos=rx,
                    rx_tau=[[0.0, 0.1]], waveform=wf, medium=Medium(1500.0), receivers=("A",), compressed=True)


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    n_pulses, n_samples = (512, 512) if args.quick else (2048, 1024)
    echo = scene(n_pulses, n_samples)
    image = omega_k(echo, elements=(0.1, 0.1), backend="opencl")
    size = {"pulses": n_pulses, "samples": n_samples, "pixels": image.data.size}
    work = image.data.size * n_pulses
    seconds = measure(lambda: omega_k(echo, elements=(0.1, 0.1), backend="opencl"), repeats=args.repeats or 3)
    report(args, "omegak", "opencl", size, work / seconds / 1e9, "G pixel-pulses/s", seconds, algorithm="omega_k")
    grid = Grid.points(image.positions, dims=("y", "x"))
    seconds_bp = measure(lambda: backproject(echo, grid, backend="opencl", interp="sinc8", progress=False),
                         repeats=args.repeats or 1, warmup=0)
    report(args, "omegak", "opencl", size, work / seconds_bp / 1e9, "G pixel-pulses/s", seconds_bp,
           algorithm="backprojection", omega_k_speedup=seconds_bp / seconds)


if __name__ == "__main__":
    main()
