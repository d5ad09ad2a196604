"""Estimates that know when they are wrong (issue 26, deliverable 1): the SoWVD's cross-terms on
targets of several scatterers, the receivers' FM rates against one velocity, and sigma and
confidence that say how far to trust the velocity (Kiang & Kiang 2022, sections III-V).

The targets here are groups of point scatterers moving together (a rigid target) in the Table I
geometry: three equal points on the hull's axis (the issue's case), and seeded random groups of
3-20 points (amplitudes 0.3-1) over a 10 m x 2 m footprint at random headings, the footprint's
centre given as the position.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import clsas
from clsas.errors import EstimationError
from clsas.estimate.moving import chain, closed_forms, layout_of, motion_from_receivers
from clsas.estimate.moving.sowvd import modified_sowvd, rfrt
from clsas.estimate.moving import trace
from clsas.estimate.moving.records import UPSAMPLE
from clsas.scene import presets
from clsas.scene.targets import PointTargets

CENTRE = np.array([1989.0, 0.0, -350.0])
BOUND = 0.03  # the paper's velocity error bound
#: Of test_random_targets_at_the_papers_noise's 8 targets at -15 dB, estimated at least (measured 8).
MIN_ESTIMATED = 6


def random_target(seed: int):
    """(positions (n, 3), amplitudes (n,), velocity (3,)): 3-20 points (amplitudes 0.3-1) over a
    10 m x 2 m footprint centred on CENTRE, its long side along a random heading, moving along
    it at 3-6 m/s with a vertical speed within +-1 m/s."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 21))
    heading = rng.uniform(-np.pi, np.pi)
    speed = rng.uniform(3.0, 6.0)
    velocity = np.array([speed * np.cos(heading), speed * np.sin(heading), rng.uniform(-1.0, 1.0)])
    along, across = rng.uniform(-5.0, 5.0, n), rng.uniform(-1.0, 1.0, n)
    axis = np.array([np.cos(heading), np.sin(heading), 0.0])
    side = np.array([-np.sin(heading), np.cos(heading), 0.0])
    return CENTRE + along[:, None] * axis + across[:, None] * side, rng.uniform(0.3, 1.0, n), velocity


def _echo(positions, amplitudes, velocity, n_pulses):
    sc = presets.kiang2022(n_pulses=n_pulses).replace(
        targets=(PointTargets(positions, reflectivity=amplitudes, velocity=velocity),))
    return sc, clsas.simulate(sc, backend="opencl", progress=False)


def _error(est, velocity) -> float:
    return float(np.linalg.norm(est.velocity - velocity) / np.linalg.norm(velocity))


@pytest.fixture(scope="module")
def axis_points(opencl_device):
    """Three equal points on the hull's axis (centre and +-5 m along the track), Table II case 1,
    2048 pulses: the issue's case (396 % error at confidence 1.00 with one SoWVD map)."""
    v = np.array(presets.KIANG_CASES[1])
    return (v,) + _echo(np.stack([CENTRE, CENTRE + [0, 5, 0], CENTRE - [0, 5, 0]]), np.ones(3), v, 2048)


def test_one_sowvd_map_locks_on_a_cross_term_the_rate_search_does_not(axis_points):
    """The mechanism (sowvd module docstring): on the three points the strongest peak of the map
    at p0 = 0.1 s is a cross-term at every receiver (measured K -29.9, -29.6, -22.4 Hz/s); the
    maps at several lag offsets agree on the true rate (measured within 0.3 %, 1.3-1.8 dB ahead
    of the next candidate a map)."""
    v, sc, echo = axis_points
    truth = closed_forms(sc, CENTRE, v)
    for name in "ABC":
        rec = chain.records(echo, name)
        line = rfrt(rec.x, trace.support(rec.x, UPSAMPLE))
        single = modified_sowvd(line, rec.prf, chain.P0)
        assert abs(single.fm_rate - truth[name].fm_rate) > 5.0, name  # a cross-term, far off
        search = chain.sowvd(rec, chain.P0)
        assert search.fm_rate == pytest.approx(truth[name].fm_rate, rel=0.01), name
        assert search.margin_db > 0.5, name


def test_three_points_on_the_axis(axis_points):
    """The issue's case end to end: the velocity within 0.1 % (measured 0.04 %) and the estimate
    says it is good (confidence measured 0.84; no receiver flagged)."""
    v, _, echo = axis_points
    est = clsas.estimate_motion(echo, position=CENTRE)
    assert _error(est, v) < 0.001, est.velocity
    assert est.confidence > 0.5 and est.problems == ()
    assert np.all(np.abs(est.velocity - v) < 3 * est.sigma)


def test_a_receiver_on_a_cross_term_is_named_and_the_confidence_falls(axis_points):
    """Receiver C forced onto another candidate of its rate search (a cross-term): the solution
    disagrees with C's FM rate, the problem names C and why, the confidence falls below 0.5 and
    sigma widens; the re-pick (estimate's last step) finds C's true rate again."""
    from clsas.estimate.moving.motion import _repick

    v, _, echo = axis_points
    est = clsas.estimate_motion(echo, position=CENTRE)
    rec = chain.records(echo, "C")
    rx = est.receivers["C"]
    wrong = max((c[0] for c in rx.fm_rate_candidates), key=lambda k: abs(k - rx.fm_rate))
    estimates = dict(est.receivers)
    estimates["C"] = chain.with_rate(rec, rx.search, wrong)
    bad = motion_from_receivers(est.layout, estimates, CENTRE)
    assert "C" in bad.consistency.outliers
    assert any(p.startswith("receiver C: its FM rate") and "cross-term" in p for p in bad.problems)
    assert bad.confidence < 0.5
    assert np.all(bad.sigma > est.sigma)
    kept = {"C": rec}
    fixed = _repick(est.layout, bad, estimates, lambda name: kept.setdefault(name, chain.records(echo, name)), CENTRE)
    assert "C" in fixed.repicked and fixed.problems == ()
    assert estimates["C"].fm_rate == pytest.approx(rx.fm_rate, rel=0.01)
    assert fixed.confidence > 0.5


@pytest.mark.parametrize("case", [1, 6])
@pytest.mark.parametrize("name", ["A", "B", "C"])
@pytest.mark.parametrize("shift", [-1500.0, 1500.0])
def test_an_unphysical_speed_is_refused_naming_the_receiver(case, name, shift):
    """No echo: Table II case 1's or 6's true per-receiver values with one receiver's centroid
    moved by +-1500 Hz (a Radon line on noise): the centroids solve to 119-318 m/s (case 6),
    beyond validate.MAX_SPEED, where the delay model's own ValueError escaped estimate_motion
    (tests/test_moving_noise.py's 6400-pulse hull, case 6, on da5b311). The estimate refuses
    with an EstimationError that names the moved receiver (the one without which the others
    agree) and the speed."""
    sc = presets.kiang2022(n_pulses=512)
    truth = closed_forms(sc, CENTRE, presets.KIANG_CASES[case])
    wrong = dict(truth)
    wrong[name] = dataclasses.replace(truth[name], doppler_centroid=truth[name].doppler_centroid + shift)
    with pytest.raises(EstimationError, match=rf"^receiver {name}: the receivers' FM rates and Doppler centroids "
                                              r"solve to a speed of \d+\.\d m/s, beyond the 100 m/s"):
        motion_from_receivers(layout_of(sc), wrong, position=CENTRE)


def test_inconsistent_closed_forms_lower_the_confidence():
    """No echo: the true per-receiver values of case 3, then C's FM rate and centroid replaced by
    a cross-term's: the velocity solved from the centroids is > 3 % off, and the estimate says so
    (confidence < 0.5, C named); the true values give confidence ~1 and no problem."""
    sc = presets.kiang2022(n_pulses=512)
    v = np.array(presets.KIANG_CASES[3])
    truth = closed_forms(sc, CENTRE, v)
    good = motion_from_receivers(layout_of(sc), truth, position=CENTRE)
    assert good.confidence > 0.99 and good.problems == ()
    wrong = dict(truth)
    wrong["C"] = dataclasses.replace(truth["C"], fm_rate=truth["C"].fm_rate + 8.0,
                                     doppler_centroid=truth["C"].doppler_centroid + 7.0)
    bad = motion_from_receivers(layout_of(sc), wrong, position=CENTRE)
    assert _error(bad, v) > BOUND
    assert bad.confidence < 0.5
    assert bad.consistency.outliers[0] == "C" and "receiver C" in bad.problems[0]


def test_a_receiver_that_focused_two_objects_is_named_and_the_confidence_halves():
    """Review R2 through the consistency check: the true per-receiver values of case 1, then C
    as a chain estimate whose focus also confirmed a rate 30 % off (chain.ReceiverEstimate's
    fm_rate_rivals, kept the brighter). C's kept K agrees with the solution, so it is no
    outlier (no re-pick), but the estimate names C and both rates, and its confidence is
    halved (one of two equally confirmed objects)."""
    sc = presets.kiang2022(n_pulses=512)
    truth = closed_forms(sc, CENTRE, np.array(presets.KIANG_CASES[1]))
    good = motion_from_receivers(layout_of(sc), truth, position=CENTRE)
    c = truth["C"]
    two = dict(truth)
    two["C"] = chain.ReceiverEstimate(fm_rate=c.fm_rate, doppler_centroid=c.doppler_centroid, receiver="C",
                                      tau_c=c.tau_c, eta_c=c.eta_c, peak_to_background=1.0, p0=chain.P0,
                                      aperture=layout_of(sc).aperture, fm_rate_source="focus",
                                      fm_rate_rivals=((1.3 * c.fm_rate, "trace", 24.0),))
    flagged = motion_from_receivers(layout_of(sc), two, position=CENTRE)
    np.testing.assert_allclose(flagged.velocity, good.velocity, rtol=1e-9)
    assert flagged.consistency.outliers == () and flagged.consistency.rate_ambiguity == 2
    assert flagged.confidence == pytest.approx(good.confidence / 2, rel=1e-9)
    assert len(flagged.problems) == 1 and flagged.problems[0].startswith("receiver C: its record focuses sharply")
    assert f"{1.3 * c.fm_rate:.4g} Hz/s (trace" in flagged.problems[0]


def test_a_flagged_estimate_names_why_even_when_every_receiver_agrees():
    """The verifier's case (a random group, 8 m/s, v_z -0.7 m/s: error 0.03 %, confidence 0.27,
    ``problems == ()``): whenever the confidence is below 0.5 ``problems`` says why. Here the
    true per-receiver values of case 1 (every receiver consistent) with the velocity's sigma
    widened as a wide v_z sigma does: the problem names the velocity, its widest component and
    the confidence; with the ambiguity of two roots it names that instead."""
    sc = presets.kiang2022(n_pulses=512)
    truth = closed_forms(sc, CENTRE, np.array(presets.KIANG_CASES[1]))
    good = motion_from_receivers(layout_of(sc), truth, position=CENTRE)
    assert good.problems == () and good.uncertainty_problem == ""
    wide = dataclasses.replace(good, sigma=np.array([0.01, 0.02, 0.16]), confidence=0.27)
    assert len(wide.problems) == 1 and wide.problems[0].startswith("velocity: its 1-sigma")
    assert "widest in z" in wide.problems[0] and "0.27" in wide.problems[0]
    tied = dataclasses.replace(good, confidence=0.49, ambiguity=2)
    assert tied.problems[0].startswith("velocity: 2 velocities fit")


@pytest.mark.parametrize("seed", [2, 22, 23])
def test_random_targets_are_right_or_flagged(opencl_device, seed):
    """Seeded random groups (512 pulses, 6.4 s): the velocity within the paper's 3 % or the
    estimate flagged (confidence < 0.5). Seed 22 needed two receivers re-picked (their SoWVD
    score ties a cross-term within 0.1 dB); seed 23 (3 points) has a receiver that cannot refine
    its centroid, so its sigma is wide."""
    positions, amplitudes, velocity = random_target(seed)
    _, echo = _echo(positions, amplitudes, velocity, 512)
    est = clsas.estimate_motion(echo, position=CENTRE)
    assert _error(est, velocity) < BOUND or est.confidence < 0.5, (est.velocity, velocity, est.confidence)
    assert est.confidence >= 0.5 or est.problems, (est.confidence, est.sigma)
    assert np.all(np.abs(est.velocity - velocity) <= 3 * est.sigma), (est.velocity - velocity, est.sigma)


@pytest.mark.slow
def test_sigma_is_calibrated_over_random_targets(opencl_device):
    """Over 24 seeded random groups (512 pulses): every velocity within 3 % or flagged, the true
    error within 3 sigma (each component) in >= 90 % of them, and the confidence above 0.5 in
    most (an estimator that flags everything would pass the first two)."""
    within, confident, n = 0, 0, 24
    for seed in range(n):
        positions, amplitudes, velocity = random_target(seed)
        _, echo = _echo(positions, amplitudes, velocity, 512)
        est = clsas.estimate_motion(echo, position=CENTRE)
        assert _error(est, velocity) < BOUND or est.confidence < 0.5, (seed, est.velocity, velocity)
        assert est.confidence >= 0.5 or est.problems, (seed, est.confidence, est.sigma)
        within += bool(np.all(np.abs(est.velocity - velocity) <= 3 * est.sigma))
        confident += est.confidence >= 0.5
    assert within >= 0.9 * n
    assert confident >= 0.75 * n


def test_the_followed_traces_curvature_gives_the_rate_the_sowvd_misses(opencl_device):
    """Random target 4004 (16 points, 2048 pulses) at "echo" SNR -15 dB (noise seed 1), receiver A:
    the SoWVD scores 16.0 dB (threshold 26) and its best candidate, K = 28.7 Hz/s against a true
    0.333, focuses nothing (13.9 dB over the median against FOCUS_DB 20); the followed traces'
    curvatures read 0.323 / 0.314 Hz/s (track.trace_rate), the focus takes the first to 0.3326
    Hz/s, which passes FOCUS_DB (32.7 dB) and SHARP_DB (5.7 dB). Measured K -0.05 %, f_dc 0.05 Hz
    off; asserted 0.5 % and 0.5 Hz."""
    from clsas.estimate.moving.records import records
    from clsas.synthesis.echo.noise import add_noise

    positions, amplitudes, velocity = random_target(4004)
    sc, echo = _echo(positions, amplitudes, velocity, 2048)
    echo = echo.replace(data=add_noise(echo.data.copy(), -15.0, 1, echo.provenance["n_valid"]))
    truth = closed_forms(sc, CENTRE, velocity)["A"]
    est = chain.estimate_records(records(echo, "A"))
    search = est.search  # the rate search the estimate came from
    assert search.score_db < chain.THRESHOLD_DB and abs(search.fm_rate / truth.fm_rate - 1) > 0.5, search
    assert search.trace_rates and abs(search.trace_rates[0] / truth.fm_rate - 1) < 0.3, search.trace_rates
    assert est.fm_rate == pytest.approx(truth.fm_rate, rel=0.005)
    assert est.doppler_centroid == pytest.approx(truth.doppler_centroid, abs=0.5)
    assert est.fm_rate_source == "trace" and est.fm_rate_rivals == ()


@pytest.mark.slow
def test_random_targets_at_the_papers_noise(opencl_device):
    """Issue 26 items 1 and 3 together: seeded random groups (4001-4008, 4-20 points, 2048 pulses,
    the paper's) at "echo" SNR -15 dB (noise seed 1). Each within 3 % or flagged (confidence <
    0.5), or an EstimationError naming the receiver; at least MIN_ESTIMATED estimated. Before the
    followed trace's curvature was a candidate rate (chain.estimate_records, track.trace_rate)
    5 of the 8 were refused (receiver A or B: the SoWVD of many scatterers peaked on the noise,
    15.4-16.0 dB against 26, and its best candidate focused nothing, 13.7-14.6 dB against 20);
    with it, measured: all 8 estimate, 0.04-1.44 % (1.44 %: 4003, 5 points), confidence
    0.85-1.00, the error within 3 sigma in all 8 (load 5-10). Takes ~26 min at load 8-11."""
    from clsas.synthesis.echo.noise import add_noise

    estimated = 0
    for seed in range(4001, 4009):
        positions, amplitudes, velocity = random_target(seed)
        _, echo = _echo(positions, amplitudes, velocity, 2048)
        echo = echo.replace(data=add_noise(echo.data.copy(), -15.0, 1, echo.provenance["n_valid"]))
        try:
            est = clsas.estimate_motion(echo, position=CENTRE)
        except EstimationError as error:
            assert str(error).startswith("receiver "), (seed, error)
            continue
        estimated += 1
        assert _error(est, velocity) < BOUND or est.confidence < 0.5, (seed, est.velocity, velocity, est.confidence)
        assert est.confidence >= 0.5 or est.problems, (seed, est.confidence, est.sigma)
    assert estimated >= MIN_ESTIMATED, estimated


# --------------------------------------------------------------------------- intra-pulse Doppler


@pytest.fixture(scope="module", params=[6, 8])
def intra_pulse_echoes(request, opencl_device):
    """Table II cases 6 and 8 (the largest Doppler centroids, 410-597 Hz), one point, 512 pulses,
    with and without intra-pulse Doppler (clsas.simulate's intra_pulse)."""
    v = np.array(presets.KIANG_CASES[request.param])
    sc = presets.kiang2022(n_pulses=512).replace(targets=(PointTargets(CENTRE, velocity=v),))
    return v, sc, {mode: clsas.simulate(sc, backend="opencl", progress=False, intra_pulse=mode)
                   for mode in ("none", "moving")}


def test_intra_pulse_doppler_shifts_the_compressed_peak_by_f_dc_over_k_r(intra_pulse_echoes):
    """The range-Doppler coupling of the LFM (layout module docstring): with intra-pulse Doppler the
    compressed peak lies f_dc / K_r after the closed form's delay (measured within 1.2 us of it,
    up to 150 us: three range cells), without it on the closed form (within 1 us)."""
    from clsas.estimate.moving import delay_history

    v, sc, echoes = intra_pulse_echoes
    truth = closed_forms(sc, CENTRE, v)
    for mode, echo in echoes.items():
        comp = clsas.range_compress(echo, upsample=16)
        lay = layout_of(echo)
        assert lay.range_doppler == (0.0 if mode == "none" else echo.waveform.duration / echo.waveform.bandwidth)
        for h, name in enumerate(echo.receivers):
            mag = np.abs(comp.data[h])
            k = np.argmax(mag, axis=1)
            rows = np.arange(mag.shape[0])
            a, b, c = mag[rows, k - 1], mag[rows, k], mag[rows, k + 1]
            peak = comp.t0[h] + (k + 0.5 * (a - c) / (a - 2 * b + c)) / comp.fs
            shift = np.median(peak - delay_history(lay, name, CENTRE, v, echo.eta))
            expected = 0.0 if mode == "none" else truth[name].doppler_centroid * echo.waveform.duration / \
                echo.waveform.bandwidth
            assert shift == pytest.approx(expected, abs=3e-6), (mode, name)


def test_the_estimate_and_the_focus_take_the_coupling_into_account(intra_pulse_echoes):
    """With intra-pulse Doppler the velocity stays within 0.1 % (measured 0.004 % and 0.034 %),
    the position estimated with it within 2 cm (measured 5 mm; 0.1-0.3 m when the coupling is
    ignored) and the back-projected point within 0.5 dB of its peak without intra-pulse Doppler
    (measured -0.1 to -0.2 dB)."""
    v, _, echoes = intra_pulse_echoes
    peaks = {}
    for mode, echo in echoes.items():
        joint = clsas.estimate_motion(echo)
        assert _error(joint, v) < 0.001, (mode, joint.velocity)
        assert np.linalg.norm(joint.position - CENTRE) < 0.02, (mode, joint.position)
        est = clsas.estimate_motion(echo, position=CENTRE)
        peaks[mode] = {n: np.abs(im.data).max() for n, im in clsas.focus_moving(echo, est, half_size=1.0).items()}
    for name, peak in peaks["moving"].items():
        assert 20 * np.log10(peak / peaks["none"][name]) > -0.5, name


def test_the_wrapped_band_edge_of_a_fast_target_is_not_taken_for_the_target(opencl_device):
    """Seed 7's velocity (f_dc -822 to -829 Hz, K 0.15-0.52 Hz/s) on one point with intra-pulse
    Doppler: the echo's band, shifted by 822 Hz, wraps at Table I's F_r = B, and the wrapped
    sliver focused as a ghost 5 ms and 29-100 s away that the extent took for the target (eta_c
    29-100 s off, the centroids 14.5 Hz off, the velocity 8 sigma off at confidence 0.94).
    With the band zeroed (:func:`clsas.estimate.moving.records.wrapped_band`): eta_c within 0.5 s of the middle of the
    record (measured 0.03-0.08 s) and the velocity within 0.1 % (measured < 0.01 %)."""
    from clsas.estimate.moving.records import records, wrapped_band

    _, _, v = random_target(7)
    sc, echo = _echo(CENTRE[None], np.ones(1), v, 512)
    est = clsas.estimate_motion(echo, position=CENTRE)
    assert _error(est, v) < 0.001 and est.confidence > 0.5, est.velocity
    middle = 0.5 * (echo.eta[0] + echo.eta[-1])
    for name, rx in est.receivers.items():
        assert abs(rx.eta_c - middle) < 0.5, name
        (band,) = wrapped_band(records(echo, name), rx.doppler_centroid, rx.fm_rate)  # f_D < 0 throughout
        edge = 0.5 * echo.fs
        assert band[0] == -edge and band[1] - band[0] > abs(rx.doppler_centroid), (name, band)
    none = clsas.simulate(sc, backend="opencl", progress=False, intra_pulse="none")
    assert wrapped_band(records(none, "A"), -822.0, 0.15) == []


def test_both_band_edges_wrap_when_the_doppler_changes_sign():
    """Review M2: f_D = f_dc + K d takes both signs when |K| T_a / 2 > |f_dc| (f_dc 50 Hz, K 7.5
    Hz/s over 80 s: f_D from -250 to 350 Hz), and both edges of the band wrap at F_r = B: the top
    by 350 Hz (and the margin), the bottom by 250 Hz."""
    from clsas.estimate.moving.records import Records, wrapped_band

    eta = np.arange(6400) / 80.0 - 40.0
    rec = Records(x=np.zeros((6400, 8), np.complex64), eta=eta, t0=0.0, fs=40e3, f0=150e3, bandwidth=20e3, name="A",
                  range_doppler=1e-6)
    margin = 0.01 * 20e3
    top, bottom = wrapped_band(rec, 50.0, 7.5)
    assert top == pytest.approx((10e3 - 350.0 - margin, 10e3), abs=1.0)
    assert bottom == pytest.approx((-10e3, -10e3 + 250.0 + margin), abs=1.0)
    (only,) = wrapped_band(rec, 800.0, 7.5)  # f_D from 500 to 1100 Hz: the top edge only
    assert only == pytest.approx((10e3 - 1100.0 - margin, 10e3), abs=1.0)
