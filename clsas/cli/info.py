"""``clsas info``: the version, the backend, the OpenCL device and where its driver comes from.

``--check`` also builds and runs a kernel (``kernelmath.rotate_phase``) on the device against its
NumPy twin and exits 1 when that fails: the Makefile uses it to tell a device that is listed
from one that works (pip's PoCL lists a device on some CPUs whose compiler then fails).
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
    print(json.dumps(info, indent=2))
    return status
