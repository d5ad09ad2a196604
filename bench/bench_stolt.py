"""Stolt mapping throughput: M output samples per second, NumPy reference vs OpenCL kernel.

A 4096 x 4096 complex64 wavenumber spectrum (random content: the rate does not depend on it) of a
150 kHz, 20 kHz-band sonar sampled at 40 kHz, along-track wavenumbers up to the Nyquist of
0.02 m sampling; the whole ``clsas.image.stolt.stolt`` call is timed (host buffers used in place
by the OpenCL path, the result mapped back). The OpenCL path is timed twice: returning a fresh
result array (``"output": "fresh"``: its 134 MB are page-faulted in during the call) and writing
into one reused array (``"output": "reused"``, the ``out=`` of a stream of equal blocks). The
NumPy reference runs on fewer rows (its rate does not depend on the row count); each JSON line
names its interpolator (``"interp"``), and the OpenCL lines carry the kernel's relative L2
difference from the float64 reference on the reference's rows (``"rel_l2_to_reference"``).
"""

from __future__ import annotations

from functools import partial

import numpy as np
from _harness import arguments, measure, report

from clsas.image.stolt import StoltAxes, stolt

C, F0, FS = 1500.0, 150e3, 40e3


def case(n_rows: int, n: int):
    rng = np.random.default_rng(0)
    spec = (rng.standard_normal((n_rows, n)) + 1j * rng.standard_normal((n_rows, n))).astype(np.complex64)
    ku = 2 * np.pi * np.fft.fftfreq(n_rows, 0.02)
    df = FS / n
    axes = StoltAxes(f_first=-FS / 2, df=df, n_src=n, kx_first=4 * np.pi * (-FS / 2) / C, dkx=4 * np.pi * df / C,
                     n_out=n, f0=F0, c=C)
    return spec, ku, axes


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    n = 1024 if args.quick else 4096
    rows = {"opencl": n, "numpy": 64 if args.quick else 128}
    for interp in ("linear", "sinc8"):
        spec, ku, axes = case(rows["numpy"], n)
        reference = stolt(spec, ku, axes, interp, backend="numpy")
        kernel = stolt(spec, ku, axes, interp, backend="opencl")
        error = float(np.linalg.norm(kernel - reference) / np.linalg.norm(reference))
        for backend, n_rows in rows.items():
            spec, ku, axes = case(n_rows, n)
            outputs = {"fresh": None, "reused": np.empty((n_rows, n), np.complex64)} if backend == "opencl" \
                else {"fresh": None}
            for output, out in outputs.items():
                seconds = measure(partial(stolt, spec, ku, axes, interp, backend=backend, out=out),
                                  repeats=args.repeats or (7 if backend == "opencl" else 1))
                report(args, "stolt", backend, {"rows": n_rows, "columns": n}, n_rows * n / seconds / 1e6,
                       "M samples/s", seconds, interp=interp, output=output,
                       **({"rel_l2_to_reference": error} if backend == "opencl" else {}))


if __name__ == "__main__":
    main()
