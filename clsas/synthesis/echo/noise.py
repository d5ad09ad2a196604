"""Noise of the echo synthesis: :func:`add_noise`, :func:`signal_power`, :func:`snr_offset_db`.

Noise (``snr_db``): complex white Gaussian noise added to every recorded raw sample, seeded by
``seed`` (the same seed gives the same noise on either backend). ``simulate`` takes the SNR
per sample of the echo, the mean of |s|^2 over the samples where the noise-free echo is nonzero
over the noise variance (``snr_reference="echo"``), or over the whole record
(``snr_reference="record"``), the other reading of Kiang & Kiang 2022 section VII-C, which does not
define its SNR. The two readings, their exact conversion and what each means after compression
are derived in :func:`add_noise`.
"""

from __future__ import annotations

import numpy as np

from ...model import EchoData
from ...validate import choice, compression, instance, integer, scalar
from ..checks import SNR_DB_RANGE


def signal_power(data, n_valid=None, block: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """The signal power of the noise definition, per receiver and pulse: the sum of |s|^2
    (float64) over the samples a receiver records where the echo is nonzero, and their count;
    each (n_rx, n_pulses). Per pulse, so that pulse blocks computed apart (by the workers of
    :mod:`clsas.distributed`) give the same figures bit for bit as the whole cube."""
    n_rx, n_pulses = data.shape[:2]
    n_valid = np.full(n_rx, data.shape[2]) if n_valid is None else np.asarray(n_valid)
    sums = np.zeros((n_rx, n_pulses))
    counts = np.zeros((n_rx, n_pulses), np.int64)
    for h in range(n_rx):
        for s in range(0, n_pulses, block):
            mag2 = np.abs(data[h, s:s + block, :n_valid[h]]) ** 2
            sums[h, s:s + block] = mag2.astype(np.float64).sum(axis=-1)  # a row at a time, whatever the block
            counts[h, s:s + block] = np.count_nonzero(mag2, axis=-1)
    return sums, counts


#: The powers an SNR can be taken over (:func:`add_noise`).
SNR_REFERENCES = ("echo", "record")


def add_noise(data, snr_db: float, seed, n_valid=None, block: int = 64, power=None, reference: str = "echo"):
    """Add complex white Gaussian noise at ``snr_db`` per receiver.

    ``data`` is (n_rx, n_pulses, n_samples): a NumPy array (changed in place and returned) or
    a zarr array (read, noised and written back a pulse block at a time). Receiver h records
    only its first ``n_valid[h]`` samples (default all; an EchoData's are
    ``provenance["n_valid"]``), and only those get noise. ``power``: :func:`signal_power`'s
    (sums, counts) when already known, else computed from ``data``. Noise is drawn pulse block
    by pulse block (same draws for the same ``seed`` whatever the backend).

    The SNR. Receiver h's noise is circular with variance sigma^2 (sigma^2 / 2 per real
    component), SNR = P / sigma^2, and ``reference`` says which signal power P is meant:

    - ``"echo"`` (default; ``simulate(snr_db=)``): P_echo = the mean of |s|^2 over the samples
      where the noise-free echo is nonzero (n_echo of them: n_pulses x the echo's length);
    - ``"record"``: P_record = the mean of |s|^2 over every recorded sample (n_rec = n_pulses x
      n_valid[h]), zeros included: MATLAB's ``awgn(s, snr, "measured")`` on the whole record.

    Kiang & Kiang 2022 section VII-C adds "white Gaussian noise at a given level" to the
    received signal s_rb1(tau, eta) of its eq. (7) and quotes SNRs (-15 dB: 1.956 % error; >=
    -17 dB: 1.8-2.2 %; -20 dB: no SoWVD peak, Figs. 20-22) without saying over which samples the
    signal power is taken. Both readings are natural: eq. (7)'s s_rb1 is a rect of the pulse
    length T on each pulse, nonzero only on the echo ("echo", which is also ``awgn(s, snr)``
    without "measured" for a unit-amplitude echo, 0 dBW on its support), and the simulated
    matrix s_rb1 covers the recording window, whose mean power includes the zeros around the
    echo ("record"). They differ by the echo's duty in the record, exactly:

        SNR_record = SNR_echo + 10 log10(n_echo / n_rec)  dB,

    since P_record n_rec = P_echo n_echo (the zeros add no power); :func:`snr_offset_db` gives
    10 log10(n_echo / n_rec) per receiver. clsas's windows span the echo's migration over the
    exposure (a pulse length T at each pulse plus the range walk and curvature), so the offset
    grows with the exposure and the walk (``clsas reproduce kiang2022 --snr-sweep`` prints it
    per receiver). The paper's window is not given; in a window wider than clsas's the same
    noise would read as a lower "record" SNR still.

    After processing, what counts is the same in either reading: a point echo of N = T fs
    samples of power P_echo range-compresses (eq. 8) to a peak N^2 P_echo over noise N sigma^2,
    N SNR_echo per pulse (+20 dB on Table I, T fs = 100), and azimuth compression over M pulses
    multiplies it by M (tests/test_moving_noise.py measures both).
    """
    scalar("add_noise snr_db", snr_db, low=SNR_DB_RANGE[0], high=SNR_DB_RANGE[1], unit="dB")
    choice("add_noise reference", reference, SNR_REFERENCES)
    n_valid = np.full(data.shape[0], data.shape[2]) if n_valid is None else np.asarray(n_valid)
    sums, counts = signal_power(data, n_valid) if power is None else power
    total, heard = sums.sum(axis=1), counts.sum(axis=1)
    for h in range(data.shape[0]):
        if heard[h] == 0:
            raise ValueError(f"receiver {h} recorded no echo: its SNR is undefined")
    samples = heard if reference == "echo" else n_valid * data.shape[1]
    sigma = np.sqrt(total / samples / 10 ** (snr_db / 10) / 2).astype(np.float32)
    rng = np.random.default_rng(seed)
    in_place = isinstance(data, np.ndarray)
    for s in range(0, data.shape[1], block):
        part = data[:, s:s + block] if in_place else np.asarray(data[:, s:s + block])
        noise = rng.standard_normal(part.shape + (2,), dtype=np.float32)
        noise = (noise[..., 0] + 1j * noise[..., 1]) * sigma[:, None, None]
        for h in range(part.shape[0]):
            part[h, :, :n_valid[h]] += noise[h, :, :n_valid[h]]
        if not in_place:
            data[:, s:s + block] = part
    return data


def _noise_free(data, n_valid):
    """(array (n_rx, n_pulses, n_samples), n_valid (n_rx,) ints) of :func:`snr_offset_db`'s
    arguments, checked."""
    if isinstance(data, EchoData):
        compression("snr_offset_db data", data, compressed=False, advice="the offset is the raw echo's duty")
        if data.provenance.get("snr_db") is not None:
            raise ValueError(f"snr_offset_db data: must be a noise-free echo (the offset is its duty in the record), "
                             f"got one with snr_db {data.provenance['snr_db']}")
        n_valid = data.provenance.get("n_valid") if n_valid is None else n_valid
        data = data.data
    instance("snr_offset_db data", data, np.ndarray, "an EchoData or an array (n_rx, n_pulses, n_samples)")
    if data.ndim != 3 or 0 in data.shape:
        raise ValueError(f"snr_offset_db data: must be (n_rx, n_pulses, n_samples) with none empty, got shape "
                         f"{data.shape}")
    if n_valid is None:
        return data, np.full(data.shape[0], data.shape[2])
    if np.ndim(n_valid) != 1 or len(n_valid) != data.shape[0]:
        raise ValueError(f"snr_offset_db n_valid: must be {data.shape[0]} counts (one a receiver), got shape "
                         f"{np.shape(n_valid)}")
    return data, np.array([integer("snr_offset_db n_valid", n, 1, data.shape[2]) for n in n_valid])


def snr_offset_db(data, n_valid=None, power=None) -> np.ndarray:
    """SNR_record - SNR_echo per receiver, dB (n_rx,): 10 log10 of the fraction of the recorded
    samples where the noise-free echo ``data`` is nonzero (:func:`add_noise` derives it); <= 0.
    ``data``: a noise-free raw EchoData (its ``provenance["n_valid"]`` used) or an array
    (n_rx, n_pulses, n_samples); ``n_valid`` and ``power`` as in :func:`add_noise`. So
    ``simulate(sc, snr_db=x, snr_reference="record")`` and ``simulate(sc, snr_db=x -
    snr_offset_db(clean)[h])`` give receiver h the same noise."""
    data, n_valid = _noise_free(data, n_valid)
    _, counts = signal_power(data, n_valid) if power is None else power
    heard = counts.sum(axis=1)
    if np.any(heard == 0):
        raise ValueError(f"receivers {np.flatnonzero(heard == 0).tolist()} recorded no echo: their SNR is undefined")
    return 10 * np.log10(heard / (n_valid * data.shape[1]))
