"""Where a file is written: the target's checks, the temporary beside it, the one rename.

A save writes ``.<name>.<random>.clsas-tmp<suffix>`` in the target's folder (a file, or a
zarr store: a folder) and, once it has been read back, moves it onto the target with one
rename: ``os.replace`` for a file; for a store over an existing store, Linux's
``renameat2(RENAME_EXCHANGE)`` swaps the two folders in one step (there is always a complete
store at the target) and the old one, now under the temporary name, is deleted. Where the
system has no exchange the old store is first moved aside (a warning says so). A folder that
is not a clsas store is never replaced, and nothing but a regular file or a clsas store is.

While the temporary exists, SIGTERM and SIGHUP (when their handlers are the default, in the
main thread) are turned into an exception so that the temporary is deleted; the signal is then
delivered again and ends the process as it would have. Ctrl-C (KeyboardInterrupt) and any
other exception delete it too.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import json
import logging
import os
import secrets
import shutil
import signal
import stat
import threading
from pathlib import Path

log = logging.getLogger("clsas")

NETCDF_SUFFIXES = (".nc", ".nc4", ".h5")  # NetCDF4 (HDF5) files
ZARR_SUFFIX = ".zarr"
TEMPORARY_TAG = ".clsas-tmp"
_TEMPORARY_NAME_BYTES = 100  # of the target's name kept in the temporary's (names have a length limit)
_RENAME_EXCHANGE = 2  # linux/fs.h
_AT_FDCWD = -100


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
        what = "does not exist" if not folder.exists() else "is not a folder"
        raise FileNotFoundError(f"{name}: the folder {str(folder)!r} {what}")
    limit = _name_max(folder)
    if len(os.fsencode(path.name)) > limit:
        raise ValueError(f"{name}: the file name is {len(os.fsencode(path.name))} bytes long; the folder "
                         f"{str(folder)!r} allows names of at most {limit}")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(f"{name}: cannot write in the folder {str(folder)!r} (permission denied)")
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


def _name_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):  # pragma: no cover - non-POSIX
        return 255


def temporary_name(path: Path) -> Path:
    """A fresh hidden name beside ``path`` for writing it: ``.<name>.<random>.clsas-tmp<suffix>``."""
    stem = os.fsencode(path.name)[:_TEMPORARY_NAME_BYTES].decode(errors="ignore")
    return path.with_name(f".{stem}.{secrets.token_hex(6)}{TEMPORARY_TAG}{path.suffix}")


def remove(path: Path) -> None:
    """Delete a file or a folder tree we wrote (never following a symbolic link)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    elif path.exists() or path.is_symlink():
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


class _Terminated(BaseException):
    """SIGTERM/SIGHUP arrived while a temporary existed (raised by the handler of
    :func:`temporary`, delivered again once the temporary is gone)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


@contextlib.contextmanager
def _signals_as_exceptions():
    """In the main thread, SIGTERM and SIGHUP with the default handler raise _Terminated."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}

    def handler(signum, frame):
        raise _Terminated(signum)

    for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None and signal.getsignal(sig) == signal.SIG_DFL:
            previous[sig] = signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


@contextlib.contextmanager
def temporary(path: Path):
    """A temporary name beside ``path`` (see the module docstring); whatever is there when the
    block ends (error, Ctrl-C, SIGTERM, or not renamed) is deleted."""
    tmp = temporary_name(path)
    terminated = None
    with _signals_as_exceptions():
        try:
            yield tmp
        except _Terminated as stop:
            terminated = stop.signum
        finally:
            remove(tmp)
    if terminated is not None:  # end as the signal would have ended the process
        signal.signal(terminated, signal.SIG_DFL)
        os.kill(os.getpid(), terminated)
        raise SystemExit(128 + terminated)  # pragma: no cover - the signal ends the process first


def replace(tmp: Path, path: Path) -> None:
    """Move the written ``tmp`` onto ``path`` with one rename (see the module docstring)."""
    if is_zarr(path) and path.is_dir() and not path.is_symlink():
        if store_kind(path) is None:  # checked before writing too: it may have changed meanwhile
            raise FileExistsError(f"{str(path)!r} is a folder that is not a clsas zarr store; it is never replaced")
        if not _exchange(tmp, path):
            _replace_in_two_steps(tmp, path)
        remove(tmp)  # the old store, now under the temporary name
    else:
        os.replace(tmp, path)
    _sync_folder(path.parent)


def _exchange(a: Path, b: Path) -> bool:
    """Swap ``a`` and ``b`` in one step (Linux renameat2 RENAME_EXCHANGE); False where the
    system or the file system cannot."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        return False
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(code, f"cannot move the new store onto {str(b)!r}: {os.strerror(code)}")


def _replace_in_two_steps(tmp: Path, path: Path) -> None:
    """Without an exchange: the old store aside, the new one in, the old one back on failure."""
    log.warning("replacing %s: this system cannot swap two folders in one step; the old store is moved aside "
                "first (a crash in between leaves it under a hidden name beside it)", path)
    aside = temporary_name(path)
    os.rename(path, aside)
    try:
        os.rename(tmp, path)
    except BaseException:
        os.rename(aside, path)
        raise
    os.rename(aside, tmp)  # deleted by the caller with the temporary


def _sync_folder(folder: Path) -> None:
    """Make the rename durable (fsync of the folder); ignored where folders cannot be synced."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
