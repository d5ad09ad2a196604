"""Range compression throughput: input samples per second through scipy.fft matched filtering.

Range compression runs on the host (scipy.fft/pocketfft, docs/design.md); this benchmark shows
how it scales with scipy.fft ``workers`` (1 vs all cores) in one run.
"""

from __future__ import annotations

import os

import numpy as np
from _harness import arguments, measure, report

from clsas import EchoData, Medium, Waveform
from clsas.image import range_compress


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    n_rx, n_p, n_s = (3, 256, 4096) if args.quick else (3, 1024, 8192)
    repeats = args.repeats or (3 if args.quick else 5)
    wf = Waveform(f0=150e3, bandwidth=20e3, duration=5e-3, fs=40e3)
    rng = np.random.default_rng(0)
    data = (rng.standard_normal((n_rx, n_p, n_s)) + 1j * rng.standard_normal((n_rx, n_p, n_s))).astype(np.complex64)
    echo = EchoData(data=data, eta=np.arange(n_p) / 80.0, t0=np.zeros(n_rx), fs=wf.fs, tx_pos=np.zeros((n_p, 3)),
                    rx_pos=np.zeros((n_rx, n_p, 1, 3)), rx_tau=np.zeros((n_rx, 1)), waveform=wf,
                    medium=Medium(), receivers=tuple("ABC"))
    size = {"rx": n_rx, "pulses": n_p, "samples": n_s}
    for workers in sorted({1, os.cpu_count() or 1}):
        seconds = measure(lambda: range_compress(echo, workers=workers), repeats=repeats)
        report(args, "rangecomp", "numpy", size, data.size / seconds / 1e6, "M samples/s", seconds,
               workers=workers)


if __name__ == "__main__":
    main()
