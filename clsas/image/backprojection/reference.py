"""Back-projection's NumPy reference: the definition the kernels (:mod:`.tile_kernel`,
:mod:`.exact_kernel`) are held to, in float64."""

from __future__ import annotations

import numpy as np

from ... import budget
from ...geometry import legs
from ...interp import read_rows
from ...progress import Progress
from .records import PreparedRecords
from .tiles import GridPlan

WORK_BYTES = 400  # the temporaries a pixel-pulse holds at once (tests/test_backprojection.py measures it)


def backproject_reference(records: PreparedRecords, plan: GridPlan, aperture, velocity, stop_and_go, progress,
                          span: tuple[int, int]):
    """The float64 NumPy reference (vectorised over pixels, at most 2^22 pixel-pulses and as many
    as WORK_BYTES each leave within the memory budget at a time): image (M,) complex128. The
    sample index of a delay tau is k = (tau - t0) fs, split into floor(k) and its fraction before
    the records' offset (an integer) is taken off, as the kernels do, so that records prepared
    over any span covering the grid read alike. With
    an ``aperture`` a pixel's contribution is kept when it lies, at q where the pulse meets it,
    within the integration angle: |sin theta| <= sin(aperture / 2), theta the angle of
    transmitter -> pixel off broadside (the x-z plane; y is the nominal heading)."""
    echo = records.echo
    pixels = plan.grid.positions.reshape(-1, 3)
    image = np.zeros(pixels.shape[0], dtype=np.complex128)
    f0, fs = echo.waveform.f0, records.fs
    budget.check_bytes("backproject's NumPy reference (one pixel-pulse at a time)", WORK_BYTES,
                       "use the OpenCL backend")
    work = int(min(2**22, budget.memory_budget() // WORK_BYTES))  # pixel-pulses at a time
    chunk = min(pixels.shape[0], work)
    block = max(1, work // chunk)
    jobs = [(i, h, np.arange(s, min(s + block, span[1]))) for i, h in enumerate(records.receivers)
            for s in range(span[0], span[1], block)]
    bar = Progress(pixels.shape[0] * len(records.receivers) * (span[1] - span[0]), "pixel-pulses",
                   "back-projection (numpy)", progress)
    for i, h, pulses in jobs:
        samples = records.samples(i, pulses).astype(np.complex128)
        for first in range(0, pixels.shape[0], chunk):
            part = slice(first, first + chunk)
            t1, q, t2, _ = legs(echo, h, pulses, pixels[part], velocity, stop_and_go)
            tau = t1 + t2
            k = (tau - echo.t0[h]) * fs
            whole = np.floor(k)
            value = read_rows(samples, whole.astype(np.int64) - records.offset[i], k - whole, records.interp)
            value *= np.exp(2j * np.pi * f0 * tau)
            if aperture is not None:
                d = q - echo.tx_pos[pulses][:, None, :]
                value *= np.abs(d[..., 1] / np.linalg.norm(d, axis=-1)) <= np.sin(aperture / 2)
            image[part] += value.sum(axis=0)
            bar.done(value.size)
    bar.close()
    return image, 0, None
