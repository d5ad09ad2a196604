"""Chirp scaling (Cumming & Wong 2005 ch. 7) against back-projection."""

from __future__ import annotations

import pytest
from _line_scenes import assert_agrees_with_backprojection, compare_with_range_doppler, wide_swath

from clsas.image.csa import chirp_scaling


@pytest.mark.parametrize("scene", ["mono", "huang"])
def test_agrees_with_backprojection(opencl_device, scene):
    assert_agrees_with_backprojection(chirp_scaling, scene)


def test_points_far_from_the_reference_range_focus(opencl_device):
    """Over a 160 m swath (reference 122 m) every point's peak, PSLR and position stay within
    1 dB and 0.15 of a cell of range-Doppler's (whose SRC follows the range by sub-blocks):
    measured -0.5 dB, 0.75 dB and 0.09 cell at 44 m. A residual phase of (R0 / D - R_ref)^2
    instead of ((R0 - R_ref) / D)^2 lost 3.1 dB of peak and 3.8 dB of along-track PSLR there."""
    points, record = wide_swath()
    image = chirp_scaling(record, elements=(0.04, 0.02), deconvolve=False, backend="opencl")
    for row in compare_with_range_doppler(image, record, points):
        assert abs(row["peak_db"]) < 1.0 and abs(row["pslr_y"]) < 1.0 and abs(row["pslr_x"]) < 1.0, row
        assert abs(row["dy"]) < 0.15 * 0.02 and abs(row["dx"]) < 0.15 * 0.0375, row
