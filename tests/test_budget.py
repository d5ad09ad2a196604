"""The memory budget: one place to read and raise it; requests over it refused before allocation."""

from __future__ import annotations

import threading
import tracemalloc

import numpy as np
import pytest

import clsas
from clsas import budget
from clsas.errors import MemoryBudgetError
from clsas.scene.scenario import Array, PulseSchedule, Recording


def test_default_is_half_the_physical_memory(monkeypatch):
    monkeypatch.delenv(budget.ENV, raising=False)
    assert clsas.memory_budget() == budget.physical_memory() // 2


@pytest.mark.parametrize("text, nbytes", [("1024", 1024), ("16G", 16 * 2**30), ("1.5M", 3 * 2**19), ("2 GiB", 2**31),
                                          ("3e9", 3 * 10**9)])
def test_environment_variable(monkeypatch, text, nbytes):
    monkeypatch.setenv(budget.ENV, text)
    assert clsas.memory_budget() == nbytes


@pytest.mark.parametrize("text", ["lots", "-5G", "0", "1X", ""])
def test_bad_environment_variable_is_named(monkeypatch, text):
    monkeypatch.setenv(budget.ENV, text)
    if text == "":
        assert clsas.memory_budget() == budget.physical_memory() // 2
        return
    with pytest.raises(ValueError, match=budget.ENV):
        clsas.memory_budget()


def test_call_and_context_manager(monkeypatch):
    monkeypatch.delenv(budget.ENV, raising=False)
    default = clsas.memory_budget()
    with clsas.use_memory_budget("1M"):
        assert clsas.memory_budget() == 2**20
        with clsas.use_memory_budget(4096):
            assert clsas.memory_budget() == 4096
        assert clsas.memory_budget() == 2**20
    assert clsas.memory_budget() == default
    clsas.use_memory_budget(12345)
    try:
        assert clsas.memory_budget() == 12345
    finally:
        clsas.use_memory_budget(None)
    assert clsas.memory_budget() == default


@pytest.mark.parametrize("bad, err", [(0, ValueError), (-1, ValueError), (float("nan"), ValueError), (True, TypeError),
                                      ("x", ValueError), ([1], TypeError)])
def test_bad_budget_values(bad, err):
    with pytest.raises(err, match="use_memory_budget nbytes"):
        clsas.use_memory_budget(bad)


AXIS = np.arange(1e6)  # 8 MB: a 10^6 x 10^6 plane would need 80 TB


@pytest.mark.parametrize("make, name, allowed", [
    (lambda: PulseSchedule(prf=10.0, n_pulses=10**12), "PulseSchedule.n_pulses", 2**16),
    (lambda: PulseSchedule(prf=1e4, exposure=1e6), "PulseSchedule.exposure", 2**16),
    (lambda: Array.uniform_line(10**12, 0.1, 0.0), "n_receivers", 2**16),
    (lambda: Recording(t0=0.0, n_samples=10**12), "Recording.n_samples", 2**16),
    (lambda: clsas.Grid.plane(AXIS, AXIS, 0.0), "Grid.plane", 3 * AXIS.nbytes),  # the checked copies of x and y
    (lambda: clsas.Grid.slant((0, 0, 0), (1, 0, 0), (0, 1, 0), AXIS, AXIS), "Grid.slant", 3 * AXIS.nbytes),
])
def test_requests_over_the_budget_are_refused_before_allocation(make, name, allowed):
    tracemalloc.start()
    try:
        with pytest.raises(MemoryBudgetError, match=name) as caught:
            make()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert isinstance(caught.value, ValueError)
    assert "use_memory_budget" in str(caught.value)
    assert peak < allowed


def test_a_raised_budget_lets_a_request_through():
    with clsas.use_memory_budget(100):
        with pytest.raises(MemoryBudgetError):
            PulseSchedule(prf=10.0, n_pulses=100)
    assert PulseSchedule(prf=10.0, n_pulses=100).n_pulses == 100


def test_a_with_block_in_one_thread_leaves_another_threads_budget_alone(monkeypatch):
    monkeypatch.delenv(budget.ENV, raising=False)
    default = clsas.memory_budget()
    barrier = threading.Barrier(2, timeout=30)
    seen, errors = {}, []

    def run(name, nbytes):
        try:
            with clsas.use_memory_budget(nbytes):
                barrier.wait()  # both threads are inside their blocks
                seen[name] = clsas.memory_budget()
                barrier.wait()
            seen[name + " after"] = clsas.memory_budget()
        except BaseException as err:  # noqa: BLE001 - reported below
            errors.append(err)
            barrier.abort()

    threads = [threading.Thread(target=run, args=("a", "1M")), threading.Thread(target=run, args=("b", 4096))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    assert seen == {"a": 2**20, "b": 4096, "a after": default, "b after": default}
    assert clsas.memory_budget() == default
