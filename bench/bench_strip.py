"""The strip-map imagers against numerical PTRS with 8 sub-blocks on Zhang et al. 2019's scene, in one run.

Scene: the Table 1 sonar as the reproduction samples it (30 receivers, PRI 0.15 s;
:func:`clsas.scene.presets.zhang2019`), range-compressed echoes of the 18 points spread over
the 43-204 m swath, 64 pulses (``--quick``: 16 pulses). Each imager
is timed whole, from the range-compressed echo to the Image: PCA (:func:`clsas.pca_record`)
followed by range-Doppler, chirp scaling, nonlinear chirp scaling or omega-k (OpenCL
interpolation, the template's defaults, elements (0.04, 0.02) and no deconvolution, as the
reproduction), and :func:`clsas.ptrs_image` with 8 uniform sub-blocks (its stationary points
solved beforehand and reused: seed 003's second scheme, the cheaper for PTRS). The runs are
interleaved round by round (A B C ... A B C ...), warm-up excluded; each line reports the
median and the minimum, the ratio of medians to PTRS (``"to_ptrs8"``, < 1 is faster), the
range sub-blocks of range-Doppler's SRC and of NCS (``"src_blocks"``, ``"ncs_blocks"``), and
the load average at the start and the end.
"""

from __future__ import annotations

import os
import statistics
import time
import warnings

from _harness import arguments, report

import clsas
from clsas.image.ptrs import StationaryPoints
from clsas.scene import presets

ELEMENTS = (0.04, 0.02)


def scene(quick: bool):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the reproduction's PRF overlaps pulses (SamplingWarning)
        sc = presets.point_scene("zhang2019", n_pulses=16 if quick else 64, receivers=30, pri=0.15)
        return clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    load_start = os.getloadavg()
    echo = scene(args.quick)
    swath = echo.medium.sound_speed * echo.n_samples / echo.fs / 2
    common = {"elements": ELEMENTS, "deconvolve": False, "backend": "opencl"}
    points = StationaryPoints()

    def strip(imager):
        return lambda: imager(clsas.pca_record(echo, backend="opencl"), **common)

    runs = {
        "ptrs8": lambda: clsas.ptrs_image(echo, block_width=swath / 8, points=points, **common),
        "pca_range_doppler": strip(clsas.range_doppler),
        "pca_chirp_scaling": strip(clsas.chirp_scaling),
        "pca_omega_k": strip(clsas.omega_k),
    }
    if hasattr(clsas, "nonlinear_chirp_scaling"):
        runs["pca_nonlinear_chirp_scaling"] = strip(clsas.nonlinear_chirp_scaling)
    images = {name: run() for name, run in runs.items()}  # warm-up: kernel builds, the stationary points
    times = {name: [] for name in runs}
    for _ in range(args.repeats or 3):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - start)
    load_end = os.getloadavg()
    median = {name: statistics.median(t) for name, t in times.items()}
    size = {"receivers": echo.n_rx, "pulses": echo.n_pulses, "samples": echo.n_samples}
    for name, t in times.items():
        pixels = images[name].data.size
        extra = {"algorithm": name, "min_seconds": min(t), "to_ptrs8": median[name] / median["ptrs8"],
                 "pixels": pixels, "load_start": load_start[0], "load_end": load_end[0]}
        extra.update({key: value for key, value in images[name].provenance.items() if key.endswith("_blocks")})
        report(args, "strip", "opencl", size, pixels * echo.n_pulses * echo.n_rx / median[name] / 1e9,
               "G pixel-pulses/s", median[name], **extra)


if __name__ == "__main__":
    main()
