"""Save and load EchoData and Image as HDF5 files with named axes (h5py).

Layout of an EchoData file (``kind = "EchoData"``)::

    /data      complex64 (rx, pulse, sample)   dims named by its DIMENSION_LIST scales
    /eta       float64 (pulse,)   emission times, s   (dimension scale "pulse")
    /t0        float64 (rx,)      fast time of sample 0, s (dimension scale "rx")
    /tx_pos    float64 (pulse, 3)
    /rx_pos    float64 (rx, pulse, node, 3)
    /rx_tau    float64 (rx, node)
    attrs: kind, clsas_version, fs, compressed, receivers (JSON), waveform (JSON),
           medium (JSON), provenance (JSON)

An Image file (``kind = "Image"``) holds ``/data`` with one coordinate dataset per dim under
``/axes/<dim>`` attached as an HDF5 dimension scale (so netCDF-aware tools such as xarray show
named axes), optional ``/positions``, and ``dims`` and ``provenance`` attributes.

Provenance is stored as JSON; values that JSON cannot hold (arrays) are stored as lists.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from .data import EchoData, Image
from .scene.scenario import Medium, Waveform

_ECHO_ARRAYS = ("eta", "t0", "tx_pos", "rx_pos", "rx_tau")


def _h5py():
    import h5py

    return h5py


def _to_json(value) -> str:
    def default(obj):
        if isinstance(obj, np.ndarray):
            return obj.tolist()
        if isinstance(obj, np.generic):
            return obj.item()
        if dataclasses.is_dataclass(obj):
            return dataclasses.asdict(obj)
        raise TypeError(f"cannot store {type(obj).__name__} in a clsas file")

    return json.dumps(value, default=default)


def _version() -> str:
    from . import __version__

    return __version__


def save(obj: EchoData | Image, path: str | Path) -> Path:
    """Write ``obj`` (EchoData or Image) to the HDF5 file ``path`` (overwritten); returns the path."""
    h5py = _h5py()
    path = Path(path)
    if isinstance(obj, EchoData):
        with h5py.File(path, "w") as f:
            f.attrs["kind"] = "EchoData"
            f.attrs["clsas_version"] = _version()
            f.attrs["fs"] = obj.fs
            f.attrs["compressed"] = obj.compressed
            f.attrs["receivers"] = json.dumps(list(obj.receivers))
            f.attrs["waveform"] = _to_json(dataclasses.asdict(obj.waveform))
            f.attrs["medium"] = _to_json(dataclasses.asdict(obj.medium))
            f.attrs["provenance"] = _to_json(obj.provenance)
            data = f.create_dataset("data", data=obj.data, chunks=True)
            for name in _ECHO_ARRAYS:
                f.create_dataset(name, data=getattr(obj, name))
            f["t0"].make_scale("rx")
            f["eta"].make_scale("pulse")
            data.dims[0].attach_scale(f["t0"])
            data.dims[1].attach_scale(f["eta"])
            for i, name in enumerate(EchoData.dims):
                data.dims[i].label = name
        return path
    if isinstance(obj, Image):
        with h5py.File(path, "w") as f:
            f.attrs["kind"] = "Image"
            f.attrs["clsas_version"] = _version()
            f.attrs["dims"] = json.dumps(list(obj.dims))
            f.attrs["provenance"] = _to_json(obj.provenance)
            data = f.create_dataset("data", data=obj.data, chunks=True)
            for i, name in enumerate(obj.dims):
                axis = f.create_dataset(f"axes/{name}", data=obj.axes[name])
                axis.make_scale(name)
                data.dims[i].attach_scale(axis)
                data.dims[i].label = name
            if obj.positions is not None:
                f.create_dataset("positions", data=obj.positions)
        return path
    raise TypeError(f"save() takes an EchoData or an Image, got {type(obj).__name__}")


def load(path: str | Path) -> EchoData | Image:
    """Read an EchoData or Image written by :func:`save`."""
    h5py = _h5py()
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such clsas file: {path}")
    with h5py.File(path, "r") as f:
        kind = f.attrs.get("kind")
        if kind == "EchoData":
            return EchoData(
                data=f["data"][()],
                **{name: f[name][()] for name in _ECHO_ARRAYS},
                fs=float(f.attrs["fs"]),
                waveform=Waveform(**json.loads(f.attrs["waveform"])),
                medium=Medium(**json.loads(f.attrs["medium"])),
                receivers=tuple(json.loads(f.attrs["receivers"])),
                compressed=bool(f.attrs["compressed"]),
                provenance=json.loads(f.attrs["provenance"]),
            )
        if kind == "Image":
            dims = tuple(json.loads(f.attrs["dims"]))
            return Image(
                data=f["data"][()],
                dims=dims,
                axes={name: f[f"axes/{name}"][()] for name in dims},
                provenance=json.loads(f.attrs["provenance"]),
                positions=f["positions"][()] if "positions" in f else None,
            )
    raise ValueError(f"{path} is not a clsas file (its 'kind' attribute is {kind!r}; expected 'EchoData' or 'Image')")
