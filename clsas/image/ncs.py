"""Nonlinear chirp scaling (NCS): the imager of Wu, Tang & Zhong 2018 (section 3.3: "the imaging
algorithm utilized is the nonlinear chirp scaling algorithm [24]").

Their [24] (Wu, Tang & Zhong, "A nonlinear chirp scaling algorithm for processing multi-receiver
SAS data with small squint angle", ICWCCS 2017) is not among the seed papers; the method is the
nonlinear chirp scaling of Davidson, Cumming & Ito, "A chirp scaling approach for processing
squint mode SAR data", IEEE Trans. AES 32(1), 1996, applied to the monostatic-equivalent record
(the PCA record, or Wu 2018's corrected record, eq. 28), the same place as
:mod:`clsas.image.csa`. What chirp scaling (CSA) leaves out and NCS adds: the range FM rate in
the range-Doppler domain depends on range (C&W eq. 7.18, the secondary-range-compression term),
and the two-dimensional spectrum of a wideband sonar has a range-dependent cubic term; CSA takes
both at the reference range. Everything below is derived here (the paper gives none of it).

Signal. With D = sqrt(1 - (k_u / 2 k0)^2) and the chirp re-spread at its rate K = B / T (as
CSA), a target at closest range R has, in the two-dimensional frequency domain (f, k_u), the
phase -pi f^2 / K - (4 pi R / c) g(f), g(f) = sqrt((f0 + f)^2 - a^2), a = f0 sqrt(1 - D^2)
(= c f_eta / (2 v)); with g(0) = f0 D, g'(0) = 1 / D, g''(0) = -(1 - D^2) / (f0 D^3) and
g'''(0) = 3 (1 - D^2) / (f0^2 D^5) its expansion to third order in f is

    -4 pi R f0 D / c  -  2 pi f tau_c  -  pi f^2 / K_m(tau_c)  -  (2 pi / 3) X(tau_c) f^3,

    tau_c = 2 R / (c D)                               (the migration),
    1 / K_m = 1 / K - alpha tau_c, alpha = (1 - D^2) / (f0 D^2)   (C&W eq. 7.18),
    X = (3 / 2) alpha tau_c / (f0 D^2)                (the cubic term).

Per range sub-block n with reference range r_n (tau_ref = 2 r_n / (c D), Delta = tau_c - tau_ref,
K_0 = K_m(tau_ref), K_s = dK_m / dtau_c = alpha K_0^2, so K_m ~ K_0 + K_s Delta):

1. Along-track FFT (the template's rows).
2. On the whole record (zero-padded so that no chirp wraps): range FFT, re-spread and a cubic
   filter exp(j (2 pi / 3) Y f^3), range IFFT. By stationary phase a target's chirp is then
   exp(j pi K_m t^2 - j (2 pi / 3) (X - Y) K_m^3 t^3), t = tau - tau_c.
3. For each sub-block, its columns and a margin (overlap-save, below): the nonlinear scaling
   exp(j pi q2 dt^2 + j (2 pi / 3) q3 dt^3), dt = tau - tau_ref
   (Davidson et al.'s scaling function). With dt = t + Delta the target's phase / pi becomes
       (K_0 + q2 + (K_s + 2 q3) Delta) t^2 + (2 / 3) (q3 - (X - Y) K^3) t^3
       + 2 (q2 Delta + q3 Delta^2) t + q2 Delta^2 + (2 / 3) q3 Delta^3,
   so q3 = -K_s / 2 makes every range's FM rate K_new = K_0 + q2 (what CSA cannot: its residual
   SRC grows with |R - R_ref|), Y = X(tau_ref) + alpha / (2 K_0) would remove the cubic term at
   the reference, and q2 = K_0 (1 / D - 1) places the target (where its instantaneous frequency is
   zero, t* = -(q2 Delta + q3 Delta^2) / K_new) at tau_ref + D Delta + b Delta^2 =
   tau_ref + 2 (R - r_n) / c + b Delta^2, b = K_s / (2 K_new) = alpha K_0 D / 2.
4. Range FFT; range compression with SRC exp(j pi f^2 / K_new), the cubic remainder and bulk
   migration correction exp(j 2 pi f (tau_ref - 2 r_n / c)); range IFFT: every target at
   2 R / c + b Delta^2. Step 2 takes Y at the record's middle range, Y_mid, for all blocks; the
   cubic coefficient c_n = q3 - (X(tau_ref) - Y_mid) K_0^3 it leaves at block n's reference
   (zero at the middle range) is removed here: by stationary phase the chirp
   exp(j pi K_new t^2 + j (2 pi / 3) c t^3) has the spectrum
   exp(-j pi f^2 / K_new + j (2 pi / 3) (c / K_new^3) f^3), so the filter has the factor
   exp(-j (2 pi / 3) (c_n / K_new^3) f^3). (One step 2 for the whole record instead of one a
   block halves the margins: a block's compression reads half a chirp and the bulk shift
   around its columns.)
5. Azimuth compression exp(j 4 pi R f0 D / c) and the residual phase of step 3,
   pi (q2 Delta^2 + (2 / 3) q3 Delta^3 - (q2 Delta + q3 Delta^2)^2 / K_new), with R the column's
   range and Delta = 2 (R - r_n) / (c D). (Reading R and Delta through the shift b Delta^2
   instead would be wrong: the pixel at 2 R / c holds, on every Doppler row, the target whose
   true range is R, displaced by b Delta^2 on that row; its phase there is that of R, and a
   range error dR costs 4 pi f0 D dR / c of azimuth phase, quadratic in k_u through b.) The
   band's weights, the non-stop-and-go shift and the inverse along-track FFT are the template's
   (:func:`clsas.image.strip.strip_image`).

The price of the cubic scaling is b Delta^2: a shift that grows with the Doppler (b ~ k_u^2),
i.e. a residual migration, which blurs a point's range response and tapers its Doppler band.
The sub-blocks are as wide as keeps it within 1/16 of a range cell (b Delta^2 <= 1 / (16 B)
at the band's largest |k_u|) and the range-variant cubic term within
pi / 16 at f = B / 2 ((2 pi / 3) (dX / dtau_c) Delta (B / 2)^3); on a narrow swath (Wu 2018's
points at 297-303 m) that is one block for the whole record. Each block is scaled and
compressed over its columns and a margin of half the chirp's length and the bulk shift on each
side, at the margin's own times (the record is zero-padded, never read circularly). What stays
approximate: the expansion to third order in f and first order in Delta for K_m, the stationary
phase mapping (a time-bandwidth product >> 1).
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from ..kernelmath import unit_phasor
from ..model import Image
from .strip import follows_template, range_blocks, strip_image, strip_job

CELL_FRACTION = 1 / 16  # the residual migration b Delta^2 allowed at a block's edge, range cells
CUBIC_TOLERANCE = np.pi / 16  # rad: the range-variant cubic phase allowed at a block's edge at f = B / 2
GUARD = 16  # samples added to each side of a block beyond the chirp's length and the bulk shift
BYTES_PER_SAMPLE = 64  # per padded range sample: the spread record, a block's segment and its phase screens
FM_MARGIN = 0.5  # 1 / K - alpha tau must stay above this fraction of 1 / K (K_m finite, no sign change)


def ncs_block_width(alpha_max: float, k_max: float, f0: float, d_min: float, bandwidth: float, c: float) -> float:
    """Widest range sub-block (m) that keeps the residual migration b Delta^2 within
    CELL_FRACTION of a range cell and the range-variant cubic phase within CUBIC_TOLERANCE at its
    edges (module docstring), for the largest alpha (s) and FM rate K_m (Hz/s) of the band."""
    if alpha_max == 0:
        return np.inf
    half_shift = np.sqrt(CELL_FRACTION / bandwidth / (alpha_max * k_max / 2))  # s of two-way time
    half_cubic = CUBIC_TOLERANCE / ((2 * np.pi / 3) * 1.5 * alpha_max / (f0 * d_min**2) * (bandwidth / 2) ** 3)
    return c * min(half_shift, half_cubic)  # a block spans +-half (s) of two-way time: c * half metres


def cubic_term(alpha, tau_c, f0: float, d):
    """X(tau_c) = (3 / 2) alpha tau_c / (f0 D^2), s^3: the cubic range-frequency term of a target
    at range-Doppler delay tau_c (module docstring)."""
    return 1.5 * alpha * tau_c / (f0 * d**2)


@follows_template
def nonlinear_chirp_scaling(data, **options) -> Image:
    """Focus a straight-track record with nonlinear chirp scaling (see the module docstring).

    ``options`` are the strip-map template's (:func:`clsas.image.strip.strip_job`); NCS itself
    interpolates nothing (``interp`` serves an EchoData's path-excess compensation). Returns an
    Image, dims ("y", "x"); its provenance says how many range sub-blocks (``ncs_blocks``).
    """
    job = strip_job("nonlinear_chirp_scaling", data, **options)
    rec, workers = job.record, job.workers
    c, f0, fs = rec.medium.sound_speed, rec.waveform.f0, rec.fs
    chirp_rate = rec.waveform.bandwidth / rec.waveform.duration
    k0 = 2 * np.pi * f0 / c
    n = rec.n_samples
    tau = rec.t0 + np.arange(n) / fs
    r = c * tau / 2
    d = np.sqrt(np.clip(1 - (job.ku / (2 * k0)) ** 2, 1e-6, None))[:, None]
    alpha = (1 - d**2) / (f0 * d**2)
    headroom = 1 / chirp_rate - alpha * tau[-1] / d  # 1 / K_m at the far range, per row
    if np.min(headroom) < FM_MARGIN / chirp_rate:
        raise ValueError(f"nonlinear_chirp_scaling data: on the Doppler rows up to |k_u| = {np.abs(job.ku).max():.4g} "
                         f"rad/m the range FM rate in the range-Doppler domain (C&W eq. 7.18) diverges at the far "
                         f"range {r[-1]:.4g} m; limit the processed band with elements=(L_tx, L_rx)")
    width = ncs_block_width(alpha.max(), 1 / headroom.min(), f0, d.min(), rec.waveform.bandwidth, c)
    blocks = range_blocks(r, width)
    bulk = 2 * r[-1] * (1 / d.min() - 1) / c  # s, the largest bulk migration
    margin = int(np.ceil((rec.waveform.duration / 2 + bulk) * fs)) + GUARD  # what compressing a block reads
    pad = max(int(np.ceil(rec.waveform.duration * fs)) + GUARD, margin)  # zeros either side: no spread chirp wraps
    lengths = [scipy.fft.next_fast_len(hi - lo + 2 * margin) for lo, hi, _ in blocks]
    n_p = scipy.fft.next_fast_len(max(pad + n + pad, *(pad + lo - margin + length
                                                       for (lo, _, _), length in zip(blocks, lengths))))

    job.check_budget(n_p + max(lengths), BYTES_PER_SAMPLE)

    # step 2 on the whole record, its cubic filter at the middle range r_mid
    r_mid = r[n // 2]
    tau_mid = 2 * r_mid / (c * d)
    k_mid = 1 / (1 / chirp_rate - alpha * tau_mid)
    y_mid = cubic_term(alpha, tau_mid, f0, d) + alpha / (2 * k_mid)
    f = np.fft.fftfreq(n_p, 1 / fs)[None, :]
    spread = np.zeros((job.rows.size, n_p), np.complex64)
    spread[:, pad:pad + n] = job.doppler(rec.data)
    spread = scipy.fft.fft(spread, axis=1, workers=workers)
    spread *= unit_phasor(-np.pi * f**2 / chirp_rate + (2 * np.pi / 3) * y_mid * f**3)
    spread = scipy.fft.ifft(spread, axis=1, workers=workers)

    out = np.empty((job.rows.size, n), np.complex64)
    block_of = np.empty(n, int)
    k_refs = np.empty((len(blocks), job.rows.size))  # K_0 of every block and row
    for b, ((lo, hi, r_n), length) in enumerate(zip(blocks, lengths)):
        tau_ref = 2 * r_n / (c * d)
        k_ref = 1 / (1 / chirp_rate - alpha * tau_ref)
        q2, q3, k_new = k_ref * (1 / d - 1), -alpha * k_ref**2 / 2, k_ref / d
        cubic = q3 - (cubic_term(alpha, tau_ref, f0, d) - y_mid) * k_ref**3  # left at the block's reference
        segment = spread[:, pad + lo - margin:pad + lo - margin + length].copy()
        dt = rec.t0 + (lo - margin + np.arange(length))[None, :] / fs - tau_ref
        segment *= unit_phasor(np.pi * q2 * dt**2 + (2 * np.pi / 3) * q3 * dt**3)  # step 3
        f = np.fft.fftfreq(length, 1 / fs)[None, :]
        segment = scipy.fft.fft(segment, axis=1, workers=workers)
        segment *= unit_phasor(np.pi * f**2 / k_new - (2 * np.pi / 3) * cubic / k_new**3 * f**3
                               + 2 * np.pi * f * (tau_ref - 2 * r_n / c))  # step 4
        out[:, lo:hi] = scipy.fft.ifft(segment, axis=1, workers=workers)[:, margin:margin + hi - lo]
        block_of[lo:hi] = b
        k_refs[b] = k_ref[:, 0]
    # step 5, every column from its block's reference
    r_n = np.array([block[2] for block in blocks])[block_of][None, :]
    k_ref = k_refs[block_of].T
    rho = 2 * (r[None, :] - r_n) / c
    delta = rho / d  # the column's own Delta (b Delta^2 is left: within the block rule)
    q2, q3, k_new = k_ref * (1 / d - 1), -alpha * k_ref**2 / 2, k_ref / d
    residual = np.pi * (q2 * delta**2 + (2 / 3) * q3 * delta**3 - (q2 * delta + q3 * delta**2) ** 2 / k_new)
    out *= unit_phasor(4 * np.pi * f0 * (r_n + c * d * delta / 2) * d / c - residual)
    return strip_image(job, out, r, ncs_blocks=len(blocks))
