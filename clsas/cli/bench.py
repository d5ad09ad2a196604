"""``clsas bench``: the stages of the simulate -> image workflow timed on this machine.

Each stage runs once as a warm-up (kernel builds, FFT plans; not counted), then ``--repeat``
times; the minimum and the median are printed with the size and a rate. ``--quick`` uses a
smaller scene. The per-kernel benchmarks of a source checkout are ``make bench``.
"""

from __future__ import annotations

import json
import statistics
import time

import numpy as np


def add_arguments(parser) -> None:
    parser.add_argument("--quick", action="store_true", help="a smaller scene (about 10 s in all)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per stage after the warm-up (default 3)")
    parser.add_argument("--json", action="store_true", help="one JSON line per stage instead of the table")
    parser.add_argument("--backend", choices=("auto", "opencl", "numpy"), default=None)


def _time(fn, repeat: int):
    out = fn()  # warm-up
    runs = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        runs.append(time.perf_counter() - t)
    return out, min(runs), statistics.median(runs)


def run(args) -> int:
    from .. import backend as backends
    from ..model import Grid
    from ..image import backproject, range_compress
    from ..image.multireceiver import pca_record
    from ..image.omegak import omega_k
    from ..scene import presets
    from ..synthesis import simulate

    if args.repeat < 1:
        from ._common import UsageError

        raise UsageError(f"--repeat must be >= 1, got {args.repeat}")
    n_pulses = 32 if args.quick else 128
    scene = presets.point_scene("huang2022", n_pulses=n_pulses)
    name = backends.resolve(args.backend)
    rows = []
    echo, lo, med = _time(lambda: simulate(scene, backend=args.backend, progress=False), args.repeat)
    n = echo.n_rx * echo.n_pulses * echo.n_samples
    rows.append(("simulate", f"{echo.n_rx} rx x {echo.n_pulses} pulses x {echo.n_samples} samples, 6 points",
                 n / lo, "samples/s", lo, med))
    comp, lo, med = _time(lambda: range_compress(echo), args.repeat)
    rows.append(("range_compress", f"{n} samples", n / lo, "samples/s", lo, med))
    side = 128 if args.quick else 256
    grid = Grid.plane(np.linspace(38, 42, side), np.linspace(-2, 2, side), scene.platform.start[2])
    _, lo, med = _time(lambda: backproject(comp, grid, backend=args.backend, progress=False), args.repeat)
    work = grid.size * comp.n_rx * comp.n_pulses
    rows.append(("backproject", f"{side}^2 pixels x {comp.n_rx} rx x {comp.n_pulses} pulses", work / lo,
                 "pixel-pulses/s", lo, med))
    record = pca_record(comp, backend=args.backend)
    img, lo, med = _time(lambda: omega_k(record, backend=args.backend), args.repeat)
    rows.append(("omega_k", f"record {record.data.shape[0]} x {record.data.shape[1]} -> image "
                 f"{img.shape[0]} x {img.shape[1]}", img.data.size / lo, "pixels/s", lo, med))
    if args.json:
        for stage, size, rate, unit, lo, med in rows:
            print(json.dumps({"bench": stage, "backend": name, "size": size, "rate": rate, "unit": unit,
                              "seconds": lo, "median_seconds": med}))
        return 0
    print(f"backend {name}, {args.repeat} timed runs after a warm-up; min and median seconds")
    print(f"{'stage':15s} {'rate':>10s} {'unit':15s} {'min s':>8s} {'median s':>9s}  size")
    for stage, size, rate, unit, lo, med in rows:
        print(f"{stage:15s} {rate:10.3g} {unit:15s} {lo:8.3f} {med:9.3f}  {size}")
    return 0
