"""Peak memory of one back-projection, run in a fresh process by tests/test_backprojection.py.

Usage: python _bp_memory.py N_PIX N_RX N_PULSES N_SAMPLES UPLOAD_BYTES. Builds a range-compressed
record (random samples) and an N_PIX^2 plane grid, back-projects a tiny case first (kernel
builds, OpenCL start-up), then samples the resident set every 2 ms while back-projecting the
full case (default upsample=8) and prints one JSON line: the resident set before the call and
its peak during it (MB), and the sizes of the inputs and the image.
"""

from __future__ import annotations

import json
import sys
import threading
import time

import numpy as np

import clsas.image.backprojection as bp
import clsas.image.backprojection.records as bp_records
from clsas import EchoData, Medium, Waveform
from clsas.model import Grid


def resident_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def echo_of(n_rx: int, n_pulses: int, n_samples: int) -> EchoData:
    wf = Waveform(f0=150e3, bandwidth=20e3, duration=5e-3, fs=40e3)
    eta = np.arange(n_pulses) / 20.0
    tx = np.column_stack([np.zeros(n_pulses), eta, np.zeros(n_pulses)])
    rx = np.stack([np.stack([tx, tx + [0.0, 0.2, 0.0]], axis=1) + [0.0, 0.01 * h, 0.0] for h in range(n_rx)])
    rng = np.random.default_rng(0)
    data = rng.standard_normal((n_rx, n_pulses, n_samples), dtype=np.float32).astype(np.complex64)
    return EchoData(data=data, eta=eta, t0=[2 * 35.0 / 1500.0] * n_rx, fs=wf.fs, tx_pos=tx, rx_pos=rx,
                    rx_tau=[[0.0, 0.2]] * n_rx, waveform=wf, medium=Medium(1500.0),
                    receivers=tuple(f"r{h}" for h in range(n_rx)), compressed=True)


def main() -> None:
    n_pix, n_rx, n_pulses, n_samples, upload = (int(a) for a in sys.argv[1:6])
    bp_records.UPLOAD_BYTES = upload
    echo = echo_of(n_rx, n_pulses, n_samples)
    grid = Grid.plane(np.linspace(40.0, 45.0, n_pix), np.linspace(-5.0, 5.0, n_pix), 0.0)
    bp.backproject(echo_of(1, 2, n_samples), Grid.plane(np.linspace(40.0, 41.0, 16), [0.0], 0.0),
                   backend="opencl", progress=False)
    before = resident_mb()
    peak, running = before, True

    def watch() -> None:
        nonlocal peak
        while running:
            peak = max(peak, resident_mb())
            time.sleep(0.002)

    watcher = threading.Thread(target=watch)
    watcher.start()
    image = bp.backproject(echo, grid, backend="opencl", progress=False)
    running = False
    watcher.join()
    print(json.dumps({"before_mb": before, "peak_mb": max(peak, resident_mb()), "data_mb": echo.data.nbytes / 2**20,
                      "grid_mb": grid.positions.nbytes / 2**20, "image_mb": image.data.nbytes / 2**20}))


if __name__ == "__main__":
    main()
