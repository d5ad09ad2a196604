"""clsas: synthetic aperture sonar simulation and imaging (OpenCL kernels, NumPy references).

The public API, re-exported. Names are imported on first use (PEP 562), so that ``import
clsas`` and the ``clsas`` command start in a fraction of the time the whole stack (scipy's
interpolate, optimize and special modules) takes to import; ``clsas.X`` and ``from clsas
import X`` work as for eager imports.
"""

import importlib
import importlib.util

from .version import __version__

#: public name -> (module, attribute; None for the module itself)
_EXPORTS = {
    "Array": (".scene.scenario", "Array"),
    "absorption_db_per_km": (".synthesis.propagation", "absorption_db_per_km"),
    "EchoData": (".model", "EchoData"),
    "EstimationError": (".errors", "EstimationError"),
    "Grid": (".model", "Grid"),
    "Image": (".model", "Image"),
    "Medium": (".model", "Medium"),
    "Platform": (".scene.scenario", "Platform"),
    "PointTargets": (".scene.targets", "PointTargets"),
    "PulseSchedule": (".scene.scenario", "PulseSchedule"),
    "Recording": (".scene.scenario", "Recording"),
    "Scenario": (".scene.scenario", "Scenario"),
    "SeaSurface": (".scene.surface", "SeaSurface"),
    "Seafloor": (".scene.seafloor", "Seafloor"),
    "Sediment": (".scene.seafloor", "Sediment"),
    "Sonobuoy": (".scene.scenario", "Sonobuoy"),
    "Waveform": (".model", "Waveform"),
    "backproject": (".image.backprojection", "backproject"),
    "chirp_scaling": (".image.csa", "chirp_scaling"),
    "correct_inclined_array": (".image.inclined", "correct_inclined_array"),
    "distributed": (".distributed", None),
    "estimate_motion": (".estimate.moving", "estimate"),
    "estimate_motions": (".estimate.moving", "estimate_motions"),
    "ffbp": (".image.ffbp", "ffbp"),
    "focus_moving": (".estimate.moving", "focus"),
    "line_record": (".image.record", "line_record"),
    "from_xarray": (".io", "from_xarray"),
    "load": (".io", "load"),
    "load_scenario": (".io", "load_scenario"),
    "memory_budget": (".budget", "memory_budget"),
    "nonlinear_chirp_scaling": (".image.ncs", "nonlinear_chirp_scaling"),
    "omega_k": (".image.omegak", "omega_k"),
    "pca_record": (".image.multireceiver", "pca_record"),
    "ptrs_image": (".image.ptrs", "ptrs_image"),
    "range_compress": (".image.rangecomp", "range_compress"),
    "range_doppler": (".image.rda", "range_doppler"),
    "save": (".io", "save"),
    "scenario_to_toml": (".io", "scenario_to_toml"),
    "simulate": (".synthesis", "simulate"),
    "snr_offset_db": (".synthesis.echo.noise", "snr_offset_db"),
    "to_xarray": (".io", "to_xarray"),
    "use_backend": (".backend", "use_backend"),
    "use_memory_budget": (".budget", "use_memory_budget"),
}

__all__ = sorted(_EXPORTS)

def __getattr__(name: str):
    """A public name (imported now and kept), or a submodule (``clsas.backend``, ``clsas.metrics``)."""
    if name in _EXPORTS:
        module, attr = _EXPORTS[name]
        value = importlib.import_module(module, __name__)
        value = value if attr is None else getattr(value, attr)
    elif not name.startswith("__") and importlib.util.find_spec(f"{__name__}.{name}") is not None:
        value = importlib.import_module(f".{name}", __name__)
    else:
        raise AttributeError(f"module 'clsas' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
