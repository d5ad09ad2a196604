"""Two moving targets end to end (issue 26 item 4; Kiang & Kiang 2022 section VII-B): the first
moving as in Table II case 1, the second as in case 3, at the same depth and 50 m apart; each
receiver's targets found one by one and associated across A, B and C
(:func:`clsas.estimate_motions`)."""

from __future__ import annotations

import numpy as np
import pytest

import clsas
from clsas.scene import presets
from clsas.scene.targets import PointTargets

CENTRE = np.array([1989.0, 0.0, -350.0])
SECOND = CENTRE + np.array([0.0, 50.0, 0.0])
V1, V3 = np.array(presets.KIANG_CASES[1]), np.array(presets.KIANG_CASES[3])


@pytest.fixture(scope="module")
def two_points(opencl_device):
    sc = presets.kiang2022(n_pulses=1024).replace(
        targets=(PointTargets(CENTRE, velocity=V1), PointTargets(SECOND, velocity=V3)))
    return clsas.simulate(sc, backend="opencl", progress=False)


def _error(est, v) -> float:
    return float(np.linalg.norm(est.velocity - v) / np.linalg.norm(v))


def test_two_targets_with_their_positions_estimated(two_points):
    """Both velocities within 0.1 % (measured 0.003-0.005 %) and both positions within 0.5 m
    (measured 0.01 m), each within 3 sigma, confident, whichever order the receivers found them in."""
    found = clsas.estimate_motions(two_points, 2)
    assert len(found) == 2
    truth = {0: (CENTRE, V1), 1: (SECOND, V3)}
    matched = sorted(range(2), key=lambda t: np.linalg.norm(found[0].position - truth[t][0]))
    for est, t in zip(found, matched):
        position, v = truth[t]
        assert est.position_estimated
        assert _error(est, v) < 1e-3, (t, est.velocity)
        assert np.linalg.norm(est.position - position) < 0.5, (t, est.position)
        assert np.all(np.abs(est.velocity - v) <= 3 * est.sigma), (t, est.velocity - v, est.sigma)
        assert est.confidence > 0.5 and est.problems == ()
    assert matched[0] != matched[1]


def test_two_targets_in_the_order_of_their_given_positions(two_points):
    """With the positions given, the estimates come in their order (the second target first here)."""
    second, first = clsas.estimate_motions(two_points, 2, positions=[SECOND, CENTRE])
    assert _error(second, V3) < 1e-3 and _error(first, V1) < 1e-3
    assert not second.position_estimated and np.allclose(second.position, SECOND)


def test_estimate_motions_rejects_bad_input(two_points):
    with pytest.raises(ValueError, match="n_targets"):
        clsas.estimate_motions(two_points, 0)
    with pytest.raises(ValueError, match="positions"):
        clsas.estimate_motions(two_points, 2, positions=[CENTRE])
    with pytest.raises(TypeError, match="n_targets"):
        clsas.estimate_motions(two_points, "2")
