"""omega-k (Heremans 2009 section 4): agreement with back-projection, resolution (eq. 47),
the non-stop-and-go shift, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from _line_scenes import MONO_D, assert_agrees_with_backprojection, huang_six, mono_grid

from clsas import metrics
from clsas.image.omegak import omega_k
from clsas.image.record import line_record


@pytest.mark.parametrize("scene", ["mono", "huang"])
def test_agrees_with_backprojection(opencl_device, scene):
    assert_agrees_with_backprojection(lambda rec, **kw: omega_k(rec, backend="opencl", **kw), scene)


def test_hamming_resolution_follows_eq_47(opencl_device):
    """delta y = 1.30 D / 2 and delta x = 1.30 x 2 pi / B_kx (eq. 45's extracted band)."""
    sc, echo = mono_grid()
    img = omega_k(echo, window="hamming", elements=(MONO_D, MONO_D), deconvolve=False, backend="opencl")
    c, f0, b = sc.medium.sound_speed, sc.waveform.f0, sc.waveform.bandwidth
    k_min, k_max = 2 * np.pi * (f0 - b / 2) / c, 2 * np.pi * (f0 + b / 2) / c
    b_kx = np.sqrt(4 * k_max**2 - (2 * np.pi / MONO_D) ** 2) - 2 * k_min
    for p in sc.targets[0].positions:
        res = metrics.analyse_point(img, near=(p[1], p[0]), radius=MONO_D / 2)
        assert abs(res["y"].irw / (1.30 * MONO_D / 2) - 1) < 0.1
        assert abs(res["x"].irw / (1.30 * 2 * np.pi / b_kx) - 1) < 0.1


def test_numpy_and_opencl_stolt_give_one_image(opencl_device):
    _, echo = mono_grid()
    a = omega_k(echo, elements=(MONO_D, MONO_D), backend="numpy").data
    b = omega_k(echo, elements=(MONO_D, MONO_D), backend="opencl").data
    assert np.linalg.norm(a - b) / np.linalg.norm(a) < 1e-4


def test_nonstop_shift_is_corrected(opencl_device):
    """Imaged as if stop-and-go, a target at range r lands v r / c behind its true position
    (the echo's phase centre); the default correction puts it back."""
    sc, echo = mono_grid()
    v, c = sc.platform.speed, sc.medium.sound_speed
    right = omega_k(echo, elements=(MONO_D, MONO_D), window="none", backend="opencl")
    wrong = omega_k(line_record(echo, stop_and_go=True), elements=(MONO_D, MONO_D), window="none", backend="opencl")
    for p in sc.targets[0].positions:
        y_right = metrics.analyse_point(right, near=(p[1], p[0]), radius=MONO_D)["y"].location
        y_wrong = metrics.analyse_point(wrong, near=(p[1], p[0]), radius=MONO_D)["y"].location
        assert abs(y_right - p[1]) < 0.1 * MONO_D / 2
        assert abs((p[1] - y_wrong) / (v * p[0] / c) - 1) < 0.15


def test_bad_input():
    _, mono = mono_grid()
    _, multi = huang_six()
    with pytest.raises(ValueError, match="window"):
        omega_k(mono, window="blackman", backend="numpy")
    with pytest.raises(ValueError, match="elements"):
        omega_k(mono, elements=(0.05, 0.05), backend="numpy")  # needs samples 0.025 m apart
    with pytest.raises(ValueError, match="elements"):
        omega_k(mono, elements=(-1.0, 0.2), backend="numpy")
    with pytest.raises(ValueError, match="not monostatic"):
        omega_k(multi, receiver=5, backend="numpy")
    with pytest.raises(ValueError, match="receiver"):
        omega_k(mono, receiver=3, backend="numpy")
    with pytest.raises(ValueError, match="one index or name"):
        omega_k(mono, receiver=[0, 0], backend="numpy")
    with pytest.raises(ValueError, match="range-compressed"):
        omega_k(mono.replace(compressed=False), backend="numpy")
    with pytest.raises(ValueError, match="straight"):
        bent = mono.tx_pos.copy()
        bent[100:, 0] += 0.01
        omega_k(mono.replace(tx_pos=bent), backend="numpy")
    with pytest.raises(TypeError, match="LineRecord"):
        omega_k(np.zeros((4, 4), complex), backend="numpy")
