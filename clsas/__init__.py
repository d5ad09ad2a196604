"""clsas: synthetic aperture sonar simulation and imaging (OpenCL kernels, NumPy references)."""

from .backend import use_backend
from .data import EchoData, Grid, Image
from .image.backprojection import backproject
from .image.rangecomp import range_compress
from .io import load, save
from .scene.scenario import (
                             Array,
                             Medium,
                             Platform,
                             PulseSchedule,
                             Recording,
                             Scenario,
                             Sonobuoy,
                             Waveform,
)
from .scene.targets import PointTargets
from .simulate import simulate

__all__ = [
    "Array", "EchoData", "Grid", "Image", "Medium", "Platform", "PulseSchedule", "Recording", "Scenario",
    "PointTargets", "Sonobuoy", "Waveform", "backproject", "load", "range_compress", "save", "simulate", "use_backend",
]
__version__ = "0.1.0"
