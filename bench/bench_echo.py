"""Echo synthesis throughput: in-pulse contributions per second (NumPy reference vs OpenCL kernel),
seafloor facets x pulses x receivers per second (raw and straight into the compressed domain),
and the size of intra-pulse Doppler for stationary scatterers.

1. ``echo``: one contribution = one scatterer added into one output sample inside its pulse, for
   one pulse and one receiver: n_scatterers x n_pulses x n_receivers x T fs. Scene: Kiang & Kiang
   2022 Table I sonar (A, B, sonobuoy C; T fs = 100 samples per pulse, and 400 at 4 F_r) and a
   submarine-sized cloud of scatterers (62 m x 8 m x 8 m around (1989, 0, -350) m) moving at
   (0, -4, 0) m/s. The NumPy reference runs on fewer pulses (its rate does not depend on the
   pulse count).
2. ``echo_seafloor``: Heremans's 15-receiver sonar over a 100 m (along) x 60 m (across, ground
   range 40-100 m) sand swath 15 m below (clsas.simulate's defaults: speckle facets 4 a
   resolution cell, spreading, absorption; the seabed bounces are dark for facets and pruned);
   the middle 8 pulses (2 with --quick) of the track, raw and compressed=True each by the direct
   and the grid accumulation (old and new: clsas/synthesis/echo/grid.py; the grid route's OpenCL
   synthesis runs in one pass), and compressed="hamming", timed interleaved (A B C D E A B C D E,
   one warm-up each), min and median, with the load average, and the route each compressed mode
   took (its taps, or the raw echo then the matched filter, clsas/synthesis/echo/compressed.py); rate = facets in the beam's reach x pulses x receivers per second (the facets
   out of a pulse's reach carry no echo and are skipped). ``swath_estimate_s``: the whole swath
   at 256 pulses (its facets in reach x pulses x receivers) divided by that rate: an
   extrapolation from the measured middle pulses, not a run of the whole swath.
3. ``intra_pulse``: a stationary point at the first null of Huang's transmitter beam, seen from
   the 2 m/s platform, with and without intra-pulse Doppler: the largest phase difference of
   the raw samples (rad) and the compressed peak's amplitude ratio and shift (samples).
"""

from __future__ import annotations

import dataclasses
import os

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
SWATH = (40.0, 100.0, -50.0, 50.0)  # m: 60 m across (ground range 40-100 m), 100 m along track
SWATH_PULSES = 256


def swath_scene(n_pulses: int):
    """Heremans's sonar (15 receivers) over the sand swath ``SWATH``, 15 m below, ``n_pulses``
    centred on the swath's middle."""
    return presets.heremans2009(n_pulses=n_pulses).replace(seafloor=Seafloor(SWATH, -ALTITUDE, sediment="sand"))


def paths_in_reach(sc, every: int = 1) -> float:
    """Facets x pulses x receivers the beam reaches (the synthesis's real work: the other facets
    carry no echo at that pulse), counted on every ``every``-th pulse and scaled."""
    facets = generate(sc.seafloor, sc)
    tx = sc.tx_position(sc.eta[::every])
    reached = sum(int(np.count_nonzero(facets.in_reach(t))) for t in tx)
    return reached * sc.eta.size / tx.shape[0] * sc.n_receivers


def seafloor(args) -> None:
    """The swath: a measured fraction (the middle ``n_pulses`` pulses: the facets their beam reaches)
    and the whole swath's time extrapolated from its rate (an estimate: the rate of the middle
    pulses applied to the whole swath's paths in reach)."""
    n_pulses = 2 if args.quick else 8
    sc = swath_scene(n_pulses)
    work = paths_in_reach(sc)
    whole = swath_scene(SWATH_PULSES)
    whole_work = paths_in_reach(whole, every=8)
    whole_facets = generate(whole.seafloor, whole).count
    modes = {"raw_direct": (False, "direct"), "raw_grid": (False, "grid"), "compressed_direct": (True, "direct"),
             "compressed_grid": (True, "grid"), "compressed_hamming": ("hamming", "auto")}
    echoes = {}

    def run(name, mode):
        def call():
            echoes[name] = simulate(sc, backend="opencl", progress=False, compressed=mode[0], accumulation=mode[1])
        return call

    timed = interleaved({name: run(name, mode) for name, mode in modes.items()}, repeats=args.repeats or 2)
    for name, (fastest, median) in timed.items():
        rate = work / median
        extra = {"min_seconds": fastest, "paths_in_reach": work, "load": os.getloadavg()[0],
                 "swath_m": [SWATH[3] - SWATH[2], SWATH[1] - SWATH[0]], "swath_facets": whole_facets,
                 "swath_pulses": SWATH_PULSES, "swath_paths_in_reach": whole_work,
                 "swath_estimate_s": whole_work / rate,
                 "case": f"Heremans swath, middle {n_pulses} pulses measured; swath_estimate_s extrapolated"}
        extra["accumulation"] = echoes[name].provenance["accumulation"]
        if name.startswith("compressed"):
            how = echoes[name].provenance["compressed"]
            extra.update(route=how["route"], taps=how["taps"], discarded_db=how["discarded_db"])
        report(args, "echo_seafloor", "opencl", {"facets": echoes[name].provenance["n_scatterers"],
                                                 "pulses": n_pulses, "receivers": sc.n_receivers, "mode": name},
               rate / 1e6, "M facet-pulse-receivers/s (in reach)", median, **extra)


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
