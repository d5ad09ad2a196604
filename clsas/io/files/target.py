"""Where a clsas file is written: the target's checks before anything is computed, and the one
rename that puts a written temporary in place (:mod:`clsas.atomic`).

A folder that is not a clsas zarr store is never replaced, and nothing but a regular file or a
clsas store is.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

from ... import atomic
from ...atomic import remove, temporary  # noqa: F401 - the save's temporary, re-exported for its callers

NETCDF_SUFFIXES = (".nc", ".nc4", ".h5")  # NetCDF4 (HDF5) files
ZARR_SUFFIX = ".zarr"


def file_path(name: str, value) -> Path:
    """``value`` (str or os.PathLike) as a Path; TypeError naming ``name`` for anything else."""
    if not isinstance(value, (str, os.PathLike)) or isinstance(value, bytes):
        raise TypeError(f"{name}: must be a file name (str or os.PathLike), got {value!r:.60} ({type(value).__name__})")
    path = Path(value)
    if not str(path) or str(path) == ".":
        raise ValueError(f"{name}: must name a file, got {str(value)!r}")
    return path


def is_zarr(path: Path) -> bool:
    return path.suffix == ZARR_SUFFIX


def check_suffix(name: str, path: Path) -> None:
    """ValueError unless ``path`` ends in a suffix clsas writes."""
    if path.suffix not in NETCDF_SUFFIXES + (ZARR_SUFFIX,):
        raise ValueError(f"{name}: {str(path)!r} must end in {', '.join(NETCDF_SUFFIXES)} (NetCDF4) or "
                         f"{ZARR_SUFFIX} (a zarr store)")


def store_kind(path: Path) -> str | None:
    """The ``clsas_kind`` of a zarr store (v2 ``.zattrs`` or v3 ``zarr.json``), else None."""
    for name, inner in ((".zattrs", None), ("zarr.json", "attributes")):
        meta = path / name
        if meta.is_file():
            try:
                attrs = json.loads(meta.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                return None
            attrs = attrs.get(inner, {}) if inner and isinstance(attrs, dict) else attrs
            kind = attrs.get("clsas_kind") if isinstance(attrs, dict) else None
            return kind if isinstance(kind, str) else None
    return None


def check_target(name: str, value, overwrite: bool = True) -> Path:
    """The Path ``value`` names, checked before anything is computed or written: a known suffix,
    an existing folder, a name the file system can hold (with the temporary's), and, when
    something is already there, that it may be replaced: a regular file (``.nc``) or a clsas
    zarr store (``.zarr``), and only with ``overwrite``. FileExistsError, IsADirectoryError,
    FileNotFoundError, ValueError and TypeError name the path."""
    path = file_path(name, value)
    check_suffix(name, path)
    folder = path.parent
    if not folder.is_dir():
        what = "does not exist" if not folder.exists() else "is a file, not a folder"
        raise FileNotFoundError(f"{name}: the folder {str(folder)!r} {what}")
    limit = atomic.name_max(folder)
    if len(os.fsencode(path.name)) > limit:
        raise ValueError(f"{name}: the file name is {len(os.fsencode(path.name))} bytes long; the folder "
                         f"{str(folder)!r} allows names of at most {limit}")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(f"{name}: cannot write in the folder {str(folder)!r} (permission denied)")
    if path.is_symlink() and is_zarr(path):
        raise FileExistsError(f"{name}: {str(path)!r} is a symbolic link; a store is replaced by swapping folders, "
                              "which would replace the link, not the store it points to: give the store's own path")
    try:
        info = os.stat(path)
    except FileNotFoundError:
        if path.is_symlink():
            raise FileExistsError(f"{name}: {str(path)!r} is a dangling symbolic link; remove it or pick another "
                                  "name") from None
        return path
    if is_zarr(path):
        if not stat.S_ISDIR(info.st_mode):
            raise FileExistsError(f"{name}: {str(path)!r} exists and is not a zarr store (a folder); not replaced")
        if store_kind(path) is None:
            raise FileExistsError(f"{name}: {str(path)!r} is a folder that is not a clsas zarr store; it is never "
                                  "replaced (move it away or pick another name)")
    elif stat.S_ISDIR(info.st_mode):
        raise IsADirectoryError(f"{name}: {str(path)!r} is a folder; give a file name (.nc) or a name ending in "
                                f"{ZARR_SUFFIX}")
    elif not stat.S_ISREG(info.st_mode):
        raise FileExistsError(f"{name}: {str(path)!r} exists and is not a regular file (a FIFO, socket or device); "
                              "not replaced")
    if not overwrite:
        raise FileExistsError(f"{name}: {str(path)!r} exists; give --overwrite (or overwrite=True) to replace it")
    return path


def replace(tmp: Path, path: Path) -> None:
    """Move the written ``tmp`` onto ``path`` with one rename (:func:`clsas.atomic.replace`);
    a folder at ``path`` is replaced only if it is a clsas store (checked before writing too: it
    may have changed meanwhile)."""
    if is_zarr(path) and path.is_dir() and not path.is_symlink() and store_kind(path) is None:
        raise FileExistsError(f"{str(path)!r} is a folder that is not a clsas zarr store; it is never replaced")
    atomic.replace(tmp, path)
