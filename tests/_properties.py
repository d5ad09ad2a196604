"""Property-test machinery for clsas's public functions (hypothesis), stated once so that the next
estimator is covered by declaring its parameters' domains.

The rule every entry point keeps (:mod:`clsas.validate`): a value of the wrong kind (a string,
None, a bool or a list where a number belongs; a float where an integer belongs) raises
TypeError; a value of the right kind outside what is allowed (NaN, inf, out of range, too large
for a float) raises ValueError; both name the parameter; a request over the memory budget
raises MemoryBudgetError (a ValueError) before it allocates; functions with two backends raise
the same error on both. :func:`parameter_properties` turns a call and its domains into three
hypothesis tests of that rule::

    from _properties import choices, flags, integers, parameter_properties, reals

    test_pga_bad, test_pga_valid, test_pga_budget = parameter_properties(
        lambda **kw: autofocus.pga(IMAGE, **kw),    # every other argument fixed
        prefix="pga",                                # messages name "pga tolerance", ...
        domains={"tolerance": reals(0.0, 10.0, low_open=True),
                 "max_iterations": integers(1, 10_000),
                 "workers": integers(-1024, 1024, none=True)},
        outcomes=(EstimationError,))                 # what a valid call may raise besides returning

- ``bad``: one parameter gets a bad value of its domain: the documented error, naming
  ``"<prefix> <parameter>"``; with ``backends``, the same message on each.
- ``valid``: every parameter gets a valid value (or keeps its default): the call returns
  (``check(result)`` passes) or raises one of ``outcomes``, or a ValueError naming one of the
  parameters (values valid alone may be refused together, or with another's default:
  ``may_refuse``).
- ``budget``: valid values under a small memory budget: the call stays within it (NumPy's
  allocations, traced) or refuses with MemoryBudgetError having allocated next to nothing.
"""

from __future__ import annotations

import functools
import math
import re
import tracemalloc
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import clsas
from clsas.errors import MemoryBudgetError

CHECKS = settings(max_examples=25, deadline=None, derandomize=True)

WRONG_KIND = st.one_of(st.text(max_size=5), st.none(), st.booleans(), st.lists(st.floats(), min_size=2, max_size=3),
                       st.just(object()), st.just(1j))

BUDGET_SLACK = 1 << 20  # bytes a call may allocate besides its budget (NumPy's small temporaries)


def bad_reals(low: float | None, high: float | None, low_open: bool = False, high_open: bool = False):
    """(value, ValueError) outside [low, high] (open ends excluded), non-finite, or beyond float;
    (value, TypeError) of the wrong kind."""
    values = [st.sampled_from([math.nan, math.inf, -math.inf, 10**400, -(10**400)])]
    if low is not None:
        values.append(st.floats(max_value=low, exclude_max=not low_open, allow_nan=False, allow_infinity=False))
    if high is not None:
        values.append(st.floats(min_value=high, exclude_min=not high_open, allow_nan=False, allow_infinity=False))
    return st.one_of(st.tuples(st.one_of(values), st.just(ValueError)), st.tuples(WRONG_KIND, st.just(TypeError)))


def bad_integers(low: int, high: int | None = None):
    """(value, ValueError) for integers out of [low, high]; (value, TypeError) for non-integers."""
    out = [st.integers(max_value=low - 1)]
    if high is not None:
        out.append(st.integers(min_value=high + 1, max_value=10**30))
    kinds = st.one_of(WRONG_KIND, st.floats(), st.sampled_from([2.0, 1.5, np.float64(3.0)]))
    return st.one_of(st.tuples(st.one_of(out), st.just(ValueError)), st.tuples(kinds, st.just(TypeError)))


def not_none(strategy):
    """For parameters where None is allowed (it means the default)."""
    return strategy.filter(lambda case: case[0] is not None)


def raises(error, name: str, call):
    """``call()`` raises ``error`` with ``name`` in its message; returns the exception."""
    with pytest.raises(error, match=re.escape(name)) as caught:
        call()
    return caught.value


def same_on_both_backends(name, error, call):
    """``call(backend)`` raises ``error`` naming ``name``, with the same message on both backends."""
    messages = {str(raises(error, name, functools.partial(call, backend))) for backend in ("numpy", "opencl")}
    assert len(messages) == 1, messages


@dataclass(frozen=True)
class Domain:
    """A parameter's values: ``valid`` ones (a strategy) and ``bad`` ones (a strategy of
    ``(value, error type)``, or ``(value, error type, text the message must hold)`` where it is
    not ``"<prefix> <parameter>"``: a file's errors name the file)."""

    valid: st.SearchStrategy
    bad: st.SearchStrategy


def reals(low: float | None = None, high: float | None = None, low_open: bool = False, high_open: bool = False,
          none: bool = False, valid=None) -> Domain:
    """A finite real in [low, high] (``low_open`` / ``high_open`` exclude the ends); ``none``:
    None is valid too (it means the default); ``valid``: a narrower strategy of valid values
    (e.g. the part of the range a tiny scene can use)."""
    if valid is None:
        valid = st.floats(min_value=low, max_value=high, exclude_min=low_open and low is not None,
                          exclude_max=high_open and high is not None, allow_nan=False, allow_infinity=False)
    bad = bad_reals(low, high, low_open, high_open)
    return Domain(valid | st.none() if none else valid, not_none(bad) if none else bad)


def integers(low: int, high: int | None = None, none: bool = False, valid=None) -> Domain:
    """An integer in [low, high] (Python or NumPy, never a bool or a float)."""
    valid = st.integers(low, high) if valid is None else valid
    bad = bad_integers(low, high)
    return Domain(valid | st.none() if none else valid, not_none(bad) if none else bad)


def flags() -> Domain:
    """True or False (a string such as "no", 0 or None is a TypeError, never read as a bool)."""
    return Domain(st.booleans(), st.tuples(st.sampled_from(["no", "yes", "", 0, 1, None, 1.0, [True]]),
                                           st.just(TypeError)))


CHOICE_OTHER_KINDS = (None, 0, 1.5, True, 1j)


def choices(options, bad=("", "NONE", "unknown")) -> Domain:
    """One of the strings ``options``; anything else, a string or not (None, a number, a bool),
    is a ValueError (docs/design.md: a choice is judged by membership, ``validate.choice``)."""
    return Domain(st.sampled_from(list(options)), st.tuples(st.sampled_from(list(bad) + list(CHOICE_OTHER_KINDS)),
                                                            st.just(ValueError)))


def fixed(valid, bad) -> Domain:
    """Values listed by hand: ``valid`` values, ``bad`` as ``(value, error type)`` pairs (or
    ``(value, error type, text)``)."""
    return Domain(st.sampled_from(list(valid)), st.sampled_from(list(bad)))


def _label(prefix: str, name: str) -> str:
    """What a message names: ``"pga tolerance"``, or ``"EchoData.fs"`` for a prefix ending in a dot."""
    return f"{prefix}{name}" if prefix.endswith(".") else f"{prefix} {name}"


def parameter_properties(call, prefix: str, domains: dict, outcomes: tuple = (), check=None, backends: tuple = (),
                         may_refuse: bool = False, budget: int | None = 1 << 20, examples: int = 25, setup=None,
                         labels: dict | None = None):
    """Three hypothesis tests of ``call(**{parameter: value})`` over ``domains`` (see the module
    docstring): ``(bad, valid, budget)``; ``budget=None`` leaves out the third (returns None).

    ``call(backend=..., **kw)`` is called once per backend of ``backends`` (names as
    :func:`clsas.use_backend` takes them), else ``call(**kw)`` once. ``check(result)`` asserts
    what a result must be (finite, a shape). ``budget``: the memory budget (bytes) of the third
    test; NumPy's allocations are traced (OpenCL buffers and C libraries' own memory are not).
    ``setup()`` builds what the call uses (cached fixtures) before the allocations are traced.
    ``labels``: what the messages name instead of ``"<prefix> <parameter>"``, by parameter (a
    function that checks through another one's helper names that one).
    """
    names = sorted(domains)
    labels = {name: _label(prefix, name) for name in names} | (labels or {})
    runs = settings(max_examples=examples, deadline=None, derandomize=True)

    def each_backend(kw):
        if not backends:
            return [call(**kw)]
        return [call(backend=b, **kw) for b in backends]

    @runs
    @given(st.data())
    def bad(data):
        name = data.draw(st.sampled_from(names), label="parameter")
        case = data.draw(domains[name].bad, label="bad value")
        value, error = case[:2]
        label = case[2] if len(case) > 2 else labels[name]
        if not backends:
            raises(error, label, lambda: call(**{name: value}))
            return
        messages = {str(raises(error, label, lambda b=b: call(backend=b, **{name: value}))) for b in backends}
        assert len(messages) == 1, messages

    def drawn(data) -> dict:
        chosen = data.draw(st.lists(st.sampled_from(names), unique=True), label="parameters")
        return {name: data.draw(domains[name].valid, label=name) for name in chosen}

    def allowed(err: BaseException, kw: dict) -> bool:
        if isinstance(err, outcomes):
            return True
        return may_refuse and isinstance(err, ValueError) and any(labels[n] in str(err) for n in names)

    @runs
    @given(st.data())
    def valid(data):
        kw = drawn(data)
        try:
            results = each_backend(kw)
        except Exception as err:  # noqa: BLE001 - judged below
            if not allowed(err, kw):
                raise
            return
        if check is not None:
            for result in results:
                check(result)

    if budget is None:
        return bad, valid, None

    @runs
    @given(st.data())
    def within_budget(data):
        kw = drawn(data)
        limit = data.draw(st.integers(budget // 16, budget), label="budget")
        if setup is not None:
            setup()
        with clsas.use_memory_budget(limit):
            tracemalloc.start()
            try:
                each_backend(kw)
            except MemoryBudgetError:
                pass  # refused: the peak below shows it was before allocating
            except Exception as err:  # noqa: BLE001 - judged as in `valid`
                if not allowed(err, kw):
                    raise
            finally:
                peak = tracemalloc.get_traced_memory()[1]
                tracemalloc.stop()
        assert peak <= limit + BUDGET_SLACK, f"{prefix}: {peak} bytes allocated under a budget of {limit}"

    return bad, valid, within_budget
