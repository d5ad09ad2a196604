"""Seafloor throughput: facet generation (facets/s), the seafloor's path weights on OpenCL against
their NumPy twin (facets x pulses x receivers per second, interleaved A B A B), the shadow pass
(rays cast per second on the mine-like scene), and the Heremans-resolution swath (100 m along
track x 60 m across, 256 pulses, 15 receivers: facets, weights, and the echo synthesis when
clsas.simulate can synthesize straight into the range-compressed domain).

Every row reports min and median over the repeats and the load average when it ran.
"""

from __future__ import annotations

import inspect
import os
import statistics
import time

import numpy as np
from _harness import arguments, report

import clsas
from clsas.scene import presets
from clsas.scene.seafloor import Seafloor, generate
from clsas.synthesis.occlusion import PathWeights


def timed(run) -> float:
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


def interleaved(runs: dict, repeats: int) -> dict:
    """{name: [seconds...]}: the runs taken in turn (A B A B ...), after one warm-up each."""
    for run in runs.values():
        run()
    times = {name: [] for name in runs}
    for _ in range(repeats):
        for name, run in runs.items():
            times[name].append(timed(run))
    return times


def spread(seconds: list) -> dict:
    return {"min_s": min(seconds), "median_s": statistics.median(seconds), "load": os.getloadavg()[0]}


def swath(n_pulses: int, along: float, across: tuple) -> clsas.Scenario:
    """The Heremans sonar over a flat sand swath ``along`` m long (centred on y = 0) between the
    ground ranges ``across`` (m), 15 m below."""
    scene = presets.heremans2009(n_pulses=n_pulses)
    return scene.replace(seafloor=Seafloor((across[0], across[1], -along / 2, along / 2), -15.0, sediment="sand"))


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    repeats = args.repeats or 3
    along, across, pulses = (20.0, (80.0, 100.0), 32) if args.quick else (100.0, (40.0, 100.0), 256)

    scene = swath(pulses, along, across)
    generate.cache_clear()
    seconds = [timed(lambda: (generate.cache_clear(), generate(scene.seafloor, scene))) for _ in range(repeats)]
    facets = generate(scene.seafloor, scene)
    report(args, "seafloor", "numpy", {"facets": facets.count, "area_m2": along * (across[1] - across[0])},
           facets.count / statistics.median(seconds), "facets/s", statistics.median(seconds), **spread(seconds),
           case="facet generation (counter-based draws, heights, normals, sorted by y)")

    # the path weights: OpenCL kernel against its NumPy twin, a few pulses, interleaved
    n_rx = scene.n_receivers
    block = scene.eta[pulses // 2: pulses // 2 + (2 if args.quick else 4)]
    weights = {backend: PathWeights(scene, backend=backend).seafloor for backend in ("opencl", "numpy")}
    out = np.zeros((n_rx, block.size, facets.count))

    def fill(backend):
        return lambda: weights[backend].fill(block, out)

    times = interleaved({"opencl": fill("opencl"), "numpy": fill("numpy")}, repeats)
    paths = n_rx * block.size * facets.count
    for backend, secs in times.items():
        report(args, "seafloor", backend, {"facets": facets.count, "pulses": block.size, "receivers": n_rx},
               paths / min(secs), "paths/s", statistics.median(secs), **spread(secs),
               case="seafloor path weights (reach, facing, the law at the bisector): facets x pulses x receivers")
    ratio = min(times["numpy"]) / min(times["opencl"])
    print(f"# weights: OpenCL / NumPy = {ratio:.1f}x (min), load {os.getloadavg()[0]:.1f}", flush=True)

    # the shadow pass on the mine-like scene (rippled sand, two objects)
    mines = presets.mine_scene(n_pulses=32 if args.quick else 320)
    shadow = PathWeights(mines, backend="opencl")
    eta = mines.eta[mines.eta.size // 2: mines.eta.size // 2 + 8]
    buf = np.zeros((1, eta.size, shadow.seafloor.count))
    shadow.seafloor.fill(eta, buf)
    before = shadow.seafloor.rays_cast
    secs = [timed(lambda: shadow.seafloor.fill(eta, buf)) for _ in range(repeats)]
    rays = (shadow.seafloor.rays_cast - before) / repeats
    report(args, "seafloor", "embree", {"facets": shadow.seafloor.count, "pulses": eta.size},
           shadow.seafloor.count * eta.size / statistics.median(secs), "paths/s", statistics.median(secs),
           **spread(secs), rays_per_pulse=rays / eta.size, rays_per_s=rays / statistics.median(secs),
           case="mine scene seafloor weights with shadows (ripples, cylinder, cone): paths/s and rays cast")

    # the whole swath
    compressed = "compressed" in inspect.signature(clsas.simulate).parameters
    start = time.perf_counter()
    if compressed:
        generate.cache_clear()
        clsas.simulate(scene, compressed=True, progress=False)
        what = "facets + weights + compressed synthesis (spreading, absorption, bottom bounce: the defaults)"
    else:
        paths = PathWeights(scene)
        for s in range(pulses):  # one pulse at a time: (15, 1, facets) float64 is ~0.35 GB at full size
            paths(slice(s, s + 1))
        what = "facets + weights (no compressed synthesis in clsas.simulate)"
    total = time.perf_counter() - start
    work = facets.count * pulses * n_rx
    report(args, "seafloor", "opencl", {"facets": facets.count, "pulses": pulses, "receivers": n_rx,
                                        "swath_m": [along, across[1] - across[0]]},
           work / total, "facets x pulses x receivers /s", total, load=os.getloadavg()[0], case=f"swath: {what}")


if __name__ == "__main__":
    main()
