"""clsas: synthetic aperture sonar simulation and imaging (OpenCL kernels, NumPy references)."""

from .backend import use_backend

__all__ = ["use_backend"]
__version__ = "0.1.0"
