"""Writing a file or a folder beside its target and moving it in place with one rename (a ground
service: clsas's files, scenario TOML and pictures are all written this way).

The temporary is ``.<name>.<random>.clsas-tmp<suffix>`` in the target's folder; :func:`replace`
moves it onto the target with ``os.replace`` (a file) or, for a folder over a folder (a zarr
store), Linux's ``renameat2(RENAME_EXCHANGE)``, which swaps the two in one step so that the
target is always whole; the old one, now under the temporary name, is then deleted. Where the
system has no exchange the old folder is first moved aside (a warning says so).

While :func:`temporary` is open, SIGTERM and SIGHUP (when their handlers are the default, in
the main thread) are turned into an exception so that the temporary is deleted; the signal is
then delivered again and ends the process as it would have. Ctrl-C (KeyboardInterrupt) and any
other exception delete it too. A signal's exception can be lost: Python ignores (prints and
drops) an exception raised in some callbacks, such as a weak reference's, and the handler may
run inside one while a writer cleans up. The handlers therefore also note the signal, and
:func:`replace` and the end of :func:`temporary` raise it again, so that an interrupted save
never goes on to the rename. Files are created by their writers with the mode the umask
gives (not 0600 as ``tempfile.mkstemp`` would).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import logging
import os
import secrets
import shutil
import signal
import threading
import warnings
from pathlib import Path

log = logging.getLogger("clsas")

TEMPORARY_TAG = ".clsas-tmp"
_TEMPORARY_NAME_BYTES = 100  # of the target's name kept in the temporary's (names have a length limit)
_RENAME_EXCHANGE = 2  # linux/fs.h
_AT_FDCWD = -100


def name_max(folder: Path) -> int:
    """The longest file name (bytes) ``folder`` holds."""
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):  # pragma: no cover - non-POSIX
        return 255


def check_output(name: str, value, suffixes: tuple, overwrite: bool = True) -> Path:
    """The Path of a single file to write, checked before anything is computed: a str or
    os.PathLike (TypeError), one of ``suffixes`` (ValueError), an existing folder
    (FileNotFoundError), a name the folder holds (ValueError), and what is there a regular file
    that may be replaced (IsADirectoryError, FileExistsError; ``overwrite``). Every message
    starts with ``name``."""
    if not isinstance(value, (str, os.PathLike)) or isinstance(value, bytes):
        raise TypeError(f"{name}: must be a file name (str or os.PathLike), got {value!r:.60} ({type(value).__name__})")
    path = Path(value)
    if path.suffix.lower() not in suffixes:
        raise ValueError(f"{name}: {str(path)!r} must end in {', '.join(suffixes)}")
    if not path.parent.is_dir():
        what = "does not exist" if not path.parent.exists() else "is a file, not a folder"
        raise FileNotFoundError(f"{name}: the folder {str(path.parent)!r} {what}")
    if len(os.fsencode(path.name)) > name_max(path.parent):
        raise ValueError(f"{name}: the file name is {len(os.fsencode(path.name))} bytes long; the folder "
                         f"{str(path.parent)!r} allows names of at most {name_max(path.parent)}")
    if path.exists() or path.is_symlink():
        if not path.is_file():
            raise IsADirectoryError(f"{name}: {str(path)!r} exists and is not a regular file; not replaced")
        if not overwrite:
            raise FileExistsError(f"{name}: {str(path)!r} exists; give --overwrite to replace it")
    return path


def remove(path: Path) -> None:
    """Delete a file or a folder tree we wrote (never following a symbolic link)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    elif path.exists() or path.is_symlink():
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def temporary_name(path: Path) -> Path:
    """A fresh hidden name beside ``path`` for writing it: ``.<name>.<random>.clsas-tmp<suffix>``."""
    stem = os.fsencode(path.name)[:_TEMPORARY_NAME_BYTES].decode(errors="ignore")
    return path.with_name(f".{stem}.{secrets.token_hex(6)}{TEMPORARY_TAG}{path.suffix}")


#: signals that arrived while a temporary was open (their exception may have been dropped)
_pending: list = []


def check_signals() -> None:
    """Raise again a SIGTERM / SIGHUP (_Terminated) or Ctrl-C (KeyboardInterrupt) that arrived
    while a temporary was open, in case its exception was dropped (module docstring)."""
    if _pending:
        signum = _pending[0]
        raise KeyboardInterrupt if signum == signal.SIGINT else _Terminated(signum)


class _Terminated(BaseException):
    """SIGTERM/SIGHUP arrived while a temporary existed (raised by the handler of
    :func:`temporary`, delivered again once the temporary is gone)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


@contextlib.contextmanager
def _signals_as_exceptions():
    """In the main thread, SIGTERM and SIGHUP with the default handler raise _Terminated, and
    SIGINT with Python's raises KeyboardInterrupt; each is noted in ``_pending`` too."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}

    def handler(signum, frame):
        _pending.append(signum)
        raise KeyboardInterrupt if signum == signal.SIGINT else _Terminated(signum)

    for sig, default in ((signal.SIGTERM, signal.SIG_DFL), (getattr(signal, "SIGHUP", None), signal.SIG_DFL),
                         (signal.SIGINT, signal.default_int_handler)):
        if sig is not None and signal.getsignal(sig) == default:
            previous[sig] = signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
        _pending.clear()


def stale_temporaries(path: Path) -> list:
    """The temporaries of ``path`` already beside it: left by a save that was killed where no
    handler runs (SIGKILL, the out-of-memory killer, a power cut), or one still running."""
    stem = os.fsencode(path.name)[:_TEMPORARY_NAME_BYTES].decode(errors="ignore")
    try:
        return sorted(p for p in path.parent.iterdir()
                      if p.name.startswith(f".{stem}.") and p.name.endswith(f"{TEMPORARY_TAG}{path.suffix}"))
    except OSError:
        return []


@contextlib.contextmanager
def temporary(path: Path):
    """A temporary name beside ``path`` (see the module docstring); whatever is there when the
    block ends (error, Ctrl-C, SIGTERM, or not renamed) is deleted. Temporaries of ``path``
    already there (:func:`stale_temporaries`) are named in a RuntimeWarning, never deleted: a
    save elsewhere may still be writing one."""
    stale = stale_temporaries(path)
    if stale:
        warnings.warn(f"{str(path)!r}: {', '.join(repr(p.name) for p in stale)} beside it: left by a save that was "
                      "killed (SIGKILL, out of memory) or one still running; delete them once no save of it runs",
                      RuntimeWarning, stacklevel=3)
    tmp = temporary_name(path)
    terminated = None
    with _signals_as_exceptions():
        try:
            yield tmp
            check_signals()  # one whose exception was dropped
        except _Terminated as stop:
            terminated = stop.signum
        finally:
            remove(tmp)
    if terminated is not None:  # end as the signal would have ended the process
        signal.signal(terminated, signal.SIG_DFL)
        os.kill(os.getpid(), terminated)
        raise SystemExit(128 + terminated)  # pragma: no cover - the signal ends the process first


def replace(tmp: Path, path: Path) -> None:
    """Move the written ``tmp`` onto ``path`` with one rename: ``os.replace`` for a file; for a
    folder over a folder, one exchange of the two (the old one, now under ``tmp``'s name, is
    deleted). The folder holding them is synced. A signal noted while the temporary was
    written stops it first (:func:`check_signals`). The temporary's data reach the disk
    before the rename (:func:`sync_tree`), so that a crash after it finds the new file whole,
    not an empty or short one (nor, for a store, the old one deleted and the new one lost)."""
    check_signals()
    sync_tree(tmp)
    if tmp.is_dir() and path.is_dir() and not path.is_symlink():
        if not _exchange(tmp, path):
            _replace_in_two_steps(tmp, path)
        remove(tmp)  # the old folder, now under the temporary name
    else:
        os.replace(tmp, path)
    sync_folder(path.parent)


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


def sync_tree(path: Path) -> None:
    """fsync a file, or every file and folder of a tree from the bottom up (a zarr store); a
    symbolic link is not followed. Folders that cannot be synced are skipped."""
    if path.is_symlink():
        return
    if not path.is_dir():
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        return
    for folder, _, files in os.walk(path, topdown=False):
        for name in files:
            if not os.path.islink(os.path.join(folder, name)):
                sync_tree(Path(folder, name))
        sync_folder(Path(folder))


def sync_folder(folder: Path) -> None:
    """Make the rename durable (fsync of the folder); ignored where folders cannot be synced."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
