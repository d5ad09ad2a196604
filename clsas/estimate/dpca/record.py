"""Motion compensation over the whole beam: the record of :func:`clsas.estimate.dpca.compensate`
(eqs. 74-75, exact at broadside) interleaved into a monostatic-equivalent line record and
corrected look angle by look angle in the (range frequency, along-track wavenumber) domain of
eq. (75), so that omega_k, range_doppler and chirp_scaling focus it.

Derivation
----------
A phase centre displaced by x across track (towards +x, the imaged side) shortens the two-way
path to a scatterer in direction n (unit vector from the sonar) by 2 x n_x, n_x =
sqrt(1 - n_y^2 - n_z^2): n_y the along-track direction cosine, n_z the vertical one. Eq. (74)'s
delay dt = -2 x / c restores the path at broadside (n_y = n_z = 0) only and leaves
2 x (1 - n_x) ~ x (n_y^2 + n_z^2) elsewhere: 0.25 mm at the -3 dB edge of Heremans' beam
(n_y = 0.07) for 5 cm of sway, 0.1 rad of phase (its cost in azimuth PSLR: tests/test_dpca.py).

On a monostatic line record the along-track direction cosine is the along-track wavenumber:
a scatterer seen at n_y contributes at k_u = 2 k n_y, k = 2 pi (f0 + f) / c at baseband
frequency f. So for a displacement x constant along the record, the residual is removed
exactly by the phase exp(+j 2 k x (1 - n_x(k_u, f))) on its 2-D spectrum (the sign of eq. 75's
correction: the broadside delay over-corrected by 2 x (1 - n_x)). The displacement changes
along the track, so the record is cut into overlapping sub-apertures (periodic Hann windows of
``subaperture`` phase centres at half overlap, which sum to one), each corrected with the
displacement at its centre, and added back. What is left is the change of x across half a
sub-aperture times (1 - n_x): 1 cm x 2.5e-3 at Heremans' 5 cm / 40 s sway over 3.5 m, 0.01 rad.
n_z is taken at the record's mid range from the height of the imaged plane above the track
(``depth``): exact for a scene at the track's depth (n_z = 0), otherwise the depression's part
is that of the mid range (its change over the swath, 2 x d(n_z^2) / 2, is left).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.fft

from ... import budget, validate
from ...model import EchoData
from ...image.multireceiver import BYTES_PER_SAMPLE, pca_record
from ...image.rangecomp import check_workers
from ...image.record import LineRecord
from ...kernelmath import unit_phasor
from ...scene.scenario import Scenario
from .track import DELAY_BYTES, Trajectory, compensate


def displacement(trajectory: Trajectory, scenario: Scenario, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u, x), each (hydrophone, pulse), m: the nominal along-track position of each phase
    centre (the transmitter at emission and hydrophone h midway) and its cross-track
    displacement, half the two-way path change that :func:`compensate` takes out
    (cross + (o_h - o_tx) sin(heading) / 2, the transmitter at the centre of rotation)."""
    array = scenario.array
    lever = array.rx_offsets[:, 1] - array.tx_offset[1]
    pc = 0.5 * (array.rx_offsets[:, 1] + array.tx_offset[1])
    y = scenario.platform.speed * eta + scenario.platform.start[1]
    x = trajectory.cross[None, :] + 0.5 * lever[:, None] * np.sin(trajectory.heading)[None, :]
    return y[None, :] + pc[:, None], x


def _check_subaperture(caller: str, subaperture, rows: int) -> None:
    """An even number of rows in [4, max(4, rows)] (a TypeError for a non-integer)."""
    n = validate.integer(f"{caller}: subaperture", subaperture, low=4, high=max(4, rows),
                         why="rows per sub-aperture, even, at most the record's rows")
    if n % 2:
        raise ValueError(f"{caller}: subaperture must be an even integer >= 4 rows, got {n}")


def beam_correction(record: LineRecord, x: np.ndarray, n_z: float = 0.0, subaperture: int = 32,
                    workers: int | None = -1) -> LineRecord:
    """``record`` with the residual 2 x (1 - n_x) of a broadside delay correction removed over
    the beam (module docstring). x : m (n_u,), each row's cross-track displacement; n_z : the
    vertical direction cosine of the scene; subaperture : rows per sub-aperture (even, >= 4)."""
    _check_subaperture("beam_correction", subaperture, record.n_u)
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (record.n_u,):
        raise ValueError(f"beam_correction: x must have one displacement per row ({record.n_u}), got {x.shape}")
    if not (np.isfinite(n_z) and abs(n_z) < 1):
        raise ValueError(f"beam_correction: n_z must be a direction cosine in (-1, 1), got {n_z!r}")
    hop = subaperture // 2
    size = scipy.fft.next_fast_len(2 * subaperture)
    c = record.medium.sound_speed
    f = scipy.fft.fftfreq(record.n_samples, 1 / record.fs)
    k = 2 * np.pi * (record.waveform.f0 + f) / c                                   # (sample,)
    ku = 2 * np.pi * scipy.fft.fftfreq(size, record.du)                             # (row,)
    n_y2 = (ku[:, None] / (2 * k[None, :])) ** 2
    cos_x = np.sqrt(np.maximum(1 - n_y2 - n_z**2, 0.0))
    residual = np.where(n_y2 + n_z**2 < 1, 2 * k[None, :] * (1 - cos_x), 0.0)    # rad per m of x
    window = np.sin(np.pi * np.arange(subaperture) / subaperture) ** 2              # periodic Hann
    spec = scipy.fft.fft(record.data, axis=1, workers=workers)                      # range spectrum
    padded = np.zeros((record.n_u + 2 * subaperture, record.n_samples), np.complex64)
    padded[subaperture:subaperture + record.n_u] = spec
    x_pad = np.pad(x, subaperture, mode="edge")
    out = np.zeros_like(padded)
    for start in range(hop, record.n_u + subaperture + 1, hop):
        rows = slice(start, start + subaperture)
        if not np.any(padded[rows]):
            continue
        x_c = float(np.sum(window * x_pad[rows]) / np.sum(window))
        # the windowed sub-aperture in the middle of a buffer twice its length: the correction
        # spreads it a few rows both ways without wrapping round
        seg = np.zeros((size, record.n_samples), np.complex64)
        seg[hop:hop + subaperture] = window[:, None] * padded[rows]
        seg = scipy.fft.fft(seg, axis=0, workers=workers)
        seg *= unit_phasor(x_c * residual)
        lo = start - hop
        out[lo:lo + size] += scipy.fft.ifft(seg, axis=0, workers=workers)[:out.shape[0] - lo]
    data = scipy.fft.ifft(out[subaperture:subaperture + record.n_u], axis=1, workers=workers).astype(np.complex64)
    return dataclasses.replace(record, data=data, provenance={
        **record.provenance, "beam_correction": {"subaperture": int(subaperture), "n_z": float(n_z)}})


def _chosen(echo: EchoData, receivers) -> int:
    """How many receivers the record interleaves (the rows a ping), at most the echo's: all of
    them for None (pca_record checks what they are)."""
    return echo.n_rx if receivers is None or not hasattr(receivers, "__len__") else min(len(receivers), echo.n_rx)


def _check_budget(echo: EchoData, hydrophones: int, chosen: int, subaperture: int) -> None:
    """Refuse before the first allocation what compensate_record holds at its peak (bytes per
    sample of the echo, complex64 8, complex128 16): the compensated copy of the echo (8, held to
    the end) with, in turn, :func:`compensate`'s delay over the hydrophones' records (their
    spectra, the phase ramp in complex128 and its argument, the delayed copy: 48), pca_record's
    interleaved rows (multireceiver.BYTES_PER_SAMPLE) and one receiver's working records, and
    beam_correction's record, its range spectrum, the padded and summed buffers, the result
    and its cast (48) with one sub-aperture's tables (about ten arrays of float64 or complex64
    over twice its rows); ``chosen`` receivers interleaved."""
    per_ping = echo.n_pulses * echo.n_samples
    rows = scipy.fft.next_fast_len(2 * subaperture) * echo.n_samples
    peak = max(DELAY_BYTES * hydrophones * per_ping, BYTES_PER_SAMPLE * chosen * per_ping + 64 * per_ping,
               48 * chosen * per_ping + 32 * subaperture * echo.n_samples + 80 * rows)
    budget.check_bytes(f"compensate_record of {chosen} receivers x {echo.n_pulses} pings x {echo.n_samples} samples",
                       8 * echo.n_rx * per_ping + peak, "fewer pings or samples at a time")


def compensate_record(echo: EchoData, trajectory: Trajectory, scenario: Scenario, receivers=None,
                      depth: float | None = None, subaperture: int = 32, backend: str | None = None,
                      workers: int | None = -1) -> LineRecord:
    """The motion-compensated monostatic-equivalent record of ``echo`` for omega_k /
    range_doppler / chirp_scaling: eq. (74)'s delay per hydrophone and ping (:func:`compensate`),
    the hydrophones ``receivers`` interleaved (:func:`clsas.image.multireceiver.pca_record`; their
    phase centres must not overlap between pings), then eq. (75) over the beam
    (:func:`beam_correction`, see the module docstring). depth : m, z of the imaged plane
    (default: the track's, a horizontal geometry)."""
    chosen = _chosen(echo, receivers)
    _check_subaperture("compensate_record", subaperture, chosen * echo.n_pulses)
    workers = check_workers(workers, "compensate_record workers")
    _check_budget(echo, scenario.array.n_receivers, chosen, subaperture)
    if depth is not None:
        depth = validate.scalar("compensate_record depth", depth, low=-validate.MAX_COORDINATE,
                                high=validate.MAX_COORDINATE, unit="m")
    # the broadside delay alone (depth=None): beam_correction's 2 x (1 - n_x) over the beam holds the
    # depression's part too, which compensate(depth=) would count a second time
    straight = compensate(echo, trajectory, scenario, workers=workers, depth=None)
    record = pca_record(straight, receivers, backend=backend)
    u, x = displacement(trajectory, scenario, echo.eta)
    rows = record.u0 + record.du * np.arange(record.n_u)
    chosen = [echo.receivers.index(name) for name in record.provenance["receivers"]]
    u, x = u[chosen].ravel(), x[chosen].ravel()
    order = np.argsort(u)
    x_rows = np.interp(rows, u[order], x[order])
    n_z = 0.0
    if depth is not None:
        r_mid = echo.medium.sound_speed * (record.t0 + record.n_samples / (2 * record.fs)) / 2
        n_z = (float(depth) - record.track[1]) / r_mid
        if not abs(n_z) < 1.0:
            raise ValueError(f"compensate_record depth: the plane z = {depth:g} m lies {abs(depth - record.track[1]):.4g} m "
                             f"from the track, beyond the record's mid range {r_mid:.4g} m; give the z of a plane the "
                             "beam reaches")
    return beam_correction(record, x_rows, n_z, subaperture, workers)
