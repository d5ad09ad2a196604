"""Echo synthesis: ``simulate(scenario) -> EchoData`` (NumPy reference and OpenCL launcher).

Signal model (DESIGN.md): the baseband echo of path (receiver h, pulse p, scatterer n) is

    s(tau) = a rect((tau - tau_n) / T) exp(-j 2 pi f0 tau_n) exp(j pi K (tau - tau_n)^2),

tau_n the exact two-way delay and a the path amplitude of :mod:`clsas.simulate.geometry`
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
between them, :func:`clsas.simulate.window.receiver_nodes`); the reference evaluates the
scenario's trajectory exactly.

Noise (``snr_db``): Kiang & Kiang 2022 section VII-C adds white Gaussian noise "at a given
level" to the received signal s_rb1(tau, eta) of its eq. (7) without defining the SNR further;
clsas defines it per receiver as

    SNR = P_s / sigma^2,  P_s = mean of |s|^2 over the samples where the noise-free echo is nonzero,

with complex circular noise of variance sigma^2 (sigma^2 / 2 per real component) added to
every recorded sample. Seeded by ``seed``; the same seed gives the same noise on either backend.
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from .. import backend as _backend
from .. import opencl
from ..data import EchoData
from ..scene.scenario import Scenario
from ..scene.targets import Scatterers, scatterers_of
from . import geometry
from .occlusion import PathWeights, has_meshes
from .window import DEFAULT_MAX_BYTES, check_cube_size, node_span, receiver_nodes

CHUNK_SCATTERERS = 16  # scatterers per bounds chunk in the OpenCL accumulation
ROWS = 8  # 16-sample rows per work-item of the OpenCL accumulation


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
    """float64 reference: exact trajectories (geometry.paths) and accumulate_reference."""

    def paths(self, pulses: slice):
        tau, amp = geometry.paths(self.scenario, self.eta[pulses], self.scat, range(self.n_rx),
                                  self.stop_and_go, self.spreading)
        w = self.weights(pulses)
        return tau, amp if w is None else amp * w

    def delays(self, pulses: slice) -> np.ndarray:
        return geometry.paths(self.scenario, self.eta[pulses], self.scat, range(self.n_rx), self.stop_and_go,
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
        prg = opencl.program("echo", defines=defines, double=double)
        self.k_paths = cl.Kernel(prg, "echo_paths")
        self.k_bounds = cl.Kernel(prg, "echo_bounds")
        self.k_extents = cl.Kernel(prg, "echo_extents")
        self.k_acc = cl.Kernel(prg, "echo_accumulate")
        wf = sc.waveform
        self.params = np.array([c, wf.f0, wf.fs, wf.wavelength(sc.medium), sc.array.tx_length,
                                self.rx_tau[1] - self.rx_tau[0], 0.0, 0.0])

    def _delay_order(self) -> np.ndarray:
        """Per receiver, the scatterers sorted by their stop-and-go delay at the middle pulse (H, N).

        Sorting keeps each chunk of CHUNK_SCATTERERS compact in delay, so the accumulation skips
        whole chunks that cannot reach a block of samples; any order gives the same result.
        """
        mid = self.eta[self.eta.size // 2: self.eta.size // 2 + 1]
        tau, _ = geometry.paths(self.scenario, mid, self.scat, range(self.n_rx), stop_and_go=True)
        return np.argsort(tau[:, 0, :], axis=1, kind="stable")

    def _run_paths(self, pulses: slice, t0: np.ndarray):
        cl, q, ctx = self.cl, self.rt.queue, self.rt.context
        mf = cl.mem_flags
        idx = np.arange(self.eta.size)[pulses]
        pc, h, n = idx.size, self.n_rx, self.n_pad
        pulse = np.zeros((pc, 8))
        pulse[:, 0:3], pulse[:, 3], pulse[:, 4:7] = self.tx[idx], self.eta[idx], self.tx_axis[idx]
        nodes = np.zeros((h, pc, self.rx_tau.size, 8))
        nodes[..., 0:3], nodes[..., 3:6] = self.rx_pos[:, idx], self.rx_axis[:, idx]
        rx = np.column_stack([t0 * self.scenario.waveform.fs, self.scenario.receiver_lengths]).astype(np.float64)
        w = self.weights(pulses)
        w = np.ones(1, np.float32) if w is None else np.ascontiguousarray(w, dtype=np.float32)
        bufs = [cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))
                for a in (pulse, nodes, rx, w)]
        paths = cl.Buffer(ctx, mf.READ_WRITE, 4 * np.dtype(self.real).itemsize * h * pc * n)
        self.k_paths(q, (n // 8, pc, h), None, self.soa_buf, bufs[0], bufs[1], bufs[2], self.order_buf, bufs[3],
                     self.params.view(cl.cltypes.double8)[0], np.int32(self.scat.count), np.int32(n), np.int32(pc),
                     paths)
        return paths, pc

    def release(self) -> None:
        """Drop the cached path buffers (after pass B)."""
        self.cache.clear()
        self.cached_bytes = 0

    def delays(self, pulses: slice) -> np.ndarray:
        """Two-way delays (H, P, N) of the block from the kernel, in scatterer order."""
        h, n = self.n_rx, self.scat.count
        paths, pc = self._run_paths(pulses, np.zeros(h))
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
        """(floor(min u), floor(max u) + 1) per (receiver, scatterer), reduced on the device."""
        cl, q = self.cl, self.rt.queue
        h, n = self.n_rx, self.scat.count
        paths, pc = self._run_paths(pulses, np.zeros(h))
        if self.cached_bytes + 4 * np.dtype(self.real).itemsize * h * pc * self.n_pad <= self.cache_bytes:
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


def _pulse_blocks(n_pulses: int, per_pulse_bytes: int, chunk_bytes: int) -> list[slice]:
    size = int(max(1, min(n_pulses, chunk_bytes // max(1, per_pulse_bytes))))
    return [slice(s, min(s + size, n_pulses)) for s in range(0, n_pulses, size)]


def _delay_bound(scenario: Scenario, scat: Scatterers) -> float:
    """An upper bound guess of every delay (s) for the node span, from the first/middle/last pulses."""
    eta = scenario.eta[[0, scenario.eta.size // 2, -1]]
    c = scenario.medium.sound_speed
    tx = scenario.tx_position(eta)
    worst = 0.0
    for p in range(eta.size):
        q = scat.p0 + scat.vel * eta[p]
        out = np.linalg.norm(q - tx[p], axis=1)
        back = max(np.max(np.linalg.norm(q - scenario.receiver_position(h, eta[p]), axis=1))
                   for h in range(scenario.n_receivers))
        worst = max(worst, np.max(out) + back)
    return 1.2 * worst / c + scenario.waveform.duration


def _window(scenario: Scenario, lo: np.ndarray, hi: np.ndarray):
    """(t0 per receiver, valid samples per receiver, origin text) from the delay extents lo/hi (H, N)."""
    wf = scenario.waveform
    if scenario.recording is not None:
        t0, n_valid = scenario.recording.for_receivers(scenario.n_receivers)
        return np.asarray(t0, float), np.asarray(n_valid, np.int64), "given by Scenario.recording"
    first = np.floor((lo.min(axis=1) - 0.5 * wf.duration) * wf.fs)
    last = np.ceil((hi.max(axis=1) + 0.5 * wf.duration) * wf.fs)
    return first / wf.fs, (last - first + 1).astype(np.int64), "derived from the geometry"


def _check_targets_in_windows(scenario: Scenario, lo, hi, t0, n_valid) -> None:
    wf = scenario.waveform
    end = t0 + (n_valid - 1) / wf.fs
    heard = ((hi + 0.5 * wf.duration) >= t0[:, None]) & ((lo - 0.5 * wf.duration) <= end[:, None])
    deaf = np.flatnonzero(~heard.any(axis=0))
    if deaf.size:
        raise ValueError(
            f"{deaf.size} scatterer(s) (indices {deaf[:5].tolist()}{'...' if deaf.size > 5 else ''}) echo "
            f"between {lo[:, deaf[0]].min():.6g} and {hi[:, deaf[0]].max():.6g} s, outside every recording "
            f"window (Scenario.recording: starts {np.round(t0, 6).tolist()} s, {n_valid.tolist()} samples); "
            "move the targets or widen the window"
        )


def add_noise(data: np.ndarray, snr_db: float, seed, n_valid=None, block: int = 64) -> np.ndarray:
    """Add complex white Gaussian noise in place at ``snr_db`` per receiver (see the module docstring).

    ``data`` is (n_rx, n_pulses, n_samples); receiver h records only its first ``n_valid[h]``
    samples (default all), and only those get noise. Noise is drawn pulse block by pulse block
    (same draws for the same ``seed`` whatever the backend).
    """
    if not np.isfinite(snr_db):
        raise ValueError(f"snr_db must be a finite number of dB, got {snr_db}")
    n_valid = np.full(data.shape[0], data.shape[2]) if n_valid is None else np.asarray(n_valid)
    rng = np.random.default_rng(seed)
    power = np.empty(data.shape[0])
    for h in range(data.shape[0]):
        mag2 = np.abs(data[h, :, :n_valid[h]]) ** 2
        on = mag2 > 0
        if not on.any():
            raise ValueError(f"receiver {h} recorded no echo: its SNR is undefined")
        power[h] = mag2[on].mean()
    sigma = np.sqrt(power / 10 ** (snr_db / 10) / 2).astype(np.float32)
    for s in range(0, data.shape[1], block):
        part = data[:, s:s + block]
        noise = rng.standard_normal(part.shape + (2,), dtype=np.float32)
        noise = (noise[..., 0] + 1j * noise[..., 1]) * sigma[:, None, None]
        for h in range(part.shape[0]):
            part[h, :, :n_valid[h]] += noise[h, :, :n_valid[h]]
    return data


def _with_mesh_weights(scenario: Scenario, occlusion, stop_and_go: bool, hull_occlusion: bool):
    """The user's occlusion factor times the mesh targets' path weights (hull visibility and
    angular law, :class:`clsas.simulate.occlusion.PathWeights`) when the scene has meshes."""
    if not has_meshes(scenario):
        return occlusion
    mesh = PathWeights(scenario, stop_and_go=stop_and_go, hull_occlusion=hull_occlusion)
    if occlusion is None:
        return mesh
    if callable(occlusion):
        return lambda pulses: mesh(pulses) * np.asarray(occlusion(pulses), dtype=np.float64)
    return lambda pulses: mesh(pulses) * occlusion[:, pulses]


def _make_synth(scenario: Scenario, name: str, double: bool, occlusion, stop_and_go: bool, spreading: bool,
                chunk_bytes: int, hull_occlusion: bool = True):
    """The backend's synthesizer and the pulse blocks that keep its working memory under ``chunk_bytes``."""
    scat = scatterers_of(scenario.targets)
    if scat.count == 0:
        raise ValueError("Scenario.targets is empty: add PointTargets or a mesh target to simulate echoes")
    n_rx, n_pulses = scenario.n_receivers, scenario.eta.size
    if occlusion is not None and not callable(occlusion):
        occlusion = np.asarray(occlusion, dtype=np.float64)
        if occlusion.shape != (n_rx, n_pulses, scat.count):
            raise ValueError(f"occlusion must have shape (n_rx, n_pulses, n_scatterers) = "
                             f"{(n_rx, n_pulses, scat.count)}, got {occlusion.shape}")
    occlusion = _with_mesh_weights(scenario, occlusion, stop_and_go, hull_occlusion)
    args = (scenario, scat, occlusion, stop_and_go, spreading)
    if name == "numpy":
        span = int(0.5 * scenario.waveform.duration * scenario.waveform.fs) + 2
        synth = _NumpySynth(*args)
        per_pulse = n_rx * scat.count * (16 * 8 + 48 * span)
    else:
        tau_hi = node_span(scenario, scenario.eta, _delay_bound(scenario, scat))
        synth = _OpenCLSynth(*args, double=double,
                             nodes=receiver_nodes(scenario, scenario.eta, tau_hi, strict=not stop_and_go))
        per_pulse = n_rx * scat.count * 4 * 8  # path records (float4 or double4) on the device
    return synth, _pulse_blocks(n_pulses, per_pulse, int(chunk_bytes))


def delays(scenario: Scenario, backend: str | None = None, stop_and_go: bool = False) -> np.ndarray:
    """Exact two-way delays of every (receiver, pulse, scatterer) path, s, shape (H, P, N).

    The NumPy backend iterates the fixed point of :mod:`clsas.simulate.geometry`; the OpenCL
    kernel solves each leg in closed form (kernels/echo.cl, ``meet_time``) and returns the
    delay as the sample index it hands to the accumulation (float32 fraction: ~3e-12 s at 20 kHz).
    """
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    synth, blocks = _make_synth(scenario, _backend.resolve(backend), False, None, stop_and_go, False, 256 * 2**20)
    return np.concatenate([synth.delays(sl) for sl in blocks], axis=1)


def _synthesize(scenario: Scenario, name: str, double: bool, stop_and_go: bool, progress: bool, spreading: bool,
                occlusion, max_bytes: int, chunk_bytes: int, hull_occlusion: bool = True, dtype=None) -> dict:
    """Both passes; returns the cube in ``dtype`` (default: the backend's own precision,
    complex128 for NumPy and precision="double", complex64 otherwise) with its window and
    receiver nodes."""
    synth, blocks = _make_synth(scenario, name, double, occlusion, stop_and_go, spreading, chunk_bytes,
                                hull_occlusion)
    wf = scenario.waveform
    n_rx, n_pulses, n_scat = scenario.n_receivers, scenario.eta.size, synth.scat.count
    lo = np.full((n_rx, n_scat), np.inf)
    hi = np.full((n_rx, n_scat), -np.inf)
    for sl in tqdm(blocks, desc="echo delays", disable=not progress, leave=False):
        a, b = synth.extents(sl)
        lo, hi = np.minimum(lo, a), np.maximum(hi, b)
    lo, hi = lo / wf.fs, hi / wf.fs  # s, whole samples
    # the nodes span the recording window (and not beyond sampled motion errors)
    tau_span = node_span(scenario, scenario.eta, hi.max() + 0.5 * wf.duration + 2 / wf.fs)
    if name == "opencl" and hi.max() > synth.rx_tau[-1]:
        synth = _OpenCLSynth(*synth.args, double=double,
                             nodes=receiver_nodes(scenario, scenario.eta, tau_span, strict=not stop_and_go))
    t0, n_valid, origin = _window(scenario, lo, hi)
    _check_targets_in_windows(scenario, lo, hi, t0, n_valid)
    n_samples = int(n_valid.max())
    nodes = (synth.rx_tau, synth.rx_pos, synth.rx_node_error) if name == "opencl" else \
        (lambda n: (n[0], n[1], n[3]))(receiver_nodes(scenario, scenario.eta, tau_span, strict=False))
    check_cube_size(n_rx, n_pulses, n_samples, max_bytes, origin, n_nodes=nodes[0].size)
    native = np.complex64 if name == "opencl" and not double else np.complex128
    data = np.zeros((n_rx, n_pulses, n_samples), dtype=dtype or native)
    # pass B in blocks that also bound the records' memory (complex128 on the host, the
    # kernel's output buffer and its copy)
    per_pulse = n_rx * (synth.scat.count * 32 + 3 * 16 * n_samples)
    for sl in tqdm(_pulse_blocks(n_pulses, per_pulse, chunk_bytes), desc=f"echo synthesis ({name})",
                   disable=not progress):
        block = synth.records(sl, t0, n_samples)
        if not np.all(np.isfinite(block)):
            raise ValueError("the echo has non-finite samples: a scatterer coincides with the transmitter or a "
                             "receiver (zero path length); move it away")
        data[:, sl] = block
    synth.release()
    for h in range(n_rx):
        data[h, :, n_valid[h]:] = 0
    return {"data": data, "t0": t0, "n_valid": n_valid, "origin": origin, "nodes": nodes[:2],
            "node_error_m": float(nodes[2]), "n_scatterers": n_scat}


def simulate(scenario: Scenario, backend: str | None = None, stop_and_go: bool = False, snr_db: float | None = None,
             seed=None, precision: str = "single", progress: bool = True, spreading: bool = False,
             occlusion=None, max_bytes: int = DEFAULT_MAX_BYTES, chunk_bytes: int = 256 * 2**20,
             hull_occlusion: bool = True) -> EchoData:
    """Synthesize the raw echoes of ``scenario`` (see the module docstring for the model).

    Parameters
    ----------
    scenario : Scenario with at least one target (``Scenario.targets``).
    backend : {"numpy", "opencl", "auto"} or None (the current default, :func:`clsas.use_backend`).
    stop_and_go : bool
        Evaluate every position at the emission time (for comparisons) instead of the exact
        non-stop-and-go delays.
    snr_db : float, optional
        Add white Gaussian noise at this SNR (definition in the module docstring); ``seed`` seeds it.
    precision : {"single", "double"}
        Accumulation precision of the OpenCL kernel (delays are always double). The returned
        samples are complex64 either way (DESIGN.md).
    progress : bool
        Show tqdm progress bars over pulse blocks.
    spreading : bool
        Include the spherical spreading 1 / (R1 R2).
    occlusion : None, array (n_rx, n_pulses, n_scatterers) or callable
        Factor per path (1 = seen, 0 = hidden); a callable ``occlusion(pulses: slice)`` returns
        the block (n_rx, len(pulses), n_scatterers), so that memory stays bounded. Mesh targets
        multiply it by their own path weights (hull visibility by Embree ray casting and the
        facets' angular law, :mod:`clsas.simulate.occlusion`).
    hull_occlusion : bool
        Cast rays for the hull occlusion of mesh targets (False keeps only back-facing
        darkness and the angular law).
    max_bytes : int
        Largest echo cube allowed (complex64); larger requests are refused before allocation.
    chunk_bytes : int
        Working memory per pulse block.

    Returns
    -------
    EchoData, raw (not range-compressed), complex64 (n_rx, n_pulses, n_samples). The recording
    window of receiver h starts at ``t0[h]`` (from the geometry: earliest echo minus T/2, to
    the latest plus T/2, unless ``Scenario.recording`` gives it); its samples beyond its own
    window length (``provenance["n_valid"]``) are zero.
    """
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    name = _backend.resolve(backend)
    double = _backend.check_precision(precision)
    if snr_db is not None and not np.isfinite(snr_db):
        raise ValueError(f"snr_db must be a finite number of dB or None, got {snr_db}")
    if int(max_bytes) <= 0 or int(chunk_bytes) <= 0:
        raise ValueError("max_bytes and chunk_bytes must be positive numbers of bytes")
    if scenario.recording is not None:
        _, n_valid = scenario.recording.for_receivers(scenario.n_receivers)
        check_cube_size(scenario.n_receivers, scenario.eta.size, int(np.max(n_valid)), max_bytes,
                        "given by Scenario.recording")
    out = _synthesize(scenario, name, double, stop_and_go, progress, spreading, occlusion, int(max_bytes),
                      int(chunk_bytes), hull_occlusion, dtype=np.complex64)
    data = out["data"]
    if snr_db is not None:
        add_noise(data, float(snr_db), seed, out["n_valid"])
    rx_tau, rx_pos = out["nodes"]
    n_rx = scenario.n_receivers
    return EchoData(
        data=data, eta=scenario.eta, t0=out["t0"], fs=scenario.waveform.fs,
        tx_pos=scenario.tx_position(scenario.eta), rx_pos=rx_pos, rx_tau=np.tile(rx_tau, (n_rx, 1)),
        waveform=scenario.waveform, medium=scenario.medium, receivers=scenario.receiver_names, compressed=False,
        provenance={"algorithm": "clsas.simulate", "backend": name, "precision": precision,
                    "stop_and_go": bool(stop_and_go), "spreading": bool(spreading), "snr_db": snr_db,
                    "seed": seed if seed is None or isinstance(seed, int) else str(seed),
                    "n_scatterers": out["n_scatterers"], "occlusion": occlusion is not None,
                    "hull_occlusion": bool(hull_occlusion and has_meshes(scenario)),
                    "window": out["origin"], "n_valid": out["n_valid"].tolist(),
                    "rx_node_error_m": out["node_error_m"]},
    )
