"""Moving-target estimation (Kiang & Kiang 2022, sections III-VII): closed forms, velocity and
position solves, the r-y mapping, the public API and its input checks."""

from __future__ import annotations

import numpy as np
import pytest

from clsas.estimate.moving.closedforms import closed_forms
from clsas.estimate.moving.layout import layout_of
from clsas.estimate.moving.velocity import solve_motion, solve_velocity
from clsas.scene import presets
from clsas.scene.scenario import PulseSchedule, Sonobuoy
from clsas.scene.targets import PointTargets
from clsas.simulate import delays

CENTRE = np.array([1989.0, 0.0, -350.0])  # the paper's target centre at eta = 0 (section II-B)


def other_layout():
    """Not the paper's: sonobuoy C moved ahead and nearer, a second sonobuoy D behind."""
    return presets.kiang2022(n_pulses=16).replace(
        sonobuoys=(Sonobuoy((300.0, 400.0, -100.0), name="C"), Sonobuoy((-200.0, -600.0, -80.0), name="D")))


OTHER_TARGET = (np.array([1500.0, 200.0, -200.0]), np.array([2.0, -3.0, 1.0]))


# --------------------------------------------------------------------------- closed forms


def test_case_1_gives_the_printed_truth():
    """Section III-C/IV: K_a1 = 4.879 Hz/s, f_dc1 = 6.533 Hz, K_a2 = 4.863 Hz/s, f_dc2 = -80.022 Hz.
    The printed eqs. reproduce them within 0.25 % (the paper rounds its geometry: 0.19 % on K_a1
    with either model); the exact rates are 0.95 % below the printed K_a2 because eq. 25 drops the
    radial term (closedforms module docstring)."""
    sc = presets.kiang2022(n_pulses=16)
    paper = closed_forms(sc, CENTRE, presets.KIANG_CASES[1], model="paper")
    exact = closed_forms(sc, CENTRE, presets.KIANG_CASES[1])
    assert paper["A"].doppler_centroid == pytest.approx(6.533, abs=1e-3)
    assert exact["A"].doppler_centroid == pytest.approx(6.533, abs=1e-3)
    assert paper["A"].fm_rate == pytest.approx(4.879, rel=0.0025)
    assert paper["B"].fm_rate == pytest.approx(4.863, rel=0.0025)
    assert paper["B"].doppler_centroid == pytest.approx(-80.022, rel=0.0025)
    assert exact["A"].fm_rate == pytest.approx(4.879, rel=0.0025)
    assert exact["B"].fm_rate == pytest.approx(4.863, rel=0.01)
    assert exact["B"].doppler_centroid == pytest.approx(-80.022, rel=0.0025)
    assert set(exact) == {"A", "B", "C"} and exact["C"].eta_c == 0.0


def _fit(scenario, position, velocity):
    """Quadratic fit of the simulator's exact delays over +-1 s: {name: (tau_c, f_dc, K)}."""
    sc = scenario.replace(schedule=PulseSchedule(prf=80.0, n_pulses=161),
                          targets=(PointTargets(position, velocity=velocity),))
    tau = delays(sc, backend="numpy")[:, :, 0]
    f0 = sc.waveform.f0
    out = {}
    for h, name in enumerate(sc.receiver_names):
        c2, c1, c0 = np.polyfit(sc.eta, tau[h], 2)
        out[name] = (c0, f0 * c1, 2 * f0 * c2)
    return out


@pytest.mark.parametrize("case", range(1, 9))
def test_closed_forms_match_the_phase_history_of_exact_delays(case):
    sc = presets.kiang2022(n_pulses=16)
    v = presets.KIANG_CASES[case]
    fit = _fit(sc, CENTRE, v)
    truth = closed_forms(sc, CENTRE, v)
    for name, (tau, fdc, k) in fit.items():
        assert truth[name].tau_c == pytest.approx(tau, abs=1e-10)
        # measured: 1e-5 relative, 0.3 mHz absolute (the cubic term over the +-1 s fit)
        assert truth[name].doppler_centroid == pytest.approx(fdc, rel=1e-4, abs=5e-3)
        assert truth[name].fm_rate == pytest.approx(k, rel=1e-4, abs=1e-5)


def test_closed_forms_on_another_layout_with_two_sonobuoys():
    sc = other_layout()
    fit = _fit(sc, *OTHER_TARGET)
    truth = closed_forms(sc, *OTHER_TARGET)
    assert set(truth) == {"A", "B", "C", "D"}
    for name, (tau, fdc, k) in fit.items():
        assert truth[name].tau_c == pytest.approx(tau, abs=1e-10)
        assert truth[name].doppler_centroid == pytest.approx(fdc, rel=1e-4, abs=5e-3)
        assert truth[name].fm_rate == pytest.approx(k, rel=1e-4, abs=1e-5)


def test_paper_rates_drop_the_radial_term():
    """Case 8 moves along the line of sight: eq. 5 is about twice the true rate at A."""
    sc = presets.kiang2022(n_pulses=16)
    paper = closed_forms(sc, CENTRE, presets.KIANG_CASES[8], model="paper")["A"].fm_rate
    exact = closed_forms(sc, CENTRE, presets.KIANG_CASES[8])["A"].fm_rate
    assert 1.8 < paper / exact < 2.1


def test_layout_from_echo_equals_layout_from_scenario():
    sc = presets.kiang2022(n_pulses=8).replace(targets=(PointTargets(CENTRE, velocity=(1.0, -2.0, 0.5)),))
    from clsas import simulate

    echo = simulate(sc, backend="numpy", progress=False)
    a, b = layout_of(sc), layout_of(echo)
    assert b.receivers.keys() == a.receivers.keys()
    np.testing.assert_allclose(b.tx_velocity, a.tx_velocity, atol=1e-9)
    for name in a.names:
        for got, want in zip(b.receivers[name], a.receivers[name]):
            np.testing.assert_allclose(got, want, atol=1e-6)


@pytest.mark.parametrize("bad, match", [((1.0, 2.0), "position"), (np.zeros((2, 3)), "position")])
def test_closed_forms_reject_a_position_of_the_wrong_shape(bad, match):
    with pytest.raises(ValueError, match=match):
        closed_forms(presets.kiang2022(n_pulses=4), bad, (0.0, 1.0, 0.0))


def test_closed_forms_reject_an_unknown_receiver_and_model():
    sc = presets.kiang2022(n_pulses=4)
    with pytest.raises(ValueError, match="receiver 'Z'"):
        closed_forms(sc, CENTRE, (0.0, 1.0, 0.0), receivers=["Z"])
    with pytest.raises(ValueError, match="model"):
        closed_forms(sc, CENTRE, (0.0, 1.0, 0.0), model="stop-and-go")


# --------------------------------------------------------------------------- velocity and position


@pytest.mark.parametrize("case", range(1, 9))
def test_velocity_from_closed_form_centroids(case):
    sc = presets.kiang2022(n_pulses=16)
    v = np.array(presets.KIANG_CASES[case])
    truth = closed_forms(sc, CENTRE, v)
    sol = solve_velocity(layout_of(sc), CENTRE, {n: d.doppler_centroid for n, d in truth.items()},
                         fm_rates={n: d.fm_rate for n, d in truth.items()})
    np.testing.assert_allclose(sol.velocity, v, atol=1e-6)
    assert sol.residual < 1e-6 and len(sol.alternatives) == 0
    assert np.all(sol.sigma > 0) and 0 < sol.confidence <= 1


def test_velocity_and_position_on_another_layout():
    sc = other_layout()
    truth = closed_forms(sc, *OTHER_TARGET)
    lay = layout_of(sc)
    sol = solve_velocity(lay, OTHER_TARGET[0], {n: d.doppler_centroid for n, d in truth.items()})
    np.testing.assert_allclose(sol.velocity, OTHER_TARGET[1], atol=1e-6)
    joint = solve_motion(lay, {n: d.tau_c for n, d in truth.items()}, {n: d.doppler_centroid for n, d in truth.items()},
                         {n: d.fm_rate for n, d in truth.items()})
    np.testing.assert_allclose(joint.position, OTHER_TARGET[0], atol=1e-4)
    np.testing.assert_allclose(joint.velocity, OTHER_TARGET[1], atol=1e-6)


def test_joint_solve_with_measurement_errors_stays_within_its_stated_sigma():
    """Delays off by a tenth of a range cell and centroids by 0.3 Hz (case 3): the position and
    velocity errors stay within 3 of the reported sigmas."""
    sc = presets.kiang2022(n_pulses=16)
    v = np.array(presets.KIANG_CASES[3])
    truth = closed_forms(sc, CENTRE, v)
    rng = np.random.default_rng(1)
    tau = {n: d.tau_c + 0.1 / 20e3 * rng.standard_normal() for n, d in truth.items()}
    fdc = {n: d.doppler_centroid + 0.3 * rng.standard_normal() for n, d in truth.items()}
    joint = solve_motion(layout_of(sc), tau, fdc, {n: d.fm_rate for n, d in truth.items()})
    assert np.all(np.abs(joint.position - CENTRE) < 3 * joint.position_sigma + 1e-6)
    assert np.all(np.abs(joint.velocity - v) < 3 * joint.sigma + 1e-6)
    assert np.linalg.norm(joint.velocity - v) / np.linalg.norm(v) < 0.03


def test_velocity_solve_rejects_too_few_receivers_and_bad_position():
    sc = presets.kiang2022(n_pulses=4)
    lay = layout_of(sc)
    with pytest.raises(ValueError, match="at least 3 receiver"):
        solve_velocity(lay, CENTRE, {"A": 1.0, "B": 2.0})
    with pytest.raises(ValueError, match="position"):
        solve_velocity(lay, CENTRE[:2], {"A": 1.0, "B": 2.0, "C": 0.0})
    with pytest.raises(ValueError, match="receiver 'Q'"):
        solve_velocity(lay, CENTRE, {"A": 1.0, "B": 2.0, "Q": 0.0})


# --------------------------------------------------------------------------- preset


def test_kiang_case_hull_is_the_albacore_scaled_down_six_times():
    """Section II-B: the model is scaled down by six, LOA about 10 m."""
    hull = presets.kiang2022_case(1, n_pulses=4, sections=16, stations=16).targets[0]
    extents = hull.mesh.extents  # body frame: x_b along the hull
    assert 10.0 < extents[0] < 11.0
    assert 1.3 < min(extents[1], extents[2]) < 2.5
