"""Echo synthesis (kernels/echo.cl): :mod:`.pipeline` (simulate, delays, noise) drives the
NumPy reference and the OpenCL launcher of :mod:`.synth`."""

from .pipeline import add_noise, delays, simulate
from .synth import accumulate_reference

__all__ = ["accumulate_reference", "add_noise", "delays", "simulate"]
