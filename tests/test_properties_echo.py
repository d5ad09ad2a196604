"""Property tests (hypothesis) of echo synthesis's propagation: random scenes with a sea surface,
a seabed, absorption and intra-pulse Doppler, the OpenCL kernel against the float64 reference;
absorption positive and finite over the Medium's whole domain; bad parameters refused by name.

The machinery (bounded example counts, ``CLSAS_PROPERTY_EXAMPLES`` soak) is tests/test_properties.py's.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from clsas.model import Medium
from clsas.scene.seafloor import Seafloor
from clsas.scene.surface import SeaSurface
from clsas.synthesis import SynthesisOptions, simulate, synthesize
from clsas.synthesis.propagation import absorption_db_per_km, path_kinds, boundaries

from _tolerances import rel_l2
from test_properties import PROPERTY, scenes


@st.composite
def environments(draw):
    """A random scene (tests/test_properties.py) under a surface 1-10 m above the platform,
    over a sandy or muddy bottom 30-60 m below it (a 20 cm patch of its speckle), in random water."""
    scene = draw(scenes())
    medium = Medium(scene.medium.sound_speed, temperature=draw(st.floats(-2.0, 30.0)),
                    salinity=draw(st.floats(30.0, 40.0)), depth=draw(st.floats(0.0, 500.0)),
                    ph=draw(st.floats(7.5, 8.4)))
    surface = SeaSurface(draw(st.floats(1.0, 10.0)), rms_height=draw(st.floats(0.0, 0.05)))
    floor = Seafloor((40.0, 40.2, -0.1, 0.1), -draw(st.floats(30.0, 60.0)),
                     sediment=draw(st.sampled_from(["sand", "mud", "gravel"])))
    return scene.replace(medium=medium, surface=surface, seafloor=floor)


@PROPERTY
@given(scene=environments(), order=st.integers(0, 2), intra=st.sampled_from(["moving", "all", "none"]))
def test_propagating_kernel_matches_reference(opencl_device, scene, order, intra):
    """Measured over 60 random scenes: relative L2 up to 1.5e-5 (the seabed table, the float32
    chirps): bound 2e-4."""
    common = dict(progress=False, multipath=order, intra_pulse=intra, spreading=True, absorption=True,
                  max_bytes=2**30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # random scenes may overlap pulses or undersample: not the point here
        ref = synthesize(scene, SynthesisOptions(backend="numpy", dtype=np.complex128, **common))
        got = synthesize(scene, SynthesisOptions(backend="opencl", **common))
    assert len(ref.physics.kinds) == len(path_kinds(boundaries(scene), order))
    assert np.all(np.isfinite(got.data))
    if np.any(ref.data):
        assert rel_l2(got.data, ref.data) < 2e-4


@PROPERTY
@given(t=st.floats(-2.0, 40.0), s=st.floats(0.0, 45.0), d=st.floats(0.0, 12000.0), ph=st.floats(6.0, 9.0),
       f=st.floats(1.0, 1e7))
def test_absorption_is_positive_and_finite_over_the_medium(t, s, d, ph, f):
    a = absorption_db_per_km(f, Medium(temperature=t, salinity=s, depth=d, ph=ph))
    assert np.isfinite(a) and a > 0


@pytest.mark.parametrize("field,value,error", [
    ("temperature", 50.0, ValueError), ("temperature", float("nan"), ValueError), ("salinity", -1.0, ValueError),
    ("depth", -5.0, ValueError), ("ph", 12.0, ValueError), ("ph", "8", TypeError)])
def test_medium_refuses_bad_water_by_name(field, value, error):
    with pytest.raises(error, match=f"Medium.{field}"):
        Medium(**{field: value})


@pytest.mark.parametrize("option,value,error", [
    ("multipath", 3, ValueError), ("multipath", 1.5, TypeError), ("intra_pulse", "sometimes", ValueError),
    ("absorption", "yes", TypeError), ("spreading", 1, TypeError), ("spreading", None, TypeError),
    ("multipath", None, TypeError)])
def test_propagation_options_are_refused_by_name(option, value, error):
    with pytest.raises(error, match=option):
        SynthesisOptions(**{option: value})


def test_absorption_refuses_bad_frequencies():
    with pytest.raises(ValueError, match="frequency_hz"):
        absorption_db_per_km(0.0)
    with pytest.raises(ValueError, match="frequency_hz"):
        absorption_db_per_km([1e3, np.inf])
    with pytest.raises(TypeError, match="medium"):
        absorption_db_per_km(1e3, medium=1500.0)


def test_simulate_refuses_a_bad_multipath_before_any_work(rng):
    from clsas.scene import presets
    from clsas.scene.targets import PointTargets

    sc = presets.kiang2022(n_pulses=2).replace(targets=(PointTargets([100.0, 0.0, -40.0]),))
    with pytest.raises(ValueError, match="multipath"):
        simulate(sc, multipath=-1, progress=False)
    sc = dataclasses.replace(sc)
    with pytest.raises(ValueError, match="intra_pulse"):
        simulate(sc, intra_pulse="all-of-them", progress=False)
