"""bench/_harness.py: every figure names the machine and the code its kernels were built for;
``--kernels avx2`` builds them as PoCL does on an AVX2 CPU (run in a fresh process each, since PoCL
reads its settings when the first device is opened)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "bench"

PROBE = """
import json, sys
sys.argv = ["probe", *sys.argv[1:]]
from _harness import arguments, machine
from clsas import opencl
args = arguments("probe")
opencl.program("kernelmath")  # a real build on the chosen code model
print(json.dumps({"machine": machine(), "device": opencl.runtime().device.name}))
"""


def _probe(tmp_path, *argv) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("POCL_") and k != "PYOPENCL_NO_CACHE"}
    env["XDG_CACHE_HOME"] = str(tmp_path / "cache")
    done = subprocess.run([sys.executable, "-c", PROBE, *argv], cwd=BENCH, env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_kernels_avx2_builds_for_an_avx2_cpu_and_says_so(opencl_device, tmp_path):
    platform = opencl_device.device.platform.name
    if "portable computing language" not in platform.lower():
        pytest.fail(f"--kernels avx2 sets PoCL's options; the device's platform is {platform!r}")
    native, avx2 = _probe(tmp_path), _probe(tmp_path, "--kernels", "avx2")
    assert native["machine"]["kernels"] == "native" and avx2["machine"]["kernels"] == "avx2"
    assert "haswell" in avx2["device"], avx2["device"]  # PoCL names the device after the code model it builds for
    assert avx2["machine"]["opencl_device"].startswith(avx2["device"])
    assert (tmp_path / "cache" / "clsas-bench" / "pocl-avx2").is_dir()  # its own PoCL kernel cache
    if "avx512f" in Path("/proc/cpuinfo").read_text():
        assert "haswell" not in native["device"]  # on an AVX-512 CPU the native build is not the AVX2 one


def test_a_figure_not_run_by_opencl_names_what_ran_it():
    """A peer's or Embree's row names them, not NumPy (the torchbp and occlusion rows said
    "numpy on x86_64")."""
    sys.path.insert(0, str(BENCH))
    try:
        import _harness
    finally:
        sys.path.remove(str(BENCH))
    for backend in ("numpy", "embree", "torchbp-cpu"):
        assert _harness.device_name(backend).startswith(f"{backend} on ")
