"""Property tests (hypothesis) of back-projection's FIR record upsampler (clsas.image.upsample):
the kernel against its NumPy twin on random rows, factors and spans, any span's samples those of
the whole record, the original samples kept, and finite output from finite input at any scale.

As in tests/test_properties.py: a dozen derandomised cases a property (CLSAS_PROPERTY_EXAMPLES=N
for a randomised soak), bounds ~10x the largest error measured over randomised runs.
"""

from __future__ import annotations

import os

import numpy as np
from _tolerances import rel_l2
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from clsas.image import upsample as fir

SOAK = int(os.environ.get("CLSAS_PROPERTY_EXAMPLES", "0"))
PROPERTY = settings(max_examples=SOAK or 12, deadline=None, derandomize=not SOAK, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@st.composite
def cases(draw):
    """(records (rows, n) complex64, factor, first, stop): 1-4 rows of 1-300 samples at a scale
    from 1e-30 to 1e30, a factor in [2, 64] (multiples of 8 and others), a span within the row."""
    rows, n = draw(st.integers(1, 4)), draw(st.integers(1, 300))
    factor = draw(st.one_of(st.sampled_from([8, 16, 64]), st.integers(2, 64)))
    first = draw(st.integers(0, n - 1))
    stop = draw(st.integers(first + 1, n))
    scale = 10.0 ** draw(st.integers(-30, 30))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    records = (scale * (rng.standard_normal((rows, n)) + 1j * rng.standard_normal((rows, n)))).astype(np.complex64)
    return records, factor, first, stop


@PROPERTY
@given(case=cases())
def test_kernel_matches_its_twin_on_any_span(opencl_device, case):
    """Kernel vs twin: measured <= 1.2e-7 relative L2 over 300 randomised cases; the original samples
    kept exactly (phase 0); a span's samples the whole record's, bit for bit; all finite."""
    records, factor, first, stop = case
    got = fir.upsample_fir(records, factor, first, stop)
    assert np.all(np.isfinite(got))
    assert rel_l2(got, fir.upsample_reference(records, factor, first, stop)) < 1e-6
    assert np.array_equal(got[:, ::factor], records[:, first:stop])
    whole = fir.upsample_fir(records, factor, 0, records.shape[1])
    assert np.array_equal(got, whole[:, factor * first:factor * stop])
