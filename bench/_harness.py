"""Shared benchmark protocol (DESIGN.md): ``--quick`` / ``--json``, warm-up excluded, median of N.

A benchmark script builds its inputs, then calls :func:`measure` once per (backend, case)
with a function that runs the work to completion (OpenCL launchers wait for their queue
before returning), and :func:`report` with the rate. With ``--json`` every result is one JSON
object per line on stdout::

    {"bench": "X", "backend": "numpy"|"opencl", "device": ..., "size": {...},
     "rate": float, "unit": "...", "seconds": float, ...extra}

otherwise a readable line.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def arguments(description: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true", help="a size that finishes in under 30 s on 2 cores")
    parser.add_argument("--json", action="store_true", help="one JSON object per line on stdout")
    parser.add_argument("--repeats", type=int, default=None, help="timed runs (median is reported)")
    return parser.parse_args()


def measure(run, repeats: int = 5, warmup: int = 1) -> float:
    """Median wall time of ``run()`` in seconds over ``repeats`` runs after ``warmup`` runs."""
    for _ in range(warmup):
        run()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def device_name(backend: str) -> str:
    if backend == "opencl":
        from clsas import opencl

        return opencl.runtime().device.name
    import platform

    return f"numpy on {platform.processor() or platform.machine()}"


def report(args, bench: str, backend: str, size: dict, rate: float, unit: str, seconds: float, **extra) -> dict:
    row = {"bench": bench, "backend": backend, "device": device_name(backend), "size": size,
           "rate": float(rate), "unit": unit, "seconds": float(seconds), **extra}
    if args.json:
        print(json.dumps(row), flush=True)
    else:
        tags = " ".join(f"{k}={v}" for k, v in extra.items())
        print(f"{bench:16s} {backend:7s} {rate:12.4g} {unit:18s} {seconds*1e3:10.2f} ms  {size} {tags}", flush=True)
    return row
