"""Hull occlusion throughput: paths answered per second by PathWeights on the Kiang case 8
submarine ("useful rays": the transmitter leg of every facing facet and each receiver's leg of
every lit, facing facet; back-facing facets need no ray), with visibility reused between nearby
pulses (default tolerance) and with every useful ray cast, two threads over pulse blocks; rays
actually cast reported beside; Embree (embreex) vs the Moller-Trumbore reference, direct embreex
vs trimesh's Embree interface, and the share of occlusion in simulating Kiang case 8.
"""

from __future__ import annotations

import time

import numpy as np
from _harness import arguments, measure, report

import clsas
from clsas.scene import presets
from clsas.scene.hulls import sphere
from clsas.synthesis.echo import pipeline
from clsas.synthesis.occlusion import PathWeights, RayCaster


def rays(rng, n):
    origins = rng.uniform(-3, 3, (n, 3))
    d = rng.normal(size=(n, 3))
    return origins, d / np.linalg.norm(d, axis=1, keepdims=True), rng.uniform(0.5, 6.0, n)


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    n_pulses = 32 if args.quick else 256
    scene = presets.kiang2022_case(8, n_pulses=n_pulses, max_facet=0.6 if not args.quick else 0.9)
    facets = scene.targets[0].n_facets
    for tolerance in (PathWeights(scene).reuse_tolerance, 0.0):
        weights = PathWeights(scene, reuse_tolerance=tolerance)
        caster = weights.parts[0][3]
        weights(slice(None))  # warm-up, and the counts of one run
        queries, cast = caster.queries, caster.rays_cast
        seconds = measure(lambda: weights(slice(None)), repeats=args.repeats or 3, warmup=0)
        report(args, "occlusion", "embree", {"facets": facets, "pulses": n_pulses, "receivers": 3},
               queries / seconds / 1e6, "M useful rays/s", seconds, useful_rays=queries, rays_cast=cast,
               reuse_tolerance_rad=tolerance, threads=2,
               case="PathWeights, Kiang case 8 submarine: useful rays answered (cast or reused) per second")

    rng = np.random.default_rng(0)
    small = sphere(1.0, 2)  # 320 facets: the brute-force reference's scale
    o, d, t = rays(rng, 20_000)
    for method in ("embree", "reference"):
        rc = RayCaster(small, method)
        seconds = measure(lambda: rc.occluded(o, d, t), repeats=args.repeats or 3)
        report(args, "occlusion", "numpy" if method == "reference" else "embree",
               {"facets": len(small.faces), "rays": len(o)}, len(o) / seconds / 1e6, "M rays/s", seconds,
               case=f"{method} occlusion query, one thread")

    from trimesh.ray.ray_pyembree import RayMeshIntersector

    hull = scene.targets[0].mesh
    o, d, t = rays(rng, 1_000_000 if not args.quick else 200_000)
    o = o * 10
    direct = RayCaster(hull)
    seconds = measure(lambda: direct.occluded(o, d, np.full(len(o), 1e3)), repeats=args.repeats or 3)
    report(args, "occlusion", "embree", {"facets": len(hull.faces), "rays": len(o)}, len(o) / seconds / 1e6,
           "M rays/s", seconds, case="embreex directly (occluded query), one thread")
    via_trimesh = RayMeshIntersector(hull)
    seconds = measure(lambda: via_trimesh.intersects_any(o, d), repeats=args.repeats or 3)
    report(args, "occlusion", "embree", {"facets": len(hull.faces), "rays": len(o)}, len(o) / seconds / 1e6,
           "M rays/s", seconds, case="trimesh RayMeshIntersector.intersects_any, one thread")

    case8 = presets.kiang2022_case(8, n_pulses=256 if not args.quick else 32)
    inside = _TimedPathWeights.seconds
    clsas.simulate(case8, backend="opencl", progress=False)  # warm-up: kernel builds
    pipeline.PathWeights = _TimedPathWeights  # time the weights simulate() itself asks for
    try:
        inside.clear()
        repeats = args.repeats or 3
        total = measure(lambda: clsas.simulate(case8, backend="opencl", progress=False), repeats=repeats, warmup=0)
    finally:
        pipeline.PathWeights = PathWeights
    occl = sum(inside) / repeats
    report(args, "occlusion", "opencl", {"facets": case8.targets[0].n_facets, "pulses": case8.eta.size,
                                          "receivers": 3}, occl / total, "share of simulate time", total,
           occlusion_seconds=occl, calls_per_simulate=len(inside) // repeats,
           occlusion_per_synthesis_second=occl / (total - occl),  # against the rest of simulate()
           case="Kiang case 8: time in PathWeights calls / whole simulate time (warm, median)")


class _TimedPathWeights(PathWeights):
    """PathWeights that records the wall time of each call (for the share of simulate time)."""

    seconds: list = []

    def __call__(self, pulses):
        start = time.perf_counter()
        try:
            return super().__call__(pulses)
        finally:
            self.seconds.append(time.perf_counter() - start)

if __name__ == "__main__":
    main()
