"""Scene -> EchoData: echo synthesis (and, with meshes, hull occlusion)."""

from .echo import Synthesis, SynthesisOptions, delays, simulate, synthesize

__all__ = ["Synthesis", "SynthesisOptions", "delays", "simulate", "synthesize"]
