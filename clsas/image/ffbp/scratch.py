"""Device buffers :func:`clsas.image.ffbp.ffbp` keeps between calls for its scratch images.

A call's largest device buffers hold only its own intermediate results, written before they are
read: the first stage's bp_tile sums (:mod:`.leaves`: a batch's, recycled within the call for a
later batch once its leaves are demodulated, :meth:`Scratch.recycle`), its batches' pixel fields
(ffbp_fields' output, which bp_tile reads) and the merge tree's groups, one buffer a level
(:class:`.store.DeviceStore`). Fresh ones cost their memory's page faults when the kernels first
touch them (on PoCL's CPU device: thousands of faults and milliseconds of system time a call,
bench_ffbp's wide case), so a call takes the buffers the last one gave back when they are large
enough (:meth:`Scratch.take`), and gives its own back at its end (:meth:`Scratch.give_back`). A
batch's pixel fields belong to its layout when :mod:`.reuse` keeps that (:meth:`Scratch.hand_over`):
their buffer serves later calls once the layout is let go (a new geometry's call lets go of the
last one's).

Sizes are rounded up to 1/GRAIN of their power of two (a buffer holds up to 1/GRAIN more than
asked; :func:`clsas.image.ffbp.memory_plan` counts it), so that a call on a slightly different
tree (a new geometry onto the same grid) finds the last call's buffers large enough. A taken
buffer is the call's alone until it gives it back (calls on several threads take different
ones). What is kept between calls is bounded by the room the caller gives (:meth:`Scratch.trim`
at the call's start, before it allocates, and :meth:`Scratch.give_back` at its end: the memory
budget beside the call's plan and what :mod:`.reuse` keeps); :func:`release` lets go of it all.
A buffer serves only calls on the OpenCL context that made it (a process may use several: the
default device is read from the environment at each call); the room bounds all contexts' together.
"""

from __future__ import annotations

import threading
import weakref

from ... import opencl

GRAIN = 32  # a buffer's size rounded up to a multiple of 1/GRAIN of its power of two

_FREE: list = []  # (context's int_ptr, buffer) of the buffers kept between calls
_LOCK = threading.RLock()  # re-entrant: a buffer handed over comes back when its owner is collected, at any time


def rounded(nbytes: int) -> int:
    """``nbytes`` rounded up to a multiple of 1/GRAIN of its power of two (at least 1 byte)."""
    nbytes = max(int(nbytes), 1)
    step = max((1 << (nbytes - 1).bit_length()) // GRAIN, 1)
    return -(-nbytes // step) * step


def held_bytes() -> int:
    """Bytes of the buffers kept now (between calls)."""
    with _LOCK:
        return sum(b.size for _, b in _FREE)


def _fit(buffers: list, room: float) -> list:
    """The (context, buffer) pairs to keep within ``room`` bytes: in order, each that still fits."""
    kept, total = [], 0
    for key, b in buffers:
        if total + b.size <= room:
            kept.append((key, b))
            total += b.size
    return kept


def _largest_first(pairs: list) -> list:
    """(context, buffer) pairs, the largest buffer first."""
    return sorted(pairs, key=lambda kb: -kb[1].size)


def _returned(key: int, buffer) -> None:
    """A buffer handed over (:meth:`Scratch.hand_over`) whose owner was collected: kept for later calls
    (within the room at the next call's trim and give_back)."""
    with _LOCK:
        _FREE.append((key, buffer))


def release() -> None:
    """Let go of every buffer kept between calls."""
    with _LOCK:
        _FREE.clear()


class Scratch:
    """One call's scratch buffers (module docstring), on the context and queue of
    :func:`clsas.opencl.runtime` when it is made."""

    def __init__(self):
        rt = opencl.runtime()
        self.context, self.queue, self.key = rt.context, rt.queue, rt.context.int_ptr
        self.taken = []

    @staticmethod
    def trim(room: float) -> None:
        """Before the call allocates: keep at most ``room`` bytes of the buffers kept between calls."""
        with _LOCK:
            _FREE[:] = _fit(_largest_first(_FREE), room)

    def take(self, nbytes: int):
        """A READ_WRITE device buffer of at least ``nbytes`` (its contents undefined): the smallest
        kept one large enough, else a new one of :func:`rounded` bytes."""
        import pyopencl as cl

        size = rounded(nbytes)
        with _LOCK:
            fits = [kb for kb in _FREE if kb[0] == self.key and kb[1].size >= size]
            pair = min(fits, key=lambda kb: kb[1].size) if fits else None
            if pair is not None:
                _FREE.remove(pair)
        buffer = cl.Buffer(self.context, cl.mem_flags.READ_WRITE, size) if pair is None else pair[1]
        self.taken.append(buffer)
        return buffer

    def recycle(self, buffer) -> None:
        """Make a buffer this call took (and no longer uses: its kernels done) available to the next
        :meth:`take`."""
        self.taken.remove(buffer)
        with _LOCK:
            _FREE.append((self.key, buffer))

    def hand_over(self, buffer, owner) -> None:
        """A buffer this call took goes to ``owner``, an object kept beyond the call (a first-stage
        layout :mod:`.reuse` keeps): it is not given back at the call's end, and serves later calls'
        :meth:`take` once ``owner`` is collected. No kernel reads it then: a call holds the layouts it
        launched with until its queue has finished them (:meth:`.leaves.FirstStage.settle`)."""
        self.taken.remove(buffer)
        weakref.finalize(owner, _returned, self.key, buffer).atexit = False

    def give_back(self, room: float) -> None:
        """At the call's end: once its queue is finished (no kernel of the call still uses them),
        keep its buffers, then those kept before, within ``room`` bytes, the largest first; the
        others are let go."""
        self.queue.finish()
        with _LOCK:
            _FREE[:] = _fit(_largest_first([(self.key, b) for b in self.taken]) + _largest_first(_FREE), room)
        self.taken = []
