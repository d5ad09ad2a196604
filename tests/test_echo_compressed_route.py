"""The raw route into the compressed domain (clsas/synthesis/echo/compressed.py): where a path's
compressed response has more taps than its pulse has samples (Heremans's sonar: T fs = 125, 250
taps at -40 dB), simulate(..., compressed=...) synthesizes the raw echo and range-compresses it
record by record, so it drops nothing: it equals range_compress(simulate(...)) to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from clsas import range_compress, simulate
from clsas.scene import presets
from clsas.scene.targets import PointTargets
from clsas.synthesis.echo.compressed import CompressedResponse
from clsas.synthesis.echo.options import SynthesisOptions
from clsas.synthesis.echo.physics import Physics


def heremans_points():
    sc = presets.heremans2009(n_pulses=4)
    return sc.replace(targets=(PointTargets([[40.0, 0.1, -10.0], [47.0, -0.3, -12.0], [47.4, 0.2, -12.0]],
                                            reflectivity=[1.0, 0.5j, -0.8]),))


def error_db(got, ref) -> float:
    got, ref = got.data.astype(np.complex128), ref.data.astype(np.complex128)
    return float(20 * np.log10(max(np.max(np.abs(got - ref)), 1e-300) / np.max(np.abs(ref))))


@pytest.mark.parametrize("window", ["none", "hamming"])
def test_raw_route_equals_range_compress(backend, window):
    """Against range_compress of the float64 reference's raw echo: measured -113 dB re the peak on
    OpenCL (float32 accumulation) and -134 dB with NumPy (complex64 samples), either window."""
    sc = heremans_points()
    ref = range_compress(simulate(sc, backend="numpy", progress=False), window=window)  # the float64 reference
    got = simulate(sc, backend=backend, progress=False, compressed=True if window == "none" else window)
    route = got.provenance["compressed"]
    assert route["route"] == "raw echo + matched filter" and route["discarded_db"] is None
    np.testing.assert_array_equal(got.t0, ref.t0)
    for h, n in enumerate(got.provenance["n_valid"]):
        ref.data[h, :, n:] = 0  # simulate records nothing past a receiver's window
    assert error_db(got, ref) < (-93.0 if backend == "opencl" else -114.0), error_db(got, ref)


def test_route_follows_the_work_per_path():
    """Taps where the response is shorter than the pulse (Huang's, no window: 98 taps against
    250 samples), the raw route where longer (Heremans's 250 against 125), and for paths with
    their own laws (3 tables) once 3 (2 L + 2) exceeds the pulse."""
    huang = CompressedResponse.of(presets.huang2022().waveform, "none", -40.0)
    heremans = CompressedResponse.of(presets.heremans2009().waveform, "none", -40.0)
    plain = SynthesisOptions(intra_pulse="none", backend="numpy")
    assert Physics(plain, response=huang).writes_taps
    assert Physics(plain, response=heremans).compress_raw
    assert Physics(SynthesisOptions(intra_pulse="all", backend="numpy"), response=huang, moving=True).compress_raw
    assert not Physics(plain).compress_raw and not Physics(plain).writes_taps
    # paths with their own chirp: the taps while its mismatch is small, the raw route beyond (E1)
    doppler = SynthesisOptions(intra_pulse="all", backend="numpy")
    slow = CompressedResponse.of(presets.huang2022().waveform, "hamming", -40.0)
    assert Physics(doppler, response=slow, moving=True, doppler_mismatch=0.05).writes_taps
    assert Physics(doppler, response=slow, moving=True, doppler_mismatch=0.5).compress_raw
