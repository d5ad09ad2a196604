"""One receiver's moving-target chain (Kiang & Kiang 2022 sections III-IV, VII-B, VII-C):
K_a,eq and f_dc,eq from the echo of a point target moving at a Table II case's velocity.

The truth is a phase-history fit of the simulated echo's exact delays (clsas.simulate.delays):
tau(eta) ~ tau0 + (f_dc / f0) eta + (K / (2 f0)) eta^2 fitted over a few pulses around eta = 0.
The paper's bound is 3 % (K) and 3 % or 1 Hz (f_dc); the tolerances below are ~10x the errors
measured on these reduced scenes (K within 0.1 %, f_dc within 0.06 Hz).

Reduced scenes (CI): the Table I sonar, target at (1989, 0, -350) m, with
- 1024 pulses at 80 Hz (12.8 s): K T_a ~ 62 Hz < PRF, unaliased;
- 512 pulses at 20 Hz (25.6 s): K T_a ~ 125 Hz, the azimuth chirp wraps ~6 times (Table I's
  80 s at 80 Hz wrap ~5 times) — the same aliasing at an eighth of the pulses.
"""

from __future__ import annotations

import numpy as np
import pytest

from clsas import PointTargets
from clsas.errors import EstimationError
from clsas.estimate.moving.chain import estimate_receiver, focus_receiver
from clsas.scene import presets
from clsas.scene.scenario import PulseSchedule
from clsas.simulate import delays, simulate

TARGET = (1989.0, 0.0, -350.0)
K_RTOL = 0.01      # measured <= 0.08 %
FDC_ATOL = 0.5     # Hz; measured <= 0.06 Hz


def scene(velocity, n_pulses: int, prf: float, targets=None):
    sonar = presets.kiang2022(n_pulses=n_pulses)
    if targets is None:
        targets = (PointTargets(TARGET, velocity=velocity),)
    return sonar.replace(schedule=PulseSchedule(prf=prf, n_pulses=n_pulses), targets=targets)


def truth(scenario, target: int = 0) -> dict:
    """{receiver: (K, f_dc, tau0)} from a cubic fit of the exact delays within ~1 s of eta = 0."""
    tau = delays(scenario, backend="numpy")[:, :, target]
    eta = scenario.eta
    near = np.abs(eta) <= max(1.0, 4 / scenario.schedule.prf)
    f0 = scenario.waveform.f0
    out = {}
    for h, name in enumerate(scenario.receiver_names):
        c = np.polyfit(eta[near], tau[h, near], 3)
        out[name] = (2 * f0 * c[1], f0 * c[2], c[3])
    return out


@pytest.fixture(scope="module", params=[(1024, 80.0), (512, 20.0)], ids=["unaliased", "aliased"])
def case1(request):
    n, prf = request.param
    sc = scene((0.0, -4.0, 0.0), n, prf)
    return sc, simulate(sc, backend="numpy", progress=False), truth(sc)


@pytest.mark.parametrize("receiver", ["A", "B", "C"])
def test_case1_each_receiver(case1, receiver):
    sc, echo, true = case1
    est = estimate_receiver(echo, receiver)
    k, f_dc, tau0 = true[receiver]
    assert est.receiver == receiver
    assert est.fm_rate == pytest.approx(k, rel=K_RTOL)
    assert est.doppler_centroid == pytest.approx(f_dc, abs=FDC_ATOL)
    # eq. (20): the focus sits at the two-way delay at eta = 0 (measured within 1/40 of a
    # sample), and at eta_c = -(f_dc,true - f_dc) / K: ~0
    assert abs(est.tau_c - tau0) < 0.1 / echo.fs
    assert abs(est.eta_c * k) < FDC_ATOL
    assert 10 * np.log10(est.peak_to_background) > 35


def test_focus_receiver_image(case1):
    sc, echo, true = case1
    est = estimate_receiver(echo, "A")
    img = focus_receiver(echo, "A", est, tau_span=0.01)
    assert img.dims == ("eta", "tau")
    mag = np.abs(img.data)
    i, j = np.unravel_index(np.argmax(mag), mag.shape)
    k, _, tau0 = true["A"]
    assert abs(img.axes["tau"][j] - tau0) <= 0.5 / (2 * echo.fs)  # within half an upsampled sample
    assert abs(img.axes["eta"][i]) <= 1.0 / (k * est.aperture)  # within one azimuth resolution cell
    # azimuth compression gathers the whole aperture: the peak is the coherent sum of all pulses
    # (the compressed range peak is 1 per pulse for a unit scatterer)
    assert mag[i, j] == pytest.approx(echo.n_pulses, rel=0.1)
    # one period PRF / K of eta, centred on the focus
    prf = sc.schedule.prf
    assert img.axes["eta"][-1] - img.axes["eta"][0] == pytest.approx(prf / k, rel=0.01)


@pytest.mark.parametrize("velocity", [(0.0, -5.0, 3.0), (3.0, 0.0, 0.0)], ids=["case3", "case8"])
def test_other_cases_aliased(velocity):
    sc = scene(velocity, 512, 20.0)
    echo = simulate(sc, backend="numpy", progress=False)
    true = truth(sc)
    for receiver in ("A", "C"):
        est = estimate_receiver(echo, receiver)
        k, f_dc, _ = true[receiver]
        assert est.fm_rate == pytest.approx(k, rel=K_RTOL)
        assert est.doppler_centroid == pytest.approx(f_dc, abs=FDC_ATOL)


def test_case7_moving_with_the_platform():
    """Case 7: K = 0 at A (the target keeps its range): estimated as ~0, not focusable; C focuses."""
    sc = scene((0.0, 3.0, 0.0), 512, 20.0)
    echo = simulate(sc, backend="numpy", progress=False)
    est_a = estimate_receiver(echo, "A")
    assert abs(est_a.fm_rate) < 1e-3 and abs(est_a.doppler_centroid) < 0.05
    assert not est_a.focusable
    with pytest.raises(EstimationError, match="receiver A: cannot focus"):
        focus_receiver(echo, "A", est_a)
    est_c = estimate_receiver(echo, "C")
    k, f_dc, _ = truth(sc)["C"]
    assert est_c.focusable
    assert est_c.fm_rate == pytest.approx(k, rel=K_RTOL)
    assert est_c.doppler_centroid == pytest.approx(f_dc, abs=FDC_ATOL)


def test_bad_input(case1):
    sc, echo, _ = case1
    with pytest.raises(ValueError, match="receiver: unknown receiver 'D'"):
        estimate_receiver(echo, "D")
    with pytest.raises(TypeError, match="receiver must be a receiver name"):
        estimate_receiver(echo, 0)
    from clsas import range_compress
    with pytest.raises(ValueError, match="echo must be raw"):
        estimate_receiver(range_compress(echo), "A")
    with pytest.raises(TypeError, match="echo must be an EchoData"):
        estimate_receiver(echo.data, "A")
    with pytest.raises(ValueError, match="p0 must be between one pulse"):
        estimate_receiver(echo, "A", p0=1e-4)
    est = estimate_receiver(echo, "A")
    with pytest.raises(ValueError, match="tau_span must be a positive"):
        focus_receiver(echo, "A", est, tau_span=-1.0)
