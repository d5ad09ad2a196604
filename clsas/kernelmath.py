"""The maths of ``kernels/common.h`` in NumPy, beside launchers that run the OpenCL helpers.

The NumPy functions are the definitions the kernels are held to (and are reused by the
NumPy references of the imaging kernels); ``rotate_phase`` and ``kaiser_sinc_taps`` run
``kernels/kernelmath.cl`` so that the tests can compare the two element by element.
"""

from __future__ import annotations

import numpy as np

from . import backend as _backend
from . import opencl


def expj_cycles(cycles):
    """exp(j 2 pi cycles), with the phase reduced to its fractional part first (as the kernels do)."""
    cycles = np.asarray(cycles, dtype=np.float64)
    return np.exp(2j * np.pi * (cycles - np.trunc(cycles)))


def unit_phasor(phase: np.ndarray) -> np.ndarray:
    """exp(j phase) as complex64 for a float64 ``phase`` (rad) of any size: reduced to
    [-pi, pi] in float64 first, so that float32 cos and sin keep ~1e-7 rad (a phase of 1e5 rad
    would lose 1e-2 rad in float32); ~7x faster than a complex128 exp (NumPy's float32 cos/sin
    are SIMD)."""
    reduced = (phase - 2 * np.pi * np.rint(phase * (0.5 / np.pi))).astype(np.float32)
    out = np.empty(reduced.shape, np.complex64)
    np.cos(reduced, out=out.real)
    np.sin(reduced, out=out.imag)
    return out


def kaiser_sinc_tap(x, half_width: float, beta: float):
    """Kaiser-windowed sinc tap for a sample ``x`` samples away from the interpolation point.

    sinc(x) I0(beta sqrt(1 - (x / half_width)^2)) / I0(beta) inside ``|x| < half_width``,
    0 outside; an N-tap interpolator uses ``half_width = N / 2``.
    """
    x = np.asarray(x, dtype=np.float64)
    u = x / half_width
    inside = np.abs(u) < 1
    window = np.i0(beta * np.sqrt(np.clip(1 - u * u, 0, None))) / np.i0(beta)
    return np.where(inside, np.sinc(x) * window, 0.0)


def _dtypes(double: bool):
    return (np.float64, np.complex128) if double else (np.float32, np.complex64)


def rotate_phase(x, cycles, backend: str | None = None, precision: str = "single"):
    """x * exp(j 2 pi cycles), element-wise, on the chosen backend (1-D arrays of equal length)."""
    x = np.asarray(x)
    cycles = np.asarray(cycles)
    if x.ndim != 1 or x.shape != cycles.shape:
        raise ValueError(f"x and cycles must be 1-D of equal length, got {x.shape} and {cycles.shape}")
    double = _backend.check_precision(precision)
    if _backend.resolve(backend) == "numpy":
        return x.astype(np.complex128) * expj_cycles(cycles)
    import pyopencl.array as cla

    real, cplx = _dtypes(double)
    rt = opencl.runtime()
    x_d = cla.to_device(rt.queue, np.ascontiguousarray(x, dtype=cplx))
    c_d = cla.to_device(rt.queue, np.ascontiguousarray(cycles, dtype=real))
    y_d = cla.empty_like(x_d)
    knl = opencl.kernel("kernelmath", "rotate_phase", double=double)
    knl(rt.queue, (x.size,), None, x_d.data, c_d.data, y_d.data)
    return y_d.get()


def kaiser_sinc_taps(offsets, half_width: float, beta: float, backend: str | None = None,
                     precision: str = "single"):
    """:func:`kaiser_sinc_tap` for every offset, on the chosen backend (1-D array)."""
    offsets = np.asarray(offsets)
    if offsets.ndim != 1:
        raise ValueError(f"offsets must be 1-D, got shape {offsets.shape}")
    if not (np.isfinite(half_width) and half_width > 0):
        raise ValueError(f"half_width must be a positive finite number of samples, got {half_width}")
    if not (np.isfinite(beta) and 0 <= beta <= 40):
        raise ValueError(f"beta must be in [0, 40], got {beta}")
    double = _backend.check_precision(precision)
    if _backend.resolve(backend) == "numpy":
        return kaiser_sinc_tap(offsets, half_width, beta)
    import pyopencl.array as cla

    real, _ = _dtypes(double)
    rt = opencl.runtime()
    o_d = cla.to_device(rt.queue, np.ascontiguousarray(offsets, dtype=real))
    t_d = cla.empty_like(o_d)
    knl = opencl.kernel("kernelmath", "kaiser_sinc_taps", double=double)
    knl(rt.queue, (offsets.size,), None, o_d.data, real(half_width), real(beta), t_d.data)
    return t_d.get()


def expj_fractions(r, backend: str | None = None):
    """exp(j 2 pi r) for phases ``r`` in (-1, 1) cycles: on OpenCL by the float polynomial of
    ``common.h`` (``expj_fraction``, error < 1.4e-8 plus float rounding), on NumPy exactly."""
    r = np.asarray(r, dtype=np.float64)
    if r.ndim != 1 or np.any(np.abs(r) >= 1):
        raise ValueError("r must be a 1-D array of phases in (-1, 1) cycles")
    if _backend.resolve(backend) == "numpy":
        return np.exp(2j * np.pi * r)
    import pyopencl.array as cla

    rt = opencl.runtime()
    r_d = cla.to_device(rt.queue, np.ascontiguousarray(r, dtype=np.float32))
    out = cla.empty(rt.queue, r.size, np.complex64)
    opencl.kernel("kernelmath", "expj_fractions")(rt.queue, (r.size,), None, r_d.data, out.data)
    return out.get()
