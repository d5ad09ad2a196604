"""``clsas info``: the version, the backend, the OpenCL device and where its driver comes from.

``--check`` also builds and runs a kernel (``kernelmath.rotate_phase``) on the device against its
NumPy twin and exits 1 when that fails: the Makefile uses it to tell a device that is listed
from one that works (pip's PoCL lists a device on some CPUs whose compiler then fails). Then it
builds ahead the kernels of the usual calls (echo synthesis, back-projection with each
interpolator, with an aperture and stop-and-go, ffbp) by running them on a tiny scene: PoCL
keeps compiled kernels in its disk cache (keyed by the preprocessed source, so the headers,
the build options and the device and driver), so the first real call in any later process
finds them built. ``kernels_built`` in the output gives each call's seconds.
"""

from __future__ import annotations

import importlib.metadata
import json


def add_arguments(parser) -> None:
    parser.add_argument("--check", action="store_true",
                        help="also build and run a kernel on the device; exit 1 when it fails")


def opencl_source(platform_version: str) -> str:
    """Where the PoCL driver of a platform comes from, from its version string: pip's
    pocl-binary-distribution (``clsas[pocl]``), a Debian/Ubuntu package, or another ICD."""
    try:
        pip_version = importlib.metadata.version("pocl-binary-distribution")
    except importlib.metadata.PackageNotFoundError:
        pip_version = None
    if "PoCL" in platform_version:
        if "debian" in platform_version.lower() or "ubuntu" in platform_version.lower():
            return "distribution package (pocl-opencl-icd)"
        if pip_version and f"PoCL {pip_version}" in platform_version:
            return f"pip (pocl-binary-distribution {pip_version})"
        return "PoCL from a system ICD"
    return "system ICD"


def kernel_check() -> str | None:
    """None when a helper kernel builds, runs and matches its NumPy twin; else what went wrong."""
    import numpy as np

    from .. import kernelmath

    try:
        rng = np.random.default_rng(0)
        x = (rng.standard_normal(4096) + 1j * rng.standard_normal(4096)).astype(np.complex64)
        cycles = rng.uniform(-1e3, 1e3, x.size).astype(np.float32)
        err = np.max(np.abs(kernelmath.rotate_phase(x, cycles, backend="opencl")
                            - kernelmath.rotate_phase(x, cycles, backend="numpy")))
    except Exception as exc:  # noqa: BLE001 - any failure of the driver is the answer
        return f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"
    return None if err < 1e-4 else f"the kernel disagrees with NumPy by {err:.3g}"


def build_ahead() -> dict:
    """Run the usual calls once on a tiny scene (their kernels are compiled and cached by PoCL):
    seconds per call, or the error of a call that failed."""
    import time

    import numpy as np

    import clsas
    from ..image import upsample
    from ..scene import presets

    done = {}

    def timed(name, call):
        start = time.perf_counter()
        try:
            result = call()
        except Exception as exc:  # noqa: BLE001 - reported, the check goes on
            done[name] = f"failed: {type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
            return None
        done[name] = round(time.perf_counter() - start, 3)
        return result

    scene = presets.kiang2022(n_pulses=16)
    scene = scene.replace(targets=(clsas.PointTargets([[30.0, 0.0, -43.0]]),))
    raw = timed("simulate", lambda: clsas.simulate(scene, backend="opencl", progress=False))
    if raw is None:
        return done
    echo = clsas.range_compress(raw)
    grid = clsas.Grid.plane(np.linspace(29.5, 30.5, 24), np.linspace(-0.5, 0.5, 24), -43.0)
    kw = dict(backend="opencl", receivers=["A"], progress=False)
    for name, options in (("backproject linear", {}), ("backproject sinc8", {"interp": "sinc8"}),
                          ("backproject aperture", {"aperture": 0.5}), ("backproject stop-and-go", {"stop_and_go": True})):
        timed(name, lambda: clsas.backproject(echo, grid, **kw, **options))
    timed("ffbp", lambda: clsas.ffbp(echo, grid, **kw))
    # the scene samples at fs = B, where back-projection upsamples by FFT: build the FIR's kernel too
    timed("upsample FIR", lambda: upsample.upsample_fir(echo.data[0], 8, 0, echo.n_samples))
    return done


def run(args) -> int:
    from .. import __version__, backend

    info = {"clsas": __version__, **backend.info()}
    if "platform" in info:
        from .. import opencl

        info["opencl_source"] = opencl_source(opencl.runtime().device.platform.version)
    status = 0
    if args.check:
        problem = kernel_check() if "platform" in info else info.get("opencl_error", "no OpenCL device")
        info["kernel_check"] = "ok" if problem is None else f"failed: {problem}"
        status = 0 if problem is None else 1
        if problem is None:
            info["kernels_built"] = build_ahead()
    print(json.dumps(info, indent=2))
    return status
