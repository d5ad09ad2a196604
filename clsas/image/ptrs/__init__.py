"""Numerical point-target-reference-spectrum imaging of multireceiver SAS (Zhang, Tan & Ying 2019)."""

from .imaging import ptrs_image
from .stationary import StationaryPoints, delay, stationary_points

__all__ = ["StationaryPoints", "delay", "ptrs_image", "stationary_points"]
