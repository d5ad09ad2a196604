"""Echo synthesis, the maths and its fast twin: the float64 NumPy reference and the launcher of
``kernels/echo.cl``, side by side (:mod:`.pipeline` drives them).

Signal model (DESIGN.md): the baseband echo of path (receiver h, pulse p, scatterer n) is

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

import numpy as np

from ... import geometry, opencl
from ..paths import direct_paths
from ...cstruct import declare_all, record_dtype
from ...scene.scenario import Scenario
from ...scene.targets import Scatterers

CHUNK_SCATTERERS = 16  # scatterers per bounds chunk in the OpenCL accumulation
ROWS = 8  # 16-sample rows per work-item of the OpenCL accumulation
# the records echo_paths reads (kernels/echo.cl): a pulse, a receiver and the launch's parameters
PULSE = record_dtype([("tx", "f8", 3), ("eta", "f8"), ("tx_axis", "f8", 3)])  # m, s, unit vector
RECEIVER = record_dtype([("t0_fs", "f8"), ("length", "f8")])  # window start in samples, element length m
PARAMS = record_dtype([("c", "f8"), ("f0", "f8"), ("fs", "f8"), ("wavelength", "f8"), ("tx_length", "f8"),
                       ("dtau", "f8")])  # m/s, Hz, Hz, m, m, receiver node spacing s
RECORDS = declare_all({"node_t": geometry.NODE, "echo_pulse_t": PULSE, "echo_rx_t": RECEIVER,
                       "echo_params_t": PARAMS})


def accumulate_reference(start, frac, amp, alpha: float, half_len: float, n_samples: int) -> np.ndarray:
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

    Returns complex128 (R, n_samples): sample k of record r holds
    sum_n amp[r, n] exp(j 2 pi alpha d^2) [|d| <= half_len], d = k - start[r, n] - frac[r, n].
    """
    start = np.asarray(start)
    span = int(half_len) + 2
    offsets = np.arange(-span, span + 1)
    out = np.zeros((start.shape[0], n_samples), dtype=np.complex128)
    for r in range(start.shape[0]):
        k = start[r][:, None] + offsets[None, :]
        d = offsets[None, :] - frac[r][:, None]
        keep = (np.abs(d) <= half_len) & (k >= 0) & (k < n_samples)
        vals = (amp[r][:, None] * np.exp(2j * np.pi * alpha * d * d))[keep]
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

    def __init__(self, scenario: Scenario, scat: Scatterers, occlusion, stop_and_go: bool, spreading: bool):
        self.args = (scenario, scat, occlusion, stop_and_go, spreading)
        self.scenario, self.scat, self.occlusion = scenario, scat, occlusion
        self.stop_and_go, self.spreading = stop_and_go, spreading
        self.eta = scenario.eta
        self.n_rx = scenario.n_receivers
        wf = scenario.waveform
        self.alpha = 0.5 * wf.chirp_rate / wf.fs**2
        self.half_len = 0.5 * wf.duration * wf.fs

    def weights(self, pulses: slice):
        if self.occlusion is None:
            return None
        if callable(self.occlusion):
            w = np.asarray(self.occlusion(pulses), dtype=np.float64)
        else:
            w = self.occlusion[:, pulses]
        shape = (self.n_rx, len(range(*pulses.indices(self.eta.size))), self.scat.count)
        if w.shape != shape or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError(f"occlusion for pulses {pulses} must be finite, >= 0, with shape {shape}, got {w.shape}")
        return w


class _NumpySynth(_Synth):
    """float64 reference: exact trajectories (clsas.synthesis.paths) and accumulate_reference."""

    def paths(self, pulses: slice):
        tau, amp = direct_paths(self.scenario, self.eta[pulses], self.scat, range(self.n_rx),
                                  self.stop_and_go, self.spreading)
        w = self.weights(pulses)
        return tau, amp if w is None else amp * w

    def delays(self, pulses: slice) -> np.ndarray:
        return direct_paths(self.scenario, self.eta[pulses], self.scat, range(self.n_rx), self.stop_and_go,
                              self.spreading)[0]

    def release(self) -> None:
        """Nothing is cached by the reference."""

    def extents(self, pulses: slice):
        return sample_extents(self.delays(pulses) * self.scenario.waveform.fs)

    def records(self, pulses: slice, t0: np.ndarray, n_samples: int) -> np.ndarray:
        wf = self.scenario.waveform
        tau, amp = self.paths(pulses)
        amp = amp * np.exp(-2j * np.pi * wf.f0 * tau)
        start, frac = _split(tau, t0, wf.fs)
        h, p, n = tau.shape
        out = accumulate_reference(start.reshape(h * p, n), frac.reshape(h * p, n), amp.reshape(h * p, n),
                                   self.alpha, self.half_len, n_samples)
        return out.reshape(h, p, n_samples)


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
        sc, scat = self.scenario, self.scat
        c = sc.medium.sound_speed
        self.rx_tau, self.rx_pos, self.rx_axis, self.rx_node_error = nodes
        n = scat.count
        self.n_pad = -(-n // 8) * 8  # the paths kernel takes eight scatterers a work-item
        self.order = self._delay_order()
        padded = np.concatenate([self.order, np.repeat(self.order[:, -1:], self.n_pad - n, axis=1)], axis=1)
        fields = np.concatenate([scat.p0, scat.vel, scat.refl.real[:, None], scat.refl.imag[:, None]], axis=1)
        soa = np.ascontiguousarray(np.transpose(fields[padded], (0, 2, 1)))  # (H, 8 fields, n_pad)
        soa[:, 6:, n:] = 0.0  # padding scatterers reflect nothing
        mf = cl.mem_flags
        ctx = self.rt.context
        self.soa_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=soa)
        self.order_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=padded.astype(np.int32))
        self.tx = sc.tx_position(self.eta)
        self.tx_axis = sc.platform.rotation(self.eta)[..., :, 1]
        defines = {
            "N_NODES": self.rx_tau.size,
            "SEGMENT_PASSES": 1 if self.rx_tau.size == 2 else 3,
            "CHUNK": CHUNK_SCATTERERS,
            "ROWS": ROWS,
        }
        for flag, on in (("STOP_AND_GO", self.stop_and_go), ("SPREADING", self.spreading),
                         ("PATH_WEIGHTS", self.occlusion is not None)):
            if on:
                defines[flag] = 1
        prg = opencl.program("echo", defines=defines, double=double, preamble=RECORDS)
        self.k_paths = cl.Kernel(prg, "echo_paths")
        # delays and extents need no weights: their paths come from a build without them
        plain = {key: value for key, value in defines.items() if key != "PATH_WEIGHTS"}
        self.k_paths_plain = self.k_paths if plain == defines else \
            cl.Kernel(opencl.program("echo", defines=plain, double=double, preamble=RECORDS), "echo_paths")
        self.k_bounds = cl.Kernel(prg, "echo_bounds")
        self.k_extents = cl.Kernel(prg, "echo_extents")
        self.k_acc = cl.Kernel(prg, "echo_accumulate")
        wf = sc.waveform
        self.params = np.zeros((), PARAMS)
        self.params["c"], self.params["f0"], self.params["fs"] = c, wf.f0, wf.fs
        self.params["wavelength"], self.params["tx_length"] = wf.wavelength(sc.medium), sc.array.tx_length
        self.params["dtau"] = self.rx_tau[1] - self.rx_tau[0]

    def _delay_order(self) -> np.ndarray:
        """Per receiver, the scatterers sorted by their stop-and-go delay at the middle pulse (H, N).

        Sorting keeps each chunk of CHUNK_SCATTERERS compact in delay, so the accumulation skips
        whole chunks that cannot reach a block of samples; any order gives the same result.
        """
        mid = self.eta[self.eta.size // 2: self.eta.size // 2 + 1]
        tau, _ = direct_paths(self.scenario, mid, self.scat, range(self.n_rx), stop_and_go=True)
        return np.argsort(tau[:, 0, :], axis=1, kind="stable")

    def _run_paths(self, pulses: slice, t0: np.ndarray, weighted: bool = True):
        """The paths kernel on a pulse block: delays and amplitudes (times the occlusion weights
        unless not ``weighted``: the delays and extents do not need them)."""
        cl, q, ctx = self.cl, self.rt.queue, self.rt.context
        mf = cl.mem_flags
        idx = np.arange(self.eta.size)[pulses]
        pc, h, n = idx.size, self.n_rx, self.n_pad
        pulse = np.zeros(pc, PULSE)
        pulse["tx"], pulse["eta"], pulse["tx_axis"] = self.tx[idx], self.eta[idx], self.tx_axis[idx]
        nodes = np.zeros((h, pc, self.rx_tau.size), geometry.NODE)
        nodes["pos"], nodes["axis"] = self.rx_pos[:, idx], self.rx_axis[:, idx]
        rx = np.zeros(h, RECEIVER)
        rx["t0_fs"], rx["length"] = t0 * self.scenario.waveform.fs, self.scenario.receiver_lengths
        w = self.weights(pulses) if weighted else None
        w = np.ones(1, np.float32) if w is None else np.ascontiguousarray(w, dtype=np.float32)
        bufs = [cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))
                for a in (pulse, nodes, rx, w)]
        paths = cl.Buffer(ctx, mf.READ_WRITE, 4 * np.dtype(self.real).itemsize * h * pc * n)
        kernel = self.k_paths if weighted else self.k_paths_plain
        kernel(q, (n // 8, pc, h), None, self.soa_buf, bufs[0], bufs[1], bufs[2], self.order_buf, bufs[3],
               self.params[()], np.int32(self.scat.count), np.int32(n), np.int32(pc), paths)
        return paths, pc

    def release(self) -> None:
        """Drop the cached path buffers (after pass B)."""
        self.cache.clear()
        self.cached_bytes = 0

    def delays(self, pulses: slice) -> np.ndarray:
        """Two-way delays (H, P, N) of the block from the kernel, in scatterer order."""
        h, n = self.n_rx, self.scat.count
        paths, pc = self._run_paths(pulses, np.zeros(h), weighted=False)
        host = np.empty((h, pc, self.n_pad, 4), self.real)
        self.cl.enqueue_copy(self.rt.queue, host, paths)
        host = host[:, :, :n]
        start = host[..., 0].view(np.int32) if self.real == np.float32 else host[..., 0]
        frac = host[..., 1]
        tau = np.empty((h, pc, n))
        tau[np.arange(h)[:, None, None], np.arange(pc)[None, :, None], self.order[:, None, :]] = \
            (start + frac.astype(np.float64)) / self.scenario.waveform.fs
        return tau

    def extents(self, pulses: slice):
        """(floor(min u), floor(max u) + 1) per (receiver, scatterer), reduced on the device. With
        an occlusion factor the paths are computed unweighted and not kept for pass B: the
        weights (hull ray casting for meshes) are then computed once, by pass B, whose pulse
        blocks need not match these."""
        cl, q = self.cl, self.rt.queue
        h, n = self.n_rx, self.scat.count
        paths, pc = self._run_paths(pulses, np.zeros(h), weighted=False)
        reusable = self.occlusion is None  # unweighted paths are pass B's paths only without weights
        if reusable and self.cached_bytes + 4 * np.dtype(self.real).itemsize * h * pc * self.n_pad <= self.cache_bytes:
            self.cache[(pulses.start, pulses.stop)] = (paths, pc)
            self.cached_bytes += 4 * np.dtype(self.real).itemsize * h * pc * self.n_pad
        ext = cl.Buffer(self.rt.context, cl.mem_flags.WRITE_ONLY, 8 * h * self.n_pad)
        self.k_extents(q, (self.n_pad, h), None, paths, np.int32(self.n_pad), np.int32(pc), ext)
        host = np.empty((h, self.n_pad, 2), np.int32)
        cl.enqueue_copy(q, host, ext)
        lo, hi = np.empty((h, n)), np.empty((h, n))
        rows = np.arange(h)[:, None]
        lo[rows, self.order] = host[:, :n, 0]
        hi[rows, self.order] = host[:, :n, 1] + 1.0
        return lo, hi

    def records(self, pulses: slice, t0: np.ndarray, n_samples: int) -> np.ndarray:
        """The block's records; reuses the paths of extents() when the window starts on a whole sample."""
        cl, q = self.cl, self.rt.queue
        h, n = self.n_rx, self.n_pad
        first = t0 * self.scenario.waveform.fs
        whole = np.all(np.abs(first - np.round(first)) < 1e-6) and np.all(np.abs(first) < 2**31)
        cached = self.cache.pop((pulses.start, pulses.stop), None) if whole else None
        if cached is not None:
            paths, pc = cached
            shift = np.round(first).astype(np.int32)
        else:
            paths, pc = self._run_paths(pulses, t0)
            shift = np.zeros(h, np.int32)
        n_chunks = -(-n // CHUNK_SCATTERERS)
        mf = cl.mem_flags
        bounds = cl.Buffer(self.rt.context, mf.READ_WRITE, 8 * h * pc * n_chunks)
        self.k_bounds(q, (n_chunks, pc, h), None, paths, np.int32(n), np.int32(pc), bounds)
        rows = 16 * ROWS
        n_pad = -(-n_samples // rows) * rows
        out = cl.Buffer(self.rt.context, mf.WRITE_ONLY, np.dtype(self.cplx).itemsize * h * pc * n_pad)
        shift_buf = cl.Buffer(self.rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=shift)
        self.k_acc(q, (n_pad // rows, pc, h), None, paths, bounds, self.real(self.alpha), self.real(self.half_len),
                   np.int32(n), np.int32(pc), np.int32(n_pad), np.int32(n_samples), shift_buf, out)
        host = np.empty((h, pc, n_pad), self.cplx)
        cl.enqueue_copy(q, host, out)
        return host[:, :, :n_samples]


def sample_extents(u: np.ndarray):
    """Echo-centre extents per (receiver, scatterer) over the pulses of ``u`` (H, P, N), in samples
    from t = 0, rounded outwards to whole samples: (floor(min u), floor(max u) + 1). Both
    backends report extents this way (the OpenCL kernel returns floor(u) directly), so that
    they derive the same recording window."""
    return np.floor(u.min(axis=1)), np.floor(u.max(axis=1)) + 1
