"""Several moving targets in one echo (Kiang & Kiang 2022 section VII-B, carried across the
receivers: issue 26, deliverable 4).

The paper extracts the targets one by one at one receiver: the strongest SoWVD peak is focused,
its image taken back through the inverse chain and removed, and the next peak searched
(:func:`.chain.estimate_receivers`). Each receiver orders its targets by its own strength, which
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

import itertools
import logging

import numpy as np

from ... import validate
from ...errors import EstimationError
from ...model import EchoData
from .chain import P0, THRESHOLD_DB, estimate_receivers, records, remove_target
from .layout import layout_of
from .motion import MotionEstimate, _check_position, _refocus, announce, check_echo, motion_from_receivers

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


def estimate_motions(echo: EchoData, n_targets: int = 2, positions=None, receivers=None, *, p0: float = P0,
                     threshold_db: float = THRESHOLD_DB) -> list[MotionEstimate]:
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
    p0, threshold_db : the chain's (:func:`.chain.estimate_receiver`).

    Raises :class:`clsas.errors.EstimationError` naming the receiver when it shows fewer targets,
    or when no assignment of the receivers' targets gives every target a solution.
    """
    names = check_echo(echo, receivers)
    n_targets = validate.integer("estimate_motions n_targets", n_targets, low=1, high=MAX_TARGETS)
    positions = _positions(positions, n_targets)
    found = {name: estimate_receivers(echo, name, n_targets, p0=p0, threshold_db=threshold_db) for name in names}
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
        out.append(_refocus(layout, est, dict(group), _cleaned(echo, others), None if positions is None else positions[t]))
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
