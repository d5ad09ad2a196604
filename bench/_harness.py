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

``--kernels avx2`` builds the OpenCL kernels as PoCL would on an AVX2 CPU (its AVX2 kernel
library and LLVM's Haswell model: 256-bit vectors, no AVX-512) while running on an AVX-512 CPU,
so that what an AVX2 machine's kernels do can be measured on the machine one has (the rest of
the machine, its caches and memory, stays this one's). It sets POCL_KERNELLIB_NAME=avx2 and
POCL_LLVM_CPU_NAME=haswell before any device is opened (PoCL ignores the second without the
first), a PoCL kernel cache of its own and no pyopencl binary cache (whose key holds the
device's name, which PoCL keeps, not the code model). The device then reports itself as
"pthread-haswell-...", and every row's machine holds ``"kernels": "avx2"``.
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
    parser.add_argument("--kernels", choices=("native", "avx2"), default="native",
                        help="the instruction set the OpenCL kernels are built for (avx2: as on an AVX2 CPU; "
                             "module docstring)")
    if parts:
        parser.add_argument("--only", choices=sorted(parts), default=None, help="run only this part of the bench")
    args = parser.parse_args()
    if args.kernels == "avx2":
        kernels_for_avx2()
    return args


AVX2_KERNELS = {"POCL_KERNELLIB_NAME": "avx2", "POCL_LLVM_CPU_NAME": "haswell"}


def kernels_for_avx2() -> None:
    """Build this process's OpenCL kernels as on an AVX2 CPU (module docstring); call it before the
    first device is opened."""
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "clsas-bench" / "pocl-avx2"
    cache.mkdir(parents=True, exist_ok=True)
    os.environ.update(AVX2_KERNELS, POCL_CACHE_DIR=str(cache), PYOPENCL_NO_CACHE="1")


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
    kernels = "avx2" if all(os.environ.get(k) == v for k, v in AVX2_KERNELS.items()) else "native"
    return {**_cpu(), "opencl_device": _opencl_device(), "kernels": kernels,
            "load_average": [round(x, 2) for x in load]}


def machine_brief(m: dict) -> str:
    kernels = ", kernels built for AVX2" if m.get("kernels") == "avx2" else ""
    return (f"[{m['cpu']}, {'/'.join(m['vector']) or 'no AVX2'}, {m['cores']} cores, {m['opencl_device'].split(' (')[0]}"
            f"{kernels}, load {m['load_average'][0]:.2f}]")


def device_name(backend: str) -> str:
    """What ran the figure: the OpenCL device, or the backend (numpy, embree, a peer such as
    torchbp-cpu) on this CPU."""
    if backend == "opencl":
        from clsas import opencl

        return opencl.runtime().device.name
    return f"{backend} on {platform.processor() or platform.machine()}"


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
