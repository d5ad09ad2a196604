"""EchoData -> Image: range compression and the imaging algorithms."""

from .backprojection import backproject
from .rangecomp import (
           WINDOWS,
           lfm_replica,
           matched_filter,
           range_compress,
           spectral_window,
           upsample_records,
)

__all__ = ["WINDOWS", "backproject", "lfm_replica", "matched_filter", "range_compress", "spectral_window",
           "upsample_records"]
