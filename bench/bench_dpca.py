"""DPCA micronavigation and phase gradient autofocus: ping pairs per second, and PGA time per
iteration.

DPCA runs on a synthetic track whose pings share phase centres exactly (ping p + 1's hydrophone
i records what ping p's hydrophone i + 7 recorded, plus noise: Heremans 2009's 15-hydrophone
geometry), so the estimator does its full work on every pair without a simulation first:
1000 pings (quick: 100) of 2048 samples. PGA runs on a 2048 x 2048 image (quick: 1024^2) of
speckle and bright points blurred by a quadratic phase error; rate = iterations per second.
Both run on the host (NumPy / scipy.fft); see clsas.estimate.dpca and clsas.estimate.autofocus.
"""

from __future__ import annotations

import numpy as np
from _harness import arguments, measure, report

from clsas import EchoData, Image, Medium, Waveform
from clsas.estimate import autofocus, dpca
from clsas.scene import presets


def dpca_track(n_pings: int, n_samples: int, rng) -> tuple[EchoData, object, float]:
    scene = presets.heremans2009(n_pulses=n_pings)
    shift, _ = dpca.nominal_shift(scene.array, scene.platform.speed, scene.schedule.prf)
    h = scene.array.n_receivers
    centres = (rng.standard_normal((shift * n_pings + h, n_samples))
               + 1j * rng.standard_normal((shift * n_pings + h, n_samples))).astype(np.complex64)
    index = shift * np.arange(n_pings)[None, :] + np.arange(h)[:, None]      # phase centre of (h, p)
    data = centres[index] + 0.1 * (rng.standard_normal((h, n_pings, n_samples))).astype(np.complex64)
    wf: Waveform = scene.waveform
    echo = EchoData(data=data, eta=scene.eta, t0=np.full(h, 0.12), fs=wf.fs, tx_pos=np.zeros((n_pings, 3)),
                    rx_pos=np.zeros((h, n_pings, 1, 3)), rx_tau=np.zeros((h, 1)), waveform=wf, medium=Medium(),
                    receivers=scene.receiver_names, compressed=True)
    return echo, scene.array, scene.platform.speed


def blurred_image(n: int, rng) -> Image:
    img = 0.05 * (rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n)))
    rows, cols = rng.integers(0, n, 32), rng.integers(0, n, 32)
    img[rows, cols] += 30.0
    k = np.linspace(-1, 1, n)
    blurred = autofocus.apply_phase_correction(img.astype(np.complex64), -8 * k**2, 0)
    return Image(blurred, ("y", "x"), {"y": np.arange(n) * 0.01, "x": np.arange(n) * 0.01})


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    rng = np.random.default_rng(0)
    repeats = args.repeats or 3
    n_pings, n_samples = (100, 2048) if args.quick else (1000, 2048)
    echo, array, speed = dpca_track(n_pings, n_samples, rng)
    seconds = measure(lambda: dpca.estimate(echo, array, speed), repeats=repeats)
    report(args, "dpca", "numpy", {"pings": n_pings, "hydrophones": echo.n_rx, "samples": n_samples},
           (n_pings - 1) / seconds, "ping pairs/s", seconds, per_pair_ms=1e3 * seconds / (n_pings - 1))

    n = 1024 if args.quick else 2048
    image = blurred_image(n, rng)
    result = autofocus.pga(image, max_iterations=5, tolerance=1e-9)
    seconds = measure(lambda: autofocus.pga(image, max_iterations=5, tolerance=1e-9), repeats=repeats)
    report(args, "pga", "numpy", {"pixels": [n, n]}, result.iterations / seconds, "iterations/s", seconds,
           per_iteration_ms=1e3 * seconds / result.iterations, iterations=result.iterations)


if __name__ == "__main__":
    main()
