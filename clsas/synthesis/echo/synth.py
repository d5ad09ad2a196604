"""Echo synthesis, the maths and its fast twin: the float64 NumPy reference and the launcher of
``kernels/echo.cl``, side by side (:mod:`.pipeline` drives them).

Signal model (docs/design.md): the baseband echo of path (receiver h, pulse p, scatterer n) is

    s(tau) = a rect((tau - tau_n) / T) exp(-j 2 pi f0 tau_n) exp(j pi K (tau - tau_n)^2),

tau_n the exact two-way delay and a the path amplitude of :mod:`clsas.geometry`
(times the occlusion factor). Fast time is sampled at ``t0_h + k / fs``; with
``u = (tau_n - t0_h) fs`` (the echo centre in samples) and ``d = k - u``, sample k receives
``a exp(-j 2 pi f0 tau_n) exp(j 2 pi alpha d^2)`` when ``|d| <= T fs / 2``, with
``alpha = K / (2 fs^2)`` cycles per sample^2 (:func:`accumulate_reference`).

Precision of the OpenCL kernel (``precision="single"``): the delays, the amplitudes and the
carrier phase f0 tau_n are computed in double (the carrier phase at 2 km and 150 kHz is
4e5 cycles: in float32 it would be off by ~0.03 cycle); the echo centre is handed to the
float accumulation as an integer sample ``floor(u)`` plus a fraction in [0, 1), so that the
chirp phase 2 pi alpha d^2 is computed from d known to 1e-7 sample at any range; the carrier
factor is stored as a float32 complex amplitude (relative error 6e-8). The remaining float32
errors are the chirp phase (alpha d^2 <= BT/8 cycles, relative error 6e-8: 5e-6 rad at BT = 100)
and the summation of the overlapping echoes in float32 (relative ~1e-7 per term). This meets
the issue's budget (phase error < 0.01 rad per contribution, relative L2 < 5e-3) with orders
of magnitude to spare. ``precision="double"`` runs the accumulation in double too.

The receiver's motion during reception enters the kernel through position nodes (linear
between them, :func:`clsas.synthesis.window.receiver_nodes`); the reference evaluates the
scenario's trajectory exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import geometry, opencl
from ...cstruct import declare_all, record_dtype
from ...scene.scenario import Scenario
from ...scene.seafloor import generate
from ...scene.targets import Scatterers
from ..paths import Paths, bottom_coefficient, paths
from ..propagation import BOTTOM, DIRECT, BandAbsorption
from .compressed import PAD, PHASES, CompressedResponse

CHUNK_SCATTERERS = 16  # paths per bounds chunk in the OpenCL accumulation
ROWS = 8  # 16-sample rows per work-item of the OpenCL accumulation
BOTTOM_TABLE = 1025  # entries of the seabed's reflection table, sin(grazing) in [0, 1]
MAX_BOUNCES = 2  # per leg
UNHEARD = 1 << 30  # kernels/echo.cl: the start sample of a path that carries no echo
# the records echo_paths reads (kernels/echo.cl): a pulse, a receiver, the launch's parameters and
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
# m, m/s, re/im, 1 on the seabed (synth.on_floor)


def groups(n_x: int, *rest: int) -> tuple[tuple, tuple]:
    """(global, local) sizes of a launch of (n_x, *rest) work-items in fixed work-groups along the
    first dimension (:func:`clsas.opencl.work_groups`: PoCL compiles each kernel once per process
    whatever the shape; the kernels return for the work-items past n_x)."""
    (size,), (group,) = opencl.work_groups(n_x)
    return (size, *rest), (group,) + (1,) * len(rest)


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


@dataclass(frozen=True)
class Physics:
    """What the paths carry, resolved for one scenario: the path ``kinds`` (direct first),
    ``intra_pulse`` ("none", "moving", "all"), ``absorption`` (None: none), ``spreading``,
    ``stop_and_go``; ``response``: synthesis into the range-compressed domain with these
    tabulated responses (None: raw echoes); ``floor_first``: the index of the first seafloor
    facet among the scatterers (None: none; :func:`on_floor`); ``extended``: the paths need
    their own chirp and envelope."""

    kinds: tuple = (DIRECT,)
    intra_pulse: str = "none"
    absorption: BandAbsorption | None = None
    spreading: bool = False
    stop_and_go: bool = False
    moving: bool = False
    response: CompressedResponse | None = None
    floor_first: int | None = None

    @property
    def doppler(self) -> bool:
        """Some path gets an in-pulse delay law."""
        return not self.stop_and_go and (self.intra_pulse == "all" or (self.intra_pulse == "moving" and self.moving))

    @property
    def extended(self) -> bool:
        return self.doppler or self.absorption is not None or len(self.kinds) > 1

    @staticmethod
    def touches_floor(kind) -> bool:
        """A leg of ``kind`` meets the seabed last before (or first after) the scatterer."""
        return any(bool(leg.planes) and leg.planes[-1].law == BOTTOM for leg in (kind.out, kind.back))


def on_floor(scat: Scatterers, floor_first: int | None, kinds) -> np.ndarray:
    """bool (N,): the scatterers that lie on the seabed (its facets, from ``floor_first``, and any
    scatterer within 1 mm of its mean plane or below it at t = 0): a path that "bounces" off the
    seabed right next to them is their direct path again, so those kinds are dark for them."""
    out = np.zeros(scat.count, dtype=bool)
    if floor_first is not None:
        out[floor_first:] = True
    for kind in kinds:
        for plane in kind.out.planes + kind.back.planes:
            if plane.law == BOTTOM:
                out |= (scat.p0 - plane.origin) @ plane.normal <= 1e-3
    return out


def in_pulse_laws(p: Paths, waveform) -> dict:
    """Each path's echo as the kernel writes it (module docstring, :mod:`clsas.synthesis.paths`):
    chirp (cycles a sample^2), lin (cycles a sample), beta (Np a sample), gamma (Np a sample^2),
    lo, hi (samples about the centre), each (H, P, N)."""
    k, fs, f0, half = waveform.chirp_rate, waveform.fs, waveform.f0, 0.5 * waveform.duration
    s = 1.0 / (1.0 + p.d1)
    kfs = k * s / fs
    centre = p.d2 * half * half
    return {"chirp": (0.5 * k * s * s - f0 * p.d2 * s ** 3) / fs ** 2, "lin": -f0 * p.d1 * s / fs,
            "beta": p.lnf1 * kfs, "gamma": p.lnf2 * kfs * kfs,
            "lo": (centre - half * (1.0 + p.d1)) * fs, "hi": (centre + half * (1.0 + p.d1)) * fs}


def accumulate_reference(start, frac, amp, alpha: float, half_len: float, n_samples: int,
                         laws: dict | None = None) -> np.ndarray:
    """The echoes of every path added into records of ``n_samples`` samples (float64 reference).

    Parameters
    ----------
    start : int (R, N), frac : float (R, N)
        Echo centres u = start + frac in samples (0 <= frac < 1) for R records and N paths.
    amp : complex (R, N)
        Path amplitudes including the carrier phase.
    alpha : float
        Chirp phase rate, cycles per sample^2 (K / (2 fs^2)).
    half_len : float
        Half the pulse length in samples (T fs / 2).
    laws : dict of (R, N) arrays, optional
        Each path's own chirp, lin, beta, gamma, lo, hi (:func:`in_pulse_laws`) instead of
        alpha, 0, 0, 0, -half_len, half_len.

    Returns complex128 (R, n_samples): sample k of record r holds
    sum_n amp exp(j 2 pi (chirp d^2 + lin d) + gamma d^2 + beta d) [lo <= d <= hi],
    d = k - start[r, n] - frac[r, n].
    """
    start = np.asarray(start)
    reach = half_len if laws is None else max(np.max(np.abs(laws["lo"]), initial=0.0),
                                              np.max(np.abs(laws["hi"]), initial=0.0))
    span = int(reach) + 2
    offsets = np.arange(-span, span + 1)
    out = np.zeros((start.shape[0], n_samples), dtype=np.complex128)
    for r in range(start.shape[0]):
        k = start[r][:, None] + offsets[None, :]
        d = offsets[None, :] - frac[r][:, None]
        if laws is None:
            keep = (np.abs(d) <= half_len) & (k >= 0) & (k < n_samples)
            vals = (amp[r][:, None] * np.exp(2j * np.pi * alpha * d * d))[keep]
        else:
            law = {name: value[r][:, None] for name, value in laws.items()}
            keep = (d >= law["lo"]) & (d <= law["hi"]) & (k >= 0) & (k < n_samples)
            exponent = 2j * np.pi * (law["chirp"] * d + law["lin"]) * d + (law["gamma"] * d + law["beta"]) * d
            vals = (amp[r][:, None] * np.exp(exponent))[keep]
        out[r] = np.bincount(k[keep], weights=vals.real, minlength=n_samples) \
            + 1j * np.bincount(k[keep], weights=vals.imag, minlength=n_samples)
    return out


def _split(tau: np.ndarray, t0: np.ndarray, fs: float):
    """Echo centres as (floor(u), u - floor(u)) with u = tau fs - t0 fs; ``t0`` per receiver (H,)."""
    u = tau * fs - (t0 * fs)[:, None, None]
    start = np.floor(u)
    return start.astype(np.int64), u - start


class _Synth:
    """What both backends provide: the delays of a pulse block (pass A, which also gives the
    recording window) and its records (pass B)."""

    def __init__(self, scenario: Scenario, scat: Scatterers, occlusion, physics: Physics):
        self.args = (scenario, scat, occlusion, physics)
        self.scenario, self.scat, self.occlusion, self.physics = scenario, scat, occlusion, physics
        self.stop_and_go, self.spreading = physics.stop_and_go, physics.spreading
        self.eta = scenario.eta
        self.n_rx = scenario.n_receivers
        wf = scenario.waveform
        self.alpha = 0.5 * wf.chirp_rate / wf.fs**2
        self.half_len = 0.5 * wf.duration * wf.fs
        self.floor_first = scat.count if physics.floor_first is None else physics.floor_first
        self.facets = None if physics.floor_first is None else generate(scenario.seafloor, scenario)
        self.across = 0.0 if self.facets is None else self.facets.across(scenario.tx_position(scenario.eta))

    def reach(self, pulses: slice, cull: bool = True):
        """int64 (P, 2): per pulse of the block, the seafloor facets [first, stop) (indices among
        the facets) that its beam can reach (:meth:`clsas.scene.seafloor.Facets.reach_span`; every
        facet unless ``cull``); None without a seafloor. The facets outside carry no echo at that
        pulse (their path weights are 0): both backends leave them out of the recording window."""
        if self.facets is None:
            return None
        eta = self.eta[pulses]
        if not cull:
            return np.tile(np.array([0, self.facets.count], np.int64), (eta.size, 1))
        return self.facets.reach_spans(self.scenario.tx_position(eta), self.across)

    def heard(self, pulses: slice) -> np.ndarray:
        """bool (P, N): the scatterers that can carry an echo at each pulse of the block (every
        target; the facets within :meth:`reach`)."""
        n_p = len(range(*pulses.indices(self.eta.size)))
        out = np.ones((n_p, self.scat.count), dtype=bool)
        spans = self.reach(pulses)
        if spans is not None:
            k = np.arange(self.scat.count - self.floor_first)
            out[:, self.floor_first:] = (k >= spans[:, :1]) & (k < spans[:, 1:])
        return out

    def weights(self, pulses: slice):
        """The path weights of a pulse block: (H, P, N), or (1, P, N) shared by the receivers."""
        if self.occlusion is None:
            return None
        if callable(self.occlusion):
            w = np.asarray(self.occlusion(pulses), dtype=np.float64)
        else:
            w = self.occlusion[:, pulses]
        n_p = len(range(*pulses.indices(self.eta.size)))
        shapes = ((self.n_rx, n_p, self.scat.count), (1, n_p, self.scat.count))
        if w.shape not in shapes or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError(f"occlusion for pulses {pulses} must be finite, >= 0, with shape {shapes[0]} (or "
                             f"{shapes[1]}: shared by the receivers), got {w.shape}")
        return w


class _NumpySynth(_Synth):
    """float64 reference: exact trajectories (clsas.synthesis.paths) and accumulate_reference."""

    def _paths(self, pulses: slice, kind) -> Paths:
        ph = self.physics
        p = paths(self.scenario, self.eta[pulses], self.scat, range(self.n_rx), kind, ph.stop_and_go,
                  ph.spreading, ph.intra_pulse if ph.doppler else "none", ph.absorption)
        if ph.touches_floor(kind):
            p.amp[:, :, on_floor(self.scat, ph.floor_first, ph.kinds)] = 0.0
        return p

    def delays(self, pulses: slice, kind: int = 0) -> np.ndarray:
        """Delays (H, P, N), s, of the paths of ``physics.kinds[kind]`` (0: direct)."""
        return self._paths(pulses, self.physics.kinds[kind]).tau

    def release(self) -> None:
        """Nothing is cached by the reference."""

    def extents(self, pulses: slice):
        lo, hi = None, None
        heard = self.heard(pulses)
        for kind in self.physics.kinds:
            a, b = sample_extents(self._paths(pulses, kind).tau * self.scenario.waveform.fs, heard)
            lo, hi = (a, b) if lo is None else (np.minimum(lo, a), np.maximum(hi, b))
        return lo, hi

    def spread(self, pulse: int) -> np.ndarray:
        """(H,) s: the spread of the direct paths' delays at ``pulse`` over the scatterers heard then."""
        tau = self._paths(slice(pulse, pulse + 1), self.physics.kinds[0]).tau[:, 0, self.heard(slice(pulse, pulse + 1))[0]]
        return tau.max(axis=1) - tau.min(axis=1)

    def records(self, pulses: slice, t0: np.ndarray, n_samples: int) -> np.ndarray:
        wf = self.scenario.waveform
        w = self.weights(pulses)
        out = 0.0
        for kind in self.physics.kinds:
            p = self._paths(pulses, kind)
            amp = p.amp * np.exp(-2j * np.pi * wf.f0 * p.tau)
            if w is not None:
                amp = amp * w
            start, frac = _split(p.tau, t0, wf.fs)
            h, n_p, n = p.tau.shape
            laws = {k: v.reshape(h * n_p, n) for k, v in in_pulse_laws(p, wf).items()} \
                if self.physics.extended else None
            args = (start.reshape(h * n_p, n), frac.reshape(h * n_p, n), amp.reshape(h * n_p, n))
            if self.physics.response is not None:
                out = out + self.physics.response.accumulate(*args, n_samples, laws)
            else:
                out = out + accumulate_reference(*args, self.alpha, self.half_len, n_samples, laws)
        return out.reshape(self.n_rx, -1, n_samples)


def _legs_record(kind) -> np.ndarray:
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


class _OpenCLSynth(_Synth):
    """The kernels of kernels/echo.cl: paths in double, accumulation in float (or double)."""

    def __init__(self, *args, double: bool, nodes, cache_bytes: int = 2 * 2**30):
        super().__init__(*args)
        import pyopencl as cl

        self.cl = cl
        self.rt = opencl.runtime()
        if not opencl.has_fp64(self.rt.device):
            raise RuntimeError(f"echo synthesis computes delays in double; device {self.rt.device.name!r} has no fp64")
        self.double = double
        self.cache, self.cached_bytes, self.cache_bytes = {}, 0, cache_bytes
        self.real = np.float64 if double else np.float32
        self.cplx = np.complex128 if double else np.complex64
        ph = self.physics
        self.path_dtype = path_record(self.real, ph.extended)
        sc, scat = self.scenario, self.scat
        c = sc.medium.sound_speed
        self.rx_tau, self.rx_pos, self.rx_axis, self.rx_node_error = nodes
        n = scat.count
        # positions 0 .. split - 1: the targets in each receiver's delay order; from split on: the
        # seafloor's facets in their own order (shared by the receivers), each part padded to eight
        n_t, n_f = self.floor_first, n - self.floor_first
        self.split, self.n_floor = -(-n_t // 8) * 8, -(-n_f // 8) * 8
        fields = np.zeros(n, SCATTERER)
        fields["p0"], fields["vel"] = scat.p0, scat.vel
        fields["refl"] = np.column_stack([scat.refl.real, scat.refl.imag])
        fields["on_floor"] = on_floor(scat, ph.floor_first, ph.kinds)
        flat = np.concatenate([fields[name].reshape(n, -1) for name in SCATTERER.names], axis=1)
        refl = SCATTERER.fields["refl"][1] // 8  # the first reflectivity field (doubles)
        order = self._delay_order()
        self.target_index = np.full((self.n_rx, self.split), -1, np.int64)  # scatterer per position, -1: padding
        self.target_index[:, :n_t] = order
        padded = np.where(self.target_index < 0, order[:, -1:] if n_t else 0, self.target_index)
        tsoa = np.ascontiguousarray(np.transpose(flat[padded], (0, 2, 1))) if n_t else np.zeros(1)  # (H, fields, split)
        if n_t:
            tsoa[:, refl:refl + 2, n_t:] = 0.0  # padding scatterers reflect nothing
        facet_index = np.minimum(n_t + np.arange(self.n_floor), n - 1)
        fsoa = np.ascontiguousarray(flat[facet_index].T) if n_f else np.zeros(1)  # (fields, n_floor)
        if n_f:
            fsoa[refl:refl + 2, n_f:] = 0.0
        mf = cl.mem_flags
        ctx = self.rt.context
        self.tsoa_buf, self.fsoa_buf, self.torder_buf, self.forder_buf = (
            cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))
            for a in (tsoa, fsoa, padded.astype(np.int32) if n_t else np.zeros(1, np.int32),
                      facet_index.astype(np.int32) if n_f else np.zeros(1, np.int32)))
        del tsoa, fsoa, flat, fields
        self.tx = sc.tx_position(self.eta)
        self.tx_vel = (sc.tx_position(self.eta + 1e-3) - sc.tx_position(self.eta - 1e-3)) / 2e-3
        self.tx_axis = sc.platform.rotation(self.eta)[..., :, 1]
        self.bottom_buf = self._bottom_table()
        defines = {
            "N_NODES": self.rx_tau.size,
            "SEGMENT_PASSES": 1 if self.rx_tau.size == 2 else 3,
            "CHUNK": CHUNK_SCATTERERS,
            "ROWS": ROWS,
            "BOTTOM_TABLE": BOTTOM_TABLE,
        }
        for flag, on in (("STOP_AND_GO", ph.stop_and_go), ("SPREADING", ph.spreading),
                         ("PATH_WEIGHTS", self.occlusion is not None), ("EXTENDED", ph.extended),
                         ("ABSORPTION", ph.absorption is not None), ("BOUNCES", len(ph.kinds) > 1)):
            if on:
                defines[flag] = 1
        if ph.doppler:
            defines["INTRA_PULSE"] = 2 if ph.intra_pulse == "all" else 1
        if ph.response is not None:
            defines.update(COMPRESSED=ph.response.taps, N_TABLES=3 if ph.extended else 1, PHASES=PHASES, PAD=PAD)
            table, impulse = ph.response.planar(self.real)
            table = np.ascontiguousarray(table[:defines["N_TABLES"]])
            self.table_row, self.impulse_len = table.shape[-1], impulse.shape[-1]
            self.table_buf, self.impulse_buf = (
                cl.Buffer(self.rt.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=a)
                for a in (table, impulse))
        preamble = records_preamble(self.real, ph.extended)
        prg = opencl.program("echo", defines=defines, double=double, preamble=preamble)
        self.k_paths = cl.Kernel(prg, "echo_paths")
        # delays and extents need no weights: their paths come from a build without them
        plain = {key: value for key, value in defines.items() if key != "PATH_WEIGHTS"}
        self.k_paths_plain = self.k_paths if plain == defines else \
            cl.Kernel(opencl.program("echo", defines=plain, double=double, preamble=preamble), "echo_paths")
        self.k_bounds = cl.Kernel(prg, "echo_bounds")
        self.k_extents = cl.Kernel(prg, "echo_extents")
        self.k_spread = cl.Kernel(prg, "echo_spread")
        self.k_acc = cl.Kernel(prg, "echo_accumulate_compressed" if ph.response is not None else "echo_accumulate")
        wf = sc.waveform
        self.params = np.zeros((), PARAMS)
        self.params["c"], self.params["f0"], self.params["fs"] = c, wf.f0, wf.fs
        self.params["wavelength"], self.params["tx_length"] = wf.wavelength(sc.medium), sc.array.tx_length
        self.params["dtau"] = self.rx_tau[1] - self.rx_tau[0]
        self.params["chirp_rate"], self.params["duration"] = wf.chirp_rate, wf.duration
        if ph.absorption is not None:
            self.params["abs_a0"], self.params["abs_a1"] = ph.absorption.a0, ph.absorption.a1
            self.params["abs_a2"] = ph.absorption.a2
        self.legs = [_legs_record(kind) for kind in ph.kinds]

    def _bottom_table(self):
        planes = [p for kind in self.physics.kinds for p in kind.out.planes + kind.back.planes if p.law == BOTTOM]
        table = np.zeros((BOTTOM_TABLE, 2))
        if planes:
            v = bottom_coefficient(planes[0], np.linspace(0.0, 1.0, BOTTOM_TABLE))
            table[:, 0], table[:, 1] = v.real, v.imag
        return self.cl.Buffer(self.rt.context, self.cl.mem_flags.READ_ONLY | self.cl.mem_flags.COPY_HOST_PTR,
                              hostbuf=table)

    def _delay_order(self) -> np.ndarray:
        """Per receiver, the targets' scatterers (those before the seafloor's facets) sorted by
        their stop-and-go delay at the middle pulse (H, n_targets).

        Sorting keeps each chunk of CHUNK_SCATTERERS compact in delay, so the accumulation skips
        whole chunks that cannot reach a block of samples; any order gives the same result (the
        facets keep their own order, by along-track band and range: compact too).
        """
        mid = self.eta[self.eta.size // 2]
        q = self.scat.p0[:self.floor_first] + self.scat.vel[:self.floor_first] * mid
        out = np.linalg.norm(q - self.scenario.tx_position(mid), axis=1)
        return np.stack([np.argsort(out + np.linalg.norm(q - self.scenario.receiver_position(h, mid), axis=1),
                                    kind="stable") for h in range(self.n_rx)]).reshape(self.n_rx, -1)

    def _block(self, pulses: slice, cull: bool):
        """(jump, n_act, active) of a pulse block: the paths kernel computes positions 0 .. split - 1
        and split + jump .. n_act + jump - 1 (the facets some pulse of the block can reach, in
        whole eights); active (P, 2) int32: each pulse's reach in positions."""
        spans = self.reach(pulses, cull)
        n_p = len(range(*pulses.indices(self.eta.size)))
        if spans is None or self.n_floor == 0:
            return 0, self.split, np.zeros((n_p, 2), np.int32)
        first = min(int(spans[:, 0].min()) // 8 * 8, self.n_floor - 8)
        stop = max(min(self.n_floor, -(-int(spans[:, 1].max()) // 8) * 8), first + 8)
        return first, self.split + stop - first, (spans + self.split).astype(np.int32)

    def _index(self, jump: int, n_act: int) -> np.ndarray:
        """(H, n_act) int64: the scatterer of each computed path slot (-1: padding)."""
        out = np.full((self.n_rx, n_act), -1, np.int64)
        out[:, :self.split] = self.target_index
        k = np.arange(self.split, n_act) + jump - self.split  # facet index
        out[:, self.split:] = np.where(k < self.scat.count - self.floor_first, self.floor_first + k, -1)
        return out

    def _run_paths(self, pulses: slice, t0: np.ndarray, weighted: bool = True, kinds=None, cull: bool = True):
        """The paths kernel on a pulse block for the path ``kinds`` (indices; default every kind):
        delays and amplitudes (times the occlusion weights unless not ``weighted``: the delays and
        extents do not need them), of the targets and of the facets the block's beam reaches
        (every facet unless ``cull``). Returns (paths buffer, pulses, (jump, n_act, stride))."""
        cl, q, ctx = self.cl, self.rt.queue, self.rt.context
        mf = cl.mem_flags
        idx = np.arange(self.eta.size)[pulses]
        pc, h = idx.size, self.n_rx
        kinds = range(len(self.physics.kinds)) if kinds is None else kinds
        jump, n_act, active = self._block(pulses, cull)
        stride = n_act * len(kinds)
        rx = np.zeros(h, RECEIVER)
        rx["t0_fs"], rx["length"] = t0 * self.scenario.waveform.fs, self.scenario.receiver_lengths
        w = self.weights(pulses) if weighted else None
        w_rx = 0 if w is None or w.shape[0] == 1 else pc
        w = np.ones(1, np.float32) if w is None else np.ascontiguousarray(w, dtype=np.float32)
        w_buf, rx_buf, active_buf = (cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))
                                     for a in (w, rx, active))
        paths_buf = cl.Buffer(ctx, mf.READ_WRITE, self.path_dtype.itemsize * h * pc * stride)
        kernel = self.k_paths if weighted else self.k_paths_plain
        for slot, k in enumerate(kinds):
            kind = self.physics.kinds[k]
            out_image, back_image = kind.out.image, kind.back.image
            pulse = np.zeros(pc, PULSE)
            pulse["tx"], pulse["eta"] = out_image.points(self.tx[idx]), self.eta[idx]
            pulse["tx_axis"], pulse["tx_vel"] = out_image.vectors(self.tx_axis[idx]), out_image.vectors(self.tx_vel[idx])
            nodes = np.zeros((h, pc, self.rx_tau.size), geometry.NODE)
            nodes["pos"], nodes["axis"] = back_image.points(self.rx_pos[:, idx]), back_image.vectors(self.rx_axis[:, idx])
            pulse_buf, node_buf = (cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))
                                   for a in (pulse, nodes))
            kernel(q, *groups(n_act // 8, pc, h), self.tsoa_buf, self.fsoa_buf, pulse_buf, node_buf, rx_buf,
                   self.torder_buf, self.forder_buf, w_buf, self.bottom_buf, self.params[()], self.legs[k][()],
                   np.int32(self.scat.count), np.int32(self.split), np.int32(self.n_floor), np.int32(jump),
                   active_buf, np.int32(pc), np.int32(w_rx), np.int32(stride), np.int32(slot * n_act),
                   np.int32(n_act // 8), paths_buf)
        return paths_buf, pc, (jump, n_act, stride)

    def release(self) -> None:
        """Drop the cached path buffers (after pass B)."""
        self.cache.clear()
        self.cached_bytes = 0

    def delays(self, pulses: slice, kind: int = 0) -> np.ndarray:
        """Delays (H, P, N) of the block's paths of ``physics.kinds[kind]`` (0: direct) from the
        kernel, in scatterer order (every facet, in the beam's reach or not)."""
        h, n = self.n_rx, self.scat.count
        paths_buf, pc, (jump, n_act, stride) = self._run_paths(pulses, np.zeros(h), weighted=False, kinds=[kind],
                                                               cull=False)
        host = np.empty((h, pc, stride), self.path_dtype)
        self.cl.enqueue_copy(self.rt.queue, host, paths_buf)
        u = (host["start"] + host["frac"].astype(np.float64)) / self.scenario.waveform.fs
        index = self._index(jump, n_act)
        tau = np.empty((h, pc, n))
        for r in range(h):
            valid = index[r] >= 0
            tau[r][:, index[r, valid]] = u[r][:, valid]
        return tau

    def spread(self, pulse: int) -> np.ndarray:
        """(H,) s: the spread of the direct paths' delays at ``pulse`` over the scatterers heard
        then (kernels/echo.cl ``echo_spread``)."""
        paths_buf, _, (_, n_act, stride) = self._run_paths(slice(pulse, pulse + 1), np.zeros(self.n_rx),
                                                           weighted=False, kinds=[0])
        out = self.cl.Buffer(self.rt.context, self.cl.mem_flags.WRITE_ONLY, 16 * self.n_rx)
        self.k_spread(self.rt.queue, *groups(1, self.n_rx), paths_buf, np.int32(n_act), np.int32(stride), np.int32(1),
                      out)
        host = np.empty((self.n_rx, 2))
        self.cl.enqueue_copy(self.rt.queue, host, out)
        return (host[:, 1] - host[:, 0]) / self.scenario.waveform.fs

    def _path_bytes(self, pc: int, stride: int) -> int:
        return self.path_dtype.itemsize * self.n_rx * pc * stride

    def extents(self, pulses: slice):
        """(floor(min u), floor(max u) + 1) per (receiver, scatterer) over every path kind and the
        block's pulses that hear it (inf, -inf: none), reduced on the device. With an occlusion
        factor the paths are computed unweighted and not kept for pass B: the weights (hull ray
        casting for meshes) are then computed once, by pass B, whose pulse blocks need not match
        these."""
        cl, q = self.cl, self.rt.queue
        h, n = self.n_rx, self.scat.count
        paths_buf, pc, block = self._run_paths(pulses, np.zeros(h), weighted=False)
        jump, n_act, stride = block
        reusable = self.occlusion is None  # unweighted paths are pass B's paths only without weights
        if reusable and self.cached_bytes + self._path_bytes(pc, stride) <= self.cache_bytes:
            self.cache[(pulses.start, pulses.stop)] = (paths_buf, pc, block)
            self.cached_bytes += self._path_bytes(pc, stride)
        ext = cl.Buffer(self.rt.context, cl.mem_flags.WRITE_ONLY, 8 * h * stride)
        self.k_extents(q, *groups(stride, h), paths_buf, np.int32(stride), np.int32(pc), ext)
        host = np.empty((h, len(self.physics.kinds), n_act, 2), np.int32)
        cl.enqueue_copy(q, host, ext)
        first, last = host[..., 0].min(axis=1), host[..., 1].max(axis=1)
        first = np.where(first == UNHEARD, np.inf, first)
        last = np.where(last == -UNHEARD, -np.inf, last + 1.0)
        lo, hi = np.full((h, n), np.inf), np.full((h, n), -np.inf)
        index = self._index(jump, n_act)
        for r in range(h):
            valid = index[r] >= 0
            lo[r, index[r, valid]] = first[r, valid]
            hi[r, index[r, valid]] = last[r, valid]
        return lo, hi

    def records(self, pulses: slice, t0: np.ndarray, n_samples: int) -> np.ndarray:
        """The block's records; reuses the paths of extents() when the window starts on a whole sample."""
        cl, q = self.cl, self.rt.queue
        h = self.n_rx
        first = t0 * self.scenario.waveform.fs
        whole = np.all(np.abs(first - np.round(first)) < 1e-6) and np.all(np.abs(first) < 2**31)
        cached = self.cache.pop((pulses.start, pulses.stop), None) if whole else None
        if cached is not None:
            paths_buf, pc, (_, _, n) = cached
            shift = np.round(first).astype(np.int32)
        else:
            paths_buf, pc, (_, _, n) = self._run_paths(pulses, t0)
            shift = np.zeros(h, np.int32)
        n_chunks = -(-n // CHUNK_SCATTERERS)
        mf = cl.mem_flags
        bounds = cl.Buffer(self.rt.context, mf.READ_WRITE, 8 * h * pc * n_chunks)
        self.k_bounds(q, *groups(n_chunks, pc, h), paths_buf, self.real(self.half_len), np.int32(n), np.int32(pc),
                      bounds)
        rows = 16 * ROWS
        n_pad = -(-n_samples // rows) * rows
        out = cl.Buffer(self.rt.context, mf.WRITE_ONLY, np.dtype(self.cplx).itemsize * h * pc * n_pad)
        shift_buf = cl.Buffer(self.rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=shift)
        if self.physics.response is not None:
            resp = self.physics.response
            self.k_acc(q, *groups(n_pad // rows, pc, h), paths_buf, bounds, self.table_buf, self.real(self.alpha),
                       np.int32(self.table_row), self.impulse_buf, np.int32(self.impulse_len), np.int32(resp.lag0),
                       np.int32(resp.edges[0]), np.int32(resp.edges[1]), self.real(resp.half_len), np.int32(n),
                       np.int32(pc), np.int32(n_pad), np.int32(n_samples), shift_buf, out)
        else:
            self.k_acc(q, *groups(n_pad // rows, pc, h), paths_buf, bounds, self.real(self.alpha),
                       self.real(self.half_len), np.int32(n), np.int32(pc), np.int32(n_pad), np.int32(n_samples),
                       shift_buf, out)
        host = np.empty((h, pc, n_pad), self.cplx)
        cl.enqueue_copy(q, host, out)
        return host[:, :, :n_samples]


def sample_extents(u: np.ndarray, heard: np.ndarray | None = None):
    """Echo-centre extents per (receiver, scatterer) over the pulses of ``u`` (H, P, N), in samples
    from t = 0, rounded outwards to whole samples: (floor(min u), floor(max u) + 1), over the
    pulses where ``heard`` (P, N) (inf, -inf where none). Both backends report extents this way
    (the OpenCL kernel returns floor(u) directly), so that they derive the same recording window."""
    if heard is None:
        return np.floor(u.min(axis=1)), np.floor(u.max(axis=1)) + 1
    return np.floor(np.where(heard, u, np.inf).min(axis=1)), np.floor(np.where(heard, u, -np.inf).max(axis=1)) + 1
