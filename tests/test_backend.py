"""Backend choice (call, context manager, CLSAS_BACKEND, auto fallback) and OpenCL plumbing."""

from __future__ import annotations

import contextvars
import threading
import warnings

import numpy as np
import pytest

import clsas
from clsas import backend, opencl


@pytest.fixture(autouse=True)
def _restore_choice(monkeypatch):
    token = backend._choice.set(None)
    monkeypatch.setattr(backend, "_auto_warned", False)
    monkeypatch.delenv("CLSAS_BACKEND", raising=False)
    yield
    backend._choice.reset(token)


def test_use_backend_as_call_persists():
    clsas.use_backend("numpy")
    assert backend.default() == "numpy"
    assert backend.resolve() == "numpy"


def test_use_backend_as_context_manager_restores():
    clsas.use_backend("numpy")
    with clsas.use_backend("auto"):
        assert backend.default() == "auto"
    assert backend.default() == "numpy"


def _in_threads(first, second):
    """Run ``first(step)`` and ``second(step)`` on two threads in lockstep: each waits at
    ``step()`` for the other, so the second's checks fall inside the first's ``with`` block."""
    barrier = threading.Barrier(2, timeout=30)
    errors = []

    def run(body):
        try:
            body(barrier.wait)
        except BaseException as err:  # noqa: BLE001 - reported by the test
            errors.append(err)
            barrier.abort()

    threads = [threading.Thread(target=run, args=(body,)) for body in (first, second)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if errors:
        raise errors[0]


def test_a_with_block_in_one_thread_leaves_another_threads_backend_alone():
    seen = {}

    def first(step):
        with clsas.use_backend("numpy"):
            step()  # 1: the second thread looks now
            seen["first inside"] = backend.default()
            step()  # 2
        seen["first after"] = backend.default()

    def second(step):
        with clsas.use_backend("opencl"):
            step()  # 1
            seen["second inside"] = backend.default()
            step()  # 2
        seen["second after"] = backend.default()

    _in_threads(first, second)
    assert seen == {"first inside": "numpy", "second inside": "opencl", "first after": "auto", "second after": "auto"}
    assert backend.default() == "auto"  # this thread never chose


def test_plain_call_belongs_to_its_thread_and_copies_with_the_context():
    clsas.use_backend("numpy")
    seen = {}
    worker = threading.Thread(target=lambda: seen.update(fresh=backend.default()))
    worker.start()
    worker.join()
    context = contextvars.copy_context()
    worker = threading.Thread(target=lambda: seen.update(copied=context.run(backend.default)))
    worker.start()
    worker.join()
    assert seen == {"fresh": "auto", "copied": "numpy"}


def test_the_same_chooser_entered_twice_restores():
    chooser = clsas.use_backend("numpy")
    with chooser:
        pass
    assert backend.default() == "auto"
    with chooser:
        pass
    assert backend.default() == "auto"


def test_environment_variable(monkeypatch):
    monkeypatch.setenv("CLSAS_BACKEND", "numpy")
    assert backend.default() == "numpy"
    assert backend.resolve(None) == "numpy"
    monkeypatch.setenv("CLSAS_BACKEND", "cuda")
    with pytest.raises(ValueError, match="CLSAS_BACKEND"):
        backend.default()


def test_use_backend_overrides_environment(monkeypatch):
    monkeypatch.setenv("CLSAS_BACKEND", "opencl")
    with clsas.use_backend("numpy"):
        assert backend.resolve() == "numpy"


@pytest.mark.parametrize("bad", ["cuda", "", None, 3])
def test_unknown_backend_names_the_parameter(bad):
    with pytest.raises(ValueError, match="backend must be one of"):
        clsas.use_backend(bad)
    if bad is not None:
        with pytest.raises(ValueError, match="backend must be one of"):
            backend.resolve(bad)


def _no_device(monkeypatch):
    def fail(*_args, **_kwargs):
        raise opencl.OpenCLUnavailable(f"no OpenCL platform found (test). {opencl.INSTALL_HINT}")

    monkeypatch.setattr(opencl, "_all_devices", fail)
    monkeypatch.setattr(opencl, "_runtimes", {})
    monkeypatch.setattr(opencl, "_runtime_by_spec", {})


def test_opencl_without_device_raises_with_install_hint(monkeypatch):
    _no_device(monkeypatch)
    with pytest.raises(RuntimeError, match="pocl-opencl-icd"):
        backend.resolve("opencl")


def test_auto_without_device_falls_back_with_one_warning(monkeypatch):
    _no_device(monkeypatch)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert backend.resolve("auto") == "numpy"
        assert backend.resolve("auto") == "numpy"
        assert backend.resolve(None) == "numpy"
    relevant = [w for w in caught if issubclass(w.category, RuntimeWarning) and "auto" in str(w.message)]
    assert len(relevant) == 1


def test_numpy_path_works_without_device(monkeypatch):
    _no_device(monkeypatch)
    from clsas import kernelmath

    y = kernelmath.rotate_phase(np.ones(3, np.complex64), np.array([0.0, 0.25, 0.5]), backend="numpy")
    np.testing.assert_allclose(y, [1, 1j, -1], atol=1e-12)
    assert "opencl_error" in backend.info()


def test_info_reports_device(opencl_device):
    info = backend.info()
    for key in ("platform", "device", "opencl_version", "compute_units", "fp64"):
        assert key in info
    assert info["compute_units"] >= 1
    assert isinstance(info["fp64"], bool)


def test_device_selection_by_index_and_name(opencl_device):
    dev = opencl_device.device
    assert opencl.select_device("0:0") is not None
    assert opencl.select_device(dev.name[:6]).name == dev.name
    with pytest.raises(opencl.OpenCLUnavailable, match="matches no device"):
        opencl.select_device("no-such-device-xyz")


def test_clsas_device_environment(monkeypatch, opencl_device):
    monkeypatch.setenv("CLSAS_DEVICE", "no-such-device-xyz")
    with pytest.raises(opencl.OpenCLUnavailable, match="CLSAS_DEVICE"):
        opencl.select_device()
    with pytest.raises(opencl.OpenCLUnavailable, match="CLSAS_DEVICE"):
        opencl.runtime()  # the cache is keyed by the resolved spec: a new environment is honoured


def test_one_runtime_per_device(opencl_device):
    assert opencl.runtime() is opencl.runtime()
    assert opencl.runtime("0:0") is opencl.runtime(opencl_device.device.name)  # two specs, one device


def test_program_cache_keyed_by_options(opencl_device):
    a = opencl.program("kernelmath")
    assert opencl.program("kernelmath") is a
    b = opencl.program("kernelmath", defines={"UNUSED_CONSTANT": 3})
    assert b is not a
    if opencl.has_fp64(opencl_device.device):
        assert opencl.program("kernelmath", double=True) is not a


def test_build_error_shows_log(opencl_device, tmp_path, monkeypatch):
    (tmp_path / "common.h").write_text((opencl.kernels_dir() / "common.h").read_text())
    (tmp_path / "broken.cl").write_text(
        '#include "common.h"\n__kernel void broken(__global float *x) { x[0] = undefined_symbol_q; }\n')
    monkeypatch.setattr(opencl, "kernels_dir", lambda: tmp_path)
    with pytest.raises(opencl.KernelBuildError, match="undefined_symbol_q"):
        opencl.program("broken")


def test_unknown_kernel_source_lists_known(opencl_device):
    with pytest.raises(ValueError, match="kernelmath"):
        opencl.program("no_such_kernel")


def test_bad_precision():
    with pytest.raises(ValueError, match="precision"):
        backend.check_precision("half")


def _typed_kernel(rt):
    import pyopencl as cl

    prg = cl.Program(rt.context, "__kernel void k(__global float *o, const float a, const int b)"
                                 "{ o[0] = a; o[1] = (float)b; }").build()
    return opencl.TypedKernel(cl.Kernel(prg, "k")), cl.Buffer(rt.context, cl.mem_flags.READ_WRITE, 8)


def _launch(rt, kern, buf, a, b):
    import pyopencl as cl

    out = np.zeros(2, np.float32)
    kern(rt.queue, (1,), None, buf, a, b)
    cl.enqueue_copy(rt.queue, out, buf)
    return out.tolist()


def test_a_typed_kernel_packs_its_scalars_and_refuses_another_width(opencl_device):
    kern, buf = _typed_kernel(opencl_device)
    assert _launch(opencl_device, kern, buf, np.float32(1.5), np.int32(2)) == [1.5, 2.0]
    assert _launch(opencl_device, kern, buf, np.float32(-3.25), np.int32(7)) == [-3.25, 7.0]
    with pytest.raises(TypeError, match=r"argument 1 must be a float32 .*not float64"):
        _launch(opencl_device, kern, buf, np.float64(2.5), np.int32(3))  # never narrowed silently
    with pytest.raises(TypeError, match=r"argument 2 must be a int32 .*not int"):
        _launch(opencl_device, kern, buf, np.float32(2.5), 3)


def test_a_failed_first_launch_leaves_a_typed_kernel_usable(opencl_device):
    import pyopencl as cl

    kern, buf = _typed_kernel(opencl_device)
    with pytest.raises(cl.LogicError):  # a double in a float slot: pyopencl refuses its width
        _launch(opencl_device, kern, buf, np.float64(1.5), np.int32(2))
    assert _launch(opencl_device, kern, buf, np.float32(1.5), np.int32(2)) == [1.5, 2.0]
