"""Echo synthesis throughput: in-pulse contributions per second, NumPy reference vs OpenCL kernel.

One contribution = one scatterer added into one output sample inside its pulse, for one
pulse and one receiver: n_scatterers x n_pulses x n_receivers x T fs. Scene: Kiang & Kiang
2022 Table I sonar (A, B, sonobuoy C; T fs = 100 samples per pulse) and a submarine-sized
cloud of scatterers (62 m x 8 m x 8 m around (1989, 0, -350) m) moving at (0, -4, 0) m/s.
The NumPy reference runs on fewer pulses (its rate does not depend on the pulse count).

Two waveform cases: Table I as printed (F_r = B = 20 kHz: 100 samples in a pulse) and Table I
sampled at 4 F_r (400 samples in a pulse, the configuration of the POCL_NOTES anchor figures).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from _harness import arguments, measure, report

from clsas.scene import presets
from clsas.scene.targets import PointTargets
from clsas.synthesis import simulate


def scene(n_scatterers: int, n_pulses: int):
    rng = np.random.default_rng(0)
    pos = np.array([1989.0, 0.0, -350.0]) + rng.uniform(-0.5, 0.5, (n_scatterers, 3)) * [8.0, 62.0, 8.0]
    target = PointTargets(pos, reflectivity=np.exp(2j * np.pi * rng.random(n_scatterers)), velocity=(0.0, -4.0, 0.0))
    return presets.kiang2022(n_pulses=n_pulses).replace(targets=(target,))


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    n_scat = 10_000
    cases = {"opencl": 256 if not args.quick else 64, "numpy": 8 if not args.quick else 2}
    for oversample in (1, 4):
        for backend, n_pulses in cases.items():
            sc = scene(n_scat, n_pulses)
            sc = sc.replace(waveform=dataclasses.replace(sc.waveform, fs=oversample * sc.waveform.fs))
            wf = sc.waveform
            contributions = n_scat * n_pulses * sc.n_receivers * wf.duration * wf.fs
            seconds = measure(lambda: simulate(sc, backend=backend, progress=False),
                              repeats=args.repeats or (3 if backend == "opencl" else 1))
            report(args, "echo", backend, {"scatterers": n_scat, "pulses": n_pulses, "receivers": sc.n_receivers,
                                           "in_pulse_samples": int(round(wf.duration * wf.fs))},
                   contributions / seconds / 1e9, "G contributions/s", seconds, fs_hz=wf.fs)


if __name__ == "__main__":
    main()
