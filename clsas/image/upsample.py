"""Upsampling of complex records by a polyphase Kaiser-windowed-sinc FIR: the OpenCL launcher
(``kernels/upsample.cl``) and its NumPy twin.

Back-projection's linear interpolator reads records upsampled by ``factor`` (default 8). The
exact band-limited upsampling is an FFT (:func:`clsas.image.rangecomp.upsample_records`); this
FIR approximates it with ``TAPS`` original samples an output, cheaply enough to run on the device
in every call, and every output depends only on the samples around it (no blocks, no spans).

Output q = factor (j - first) + p of a row is the record at original position x = j + p / factor:
p = 0 is the sample j itself, p > 0 is

    sum_t h(p / factor - (t - HALF)) s[j - HALF + t],   t = 0 .. TAPS - 1,  HALF = TAPS / 2 - 1,

with h(x) = sinc(x) I0(beta sqrt(1 - (2 x / TAPS)^2)) / I0(beta) (:func:`clsas.kernelmath.kaiser_sinc_tap`)
and samples outside the record read as zero (as the FFT's zero padding does).

Departure from exact band-limited upsampling. For a tone at f cycles a sample, phase p's response
is H_p(f) = sum_t h(p / factor - (t - HALF)) exp(j 2 pi f (t - HALF)) against the exact
exp(j 2 pi f p / factor); its worst case over |f| <= B / (2 fs) and the phases,
:func:`worst_tone_error`, is what the design bounds: with TAPS = 24 and beta = 7.5 it stays below
4e-4 over |f| <= 0.4 (fs >= 1.25 B), a thirtieth of the linear interpolator's own error on x8
records at that band edge ((2 pi 0.4 / 8)^2 / 8 = 1.2e-2), and falls fast at lower band edges.
Near the Nyquist edge no short FIR holds: above ``MAX_BAND`` (fs < 1.25 B) the records are
upsampled by FFT instead, block by block (:func:`upsample_blocks`). tests/test_upsample.py
holds both the tone bound and the departure on simulated records.

FFT blocks. Block b holds the original samples [b UPSAMPLE_BLOCK, (b + 1) UPSAMPLE_BLOCK) and its
FFT also reads UPSAMPLE_GUARD samples on each side (zeros outside the record): the block plus its
guards (512 samples) is transformed, its spectrum zero-padded to ``factor`` times its length
(:func:`clsas.image.rangecomp._upsample_spectrum`), transformed back, and the block's own part
kept. A sample therefore depends on its block only, not on the span or on how many records are
transformed at once. The guard truncates the band-limited interpolation kernel: the blocks depart
from one FFT of the whole zero-padded record (:func:`clsas.image.rangecomp.upsample_records`) by
far less than linear interpolation's own error (tests/test_backprojection.py holds the
difference). Small FFTs (512 -> 4096 points) stay in cache. They run on the host (scipy.fft): an
OpenCL FFT on PoCL was many times slower.
"""

from __future__ import annotations

from functools import lru_cache

import os

import numpy as np
import scipy.fft

from .. import budget, opencl
from .. import validate as v
from ..kernelmath import kaiser_sinc_tap
from .rangecomp import _upsample_spectrum

TAPS = 24
BETA = 7.5
HALF = TAPS // 2 - 1
MAX_BAND = 0.4  # the largest occupied band edge, cycles a sample (B / (2 fs)), the FIR serves
ROWS_GROUP = 8  # rows a work-group of the kernel (opencl.work_groups_2d)
UPSAMPLE_BLOCK = 384  # original samples a block of the FFT upsampling keeps (the FFT: 512 points)
UPSAMPLE_GUARD = 64  # original samples each side a block's FFT reads beyond it
FFT_BATCH_BYTES = 32 * 2**20  # upsampled spectra in memory at once


@lru_cache(maxsize=16)
def _taps64(factor: int) -> np.ndarray:
    """:func:`fir_taps` in float64 (read-only, cached)."""
    p = np.arange(factor)[:, None] / factor
    t = np.arange(TAPS)[None, :] - HALF
    table = kaiser_sinc_tap(p - t, TAPS / 2, BETA)
    table[0] = 0.0
    table[0, HALF] = 1.0
    table.flags.writeable = False
    return table


@lru_cache(maxsize=16)
def fir_taps(factor: int) -> np.ndarray:
    """(factor, TAPS) float32: phase p's taps on samples j - HALF .. j - HALF + TAPS - 1 (row 0,
    the sample itself, is the unit impulse at t = HALF). Read-only (cached)."""
    table = _taps64(factor).astype(np.float32)
    table.flags.writeable = False
    return table


def phase_vectors(factor: int) -> np.ndarray:
    """(ceil(factor / 8), TAPS, 16) float32: the kernel's tap vectors, lane 2 q + c of vector v at
    step t = :func:`fir_taps` [8 v + q, t] for both parts c (zero for phases 8 v + q >= factor)."""
    n_vec = -(-factor // 8)
    table = np.zeros((8 * n_vec, TAPS), np.float32)
    table[:factor] = fir_taps(factor)
    return np.ascontiguousarray(np.repeat(table.reshape(n_vec, 8, TAPS).transpose(0, 2, 1), 2, axis=2))


def mirror_vectors(factor: int) -> np.ndarray:
    """(TAPS / 2, 16) float32: the kernel's tap table for factors up to 8 (MIRROR: phases q and
    factor - q, whose taps are mirror images, h_{factor - q}[t] = h_q[TAPS - 1 - t], from one pass
    over the sample pairs t, TAPS - 1 - t): lane 2 q of row t is S_q[t] = (h_q[t] + h_q[TAPS - 1 - t]) / 2,
    lane 2 q + 1 is D_q[t] = (h_q[t] - h_q[TAPS - 1 - t]) / 2, for 1 <= q <= factor / 2 (computed in
    float64, then rounded: phase q is S_q (a + b) + D_q (a - b) over the pairs a, b, phase factor - q
    S_q (a + b) - D_q (a - b), phase factor / 2 S (a + b) alone)."""
    if factor > 8:
        raise ValueError(f"mirror_vectors factor: at most 8 (one phase vector), got {factor}")
    h = _taps64(factor)
    table = np.zeros((TAPS // 2, 16))
    for q in range(1, factor // 2 + 1):
        a, b = h[q, :TAPS // 2], h[q, TAPS - 1:TAPS // 2 - 1:-1]
        table[:, 2 * q] = 0.5 * (a + b)
        table[:, 2 * q + 1] = 0.5 * (a - b) if 2 * q < factor else 0.0
    return np.ascontiguousarray(table, dtype=np.float32)


def worst_tone_error(factor: int, band: float = MAX_BAND, n_freq: int = 801) -> float:
    """max over |f| <= ``band`` (cycles a sample) and the phases of |H_p(f) - exp(j 2 pi f p / factor)|
    (the module docstring): the FIR's departure from exact band-limited upsampling, per unit tone."""
    f = np.linspace(-band, band, n_freq)
    t = np.arange(TAPS) - HALF
    response = fir_taps(factor).astype(np.float64) @ np.exp(2j * np.pi * t[:, None] * f[None, :])
    exact = np.exp(2j * np.pi * (np.arange(factor) / factor)[:, None] * f[None, :])
    return float(np.max(np.abs(response - exact)))


def _check(records, factor: int, first: int, stop: int, bytes_per_output: float) -> np.ndarray:
    if not isinstance(records, np.ndarray) or records.ndim != 2 or not np.iscomplexobj(records):
        raise TypeError(f"upsample records: must be a complex (rows, samples) array, got "
                        f"{type(records).__name__} {getattr(records, 'shape', '')}")
    v.integer("upsample factor", factor, low=2, high=64)
    n = records.shape[1]
    if not (isinstance(first, (int, np.integer)) and isinstance(stop, (int, np.integer)) and 0 <= first < stop <= n):
        raise ValueError(f"upsample first, stop: must be integers with 0 <= first < stop <= {n}, got {first}, {stop}")
    budget.check_bytes(f"upsample of {records.shape[0]} rows x {stop - first} samples by {factor}",
                       bytes_per_output * records.shape[0] * (stop - first) * factor, "fewer rows or a shorter span")
    return records


def upsample_reference(records: np.ndarray, factor: int, first: int, stop: int) -> np.ndarray:
    """The NumPy twin of ``upsample_fir``: original samples [first, stop) of the (R, n) complex
    ``records`` upsampled by ``factor``, complex64 (R, (stop - first) factor), output q at original
    position first + q / factor (accumulated in complex128)."""
    _check(records, factor, first, stop, 40.0)  # the complex128 sum and a term, the complex64 result
    n_rec, n = records.shape
    m = stop - first
    lo, hi = first - HALF, stop - HALF + TAPS - 1  # the samples the outputs read
    padded = np.zeros((n_rec, hi - lo), np.complex128)
    padded[:, max(lo, 0) - lo:min(hi, n) - lo] = records[:, max(lo, 0):min(hi, n)]
    taps = fir_taps(factor).astype(np.float64)
    out = np.zeros((n_rec, m, factor), np.complex128)
    out[:, :, 0] = records[:, first:stop]
    for t in range(TAPS):
        out[:, :, 1:] += padded[:, t:t + m, None] * taps[None, None, 1:, t]
    return out.reshape(n_rec, m * factor).astype(np.complex64)


#: The mirrored pass's pairs of phases a pass over the samples the kernel can be built with
#: (MIRROR_PASS; by default the kernel picks 4 on AVX-512 targets and 2 otherwise).
MIRROR_PASSES = (1, 2, 4)


def enqueue(queue, src, n_src: int, n_rows: int, first: int, stop: int, factor: int, dst,
            mirror_pass: int | None = None):
    """Enqueue ``upsample_fir`` (kernels/upsample.cl): rows of the device buffer ``src`` (n_rows x
    n_src complex64) upsampled over original samples [first, stop) into ``dst`` (n_rows x
    (stop - first) factor complex64); returns its event. ``mirror_pass``: one of
    :data:`MIRROR_PASSES` to build the mirrored pass with that many pairs a pass instead of the
    target's choice (the same sums in the same order: the samples do not change)."""
    taps = _taps_buffer(queue.context, factor)
    defines = {"FACTOR": factor, "TAPS": TAPS, "PHASE_VECS": -(-factor // 8), "MIRROR": int(factor <= 8)}
    if mirror_pass is not None:
        defines["MIRROR_PASS"] = _mirror_pass(mirror_pass)
    kern = opencl.kernel("upsample", "upsample_fir", defines=defines)
    global_size, local_size = opencl.work_groups_2d(-(-(stop - first) // 8), n_rows, ROWS_GROUP)
    return kern(queue, global_size, local_size, src, np.int32(n_src), np.int32(n_rows), np.int32(first),
                np.int32(stop - first), taps, dst)


def _mirror_pass(value) -> int:
    n = v.integer("upsample mirror_pass", value, low=1, high=max(MIRROR_PASSES))
    if n not in MIRROR_PASSES:
        raise ValueError(f"upsample mirror_pass: must be one of {MIRROR_PASSES}, got {n}")
    return n


_TAP_BUFFERS: dict = {}


def _taps_buffer(ctx, factor: int):
    key = (int(ctx.int_ptr), factor)
    if key not in _TAP_BUFFERS:
        import pyopencl as cl

        _TAP_BUFFERS[key] = cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                                      hostbuf=mirror_vectors(factor) if factor <= 8 else phase_vectors(factor))
    return _TAP_BUFFERS[key]


def upsample_fir(records: np.ndarray, factor: int, first: int, stop: int, out: np.ndarray | None = None,
                 mirror_pass: int | None = None) -> np.ndarray:
    """:func:`upsample_reference` on the OpenCL device (``kernels/upsample.cl``): complex64
    (R, (stop - first) factor), written into ``out`` when given; ``mirror_pass`` as in :func:`enqueue`."""
    import pyopencl as cl

    _check(records, factor, first, stop, 0.0 if out is not None else 8.0)
    if mirror_pass is not None:
        _mirror_pass(mirror_pass)
    rt = opencl.runtime()
    mf = cl.mem_flags
    src = np.ascontiguousarray(records, np.complex64)
    out = np.empty((src.shape[0], (stop - first) * factor), np.complex64) if out is None else out
    src_buf = cl.Buffer(rt.context, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=src)
    dst_buf = cl.Buffer(rt.context, mf.WRITE_ONLY | mf.USE_HOST_PTR, hostbuf=out)
    enqueue(rt.queue, src_buf, src.shape[1], src.shape[0], first, stop, factor, dst_buf, mirror_pass).wait()
    mapped, _ = cl.enqueue_map_buffer(rt.queue, dst_buf, cl.map_flags.READ, 0, out.shape, out.dtype)
    mapped.base.release()  # the result is the host array (read after the map: a GPU copies it back there)
    return out


def upsample_blocks(records: np.ndarray, factor: int, first: int, stop: int, workers: int | None = None,
                    out: np.ndarray | None = None) -> np.ndarray:
    """Original samples [first, stop) of the (R, n) records, FFT-upsampled by ``factor`` block by
    block (module docstring; ``first`` a multiple of UPSAMPLE_BLOCK): complex64 (R, (stop - first) factor),
    sample j at original position first + j / factor. Written into ``out`` when given."""
    n_rec, n = records.shape
    block, guard = UPSAMPLE_BLOCK, UPSAMPLE_GUARD
    if first % block or not 0 <= first < stop <= n:
        raise ValueError(f"first must be a multiple of {block} and 0 <= first < stop <= {n}, got {first}, {stop}")
    workers = os.cpu_count() if workers is None else int(workers)
    n_blocks = -(-(stop - first) // block)
    width = block + 2 * guard
    lo, hi = first - guard, first + n_blocks * block + guard
    out = np.empty((n_rec, (stop - first) * factor), np.complex64) if out is None else out
    per_record = n_blocks * width * factor * 16
    batch = max(1, int(FFT_BATCH_BYTES // per_record))
    for s in range(0, n_rec, batch):
        e = min(s + batch, n_rec)
        padded = np.zeros((e - s, hi - lo), np.complex64)
        padded[:, max(lo, 0) - lo:min(hi, n) - lo] = records[s:e, max(lo, 0):min(hi, n)]
        windows = np.lib.stride_tricks.sliding_window_view(padded, width, axis=-1)[:, ::block]
        spec = scipy.fft.fft(windows, axis=-1, workers=workers)
        spec *= factor
        up = scipy.fft.ifft(_upsample_spectrum(spec, factor), axis=-1, workers=workers, overwrite_x=True)
        kept = up[..., guard * factor:(guard + block) * factor]  # (records, blocks, block factor)
        whole = (stop - first) // block  # blocks kept whole
        out[s:e, :whole * block * factor] = kept[:, :whole].reshape(e - s, whole * block * factor)
        if whole < n_blocks:  # the last block, cut at the record's end
            out[s:e, whole * block * factor:] = kept[:, whole, :(stop - first - whole * block) * factor]
    return out
