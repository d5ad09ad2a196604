"""A setting of the current thread held in a context variable (:mod:`contextvars`): the one
mechanism behind :func:`clsas.use_backend` and :func:`clsas.use_memory_budget`.

Setting it is a plain call (the value stays) or a context manager (the previous value comes back
on exit). A ``with`` block in one thread (or asyncio task) leaves every other thread's value
alone; a new thread starts from the variable's default.
"""

from __future__ import annotations

import contextvars


class ThreadSetting:
    """Set ``variable`` to ``value`` in the current context now; as a context manager, restore
    the previous value on exit."""

    def __init__(self, variable: contextvars.ContextVar, value):
        self._variable = variable
        self._previous = variable.get()
        self._token = variable.set(value)

    def __enter__(self):
        return self

    def __exit__(self, *exc_info) -> None:
        try:
            self._variable.reset(self._token)
        except (RuntimeError, ValueError):  # the same object entered twice, or exited in another context
            self._variable.set(self._previous)
