"""The wheel ships kernels/ as clsas/kernels and runs a kernel when installed outside the checkout."""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import textwrap
import venv
import zipfile
from pathlib import Path

import pytest

from clsas import opencl

ROOT = Path(__file__).resolve().parent.parent


def test_kernels_found_in_checkout():
    kdir = opencl.kernels_dir()
    assert (kdir / "common.h").is_file()
    assert {p.name for p in (ROOT / "kernels").glob("*.cl")} <= {p.name for p in kdir.glob("*.cl")}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                    "-w", str(out), str(ROOT)], check=True)
    (path,) = out.glob("clsas-*.whl")
    return path


def test_wheel_contains_kernels(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert "clsas/kernels/common.h" in names
    for cl in (ROOT / "kernels").glob("*.cl"):
        assert f"clsas/kernels/{cl.name}" in names


def test_installed_wheel_runs_a_kernel_outside_the_checkout(wheel, tmp_path, opencl_device):
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=False)
    py = env_dir / "bin" / "python"
    site = subprocess.run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          check=True, capture_output=True, text=True).stdout.strip()
    # the dependencies come from the test's own environment (a plain path entry: its .pth
    # files, among them the editable install of the checkout, are not processed)
    Path(site, "deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", site, str(wheel)],
                   check=True)
    script = textwrap.dedent(f"""
        import numpy as np, clsas
        from clsas import kernelmath, opencl
        assert {str(ROOT)!r} not in clsas.__file__, clsas.__file__
        kdir = opencl.kernels_dir()
        assert str(kdir).startswith({site!r}), kdir
        y = kernelmath.rotate_phase(np.ones(4, np.complex64), np.array([0, .25, .5, .75], np.float32),
                                    backend="opencl")
        assert np.allclose(y, [1, 1j, -1, -1j], atol=1e-6), y
        print("OK", kdir)
    """)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    result = subprocess.run([py, "-c", script], cwd=tmp_path, capture_output=True, text=True, env=env)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("OK")
