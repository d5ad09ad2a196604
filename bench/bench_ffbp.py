"""Fast factorised back-projection against direct back-projection: effective rate (pixels x pulses / s).

The issue's configuration: 1024^2 pixels x 2048 pulses (``--quick``: 512^2 x 1024). Scene: a
monostatic sonar on a straight track 5 m above a seafloor of 4000 random complex scatterers
(150 kHz carrier, B = 20 kHz sampled at 25 kHz, 0.1 m transmit and receive elements, so the
beam's main lobe is 2 lambda / D = 0.2 rad and the along-track resolution D / 2 = 5 cm; pulses
every 2.5 cm = D / 4), simulated by clsas (exact delays, element directivity), range-compressed
and upsampled x 8 once; the image plane 40-60 m across track by half the track's length along it.

Cases, each timing ``clsas.backproject`` (linear, upsample=1 on the upsampled records) and
``clsas.ffbp`` (default tolerance) interleaved (direct, ffbp, direct, ...) after one warm-up
each, min and median, with the relative L2 difference of the two images:

- ``aperture``: both with ``aperture=0.2`` (the elements' main lobe, 2 lambda / D: the same
  hard integration-angle mask; ffbp's polar grids then cover only what each sub-aperture sees
  within it, which is where it saves most on a long track).
- ``full``: both over every pulse and angle (the pixels then sample the image far more coarsely
  than its resolution along track, which limits how far merging pays).

``--scan`` adds the aperture case's ratio for 512, 1024, 2048 and 4096 pulses (512^2 pixels, one
timed run each).

Measured 2026-11-23 after direct back-projection learnt to sum, with an aperture, only the
pulses that can see each tile (kernels/backprojection.cl PULSE_SPAN; 2-core AVX2 EPYC, PoCL 3.1,
quiet machine, load average < 1; direct / ffbp interleaved, 3 timed runs, median and best):
1024^2 x 2048 aperture 3.3x (3.3x), ffbp 0.88 s against direct 2.91 s (direct over every angle:
6.85 s, so the span saves it 2.4x), 3 levels of 2.9/2.5/2.4M polar samples, relative L2 0.054;
full 1.14x (1.36x), ffbp 6.0 s against 6.85 s, 4 levels, relative L2 0.0067. Quick (512^2 x
1024): aperture 1.9x, full 1.8x. Before that change (direct summing every pulse, masked: 17.1 s
at load 5.6-5.8) the aperture case measured 10.1x (10.7x) with the same ffbp.
Aperture case at 512^2 pixels for 512, 1024, 2048, 4096 pulses (one timed run each, against
the spanned direct): 2.1, 1.9, 1.5, 1.04x (relative L2 0.031, 0.048, 0.055, 0.060; 3, 2, 1, 1
levels; against the unspanned direct the same ffbp measured 2.4, 2.5, 4.4, 5.0x). On a fixed
512^2 grid the longer scene is sampled ever more coarsely along track, so the merges stop early
(at 2048 and 4096 pulses the leaves go straight to the pixels), while the spanned direct's cost
a pixel stays the beam's footprint: the ratio grows with the pixels, not with the pulses.
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np
from _harness import arguments, report

import clsas
from clsas import Array, Medium, Platform, PointTargets, PulseSchedule, Scenario, Waveform
from clsas.data import Grid
from clsas.image.backprojection import backproject
from clsas.image.ffbp import ffbp

F0, B, FS, UP, DEPTH = 150e3, 20e3, 25e3, 8, -5.0
# the two sonars: element length D (m; pulses every D / 4) and the image's ranges (m)
SONARS = {"narrow": {"element": 0.1, "ranges": (40.0, 60.0)}, "wide": {"element": 0.02, "ranges": (20.0, 40.0)}}


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


def interleaved(runs: dict, repeats: int) -> dict:
    """Wall times of each run, interleaved (A B A B ...), after one warm-up run each."""
    results = {name: run() for name, run in runs.items()}
    times = {name: [] for name in runs}
    for _ in range(repeats):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - start)
    return times, results


def main() -> None:
    scan = "--scan" in sys.argv
    if scan:
        sys.argv.remove("--scan")
    args = arguments(__doc__.splitlines()[0])
    n_pix, n_pulses = (512, 1024) if args.quick else (1024, 2048)
    repeats = args.repeats or 3
    # case: (sonar, options of both imagers)
    cases = {"wide": ("wide", {}), "aperture": ("narrow", {"aperture": 2 * 0.01 / SONARS["narrow"]["element"]}),
             "full": ("narrow", {})}
    sizes = [(n_pix, n_pulses, case, repeats) for case in cases]
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
        runs = {"direct": lambda: backproject(echo, grid, interp="linear", **kw, **options),
                "ffbp": lambda: ffbp(echo, grid, interp="linear", **kw, **options)}
        times, images = interleaved(runs, reps)
        ref = images["direct"].data
        err = float(np.linalg.norm(images["ffbp"].data - ref) / np.linalg.norm(ref))
        work = grid.size * pulses
        medians = {name: statistics.median(t) for name, t in times.items()}
        for name, t in times.items():
            extra = {"method": name, "case": case, "min_seconds": min(t), "rate_best": work / min(t), "runs": len(t)}
            if name == "ffbp":
                extra.update(ratio_median=medians["direct"] / medians["ffbp"],
                             ratio_best=min(times["direct"]) / min(t), rel_l2=err,
                             levels=images["ffbp"].provenance["levels"], first=images["ffbp"].provenance["first"],
                             oversampling=images["ffbp"].provenance["oversampling"],
                             polar_samples=images["ffbp"].provenance["polar_samples"])
            report(args, "ffbp", "opencl", {"pixels": grid.size, "pulses": pulses, "receivers": 1},
                   work / medians[name], "BP/s", medians[name], **extra)


if __name__ == "__main__":
    main()
