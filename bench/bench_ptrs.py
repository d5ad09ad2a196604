"""Numerical PTRS imaging against back-projection and PCA + omega-k on Zhang et al. 2019's sonar, in one run.

Kernels first: the two phase multiplies of kernels/ptrs.cl (decoupling, eqs. 12-13, and azimuth
compression, eq. 14) on one receiver's 2-D array (Doppler rows x range columns, the scene's
size; ``--quick``: a quarter of it), NumPy reference and OpenCL interleaved, in M elements/s.

Scene: the Table 1 sonar as the reproduction samples it (30 receivers, PRI 0.15 s; see
:func:`clsas.scene.presets.zhang2019`), range-compressed echoes of points spread over the swath
(full: the 18-point scene, 43-204 m, 208 pulses; ``--quick``: 2 points at 44 and 54 m, 64
pulses). Timed, interleaved round by round (warm-up excluded): PTRS with 4 and 8 uniform
sub-blocks (the stationary points solved beforehand, seed 003's second scheme) on OpenCL and,
with ``--quick``, on NumPy; PCA (:func:`clsas.pca_record`) + omega-k; back-projection (OpenCL,
sinc8) of the PTRS image's pixels (the same plane grid). The rate of each is pixels x pulses x receivers / s, so
ratios of rates are speed-ups. The closing note prints BP / PTRS beside seed 003's Table 5
(real data, Matlab: 35,234 s vs 608 s with 4 sub-blocks, 58x; 1149 s with 8, 30.7x).

The figures are this script's output (``--json``; docs/validation.md gathers them). PTRS's cost
is M x (M N_p) x N_r per pass (every receiver filters the whole M x PRF Doppler grid), spent in
range FFTs of the sub-block segments; clsas's back-projection is a vectorised OpenCL kernel
where the paper's was Matlab with sinc interpolation, so the ratio to BP is the
implementations' as much as the methods'.
"""

from __future__ import annotations

import statistics
import time
import warnings

import numpy as np
from _harness import arguments, report

import clsas
from clsas.model import Grid
from clsas.image.ptrs import StationaryPoints
from clsas.image.ptrs.phase import compress_azimuth, decouple
from clsas.scene import presets
from clsas.scene.targets import PointTargets


def scene(quick: bool):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if quick:
            sc = presets.zhang2019(n_pulses=64, receivers=30, pri=0.15)
            sc = sc.replace(targets=(PointTargets([[44.0, -1.0, 0.0], [54.0, 1.0, 0.0]]),))
        else:
            sc = presets.point_scene("zhang2019", n_pulses=208, receivers=30, pri=0.15)
    return clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


def kernels(args) -> None:
    """The decoupling and azimuth-compression multiplies, NumPy and OpenCL interleaved."""
    rows, cols = (780, 1500) if args.quick else (3120, 6000)  # one receiver: Doppler rows (|f_t| <= 50 Hz) x range
    points = StationaryPoints().bind(0.03 + 0.02 * np.arange(30), 2.0, 1500.0, s_max=3.8e-4)
    t, g = points.tables([125.0, 143.0, *np.arange(40.0, 210.0, 0.5)])
    ft = np.linspace(-50.0, 50.0, rows)
    ftau = np.fft.fftfreq(cols, 1 / 25e3)
    r = np.linspace(40.0, 209.0, cols)
    node = np.minimum(((r - 40.0) / 0.5).astype(int), 337)
    weight = (r - 40.0 - 0.5 * node) / 0.5
    data = np.ones((rows, cols), np.complex64)
    runs = {}
    for backend in ("numpy", "opencl"):
        runs[("ptrs_decouple", backend)] = lambda b=backend: decouple(
            data, ft, ftau, 150e3, g[15, 1] - g[15, 0], t[15, 1] - t[15, 0], points.s_first, points.ds, 0.024, backend=b)
        runs[("ptrs_compress_azimuth", backend)] = lambda b=backend: compress_azimuth(
            data, ft, 150e3, g[15, 2:], t[15, 2:], points.s_first, points.ds, node, weight, backend=b)
    for run in runs.values():
        run()
    times = {key: [] for key in runs}
    for _ in range(args.repeats or 3):
        for key, run in runs.items():
            start = time.perf_counter()
            run()
            times[key].append(time.perf_counter() - start)
    for (kernel, backend), t_run in times.items():
        median = statistics.median(t_run)
        report(args, "ptrs", backend, {"rows": rows, "columns": cols}, data.size / median / 1e6, "M elements/s",
               median, kernel=kernel, min_seconds=min(t_run))


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    kernels(args)
    echo = scene(args.quick)
    swath = echo.medium.sound_speed * echo.n_samples / echo.fs / 2
    common = {"elements": (0.04, 0.02), "deconvolve": False}
    points = StationaryPoints()
    first = clsas.ptrs_image(echo, block_width=swath / 4, points=points, backend="opencl", **common)
    grid = Grid.plane(first.axes["x"], first.axes["y"], float(first.positions[0, 0, 2]))
    runs = {
        ("ptrs", "opencl", 4): lambda: clsas.ptrs_image(echo, block_width=swath / 4, points=points, backend="opencl",
                                                        **common),
        ("ptrs", "opencl", 8): lambda: clsas.ptrs_image(echo, block_width=swath / 8, points=points, backend="opencl",
                                                        **common),
        ("pca_omega_k", "opencl", 0): lambda: clsas.omega_k(clsas.pca_record(echo, backend="opencl"),
                                                            backend="opencl", **common),
        ("pca_range_doppler", "opencl", 0): lambda: clsas.range_doppler(clsas.pca_record(echo, backend="opencl"),
                                                                        backend="opencl", **common),
        ("backprojection", "opencl", 0): lambda: clsas.backproject(echo, grid, backend="opencl", interp="sinc8",
                                                                   progress=False),
    }
    if args.quick:
        runs[("ptrs", "numpy", 4)] = lambda: clsas.ptrs_image(echo, block_width=swath / 4, points=points,
                                                              backend="numpy", **common)
    for run in runs.values():  # warm-up: kernel builds, first-touch of buffers
        run()
    times = {key: [] for key in runs}
    for _ in range(args.repeats or 2):
        for key, run in runs.items():
            start = time.perf_counter()
            run()
            times[key].append(time.perf_counter() - start)
    work = grid.size * echo.n_pulses * echo.n_rx
    size = {"receivers": echo.n_rx, "pulses": echo.n_pulses, "samples": echo.n_samples, "pixels": grid.size}
    median = {key: statistics.median(t) for key, t in times.items()}
    for (algorithm, backend, blocks), t in times.items():
        extra = {"algorithm": algorithm, "min_seconds": min(t)}
        if blocks:
            extra["sub_blocks"] = blocks
        report(args, "ptrs", backend, size, work / median[(algorithm, backend, blocks)] / 1e9, "G pixel-pulses/s",
               median[(algorithm, backend, blocks)], **extra)
    if not args.json:
        bp = median[("backprojection", "opencl", 0)]
        print(f"BP / PTRS (OpenCL): 4 sub-blocks {bp / median[('ptrs', 'opencl', 4)]:.2f}x [seed 003 Table 5: 58x], "
              f"8 sub-blocks {bp / median[('ptrs', 'opencl', 8)]:.2f}x [30.7x]; "
              f"PTRS (4) / PCA + omega-k: {median[('ptrs', 'opencl', 4)] / median[('pca_omega_k', 'opencl', 0)]:.2f}, "
              f"/ PCA + R-D: {median[('ptrs', 'opencl', 4)] / median[('pca_range_doppler', 'opencl', 0)]:.2f}")


if __name__ == "__main__":
    main()
