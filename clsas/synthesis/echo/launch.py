"""The launcher of ``kernels/echo_paths.cl`` and ``kernels/echo_accumulate.cl`` (its NumPy twin: :mod:`.reference`): the paths kernel,
the bounds and extents, and the accumulation of the raw or compressed records.

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
between them, :func:`clsas.synthesis.window.receiver_nodes`).
"""

from __future__ import annotations

import numpy as np

from ... import geometry, opencl
from ..paths import bottom_coefficient
from ..propagation import BOTTOM
from .blocks import BlockSynth
from . import grid
from .compressed import PAD, PHASES
from .physics import on_floor
from .records import (BOTTOM_TABLE, CHUNK_SCATTERERS, PARAMS, PULSE, RECEIVER, ROWS, SCATTERER, UNHEARD,
                      legs_record, path_record, records_preamble)


def groups(n_x: int, *rest: int) -> tuple[tuple, tuple]:
    """(global, local) sizes of a launch of (n_x, *rest) work-items in fixed work-groups along the
    first dimension (:func:`clsas.opencl.work_groups`: PoCL compiles each kernel once per process
    whatever the shape; the kernels return for the work-items past n_x)."""
    (size,), (group,) = opencl.work_groups(n_x)
    return (size, *rest), (group,) + (1,) * len(rest)


class OpenCLSynth(BlockSynth):
    """The kernels of kernels/echo_paths.cl and echo_accumulate.cl: paths in double, accumulation in float (or double)."""

    def __init__(self, *args, double: bool, nodes):
        super().__init__(*args)
        import pyopencl as cl

        self.cl = cl
        self.rt = opencl.runtime()
        if not opencl.has_fp64(self.rt.device):
            raise RuntimeError(f"echo synthesis computes delays in double; device {self.rt.device.name!r} has no fp64")
        self.double = double
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
        if ph.writes_taps:
            defines.update(COMPRESSED=ph.response.taps, N_TABLES=3 if ph.extended else 1, PHASES=PHASES, PAD=PAD)
            table, impulse = ph.response.planar(self.real)
            table = np.ascontiguousarray(table[:defines["N_TABLES"]])
            self.table_row, self.impulse_len = table.shape[-1], impulse.shape[-1]
            self.table_buf, self.impulse_buf = (
                cl.Buffer(self.rt.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=a)
                for a in (table, impulse))
        if ph.grid is not None:
            defines.update(GRID=ph.grid.terms, GRID_RATE=grid.RATE, GRID_TAPS=grid.TAPS, GRID_DEGREE=grid.DEGREE,
                           TAPER=grid.TAPER, GRID_BLOCK=grid.BLOCK, GRID_PAD=ph.grid.pad)
            self.taps_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                                      hostbuf=np.ascontiguousarray(grid.tap_polynomials(), dtype=self.real))
        preamble = records_preamble(self.real, ph.extended)
        paths = opencl.program("echo_paths", defines=defines, double=double, preamble=preamble)
        self.k_paths = cl.Kernel(paths, "echo_paths")
        # paths without weights (pass A's, kept for pass B when there are no weights) and the echo
        # centres alone (the delays and the extents when pass B computes its own paths)
        plain = {key: value for key, value in defines.items() if key != "PATH_WEIGHTS"}
        self.k_paths_plain = self.k_paths if plain == defines else \
            cl.Kernel(opencl.program("echo_paths", defines=plain, double=double, preamble=preamble), "echo_paths")
        self.k_paths_delays = cl.Kernel(opencl.program("echo_paths", defines={**plain, "DELAYS_ONLY": 1},
                                                       double=double, preamble=preamble), "echo_paths")
        self.k_extents = cl.Kernel(paths, "echo_extents")
        self.k_spread = cl.Kernel(paths, "echo_spread")
        accumulate = opencl.program("echo_accumulate", defines=defines, double=double, preamble=preamble)
        self.k_bounds = cl.Kernel(accumulate, "echo_bounds")
        self.k_acc = cl.Kernel(accumulate, "echo_grid" if ph.grid is not None else "echo_accumulate")
        wf = sc.waveform
        self.params = np.zeros((), PARAMS)
        self.params["c"], self.params["f0"], self.params["fs"] = c, wf.f0, wf.fs
        self.params["wavelength"], self.params["tx_length"] = wf.wavelength(sc.medium), sc.array.tx_length
        self.params["dtau"] = self.rx_tau[1] - self.rx_tau[0]
        self.params["chirp_rate"], self.params["duration"] = wf.chirp_rate, wf.duration
        if ph.absorption is not None:
            self.params["abs_a0"], self.params["abs_a1"] = ph.absorption.a0, ph.absorption.a1
            self.params["abs_a2"] = ph.absorption.a2
        self.legs = [legs_record(kind) for kind in ph.kinds]

    def delay_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) (H,) s: bounds of the delay of every path the kernel can compute, over the
        pulses and path kinds: the (image) transmitter's distance to a box holding the
        scatterers then (the targets over the pulses and their flight, the facets in the pulse's
        reach) plus the box's distance to the box of receiver h's (image) nodes over the pulse,
        nearest and farthest, over c. The positions the kernel uses lie in those boxes."""
        c, sc = self.scenario.medium.sound_speed, self.scenario
        n_p = self.eta.size
        box_lo, box_hi = np.full((n_p, 3), np.inf), np.full((n_p, 3), -np.inf)
        n_t = self.floor_first
        if n_t:
            p0, vel = self.scat.p0[:n_t], self.scat.vel[:n_t]
            ends = [p0 + vel * self.eta[0], p0 + vel * (self.eta[-1] + self.rx_tau[-1])]
            box_lo[:] = np.minimum(ends[0].min(axis=0), ends[1].min(axis=0))
            box_hi[:] = np.maximum(ends[0].max(axis=0), ends[1].max(axis=0))
        spans = self.reach(slice(None))
        if spans is not None:
            facets = self.scat.p0[n_t:]
            size = 1024
            starts = np.arange(0, facets.shape[0], size)
            chunk_lo, chunk_hi = np.minimum.reduceat(facets, starts), np.maximum.reduceat(facets, starts)
            for p, (a, b) in enumerate(spans):
                if b > a:
                    k = slice(a // size, (b - 1) // size + 1)
                    box_lo[p] = np.minimum(box_lo[p], chunk_lo[k].min(axis=0))
                    box_hi[p] = np.maximum(box_hi[p], chunk_hi[k].max(axis=0))
        heard = np.all(np.isfinite(box_lo), axis=1)
        box_lo, box_hi = np.where(heard[:, None], box_lo, 0.0), np.where(heard[:, None], box_hi, 0.0)
        lo, hi = np.full(self.n_rx, np.inf), np.full(self.n_rx, -np.inf)
        for kind in self.physics.kinds:
            tx = kind.out.image.points(self.tx)  # (P, 3)
            out_lo = np.linalg.norm(np.clip(tx, box_lo, box_hi) - tx, axis=1)
            out_hi = np.linalg.norm(np.maximum(np.abs(tx - box_lo), np.abs(tx - box_hi)), axis=1)
            nodes = kind.back.image.points(self.rx_pos.reshape(-1, 3)).reshape(self.rx_pos.shape)  # (H, P, N, 3)
            r_lo, r_hi = nodes.min(axis=2), nodes.max(axis=2)
            gap = np.maximum(0.0, np.maximum(box_lo - r_hi, r_lo - box_hi))
            back_lo = np.linalg.norm(gap, axis=-1)
            back_hi = np.linalg.norm(np.maximum(np.abs(r_hi - box_lo), np.abs(box_hi - r_lo)), axis=-1)
            tau_lo, tau_hi = (out_lo + back_lo) / c, (out_hi + back_hi) / c  # (H, P)
            lo = np.minimum(lo, np.where(heard, tau_lo, np.inf).min(axis=1))
            hi = np.maximum(hi, np.where(heard, tau_hi, -np.inf).max(axis=1))
        return lo, hi

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

    def _run_paths(self, pulses: slice, t0: np.ndarray, weighted: bool = True, kinds=None, cull: bool = True,
                   delays_only: bool = False):
        """The paths kernel on a pulse block for the path ``kinds`` (indices; default every kind):
        delays and amplitudes (times the occlusion weights unless not ``weighted``: the delays and
        extents do not need them; the echo centres alone if ``delays_only``), of the targets and of
        the facets the block's beam reaches (every facet unless ``cull``). Returns (paths buffer,
        pulses, (jump, n_act, stride))."""
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
        w_buf, rx_buf, active_buf, beam_buf = (
            cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))
            for a in (w, rx, active, self.beam(pulses, cull)))
        paths_buf = cl.Buffer(ctx, mf.READ_WRITE, self.path_dtype.itemsize * h * pc * stride)
        kernel = self.k_paths_delays if delays_only else self.k_paths if weighted else self.k_paths_plain
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
                   active_buf, beam_buf, np.int32(pc), np.int32(w_rx), np.int32(stride), np.int32(slot * n_act),
                   np.int32(n_act // 8), paths_buf)
        return paths_buf, pc, (jump, n_act, stride)

    def delays(self, pulses: slice, kind: int = 0) -> np.ndarray:
        """Delays (H, P, N) of the block's paths of ``physics.kinds[kind]`` (0: direct) from the
        kernel, in scatterer order (every facet, in the beam's reach or not)."""
        h, n = self.n_rx, self.scat.count
        paths_buf, pc, (jump, n_act, stride) = self._run_paths(pulses, np.zeros(h), weighted=False, kinds=[kind],
                                                               cull=False, delays_only=True)
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
        then (kernels/echo_paths.cl ``echo_spread``)."""
        paths_buf, _, (_, n_act, stride) = self._run_paths(slice(pulse, pulse + 1), np.zeros(self.n_rx),
                                                           weighted=False, kinds=[0], delays_only=True)
        out = self.cl.Buffer(self.rt.context, self.cl.mem_flags.WRITE_ONLY, 16 * self.n_rx)
        self.k_spread(self.rt.queue, *groups(1, self.n_rx), paths_buf, np.int32(n_act), np.int32(stride), np.int32(1),
                      out)
        host = np.empty((self.n_rx, 2))
        self.cl.enqueue_copy(self.rt.queue, host, out)
        spread = host[:, 1] - host[:, 0]  # -inf for a receiver that hears nothing then
        return np.where(np.isfinite(spread), spread, 0.0) / self.scenario.waveform.fs

    def extents(self, pulses: slice, lo: np.ndarray, hi: np.ndarray) -> None:
        """Widen ``lo``, ``hi`` (H, N), in place, to (floor(min u), floor(max u) + 1) per (receiver,
        scatterer) over every path kind and the block's pulses that hear it (inf, -inf: none),
        reduced on the device; the facets the block's beam reaches are one contiguous range of
        scatterers, widened as a slice. The echo centres alone are computed (DELAYS_ONLY): pass B
        computes its own paths with their weights, in pulse blocks of its own."""
        paths_buf, pc, block = self._run_paths(pulses, np.zeros(self.n_rx), weighted=False, delays_only=True)
        self._widen(paths_buf, pc, block, lo, hi, np.zeros(self.n_rx, np.int64))

    def _widen(self, paths_buf, pc: int, block: tuple, lo: np.ndarray, hi: np.ndarray, offset: np.ndarray) -> None:
        """Widen ``lo``, ``hi`` (H, N) by the extents of a block's paths (:meth:`extents`) whose
        starts are ``offset`` (H,) samples after t = 0."""
        cl, q = self.cl, self.rt.queue
        h = self.n_rx
        jump, n_act, stride = block
        ext = cl.Buffer(self.rt.context, cl.mem_flags.WRITE_ONLY, 8 * h * stride)
        self.k_extents(q, *groups(stride, h), paths_buf, np.int32(stride), np.int32(pc), ext)
        host = np.empty((h, len(self.physics.kinds), n_act, 2), np.int32)
        cl.enqueue_copy(q, host, ext)

        def widen(positions: slice, scatterers):
            ext = host[:, :, positions]
            first = ext[:, 0, :, 0] if ext.shape[1] == 1 else ext[..., 0].min(axis=1)
            last = (ext[:, 0, :, 1] if ext.shape[1] == 1 else ext[..., 1].max(axis=1)) + 1
            heard = first != UNHEARD  # some pulse of the block hears it
            first, last = first + offset[:, None], last + offset[:, None]
            if isinstance(scatterers, slice):
                np.minimum(lo[:, scatterers], first, out=lo[:, scatterers], where=heard)
                np.maximum(hi[:, scatterers], last, out=hi[:, scatterers], where=heard)
                return
            for r in range(h):
                lo[r, scatterers[r]] = np.where(heard[r], np.minimum(lo[r, scatterers[r]], first[r]), lo[r, scatterers[r]])
                hi[r, scatterers[r]] = np.where(heard[r], np.maximum(hi[r, scatterers[r]], last[r]), hi[r, scatterers[r]])

        n_t = self.floor_first
        if n_t:
            widen(slice(0, n_t), self.target_index[:, :n_t])
        n_reach = min(n_act - self.split, self.scat.count - n_t - jump)  # the facets jump .. jump + n_reach
        if n_reach > 0:
            widen(slice(self.split, self.split + n_reach), slice(n_t + jump, n_t + jump + n_reach))

    def records(self, pulses: slice, t0: np.ndarray, n_samples: int, extents=None) -> np.ndarray:
        """The block's records (H, P, n_samples), the window of receiver h starting at t0[h] (a
        whole sample when ``extents`` is given: (lo, hi) (H, N) are then widened by the block's
        paths as :meth:`extents` does, so that one pass gives the records and the extents)."""
        cl, q = self.cl, self.rt.queue
        h = self.n_rx
        paths_buf, pc, block = self._run_paths(pulses, t0)
        n = block[2]
        if extents is not None:
            self._widen(paths_buf, pc, block, *extents, np.round(t0 * self.scenario.waveform.fs).astype(np.int64))
        n_chunks = -(-n // CHUNK_SCATTERERS)
        mf = cl.mem_flags
        bounds = cl.Buffer(self.rt.context, mf.READ_WRITE, 8 * h * pc * n_chunks)
        self.k_bounds(q, *groups(n_chunks, pc, h), paths_buf, self.real(self.half_len), np.int32(n), np.int32(pc),
                      bounds)
        if self.physics.grid is not None:
            return self._grid_records(paths_buf, bounds, n, pc, n_samples)
        rows = 16 * ROWS
        n_pad = -(-n_samples // rows) * rows
        out = cl.Buffer(self.rt.context, mf.WRITE_ONLY, np.dtype(self.cplx).itemsize * h * pc * n_pad)
        compressed = ()
        if self.physics.writes_taps:
            resp = self.physics.response
            compressed = (self.table_buf, np.int32(self.table_row), self.impulse_buf, np.int32(self.impulse_len),
                          np.int32(resp.lag0), np.int32(resp.edges[0]), np.int32(resp.edges[1]))
        self.k_acc(q, *groups(n_pad // rows, pc, h), paths_buf, bounds, self.real(self.alpha), self.real(self.half_len),
                   *compressed, np.int32(n), np.int32(pc), np.int32(n_pad), np.int32(n_samples), out)
        host = np.empty((h, pc, n_pad), self.cplx)
        cl.enqueue_copy(q, host, out)
        return host[:, :, :n_samples]

    def _grid_records(self, paths_buf, bounds, n: int, pc: int, n_samples: int) -> np.ndarray:
        """The grid route (:mod:`.grid`): the kernel's grids and tails, then the plan's FFT filter."""
        cl, q, plan = self.cl, self.rt.queue, self.physics.grid
        h, mf = self.n_rx, cl.mem_flags
        n_grid = plan.grid_samples(n_samples)
        size = np.dtype(self.cplx).itemsize
        grids = cl.Buffer(self.rt.context, mf.WRITE_ONLY, size * h * pc * plan.terms * grid.RATE * n_grid)
        tails = cl.Buffer(self.rt.context, mf.WRITE_ONLY, size * h * pc * n_grid)
        self.k_acc(q, *groups(n_grid // grid.BLOCK, pc, h), paths_buf, bounds, self.real(self.alpha),
                   self.real(self.half_len), self.taps_buf, np.int32(n), np.int32(pc), np.int32(n_grid), grids, tails)
        host_grids = np.empty((h, pc, plan.terms, grid.RATE * n_grid), self.cplx)
        host_tails = np.empty((h, pc, n_grid), self.cplx)
        cl.enqueue_copy(q, host_grids, grids)
        cl.enqueue_copy(q, host_tails, tails)
        return plan.finish(host_grids, host_tails, n_samples)

