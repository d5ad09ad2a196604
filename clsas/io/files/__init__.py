"""Save and load EchoData and Image as NetCDF4 (h5netcdf) or zarr files that xarray reads.

``save(obj, "run.nc")`` writes NetCDF4/HDF5 through h5netcdf; a path ending in ``.zarr``
writes a zarr store (a folder). The layout (named dims, a coordinate for every dim, CF
``units`` and ``long_name``, provenance as JSON attributes) is :mod:`clsas.io.dataset`'s, so
``xarray.open_dataset(path)`` shows the data as it is in clsas. Arrays are chunked (about
:data:`CHUNK_BYTES` a chunk) and compressed (gzip level 1 with byte shuffle in NetCDF, zarr's
default compressor in zarr).

What a save does (:func:`save`):

- **Before writing**: the path is checked (a known suffix, an existing folder, a name the file
  system can hold, and what is there may be replaced: a regular file, or a clsas zarr store;
  a folder that is not one is never touched).
- **Atomic**: the data go to a hidden temporary beside the target, are read back and compared
  bit for bit, then one rename puts them in place (a store over a store: one exchange of the
  two folders, :mod:`.target`). Until then the old file is intact; after it the new one is
  whole.
- **Interrupted** (an error, Ctrl-C, SIGTERM or SIGHUP): the temporary is deleted; the target is
  as it was. A SIGKILL or a power cut can leave ``.<name>.<random>.clsas-tmp<suffix>``
  beside it, never a half-written target.
- **Memory**: the data are written and compared chunk by chunk: the save holds the object plus
  a few slabs of :data:`SLAB_BYTES`, never a second copy.

What a load does (:func:`load`): it reads only a regular file with the HDF5 signature or a zarr
store with all its chunks (a FIFO is refused, not read); the arrays' declared sizes count
against :func:`clsas.memory_budget` before any is read (:class:`clsas.errors.MemoryBudgetError`);
anything damaged or foreign raises :class:`clsas.errors.DataFileError` naming the file.

Files of clsas 0.1 (plain HDF5 with a ``kind`` attribute and a ``/data`` dataset) still load;
``clsas.save(clsas.load("old.h5"), "new.nc")`` converts one.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from ... import atomic, budget, validate
from ...errors import ClsasError, DataFileError
from ...model import EchoData, Image
from ..dataset import to_json, to_xarray
from ..toml import scenario_from_toml
from . import read as _read
from . import target as _target
from . import write as _write
from .read import LOAD_OVERHEAD, LOAD_WORKING_BYTES
from .target import NETCDF_SUFFIXES, ZARR_SUFFIX, check_target
from .write import CHUNK_BYTES, SLAB_BYTES

log = logging.getLogger("clsas")

#: bytes a save holds beyond the object: a few slabs and the writers' chunk buffers
#: (tests/test_hardening_files.py measures the peak)
SAVE_WORKING_BYTES = 64 << 20


def to_dataset(obj):
    """The xarray.Dataset :func:`save` writes for ``obj``; TypeError for anything else."""
    if isinstance(obj, (EchoData, Image)):
        return to_xarray(obj)
    raise TypeError(f"save obj: must be an EchoData or an Image, got {type(obj).__name__}")


def save(obj: EchoData | Image, path: str | os.PathLike, compression: int = 1, overwrite: bool = True) -> Path:
    """Write ``obj`` (EchoData or Image) to ``path``: NetCDF4 (``.nc``, ``.nc4``, ``.h5``) or a
    zarr store (``.zarr``). See the module docstring for what happens on failure, interruption
    and memory.

    ``compression``: the gzip level of a NetCDF file (1-9, with byte shuffle; 0 stores the
    chunks raw, the fastest write); zarr stores use zarr's default compressor unless it is 0.
    ``overwrite``: replace an existing clsas file or store at ``path`` (default); False raises
    FileExistsError instead. Returns ``Path(path)``.

    Raises TypeError / ValueError for bad arguments, FileNotFoundError, FileExistsError,
    IsADirectoryError or PermissionError naming the path before anything is written, OSError
    naming the path when writing fails, DataFileError when the file reads back different.
    """
    level = validate.integer("save compression", compression, low=0, high=9, why="a gzip level")
    overwrite = validate.flag("save overwrite", overwrite)
    ds = to_dataset(obj)  # TypeError / ValueError (unstorable provenance, bad dim names) before any write
    path = check_target("save path", path, overwrite)
    budget.check_bytes(f"save of {path} (its working buffers)", SAVE_WORKING_BYTES)
    with _target.temporary(path) as tmp:
        try:
            _write.write(ds, tmp, level)
            atomic.check_signals()  # a signal whose exception a writer's cleanup dropped
            _check(ds, tmp, path)
            _target.replace(tmp, path)
        except (ClsasError, MemoryError):
            raise
        except Exception as err:  # noqa: BLE001 - the writers' errors, named by the target, not the temporary
            message = " ".join(str(err).replace(str(tmp), str(path)).split())
            raise OSError(f"save: writing {path} failed: {type(err).__name__}: {message}") from err
    log.info("saved %s (%s) to %s", type(obj).__name__, "x".join(map(str, obj.data.shape)), path)
    return path


def _check(ds, tmp: Path, path: Path) -> None:
    """The written ``tmp`` read back and compared with ``ds``; its scenario TOML parses."""
    engine = "zarr" if _target.is_zarr(tmp) else "h5netcdf"
    if engine == "zarr":
        _read.check_chunks(tmp)
    with _read.open_dataset(tmp, engine) as back, _write.zarr_limits():
        _write.verify(ds, back, path)
    if "scenario" in ds.attrs:
        try:
            scenario_from_toml(ds.attrs["scenario"])
        except ValueError as err:
            raise DataFileError(f"{path}: the scenario stored with the echo does not read back ({err})") from err


def load(path: str | os.PathLike) -> EchoData | Image:
    """Read an EchoData or Image written by :func:`save` (or by clsas 0.1's HDF5 layout).

    ``path``: a ``.nc`` / HDF5 file or a ``.zarr`` store (folder). Its arrays' declared sizes
    (times :data:`LOAD_OVERHEAD`, plus :data:`LOAD_WORKING_BYTES`) must fit :func:`clsas.memory_budget` (raise it with
    ``clsas.use_memory_budget`` for a larger file).

    Raises TypeError for a path that is not a str or os.PathLike, FileNotFoundError when
    nothing is at ``path``, MemoryBudgetError (naming the file) for a file over the budget, and
    :class:`DataFileError` (naming the file and what is wrong) for anything else that is not a
    complete clsas file, a FIFO or a device included.
    """
    return _read.read(_target.file_path("load path", path))


__all__ = ["CHUNK_BYTES", "LOAD_OVERHEAD", "LOAD_WORKING_BYTES", "NETCDF_SUFFIXES", "SAVE_WORKING_BYTES", "SLAB_BYTES", "ZARR_SUFFIX",
           "check_target", "load", "save", "to_dataset", "to_json"]
