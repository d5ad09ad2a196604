"""Fast factorised back-projection against direct back-projection: effective rate (pixels x pulses / s).

The issue's configuration: 1024^2 pixels x 2048 pulses (``--quick``: 512^2 x 1024). Scenes: a
monostatic sonar on a straight track 5 m above a seafloor of 4000 random complex scatterers
(150 kHz carrier, B = 20 kHz sampled at 25 kHz, transmit and receive elements of length D,
pulses every D / 4), simulated by clsas (exact delays, element directivity), range-compressed
and upsampled x 8 once; the image plane spans the ranges below by half the track's length along
it. Two sonars (SONARS):

- ``wide``: D = 0.02 m, a 1 rad beam, ranges 20-40 m. Every pulse sees every pixel, and the
  pixels (5 mm along track, 2 cm across) sample the along-track resolution at the nearest range
  (about 1 cm over the 10 m track): the regime the issue's O(N^3) premise describes.
- ``narrow``: D = 0.1 m, a 0.2 rad main lobe (2 lambda / D), ranges 40-60 m: each pixel is seen
  by about a fifth of a 51 m track.

Cases, each timing ``clsas.backproject`` (linear, upsample=1 on the upsampled records) and
``clsas.ffbp`` (default tolerance) interleaved (direct, ffbp, direct, ...) after one warm-up
each, min and median, with the relative L2 difference of the two images:

- ``wide``: the wide sonar, every pulse and angle.
- ``aperture``: the narrow sonar, both with ``aperture=0.2`` (the same hard integration-angle
  mask). Direct back-projection then sums for each tile only the pulses that can see it
  (kernels/bp_tile.cl PULSE_SPAN), so its cost a pixel is the beam's footprint (~400
  pulses), not the track; ffbp's polar grids cover only what each sub-aperture sees.
- ``full``: the narrow sonar over every pulse and angle (the pixels then sample the image far
  more coarsely than its resolution along track, which limits how far merging pays).

Fairness (what each imager keeps between calls). ``clsas.backproject`` keeps, per Grid, only its
tile plan (the tiling's slot order, which depends on the grid, the carrier and the sound speed, not
on the echo's geometry); its records and its per-(tile, pulse) references are made in every call,
so a call on a new geometry costs what a call on the same one does. ``clsas.ffbp`` keeps, per Grid,
its Scene (skeleton and margin: the grid's alone, as the tile plan) and, per geometry, its last
tree and that tree's first-stage layouts (clsas/image/ffbp/reuse.py), which only an echo of the
same geometry can use. So every timed round gets a new geometry: the track (transmitter and
receivers) moved SHIFT across track from the round before (the records unchanged), and

- ``direct``: ``clsas.backproject`` on the round's echo (its grid's tile plan kept, as always);
- ``ffbp`` (cold, the headline ratio): ``clsas.ffbp`` on the round's echo, the first call on
  this geometry: same grid (its Scene kept), the tree planned and the first stage laid out anew;
- ``ffbp_warm``: ``clsas.ffbp`` on the same echo again: its tree and layouts kept (imaging many
  echoes of one geometry onto one grid).

Both ratios, cold and warm, are against the same direct runs, and are printed side by side at
the end of each case (wall and CPU, min and median).

``--factors`` times ``clsas.ffbp`` with factor=2 as well (a third run in the interleaving; the
default merges 4 children at a time). ``--big`` adds the issue's large case, the wide sonar at 2048^2 pixels x 4096 pulses (2 timed
runs each after a warm-up; direct back-projection takes about a minute a run on 2 cores, so the
case costs about 5 minutes). ``--scan`` adds one timed run each of the wide case for 512, 1024, 2048 and 4096 pulses on
square grids of half as many pixels a side (the aperture and the image grow together), and of
the aperture case for the same pulses on a fixed 512^2 grid.

``--stages`` adds two more ffbp calls a case, after the timed ones (a new geometry: cold, then
warm), with the device's queue finished around each stage, and reports the process CPU seconds of
each (``stages_cpu``: the tree's planning, the leaves (their batches and demodulation; of which
``leaf_bp_tile``, back-projection's kernel itself), the merges, the final stage, and the rest),
the cost breakdown that says where a case's time goes, and from it the CPU ns of a leaf's
lane-pulse, of a leaf sample's other work and of a merge interpolation (``op_ns``, :func:`op_costs`:
the ratios tree.py's leaf-length estimate takes).

Every run is timed twice: wall time and the process's CPU time (``time.process_time``: PoCL's
worker threads run in this process, so it is the CPU-seconds the call used). On a loaded machine the
wall ratios move with whatever else runs; the CPU ratios (``cpu_ratio_median``, ``cpu_ratio_best``)
move much less, so both are reported.

Each row carries the machine it was measured on (bench/_harness.py); the figures live in the
JSON output (``--json``; ``bench/run_all.py`` collects them), not here.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import pathlib
import statistics
import subprocess
import sys
import time

import numpy as np
from _harness import arguments, report

import clsas
from clsas import Array, Medium, Platform, PointTargets, PulseSchedule, Scenario, Waveform, opencl
from clsas.model import Grid
from clsas.image.backprojection import TileKernel, backproject
from clsas.image.ffbp import ffbp
from clsas.image.ffbp.leaves import FirstStage
from clsas.image.ffbp.store import DeviceStore

ffbp_package = importlib.import_module("clsas.image.ffbp")  # the package (clsas.image.ffbp is also the function)

F0, B, FS, UP, DEPTH = 150e3, 20e3, 25e3, 8, -5.0
# the two sonars: element length D (m; pulses every D / 4) and the image's ranges (m)
SONARS = {"narrow": {"element": 0.1, "ranges": (40.0, 60.0)}, "wide": {"element": 0.02, "ranges": (20.0, 40.0)}}
SHIFT = 0.002  # m: the track moves this far across track (x) a round: a new geometry for every timed round


def _commit() -> str:
    """The commit measured (both imagers come from it), with '+dirty' for uncommitted changes."""
    here = pathlib.Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=here, capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=here,
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


COMMIT = _commit()


def scene(n_pulses: int, n_pixels: int, sonar: str = "narrow"):
    """The range-compressed (upsampled x UP) echo of the speckle seafloor seen by ``sonar`` and the image plane."""
    element, (near, far) = SONARS[sonar]["element"], SONARS[sonar]["ranges"]
    step = element / 4
    half = n_pulses * step / 4
    rng = np.random.default_rng(0)
    n = 4000
    pos = np.column_stack([rng.uniform(near, far, n), rng.uniform(-half, half, n), np.full(n, DEPTH)])
    sc = Scenario(medium=Medium(1500.0), waveform=Waveform(f0=F0, bandwidth=B, duration=5e-3, fs=FS),
                  platform=Platform(speed=1.0),
                  array=Array(rx_offsets=[[0.0, 0.0, 0.0]], tx_length=element, rx_length=element),
                  schedule=PulseSchedule(prf=1.0 / step, n_pulses=n_pulses),
                  targets=(PointTargets(pos, reflectivity=rng.standard_normal(n) + 1j * rng.standard_normal(n)),))
    echo = clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False), upsample=UP)
    grid = Grid.plane(np.linspace(near, far, n_pixels), np.linspace(-half, half, n_pixels), DEPTH)
    return echo, grid


def moved(echo, k: int):
    """``echo`` with its track (transmitter and receivers) moved k x SHIFT across track: a new
    geometry (the records unchanged; the image is defocused a little, alike for both imagers)."""
    if k == 0:
        return echo
    d = np.array([k * SHIFT, 0.0, 0.0])
    return echo.replace(tx_pos=echo.tx_pos + d, rx_pos=echo.rx_pos + d)


def interleaved(runs: dict, repeats: int, echo) -> tuple[dict, dict, dict]:
    """Wall times and process CPU times of each run ``run(e)``, interleaved (A B A B ...) after one
    warm-up round, and the warm-up's results. Round k gives every run the echo moved k x SHIFT
    (:func:`moved`, made before the round and not timed): a new geometry a round."""
    times, cpu, results = {name: [] for name in runs}, {name: [] for name in runs}, {}
    for k in range(repeats + 1):
        e = moved(echo, k)
        for name, run in runs.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            out = run(e)
            if k == 0:
                results[name] = out
                continue
            times[name].append(time.perf_counter() - start)
            cpu[name].append(time.process_time() - start_cpu)
    return times, cpu, results


def summary(case: str, times: dict, cpu: dict) -> str:
    """One line: ffbp's cold and warm ratios to direct, wall and CPU, min (best against best) and median."""
    parts = []
    for name, label in (("ffbp", "cold"), ("ffbp_warm", "warm")):
        if name in times:
            wall = (min(times["direct"]) / min(times[name]),
                    statistics.median(times["direct"]) / statistics.median(times[name]))
            proc = (min(cpu["direct"]) / min(cpu[name]), statistics.median(cpu["direct"]) / statistics.median(cpu[name]))
            parts.append(f"{label}: wall {wall[0]:.2f}x / {wall[1]:.2f}x, CPU {proc[0]:.2f}x / {proc[1]:.2f}x")
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    return f"ffbp {case} ratios to direct (min / median): " + "; ".join(parts) + f"  [load {load}]"


@contextlib.contextmanager
def _stage_clock(totals: dict):
    """Within the block, ffbp's stages add their process CPU seconds to ``totals`` (the device's
    queue finished before and after each, so that its work is counted where it was enqueued)."""
    queue = opencl.runtime().queue
    targets = [("plan", ffbp_package, "plan"), ("leaves", FirstStage, "image_into"), ("leaves", DeviceStore, "flush"),
               ("leaf_bp_tile", TileKernel, "launch"), ("merges", DeviceStore, "merge"),
               ("final", DeviceStore, "final")]
    saved = [getattr(owner, attr) for _, owner, attr in targets]

    def clocked(name, original):
        def run(*args, **kwargs):
            queue.finish()
            start = time.process_time()
            try:
                return original(*args, **kwargs)
            finally:
                queue.finish()
                totals[name] = totals.get(name, 0.0) + time.process_time() - start
        return run

    for (name, owner, attr), original in zip(targets, saved):
        setattr(owner, attr, clocked(name, original))
    try:
        yield totals
    finally:
        for (_, owner, attr), original in zip(targets, saved):
            setattr(owner, attr, original)


def stages(run) -> dict:
    """Process CPU seconds of each stage of one call ``run()`` (:func:`_stage_clock`) and ``rest``
    (the call's CPU time outside them: checks, the walk, the result's copy)."""
    totals = {}
    start = time.process_time()
    with _stage_clock(totals):
        run()
    total = time.process_time() - start
    parts = {k: totals.get(k, 0.0) for k in ("plan", "leaves", "leaf_bp_tile", "merges", "final")}
    parts["rest"] = total - parts["plan"] - parts["leaves"] - parts["merges"] - parts["final"]
    parts["total"] = total
    return {k: round(v, 4) for k, v in parts.items()}


def op_costs(parts: dict, provenance: dict) -> dict:
    """CPU ns of ffbp's operations from a call's stages (:func:`stages`) and its tree (the image's
    provenance; one receiver): ``leaf_lane_pulse``, bp_tile's a leaf sample and pulse;
    ``leaf_sample``, the rest of the leaves' a sample (fields, demodulation, batches);
    ``merge_interpolation``, a merge's an (output sample, child) pair; and the first two over the
    third (``leaf_pulse_to_merge``, ``leaf_sample_to_merge``: tree.py's LEAF_PULSE_COST and
    LEAF_SAMPLE_COST measure these). The leaves' samples are the tree's, before the aperture's cut
    (leaves.py), so with an ``aperture`` the leaves' figures are low by the samples cut."""
    samples, first, factor = provenance["polar_samples"], provenance["first"], provenance["factor"]
    out = {"leaf_lane_pulse": 1e9 * parts["leaf_bp_tile"] / (samples[0] * first),
           "leaf_sample": 1e9 * (parts["leaves"] - parts["leaf_bp_tile"]) / samples[0]}
    if len(samples) > 1:
        out["merge_interpolation"] = 1e9 * parts["merges"] / (factor * sum(samples[1:]))
        out["leaf_pulse_to_merge"] = out["leaf_lane_pulse"] / out["merge_interpolation"]
        out["leaf_sample_to_merge"] = out["leaf_sample"] / out["merge_interpolation"]
    return {k: round(v, 4) for k, v in out.items()}


def main() -> None:
    flags = {flag: flag in sys.argv for flag in ("--scan", "--big", "--factors", "--stages")}
    sys.argv = [a for a in sys.argv if a not in flags]
    scan, big = flags["--scan"], flags["--big"]
    args = arguments(__doc__.splitlines()[0])
    n_pix, n_pulses = (512, 1024) if args.quick else (1024, 2048)
    repeats = args.repeats or 3
    # case: (sonar, options of both imagers)
    cases = {"wide": ("wide", {}), "aperture": ("narrow", {"aperture": 2 * 0.01 / SONARS["narrow"]["element"]}),
             "full": ("narrow", {})}
    sizes = [(n_pix, n_pulses, case, repeats) for case in cases]
    if big:
        sizes.append((2048, 4096, "wide", 2))
    if scan:
        sizes += [(n // 2, n, "wide", 1) for n in (512, 1024, 2048, 4096)]
        sizes += [(512, n, "aperture", 1) for n in (512, 1024, 2048, 4096)]
    echoes = {}
    for pix, pulses, case, reps in sizes:
        sonar, options = cases[case]
        if (pulses, pix, sonar) not in echoes:
            echoes = {(pulses, pix, sonar): scene(pulses, pix, sonar)}
        echo, grid = echoes[(pulses, pix, sonar)]
        kw = dict(backend="opencl", upsample=1, progress=False)
        runs = {"direct": lambda e: backproject(e, grid, interp="linear", **kw, **options),
                "ffbp": lambda e: ffbp(e, grid, interp="linear", **kw, **options),
                "ffbp_warm": lambda e: ffbp(e, grid, interp="linear", **kw, **options)}
        if flags["--factors"]:
            runs["ffbp_factor2"] = lambda e: ffbp(e, grid, interp="linear", factor=2, **kw, **options)
        times, cpu, images = interleaved(runs, reps, echo)
        ref = images["direct"].data
        work = grid.size * pulses
        medians = {name: statistics.median(t) for name, t in times.items()}
        cpu_medians = {name: statistics.median(t) for name, t in cpu.items()}
        for name, t in times.items():
            extra = {"method": name, "case": case, "min_seconds": min(t), "median_seconds": medians[name],
                     "cpu_min_seconds": min(cpu[name]), "cpu_median_seconds": cpu_medians[name],
                     "rate_best": work / min(t), "runs": len(t), "commit": COMMIT}
            if name != "direct":
                made = images[name]
                extra.update(ratio_median=medians["direct"] / medians[name],
                             ratio_best=min(times["direct"]) / min(t),
                             cpu_ratio_median=cpu_medians["direct"] / cpu_medians[name],
                             cpu_ratio_best=min(cpu["direct"]) / min(cpu[name]),
                             rel_l2=float(np.linalg.norm(made.data - ref) / np.linalg.norm(ref)),
                             factor=made.provenance["factor"], levels=made.provenance["levels"],
                             first=made.provenance["first"], oversampling=made.provenance["oversampling"],
                             polar_samples=made.provenance["polar_samples"])
                if flags["--stages"] and name in ("ffbp", "ffbp_warm"):  # a geometry not seen yet: cold, then warm
                    e = moved(echo, reps + 1)
                    extra["stages_cpu"] = stages(lambda: runs[name](e))
                    extra["op_ns"] = op_costs(extra["stages_cpu"], made.provenance)
            report(args, "ffbp", "opencl", {"pixels": grid.size, "pulses": pulses, "receivers": 1},
                   work / medians[name], "BP/s", medians[name], **extra)
        print(summary(case, times, cpu), file=sys.stderr if args.json else sys.stdout, flush=True)


if __name__ == "__main__":
    main()
