"""OpenCL plumbing: device discovery, one context and queue per device, a program cache.

Nothing here runs at import: the first call to :func:`runtime` picks the device. The device
is chosen by, in order, the ``device=`` argument, the ``CLSAS_DEVICE`` environment variable,
pyopencl's ``PYOPENCL_CTX``, and otherwise the first device of the first platform. A device
spec is ``"P"`` or ``"P:D"`` (platform and device indices, as ``clinfo -l`` lists them) or a
case-insensitive substring of the platform or device name (``"pocl"``, ``"avx512"``).

Kernel sources live in ``kernels/NAME.cl`` (shipped in the wheel as ``clsas/kernels``) and may
``#include "common.h"``. :func:`program` builds a source once per (device, source text,
build options) and caches it; structural constants are passed as ``defines``.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import logging
import os
import re
import sys
import tempfile
import threading
import warnings
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

INSTALL_HINT = (
    "Install an OpenCL driver for the CPU: on Debian/Ubuntu `sudo apt-get install "
    "pocl-opencl-icd` (or run `make setup`, which does it), then `clinfo -l` should list a "
    "device. To run without OpenCL, use clsas.use_backend('numpy') or CLSAS_BACKEND=numpy."
)


class OpenCLUnavailable(RuntimeError):
    """No usable OpenCL platform/device (or the requested one does not exist)."""


class KernelBuildError(RuntimeError):
    """An OpenCL kernel failed to compile; the message carries the build log."""


@dataclass(frozen=True)
class Runtime:
    """The OpenCL objects clsas uses for one device."""

    device: "object"  # pyopencl.Device
    context: "object"  # pyopencl.Context
    queue: "object"  # pyopencl.CommandQueue (profiling enabled, for the benchmarks)


_runtimes: dict[str, Runtime] = {}
_runtime_by_spec: dict[str | None, Runtime] = {}  # the resolved device spec -> its Runtime, so a call costs a lookup
_programs: dict[tuple, object] = {}
_kernels: dict[tuple, "TypedKernel"] = {}  # (id(program), kernel name, thread) -> its TypedKernel
_kernel_calls: dict[tuple, "TypedKernel"] = {}  # kernel()'s arguments, runtime and thread -> TypedKernel (no hashing a call)
_sources: dict[str, tuple[str, str]] = {}  # kernels/NAME.cl -> (text, digest), read once per process


def _import_pyopencl():
    try:
        import pyopencl as cl
    except ImportError as err:  # pragma: no cover - pyopencl is a hard dependency
        raise OpenCLUnavailable(f"pyopencl cannot be imported ({err}). {INSTALL_HINT}") from err
    return cl


def _all_devices():
    cl = _import_pyopencl()
    try:
        platforms = cl.get_platforms()
    except cl.Error as err:
        raise OpenCLUnavailable(f"no OpenCL platform found ({err}). {INSTALL_HINT}") from err
    found = [(ip, idev, dev) for ip, p in enumerate(platforms) for idev, dev in enumerate(p.get_devices())]
    if not found:
        raise OpenCLUnavailable(f"OpenCL platforms exist but none has a device. {INSTALL_HINT}")
    return found


def _device_spec(spec: str | None) -> str | None:
    if spec is not None:
        return str(spec)
    return os.environ.get("CLSAS_DEVICE") or os.environ.get("PYOPENCL_CTX") or None


def select_device(spec: str | None = None):
    """The pyopencl.Device that ``spec`` (or the environment) names; see the module docstring."""
    devices = _all_devices()
    spec = _device_spec(spec)
    if spec is None or spec.strip() == "":
        return devices[0][2]
    spec = spec.strip()
    parts = spec.split(":")
    if all(p.strip().isdigit() for p in parts if p.strip()) and 1 <= len(parts) <= 2:
        ip = int(parts[0])
        idev = int(parts[1]) if len(parts) == 2 and parts[1].strip() else 0
        for p, d, dev in devices:
            if (p, d) == (ip, idev):
                return dev
    else:
        needle = spec.lower()
        for _, _, dev in devices:
            if needle in dev.name.lower() or needle in dev.platform.name.lower():
                return dev
    listing = "; ".join(f"{p}:{d} {dev.platform.name} / {dev.name}" for p, d, dev in devices)
    raise OpenCLUnavailable(
        f"OpenCL device spec {spec!r} (from the device argument, CLSAS_DEVICE or PYOPENCL_CTX) "
        f"matches no device; available: {listing}"
    )


def _device_key(device) -> str:
    return f"{device.platform.name}|{device.name}|{device.int_ptr}"


def runtime(device: str | None = None) -> Runtime:
    """The (device, context, queue) for ``device`` (a spec; None = the default device).

    Platforms are enumerated once per resolved spec (the argument, else the environment at
    the time of the call); later calls with the same spec are a dictionary lookup.
    """
    spec = _device_spec(device)
    rt = _runtime_by_spec.get(spec)
    if rt is not None:
        return rt
    cl = _import_pyopencl()
    dev = select_device(spec)
    key = _device_key(dev)
    rt = _runtimes.get(key)
    if rt is None:
        ctx = cl.Context([dev])
        queue = cl.CommandQueue(ctx, properties=cl.command_queue_properties.PROFILING_ENABLE)
        rt = Runtime(device=dev, context=ctx, queue=queue)
        _runtimes[key] = rt
        logging.getLogger("clsas").info("OpenCL device: %s / %s, %d compute units, OpenCL %s", dev.platform.name,
                                        dev.name, dev.max_compute_units, dev.version)
    _runtime_by_spec[spec] = rt
    return rt


def available(device: str | None = None) -> bool:
    """True when an OpenCL device can be used."""
    try:
        runtime(device)
    except OpenCLUnavailable:
        return False
    return True


def has_fp64(device) -> bool:
    """True when the device supports double precision (PoCL CPU devices do)."""
    return "cl_khr_fp64" in device.extensions or bool(getattr(device, "double_fp_config", 0))


def device_info(device) -> dict:
    """Platform, device, OpenCL version, compute units, fp64 support of ``device``."""
    return {
        "platform": device.platform.name,
        "device": device.name,
        "opencl_version": device.version,
        "driver_version": device.driver_version,
        "compute_units": int(device.max_compute_units),
        "fp64": has_fp64(device),
        "max_work_group_size": int(device.max_work_group_size),
        "global_mem_bytes": int(device.global_mem_size),
    }


@functools.cache
def kernels_dir() -> Path:
    """The folder holding ``common.h`` and the ``*.cl`` sources.

    In an installed wheel it is ``clsas/kernels`` (the build maps the top-level ``kernels/``
    there); in a source checkout (editable install) it is the top-level ``kernels/``. Found
    once per process (every kernel launch used to pay the lookup).
    """
    packaged = Path(str(resources.files("clsas"))) / "kernels"
    if (packaged / "common.h").is_file():
        return packaged
    checkout = Path(__file__).resolve().parent.parent / "kernels"
    if (checkout / "common.h").is_file():
        return checkout
    raise FileNotFoundError(
        f"clsas kernel sources not found: looked in {packaged} (installed wheel) and {checkout} "
        "(source checkout); reinstall clsas"
    )


def _source(name: str) -> tuple[str, str]:
    """(source text, digest of it and of every header in kernels/) for kernels/NAME.cl, read from
    disk on the first call for NAME in the process (a source edited later needs a new process)."""
    if name in _sources:
        return _sources[name]
    kdir = kernels_dir()
    path = kdir / f"{name}.cl"
    if not path.is_file():
        known = sorted(p.stem for p in kdir.glob("*.cl"))
        raise ValueError(f"kernel source {name!r} not found in {kdir}; known: {known}")
    text = path.read_text()
    digest = hashlib.sha256(text.encode())
    for header in sorted(kdir.glob("*.h")):
        digest.update(header.read_bytes())
    _sources[name] = text, digest.hexdigest()
    return _sources[name]


def program(name: str, defines: dict | None = None, device: str | None = None, double: bool = False,
            preamble: str = ""):
    """The built pyopencl.Program for ``kernels/NAME.cl``.

    Parameters
    ----------
    name : str
        Source file stem under :func:`kernels_dir`.
    defines : dict, optional
        ``-D KEY=VALUE`` structural constants (tap counts, block sizes).
    double : bool
        Build with ``-D CLSAS_DOUBLE`` so that ``real_t``/``complex_t`` of ``common.h`` are
        double precision; refused when the device has no fp64.
    preamble : str
        C text put in front of the source, e.g. the record structs of :func:`clsas.cstruct.declare`.
    """
    cl = _import_pyopencl()
    rt = runtime(device)
    if double and not has_fp64(rt.device):
        raise RuntimeError(f"precision='double' needs fp64, which device {rt.device.name!r} lacks")
    text, digest = _source(name)
    if preamble:
        text = f"{preamble}\n#line 1\n{text}"
        digest = hashlib.sha256(f"{digest}{preamble}".encode()).hexdigest()
    options = [f"-I{kernels_dir()}"]
    if double:
        options.append("-DCLSAS_DOUBLE=1")
    for key, value in sorted((defines or {}).items()):
        options.append(f"-D{key}={value}")
    cache_key = (_device_key(rt.device), digest, tuple(options))
    prg = _programs.get(cache_key)
    if prg is None:
        try:
            with quiet_build(name) as captured:
                prg = cl.Program(rt.context, text).build(options=options)
                captured.append(prg.get_build_info(rt.device, cl.program_build_info.LOG))
        except cl.RuntimeError as err:
            raise KernelBuildError(
                f"building kernels/{name}.cl with options {options} failed on "
                f"{rt.device.name}:\n{err}"
            ) from err
        _programs[cache_key] = prg
    return prg


def kernel(name: str, kernel_name: str, defines: dict | None = None, device: str | None = None,
           double: bool = False, preamble: str = ""):
    """The :class:`TypedKernel` of ``kernel_name`` from ``kernels/NAME.cl`` (see :func:`program`), one per
    (program, name, thread): a fresh Kernel looks its argument invoker up in pyopencl's on-disk
    cache (milliseconds a call), which calls launching many small kernels (ffbp's leaves and
    merges) paid every time. Launch it as ``kern(queue, ...)`` (arguments set and enqueued at once;
    scalar arguments typed on the first launch)."""
    call = (name, kernel_name, id(runtime(device)), double, preamble, tuple(sorted((defines or {}).items())),
            threading.get_ident())
    kern = _kernel_calls.get(call)
    if kern is not None:  # a launch in a loop: no source hashing, no option strings
        return kern
    cl = _import_pyopencl()
    prg = program(name, defines=defines, device=device, double=double, preamble=preamble)
    key = (id(prg), kernel_name, threading.get_ident())
    kern = _kernels.get(key)
    if kern is None:
        kern = _kernels[key] = TypedKernel(cl.Kernel(prg, kernel_name))
    _kernel_calls[call] = kern
    return kern


class TypedKernel:
    """A kernel from :func:`kernel` (a pyopencl.Kernel, ``.kernel``) launched as ``kern(queue,
    global_size, local_size, *args)``, its scalar arguments typed on its first launch.

    pyopencl sets an untyped NumPy scalar argument through its generic ``set_arg`` (~40 us a
    launch for a few ints on this project's machines, thread CPU), while typed ones are packed by
    its generated invoker (~7 us for the whole launch). The first launch's arguments say the types:
    a NumPy scalar's dtype (not a structured one) for its slot, None (set as given) for buffers,
    local memory and structured scalars. A first launch that fails leaves the kernel untyped (the
    next launch types it again). Every later launch must pass a NumPy scalar of exactly that dtype
    in a typed slot (as pyopencl's untyped path required its width): anything else is a TypeError
    naming the slot, never a silent narrowing.
    """

    __slots__ = ("kernel", "_scalars")

    def __init__(self, kernel):
        self.kernel = kernel
        self._scalars = None  # ((slot, NumPy scalar type), ...) once typed

    def __call__(self, queue, global_size, local_size, *args, **kwargs):
        if self._scalars is None:
            dtypes = [a.dtype if isinstance(a, np.generic) and a.dtype.fields is None else None for a in args]
            self.kernel.set_scalar_arg_dtypes(dtypes)
            try:
                event = self.kernel(queue, global_size, local_size, *args, **kwargs)
            except Exception:
                self.kernel.set_scalar_arg_dtypes([None] * len(args))
                raise
            self._scalars = tuple((k, d.type) for k, d in enumerate(dtypes) if d is not None)
            return event
        for k, kind in self._scalars:
            if type(args[k]) is not kind:
                raise TypeError(f"kernel {self.kernel.function_name}: argument {k} must be a {kind.__name__} "
                                f"(its type at the first launch), not {type(args[k]).__name__} {args[k]!r}")
        return self.kernel(queue, global_size, local_size, *args, **kwargs)


#: Work-items a work-group of the kernels launched through :func:`work_groups`.
WORK_GROUP = 8


def work_groups(n_items: int, group: int = WORK_GROUP) -> tuple[tuple[int], tuple[int]]:
    """(global size, local size) for ``n_items`` work-items in work-groups of ``group``, the global
    size padded to whole groups (the kernel returns for work-items past ``n_items``). A fixed
    local size lets PoCL compile a kernel once: with the local size left to it, every new global
    size may get a new one, and with it a new compilation (~0.2 s a kernel, in every process
    that meets that size, unless its disk cache holds that exact specialisation)."""
    return (-(-max(int(n_items), 1) // group) * group,), (group,)


def work_groups_2d(n_x: int, n_y: int, group: int = WORK_GROUP) -> tuple[tuple[int, int], tuple[int, int]]:
    """:func:`work_groups` for a 2-D launch of (n_x, n_y) work-items, in groups of (1, group): the
    second dimension padded (the kernel returns for work-items past n_y)."""
    return (max(int(n_x), 1), -(-max(int(n_y), 1) // group) * group), (1, group)


#: Compiler output known to be harmless: PoCL's note that a 16-wide vector argument changes the
#: ABI without AVX-512 (the kernels are compiled as a whole; nothing crosses that ABI), clang's
#: count of such warnings, and the include-spelling lines that point at them.
HARMLESS_OUTPUT = re.compile(r"changes the ABI|^\d+ warnings? generated\.$|^\s*$|^\s*\^|^\s*\d* *\|")

_log = logging.getLogger("clsas")
_build_lock = threading.RLock()  # file descriptor 2 and the warning filters are process-wide


def _verbose_compiler() -> bool:
    return any(os.environ.get(v, "") not in ("", "0") for v in ("CLSAS_DEBUG", "PYOPENCL_COMPILER_OUTPUT"))


@contextlib.contextmanager
def quiet_build(name: str):
    """Around a kernel build: hide the compiler's known-harmless output (:data:`HARMLESS_OUTPUT`)
    printed on file descriptor 2 and in pyopencl's CompilerWarning; anything else the compiler
    says is logged as a warning on ``logging.getLogger("clsas")``. The caller appends the build
    log to the list yielded. ``CLSAS_DEBUG=1`` or ``PYOPENCL_COMPILER_OUTPUT=1`` shows it all."""
    texts: list = []
    if _verbose_compiler():
        yield texts
        return
    with _build_lock:  # one build at a time: a second thread would save and restore the redirected fd
        yield from _silenced(name, texts)


def _silenced(name: str, texts: list):
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as sink, warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*compiler output", module="pyopencl")
        warnings.filterwarnings("ignore", message="From-source build succeeded", module="pyopencl")
        os.dup2(sink.fileno(), 2)
        interrupted = False  # by Ctrl-C (or SystemExit): the compiler's "1 error generated." is not news
        try:
            yield texts
        except BaseException as err:
            interrupted = not isinstance(err, Exception)
            raise
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            texts.append(sink.read().decode(errors="replace"))
            kept = [line for text in texts for line in str(text or "").splitlines() if not HARMLESS_OUTPUT.search(line)]
            kept = [line for line in kept if "warning:" in line or "error:" in line] or kept
            if kept and not interrupted:
                _log.warning("building kernels/%s.cl, the compiler said:\n%s", name, "\n".join(kept))
