"""The moving-target chain in noise (Kiang & Kiang 2022 section VII-C, Figs. 20-22) and the SNR.

The paper does not say over which samples its SNR's signal power is taken; clsas offers both
readings (:func:`clsas.synthesis.echo.noise.add_noise`, which derives them): "echo" (the
mean power over the samples the echo occupies, ``simulate(snr_db=)``) and "record" (over every
recorded sample). They differ by the echo's duty in the record, exactly; the tests below check
that, and the processing gains the derivation predicts, on simulated echoes.

The chain (case 1's point target, the Table I sonar, 1024 pulses at 80 Hz; the paper uses 6400),
"echo" reading, measured: -13 dB 0.03-0.15 %, -15 dB 0.04-0.28 %, -16 dB 0.08-0.48 % (seeds
1-5); -17 dB 0.13-0.34 %, -18 dB 0.10-0.27 % or (seed 1) an EstimationError naming receiver B
(seeds 1-3); -20 and -22 dB: EstimationError, the echo stands out of the noise in 10-21 % of A's
pulses (the paper halts at -20 dB). Confidence 1.00 and |sigma| 0.013-0.016 m/s (0.3-0.4 %)
wherever it estimates. At -17 dB the SoWVD scores below its threshold on some receivers (23-28
dB on the right K, its noise candidates 16-20 dB) and the rate is confirmed by the focus
(:data:`clsas.estimate.moving.chain.FOCUS_DB`: the point focused on 1024 pulses stands ~33 dB
over the image's median, focused noise ~13 dB).

The hull (the scaled Albacore, 2048 pulses, "echo" reading, seeds 1-2, load 6-11): before the
followed trace (:mod:`clsas.estimate.moving.track`) cases 5 and 6 raised EstimationError at -15
and -17 dB: receiver A's cell gate (:func:`clsas.estimate.moving.trace.support`) caught the
walking trace (0.8-1.7 upsampled samples a pulse, the echo over 2-4 m of range) in a few cells
of two thirds of the pulses, its band missed the trace and the SoWVD scored 15-16 dB (the
noise's). On case 5 at A, -15 dB, the true trace +-20 samples scores 31 dB, +-60 samples 17.5
dB; the bright cells of the followed trace 31-38 dB (-17 dB: 25.6 dB, K within 0.4 %). The
Radon line of the floor-subtracted magnitude there read f_dc 0.5 Hz against 270 (a line of slope
0 from the cells' uneven means); on the power less each cell's mean, 270.9 Hz.
"""

from __future__ import annotations

import numpy as np
import pytest

import clsas
from clsas import PointTargets
from clsas.errors import EstimationError
from clsas.estimate.moving import track
from clsas.estimate.moving.extent import extent
from clsas.scene import presets
from clsas.synthesis.echo.noise import add_noise, signal_power, snr_offset_db

CENTRE = (1989.0, 0.0, -350.0)
CASE1 = presets.KIANG_CASES[1]


def point_scene(n_pulses: int):
    return presets.kiang2022(n_pulses=n_pulses).replace(targets=(PointTargets(CENTRE, velocity=CASE1),))


@pytest.fixture(scope="module")
def short_echo():
    """64 pulses of case 1's point target, noise-free."""
    return clsas.simulate(point_scene(64), backend="numpy", progress=False)


@pytest.fixture(scope="module")
def chain_echo():
    """1024 pulses of case 1's point target, noise-free (the chain's scene)."""
    return clsas.simulate(point_scene(1024), backend="numpy", progress=False)


def noisy(echo, snr_db, seed, reference="echo"):
    data = add_noise(echo.data.copy(), snr_db, seed, echo.provenance["n_valid"], reference=reference)
    return echo.replace(data=data)


@pytest.mark.parametrize("reference", ["echo", "record"])
def test_noise_variance_follows_the_reading(short_echo, reference):
    """sigma^2 = P / 10^(SNR / 10) with P the mean |s|^2 over the echo's samples ("echo") or over
    every recorded sample ("record")."""
    n_valid = np.array(short_echo.provenance["n_valid"])
    sums, counts = signal_power(short_echo.data, n_valid)
    noise = noisy(short_echo, -10.0, 7, reference).data - short_echo.data
    for h in range(len(short_echo.receivers)):
        recorded = noise[h, :, :n_valid[h]]
        samples = counts[h].sum() if reference == "echo" else recorded.size
        expected = sums[h].sum() / samples / 10 ** (-10.0 / 10)
        assert np.mean(np.abs(recorded) ** 2) == pytest.approx(expected, rel=0.02)  # ~40 k samples: 0.5 % noise
        assert not np.any(noise[h, :, n_valid[h]:])


def test_readings_differ_by_the_duty(short_echo):
    """SNR_record = SNR_echo + 10 log10(n_echo / n_rec): the same noise, to float32 rounding."""
    offset = snr_offset_db(short_echo.data, short_echo.provenance["n_valid"])
    n_valid = np.array(short_echo.provenance["n_valid"])
    _, counts = signal_power(short_echo.data, n_valid)
    assert np.allclose(offset, 10 * np.log10(counts.sum(axis=1) / (n_valid * short_echo.n_pulses)))
    assert np.all(offset < -0.05)  # the window holds the migration: wider than the pulse
    for h in range(len(short_echo.receivers)):
        as_echo = noisy(short_echo, -10.0, 3, "echo").data[h]
        as_record = noisy(short_echo, -10.0 + float(offset[h]), 3, "record").data[h]
        assert np.allclose(as_echo, as_record, rtol=0, atol=1e-5 * np.abs(as_echo).max())


def test_range_compression_gain_is_n_snr_echo(chain_echo):
    """A point echo of N = T fs samples compresses to a peak N^2 P_echo over noise N sigma^2:
    the compressed SNR is N SNR_echo (20 dB above it on Table I, N = 100), less the ~0.3 dB the
    critically sampled chirp (F_r = B) loses at the peak."""
    short_echo = chain_echo
    snr_db = -15.0
    clean = clsas.range_compress(short_echo, upsample=8)  # the peak sampled within 1/16 of a sample
    noise = clsas.range_compress(noisy(short_echo, snr_db, 5), upsample=8).data - clean.data
    n = short_echo.waveform.duration * short_echo.fs
    pulses = np.arange(short_echo.n_pulses)
    for h in range(len(short_echo.receivers)):
        at = np.argmax(np.abs(clean.data[h]), axis=1)  # per pulse: where the filter meets the echo
        peak = np.abs(clean.data[h, pulses, at]) ** 2
        gain_db = 10 * np.log10(np.mean(peak) / np.mean(np.abs(noise[h, pulses, at]) ** 2)) - snr_db
        assert gain_db == pytest.approx(10 * np.log10(n) - 0.3, abs=0.5)  # 1024 noise samples: +-0.14 dB

def test_extent_ignores_the_noise_floor():
    """A point's extent in a focused image 30 dB over its noise floor: the same middle and about
    the same size as without noise (the level is the floor's plus 20 dB below the peak, not 20
    dB below the peak alone, which noise fills once the smoothed image is < ~20 dB over it)."""
    rng = np.random.default_rng(1)
    eta, tau = np.arange(1024) * 0.016, np.arange(400) * 25e-6
    cell_eta, cell_tau = 0.016, 50e-6
    spot = (np.sinc((eta[:, None] - 8.0) / cell_eta) * np.sinc((tau[None, :] - 5e-3) / cell_tau)).astype(np.complex64)
    clean = extent(spot, eta, tau, cell_eta, cell_tau)
    sigma = 10 ** (-30 / 20)
    image = spot + sigma * (rng.standard_normal(spot.shape) + 1j * rng.standard_normal(spot.shape)) / np.sqrt(2)
    ext = extent(image, eta, tau, cell_eta, cell_tau)
    assert abs(ext.eta_mid - 8.0) < 0.5 * cell_eta and abs(ext.tau_mid - 5e-3) < 0.25 * cell_tau
    assert (ext.eta[1] - ext.eta[0]) < 1.5 * (clean.eta[1] - clean.eta[0])
    assert (ext.tau[1] - ext.tau[0]) < 1.5 * (clean.tau[1] - clean.tau[0])


def velocity_error(echo):
    est = clsas.estimate_motion(echo, position=CENTRE)
    v = np.array(CASE1)
    return est, float(np.linalg.norm(est.velocity - v) / np.linalg.norm(v))


def test_chain_at_minus_15_db(chain_echo):
    """"echo" SNR -15 dB (the stricter reading of the paper's -15 dB, where it reports 1.956 %):
    measured 0.04-0.28 % over seeds 1-5 (this seed: 0.15 %), confidence 1.00."""
    est, err = velocity_error(noisy(chain_echo, -15.0, 2))
    assert err < 0.01  # ~10x the seeds' largest (0.28 %); the paper's 3 % is the reproduction's verdict
    assert est.confidence > 0.9
    assert err * np.linalg.norm(CASE1) < 3 * np.linalg.norm(est.sigma)  # honest sigma


def test_chain_at_the_papers_floor_record_reading(chain_echo):
    """"record" SNR -17 dB (the paper's floor read over the whole record: on this 12.8 s scene an
    "echo" SNR 0.8, 3.8 and 0.5 dB higher at A, B and C): an estimate within the paper's 3 %."""
    offset = snr_offset_db(chain_echo.data, chain_echo.provenance["n_valid"])
    assert np.allclose(offset, (-0.83, -3.77, -0.53), atol=0.05)
    est, err = velocity_error(noisy(chain_echo, -17.0, 1, "record"))
    assert err < 0.01 and est.confidence > 0.9


def test_chain_at_the_papers_floor_echo_reading(chain_echo):
    """"echo" SNR -17 dB on 1024 pulses: measured 0.13-0.34 % (seeds 1-3; this one 0.13 %)."""
    est, err = velocity_error(noisy(chain_echo, -17.0, 3))
    assert err < 0.01 and est.confidence > 0.9
    assert err * np.linalg.norm(CASE1) < 3 * np.linalg.norm(est.sigma)


def test_chain_below_its_floor_says_which_receiver_and_why(chain_echo):
    """"echo" SNR, seed 1. -18 dB was below the chain's floor (B's SoWVD 14.9 dB against 26, its
    best candidate's focus 14.2 dB over the median against 20); since the trace followed over
    the record holds B's walking echo it estimates there: measured 0.159 %, confidence 1.00.
    -19 dB: B's echo stands out of the noise in too few pulses and the SoWVD on its followed
    trace scores the noise's level (15.8 dB); -20 dB: A's echo stands out in too few pulses.
    (The "no SoWVD peak ... holds no target" refusal: test_moving_chain.py.)"""
    est = clsas.estimate_motion(noisy(chain_echo, -18.0, 1), position=CENTRE)
    err = float(np.linalg.norm(est.velocity - np.array(CASE1)) / np.linalg.norm(CASE1))
    assert err < 0.016 and est.confidence > 0.9, (err, est.confidence, est.problems)
    with pytest.raises(EstimationError, match=r"receiver B: the echo stands out of the noise in \d+ % of the pulses "
                                              r"< 25 %, and the SoWVD on its followed trace scores"):
        clsas.estimate_motion(noisy(chain_echo, -19.0, 1), position=CENTRE)
    with pytest.raises(EstimationError, match=r"receiver A: the echo stands out of the noise in \d+ % of the pulses"):
        clsas.estimate_motion(noisy(chain_echo, -20.0, 1), position=CENTRE)


def test_a_weak_candidate_is_confirmed_by_its_focus_not_its_brightness(chain_echo):
    """Review M6. Below the SoWVD threshold a rate is taken only when the record focused with it
    is sharper there than 3 focus steps off (located.sharpness): at "echo" SNR -17 dB (seed 3, the
    fallback's own case) the right K's peak stands well over the detuned ones; a K 5 % off
    (~25 focus steps) leaves an image that is as bright or brighter 3 steps towards the truth,
    which the peak over the median alone (also > FOCUS_DB there) did not tell."""
    import dataclasses

    from clsas.estimate.moving import chain, located
    from clsas.estimate.moving.records import records

    rec = records(noisy(chain_echo, -17.0, 3), "A")
    est = chain.estimate_records(rec)
    at, detuned = located.sharpness(rec, est)
    assert at - max(detuned) > 2 * chain.SHARP_DB, (at, detuned)
    wrong = located.locate(rec, dataclasses.replace(est, fm_rate=1.05 * est.fm_rate))
    at, detuned = located.sharpness(rec, wrong)
    assert at - max(detuned) < chain.SHARP_DB, (at, detuned)


def test_sharpness_holds_the_higher_order_terms(opencl_device):
    """Review M6 over 25.6 s (Table II case 6, a point, 2048 pulses, noise-free, receiver A): the
    delay's cubic and quartic terms blur the quadratic focus more than 3 focus steps of K do, so
    the quadratic-focus peak is the same at K and K -+ 3 steps (measured 85.6, 85.7, 85.6 dB;
    +-0.3 dB at B and C) and that check refused right candidates at -17 dB (issue 26, the lead's
    measurement: 30.7 against 30.6 dB). located.sharpness removes those terms (the sharpened window,
    its rate correction undone): measured 95.4 dB at K against 86.8 / 87.6 dB (A; B 8.3, C 8.2 dB
    margins), and a K 5 % off is still refused (73.1 against 73.4 / 72.8 dB)."""
    import dataclasses

    from clsas.estimate.moving import chain, located
    from clsas.estimate.moving.doppler import Doppler
    from clsas.estimate.moving.records import records

    scene = presets.kiang2022(n_pulses=2048).replace(
        targets=(PointTargets(CENTRE, velocity=presets.KIANG_CASES[6]),))
    rec = records(clsas.simulate(scene, backend="opencl", progress=False), "A")
    est = chain.estimate_records(rec)
    step = located.SHARP_STEPS * 4.0 / est.aperture**2
    quadratic = [located.locate(rec, est, reference=Doppler(fm_rate=est.fm_rate + s,
                                                          doppler_centroid=est.doppler_centroid)).extent.peak_db
                 for s in (0.0, -step, step)]
    assert np.ptp(quadratic) < 1.5, quadratic  # the cause: flat in K
    at, detuned = located.sharpness(rec, est)
    assert at - max(detuned) > 2 * chain.SHARP_DB, (at, detuned)
    at, detuned = located.sharpness(rec, located.locate(rec, dataclasses.replace(est, fm_rate=1.05 * est.fm_rate)))
    assert at - max(detuned) < chain.SHARP_DB, (at, detuned)


@pytest.mark.slow
@pytest.mark.parametrize("snr_db", [-13.0, -15.0, -16.0, -17.0])
def test_chain_over_seeds(chain_echo, snr_db):
    """Seeds 1-5 at each SNR ("echo" reading): error < 2 %, within 3 sigma, confident, or at -17
    dB an EstimationError naming the receiver."""
    for seed in range(1, 6):
        try:
            est, err = velocity_error(noisy(chain_echo, snr_db, seed))
        except EstimationError as error:
            assert snr_db <= -17.0 and str(error).startswith("receiver "), (seed, error)
            continue
        assert err < 0.02, (seed, err)
        assert est.confidence > 0.9, (seed, est.confidence)
        assert err * np.linalg.norm(CASE1) < 3 * np.linalg.norm(est.sigma), (seed, err, est.sigma)



@pytest.mark.slow
def test_points_at_the_papers_floor_at_other_velocities(opencl_device):
    """"echo" SNR -17 dB on a point at Table II case 6's velocity and (2, -6, 1) m/s, 2048 pulses,
    seeds 41-43 (neither the other tests' nor the verifier's 31-36); issue 26 item 3 asks < 3 %.
    These echoes walk ~1.7 upsampled samples a pulse at A: the RFRT's cell gate (trace.support,
    each range cell over 9 pulses) smears them, and the SoWVD needs the trace followed over the
    record (track.bright_gate: its blocks correlated with the other pulses' profile, from the
    middle 512 pulses when the whole record's line is too far off), the centroid its tangent, and
    below the SoWVD threshold the focus's rate taken again from each new rate. Measured on other
    seeds (31-36 of case 6 and of (2, -6, 1)): every one estimates, 0.015-0.073 % and
    0.044-0.132 %, confidence 1.00, |error| / sigma <= 0.71 (they were refused before).
    Asserted: every run estimates (no refusal) within max_error, confident, the error within 3
    sigma."""
    max_error = 0.008  # 6-10x the largest errors measured on these velocities (0.132 %, 0.073 %)
    for velocity in (presets.KIANG_CASES[6], (2.0, -6.0, 1.0)):
        v = np.array(velocity)
        echo = clsas.simulate(presets.kiang2022(n_pulses=2048).replace(targets=(PointTargets(CENTRE, velocity=v),)),
                              backend="opencl", progress=False)
        for seed in (41, 42, 43):
            est = clsas.estimate_motion(noisy(echo, -17.0, seed), position=CENTRE)
            err = float(np.linalg.norm(est.velocity - v) / np.linalg.norm(v))
            assert err < max_error and est.confidence > 0.9, (velocity, seed, err, est.confidence, est.problems)
            assert np.all(np.abs(est.velocity - v) <= 3 * est.sigma), (velocity, seed, est.velocity - v, est.sigma)


def fast_walker(seed: int = 7):
    """(whitened power map (2048, 3830) float32, the trace's sample at each pulse): exponential
    noise of mean 1 and a trace walking like Table II case 6's at A over 2048 pulses (1.708
    upsampled samples a pulse, quadratic term 165 (u / 1024)^2 samples, u the pulse from the
    middle: 2 x 165 / 1024^2 samples a pulse^2), 2.6x the noise's mean in two cells (the -17 dB
    echo)."""
    rng = np.random.default_rng(seed)
    n_pulses, n_samples = 2048, 3830
    u = np.arange(n_pulses) - 0.5 * (n_pulses - 1)
    truth = 1742.0 + 1.708 * u + 165.0 / 1024**2 * (u**2 - 1024**2 / 3.0)
    power = rng.exponential(1.0, (n_pulses, n_samples)).astype(np.float32)
    cells = np.round(truth).astype(int)
    for d in (0, 1):
        power[np.arange(n_pulses), cells + d] += 2.6
    return power, truth


@pytest.mark.parametrize("seed_pulses", [track.SEED, track.SHORT_SEED])
def test_the_followed_trace_holds_a_fast_walker(seed_pulses):
    """track.centre_line on a whitened map (exponential noise, mean 1) holding a point's trace
    that walks like Table II case 6's at A over 2048 pulses (1.71 upsampled samples a pulse,
    bending 110 samples off its straight line at the ends) and stands 2.6x the noise's mean over
    it in two cells (the -17 dB echo). Each block of the line used to be correlated with a
    profile holding its own noise, which peaked at lag 0 for every block: the line stayed near
    the first straight one, here 36 samples off the trace (median) and 180 at most. The line is
    followed up to a constant (the blocks' lags are relative to the profile); about that
    constant it holds the trace to 0.14 / 0.06 samples (median; seed SEED / SHORT_SEED), 0.6
    at most."""
    power, truth = fast_walker()
    centre, degree = track.centre_line(power, seed_pulses)
    assert degree == 2  # a parabola over 2048 pulses (from a line over SHORT_SEED's three blocks)
    off = centre - truth
    off -= np.median(off)
    assert np.max(np.abs(off)) < 6.0, np.max(np.abs(off))
    assert np.median(np.abs(off)) < 1.5, np.median(np.abs(off))


@pytest.mark.parametrize("seed_pulses", [track.SEED, track.SHORT_SEED])
def test_the_followed_traces_curvature_is_the_delays_second_derivative(seed_pulses):
    """track.bright_gate's curvature on the fast walker above (the same map, its |x| = sqrt of the
    power): the trace's second derivative, 2 x 165 / 1024^2 samples a pulse^2, measured within
    0.14 % / 0.33 % (seed SEED / SHORT_SEED; over map seeds 7-9: 0.01-2.4 % / 0.23-0.33 %), and
    track.trace_rate turns it into K = f0 prf^2 / fs d^2k/dn^2 (Kiang & Kiang 2022 eqs. 1-2,
    15-16: d^2 tau / d eta^2 = K_a,eq / f0)."""
    power, _ = fast_walker()
    followed = track.bright_gate(np.sqrt(power), 1, seed_pulses)
    assert followed.curvature == pytest.approx(2 * 165.0 / 1024**2, rel=0.03)
    # Table I: f0 150 kHz, 80 Hz PRF, 40 kHz upsampled: 24 Hz/s a 1e-3 sample a pulse^2
    assert track.trace_rate(1e-3, 150e3, 80.0, 40e3) == pytest.approx(24.0)
    assert track.trace_rate(-1e-3, 150e3, 80.0, 40e3) == pytest.approx(-24.0)


def test_a_trace_followed_as_a_straight_line_gives_no_rate():
    """Review R3: the fast walker's first 768 pulses, fewer than the 7 blocks (1024 pulses) a
    parabola needs, so track.centre_line follows them with a line (degree 1). Its parabola's x^2
    coefficient was rounding (~1e-16 samples a pulse^2), a K ~ 1e-13 Hz/s that the chain tried
    and named in its refusal; now the curvature is nan and the followed search carries no rate
    (its SoWVD still runs on the followed trace's cells)."""
    from clsas.estimate.moving import gated
    from clsas.estimate.moving.records import Records

    power = fast_walker()[0][:768]
    _, degree = track.centre_line(power)
    assert degree == 1
    followed = track.bright_gate(np.sqrt(power), 1)
    assert followed is not None and np.isnan(followed.curvature) and followed.gate.any()
    rec = Records(x=np.sqrt(power).astype(np.complex64), eta=np.arange(768) / 80.0, t0=0.0, fs=40e3, f0=150e3,
                  bandwidth=20e3, name="A")
    search = gated._followed_search(rec, 0.1, track.SEED)
    assert search is not None and search.trace_rates == () and search.trace_line is not None


@pytest.mark.parametrize("name", ["A", "B", "C"])
def test_the_followed_traces_rate_on_a_simulated_point(chain_echo, name):
    """Review R4, the derivation end to end (sign, the upsampled fs): case 1's point, 1024
    pulses, "echo" SNR 0 dB (noise seed 1). track.trace_rate of the followed trace's curvature
    against the aperture's average K (closedforms.aperture_fm_rate): measured +3.9 / +1.6 / -2.2 %
    at A / B / C (the reviewer's figures, reproduced), held within TRACE_AGREES (10 %), within
    which the chain takes it as agreeing with a confirmed K (the brief's 10x margin does not fit
    under TRACE_AGREES: 2.6-6x here)."""
    from clsas.estimate.moving import chain, closedforms
    from clsas.estimate.moving.layout import layout_of
    from clsas.estimate.moving.records import UPSAMPLE, records

    echo = noisy(chain_echo, 0.0, 1)
    rec = records(echo, name)
    followed = track.bright_gate(rec.x, UPSAMPLE, track.SEED)
    k = track.trace_rate(followed.curvature, rec.f0, rec.prf, rec.fs)
    truth = closedforms.aperture_fm_rate(layout_of(echo), name, CENTRE, CASE1, rec.eta)
    assert k == pytest.approx(truth, rel=chain.TRACE_AGREES), (k, truth)


def test_simulate_takes_either_reading():
    """``simulate(snr_reference=)``: with the same seed the "record" reading's noise is the "echo"
    reading's scaled by 10^(offset / 20) per receiver, offset = :func:`snr_offset_db` of the
    noise-free echo (the same draws; float32 rounding), and the provenance says which."""
    scene = point_scene(64)
    clean = clsas.simulate(scene, backend="numpy", progress=False)
    offset = clsas.snr_offset_db(clean)
    as_echo = clsas.simulate(scene, backend="numpy", progress=False, snr_db=-10.0, seed=4)
    as_record = clsas.simulate(scene, backend="numpy", progress=False, snr_db=-10.0, seed=4, snr_reference="record")
    assert as_echo.provenance["snr_reference"] == "echo" and as_record.provenance["snr_reference"] == "record"
    for h in range(len(clean.receivers)):
        n_echo, n_record = as_echo.data[h] - clean.data[h], as_record.data[h] - clean.data[h]
        scale = 10 ** (offset[h] / 20)
        assert np.allclose(n_record, scale * n_echo, rtol=0, atol=1e-4 * np.abs(n_echo).max())
    assert np.allclose(offset, snr_offset_db(clean.data, clean.provenance["n_valid"]))


def hull_echo(case: int, n_pulses: int = 2048):
    """The scaled hull of Table II ``case`` (default mesh, hull occlusion), noise-free."""
    return clsas.simulate(presets.kiang2022_case(case, n_pulses=n_pulses), backend="opencl", progress=False)


@pytest.mark.slow
@pytest.mark.parametrize("case", [1, 5, 6])
def test_hull_at_the_papers_noise(opencl_device, case):
    """Issue 26 item 3 on the hull: the scaled Albacore of Table II cases 1, 5 and 6 (2048 pulses,
    25.6 s) at "echo" SNR -15 and -17 dB (the stricter reading: the mean power over the samples
    the hull's echo occupies; the "record" reading of the same numbers is 1.6-9.7 dB easier on
    these scenes), seed 1: an estimate within the paper's 3 % (asserted below 2 %), confident, its
    error within 3 sigma. Measured (load 6-11; |sigma| / |v| in brackets, confidence 0.98-1.00):
    case 1 -15 dB 0.39 / 0.34 % (seeds 1 / 2), -17 dB 0.41 / 0.33 % (1.3 %); case 5 -15 dB 0.13 %,
    -17 dB 0.13 % (seed 1; 0.33 %); case 6 -15 dB 0.30 / 0.23 %, -17 dB 0.36 / 0.23 % (1.0 %).
    Noise-free the same echoes give 0.39, 0.12 and 0.24 %: the hull's own bias (its middle is
    not its centre), not the noise, sets the error."""
    echo = hull_echo(case)
    v = np.array(presets.KIANG_CASES[case])
    for snr_db in (-15.0, -17.0):
        est = clsas.estimate_motion(noisy(echo, snr_db, 1), position=CENTRE)
        err = float(np.linalg.norm(est.velocity - v))
        assert err / np.linalg.norm(v) < 0.02, (case, snr_db, est.velocity)
        assert est.confidence > 0.9, (case, snr_db, est.confidence, est.problems)
        assert err < 3 * np.linalg.norm(est.sigma), (case, snr_db, err, est.sigma)


@pytest.mark.slow
@pytest.mark.parametrize("case", [1, 5, 6])
def test_hull_at_the_papers_noise_over_6400_pulses(opencl_device, case):
    """The paper's aperture: 6400 pulses (80 s), the hull of Table II ``case``, "echo" SNR -15 and
    -17 dB, seed 1. Receiver A of case 1 raised EstimationError at -15 dB: the trace bends ~1000
    upsampled samples over the record and the followed trace started from one straight line over
    all of it (clsas.estimate.moving.track, now grown from the middle 2048 pulses). Measured
    (load 2-9, position given, each run once by script, not yet through this test): case 1
    -15 dB 0.61 % (|sigma| / |v| 1.4 %, confidence 0.96); case 1 -17 dB was an EstimationError
    naming receiver A (SoWVD 16.3 dB, its best candidate K = -54.6 Hz/s does not focus); session 9
    (a617938, by script, load 2-9): 0.52 %, confidence 0.97, A's SoWVD on the followed trace's
    bright cells 41.5 dB (its cell gate 16.3 dB); case 5 -15 dB 0.16 % (0.41 %, confidence 1.00); case 6 -15 dB 3.1 %, flagged (confidence 0.02: receiver C's Radon slope at its
    search's edge). Case 6 at -17 dB (session 8, by script, load 5-7): 0.17 %, confidence 0.98
    (|sigma| / |v| 1.2 %); on da5b311 it raised delay_history's ValueError (a joint velocity of
    102.7 m/s: receiver A's centroid from a Radon line 173 ms off its followed trace), now
    refused by name should it recur (test_moving_confidence.py::
    test_an_unphysical_speed_is_refused_naming_the_receiver). Asserted: case 1 at -15 dB within 2 %, confident, within 3 sigma; every other
    run within 2 % and confident, or flagged (confidence < 0.5 with a problem naming a
    receiver), or an EstimationError naming the receiver."""
    echo = hull_echo(case, 6400)
    v = np.array(presets.KIANG_CASES[case])
    for snr_db in (-15.0, -17.0):
        try:
            est = clsas.estimate_motion(noisy(echo, snr_db, 1), position=CENTRE)
        except EstimationError as error:
            assert (case, snr_db) != (1, -15.0) and str(error).startswith("receiver "), (case, snr_db, error)
            continue
        err = float(np.linalg.norm(est.velocity - v) / np.linalg.norm(v))
        if (case, snr_db) == (1, -15.0) or est.confidence >= 0.5:
            assert err < 0.02 and est.confidence > 0.5, (case, snr_db, err, est.confidence, est.problems)
            assert err * np.linalg.norm(v) < 3 * np.linalg.norm(est.sigma), (case, snr_db, err, est.sigma)
        else:
            assert any(p.startswith("receiver ") for p in est.problems), (case, snr_db, est.problems)
