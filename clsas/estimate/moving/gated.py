"""Step 2 of the moving-target chain (:mod:`.chain`, Kiang & Kiang 2022 eqs. 10-14): the rate
search on the RFRT gated to where the echo stands out of the noise.

The gate is first :mod:`.trace`'s cells that stand out (each range cell over a few pulses); where
its SoWVD maps score below the threshold, the bright scatterers of the trace followed over the
whole record (:mod:`.track`), from the middle :data:`.track.SEED` pulses and then from the
shorter :data:`.track.SHORT_SEED`. The followed traces also give the target's azimuth FM rate
from their curvature (:func:`.track.trace_rate`), which :func:`.chain.estimate_records` tries
when the SoWVD's best candidate is not confirmed by its focus.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from ...errors import EstimationError
from . import trace, track
from .records import UPSAMPLE, Records
from .sowvd import RateSearch, rate_search, rfrt

log = logging.getLogger("clsas")

#: Default SoWVD peak-to-background threshold: the score of :func:`.sowvd.rate_search` (20 log10
#: of each map's peak over its median, averaged over the maps), dB; noise-only maps score below
#: it (tests/test_moving_chain.py).
THRESHOLD_DB = 26.0
#: Fraction of the pulses in which the echo must stand out of the noise (:mod:`.trace`); at
#: -25 dB SNR it does in ~10 % of Table I's pulses, at -15 dB in all of them.
MIN_COVERAGE = 0.25


def _followed_search(rec: Records, p0: float, seed: int) -> RateSearch | None:
    """The rate search on the RFRT gated on the bright cells of the trace followed from the middle
    ``seed`` pulses of ``rec`` (:func:`.track.bright_gate`), carrying the trace's tangent and the
    rate its curvature gives (:func:`.track.trace_rate`); None when no cell of the followed trace
    stands out."""
    bright = track.bright_gate(rec.x, UPSAMPLE, seed)
    if bright is None:
        return None
    # nan when the trace was followed as a straight line only (:attr:`.track.FollowedTrace.curvature`)
    rate = track.trace_rate(bright.curvature, rec.f0, rec.prf, rec.fs)
    return dataclasses.replace(rate_search(rfrt(rec.x, bright.gate), rec.prf, p0),
                               trace_line=(bright.slope, bright.sample), trace_rates=(rate,) if math.isfinite(rate) else ())


def sowvd(rec: Records, p0: float, threshold_db: float = THRESHOLD_DB) -> RateSearch:
    """Step 2: the gated RFRT (eqs. 10-11) of ``rec`` and the modified SoWVD maps (eqs. 12-14) at
    lag offsets from ``p0`` whose agreement gives K_a,eq (:func:`.sowvd.rate_search`). The gate
    is :mod:`.trace`'s cells that stand out of the noise; when its maps score below
    ``threshold_db`` (or it covers too few pulses) the RFRT gated on the bright scatterers of
    the trace followed over the whole record (:func:`.track.bright_gate`, from its seed stretch and,
    when that scores below ``threshold_db`` too, from the shorter one) is tried too and the
    best-scoring search kept, with the rates the followed traces' curvatures give
    (:attr:`.sowvd.RateSearch.trace_rates`, seed stretch first). EstimationError when the echo
    stands out of the noise in too few pulses and the followed trace holds no target either."""
    gate = trace.support(rec.x, UPSAMPLE)
    coverage = float(np.mean(gate.any(axis=1)))
    search = None
    if coverage >= MIN_COVERAGE:
        search = rate_search(rfrt(rec.x, trace.band(rec.x, gate, UPSAMPLE)), rec.prf, p0)
        if search.score_db >= threshold_db:
            return search
    followed = _followed_search(rec, p0, track.SEED)
    rates = () if followed is None else followed.trace_rates
    # the shorter seed when the first does not hold a target (a trace that walks fast: :data:`.track.SHORT_SEED`)
    if (followed is None or followed.score_db < threshold_db) and rec.x.shape[0] > track.SHORT_SEED:
        shorter = _followed_search(rec, p0, track.SHORT_SEED)
        if shorter is not None:
            rates += shorter.trace_rates
            if followed is None or shorter.score_db > followed.score_db:
                followed = shorter
    if search is None and (followed is None or followed.score_db < threshold_db):
        raise EstimationError(f"receiver {rec.name}: the echo stands out of the noise in {100 * coverage:.0f} % of "
                              f"the pulses < {100 * MIN_COVERAGE:.0f} %"
                              + ("" if followed is None else f", and the SoWVD on its followed trace scores "
                                 f"{followed.score_db:.1f} dB < {threshold_db:.1f} dB"))
    if followed is not None and (search is None or followed.score_db > search.score_db):
        log.info("receiver %s: SoWVD on the followed trace's bright cells: %.1f dB (cell gate: %s)", rec.name,
                 followed.score_db, "-" if search is None else f"{search.score_db:.1f} dB")
        search = followed
    if rates:
        log.info("receiver %s: the followed traces' curvature reads K = %s Hz/s", rec.name,
                 ", ".join(f"{k:.5g}" for k in rates))
    return dataclasses.replace(search, trace_rates=rates)
