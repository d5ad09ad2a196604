"""Shared fixtures: the ``backend`` fixture runs a test once per backend.

The OpenCL case is skipped only when no OpenCL device exists *and* ``CLSAS_REQUIRE_OPENCL``
is unset; ``make test`` and CI set ``CLSAS_REQUIRE_OPENCL=1`` so that a missing device fails.
"""

from __future__ import annotations

import os

import pytest

from clsas import opencl


def _require_opencl() -> bool:
    return os.environ.get("CLSAS_REQUIRE_OPENCL", "") not in ("", "0")


@pytest.fixture(scope="session")
def opencl_device():
    """The OpenCL runtime, or a skip (or a failure when CLSAS_REQUIRE_OPENCL=1)."""
    try:
        return opencl.runtime()
    except opencl.OpenCLUnavailable as err:
        if _require_opencl():
            pytest.fail(f"CLSAS_REQUIRE_OPENCL=1 but no OpenCL device: {err}")
        pytest.skip(f"no OpenCL device: {err}")


@pytest.fixture(params=["numpy", "opencl"])
def backend(request):
    """Backend name; the OpenCL case needs a device (see the module docstring)."""
    if request.param == "opencl":
        request.getfixturevalue("opencl_device")
    return request.param


@pytest.fixture
def rng():
    return __import__("numpy").random.default_rng(12345)
