"""Fast factorised back-projection against direct back-projection: effective rate (pixels x pulses / s).

The issue's configuration: 1024^2 pixels x 2048 pulses (``--quick``: 512^2 x 1024). Scene: a
monostatic straight track (150 kHz carrier, B = 20 kHz sampled at 25 kHz, 0.1 m element, so
the integration angle lambda / D = 0.1 rad and the along-track resolution D / 2 = 5 cm; pulses
every 2.5 cm = D / 4), the plane 40-60 m across track by half the track's length along it
(pixels 2 cm across; along track the track's length / 2 over the pixel count). The records are
random complex noise band-limited to B (a speckle-like scene: the content does not change the
time, and the error against direct back-projection is measured on it).

Cases: ``beam`` integrates the element's beam (``aperture=0.1`` in both methods: the same
sum), ``full`` every pulse at every pixel (omnidirectional; the pixels then sample the image
far more coarsely than its resolution, which limits how far merging pays). Each case times
``clsas.backproject`` (linear, records upsampled x 8 once, as ``range_compress(upsample=8)``
leaves them) and ``clsas.image.ffbp.ffbp`` (default tolerance) interleaved (direct, ffbp,
direct, ...), after one warm-up each; min and median reported, with the relative L2 difference
of the two images. ``--scan`` adds the ratio for 512, 1024, 2048 and 4096 pulses (512^2 pixels,
beam case, one timed run each).
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np
from _harness import arguments, report

from clsas import EchoData, Medium, Waveform
from clsas.data import Grid
from clsas.image.backprojection import backproject
from clsas.image.ffbp import ffbp

F0, B, FS, D, STEP, UP = 150e3, 20e3, 25e3, 0.1, 0.025, 8


def scene(n_pulses: int, n_pixels: int):
    """Band-limited random records (upsampled x UP) of a monostatic track and the image plane."""
    c = 1500.0
    wf = Waveform(f0=F0, bandwidth=B, duration=5e-3, fs=FS)
    y = (np.arange(n_pulses) - (n_pulses - 1) / 2) * STEP
    tx = np.column_stack([np.zeros(n_pulses), y, np.zeros(n_pulses)])
    rx_tau = np.array([0.0, 0.2])
    rx = np.stack([tx, tx + [0.0, 0.2 * 1.0, 0.0]], axis=1)[None]  # 1 m/s
    eta = y / 1.0
    t0, t1 = 2 * 36.0 / c, 2 * 70.0 / c
    n = int((t1 - t0) * FS)
    rng = np.random.default_rng(0)
    spec = rng.standard_normal((n_pulses, n)) + 1j * rng.standard_normal((n_pulses, n))
    freq = np.fft.fftfreq(n, 1 / FS)
    spec[:, np.abs(freq) > B / 2] = 0
    padded = np.zeros((n_pulses, n * UP), complex)
    keep = np.abs(freq) <= B / 2
    idx = np.flatnonzero(keep)
    padded[:, np.where(freq[idx] < 0, idx + n * (UP - 1), idx)] = spec[:, idx]
    data = np.fft.ifft(padded, axis=1).astype(np.complex64)[None]
    echo = EchoData(data=data, eta=eta, t0=[t0], fs=FS * UP, tx_pos=tx, rx_pos=rx, rx_tau=[rx_tau], waveform=wf,
                    medium=Medium(c), receivers=("A",), compressed=True)
    half = n_pulses * STEP / 4
    grid = Grid.plane(np.linspace(40.0, 60.0, n_pixels), np.linspace(-half, half, n_pixels), -5.0)
    return echo, grid


def interleaved(runs: dict, repeats: int) -> dict:
    """Wall times of each run, interleaved (A B A B ...), after one warm-up run each."""
    results = {name: run() for name, run in runs.items()}
    times = {name: [] for name in runs}
    for _ in range(repeats):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - start)
    return times, results


def main() -> None:
    scan = "--scan" in sys.argv
    if scan:
        sys.argv.remove("--scan")
    args = arguments(__doc__.splitlines()[0])
    n_pix, n_pulses = (512, 1024) if args.quick else (1024, 2048)
    repeats = args.repeats or 3
    cases = [("beam", 0.1), ("full", None)]
    sizes = [(n_pix, n_pulses, case, ap, repeats) for case, ap in cases]
    if scan:
        sizes += [(512, n, "beam", 0.1, 1) for n in (512, 1024, 2048, 4096)]
    for pix, pulses, case, aperture, reps in sizes:
        echo, grid = scene(pulses, pix)
        kw = dict(backend="opencl", aperture=aperture, upsample=1, progress=False)
        runs = {"direct": lambda: backproject(echo, grid, interp="linear", **kw),
                "ffbp": lambda: ffbp(echo, grid, interp="linear", **kw)}
        times, images = interleaved(runs, reps)
        ref = images["direct"].data
        err = float(np.linalg.norm(images["ffbp"].data - ref) / np.linalg.norm(ref))
        work = grid.size * pulses
        medians = {name: statistics.median(t) for name, t in times.items()}
        for name, t in times.items():
            extra = {"method": name, "case": case, "min_seconds": min(t), "rate_best": work / min(t), "runs": len(t)}
            if name == "ffbp":
                extra.update(ratio_median=medians["direct"] / medians["ffbp"],
                             ratio_best=min(times["direct"]) / min(t), rel_l2=err,
                             levels=images["ffbp"].provenance["levels"], first=images["ffbp"].provenance["first"],
                             oversampling=images["ffbp"].provenance["oversampling"],
                             polar_samples=images["ffbp"].provenance["polar_samples"])
            report(args, "ffbp", "opencl", {"pixels": grid.size, "pulses": pulses, "receivers": 1}, work / medians[name],
                   "BP/s", medians[name], **extra)


if __name__ == "__main__":
    main()
