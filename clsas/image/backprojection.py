"""Time-domain back-projection for any geometry (NumPy reference and OpenCL launcher).

For every pixel P (its position at t = 0; with ``target_velocity`` v it moves, P(t) = P + v t,
which focuses a moving target, Kiang & Kiang 2022), every selected receiver h and pulse p:

    tau   = t1 + t2, the exact two-way delay: transmitter at its emission position T(eta),
            the pixel met at eta + t1 with c t1 = |P(eta + t1) - T(eta)|, the receiver at
            eta + t1 + t2 with c t2 = |R_h(eta + t1 + t2) - P(eta + t1)| (the receiver's
            positions come from EchoData: linear between its nodes);
            ``stop_and_go=True`` evaluates all positions at eta;
    image(P) += s_h,p(tau) exp(+j 2 pi f0 tau),

s the range-compressed record sampled at ``t0_h + k / fs``: its value at tau comes from linear
interpolation of the record FFT-upsampled by ``upsample`` (``interp="linear"``) or from an
8-tap Kaiser-windowed sinc (beta = 5, :func:`clsas.kernelmath.kaiser_sinc_tap`) on the original
samples (``interp="sinc8"``). The rotation exp(+j 2 pi f0 tau) undoes the carrier phase
exp(-j 2 pi f0 tau) of the baseband echo (DESIGN.md signal model), so all contributions of a
scatterer add in phase at its pixel.

Aperture: ``aperture`` (radians, full integration angle) keeps only the pulses that see the
pixel within +-aperture/2 of broadside: |sin theta| <= sin(aperture / 2) with sin theta the
along-track (y) component of the unit vector from the transmitter to the pixel.

Precision (OpenCL, ``precision="single"``): the delays, the sample index and the carrier
cycles f0 tau are computed in double per pixel (the carrier phase at 2 km and 150 kHz is 4e5
cycles: float32 would lose 0.15 rad); the interpolation, the phase factor (fractional cycles,
polynomial sin/cos, error < 1e-6) and the accumulation are float. Sums are blocked: float over a
block of at most ``PULSE_BLOCK`` pulses (relative error below 256 x 6e-8 = 1.5e-5 even if every
rounding adds up; ~1e-6 typically), then added into a double image, so 10^5 pulses x receivers
lose nothing more. ``precision="double"`` runs the data path in double as well.
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from .. import backend as _backend
from .. import opencl
from ..data import EchoData, Grid, Image
from ..kernelmath import kaiser_sinc_tap
from ..scene.targets import Scatterers
from ..simulate import geometry
from .rangecomp import upsample_records

INTERPOLATORS = ("linear", "sinc8")
SINC_BETA = 5.0
TAP_ROWS = 2049  # sinc8 tap table rows over the fractional offset [0, 1] (nearest row is used)
UPLOAD_BYTES = 64 * 2**20  # upsampled records prepared and uploaded at once
PULSE_BLOCK = 8  # pulses a kernel launch: their records stay in cache while every pixel reads them


def _check_inputs(echo, grid, receivers, interp, upsample, aperture, target_velocity):
    if not isinstance(echo, EchoData):
        raise TypeError(f"echo must be an EchoData, got {type(echo).__name__}")
    if not echo.compressed:
        raise ValueError("echo is not range-compressed: call clsas.range_compress(echo) first "
                         "(back-projection refuses raw echoes rather than compressing them silently)")
    if not isinstance(grid, Grid):
        raise TypeError(f"grid must be a clsas.data.Grid (Grid.plane, Grid.slant or Grid.points), got "
                        f"{type(grid).__name__}")
    if interp not in INTERPOLATORS:
        raise ValueError(f"interp must be one of {INTERPOLATORS}, got {interp!r}")
    if isinstance(upsample, bool) or not isinstance(upsample, (int, np.integer)) or not 1 <= upsample <= 64:
        raise ValueError(f"upsample must be an integer in [1, 64], got {upsample!r}")
    if receivers is None:
        chosen = list(range(echo.n_rx))
    else:
        chosen = []
        for r in np.atleast_1d(receivers).tolist():
            if isinstance(r, str):
                if r not in echo.receivers:
                    raise ValueError(f"receivers: unknown receiver {r!r}; the echo has {echo.receivers}")
                r = echo.receivers.index(r)
            if isinstance(r, bool) or not isinstance(r, int) or not 0 <= r < echo.n_rx:
                raise ValueError(f"receivers must be indices in [0, {echo.n_rx - 1}] or names {echo.receivers}, "
                                 f"got {r!r}")
            chosen.append(r)
        if not chosen:
            raise ValueError("receivers is empty: select at least one receiver")
    if aperture is not None and not (np.isfinite(aperture) and 0 < aperture <= np.pi):
        raise ValueError(f"aperture must be a full integration angle in (0, pi] radians, got {aperture}")
    v = np.zeros(3) if target_velocity is None else np.asarray(target_velocity, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) >= 100:
        raise ValueError(f"target_velocity must be a finite 3-vector slower than 100 m/s, got {target_velocity!r}")
    return chosen, v


def pixel_delays(echo: EchoData, h: int, pulses: np.ndarray, pixels: np.ndarray, velocity: np.ndarray,
                 stop_and_go: bool) -> tuple[np.ndarray, np.ndarray]:
    """Exact two-way delays (len(pulses), M) from the pulses' transmitters to the M pixels and back
    to receiver h (float64 fixed point, :mod:`clsas.simulate.geometry`), and where the pulses meet
    the pixels (len(pulses), M, 3)."""
    c = echo.medium.sound_speed
    tol = geometry.iteration_tolerance(echo.waveform.f0)
    eta = echo.eta[pulses]
    targets = Scatterers(pixels, np.broadcast_to(velocity, pixels.shape), np.ones(pixels.shape[0], complex))
    t1, q = geometry.outgoing(echo.tx_pos[pulses], eta, targets, c, tol, stop_and_go)

    def receiver(t):
        return echo.rx_position(h, t - eta.reshape((-1,) + (1,) * (t.ndim - 1)), pulses=pulses)

    t2, _ = geometry.incoming(receiver, eta, t1, q, c, tol, stop_and_go)
    return t1 + t2, q


def _aperture_keep(echo, pulses, q, half_sin):
    """(P, M) mask: the pixel, at ``q`` where the pulse meets it, lies within the integration
    angle, |sin theta| <= half_sin, theta the angle of transmitter -> pixel off broadside (the
    x-z plane; y is the nominal heading)."""
    d = q - echo.tx_pos[pulses][:, None, :]
    return np.abs(d[..., 1] / np.linalg.norm(d, axis=-1)) <= half_sin


def _sample(records: np.ndarray, k: np.ndarray, interp: str) -> np.ndarray:
    """Records (P, n) read at fractional indices k (P, M).

    ``"linear"``: (1 - f) s[i] + f s[i + 1] with i = floor(k), f = k - i, zero unless both
    samples exist. ``"sinc8"``: sum_j w_j(f) s[i + j], j = -3..4, zero unless all eight exist,
    with the Kaiser-windowed sinc taps w_j(f) = kaiser_sinc_tap(f - j, 4, 5) evaluated at the
    fractional offset rounded to the nearest 1/(TAP_ROWS - 1) (the OpenCL kernel's tap table;
    the rounding of at most 1/4096 sample costs at most 2 pi (fs/4) / (4096 fs) = 4e-4 rad at the
    edge of a band sampled at twice its width).
    """
    n = records.shape[1]
    i = np.floor(k).astype(np.int64)
    frac = k - i
    rows = np.arange(records.shape[0])[:, None]

    def at(j):
        return records[rows, np.clip(j, 0, n - 1)]

    if interp == "linear":
        return np.where((i >= 0) & (i < n - 1), (1 - frac) * at(i) + frac * at(i + 1), 0)
    row = np.floor(frac * (TAP_ROWS - 1) + 0.5) / (TAP_ROWS - 1)
    out = np.zeros(k.shape, dtype=np.complex128)
    for j in range(-3, 5):
        out += kaiser_sinc_tap(row - j, 4.0, SINC_BETA) * at(i + j)
    return np.where((i >= 3) & (i < n - 4), out, 0)


def backproject_reference(echo, grid, receivers, interp, upsample, aperture, velocity, stop_and_go, progress):
    """The float64 NumPy reference (vectorised over pixels, a pulse block at a time): image (M,)."""
    pixels = grid.positions.reshape(-1, 3)
    image = np.zeros(pixels.shape[0], dtype=np.complex128)
    f0 = echo.waveform.f0
    factor = upsample if interp == "linear" else 1
    fs = echo.fs * factor
    block = max(1, int(2**22 // pixels.shape[0]))
    jobs = [(h, np.arange(s, min(s + block, echo.n_pulses))) for h in receivers
            for s in range(0, echo.n_pulses, block)]
    for h, pulses in tqdm(jobs, desc="back-projection (numpy)", disable=not progress):
        records = upsample_records(echo.data[h, pulses], factor).astype(np.complex128)
        tau, q = pixel_delays(echo, h, pulses, pixels, velocity, stop_and_go)
        value = _sample(records, (tau - echo.t0[h]) * fs, interp) * np.exp(2j * np.pi * f0 * tau)
        if aperture is not None:
            value *= _aperture_keep(echo, pulses, q, np.sin(aperture / 2))
        image += value.sum(axis=0)
    return image


def _tap_table() -> np.ndarray:
    frac = np.linspace(0.0, 1.0, TAP_ROWS)[:, None]
    return kaiser_sinc_tap(frac - np.arange(-3, 5)[None, :], 4.0, SINC_BETA).astype(np.float32)


def _uniform_nodes(echo: EchoData, h: int):
    nodes = echo.rx_tau[h]
    if nodes.size == 1:
        return 1.0, np.repeat(echo.rx_pos[h], 2, axis=1)
    step = nodes[1] - nodes[0]
    if nodes[0] != 0 or not np.allclose(np.diff(nodes), step, rtol=1e-9, atol=0):
        raise ValueError("the OpenCL back-projection needs receiver nodes (EchoData.rx_tau) uniformly spaced "
                         "from 0 (as clsas.simulate makes them); use backend='numpy' for other node layouts")
    return step, echo.rx_pos[h]


def backproject_opencl(echo, grid, receivers, interp, upsample, aperture, velocity, stop_and_go, progress,
                       double=False):
    """The kernels/backprojection.cl launcher: image (M,) complex128."""
    import pyopencl as cl

    rt = opencl.runtime()
    ctx, q = rt.context, rt.queue
    mf = cl.mem_flags
    pixels = grid.positions.reshape(-1, 3)
    m = pixels.shape[0]
    m_pad = -(-m // 8) * 8
    soa = np.zeros((3, m_pad))
    soa[:, :m] = pixels.T
    soa[:, m:] = pixels[-1][:, None]
    pix_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=soa)
    image = np.zeros(m_pad, dtype=np.complex128)
    image_buf = cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=image)
    taps_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=_tap_table())
    factor = upsample if interp == "linear" else 1
    fs = echo.fs * factor
    # records are upsampled and uploaded a large block at a time (few host round trips); the
    # kernel then sums PULSE_BLOCK pulses a launch so that their records stay in cache
    per_pulse = 16 * echo.n_samples * factor
    upload = max(PULSE_BLOCK, int(UPLOAD_BYTES // per_pulse) // PULSE_BLOCK * PULSE_BLOCK)
    jobs = [(h, np.arange(s, min(s + upload, echo.n_pulses))) for h in receivers
            for s in range(0, echo.n_pulses, upload)]
    kernels = {}
    for h, pulses in tqdm(jobs, desc="back-projection (opencl)", disable=not progress):
        dtau, pos = _uniform_nodes(echo, h)
        n_nodes = pos.shape[1]
        if n_nodes not in kernels:
            defines = {"N_NODES": n_nodes, "SEGMENT_PASSES": 1 if n_nodes == 2 else 3,
                       "INTERP_LINEAR" if interp == "linear" else "INTERP_SINC8": 1, "TAP_ROWS": TAP_ROWS}
            if stop_and_go:
                defines["STOP_AND_GO"] = 1
            if aperture is not None:
                defines["APERTURE"] = 1
            kernels[n_nodes] = opencl.kernel("backprojection", "bp_block", defines=defines, double=double)
        records = upsample_records(echo.data[h, pulses], factor).astype(np.complex128 if double else np.complex64)
        pulse = np.zeros((pulses.size, 8))
        pulse[:, 0:3], pulse[:, 3], pulse[:, 4] = echo.tx_pos[pulses], echo.eta[pulses], echo.t0[h] * fs
        nodes = np.zeros((pulses.size, n_nodes, 8))
        nodes[..., 0:3] = pos[pulses]
        bufs = [cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))
                for a in (pulse, nodes, records)]
        params = np.array([echo.medium.sound_speed, echo.waveform.f0, fs, dtau, *velocity,
                           np.sin(aperture / 2) if aperture is not None else 1.0])
        for first in range(0, pulses.size, PULSE_BLOCK):
            kernels[n_nodes](q, (m_pad // 8,), None, pix_buf, bufs[0], bufs[1], bufs[2], taps_buf,
                             params.view(cl.cltypes.double8)[0], np.int32(first),
                             np.int32(min(PULSE_BLOCK, pulses.size - first)), np.int32(records.shape[1]),
                             np.int32(m_pad), image_buf)
    cl.enqueue_copy(q, image, image_buf)
    return image[:m]


def backproject(echo: EchoData, grid: Grid, backend: str | None = None, receivers=None, interp: str = "linear",
                upsample: int = 8, aperture: float | None = None, target_velocity=None, stop_and_go: bool = False,
                precision: str = "single", progress: bool = True) -> Image:
    """Back-project range-compressed echoes onto ``grid`` (see the module docstring).

    Parameters
    ----------
    echo : EchoData, range-compressed (:func:`clsas.range_compress`).
    grid : Grid (plane, slant plane or any 3-D points).
    backend : {"numpy", "opencl", "auto"} or None.
    receivers : indices or names of the receivers to sum coherently (default: all).
    interp : {"linear", "sinc8"}
        Linear interpolation of data FFT-upsampled by ``upsample``, or an 8-tap windowed sinc
        on the original samples. The upsampling is redone at every call: to image many grids
        from one echo, upsample once with ``range_compress(echo, upsample=8)`` and pass
        ``upsample=1`` here.
    aperture : float, optional
        Full integration angle, radians.
    target_velocity : 3-vector, optional
        Velocity (m/s) of the pixels, to focus a target moving at it.
    stop_and_go : bool
        Use stop-and-go delays (all positions at the emission time).
    precision : {"single", "double"}
        The OpenCL kernel's data path (delays and carrier cycles are double either way).

    Returns
    -------
    Image with the grid's dims and axes, ``positions`` the grid's pixels, complex64.
    """
    chosen, velocity = _check_inputs(echo, grid, receivers, interp, upsample, aperture, target_velocity)
    double = _backend.check_precision(precision)
    name = _backend.resolve(backend)
    args = (echo, grid, chosen, interp, upsample, aperture, velocity, stop_and_go, progress)
    flat = backproject_reference(*args) if name == "numpy" else backproject_opencl(*args, double=double)
    return Image(data=flat.reshape(grid.shape), dims=grid.dims, axes=grid.axes, positions=grid.positions,
                 provenance={"algorithm": "backprojection", "backend": name, "precision": precision, "interp": interp,
                             "upsample": int(upsample), "receivers": [echo.receivers[h] for h in chosen],
                             "aperture": aperture, "target_velocity": velocity.tolist(),
                             "stop_and_go": bool(stop_and_go), "echo": dict(echo.provenance)})
