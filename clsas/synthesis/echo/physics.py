"""What the paths of one synthesis carry: :class:`Physics` (the options, resolved for a scenario)
and which scatterers lie on the seabed (:func:`on_floor`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene.targets import Scatterers
from ..propagation import BOTTOM, DIRECT, BandAbsorption
from .compressed import CompressedResponse
from .grid import GridPlan
from .options import SynthesisOptions


MISMATCH_BOUND = 0.1  # rad: the largest chirp mismatch the compressed taps are written for


@dataclass(frozen=True)
class Physics:
    """The :class:`SynthesisOptions` of a synthesis (``options``: stop-and-go, intra-pulse Doppler)
    resolved for one scenario: the path ``kinds`` (direct first), ``absorption`` (None: none),
    ``spreading`` (the "auto" resolved), ``moving`` (some scatterer has a velocity); ``response``:
    synthesis into the range-compressed domain with these tabulated responses (None: raw echoes);
    ``floor_first``: the index of the first seafloor facet among the scatterers (None: none;
    :func:`on_floor`). ``extended``: the paths need their own chirp and envelope. ``grid``: the raw
    records are made by the grid route (:class:`.grid.GridPlan`; None: each path's samples).
    ``doppler_mismatch``: rad, a bound of |q| h^2, the chirp mismatch of a path with intra-pulse
    Doppler over half the pulse (:mod:`.compressed`): pi (2 v / c) B T / 2 with v the largest
    scatterer speed plus the platform's."""

    options: SynthesisOptions
    kinds: tuple = (DIRECT,)
    absorption: BandAbsorption | None = None
    spreading: bool = False
    moving: bool = False
    response: CompressedResponse | None = None
    floor_first: int | None = None
    grid: GridPlan | None = None
    doppler_mismatch: float = 0.0

    @property
    def stop_and_go(self) -> bool:
        return self.options.stop_and_go

    @property
    def intra_pulse(self) -> str:
        """"none", "moving" or "all" (:func:`clsas.simulate`)."""
        return self.options.intra_pulse

    @property
    def doppler(self) -> bool:
        """Some path gets an in-pulse delay law."""
        return not self.stop_and_go and (self.intra_pulse == "all" or (self.intra_pulse == "moving" and self.moving))

    @property
    def extended(self) -> bool:
        return self.doppler or self.absorption is not None or len(self.kinds) > 1

    @property
    def compress_raw(self) -> bool:
        """Synthesis into the compressed domain takes the raw route (the raw echo, then the matched
        filter: :mod:`.compressed`): its T fs samples a path cost less than the response's taps,
        (2 L + 2) per table and 3 tables for paths with their own laws; or the paths have their own
        chirp and its mismatch (``doppler_mismatch``) exceeds MISMATCH_BOUND rad, beyond which the
        taps' second-order series is not exact enough (reviewer's E1: -32 dB at 2.2 m/s radial
        on Huang's BT = 200)."""
        if self.response is None:
            return False
        if self.doppler and self.doppler_mismatch > MISMATCH_BOUND:
            return True  # the taps' second-order series would be off by ~ the mismatch
        return (3 if self.extended else 1) * (2 * self.response.taps + 2) > 2 * self.response.half_len

    @property
    def writes_taps(self) -> bool:
        """Synthesis into the compressed domain writes each path's compressed response (its taps)."""
        return self.response is not None and not self.compress_raw

    @staticmethod
    def touches_floor(kind) -> bool:
        """A leg of ``kind`` meets the seabed last before (or first after) the scatterer."""
        return any(bool(leg.planes) and leg.planes[-1].law == BOTTOM for leg in (kind.out, kind.back))


def on_floor(scat: Scatterers, floor_first: int | None, kinds) -> np.ndarray:
    """bool (N,): the scatterers that lie on the seabed (its facets, from ``floor_first``, and any
    scatterer within 1 mm of its mean plane or below it at t = 0): a path that "bounces" off the
    seabed right next to them is their direct path again, so those kinds are dark for them."""
    out = np.zeros(scat.count, dtype=bool)
    if floor_first is not None:
        out[floor_first:] = True
    for kind in kinds:
        for plane in kind.out.planes + kind.back.planes:
            if plane.law == BOTTOM:
                out |= (scat.p0 - plane.origin) @ plane.normal <= 1e-3
    return out

