"""Shared benchmark protocol (DESIGN.md): ``--quick`` / ``--json``, warm-up excluded, median of N.

A benchmark script builds its inputs, then calls :func:`measure` once per (backend, case)
with a function that runs the work to completion (OpenCL launchers wait for their queue
before returning), and :func:`report` with the rate. With ``--json`` every result is one JSON
object per line on stdout::

    {"bench": "X", "backend": "numpy"|"opencl", "device": ..., "size": {...},
     "rate": float, "unit": "...", "seconds": float, ...extra, "machine": {...}}

otherwise a readable line ending with the machine in brief. Every figure carries the machine it
was measured on (:func:`machine`: CPU model, its vector extensions, cores, the OpenCL device,
the load average when the figure was taken), so that ratios from different machines are never
mixed: compare figures only within one machine.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def arguments(description: str, parts=None, extra=()) -> argparse.Namespace:
    """The benches' options; ``parts`` (names of a bench's parts) adds ``--only NAME`` (``args.only``,
    None when not given: every part); ``extra``: a bench's own options, (flag, add_argument keywords) pairs."""
    parser = argparse.ArgumentParser(description=description)
    for flag, options in extra:
        parser.add_argument(flag, **options)
    parser.add_argument("--quick", action="store_true", help="a size that finishes in under 30 s on 2 cores")
    parser.add_argument("--json", action="store_true", help="one JSON object per line on stdout")
    parser.add_argument("--repeats", type=int, default=None, help="timed runs (median is reported)")
    if parts:
        parser.add_argument("--only", choices=sorted(parts), default=None, help="run only this part of the bench")
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


@functools.cache
def _cpu() -> dict:
    """CPU model, vector extensions (AVX2, AVX-512) and cores, from /proc/cpuinfo where it exists."""
    model, flags = platform.processor() or platform.machine(), set()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() == "model name":
                    model = value.strip()
                elif key.strip() == "flags":
                    flags = set(value.split())
                if model and flags:
                    break
    except OSError:
        pass
    vectors = [name for name, flag in (("AVX2", "avx2"), ("AVX-512", "avx512f")) if flag in flags]
    return {"cpu": model, "vector": vectors, "cores": os.cpu_count()}


@functools.cache
def _opencl_device() -> str:
    try:
        from clsas import opencl

        rt = opencl.runtime()
        return f"{rt.device.name} ({rt.device.platform.version})"
    except Exception as exc:  # noqa: BLE001 - a machine without OpenCL is still described
        return f"none ({type(exc).__name__})"


def machine() -> dict:
    """The machine a figure is measured on, with the load average now (1, 5, 15 min)."""
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return {**_cpu(), "opencl_device": _opencl_device(), "load_average": [round(x, 2) for x in load]}


def machine_brief(m: dict) -> str:
    return (f"[{m['cpu']}, {'/'.join(m['vector']) or 'no AVX2'}, {m['cores']} cores, {m['opencl_device'].split(' (')[0]}, "
            f"load {m['load_average'][0]:.2f}]")


def device_name(backend: str) -> str:
    if backend == "opencl":
        from clsas import opencl

        return opencl.runtime().device.name
    import platform

    return f"numpy on {platform.processor() or platform.machine()}"


def report(args, bench: str, backend: str, size: dict, rate: float, unit: str, seconds: float, **extra) -> dict:
    row = {"bench": bench, "backend": backend, "device": device_name(backend), "size": size,
           "rate": float(rate), "unit": unit, "seconds": float(seconds), **extra, "machine": machine()}
    if args.json:
        print(json.dumps(row), flush=True)
    else:
        tags = " ".join(f"{k}={v}" for k, v in extra.items())
        print(f"{bench:16s} {backend:7s} {rate:12.4g} {unit:18s} {seconds*1e3:10.2f} ms  {size} {tags} "
              f"{machine_brief(row['machine'])}", flush=True)
    return row
