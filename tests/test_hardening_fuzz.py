"""The fuzz of issue #27 (bench/fuzz_api.py): every (function, parameter, bad value) combination
of the public API on tiny scenes, once. No defect may sit in the hardening's own modules (files,
model, metrics, autofocus, budget, CLI ...); the others' are listed by bench/fuzz_api.py."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))

import fuzz_api  # noqa: E402


@pytest.mark.slow
def test_the_fuzz_finds_no_defect_in_the_hardened_modules():
    defects, calls = fuzz_api.run([1], None, timeout=120)
    assert calls > 900
    ours = [d for d in defects if d["owner"] == "harden"]
    assert not ours, "\n".join(f"{d['function']}({d['parameter']}={d['value']}): {d['verdict']}" for d in ours)


def test_the_fuzz_judges_by_the_rule():
    """The judge itself: a named ValueError passes; an unnamed one, a crash, a wrong kind
    accepted and NaN from finite input are defects."""
    p = fuzz_api.Param("speed", "real")

    def target(fn):
        return fuzz_api.Target("thrust", lambda **kw: fn(**kw), (p,), "clsas")

    def refuse(speed):
        raise ValueError(f"thrust speed: must be > 0, got {speed}")

    assert fuzz_api.judge(target(refuse), p, -1.0, 5) is None
    assert fuzz_api.judge(target(lambda speed: 1 / 0), p, 0.0, 5).startswith("crash: ZeroDivisionError")
    assert fuzz_api.judge(target(lambda speed: float(speed)), p, "a", 5).startswith("unnamed")
    assert fuzz_api.judge(target(lambda speed: speed), p, "a", 5).startswith("accepted")
    assert fuzz_api.judge(target(lambda speed: {"x": (speed * 1e10,)}), p, 1e300, 5).startswith("nonfinite")
    assert fuzz_api.owner("clsas.estimate.moving.velocity") == "moving" and fuzz_api.owner("clsas.metrics") == "harden"


def test_the_fuzz_judges_choices_by_membership():
    """A choice refuses anything not among its options with a ValueError, a string or not
    (docs/design.md); a TypeError there is a defect, as is a nonsense string accepted."""
    p = fuzz_api.Param("window", "choice")

    def target(fn):
        return fuzz_api.Target("shade", lambda **kw: fn(**kw), (p,), "clsas")

    def by_value(window):
        raise ValueError(f"shade window: must be one of ('none', 'hamming'), got {window!r}")

    def by_kind(window):
        raise TypeError(f"shade window: must be a string, got {window!r}")

    assert fuzz_api.judge(target(by_value), p, None, 5) is None
    assert fuzz_api.judge(target(by_value), p, 1j, 5) is None
    assert fuzz_api.judge(target(by_kind), p, None, 5).startswith("choice: TypeError")
    assert fuzz_api.judge(target(lambda window: window), p, "unknown", 5).startswith("accepted")

