"""Scene -> EchoData: echo synthesis (and, with meshes, hull occlusion)."""

from .echo import delays, simulate

__all__ = ["delays", "simulate"]
