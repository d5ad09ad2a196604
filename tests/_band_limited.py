"""Random band-limited rows: the test signal of the interpolators (tests/test_interp.py,
tests/test_stolt.py)."""

from __future__ import annotations

import numpy as np

FS = 40e3  # Hz: the sampling rate the rows are drawn at


def band_limited(rng, n_rows, n, band=24e3):
    """Random rows whose spectrum (over the source column index) occupies ``band`` of ``FS``."""
    white = rng.standard_normal((n_rows, n)) + 1j * rng.standard_normal((n_rows, n))
    f = np.fft.fftfreq(n)
    return np.fft.ifft(np.fft.fft(white, axis=1) * (np.abs(f) < band / FS / 2), axis=1)
