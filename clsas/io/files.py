"""Save and load EchoData and Image as NetCDF4 (h5netcdf) or zarr files that xarray reads.

``save(obj, "run.nc")`` writes NetCDF4/HDF5 through h5netcdf; a path ending in ``.zarr``
writes a zarr store (a folder). The layout (named dims, a coordinate for every dim, CF
``units`` and ``long_name``, provenance as JSON attributes) is :mod:`clsas.io.dataset`'s, so
``xarray.open_dataset(path)`` shows the data as it is in clsas. Arrays are chunked (about
:data:`CHUNK_BYTES` a chunk) and compressed (gzip level 1 with byte shuffle in NetCDF, zarr's
default zstd in zarr).

Safety: :func:`save` writes a temporary file beside the target, reads it back and compares it
with what was meant to be written, and only then renames it over the target, so a failed save
leaves the old file as it was. :func:`load` checks the file's signature, its declared sizes
against a budget, and its structure before reading the arrays, and raises
:class:`clsas.errors.DataFileError` naming the file and what is wrong.

Files of clsas 0.1 (plain HDF5 with a ``kind`` attribute and a ``/data`` dataset) still load;
``clsas.save(clsas.load("old.h5"), "new.nc")`` converts one.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..errors import DataFileError
from ..model import EchoData, Image, Medium, Waveform
from .dataset import from_xarray, to_json, to_xarray

log = logging.getLogger("clsas")

CHUNK_BYTES = 4 << 20  # target size of one stored chunk, bytes
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_LEGACY_ECHO_ARRAYS = ("eta", "t0", "tx_pos", "rx_pos", "rx_tau")


def default_max_bytes() -> int:
    """The default budget of :func:`load`: half the machine's physical memory (8 GiB if unknown)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 8 << 30


def _is_zarr(path: Path) -> bool:
    return path.suffix == ".zarr"


def _chunks(shape: tuple, itemsize: int) -> tuple:
    """Chunk shape of about CHUNK_BYTES: whole trailing axes, the leading axes cut."""
    chunks = list(shape)
    for axis in range(len(shape)):
        rest = itemsize * int(np.prod(chunks[axis + 1:], dtype=np.int64))
        chunks[axis] = max(1, min(shape[axis], CHUNK_BYTES // max(rest, 1)))
        if rest * chunks[axis] <= CHUNK_BYTES and chunks[axis] < shape[axis]:
            break
    return tuple(max(1, c) for c in chunks)


def _no_zarr_compressor() -> dict:
    """The zarr encoding key that turns compression off (zarr-python 3 renamed it)."""
    import zarr

    return {"compressors": None} if int(zarr.__version__.split(".")[0]) >= 3 else {"compressor": None}


def _encoding(ds, zarr: bool, level: int) -> dict:
    enc = {}
    for name, var in ds.variables.items():
        if var.ndim == 0 or var.dtype.kind in "OUS":
            continue
        chunks = _chunks(var.shape, var.dtype.itemsize)
        if zarr:
            enc[name] = {"chunks": chunks} if level else {"chunks": chunks, **_no_zarr_compressor()}
        else:
            enc[name] = {"chunksizes": chunks}
            if level:
                enc[name].update(compression="gzip", compression_opts=level, shuffle=True)
    return enc


def to_dataset(obj):
    """The xarray.Dataset :func:`save` writes for ``obj``; TypeError for anything else."""
    if isinstance(obj, (EchoData, Image)):
        return to_xarray(obj)
    raise TypeError(f"save() takes an EchoData or an Image, got {type(obj).__name__}")


def _write(ds, path: Path, level: int) -> None:
    if _is_zarr(path):
        ds.to_zarr(path, mode="w", encoding=_encoding(ds, True, level), consolidated=True, zarr_format=2)
    else:
        ds.to_netcdf(path, engine="h5netcdf", encoding=_encoding(ds, False, level))
        with open(path, "rb+") as f:
            os.fsync(f.fileno())


def _same(a, b, stored_scenario: bool) -> bool:
    if isinstance(a, EchoData):
        return (isinstance(b, EchoData) and all(np.array_equal(getattr(a, n), getattr(b, n)) for n in
                                                ("data", "eta", "t0", "tx_pos", "rx_pos", "rx_tau"))
                and a.receivers == b.receivers and a.fs == b.fs and a.compressed == b.compressed
                and (b.scenario is not None) == stored_scenario)
    return (isinstance(b, Image) and a.dims == b.dims and np.array_equal(a.data, b.data)
            and all(np.array_equal(a.axes[d], b.axes[d]) for d in a.dims)
            and (a.positions is None) == (b.positions is None)
            and (a.positions is None or np.array_equal(a.positions, b.positions)))


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    elif path.exists() or path.is_symlink():
        path.unlink()


def save(obj: EchoData | Image, path: str | os.PathLike, compression: int = 1) -> Path:
    """Write ``obj`` (EchoData or Image) to ``path``: NetCDF4, or zarr when it ends in ``.zarr``.

    ``compression``: the gzip level of a NetCDF file (1-9; 0 stores the chunks raw). Level 1
    with byte shuffle saves ~15 % of a noisy echo and ~20 % of an image, and costs several times
    the time of a raw write; zarr stores use zarr's default compressor unless it is 0.

    The file is written beside the target under a temporary name, read back and compared with
    ``obj`` (data and geometry bit for bit), then renamed over ``path``; on any failure the old
    file (if any) is left untouched and the temporary one removed. Returns ``Path(path)``.
    """
    path = Path(path)
    if isinstance(compression, bool) or not isinstance(compression, (int, np.integer)) or not 0 <= compression <= 9:
        raise ValueError(f"save: compression must be a gzip level 0-9, got {compression!r}")
    ds = to_dataset(obj)  # TypeError / ValueError (unstorable provenance, bad dim names) before any write
    if path.is_dir() and not _is_zarr(path):
        raise ValueError(f"save: {path} is a folder; give a file name (.nc) or a name ending in .zarr")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"save: the folder {path.parent} does not exist")
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    tmp.unlink()
    try:
        _write(ds, tmp, int(compression))
        back = load(tmp)
        if not _same(obj, back, "scenario" in ds.attrs):
            raise DataFileError(f"{path}: the file read back differs from the data written; the old file is kept")
        if _is_zarr(path) and path.exists():
            old = path.with_name(f".{path.name}.old")
            _remove(old)
            os.replace(path, old)
            os.replace(tmp, path)
            _remove(old)
        else:
            os.replace(tmp, path)
    finally:
        if tmp.exists():
            _remove(tmp)
    log.info("saved %s (%s) to %s", type(obj).__name__, "x".join(map(str, obj.data.shape)), path)
    return path


def _budget_check(path: Path, declared: dict, max_bytes: int) -> None:
    total = sum(declared.values())
    if total > max_bytes:
        biggest = max(declared, key=declared.get)
        raise DataFileError(f"{path}: its arrays declare {total / 2**30:.3g} GiB ({biggest}: "
                            f"{declared[biggest] / 2**30:.3g} GiB), over the budget of {max_bytes / 2**30:.3g} GiB; "
                            "if the file is genuine, pass load(..., max_bytes=) a larger budget")


def _declared_bytes(ds) -> dict:
    return {name: int(np.prod(var.shape, dtype=np.float64) * var.dtype.itemsize) for name, var in ds.variables.items()}


def _open_xarray(path: Path, engine: str):
    import xarray as xr

    kwargs = {"consolidated": True} if engine == "zarr" else {}
    return xr.open_dataset(path, engine=engine, decode_cf=False, mask_and_scale=False, **kwargs)


def load(path: str | os.PathLike, max_bytes: int | None = None) -> EchoData | Image:
    """Read an EchoData or Image written by :func:`save` (or by clsas 0.1's HDF5 layout).

    Parameters
    ----------
    path : a ``.nc`` / HDF5 file or a ``.zarr`` folder.
    max_bytes : refuse files whose arrays declare more than this many bytes in memory
        (default :func:`default_max_bytes`), before reading any of them.

    Raises FileNotFoundError when nothing is at ``path`` and :class:`DataFileError` (naming the
    file and what is wrong) when it is not a complete clsas file.
    """
    path = Path(path)
    budget = default_max_bytes() if max_bytes is None else int(max_bytes)
    if not path.exists():
        raise FileNotFoundError(f"no such clsas file: {path}")
    if path.is_dir():
        if not ((path / "zarr.json").is_file() or (path / ".zgroup").is_file()):
            raise DataFileError(f"{path}: a folder that is not a zarr store (no zarr.json or .zgroup)")
        return _load_dataset(path, "zarr", budget)
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(8)
    if head != HDF5_SIGNATURE:
        what = "empty" if size == 0 else f"starts with {head!r}"
        raise DataFileError(f"{path}: not a NetCDF4/HDF5 clsas file ({what}; expected the HDF5 signature)")
    import h5py

    try:
        with h5py.File(path, "r") as f:
            attrs = dict(f.attrs)
            legacy = "clsas_kind" not in attrs and attrs.get("kind") in ("EchoData", "Image")
            if legacy:
                return _load_legacy(path, f, budget)
    except DataFileError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as err:
        raise DataFileError(f"{path}: cannot be read as HDF5 ({size} bytes; truncated or damaged?): {err}") from err
    if "clsas_kind" not in attrs:
        raise DataFileError(f"{path}: an HDF5 file without a clsas_kind attribute: not a clsas file "
                            f"(its attributes: {sorted(attrs)[:8]})")
    return _load_dataset(path, "h5netcdf", budget)


def _load_dataset(path: Path, engine: str, budget: int) -> EchoData | Image:
    try:
        ds = _open_xarray(path, engine)
    except Exception as err:  # noqa: BLE001 - any failure to open is the file's fault here
        raise DataFileError(f"{path}: cannot be opened as a {engine} dataset (truncated or damaged?): "
                            f"{type(err).__name__}: {err}") from err
    with ds:
        _budget_check(path, _declared_bytes(ds), budget)
        try:
            return from_xarray(ds)
        except (ValueError, TypeError, KeyError) as err:
            raise DataFileError(f"{path}: {err}") from err
        except (OSError, RuntimeError) as err:
            raise DataFileError(f"{path}: reading its arrays failed (truncated or damaged?): {err}") from err


def _load_legacy(path: Path, f, budget: int) -> EchoData | Image:
    """clsas 0.1's HDF5 layout (``kind`` attribute, ``/data``, geometry datasets or ``/axes/<dim>``)."""
    import h5py

    declared = {name: int(np.prod(obj.shape, dtype=np.float64) * obj.dtype.itemsize)
                for name, obj in _walk(f, h5py)}
    _budget_check(path, declared, budget)
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
    except (KeyError, ValueError, TypeError, json.JSONDecodeError) as err:
        raise DataFileError(f"{path}: a clsas 0.1 HDF5 file with a missing or malformed item: {err}") from err
    except OSError as err:
        raise DataFileError(f"{path}: reading a clsas 0.1 HDF5 file failed (truncated?): {err}") from err


def _walk(group, h5py):
    for name, obj in group.items():
        if isinstance(obj, h5py.Dataset):
            yield f"{group.name.rstrip('/')}/{name}", obj
        elif isinstance(obj, h5py.Group):
            yield from _walk(obj, h5py)


__all__ = ["save", "load", "to_dataset", "to_json", "default_max_bytes", "CHUNK_BYTES"]
