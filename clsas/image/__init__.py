"""EchoData -> Image: range compression and the imaging algorithms."""

from .rangecomp import WINDOWS, lfm_replica, matched_filter, range_compress, spectral_window

__all__ = ["WINDOWS", "lfm_replica", "matched_filter", "range_compress", "spectral_window"]
