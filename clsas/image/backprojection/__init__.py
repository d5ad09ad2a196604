"""Time-domain back-projection for any geometry: the package that owns the bp_tile kernel.

:mod:`.direct` is the public call (NumPy reference and OpenCL launcher), :mod:`.records` the
range-compressed records prepared for it (upsampled, cut to the span a grid reaches), and
:mod:`.tiles` the pixel tiles whose references keep float32 geometry within the phase budget.
"""

from .direct import backproject
from .records import PreparedRecords, prepare

__all__ = ["PreparedRecords", "backproject", "prepare"]
