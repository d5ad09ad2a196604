"""Focus quality of :func:`clsas.focus_moving` on a point target (Kiang & Kiang 2022 Table II):
the azimuth response on the r-y plane against the resolution cell 0.886 |V_h| / (|K| T_a).

What this guards (measured on main before the fix, case 6, one point): compressing with the
SoWVD's K~ (the aperture's average rate) and the model's higher-order terms on top counts the
quartic twice; over 25.6 s receiver A's azimuth response was 45 ms wide at -0.7 dB PSLR against
the 4.6 ms cell, over Table I's 80 s 400-600 ms at 0 dB at A, B and C (20 ms with K~ alone).
The model's own Taylor K with its higher-order terms (and the sharpness search for what the
velocity error leaves, :mod:`clsas.estimate.moving.sharpen`) gives the cell. And a schedule
that does not start at -T_a / 2 (the chain expands about the middle of the record, as the
closed forms do).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from clsas import metrics
from clsas.estimate.moving import sharpen
from clsas.estimate.moving.closedforms import closed_forms
from clsas.scene import presets
from clsas.scene.scenario import PulseSchedule
from clsas.scene.targets import PointTargets

CENTRE = np.array([1989.0, 0.0, -350.0])


def _focused(case: int, n_pulses: int, prf: float, method: str = "paper"):
    import clsas

    v = np.array(presets.KIANG_CASES[case])
    sc = presets.kiang2022(n_pulses=n_pulses).replace(schedule=PulseSchedule(prf=prf, n_pulses=n_pulses),
                                                      targets=(PointTargets(CENTRE, velocity=v),))
    # one delay per pulse (intra_pulse="none"): the paper's chain, held here to its resolution
    # cell, models no range-Doppler coupling
    echo = clsas.simulate(sc, backend="opencl", progress=False, intra_pulse="none")
    est = clsas.estimate_motion(echo, position=CENTRE)
    return sc, v, est, clsas.focus_moving(echo, est, tau_span=0.004, method=method)


def _quality(sc, v, images) -> dict:
    """{name: (azimuth IRW / resolution cell, PSLR dB, |y peak - y true| / cell)}."""
    truth = closed_forms(sc, CENTRE, v)
    aperture = sc.schedule.n_pulses / sc.schedule.prf
    out = {}
    for name, image in images.items():
        cell = 0.886 * abs(image.provenance["along_track_speed"]) / (abs(truth[name].fm_rate) * aperture)
        y = metrics.analyse_point(image)["y"]
        out[name] = (y.irw / cell, y.pslr_db, abs(y.location - CENTRE[1]) / cell)
    return out


@pytest.fixture(scope="module")
def case6(opencl_device):
    """Table II case 6 (v = (3, -5, 3) m/s, the largest higher-order terms), 512 pulses at 20 Hz:
    25.6 s, aliased like Table I, where the double-counted quartic already shows."""
    sc, v, est, images = _focused(6, 512, 20.0)
    return sc, v, images


def test_point_focuses_to_its_resolution_cell_over_25_s(case6):
    """Measured: IRW / cell 1.000 at A, B, C, PSLR -13.26 to -13.28 dB (the unweighted sinc's
    -13.26), the peak 0.013-0.034 cells from the true y, residual phase found 0.017 cycles at
    most. Main before the fix: IRW / cell 9.7, 1.30, 1.09 at A, B, C (A at -0.7 dB); the
    quadratic focus with K~ alone 3.0-3.4 at -2.0 to -2.6 dB."""
    sc, v, images = case6
    quality = _quality(sc, v, images)
    assert set(quality) == {"A", "B", "C"}
    for name, (width, pslr, offset) in quality.items():
        assert width == pytest.approx(1.0, abs=0.01), (name, quality)
        assert -13.5 < pslr < -13.0, (name, quality)
        assert offset < 0.3, (name, quality)
    p = [image.provenance["residual_phase_cycles"] for image in images.values()]
    assert np.max(np.abs(p)) < 0.2  # the velocity error (0.004 %) leaves almost nothing over 25.6 s


@pytest.mark.slow
@pytest.mark.parametrize("case", [6, 8])
def test_point_focuses_to_its_resolution_cell_over_80_s(opencl_device, case):
    """Table I's 6400 pulses at 80 Hz (~3 GB, minutes). Measured at A, B, C: IRW / cell 1.00,
    PSLR -13.2 to -13.3 dB in both cases (velocity errors 0.097 % and 0.0016 %: the sharpness
    search removed 0.35-0.75 cycles of quadratic phase in case 6). Before the fix: case 6
    250-410 cells at 0 dB, case 8 2.1-5.1 cells at -11.7 dB; the quadratic focus with K~
    alone 10-13 and 4.5-5.9 cells at -2.9 to -4.5 dB."""
    sc, v, est, images = _focused(case, 6400, 80.0)
    quality = _quality(sc, v, images)
    for name, (width, pslr, offset) in quality.items():
        assert width == pytest.approx(1.0, abs=0.05), (name, quality)
        assert -13.6 < pslr < -12.9, (name, quality)


def test_residual_phase_is_found_by_sharpness(rng):
    """A point's aligned record with a known residual phase (cycles at the aperture's ends) and a
    linear term (which moves the image and is left alone), noise at 0 dB per pulse in the peak
    bin: the phase left after the correction (beyond its linear part) is within 0.05 cycles
    (measured 0.015; 4e-5 without the noise, where the grids alone, before the joint search, left 0.7)."""
    n, prf, k = 1024, 20.0, 2.0
    eta = (np.arange(n) - 0.5 * (n - 1)) / prf
    true = np.array([3.7, -1.2, 0.6])
    phase = sharpen.polynomial_phase(eta, 0.0, true) + 0.8 * eta  # cycles
    column = np.exp(-1j * np.pi * k * eta**2 - 2j * np.pi * phase)
    noise = (rng.standard_normal((n, 5)) + 1j * rng.standard_normal((n, 5))) / np.sqrt(2)
    aligned = (noise + np.outer(column, [0.1, 0.5, 1.0, 0.5, 0.1])).astype(np.complex64)
    found = sharpen.residual_phase(aligned, eta, k, 0.0, higher_order_cycles=20.0)
    left = sharpen.polynomial_phase(eta, 0.0, true - found)
    left -= np.polyval(np.polyfit(eta, left, 1), eta)
    assert np.max(np.abs(left)) < 0.05, found
    assert abs(found[1] - true[1]) < 0.05  # the odd term alone, exactly
    assert sharpen.fm_rate_correction(eta, 1.0) == pytest.approx(2.0 / (0.5 * np.ptp(eta)) ** 2)


def test_schedule_off_eta_0_estimates_and_places_the_point(opencl_device):
    """Pulses over 0..12.75 s (PulseSchedule start=0, eta_ref = 6.4 s): the chain expands about the
    middle of the record, as the closed forms do, so the velocity and the point's (r, y) come out
    as on a centred schedule (measured: 0.012 %; y within 0.03 cells, r within 0.005; the centroids
    solved with 0.002 Hz from the closed forms at eta_ref). Expanded about eta = 0, the chain's
    centroids were K eta_ref (~30 Hz) off and the velocity tens of % off."""
    import clsas

    v = np.array(presets.KIANG_CASES[1])
    n, prf = 256, 20.0
    sc = presets.kiang2022(n_pulses=n).replace(schedule=PulseSchedule(prf=prf, n_pulses=n, start=0.0),
                                               targets=(PointTargets(CENTRE, velocity=v),))
    echo = clsas.simulate(sc, backend="opencl", progress=False)
    est = clsas.estimate_motion(echo, position=CENTRE)
    assert est.layout.eta_ref == pytest.approx(0.5 * (n - 1) / prf)
    assert np.linalg.norm(est.velocity - v) / np.linalg.norm(v) < 1e-3, est.velocity
    truth = closed_forms(sc, CENTRE, v)
    q = CENTRE + v * est.layout.eta_ref
    r_true = np.linalg.norm(q - est.layout.tx_position)
    for name, image in clsas.focus_moving(echo, est, tau_span=0.004).items():
        cell_eta = 0.886 / (abs(truth[name].fm_rate) * n / prf)
        cell_y = abs(image.provenance["along_track_speed"]) * cell_eta
        point = metrics.analyse_point(image)
        assert abs(point["y"].location - q[1]) < 0.3 * cell_y, name
        assert abs(point["r"].location - r_true) < 0.05 * 1500.0 / (2 * 20e3), name
        # the centroids solved with are the closed forms' at eta_ref (f~ - K~ (eta_c - eta_ref))
        assert est.centroids[name] == pytest.approx(truth[name].doppler_centroid, abs=0.02), name


# --------------------------------------------------------------------------- every scatterer focused


def _displacement(image, reference) -> tuple:
    """(dy, dr) m: where ``image`` lies against ``reference`` (same axes), by the peak of the
    cross-correlation of their magnitudes (a velocity error moves the whole focused target)."""
    from scipy.signal import fftconvolve

    a, b = np.abs(image.data), np.abs(reference.data)
    corr = fftconvolve(a, b[::-1, ::-1], mode="full")
    k = np.unravel_index(int(np.argmax(corr)), corr.shape)
    step = [float(image.axes[d][1] - image.axes[d][0]) for d in image.dims]
    return tuple((k[i] - (b.shape[i] - 1)) * step[i] for i in range(2))


def _peak(image, y: float, r: float) -> float:
    """|peak| of the point response near (y, r), upsampled along both axes through it."""
    point = metrics.analyse_point(image, near=(y, r), radius=0.3)
    return max(abs(point["y"].peak), abs(point["r"].peak))


@pytest.fixture(scope="module")
def three_points(opencl_device):
    """Table II case 1, 2048 pulses (25.6 s): the reference point (the centre, given), one 5 m
    along the heading and one 1 m across it, equal amplitudes."""
    import clsas

    v = np.array(presets.KIANG_CASES[1])
    heading = np.array([v[0], v[1], 0.0]) / np.hypot(v[0], v[1])
    side = np.array([-heading[1], heading[0], 0.0])
    points = np.stack([CENTRE, CENTRE + 5.0 * heading, CENTRE + 1.0 * side])
    sc = presets.kiang2022(n_pulses=2048).replace(targets=(PointTargets(points, velocity=v),))
    echo = clsas.simulate(sc, backend="opencl", progress=False)
    return v, points, echo, clsas.estimate_motion(echo, position=CENTRE)


def test_every_point_of_a_target_is_focused_as_with_the_true_velocity(three_points):
    """Issue 26 item 2: back-projection in the target's frame with the estimated velocity focuses
    the points 5 m along and 1 m across from the reference within 1 dB of the same points
    focused with the true velocity (measured -0.06 to +0.20 dB at A, B and C). The estimated
    velocity's error moves the whole image (measured ~2.4 m along the track: v_z is the least
    determined component), so each point is compared where the image of the target lies."""
    import clsas

    v, points, echo, est = three_points
    assert np.linalg.norm(est.velocity - v) / np.linalg.norm(v) < 0.03
    kw = dict(half_size=(1.5, 9.0), spacing=0.02)
    estimated = clsas.focus_moving(echo, est, **kw)
    true = clsas.focus_moving(echo, dataclasses.replace(est, velocity=v), **kw)
    assert set(estimated) == set(true) == {"A", "B", "C"}
    tx = est.layout.tx_position
    for name in "ABC":
        dy, dr = _displacement(estimated[name], true[name])
        assert abs(dy) < 4.0 and abs(dr) < 0.5, (name, dy, dr)
        for p in points:
            r = float(np.linalg.norm(p - tx))
            loss = 20 * np.log10(_peak(estimated[name], p[1] + dy, r + dr) / _peak(true[name], p[1], r))
            assert abs(loss) < 1.0, (name, p, loss)


def _bright_extent(image, axis) -> float:
    """m: the span along ``axis`` (unit (dr, dy) on the image plane) that holds the middle
    :data:`ENERGY_SPAN` of the image's energy (a level-free measure: one glint a decibel brighter
    or dimmer does not move it as it moves a threshold's crossing)."""
    power = np.abs(image.data).astype(np.float64) ** 2
    y, r = np.meshgrid(image.axes["y"], image.axes["r"], indexing="ij")
    s = (r * axis[0] + y * axis[1]).ravel()
    order = np.argsort(s)
    cumulative = np.cumsum(power.ravel()[order])
    tail = 0.5 * (1 - ENERGY_SPAN) * cumulative[-1]
    lo, hi = np.searchsorted(cumulative, [tail, cumulative[-1] - tail])
    return float(s[order][min(hi, s.size - 1)] - s[order][lo])


#: The share of a focused hull's energy whose span along the hull is its bright extent.
ENERGY_SPAN = 0.98


def _reflecting_extent(scenario, layout, axis, pulses: int = 33) -> dict:
    """{receiver: m}: the span along ``axis`` (as :func:`_bright_extent`) that holds the middle
    :data:`ENERGY_SPAN` of the energy the hull's facets send to each receiver over the exposure:
    each facet's (path weight x area)^2 summed over ``pulses`` pulses spread over it (the
    synthesis's own weights: lit, heard, angular law), placed where it is at the layout's
    eta_ref. What the image of a perfectly focused hull shows, less the resolution."""
    from clsas.synthesis.occlusion.weights import PathWeights

    eta = scenario.eta
    every = max(1, (eta.size - 1) // (pulses - 1))
    sparse = scenario.replace(schedule=PulseSchedule(prf=scenario.schedule.prf / every,
                                                     n_pulses=(eta.size - 1) // every + 1, start=float(eta[0])))
    weights = PathWeights(sparse)
    w = weights(slice(None))  # (n_rx, pulses, facets)
    (first, n, target, _, _), = weights.parts
    energy = ((w[:, :, first:first + n] * target.mesh.area_faces) ** 2).sum(axis=1)  # (n_rx, facets)
    centres = target.facets_world()[0] + target.velocity * layout.eta_ref
    s = np.linalg.norm(centres - layout.tx_position, axis=1) * axis[0] + centres[:, 1] * axis[1]
    order = np.argsort(s)
    out = {}
    for h, name in enumerate(scenario.receiver_names):
        cumulative = np.cumsum(energy[h][order])
        tail = 0.5 * (1 - ENERGY_SPAN) * cumulative[-1]
        lo, hi = np.searchsorted(cumulative, [tail, cumulative[-1] - tail])
        out[name] = float(s[order][min(hi, s.size - 1)] - s[order][lo])
    return out


@pytest.mark.parametrize("case", [1, 5, 6])
def test_the_hull_is_focused_over_its_length(opencl_device, case):
    """Issue 26 item 2 on the scaled Albacore (10.35 m; Table II cases 1, 5, 6, 1024 pulses, a
    coarse mesh): focused with the estimated velocity, the hull's bright extent along its axis
    (projected on the r-y plane) is within 10 % of the same hull focused with the true velocity
    (measured within 6 %, case 5 at B) and no longer than the hull (no smear beyond it). The
    bright extent is shorter than the hull (measured 0.75-0.97 of it; at a -20 dB level 0.66-0.90):
    its tapered bow and stern send little back towards the receivers (a finer mesh shortens it
    further), so the hull's length is an upper bound here, not a target. Why, measured on the
    synthesis's own facet weights (:func:`_reflecting_extent`): the facets send the middle 98 %
    of their energy to every receiver from 0.72-0.73 of the hull's length (cases 1, 5, 6), and the
    image's bright extent is that reflecting extent plus the blur of the resolution and of the
    sidelobes (1.04-1.12x it in case 1, 1.06-1.12x in case 5, 1.27-1.34x in case 6)."""
    import clsas

    sc = presets.kiang2022_case(case, n_pulses=1024, sections=32, stations=40)
    v = np.asarray(sc.targets[0].velocity)
    echo = clsas.simulate(sc, backend="opencl", progress=False)
    est = clsas.estimate_motion(echo, position=CENTRE)
    assert np.linalg.norm(est.velocity - v) / np.linalg.norm(v) < 0.03
    kw = dict(half_size=(9.0, 9.0), spacing=0.05)
    estimated = clsas.focus_moving(echo, est, **kw)
    true = clsas.focus_moving(echo, dataclasses.replace(est, velocity=v), **kw)
    heading = v / np.linalg.norm(v)
    los = (CENTRE - est.layout.tx_position) / np.linalg.norm(CENTRE - est.layout.tx_position)
    axis = np.array([heading @ los, heading[1]])  # m of r and y per m along the hull
    length = float(sc.targets[0].mesh.extents[0]) * float(np.linalg.norm(axis))  # body frame: x_b along the hull
    axis /= np.linalg.norm(axis)
    reflecting = _reflecting_extent(sc, est.layout, axis)
    for name in "ABC":
        got, best = _bright_extent(estimated[name], axis), _bright_extent(true[name], axis)
        assert got == pytest.approx(best, rel=0.1), (name, got, best)
        assert 0.6 * length < got < 1.1 * length, (name, got, length)
        assert reflecting[name] < 0.8 * length, (name, reflecting[name], length)  # the taper: what reflects
        assert 0.95 * reflecting[name] < got, (name, got, reflecting[name])  # nothing that reflects is lost


@pytest.mark.slow  # ~20 s of CPU (run once: passed, 106 s wall at load 11)
def test_a_fast_targets_image_holds_no_wrapped_band_ghost(opencl_device, monkeypatch):
    """With intra-pulse Doppler at F_r = B the echo's band edge wraps round the sampling rate
    (:func:`clsas.estimate.moving.records.wrapped_band`): unless zeroed, it focuses as a ghost
    c T / 2 = 3.75 m nearer in range and metres away along the track. A point at 6.3 m/s
    (v = (6, 2, 0), f_dc ~ 1200 Hz at A, 1024 pulses): with the band kept, receiver A's image
    holds the ghost at dr -3.75 m, dy -11.6 m, -27.2 dB re the peak; focus_moving (band zeroed)
    leaves -38.2 dB there (measured)."""
    import sys

    import clsas

    sc = presets.kiang2022(n_pulses=1024).replace(targets=(PointTargets(CENTRE, velocity=(6.0, 2.0, 0.0)),))
    echo = clsas.simulate(sc, backend="opencl", progress=False)
    est = clsas.estimate_motion(echo, position=CENTRE)
    kw = dict(half_size=(5.0, 14.0), spacing=0.05)
    zeroed = clsas.focus_moving(echo, est, **kw)["A"]
    focus_module = sys.modules["clsas.estimate.moving.focus"]
    monkeypatch.setattr(focus_module, "without_wrapped_band", lambda rec, f_dc, k: rec)
    kept = clsas.focus_moving(echo, est, **kw)["A"]
    power_z, power_k = np.abs(zeroed.data) ** 2, np.abs(kept.data) ** 2
    r, y = kept.axes["r"], kept.axes["y"]
    iy, ir = np.unravel_index(np.argmax(power_k), power_k.shape)
    dr, dy = r[None, :] - r[ir], y[:, None] - y[iy]
    ring = (np.abs(dr + 3.75) < 0.3) & (np.abs(dy) > 3.0)  # the ghost's range, away from the leakage copy
    gy, gr = np.unravel_index(np.argmax(np.where(ring, power_k, 0.0)), power_k.shape)
    ghost_kept = 10 * np.log10(power_k[gy, gr] / power_k.max())
    ghost_zeroed = 10 * np.log10(power_z[gy, gr] / power_z.max())
    assert ghost_kept > -32.0, ghost_kept  # the ghost is there without the zeroing
    assert ghost_zeroed < ghost_kept - 8.0 and ghost_zeroed < -35.0, (ghost_kept, ghost_zeroed)
