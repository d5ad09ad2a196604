"""Reading a clsas file: what is at the path, its declared sizes against the memory budget, its
chunks, then its arrays; every failure a DataFileError naming the file.

What :func:`clsas.load` accepts: a regular file holding NetCDF4/HDF5 (checked by its signature
before any library opens it), or a folder holding a zarr store whose every chunk is present (a
missing chunk would read as zeros). A FIFO, a socket or a device is refused without being read
(reading a FIFO would block until something writes to it).
"""

from __future__ import annotations

import contextlib
import json
import os
import stat
from pathlib import Path

import numpy as np

from ... import budget
from ...errors import DataFileError, MemoryBudgetError
from ...model import EchoData, Image, Medium, Waveform
from ..dataset import from_xarray
from .write import zarr_limits

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: bytes in memory per declared byte while a file is read (its arrays, once), and the readers'
#: own buffers (decompressed chunks); tests/test_hardening_files.py measures both
LOAD_OVERHEAD = 1.1
LOAD_WORKING_BYTES = 32 << 20
_LEGACY_ECHO_ARRAYS = ("eta", "t0", "tx_pos", "rx_pos", "rx_tau")


def kind_of(path: Path) -> str:
    """``"zarr"`` (a folder) or ``"hdf5"`` (a regular file with the HDF5 signature), looked at
    without blocking; FileNotFoundError or DataFileError naming the path otherwise."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO opens without a writer and is not read
    except FileNotFoundError:
        raise FileNotFoundError(f"no such clsas file: {path}") from None
    except IsADirectoryError:  # some systems refuse to open folders
        return "zarr"
    except OSError as err:
        raise DataFileError(f"{path}: cannot be opened ({err.strerror})") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            return "zarr"
        if not stat.S_ISREG(info.st_mode):
            raise DataFileError(f"{path}: not a regular file or a zarr store (a FIFO, socket or device); clsas "
                                "reads files and stores only")
        head = os.read(fd, len(HDF5_SIGNATURE))
    finally:
        os.close(fd)
    if head != HDF5_SIGNATURE:
        what = "empty" if info.st_size == 0 else f"starts with {head!r}"
        raise DataFileError(f"{path}: not a NetCDF4/HDF5 clsas file ({what}; expected the HDF5 signature)")
    return "hdf5"


def read(path: Path):
    """The EchoData or Image at ``path`` (see the module docstring)."""
    if kind_of(path) == "zarr":
        if not ((path / "zarr.json").is_file() or (path / ".zgroup").is_file()):
            raise DataFileError(f"{path}: a folder that is not a zarr store (no zarr.json or .zgroup)")
        check_chunks(path)
        return _read_dataset(path, "zarr")
    import h5py

    try:
        with h5py.File(path, "r") as f:
            attrs = dict(f.attrs)
            if "clsas_kind" not in attrs and attrs.get("kind") in ("EchoData", "Image"):
                return _read_legacy(path, f)
    except (DataFileError, MemoryBudgetError):
        raise
    except Exception as err:  # noqa: BLE001 - h5py raises OSError, RuntimeError, KeyError ... on damage
        raise _damaged(path, "cannot be read as HDF5", err) from err
    if "clsas_kind" not in attrs:
        raise DataFileError(f"{path}: an HDF5 file without a clsas_kind attribute: not a clsas file "
                            f"(its attributes: {sorted(attrs)[:8]})")
    return _read_dataset(path, "h5netcdf")


def _damaged(path: Path, what: str, err: BaseException) -> DataFileError:
    size = f"{path.stat().st_size} bytes; " if path.is_file() else ""
    return DataFileError(f"{path}: {what} ({size}truncated or damaged?): {type(err).__name__}: "
                         f"{' '.join(str(err).split())[:300]}")


def open_dataset(path: Path, engine: str):
    """The file as a lazily read xarray.Dataset, values as stored (no CF decoding)."""
    import xarray as xr

    kwargs = {"consolidated": True} if engine == "zarr" else {}
    return xr.open_dataset(path, engine=engine, decode_cf=False, mask_and_scale=False, **kwargs)


def _read_dataset(path: Path, engine: str):
    try:
        ds = open_dataset(path, engine)
    except Exception as err:  # noqa: BLE001 - any failure to open is the file's fault here
        raise _damaged(path, f"cannot be opened as a {engine} dataset", err) from err
    with ds, (zarr_limits() if engine == "zarr" else contextlib.nullcontext()):
        check_budget(path, {name: _nbytes(var.shape, var.dtype.itemsize) for name, var in ds.variables.items()})
        try:
            return from_xarray(ds)
        except MemoryBudgetError:
            raise
        except (ValueError, TypeError, KeyError) as err:
            raise DataFileError(f"{path}: {' '.join(str(err).split())}") from err
        except Exception as err:  # noqa: BLE001 - the readers raise OSError, RuntimeError ... on damage
            raise _damaged(path, "reading its arrays failed", err) from err


def _nbytes(shape, itemsize: int) -> float:
    return float(np.prod(shape, dtype=np.float64)) * itemsize


def check_budget(path: Path, declared: dict) -> None:
    """Refuse a file whose arrays declare more than the memory budget allows (MemoryBudgetError
    naming the file and its largest array), before reading any of them."""
    total = sum(declared.values())
    biggest = max(declared, key=declared.get) if declared else "-"
    budget.check_bytes(f"load {path}: its arrays declare {total / 2**30:.3g} GiB ({biggest}: "
                       f"{declared.get(biggest, 0) / 2**30:.3g} GiB) and reading them",
                       LOAD_OVERHEAD * total + LOAD_WORKING_BYTES,
                       "if the file is genuine, load it under a larger budget")


def check_chunks(path: Path) -> None:
    """DataFileError naming the store, the array and a chunk when a chunk of any array is
    missing or is not a regular file (zarr would read a missing chunk as the fill value)."""
    for name, meta in _arrays(path):
        shape, chunks = meta["shape"], meta["chunks"]
        counts = [-(-n // c) if n else 0 for n, c in zip(shape, chunks)]
        if not shape:
            counts = []
        keys = (meta["key"](index) for index in np.ndindex(*counts))
        folder = path / name
        for key in keys:
            if not (folder / key).is_file():
                raise DataFileError(f"{path}: the zarr store lacks chunk {key!r} of {name!r} (deleted or not "
                                    "written): it is incomplete and would read as zeros")


def _arrays(path: Path):
    """(name, {shape, chunks, key(index) -> chunk file}) of every array of a zarr v2 or v3 store."""
    if (path / ".zmetadata").is_file():
        entries = _json(path, ".zmetadata").get("metadata", {})
        arrays = {k[: -len("/.zarray")]: v for k, v in entries.items() if k.endswith(".zarray")}
    elif (path / ".zgroup").is_file():
        arrays = {p.parent.name: _json(path, f"{p.parent.name}/.zarray") for p in path.glob("*/.zarray")}
    else:
        arrays = {}
        for p in path.glob("*/zarr.json"):
            meta = _json(path, f"{p.parent.name}/zarr.json")
            if meta.get("node_type") == "array":
                arrays[p.parent.name] = meta
    for name, meta in arrays.items():
        try:
            if "chunk_grid" in meta:  # zarr v3
                chunks = meta["chunk_grid"]["configuration"]["chunk_shape"]
                encoding = meta.get("chunk_key_encoding", {})
                sep = encoding.get("configuration", {}).get("separator", "/")
                prefix = "c" + sep if encoding.get("name", "default") == "default" else ""
            else:
                chunks, sep, prefix = meta["chunks"], meta.get("dimension_separator") or ".", ""
            shape = [int(n) for n in meta["shape"]]
            chunks = [int(c) for c in chunks]
        except (KeyError, TypeError, ValueError) as err:
            raise DataFileError(f"{path}: the zarr metadata of {name!r} is malformed ({err})") from None
        if len(chunks) != len(shape) or any(c < 1 for c in chunks):
            raise DataFileError(f"{path}: the zarr metadata of {name!r} is malformed (chunks {chunks} for shape {shape})")
        scalar_key = "c" if prefix else "0"
        yield name, {"shape": shape, "chunks": chunks,
                     "key": (lambda index, s=sep, p=prefix, z=scalar_key: p + s.join(map(str, index)) if index else z)}


def _json(path: Path, name: str) -> dict:
    try:
        value = json.loads((path / name).read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise DataFileError(f"{path}: its zarr metadata {name} cannot be read ({err})") from None
    if not isinstance(value, dict):
        raise DataFileError(f"{path}: its zarr metadata {name} is not a JSON object")
    return value


def _read_legacy(path: Path, f):
    """clsas 0.1's HDF5 layout (``kind`` attribute, ``/data``, geometry datasets or ``/axes/<dim>``)."""
    import h5py

    check_budget(path, {name: _nbytes(obj.shape, obj.dtype.itemsize) for name, obj in _walk(f, h5py)})
    try:
        kind = f.attrs["kind"]
        provenance = json.loads(f.attrs["provenance"])
        if kind == "EchoData":
            return EchoData(
                data=f["data"][()], **{name: f[name][()] for name in _LEGACY_ECHO_ARRAYS},
                fs=float(f.attrs["fs"]), waveform=Waveform(**json.loads(f.attrs["waveform"])),
                medium=Medium(**json.loads(f.attrs["medium"])), receivers=tuple(json.loads(f.attrs["receivers"])),
                compressed=bool(f.attrs["compressed"]), provenance=provenance)
        dims = tuple(json.loads(f.attrs["dims"]))
        return Image(data=f["data"][()], dims=dims, axes={name: f[f"axes/{name}"][()] for name in dims},
                     provenance=provenance, positions=f["positions"][()] if "positions" in f else None)
    except MemoryBudgetError:
        raise
    except (KeyError, ValueError, TypeError, json.JSONDecodeError) as err:
        raise DataFileError(f"{path}: a clsas 0.1 HDF5 file with a missing or malformed item: {err}") from err


def _walk(group, h5py):
    for name, obj in group.items():
        if isinstance(obj, h5py.Dataset):
            yield f"{group.name.rstrip('/')}/{name}", obj
        elif isinstance(obj, h5py.Group):
            yield from _walk(obj, h5py)
