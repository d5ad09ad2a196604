"""The io floor: EchoData and Image as files (NetCDF4, zarr) and xarray Datasets; scenarios as TOML.

:mod:`.files` saves and loads (atomic writes, validated reads), :mod:`.dataset` converts to and
from ``xarray.Dataset`` (CF names and units), :mod:`.toml` reads and writes scenario files. It
sits above the model and the scene, whose objects it converts, and below everything that
computes.
"""

from .dataset import from_xarray, to_xarray
from .files import CHUNK_BYTES, load, save
from .toml import load_scenario, scenario_from_toml, scenario_to_toml

__all__ = ["CHUNK_BYTES", "from_xarray", "load", "load_scenario", "save", "scenario_from_toml", "scenario_to_toml",
           "to_xarray"]
