"""Echo synthesis throughput: in-pulse contributions per second (NumPy reference vs OpenCL kernel),
seafloor facets x pulses x receivers per second (raw and straight into the compressed domain),
and the size of intra-pulse Doppler for stationary scatterers.

1. ``echo``: one contribution = one scatterer added into one output sample inside its pulse, for
   one pulse and one receiver: n_scatterers x n_pulses x n_receivers x T fs. Scene: Kiang & Kiang
   2022 Table I sonar (A, B, sonobuoy C; T fs = 100 samples per pulse, and 400 at 4 F_r) and a
   submarine-sized cloud of scatterers (62 m x 8 m x 8 m around (1989, 0, -350) m) moving at
   (0, -4, 0) m/s. The NumPy reference runs on fewer pulses (its rate does not depend on the
   pulse count).
2. ``echo_seafloor``: Huang & Yang's 32-receiver sonar over a patch of sand 15 m below it, its
   speckle facets (clsas.scene.seafloor, 4 a resolution cell) as stationary point scatterers;
   raw, compressed="hamming" and compressed=True, timed interleaved (A B C A B C, one warm-up
   each), min and median; rate = facets x pulses x receivers per second. ``swath_estimate_s``:
   the facets the transmitter's beam reaches at one pulse over a 100 m x 60 m swath, x 256
   pulses x 32 receivers, divided by that rate (the launcher computes every facet's paths at
   every pulse: it does not yet skip facets outside a pulse's beam, so a whole-swath run costs
   more than this estimate).
3. ``intra_pulse``: a stationary point at the first null of Huang's transmitter beam, seen from
   the 2 m/s platform, with and without intra-pulse Doppler: the largest phase difference of
   the raw samples (rad) and the compressed peak's amplitude ratio and shift (samples).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from _harness import arguments, measure, report
from bench_dpca import interleaved

import clsas
from clsas.scene import presets
from clsas.scene.seafloor import Seafloor, generate
from clsas.scene.targets import PointTargets
from clsas.synthesis import simulate


def scene(n_scatterers: int, n_pulses: int):
    rng = np.random.default_rng(0)
    pos = np.array([1989.0, 0.0, -350.0]) + rng.uniform(-0.5, 0.5, (n_scatterers, 3)) * [8.0, 62.0, 8.0]
    target = PointTargets(pos, reflectivity=np.exp(2j * np.pi * rng.random(n_scatterers)), velocity=(0.0, -4.0, 0.0))
    return presets.kiang2022(n_pulses=n_pulses).replace(targets=(target,))


def contributions(args) -> None:
    n_scat = 10_000
    cases = {"opencl": 256 if not args.quick else 64, "numpy": 8 if not args.quick else 2}
    for oversample in (1, 4):
        for backend, n_pulses in cases.items():
            sc = scene(n_scat, n_pulses)
            sc = sc.replace(waveform=dataclasses.replace(sc.waveform, fs=oversample * sc.waveform.fs))
            wf = sc.waveform
            count = n_scat * n_pulses * sc.n_receivers * wf.duration * wf.fs
            seconds = measure(lambda: simulate(sc, backend=backend, progress=False),
                              repeats=args.repeats or (3 if backend == "opencl" else 1))
            report(args, "echo", backend, {"scatterers": n_scat, "pulses": n_pulses, "receivers": sc.n_receivers,
                                           "in_pulse_samples": int(round(wf.duration * wf.fs))},
                   count / seconds / 1e9, "G contributions/s", seconds, fs_hz=wf.fs)


ALTITUDE = 15.0


def seafloor_scene(across: float, along: float, n_pulses: int):
    """Huang's sonar over a sand patch [20, 20 + across] x [-along/2, along/2] m, 15 m below."""
    sc = presets.huang2022(n_pulses=n_pulses)
    floor = Seafloor((20.0, 20.0 + across, -along / 2, along / 2), -ALTITUDE, sediment="sand")
    facets = generate(floor, sc)
    return sc.replace(targets=(PointTargets(facets.positions, reflectivity=facets.refl),)), facets.count


def swath_facets_per_pulse() -> int:
    """Facets the beam reaches at the middle pulse of a 100 m (along) x 60 m (across) swath."""
    sc = presets.huang2022(n_pulses=256)
    floor = Seafloor((10.0, 70.0, -50.0, 50.0), -ALTITUDE, sediment="sand")
    facets = generate(floor, sc)
    tx = sc.tx_position(sc.eta[sc.eta.size // 2])
    return int(np.count_nonzero(facets.in_reach(tx))), facets.count


def seafloor(args) -> None:
    across, along, n_pulses = (4.0, 4.0, 4) if args.quick else (10.0, 8.0, 8)
    sc, n_facets = seafloor_scene(across, along, n_pulses)
    modes = {"raw": False, "compressed_hamming": "hamming", "compressed": True}
    echoes = {}

    def run(name, mode):
        def call():
            echoes[name] = simulate(sc, backend="opencl", progress=False, compressed=mode)
        return call

    timed = interleaved({name: run(name, mode) for name, mode in modes.items()}, repeats=args.repeats or 2)
    in_reach, swath = swath_facets_per_pulse()
    for name, (fastest, median) in timed.items():
        rate = n_facets * n_pulses * sc.n_receivers / median
        extra = {"min_seconds": fastest, "swath_facets": swath, "swath_facets_in_beam": in_reach,
                 "swath_estimate_s": in_reach * 256 * 32 / rate}
        if name != "raw":
            extra.update({k: float(v) for k, v in echoes[name].provenance["compressed"].items()
                          if k in ("taps", "discarded_db")})
        report(args, "echo_seafloor", "opencl", {"facets": n_facets, "pulses": n_pulses, "receivers": sc.n_receivers,
                                                 "mode": name},
               rate / 1e6, "M facet-pulse-receivers/s", median, **extra)


def intra_pulse(args) -> None:
    sc = presets.huang2022(n_pulses=3)
    wf = sc.waveform
    null = wf.wavelength(sc.medium) / sc.array.tx_length  # sin of the first null's angle
    r = 30.0
    point = PointTargets([r * np.sqrt(1 - null * null), r * null, 0.0])
    sc = sc.replace(targets=(point,))
    plain = simulate(sc, backend="numpy", progress=False, intra_pulse="none")
    doppler = simulate(sc, backend="numpy", progress=False, intra_pulse="all")
    level = 1e-3 * np.abs(plain.data).max()
    on = (np.abs(plain.data) > level) & (np.abs(doppler.data) > level)
    on &= np.roll(on, 2, axis=-1) & np.roll(on, -2, axis=-1)  # away from the pulse's edges
    phase = np.angle(doppler.data[on] * np.conj(plain.data[on]))
    a, b = (clsas.range_compress(e, upsample=8) for e in (plain, doppler))
    peaks = [clsas.metrics.point_response(x.data[0, 1], x.fast_time(0)) for x in (a, b)]
    report(args, "echo_intra_pulse", "numpy", {"range_m": r, "sin_squint": float(null), "speed_m_s": sc.platform.speed},
           float(np.max(np.abs(phase))), "rad (largest raw phase change)", 0.0,
           peak_ratio=float(abs(peaks[1].peak) / abs(peaks[0].peak)),
           peak_shift_samples=float((peaks[1].location - peaks[0].location) * wf.fs))


def main() -> None:
    args = arguments(__doc__.splitlines()[0])
    intra_pulse(args)
    seafloor(args)
    contributions(args)


if __name__ == "__main__":
    main()
