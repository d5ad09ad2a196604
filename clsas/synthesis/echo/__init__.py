"""Echo synthesis (kernels/echo_paths.cl, kernels/echo_accumulate.cl): :mod:`.pipeline` (simulate, synthesize, delays; the noise in :mod:`.noise`) drives
the NumPy reference (:mod:`.reference`) and the OpenCL launcher (:mod:`.launch`), both reading a
pulse block's reach and weights through :mod:`.blocks`, with the options of :mod:`.options`
resolved into :mod:`.physics`, the kernel's records declared in :mod:`.records`."""

from .options import SynthesisOptions
from .noise import add_noise, signal_power, snr_offset_db
from .pipeline import Synthesis, delays, simulate, synthesize, window_extents
from .reference import accumulate_reference

__all__ = ["Synthesis", "SynthesisOptions", "accumulate_reference", "add_noise", "delays", "signal_power", "simulate",
           "snr_offset_db", "synthesize", "window_extents"]
