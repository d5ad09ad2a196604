"""``clsas demo``: a short end-to-end check on this machine.

An OpenCL helper kernel against its NumPy twin, then Heremans et al. 2009's nine-point scene
(15 hydrophones, 48 pulses) simulated, range-compressed and back-projected, with the centre
point's metrics, the NetCDF files and a picture written into ``--out``.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from ._common import UsageError


def add_arguments(parser) -> None:
    parser.add_argument("-o", "--out", default="demo-output",
                        help="folder for the demo's files, replaced on each run (default: demo-output)")


def run(args) -> int:
    """Heremans et al. 2009's nine-point scene (15 hydrophones) end to end: echoes, range
    compression, back-projection, metrics of the centre point, files and a picture."""
    from .. import backend, io, kernelmath, metrics
    from ..model import Grid
    from ..image import backproject, range_compress
    from ..scene import presets
    from ..scene.targets import PointTargets
    from ..synthesis import delays, simulate

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is an existing file; give a folder for the demo's files")
    if not out.parent.is_dir():
        raise UsageError(f"--out {out}: the folder {out.parent} does not exist (the demo makes only its own folder)")
    out.mkdir(exist_ok=True)
    info = backend.info()
    print("backend:", json.dumps(info))
    ok = True
    if info["resolved"] == "opencl":
        rng = np.random.default_rng(1)
        x = (rng.standard_normal(100_000) + 1j * rng.standard_normal(100_000)).astype(np.complex64)
        cycles = rng.uniform(-1e3, 1e3, x.size).astype(np.float32)
        err = np.max(np.abs(kernelmath.rotate_phase(x, cycles, backend="opencl")
                            - kernelmath.rotate_phase(x, cycles, backend="numpy")))
        print(f"kernel rotate_phase (OpenCL vs NumPy, 1e5 values): max |error| = {err:.2e}")
        ok &= err < 1e-5
    else:
        print("no OpenCL device: the NumPy reference path is used (run `make setup` to install PoCL)")

    scene = presets.point_scene("heremans2009", n_pulses=48)
    wf = dataclasses.replace(scene.waveform, fs=2 * scene.waveform.bandwidth)  # oversampled x2
    scene = scene.replace(waveform=wf)
    t = time.perf_counter()
    echo = simulate(scene, snr_db=20.0, seed=1)
    print(f"simulate: {echo.n_rx} hydrophones x {echo.n_pulses} pulses x {echo.n_samples} samples, "
          f"{len(scene.targets[0].positions)} point targets, SNR 20 dB ({time.perf_counter() - t:.2f} s)")
    compressed = range_compress(echo, upsample=4)

    centre = scene.targets[0].positions[4]
    alone = scene.replace(targets=(PointTargets([centre]),))  # the centre point alone, no noise
    single = range_compress(simulate(alone, progress=False), upsample=4)
    tau = delays(alone, backend="numpy")[7, :, 0]  # the middle hydrophone
    peaks = [metrics.point_response(single.data[7, p], single.fast_time(7)).location for p in range(echo.n_pulses)]
    err = np.max(np.abs(np.array(peaks) - tau)) * wf.fs
    print(f"range compression: the centre point's peaks lie on its exact delays within {err:.3f} samples")
    ok &= err < 0.05

    d = scene.array.rx_length[0]
    rres = scene.medium.sound_speed / (2 * wf.bandwidth)
    grid = Grid.plane(np.arange(93.0, 107.0, rres / 4), np.arange(-7.0, 7.0, d / 8), centre[2])
    t = time.perf_counter()
    image = backproject(compressed, grid)
    print(f"back-projection: {grid.shape[0]} x {grid.shape[1]} pixels ({time.perf_counter() - t:.2f} s)")
    res = metrics.analyse_point(image, near=(centre[1], centre[0]), radius=d)
    print(f"  centre point: position error along track {res['y'].location - centre[1]:+.4f} m, in range "
          f"{res['x'].location - centre[0]:+.4f} m")
    print(f"  range IRW {res['x'].irw * 100:.2f} cm (theory 0.886 c/2B = {0.886 * rres * 100:.2f} cm), "
          f"range PSLR {res['x'].pslr_db:.1f} dB (theory -13.3)")
    ok &= abs(res["y"].location - centre[1]) < 0.1 * d / 2 and abs(res["x"].location - centre[0]) < 0.1 * rres

    back = io.load(io.save(compressed, out / "demo_echo.nc"))
    io.save(image, out / "demo_image.nc")
    same = np.array_equal(back.data, compressed.data)
    print(f"saved {out / 'demo_echo.nc'} and {out / 'demo_image.nc'}: reload {'identical' if same else 'DIFFERENT'}")
    ok &= same
    try:
        from .. import plot

        plot.save_figure(plot.image_figure(image, floor_db=-50, title="Heremans 2009: nine points, back-projection"),
                         out / "demo_image.png")
        print(f"picture: {out / 'demo_image.png'}")
    except ImportError:
        print("matplotlib not installed: no picture (pip install 'clsas[plot]')")
    print("demo", "OK" if ok else "FAILED")
    return 0 if ok else 1
