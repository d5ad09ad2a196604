"""Time-domain back-projection for any geometry: the package that owns the bp_tile kernel.

:mod:`.direct` is the public call, :mod:`.records` the range-compressed records prepared for it
(upsampled, cut to the span a grid reaches), :mod:`.tile_kernel` the object that owns bp_tile
(:class:`TileKernel`: options, records, references, pixel fields, launch), :mod:`.tiles` the
pixel tiles whose references keep its float32 geometry within the phase budget, :mod:`.exact_kernel`
the exact double kernel bp_block, :mod:`.launcher` the OpenCL launches and :mod:`.reference`
the NumPy reference.
"""

from .direct import backproject
from .records import PreparedRecords, prepare
from .tile_kernel import TileKernel
from .tiles import GridPlan

__all__ = ["GridPlan", "PreparedRecords", "TileKernel", "backproject", "prepare"]
