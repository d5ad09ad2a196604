"""Echo synthesis (kernels/echo.cl): :mod:`.pipeline` (simulate, synthesize, delays, noise) drives
the NumPy reference and the OpenCL launcher of :mod:`.synth`, with the options of :mod:`.options`."""

from .options import SynthesisOptions
from .pipeline import Synthesis, add_noise, delays, signal_power, simulate, synthesize
from .synth import accumulate_reference

__all__ = ["Synthesis", "SynthesisOptions", "accumulate_reference", "add_noise", "delays", "signal_power", "simulate",
           "synthesize"]
