"""The records the kernels of ``kernels/echo_paths.cl`` and ``echo_accumulate.cl`` read and write, declared once here
(:mod:`clsas.cstruct`): a pulse, a receiver, the launch's parameters, a path kind's bounces (legs),
a scatterer's fields (structure of arrays) and a path (echo centre, amplitude, own chirp)."""

from __future__ import annotations

import numpy as np

from ... import geometry
from ...cstruct import declare_all, record_dtype
from .physics import Physics

CHUNK_SCATTERERS = 16  # paths per bounds chunk in the OpenCL accumulation
ROWS = 8  # 16-sample rows per work-item of the OpenCL accumulation
BOTTOM_TABLE = 1025  # entries of the seabed's reflection table, sin(grazing) in [0, 1]
MAX_BOUNCES = 2  # per leg
UNHEARD = 1 << 30  # kernels/echo_reach.h: the start sample of a path that carries no echo
# the records echo_paths reads (kernels/echo_paths.cl): a pulse, a receiver, the launch's parameters and
# the path kind's bounces
PULSE = record_dtype([("tx", "f8", 3), ("eta", "f8"), ("tx_axis", "f8", 3), ("tx_vel", "f8", 3)])  # m, s, 1, m/s
RECEIVER = record_dtype([("t0_fs", "f8"), ("length", "f8")])  # window start in samples, element length m
PARAMS = record_dtype([("c", "f8"), ("f0", "f8"), ("fs", "f8"), ("wavelength", "f8"), ("tx_length", "f8"),
                       ("dtau", "f8"), ("chirp_rate", "f8"), ("duration", "f8"), ("abs_a0", "f8"),
                       ("abs_a1", "f8"), ("abs_a2", "f8")])  # m/s, Hz, Hz, m, m, s, Hz/s, s, Np/m (/Hz, /Hz^2)
LEGS = record_dtype([("out_normal", "f8", 3 * MAX_BOUNCES), ("back_normal", "f8", 3 * MAX_BOUNCES),
                     ("out_rms", "f8", MAX_BOUNCES), ("back_rms", "f8", MAX_BOUNCES),
                     ("out_law", "i4", MAX_BOUNCES), ("back_law", "i4", MAX_BOUNCES), ("n_out", "i4"),
                     ("n_back", "i4"), ("touches_floor", "i4")])
# unfolded normals, rms heights m, laws (propagation.SURFACE/BOTTOM), 1: dark for scatterers on the seabed
# a scatterer's fields, stored field by field (structure of arrays) for the paths kernel
SCATTERER = record_dtype([("p0", "f8", 3), ("vel", "f8", 3), ("refl", "f8", 2), ("on_floor", "f8")])
# m, m/s, re/im, 1 on the seabed (physics.on_floor)


def path_record(real, extended: bool) -> np.dtype:
    """The path record echo_paths writes and the accumulation reads (``echo_path_t``): the echo
    centre (start sample and fraction), the amplitude with the carrier phase and, ``extended``,
    its own chirp (cycles a sample^2), Doppler shift (cycles a sample), envelope (Np a sample,
    a sample^2), support [lo, hi] (samples about the centre) and level (Np: the envelope's
    largest log over the support, folded into the amplitude)."""
    kind = "f8" if np.dtype(real) == np.float64 else "f4"
    fields = [("start", "i4"), ("frac", kind), ("amp", kind, 2)]
    if extended:
        fields += [(name, kind) for name in ("chirp", "lin", "beta", "gamma", "lo", "hi", "level")]
    return record_dtype(fields)


def soa_defines(dtype: np.dtype, prefix: str) -> str:
    """``#define PREFIX_FIELD offset`` (in doubles) for a record stored field by field, and
    ``PREFIX_FIELDS`` the count: the kernel reads field F of item j at (PREFIX_F + k) n + j."""
    lines, offset = [], 0
    for name in dtype.names:
        sub = dtype.fields[name][0]
        lines.append(f"#define {prefix}_{name.upper()} {offset}")
        offset += int(np.prod(sub.shape)) if sub.shape else 1
    return "\n".join(lines + [f"#define {prefix}_FIELDS {offset}"]) + "\n"


def records_preamble(real, extended: bool) -> str:
    """The kernel's records: the structs and the scatterer fields."""
    return declare_all({"node_t": geometry.NODE, "echo_pulse_t": PULSE, "echo_rx_t": RECEIVER,
                        "echo_params_t": PARAMS, "echo_legs_t": LEGS,
                        "echo_path_t": path_record(real, extended)}) + soa_defines(SCATTERER, "SCAT")

def legs_record(kind) -> np.ndarray:
    """The bounces of path ``kind`` as ``echo_legs_t`` (LEGS): unfolded normals, rms heights, laws."""
    legs = np.zeros((), LEGS)
    legs["touches_floor"] = Physics.touches_floor(kind)
    for side, leg in (("out", kind.out), ("back", kind.back)):
        normals = leg.normals
        legs[f"n_{side}"] = len(leg.planes)
        for b, plane in enumerate(leg.planes):
            legs[f"{side}_normal"][3 * b:3 * b + 3] = normals[b]
            legs[f"{side}_rms"][b] = plane.rms_height
            legs[f"{side}_law"][b] = plane.law
    return legs

