"""clsas: synthetic aperture sonar simulation and imaging (OpenCL kernels, NumPy references)."""

from . import distributed
from .backend import use_backend
from .budget import memory_budget, use_memory_budget
from .data import EchoData, Grid, Image
from .errors import EstimationError
from .estimate.moving import estimate as estimate_motion
from .estimate.moving import focus as focus_moving
from .image.backprojection import backproject
from .image.csa import chirp_scaling
from .image.ffbp import ffbp
from .image.inclined import correct_inclined_array
from .image.multireceiver import pca_record
from .image.omegak import omega_k
from .image.ptrs import ptrs_image
from .image.rangecomp import range_compress
from .image.rda import range_doppler
from .image.record import line_record
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
from .scene.toml import load_scenario
from .simulate import simulate

__all__ = [
                             "Array",
                             "EchoData",
                             "EstimationError",
                             "Grid",
                             "Image",
                             "Medium",
                             "Platform",
                             "PointTargets",
                             "PulseSchedule",
                             "Recording",
                             "Scenario",
                             "Sonobuoy",
                             "Waveform",
                             "backproject",
                             "chirp_scaling",
                             "correct_inclined_array",
                             "distributed",
                             "estimate_motion",
                             "ffbp",
                             "focus_moving",
                             "line_record",
                             "load",
                             "load_scenario",
                             "memory_budget",
                             "omega_k",
                             "pca_record",
                             "ptrs_image",
                             "range_compress",
                             "range_doppler",
                             "save",
                             "simulate",
                             "use_backend",
                             "use_memory_budget",
]
__version__ = "0.1.0"
