"""The phase-centre conversion of a multireceiver record (Huang & Yang 2022 eqs. 4, 12, 16-17;
Wu et al. 2018 eq. 27): the PCA error is compensated; bad geometries are refused."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from _line_scenes import huang_six, mono_grid

import clsas
from clsas import metrics
from clsas.image.multireceiver import pca_record
from clsas.image.record import path_excess
from clsas.image.omegak import omega_k
from clsas.scene import presets


def test_interleaved_record_is_uniform_at_half_the_receiver_spacing(opencl_device):
    _, echo = huang_six()
    rec = pca_record(echo)
    assert rec.n_u == 32 * echo.n_pulses
    assert rec.du == pytest.approx(0.02, rel=1e-9)
    assert rec.nonstop


def test_pca_error_is_compensated(opencl_device):
    """Without the preprocessing the receivers' path excess d^2 / (4 r) (Heremans eq. 49; up to
    1.7 cm two-way at 40 m, over a wavelength of 1 cm) scatters the phases across the array and
    the points defocus; with it every point focuses to a peak at least 3 dB higher."""
    sc, echo = huang_six()
    assert path_excess(40.0, 1.3, 0.0, 1500.0, nonstop=False) > sc.waveform.wavelength(sc.medium)
    good = omega_k(pca_record(echo), elements=(0.08, 0.04), window="none", deconvolve=False, backend="opencl")
    bad = omega_k(pca_record(echo, compensate=False), elements=(0.08, 0.04), window="none", deconvolve=False,
                  backend="opencl")
    for p in sc.targets[0].positions:
        near = (p[1], p[0])
        peak_good = np.abs(good.data[metrics.peak_index(good.data, near=_index(good, near), radius=(4, 4))])
        peak_bad = np.abs(bad.data[metrics.peak_index(bad.data, near=_index(bad, near), radius=(4, 4))])
        assert 20 * np.log10(peak_good / peak_bad) > 3.0
        assert abs(metrics.analyse_point(good, near=near, radius=0.04)["y"].location - p[1]) < 0.004


def _index(image, near):
    return tuple(int(np.argmin(np.abs(image.axes[d] - c))) for d, c in zip(image.dims, near))


def test_bad_input(opencl_device):
    _, echo = huang_six()
    with pytest.raises(ValueError, match="range-compressed"):
        pca_record(echo.replace(compressed=False))
    with pytest.raises(ValueError, match="uniform"):
        pca_record(echo, receivers=list(range(16)))  # half the array leaves gaps between pings
    with pytest.raises(ValueError, match="receiver"):
        pca_record(echo, receivers=[40])
    with pytest.raises(ValueError, match="empty"):
        pca_record(echo, receivers=[])
    _, mono = mono_grid()
    off_line = mono.replace(rx_pos=mono.rx_pos + np.array([0.5, 0.0, 0.0]))
    with pytest.raises(ValueError, match="track line"):
        pca_record(off_line)


@pytest.mark.filterwarnings("ignore::clsas.scene.scenario.SamplingWarning")
def test_undersampled_array_is_refused(opencl_device):
    """Zhang et al. 2019's table as printed leaves gaps between pings' phase centres."""
    sc = presets.point_scene("zhang2019", n_pulses=4)
    sc = sc.replace(waveform=dataclasses.replace(sc.waveform, fs=2 * sc.waveform.bandwidth))
    echo = clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))
    with pytest.raises(ValueError, match="uniform"):
        pca_record(echo)
