"""Range-Doppler with sub-block SRC (Huang & Yang 2022 eqs. 19-25) against back-projection."""

from __future__ import annotations

import pytest
from _line_scenes import assert_agrees_with_backprojection

from clsas.image.rda import range_doppler


@pytest.mark.parametrize("scene", ["mono", "huang"])
def test_agrees_with_backprojection(opencl_device, scene):
    assert_agrees_with_backprojection(range_doppler, scene)
