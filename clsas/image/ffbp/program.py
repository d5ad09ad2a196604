"""kernels/ffbp.cl's records, declared once, and its kernels built with them.

- :data:`FRAME` (``ffbp_frame_t``): a polar grid's frame and samples (:func:`frames`);
- :data:`PLANE` (``ffbp_plane_t``): the reference plane normal . X = offset (:func:`plane`);
- :data:`ITEM` (``ffbp_item_t``): a first-stage work-item, sixteen consecutive range samples of one
  row of one leaf's polar grid in one of bp_tile's tiles (:func:`.layout.polar_tiles`);
- bp_tile's pixel fields (``bp_pixels_t``), which ffbp_fields writes for the first stage: the
  record :class:`clsas.image.backprojection.TileKernel` declares for pixels at rest.
"""

from __future__ import annotations

import numpy as np

from ... import opencl
from ...cstruct import declare_all, record_dtype
from ...interp import TAP_ROWS
from ..backprojection import TileKernel

FRAME = record_dtype([("centre", "f8", 3), ("axis", "f8", 3), ("e1", "f8", 3), ("e2", "f8", 3), ("r0", "f8"),
                      ("dr", "f8"), ("v0", "f8"), ("dv", "f8"), ("n_r", "i4"), ("n_v", "i4")])
PLANE = record_dtype([("normal", "f8", 3), ("offset", "f8")])
ITEM = record_dtype([("leaf", "i4"), ("row", "i4"), ("sample", "i4"), ("tile", "i4")])
PREAMBLE = declare_all({"ffbp_frame_t": FRAME, "ffbp_plane_t": PLANE, "ffbp_item_t": ITEM,
                        "bp_pixels_t": TileKernel("linear").pixels})


def kernel(name: str, taps: int = 8, **defines):
    """Kernel ``name`` of kernels/ffbp.cl for the merge interpolator's ``taps`` (and more defines)."""
    return opencl.kernel("ffbp", name, preamble=PREAMBLE, defines={"TAPS": taps, "TAP_ROWS": TAP_ROWS, **defines})


def frames(grids: list) -> np.ndarray:
    """The frames (len(grids),) :data:`FRAME` of polar grids (:class:`.polar.PolarGrid`)."""
    out = np.zeros(len(grids), FRAME)
    for name in FRAME.names:
        out[name] = [getattr(g, name) for g in grids]
    return out


def plane(reference) -> np.void:
    """The reference plane (:class:`.polar.Plane`) as a :data:`PLANE`."""
    out = np.zeros((), PLANE)
    out["normal"], out["offset"] = reference.normal, reference.offset
    return out[()]
