"""Kernel builds are quiet: known-harmless compiler output is hidden, anything else is logged."""

from __future__ import annotations

import logging
import os
import subprocess
import sys

from clsas import opencl


def _say(text: str) -> None:
    os.write(2, text.encode())  # as PoCL's clang does: straight to file descriptor 2


def test_harmless_output_hidden_and_the_rest_logged(capfd, caplog, monkeypatch):
    monkeypatch.delenv("CLSAS_DEBUG", raising=False)
    monkeypatch.delenv("PYOPENCL_COMPILER_OUTPUT", raising=False)
    with caplog.at_level(logging.WARNING, logger="clsas"):
        with opencl.quiet_build("x") as log:
            _say("61 warnings generated.\n")
            log.append("warning: common.h:83:68: AVX vector argument of type 'float16' changes the ABI\n")
        assert capfd.readouterr().err == "" and not caplog.records
        with opencl.quiet_build("y") as log:
            _say("y.cl:3:1: warning: unused variable 'k'\n1 warning generated.\n")
    assert capfd.readouterr().err == ""
    (record,) = caplog.records
    assert "kernels/y.cl" in record.getMessage() and "unused variable 'k'" in record.getMessage()
    assert "generated" not in record.getMessage()


def test_debug_shows_the_compiler_output(capfd, monkeypatch):
    monkeypatch.setenv("CLSAS_DEBUG", "1")
    with opencl.quiet_build("x"):
        _say("2 warnings generated.\n")
    assert capfd.readouterr().err == "2 warnings generated.\n"


def test_a_fresh_process_building_kernels_prints_nothing(opencl_device):
    code = ("import numpy as np; from clsas import kernelmath; "
            "kernelmath.rotate_phase(np.ones(8, np.complex64), np.zeros(8, np.float32), backend='opencl')")
    env = {k: v for k, v in os.environ.items() if k not in ("CLSAS_DEBUG", "PYOPENCL_COMPILER_OUTPUT")}
    env.update(PYOPENCL_NO_CACHE="1", POCL_KERNEL_CACHE="0")  # a cold build, as on a fresh machine
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0 and out.stderr == "" and out.stdout == ""


def test_an_interrupted_build_logs_nothing(capfd, caplog, monkeypatch):
    """Ctrl-C during a build: the compiler's "1 error generated." is not logged (the CLI prints its
    one line), and the interrupt goes on."""
    monkeypatch.delenv("CLSAS_DEBUG", raising=False)
    monkeypatch.delenv("PYOPENCL_COMPILER_OUTPUT", raising=False)
    with caplog.at_level(logging.WARNING, logger="clsas"):
        try:
            with opencl.quiet_build("x"):
                _say("x.cl:1:1: error: interrupted\n1 error generated.\n")
                raise KeyboardInterrupt
        except KeyboardInterrupt:
            pass
        else:
            raise AssertionError("the interrupt was swallowed")
    assert capfd.readouterr().err == "" and not caplog.records
