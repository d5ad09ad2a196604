"""Which implementation the kernel-bearing functions run: the NumPy reference or OpenCL.

Every kernel-bearing function of clsas takes ``backend=None`` and passes it to
:func:`resolve`, which turns it into ``"numpy"`` or ``"opencl"``:

- ``None`` means the current default: the last :func:`use_backend` choice, else the
  ``CLSAS_BACKEND`` environment variable, else ``"auto"``;
- ``"auto"`` picks OpenCL when a device is found and NumPy otherwise (one warning per process);
- ``"opencl"`` with no device raises :class:`clsas.opencl.OpenCLUnavailable` (a RuntimeError
  that says how to install PoCL).

``use_backend`` works as a plain call (the choice stays) and as a context manager (the
previous choice comes back on exit)::

    clsas.use_backend("numpy")
    with clsas.use_backend("opencl"):
        image = clsas.backproject(echo, grid)

The choice is a context variable (:mod:`contextvars`): it belongs to the thread (or asyncio
task) that made it, so a ``with`` block in one thread leaves every other thread's choice
alone. A new thread starts without a choice (``CLSAS_BACKEND``, else "auto"); to hand the
calling thread's choice to a worker, run it in ``contextvars.copy_context()``. The environment
variable is the process-wide default.
"""

from __future__ import annotations

import contextvars
import os
import warnings

from .thread_setting import ThreadSetting

BACKENDS = ("numpy", "opencl", "auto")

#: set by use_backend in the current context; None defers to CLSAS_BACKEND, then "auto"
_choice: contextvars.ContextVar = contextvars.ContextVar("clsas_backend", default=None)
_auto_warned = False


def _check_name(name: object, what: str) -> str:
    if not isinstance(name, str) or name.lower() not in BACKENDS:
        raise ValueError(f"{what} must be one of {BACKENDS}, got {name!r}")
    return name.lower()


def default() -> str:
    """The backend name used when a function gets ``backend=None`` (may be ``"auto"``)."""
    chosen = _choice.get()
    if chosen is not None:
        return chosen
    env = os.environ.get("CLSAS_BACKEND")
    if env:
        return _check_name(env, "the CLSAS_BACKEND environment variable")
    return "auto"


class use_backend(ThreadSetting):
    """Set the default backend of the current thread (context); as a context manager, restore
    the previous one on exit.

    Parameters
    ----------
    name : {"numpy", "opencl", "auto"}
    """

    def __init__(self, name: str):
        self.name = _check_name(name, "use_backend name: the backend")
        super().__init__(_choice, self.name)

    def __repr__(self) -> str:
        return f"use_backend({self.name!r})"


def resolve(backend: str | None = None) -> str:
    """Turn a ``backend=`` keyword into ``"numpy"`` or ``"opencl"``.

    Raises
    ------
    ValueError
        for an unknown name.
    clsas.opencl.OpenCLUnavailable
        when ``"opencl"`` is asked for and no OpenCL device can be found.
    """
    global _auto_warned
    from . import opencl

    name = default() if backend is None else _check_name(backend, "backend")
    if name == "numpy":
        return "numpy"
    if name == "opencl":
        opencl.runtime()  # raises OpenCLUnavailable with install instructions
        return "opencl"
    if opencl.available():
        return "opencl"
    if not _auto_warned:
        _auto_warned = True
        warnings.warn(
            "backend 'auto': no OpenCL device found, using the NumPy reference path "
            f"(slow). {opencl.INSTALL_HINT}",
            RuntimeWarning,
            stacklevel=2,
        )
    return "numpy"


def info() -> dict:
    """What the backends would run on: the default choice and the OpenCL device, if any.

    Returns a dict with ``default`` (the configured name), ``resolved`` (what ``None``
    resolves to now, without warning), and, when a device is found, ``platform``,
    ``device``, ``opencl_version``, ``compute_units``, ``fp64`` and ``driver_version``;
    otherwise ``opencl_error`` says why not.
    """
    from . import opencl

    out: dict = {"default": default()}
    try:
        rt = opencl.runtime()
    except opencl.OpenCLUnavailable as err:
        out["resolved"] = "numpy"
        out["opencl_error"] = str(err)
        return out
    out["resolved"] = "numpy" if default() == "numpy" else "opencl"
    out.update(opencl.device_info(rt.device))
    return out


PRECISIONS = ("single", "double")


def check_precision(precision: str) -> bool:
    """Validate a ``precision=`` keyword; True means double (fp64 kernels)."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {PRECISIONS}, got {precision!r}")
    return precision == "double"
