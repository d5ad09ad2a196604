"""clsas: synthetic aperture sonar simulation and imaging (OpenCL kernels, NumPy references)."""

from .backend import use_backend
from .data import EchoData, Image
from .image.rangecomp import range_compress
from .io import load, save
from .scene.scenario import (Array, Medium, Platform, PulseSchedule, Recording, Scenario, Sonobuoy,
                             Waveform)

__all__ = [
    "Array", "EchoData", "Image", "Medium", "Platform", "PulseSchedule", "Recording", "Scenario",
    "Sonobuoy", "Waveform", "load", "range_compress", "save", "use_backend",
]
__version__ = "0.1.0"
