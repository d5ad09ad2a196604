"""Several moving targets in one echo (Kiang & Kiang 2022 section VII-B, carried across the
receivers: issue 26, deliverable 4).

The paper extracts the targets one by one at one receiver: the strongest SoWVD peak is focused,
its image taken back through the inverse chain and removed, and the next peak searched
(:func:`estimate_receivers`). Each receiver orders its targets by its own strength, which
need not agree (aspect, range, a hull's glints), so the targets found at A, B and C have to be
associated before a velocity can be solved: for every assignment (every order of the targets at
each receiver after the first, and, when positions are given, every order of the first
receiver's against them) each target's receivers are solved together
(:func:`.motion.motion_from_receivers`) and the assignment whose targets fit best is kept: the
least total chi2 of the FM rates against the solutions (:mod:`.consistency`), and with the
positions estimated the joint fit's own misfit (delays, centroids and rates of a target seen by
receivers that saw different targets do not meet in one position and velocity). (n!)^r
assignments for n targets over r receivers: :data:`MAX_TARGETS` bounds n.

Each target is then refocused (:func:`.motion.estimate`'s passes) in the records with the other
targets removed.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging

import numpy as np

from ... import validate
from ...errors import EstimationError
from ...model import EchoData
from . import filters
from .azimuth import compress
from .chain import FOCUS_DB, P0, THRESHOLD_DB, ReceiverEstimate, estimate_records
from .records import Records, records
from .layout import layout_of
from .motion import MotionEstimate, _check_position, _refocus, _repick, announce, check_echo, motion_from_receivers

log = logging.getLogger("clsas")

#: Targets at most (the association tries (n!)^receivers assignments).
MAX_TARGETS = 4


def _positions(positions, n_targets: int):
    if positions is None:
        return None
    if isinstance(positions, (str, bytes)) or not hasattr(positions, "__len__") or len(positions) != n_targets:
        raise ValueError(f"positions must be None or {n_targets} positions (one 3-vector in m per target), "
                         f"got {positions!r}")
    return [_check_position(p) for p in positions]


def _assignments(names: list, n_targets: int, with_positions: bool):
    """Every assignment {name: order}: order[t] is the index in that receiver's list of target t."""
    orders = list(itertools.permutations(range(n_targets)))
    first = orders if with_positions else [tuple(range(n_targets))]
    for head in first:
        for rest in itertools.product(orders, repeat=len(names) - 1):
            yield dict(zip(names, (head,) + rest))


def remove_target(rec: Records, est: ReceiverEstimate, tau_halfwidth: float, eta_cells: float) -> Records:
    """``rec`` without the target of ``est`` (section VII-B): RCMC + RWC + azimuth compression,
    the focused target's window (its extent, :mod:`.extent`, or its tau_c and eta_c without one,
    widened by ``tau_halfwidth`` s in range and ``eta_cells`` azimuth resolution cells
    1 / (|K| T_a) in slow time), then the inverse chain on the window (all three steps are
    unitary phase filters: :mod:`.filters`), subtracted from the record."""
    if not est.focusable:
        raise EstimationError(f"receiver {rec.name}: the target at K_a,eq = {est.fm_rate:.3g} Hz/s does not focus, "
                              "so it cannot be removed to look for the next one")
    shift, cycles = filters.migration(rec.d, rec.f0, est.fm_rate, est.doppler_centroid)
    image, eta_axis = compress(rec, filters.advance(rec.x, rec.fs, shift, cycles), est.fm_rate)
    tau = rec.t0 + np.arange(rec.x.shape[1]) / rec.fs
    cell = 1.0 / (abs(est.fm_rate) * est.aperture)
    ext = est.extent
    eta_lo, eta_hi = (ext.eta if ext is not None else (est.eta_c, est.eta_c))
    tau_lo, tau_hi = (ext.tau if ext is not None else (est.tau_c, est.tau_c))
    window = ((eta_axis >= eta_lo - eta_cells * cell) & (eta_axis <= eta_hi + eta_cells * cell))[:, None] \
        & (tau >= tau_lo - tau_halfwidth) & (tau <= tau_hi + tau_halfwidth)
    target = filters.decompress(np.where(window, image, 0), rec.d, est.fm_rate)
    return dataclasses.replace(rec, x=rec.x - filters.advance(target, rec.fs, -shift, -cycles))


def estimate_receivers(echo: EchoData, receiver: str, n_targets: int = 2, *, p0: float = P0,
                       threshold_db: float = THRESHOLD_DB, focus_db: float | None = FOCUS_DB,
                       tau_halfwidth: float | None = None,
                       eta_cells: float = 20.0) -> list[ReceiverEstimate]:
    """Estimates of ``n_targets`` moving targets in ``receiver``'s echo, strongest SoWVD peak
    first (Kiang & Kiang 2022 section VII-B): each target found is focused, windowed
    (``tau_halfwidth`` s around its extent, default 6 range resolution cells 1 / B; ``eta_cells``
    azimuth resolution cells around its extent: :func:`remove_target`), taken back through the
    inverse chain and removed from the record before the next search. Raises EstimationError when a search finds no peak
    (:func:`estimate_receiver` for the other parameters).
    """
    if isinstance(n_targets, bool) or not isinstance(n_targets, (int, np.integer)) or n_targets < 1:
        raise ValueError(f"n_targets must be an integer >= 1, got {n_targets!r}")
    rec = records(echo, receiver)
    if tau_halfwidth is None:
        tau_halfwidth = 6.0 / echo.waveform.bandwidth
    found = []
    for i in range(n_targets):
        found.append(estimate_records(rec, p0, threshold_db, focus_db))
        if i + 1 < n_targets:
            rec = remove_target(rec, found[-1], tau_halfwidth, eta_cells)
    return found


def estimate_motions(echo: EchoData, n_targets: int = 2, positions=None, receivers=None, *, p0: float = P0,
                     threshold_db: float = THRESHOLD_DB, focus_db: float | None = FOCUS_DB) -> list[MotionEstimate]:
    """The velocity and position of ``n_targets`` moving targets in a raw multistatic echo
    (module docstring): a :class:`.motion.MotionEstimate` per target, in the first receiver's
    order of strength (or the order of ``positions`` when given).

    Parameters
    ----------
    echo : raw EchoData with at least three receivers.
    n_targets : the number of targets, 1 to :data:`MAX_TARGETS`.
    positions : None (each target's position estimated with its velocity) or one position (3,)
        m at slow time 0 per target.
    receivers : names (or indices) to use; default all.
    p0, threshold_db, focus_db : the chain's (:func:`.chain.estimate_receiver`).

    Raises :class:`clsas.errors.EstimationError` naming the receiver when it shows fewer targets,
    or when no assignment of the receivers' targets gives every target a solution.
    """
    names = check_echo(echo, receivers)
    n_targets = validate.integer("estimate_motions n_targets", n_targets, low=1, high=MAX_TARGETS)
    positions = _positions(positions, n_targets)
    found = {name: estimate_receivers(echo, name, n_targets, p0=p0, threshold_db=threshold_db,
                                           focus_db=focus_db) for name in names}
    layout = layout_of(echo)
    best, best_score = None, np.inf
    for assignment in _assignments(names, n_targets, positions is not None):
        score, solved = 0.0, []
        for t in range(n_targets):
            group = {name: found[name][assignment[name][t]] for name in names}
            try:
                est = motion_from_receivers(layout, group, None if positions is None else positions[t], quiet=True)
            except (ValueError, EstimationError, np.linalg.LinAlgError):
                score = np.inf
                break
            score += est.consistency.chi2
            solved.append((est, group))
        log.debug("moving targets: assignment %s, chi2 %.3g", assignment, score)
        if score < best_score:
            best, best_score = (assignment, solved), score
    if best is None:
        raise EstimationError(f"no assignment of the {n_targets} targets found at each of the receivers {names} gives "
                              "every target a solution")
    assignment, solved = best
    log.info("moving targets: receivers' targets associated as %s (total chi2 %.3g)", assignment, best_score)
    out = []
    for t, (est, group) in enumerate(solved):
        others = {name: [found[name][assignment[name][u]] for u in range(n_targets) if u != t] for name in names}
        record_of, estimates = _cleaned(echo, others), dict(group)
        position = None if positions is None else positions[t]
        est = _refocus(layout, est, estimates, record_of, position)
        # a receiver whose FM rate is a cross-term of the targets (both targets can take the same
        # SoWVD peak between their rates) is re-run with the candidate its solution predicts
        out.append(_repick(layout, est, estimates, record_of, position))
        announce(out[-1])
    return out


def _cleaned(echo: EchoData, others: dict):
    """record_of(name): the receiver's record without the targets ``others[name]`` (made once)."""
    cache = {}

    def record_of(name):
        if name not in cache:
            rec = records(echo, name)
            for other in others[name]:
                if other.focusable:
                    rec = remove_target(rec, other, 6.0 / echo.waveform.bandwidth, 20.0)
            cache[name] = rec
        return cache[name]

    return record_of
