"""Back-projection throughput: giga back-projections per second (pixels x pulses x receivers / s).

Scene: a monostatic straight track (1 m/s, 20 Hz PRF, 150 kHz, B = 20 kHz sampled at 40 kHz),
records of 4096 range-compressed samples (random data: the rate does not depend on the
content), a 512 x 512 plane 40-100 m across track. The whole ``clsas.backproject`` call is
timed (FFT upsampling of the records for ``interp="linear"`` included). The NumPy reference
runs on fewer pulses (its rate does not depend on the pulse count).
"""

from __future__ import annotations

import numpy as np
from _harness import arguments, measure, report

from clsas import EchoData, Medium, Waveform
from clsas.data import Grid
from clsas.image.backprojection import backproject


def scene(n_pulses: int, n_samples: int, n_pixels: int):
    wf = Waveform(f0=150e3, bandwidth=20e3, duration=5e-3, fs=40e3)
    eta = (np.arange(n_pulses) - n_pulses / 2) / 20.0
    tx = np.column_stack([np.zeros(n_pulses), 1.0 * eta, np.zeros(n_pulses)])
    rx_tau = np.array([0.0, 0.2])
    rx = np.stack([tx, tx + [0.0, 0.2, 0.0]], axis=1)[None]  # the receiver moves on at 1 m/s
    rng = np.random.default_rng(0)
    data = (rng.standard_normal((1, n_pulses, n_samples)) + 1j * rng.standard_normal((1, n_pulses, n_samples)))
    echo = EchoData(data=data, eta=eta, t0=[2 * 35.0 / 1500.0], fs=wf.fs, tx_pos=tx, rx_pos=rx, rx_tau=[rx_tau],
                    waveform=wf, medium=Medium(1500.0), receivers=("A",), compressed=True)
    grid = Grid.plane(np.linspace(40.0, 100.0, n_pixels), np.linspace(-15.0, 15.0, n_pixels), 0.0)
    return echo, grid


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    n_pix = 256 if args.quick else 512
    cases = {"opencl": 256 if args.quick else 1024, "numpy": 8 if args.quick else 16}
    for interp in ("linear", "sinc8"):
        for backend, n_pulses in cases.items():
            echo, grid = scene(n_pulses, 4096, n_pix)
            seconds = measure(lambda: backproject(echo, grid, backend=backend, interp=interp, progress=False),
                              repeats=args.repeats or (3 if backend == "opencl" else 1))
            report(args, "backprojection", backend, {"pixels": grid.size, "pulses": n_pulses, "receivers": 1,
                                                     "samples": 4096},
                   grid.size * n_pulses / seconds / 1e9, "G backprojections/s", seconds, interp=interp)


if __name__ == "__main__":
    main()
