"""Fast-time spans of records: which fast times a grid reaches in each receiver's records
(:func:`reach`), and which original samples an interpolator reads for a span
(:func:`samples_for_span`). :mod:`.records` prepares those samples; the launcher decides from the
reach whether a call stages held records (:func:`.launcher._stage_worth_it`).
"""

from __future__ import annotations

import numpy as np

from ...model import EchoData
from ..upsample import UPSAMPLE_BLOCK
from .tiles import pixel_box

# samples an interpolator reads around floor(k) (before, after), in samples of the records it reads
INTERP_REACH = {"linear": (0, 1), "sinc8": (3, 4)}
MIN_SAMPLES = 8  # samples of the shortest prepared record (sinc8 loads eight at once)


def _box_distances(a_lo, a_hi, b_lo, b_hi):
    """Smallest and largest distance (m) between points of boxes a and b (..., 3)."""
    gap = np.maximum(0.0, np.maximum(a_lo - b_hi, b_lo - a_hi))
    far = np.maximum(np.abs(a_hi - b_lo), np.abs(b_hi - a_lo))
    return np.sqrt(np.sum(gap * gap, axis=-1)), np.sqrt(np.sum(far * far, axis=-1))


def reach(echo: EchoData, receivers, positions: np.ndarray, target_velocity=None, box=None) -> np.ndarray:
    """(len(receivers), 2) s: a fast-time span per receiver that holds the two-way delay of every
    pixel of ``positions`` (..., 3) m at every pulse whose delay falls inside the record (``box``:
    their :func:`.tiles.pixel_box` when already known, e.g. a GridPlan's; ``positions`` is then
    not read).

    A bound, not the exact extremes: the pixels' bounding box (moved to each pulse by the
    velocity, and grown by |v| times the record's end for the motion during the legs) and the
    box of the receiver's position nodes over the pulse (grown likewise where the record outlasts
    its nodes) give t1 in [d(T, box), D(T, box)] / c and t2 in [d(box_R, box), D(box_R, box)] / c,
    d and D the smallest and largest distances. It holds for the exact non-stop-and-go delays and
    for stop-and-go alike (every position either uses lies in the boxes), at the cost of a few
    samples' slack on a small patch.
    """
    c = echo.medium.sound_speed
    v = np.zeros(3) if target_velocity is None else np.asarray(target_velocity, dtype=np.float64)
    t_end = float(np.max(echo.t0)) + echo.n_samples / echo.fs
    grow = np.linalg.norm(v) * t_end
    box_lo, box_hi = pixel_box(positions) if box is None else box
    lo = box_lo + echo.eta[:, None] * v - grow  # (P, 3)
    hi = box_hi + echo.eta[:, None] * v + grow
    near1, far1 = _box_distances(echo.tx_pos, echo.tx_pos, lo, hi)  # (P,)
    h = np.asarray(receivers, dtype=np.intp)
    nodes, pos = echo.rx_tau[h], echo.rx_pos[h]  # (H, N), (H, P, N, 3): every receiver at once
    r_lo, r_hi = pos[:, :, 0], pos[:, :, 0]  # (H, P, 3): node by node (a reduction over axis 2 is slow)
    for k in range(1, pos.shape[2]):
        r_lo, r_hi = np.minimum(r_lo, pos[:, :, k]), np.maximum(r_hi, pos[:, :, k])
    if nodes.shape[1] > 1:  # rx_position extrapolates linearly beyond the nodes
        speed = np.max(np.linalg.norm(np.diff(pos, axis=2), axis=-1) / np.diff(nodes)[:, None, :], axis=2)  # (H, P)
        extra = speed * (np.maximum(t_end - nodes[:, -1], 0.0) + np.maximum(nodes[:, 0], 0.0))[:, None]
        r_lo, r_hi = r_lo - extra[..., None], r_hi + extra[..., None]
    near2, far2 = _box_distances(r_lo, r_hi, lo, hi)  # (H, P)
    return np.stack([np.min(near1 + near2, axis=1) / c, np.max(far1 + far2, axis=1) / c], axis=1)


def samples_for_span(span: np.ndarray, t0: float, fs: float, n: int, interp: str, factor: int,
               blocks: bool) -> tuple[int, int]:
    """The original samples [first, stop) to prepare for a fast-time span (s): the span's samples
    widened by the interpolator's reach (in original samples, plus one for rounding), clipped to
    the record, and for FFT-upsampled records (``blocks``) rounded out to whole UPSAMPLE_BLOCKs;
    records that are not upsampled are read in place, whole ((0, n): a view costs nothing, a cut
    would be a copy), unless the span misses them."""
    before, after = INTERP_REACH[interp]
    if factor > 1:  # the linear interpolator's two upsampled samples lie within one original sample
        before, after = 0, 1
    first = int(np.floor((span[0] - t0) * fs)) - before - 1
    stop = int(np.ceil((span[1] - t0) * fs)) + after + 2
    first, stop = max(first, 0), min(stop, n)
    if first >= stop:
        return 0, 0
    if factor == 1:
        return 0, n
    if stop - first < MIN_SAMPLES:  # the kernels load whole windows of a record: keep at least one
        stop = min(first + MIN_SAMPLES, n)
        first = max(stop - MIN_SAMPLES, 0)
    if blocks:
        first = first // UPSAMPLE_BLOCK * UPSAMPLE_BLOCK
        stop = min(-(-stop // UPSAMPLE_BLOCK) * UPSAMPLE_BLOCK, n)
    return first, stop
