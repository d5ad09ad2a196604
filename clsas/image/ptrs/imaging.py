"""Numerical point-target-reference-spectrum (PTRS) imaging of a multireceiver line array:
Zhang, Tan & Ying 2019, sections 3-4 (Fig. 2).

For each receiver i (offset d_i ahead of the transmitter), on its range-compressed record:

1. 2-D FFT (section 4.1): every receiver's fast time referred to the earliest receiver's start
   (a copy when the starts differ by whole samples, else a linear phase in range frequency),
   slow-time FFT over its pulses at the PRF. The spectrum
   is aliased M times; row f_t of the full Doppler grid of M x PRF is its row f_t mod PRF (the
   receiver's samples zero-stuffed onto the fine slow-time grid PRI / M).
2. Bulk decoupling (eq. 12) at the swath centre r_c, exp(-j phi_de_i(f_tau, f_t; r_c)) with
   phi_de = Psi - phi_ac + 4 pi f_tau r / c (eqs. 7, 8, 10, 11; the range matched filter
   conj(P) is already applied), and
3. differential decoupling (eq. 13) per range sub-block n, exp(-j [phi_de_i(r_ref_n) -
   phi_de_i(r_c)]): their product is exp(-j phi_de_i(r_ref_n)), which each sub-block applies at
   once, by overlap-save: the block's columns plus a margin of the largest range migration are
   range-FFT'd, filtered and transformed back, and the block's own columns kept (the paper
   filters the whole swath with eq. 12, then once per block with eq. 13; the product is the
   same filter, and its impulse response is shorter than the margin). This saves the
   full-swath pass of eq. 12 and its range IFFT per receiver.
3b. Residual range cell migration correction (``rcmc``, not in the paper). A point at range r
   in block n keeps the residual coupling phi_de(r) - phi_de(r_ref_n) (eq. 11). Its expansion
   in f_tau at f_tau = 0 starts with -2 pi f_tau [m(f_t; r) - m(f_t; r_ref_n)], where
   m(f_t; r) = tau_i(T_i(-f_t / f0); r) - 2 r / c is the range cell migration (d phi_de /
   d f_tau = -2 pi m, see :func:`clsas.image.ptrs.stationary.migration`): the residual is first
   of all a Doppler-dependent shift of the range envelope by (c / 2) [m(r) - m(r_ref_n)]
   ~ (r - r_ref_n) (1 / cos(theta) - 1), with no phase at the envelope's peak (phi_de vanishes at
   f_tau = 0). On Zhang et al.'s band (|f_t| <= 50 Hz, sin(theta) <= 0.125: 1 / cos - 1 =
   7.9e-3) a point 4 m from its reference (an 8 m sub-block's edge) is shifted by up to 3.2 cm
   = 0.84 range cells at the band edge, 2.6 rad of phase at f_tau = B / 2: the envelope tapers
   the azimuth spectrum (lower PSLR, wider main lobe) and eq. (13) alone cannot meet the pi / 4
   rule beyond 2.2 m sub-blocks. The correction reads every column r of the block, in the
   range-Doppler domain, at r + (c / 2) [m(f_t; r) - m(f_t; r_ref_n)] (m exact at r_ref_n and
   linear in r between the nodes below; ``interp``, :func:`clsas.interp.resample`).
   What remains is the part of phi_de(r) - phi_de(r_ref_n) beyond first order in f_tau, the
   secondary-range-compression residual ~ 2 pi (r - r_ref_n) (2 / c) f_tau^2 sin^2(theta) /
   (2 f0 cos^3(theta)): 0.17 rad at 4 m, and the pi / 4 rule allows 33 m sub-blocks.
4. Azimuth compression (eq. 14): exp(-j phi_ac_i(f_t; r)) at every range column r.
5. Coherent superposition (section 4.4) of the M receivers' spectra on the M x PRF grid (the
   aliases cancel when the phase centres v t + d_i / 2 interleave uniformly), the Doppler band
   and its window (as omega-k: ``elements``, ``window``, ``deconvolve``), and the azimuth IFFT.

The stationary points behind Psi and phi_ac are solved numerically (eq. 5, Newton,
:mod:`clsas.image.ptrs.stationary`) per receiver and range and kept in a
:class:`~clsas.image.ptrs.stationary.StationaryPoints` (pass it back as ``points`` to reuse
them: seed 003's second scheme). The azimuth modulation is tabulated at range nodes
``NODE_SPACING`` apart and interpolated linearly between them (G is linear in r up to the
bistatic d_i^2 / (4 r) terms: the interpolation error is below 1e-3 rad beyond 20 m).

Sub-block width (section 6.1.2): the residual coupling phase |phi_de(r_ref +- dr / 2) -
phi_de(r_ref)| (with ``rcmc``: what step 3b leaves of it) must stay below pi / 4 over the
processed band; without ``block_width`` or ``reference_ranges`` the width is the largest that
satisfies this at every range of the swath (the rule evaluated with the phase's range
derivative at the band's corners): 2.2 m for eq. (13) alone, 33 m with ``rcmc``, on the
reproduction's band.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.fft

from ... import budget
from ... import validate as v
from ...interp import INTERPOLATORS, TAP_WINDOWS, check_options, check_sizes, resample_prechecked
from ...model import EchoData, Image
from ..multireceiver import interleave, line_array
from ...pulse import check_window
from ..rangecomp import check_workers
from ..record import LineRecord, azimuth_weights, check_elements, image_of, oversampling
from .phase import compress_azimuth, decouple
from .stationary import StationaryPoints, hermite, migration

log = logging.getLogger("clsas")

NODE_SPACING = 0.5  # m between the ranges at which the azimuth modulation is tabulated
MIN_RANGE = 1.0  # m: columns nearer than this (or before the emission) are not imaged
RESIDUAL_LIMIT = np.pi / 4  # rad, the sub-block rule of seed 003 section 6.1.2 (after [31])


def plan_blocks(r: np.ndarray, valid: np.ndarray, block_width, reference_ranges, rule_width) -> list:
    """Range sub-blocks as (first column, stop column, reference range) over the ``valid``
    columns of ranges ``r``: ``reference_ranges`` (each column to its nearest reference; each
    must lie within the valid ranges), or a uniform partition of ``block_width`` m, or, when both
    are None, of ``rule_width()`` m; a uniform block's reference is the middle of the ranges it
    covers (Zhang et al. 2019 section 4.2: "the center range of the n-th sub-block")."""
    cols = np.flatnonzero(valid)
    lo_col, hi_col = int(cols[0]), int(cols[-1]) + 1
    if reference_ranges is not None:
        values = [reference_ranges] if np.ndim(reference_ranges) == 0 else \
            list(np.ravel(np.asarray(reference_ranges, dtype=object)))
        if not values:
            raise ValueError("ptrs_image reference_ranges: must hold at least one range (m), got none")
        refs = np.sort([v.scalar(f"ptrs_image reference_ranges[{i}]", x, low=float(r[lo_col]), high=float(r[hi_col - 1]),
                                 unit="m", why="ranges the record holds") for i, x in enumerate(values)])
        nearest = np.argmin(np.abs(r[lo_col:hi_col, None] - refs[None, :]), axis=1)
        blocks = []
        for k, ref in enumerate(refs):
            mine = np.flatnonzero(nearest == k)
            if mine.size:
                blocks.append((lo_col + int(mine[0]), lo_col + int(mine[-1]) + 1, float(ref)))
        return blocks
    width = rule_width() if block_width is None else float(block_width)
    start = r[lo_col]
    index = np.floor((r[lo_col:hi_col] - start) / width).astype(np.int64)
    edges = np.flatnonzero(np.diff(index)) + 1
    blocks = []
    for a, b in zip(np.concatenate([[0], edges]), np.concatenate([edges, [index.size]])):
        first, stop = lo_col + int(a), lo_col + int(b)
        blocks.append((first, stop, float((r[first] + r[stop - 1]) / 2)))
    return blocks


def _check_arguments(block_width, rcmc, window, window_options, deconvolve, interp, tap_window, points, depth,
                     workers):
    """The scalar arguments of :func:`ptrs_image`, checked before anything is computed (the
    template's checks, :func:`clsas.image.strip.strip_job`); returns (block_width, window
    options, workers)."""
    if block_width is not None:
        block_width = v.positive("ptrs_image block_width", block_width, high=v.MAX_COORDINATE, unit="m",
                                 why="a sub-block width, or None for the pi/4 rule")
    v.flag("ptrs_image rcmc", rcmc)
    v.flag("ptrs_image deconvolve", deconvolve)
    options = check_window(window, window_options, "ptrs_image")
    v.choice("ptrs_image interp", interp, INTERPOLATORS)
    v.choice("ptrs_image tap_window", tap_window, TAP_WINDOWS)
    if points is not None and not isinstance(points, StationaryPoints):
        raise TypeError(f"ptrs_image points: must be a StationaryPoints (or None), got {type(points).__name__}")
    if depth is not None:
        v.scalar("ptrs_image depth", depth, low=-v.MAX_COORDINATE, high=v.MAX_COORDINATE, unit="m")
    return block_width, options, check_workers(workers, "ptrs_image workers")


def _check_budget(n_rx, n_p, n_fp, n_cols, n_rows, n_ft, n_tables, n_s, n_r=None, segment=0) -> None:
    """Refuse a request over the memory budget: before the stationary-point tables (the range FFT
    length then at least ``n_cols``), and again once it and the longest sub-block segment are
    known (``n_r``, ``segment``)."""
    budget.check_bytes(f"ptrs_image of {n_rx} receivers x {n_p} pulses x {n_cols} range columns",
                       working_bytes(n_rx, n_fp, n_cols if n_r is None else n_r, n_rows, n_ft, n_cols, n_tables, n_s,
                                     segment),
                       "image fewer receivers, pulses or a shorter swath at a time")


def working_bytes(n_rx: int, n_fp: int, n_r: int, n_rows: int, n_ft: int, n_cols: int, n_tables: int,
                  n_s: int, segment: int = 0) -> float:
    """Bytes :func:`ptrs_image` holds at its peak: one receiver's spectra (three n_fp x n_r
    complex64 arrays: the range FFT, its inverse and the slow-time FFT), the two range-Doppler
    accumulators (n_rows x n_cols), the full Doppler grid, its inverse FFT and the image's pixel
    positions (n_ft x n_cols: 8 + 8 + 24 bytes), the stationary-point tables (T and G, float64,
    n_rx x n_tables x n_s) and a sub-block's segment (n_rows x ``segment``: its gathered copy, its
    FFT, the inverse and the interpolation's positions and output, 40 bytes)."""
    return (24.0 * n_fp * n_r + 16.0 * n_rows * n_cols + 40.0 * n_ft * n_cols + 16.0 * n_rx * n_tables * n_s
            + 40.0 * n_rows * segment)


def ptrs_image(echo: EchoData, *, receivers=None, block_width: float | None = None, reference_ranges=None,
               elements=None, deconvolve: bool = True, window: str = "none", interp: str = "sinc8",
               tap_window: str = "kaiser", depth: float | None = None, workers: int | None = None, rcmc: bool = True,
               points: StationaryPoints | None = None, backend: str | None = None, **window_options) -> Image:
    """Focus a multireceiver line-array record by numerical PTRS imaging (see the module docstring).

    The options are keyword-only, with the names and defaults of the strip-map imagers'
    template (:func:`clsas.image.strip.strip_job`) where they share one (``elements``,
    ``deconvolve``, ``window``, ``interp``, ``tap_window``, ``depth``, ``workers``, ``backend``);
    ``receivers`` picks several receivers where the template's ``receiver`` picks one.

    Parameters
    ----------
    echo : EchoData, range-compressed, straight uniformly sampled track, receivers on the track
        line at fixed along-track offsets (Zhang et al. 2019 Fig. 1) whose phase centres
        u_p + d_i / 2 interleave uniformly (:func:`clsas.image.multireceiver.interleave`: the
        coherent superposition cancels the aliases only then).
    receivers : indices or names (default all).
    block_width : sub-block width, m (eq. 13); None: the pi / 4 rule (section 6.1.2).
    reference_ranges : explicit sub-block reference ranges r_ref_n, m (each range column is
        decoupled at its nearest one); overrides ``block_width``.
    elements : (L_tx, L_rx) along-track element lengths, m: the processed Doppler band
        |f_t| <= v / max(L) and (``deconvolve``) the element-pattern deconvolution, as
        :func:`clsas.image.omegak.omega_k`. None keeps the whole M x PRF band.
    deconvolve : divide by the element pattern (with ``elements``); False keeps its taper.
    window : Doppler-band weighting ("none", "hamming", "taylor", "kaiser"; their options
        ``taylor_nbar``, ``taylor_sll_db``, ``kaiser_beta`` as keywords). Default "none", as every
        strip-map imager (:mod:`clsas.image.strip`).
    interp, tap_window : the interpolator of the residual range cell migration correction
        (``rcmc``): "linear", "sinc8", "sinc16"; "kaiser" or "knab" (:mod:`clsas.interp`).
    points : a :class:`StationaryPoints` to fill and reuse: empty on the first call, it keeps
        the stationary points solved, and a later call on the same geometry reuses them (its
        :attr:`~StationaryPoints.solved` count does not grow when it serves every range).
        None solves them for this call only.
    depth : the horizontal plane the pixels are placed on (default: the track's).
    workers : scipy.fft threads (default: all cores).
    rcmc : after each sub-block's differential decoupling, move every range column's samples
        by the residual range cell migration m(f_t; r) - m(f_t; r_ref_n) (module docstring, step
        3b); False applies eq. (13) alone, as the paper does.
    backend : where the phase multiplies and the interpolation run.

    Returns
    -------
    Image, dims ("y", "x"), along-track rows every v PRI / M.
    """
    block_width, window_options, workers = _check_arguments(block_width, rcmc, window, window_options, deconvolve,
                                                            interp, tap_window, points, depth, workers)
    arr = line_array(echo, receivers)
    interleave(arr.track, arr.offsets, echo.n_pulses)  # the aliases cancel only on a uniform phase-centre grid
    c, f0, fs, speed = echo.medium.sound_speed, echo.waveform.f0, echo.fs, arr.track.speed
    n_rx, n_p = len(arr.receivers), echo.n_pulses
    if f0 <= fs / 2:
        raise ValueError(f"the carrier f0 = {f0:g} Hz must exceed half the sampling rate fs / 2 = {fs / 2:g} Hz")

    # the full Doppler grid (M x PRF) and the processed band
    n_fp = scipy.fft.next_fast_len(n_p)
    n_ft = n_rx * n_fp
    ft = np.fft.fftfreq(n_ft, arr.pri / n_rx)
    probe = LineRecord(data=np.zeros((1, 1), np.complex64), u0=arr.track.u0, du=arr.track.du / n_rx, t0=0.0, fs=fs,
                       speed=speed, track=(arr.track.x, arr.track.z), waveform=echo.waveform, medium=echo.medium,
                       nonstop=False)
    elements = check_elements(elements, probe)
    weights = azimuth_weights(2 * np.pi * ft / speed, elements, window, deconvolve, **window_options)
    rows = np.flatnonzero(weights != 0)
    ft_used = ft[rows]
    f_edge = np.abs(ft_used).max()
    s_max = 1.02 * f_edge / (f0 - fs / 2)
    points = (StationaryPoints() if points is None else points).bind(arr.offsets, speed, c, s_max)

    # the common range axis
    t0 = float(np.min(echo.t0[arr.receivers]))
    n_cols = int(np.ceil(np.max(echo.t0[arr.receivers] - t0) * fs)) + echo.n_samples
    r = c * (t0 + np.arange(n_cols) / fs) / 2
    valid = r >= MIN_RANGE
    if not valid.any():
        raise ValueError("the record holds no range beyond 1 m")
    r_c = float((r[valid][0] + r[-1]) / 2)

    def rule_width() -> float:
        return residual_rule_width(points, r[valid], ft_used, echo.waveform.bandwidth, f0, c, rcmc=rcmc)

    blocks = plan_blocks(r, valid, block_width, reference_ranges, rule_width)
    nodes = np.arange(r[valid][0], r[-1] + NODE_SPACING, NODE_SPACING)
    _check_budget(n_rx, n_p, n_fp, n_cols, rows.size, n_ft, len(blocks) + nodes.size, points.n_s)
    column_node = np.clip(np.floor((r - nodes[0]) / NODE_SPACING).astype(int), 0, nodes.size - 2)
    column_weight = (r - nodes[column_node]) / NODE_SPACING
    refs = np.array([b[2] for b in blocks])
    tables_t, tables_g = points.tables(np.concatenate([refs, nodes]))
    mig = tables_g + points.slopes * tables_t - 2 * np.concatenate([refs, nodes])[None, :, None] / c
    margin = _block_margin(mig, blocks, r, nodes, fs, rcmc)
    n_r = scipy.fft.next_fast_len(n_cols + margin)  # the record's circular range axis, zero beyond n_cols
    segment = max(scipy.fft.next_fast_len(hi - lo + 2 * margin) for lo, hi, _ in blocks)
    _check_budget(n_rx, n_p, n_fp, n_cols, rows.size, n_ft, len(blocks) + nodes.size, points.n_s, n_r, segment)
    knab = oversampling(fs, echo.waveform)  # the Knab window's parameter
    if rcmc:  # resample's checks, once for every receiver and sub-block (the positions are finite by construction)
        check_options(interp, tap_window, knab, who="ptrs_image", window_name="tap_window")
        check_sizes("ptrs_image rcmc", (rows.size, segment), segment, interp, "a sub-block's columns")
    for h in arr.receivers:
        v.bounded_gain("ptrs_image echo.data", echo.data[h], float(n_r) * n_fp * n_rx,
                       advice="scale the echo down (the FFTs and the coherent sum over receivers and pulses amplify it)")
    ftau = np.fft.fftfreq(n_r, 1 / fs)
    s0 = -ft_used / f0  # the slopes of the range-Doppler rows (f_tau = 0)
    log.info("ptrs_image: %d receivers, %d Doppler rows x %d columns, %d sub-blocks, margin %d columns",
             n_rx, rows.size, n_cols, len(blocks), margin)

    acc = np.zeros((rows.size, n_cols), np.complex64)
    out = np.zeros((rows.size, n_cols), np.complex64)  # one receiver's range-Doppler image (columns outside the blocks stay 0)
    for j, h in enumerate(arr.receivers):
        # the receiver's record on the common range axis, then its slow-time spectrum at the PRF
        # (n_fp rows; row f_t of the M x PRF grid is row f_t mod PRF of it: the aliases)
        rd = _slow_time_spectrum(echo.data[h], echo.t0[h] - t0, fs, ftau, n_r, n_fp, workers)
        for b, (lo, hi, r_ref) in enumerate(blocks):
            length = scipy.fft.next_fast_len(hi - lo + 2 * margin)
            first = lo - margin
            src = rd[:, first:first + length] if 0 <= first and first + length <= n_r \
                else rd[:, np.arange(first, first + length) % n_r]  # the record is circular in range
            seg = scipy.fft.fft(src[rows % n_fp], axis=1, workers=workers)
            decouple(seg, ft_used, np.fft.fftfreq(length, 1 / fs), f0, tables_g[j, b], tables_t[j, b],
                     points.s_first, points.ds, 2 * r_ref / c, backend=backend)
            seg = scipy.fft.ifft(seg, axis=1, workers=workers)
            if rcmc:
                positions = _rcmc_positions(tables_g[j], tables_t[j], b, refs.size, points, s0, r_ref, nodes,
                                            column_node[lo:hi], column_weight[lo:hi], margin, c, fs)
                out[:, lo:hi] = resample_prechecked(seg, positions, interp, tap_window, knab, backend)
            else:
                out[:, lo:hi] = seg[:, margin:margin + hi - lo]
        del rd
        compress_azimuth(out, ft_used, f0, tables_g[j, refs.size:], tables_t[j, refs.size:],
                         points.s_first, points.ds, column_node, column_weight, backend=backend)
        acc += out
    acc *= weights[rows, None].astype(np.complex64)
    full = np.zeros((n_ft, n_cols), np.complex64)
    full[rows] = acc
    del acc
    full[:, ~valid] = 0
    v.finite_result("ptrs_image image", full, "scale the echo down")
    grid = probe.replace(data=np.broadcast_to(np.complex64(0), (1, n_cols)), t0=t0)  # the output grid's axes
    image = image_of(grid, full, r, "ptrs", {"receivers": [echo.receivers[h] for h in arr.receivers],
                                            "blocks": [(float(r[lo]), float(r[hi - 1]), ref) for lo, hi, ref in blocks],
                                            "r_c": r_c, "elements": elements, "window": window,
                                            "deconvolve": deconvolve, "rcmc": rcmc, "interp": interp,
                                            "tap_window": tap_window, "backend": backend,
                                            "stationary_points_solved": points.solved}, depth)
    return image


def _slow_time_spectrum(data: np.ndarray, delay: float, fs: float, ftau: np.ndarray, n_r: int, n_fp: int,
                        workers: int) -> np.ndarray:
    """A receiver's record (n_pulses, n) on the common range axis of ``n_r`` columns, ``delay``
    s (>= 0) after the axis' start, and its slow-time FFT of length ``n_fp``: complex64
    (n_fp, n_r), zero beyond the record. When the delay is a whole number of samples (the records
    of one array usually share their start) the record's spectrum is copied to its column;
    otherwise the record is delayed by the linear phase exp(-j 2 pi f_tau delay) in range
    frequency (``ftau``, Hz) first."""
    whole = int(round(delay * fs))
    if abs(delay * fs - whole) <= 1e-6:
        out = np.zeros((n_fp, n_r), np.complex64)
        out[:, whole:whole + data.shape[1]] = scipy.fft.fft(data, n=n_fp, axis=0, workers=workers)
        return out
    spec = scipy.fft.fft(data, n=n_r, axis=1, workers=workers)
    spec *= np.exp(-2j * np.pi * ftau * delay).astype(np.complex64)
    return scipy.fft.fft(scipy.fft.ifft(spec, axis=1, overwrite_x=True, workers=workers), n=n_fp, axis=0,
                         workers=workers)


def decoupling_phase(points: StationaryPoints, g: np.ndarray, t: np.ndarray, r: float, ft: np.ndarray,
                     ftau: np.ndarray, f0: float, c: float) -> np.ndarray:
    """phi_de(f_tau, f_t; r) (eq. 11), rad, (len(ft), len(ftau)), from the tables (g, t) at range r."""
    f = f0 + ftau[None, :]
    psi = -2 * np.pi * f * hermite(g, t, points.s_first, points.ds, -ft[:, None] / f)
    phi_ac = -2 * np.pi * f0 * hermite(g, t, points.s_first, points.ds, -ft / f0)[:, None]
    return psi - phi_ac + 4 * np.pi * ftau[None, :] * r / c


def residual_rule_width(points: StationaryPoints, r: np.ndarray, ft: np.ndarray, bandwidth: float,
                        f0: float, c: float, probes: int = 5, step: float = 1.0, rcmc: bool = True) -> float:
    """The widest sub-block (m) whose residual coupling phase stays below pi / 4 at its edges
    (seed 003 section 6.1.2): 2 (pi / 4) / max |d residual / dr| over every receiver, the
    band's corners (f_t at the band edges and 0, f_tau = +-B / 2) and ``probes`` ranges across
    the swath (the derivative by a difference over ``step`` m). The residual is phi_de (eq. 11)
    or, with ``rcmc``, phi_de + 2 pi f_tau m(-f_t / f0; r), what remains after the residual
    migration correction (module docstring)."""
    ranges = np.linspace(r[0], r[-1], probes)
    ft_c = np.array([ft.min(), 0.0, ft.max()])
    ftau_c = np.array([-bandwidth / 2, bandwidth / 2])
    t_all, g_all = points.tables(np.concatenate([ranges, ranges + step]))

    def residual(j, k, rk):
        phase = decoupling_phase(points, g_all[j, k], t_all[j, k], rk, ft_c, ftau_c, f0, c)
        if rcmc:
            m = migration(g_all[j, k], t_all[j, k], points.s_first, points.ds, -ft_c / f0, rk, c)
            phase = phase + 2 * np.pi * ftau_c[None, :] * m[:, None]
        return phase

    slope = 0.0
    for j in range(points.offsets.size):
        for k, rk in enumerate(ranges):
            diff = residual(j, probes + k, rk + step) - residual(j, k, rk)
            slope = max(slope, float(np.abs(diff).max()) / step)
    return np.inf if slope == 0 else 2 * RESIDUAL_LIMIT / slope


def _rcmc_positions(g, t, ref, first_node, points, s0, r_ref, nodes, column_node, column_weight, margin, c, fs):
    """Source positions (rows, columns) in a sub-block's segment for the residual range cell
    migration correction: the block's columns (from ``margin`` on) moved by fs [m(s0; r) -
    m(s0; r_ref)] (``g``, ``t``: one receiver's tables, index ``ref`` the block's reference
    range, from ``first_node`` on the nodes). m is taken at the block's first and last columns
    (linear between their range nodes) and linearly between them: m is linear in r up to the
    bistatic terms, 0.003 sample off over 33 m at 40 m range."""
    m_ref = migration(g[ref], t[ref], points.s_first, points.ds, s0, r_ref, c)
    ends = np.array([0, column_node.size - 1])
    node = column_node[ends]
    m_lo, m_hi = migration(g[first_node + node], t[first_node + node], points.s_first, points.ds, s0, nodes[node], c)
    m_lo1, m_hi1 = migration(g[first_node + node + 1], t[first_node + node + 1], points.s_first, points.ds, s0,
                             nodes[node + 1], c)
    w = column_weight[ends]
    start = fs * (m_lo + w[0] * (m_lo1 - m_lo) - m_ref)
    slope = fs * (m_hi + w[1] * (m_hi1 - m_hi) - m_lo - w[0] * (m_lo1 - m_lo)) / max(column_node.size - 1, 1)
    cols = np.arange(column_node.size, dtype=np.float64)
    return (margin + start)[:, None] + cols[None, :] * (1 + slope[:, None])


def _block_margin(mig: np.ndarray, blocks: list, r: np.ndarray, nodes: np.ndarray, fs: float, rcmc: bool) -> int:
    """Columns of margin for the overlap-save decoupling of the sub-blocks: the largest group
    delay of their filters exp(-j phi_de(r_ref_n)), plus (``rcmc``) the largest residual
    migration within a block, plus 32 samples for the compressed pulse's sidelobes and the
    interpolator's taps.

    d phi_de / d f_tau = 2 pi (2 r / c - tau(T(s); r)) (with dG/ds = -T, tau(T) = G + s T), so the
    group delay of exp(-j phi_de(r_ref)) is the range cell migration m = tau(T(s); r_ref) - 2 r_ref / c.
    ``mig`` holds m (n_receivers, n_ranges, n_s) at the blocks' reference ranges, then at the
    ``nodes``.
    """
    n_ref = len(blocks)
    spread = np.abs(mig[:, :n_ref]).max(initial=0.0)
    if rcmc:
        for b, (lo, hi, _) in enumerate(blocks):
            near = n_ref + np.flatnonzero((nodes >= r[lo] - NODE_SPACING) & (nodes <= r[hi - 1] + NODE_SPACING))
            if near.size:
                spread = max(spread, np.abs(mig[:, :n_ref]).max() + np.abs(mig[:, near] - mig[:, b:b + 1]).max())
    return int(32 + np.ceil(fs * spread))
