"""The ``clsas`` command (also ``python -m clsas``).

``clsas info``  prints the backend and the OpenCL device.
``clsas demo``  runs a short end-to-end check on this machine: the OpenCL helper kernels
against their NumPy twins, range compression of a point echo with its metrics, and a
save/load round trip; it writes its files into ``--out`` (default ``demo-output/``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np


def _info(_args) -> int:
    from . import backend

    print(json.dumps(backend.info(), indent=2))
    return 0


def _point_echo(scenario, delay: float):
    """One receiver, one pulse: the signal-model echo of a unit scatterer at ``delay`` (s)."""
    from .data import EchoData

    wf = scenario.waveform
    n = int(np.ceil(4 * wf.duration * wf.fs))
    t0 = delay - 2 * wf.duration
    tau = t0 + np.arange(n) / wf.fs
    samples = wf.baseband(tau - delay) * np.exp(-2j * np.pi * wf.f0 * delay)
    return EchoData(data=samples[None, None, :], eta=[0.0], t0=[t0], fs=wf.fs, tx_pos=[[0, 0, 0]],
                    rx_pos=[[[[0, 0, 0]]]], rx_tau=[[0.0]], waveform=wf, medium=scenario.medium,
                    receivers=("A",), provenance={"demo": "analytic point echo", "delay_s": delay})


def _demo(args) -> int:
    from . import backend, io, kernelmath, metrics
    from .image import range_compress
    from .scene import presets

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    info = backend.info()
    print("backend:", json.dumps(info))
    rng = np.random.default_rng(1)

    if info["resolved"] == "opencl":
        x = (rng.standard_normal(100_000) + 1j * rng.standard_normal(100_000)).astype(np.complex64)
        cycles = rng.uniform(-1e3, 1e3, x.size).astype(np.float32)
        gpu = kernelmath.rotate_phase(x, cycles, backend="opencl")
        ref = kernelmath.rotate_phase(x, cycles, backend="numpy")
        err = np.max(np.abs(gpu - ref))
        print(f"kernel rotate_phase (OpenCL vs NumPy, 1e5 values): max |error| = {err:.2e}")
        if err > 1e-5:
            print("FAILED: OpenCL helper kernel disagrees with NumPy", file=sys.stderr)
            return 1
    else:
        print("no OpenCL device: the NumPy reference path is used (run `make setup` to install PoCL)")

    # Kiang & Kiang 2022 Table I samples at F_r = B (critical sampling, which costs ~0.6 dB of
    # PSLR through aliasing of the chirp's spectral skirts); the demo samples at 2 B.
    scenario = presets.kiang2022(n_pulses=1)
    wf = dataclasses.replace(scenario.waveform, fs=2 * scenario.waveform.bandwidth)
    scenario = scenario.replace(waveform=wf)
    delay = 2 * 2000.0 / scenario.medium.sound_speed + 0.37 / wf.fs  # 2 km, off the sample grid
    echo = _point_echo(scenario, delay)
    compressed = range_compress(echo, upsample=4)
    cut = compressed.data[0, 0]
    pr = metrics.point_response(cut, compressed.fast_time(0), upsample=16)
    print(f"range compression, {wf.f0/1e3:.0f} kHz, B = {wf.bandwidth/1e3:.0f} kHz, T = {wf.duration*1e3:.1f} ms:")
    print(f"  peak at {pr.location*1e3:.6f} ms, true {delay*1e3:.6f} ms "
          f"(error {(pr.location - delay) * wf.fs:+.4f} samples)")
    print(f"  IRW {pr.irw * wf.bandwidth:.3f}/B (theory 0.886/B), PSLR {pr.pslr_db:.2f} dB (theory -13.26), "
          f"ISLR {pr.islr_db:.2f} dB, |peak| {abs(pr.peak):.4f} (amplitude 1)")

    path = io.save(compressed, out / "demo_compressed.h5")
    back = io.load(path)
    same = np.array_equal(back.data, compressed.data) and back.provenance == compressed.provenance
    print(f"saved and reloaded {path}: {'identical' if same else 'DIFFERENT'}")
    try:
        from . import plot

        ax = plot.plot_cut((compressed.fast_time(0) - delay) * 1e3, cut, label="range-compressed echo")
        ax.set_xlabel("fast time - true delay (ms)")
        ax.set_xlim(-10 / wf.bandwidth * 1e3, 10 / wf.bandwidth * 1e3)
        plot.save_figure(ax, out / "demo_range_cut.png")
        print(f"plot: {out / 'demo_range_cut.png'}")
    except ImportError:
        print("matplotlib not installed: no plot (pip install 'clsas[plot]')")
    ok = same and abs(pr.location - delay) * wf.fs < 0.05 and abs(pr.pslr_db + 13.26) < 0.5
    print("demo", "OK" if ok else "FAILED")
    return 0 if ok else 1


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="clsas", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("info", help="backend and OpenCL device").set_defaults(run=_info)
    demo = sub.add_parser("demo", help="end-to-end check on this machine")
    demo.add_argument("--out", default="demo-output", help="folder for the demo's files")
    demo.set_defaults(run=_demo)
    args = parser.parse_args(argv)
    return args.run(args)
