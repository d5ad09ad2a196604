"""Chirp scaling (Cumming & Wong 2005 ch. 7) against back-projection."""

from __future__ import annotations

import pytest
from _line_scenes import assert_agrees_with_backprojection

from clsas.image.csa import chirp_scaling


@pytest.mark.parametrize("scene", ["mono", "huang"])
def test_agrees_with_backprojection(opencl_device, scene):
    assert_agrees_with_backprojection(chirp_scaling, scene)
