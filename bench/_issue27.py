"""The machinery of bench/issue27_check.py: the registry of checks, what a check asserts
(a named error, a finite result, the memory budget held, a one-line CLI error) and the tiny
fixtures (the fuzz's scenes, an echo file made by the command line)."""

from __future__ import annotations

import dataclasses
import hashlib
import os
import subprocess
import sys
import tempfile
import threading
import time
import tracemalloc
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import clsas  # noqa: E402
from clsas.atomic import TEMPORARY_TAG  # noqa: E402
from clsas.errors import MemoryBudgetError  # noqa: E402
from fuzz_api import finite_result, fixtures  # noqa: E402  (the fuzz's tiny scenes and its judge of results)

CHECKS = []
CLI = [sys.executable, "-m", "clsas"]
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def check(section: str, owner: str):
    """Register ``fn`` as the check of one sentence of the issue (its docstring)."""
    def register(fn):
        CHECKS.append((section, fn.__name__, owner, fn))
        return fn
    return register


class Failed(Exception):
    pass


def raises(call, errors, *words):
    """``call()`` must raise one of ``errors`` whose message holds every word of ``words``."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = call()
    except errors as err:
        missing = [w for w in words if w not in str(err)]
        if missing:
            raise Failed(f"{type(err).__name__} without {missing}: {str(err)[:200]}") from None
        return err
    except Exception as err:  # noqa: BLE001 - the defect a check looks for
        raise Failed(f"{type(err).__name__} (wanted {_names(errors)}): {str(err)[:200]}") from None
    raise Failed(f"accepted (wanted {_names(errors)}), returned {type(result).__name__}")


def _names(errors):
    return "/".join(e.__name__ for e in (errors if isinstance(errors, tuple) else (errors,)))


def finite_or_refused(call, *words):
    """``call()`` returns finite numbers, or refuses with a ValueError naming ``words``."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = call()
    except ValueError as err:
        missing = [w for w in words if w not in str(err)]
        if missing:
            raise Failed(f"ValueError without {missing}: {str(err)[:200]}") from None
        return
    except Exception as err:  # noqa: BLE001
        raise Failed(f"{type(err).__name__}: {str(err)[:200]}") from None
    if not finite_result(result):
        raise Failed("NaN or inf from finite input")


def within_budget(call, budget: str, *words, allowed=None):
    """Under ``use_memory_budget(budget)``, ``call()`` refuses with MemoryBudgetError before its
    NumPy allocations pass the budget (tracemalloc's peak), or finishes within it."""
    tracemalloc.start()
    try:
        with clsas.use_memory_budget(budget), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                call()
                outcome = None
            except MemoryBudgetError as err:
                outcome = err
            except Exception as err:  # noqa: BLE001
                raise Failed(f"{type(err).__name__} (wanted MemoryBudgetError): {str(err)[:200]}") from None
            limit = clsas.memory_budget()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    if outcome is not None and any(w not in str(outcome) for w in words):
        raise Failed(f"MemoryBudgetError without {words}: {str(outcome)[:200]}")
    bound = allowed if allowed is not None else limit
    if peak > bound:
        raise Failed(f"{'refused' if outcome else 'finished'} after allocating {peak / 2**20:.2f} MiB under a "
                     f"{limit / 2**20:.2f} MiB budget")


def cli(*args, cwd, timeout=120, signal_after=None, env=None):
    """(returncode, stdout, stderr, seconds) of one ``clsas`` command run as a new user would;
    ``env``: variables added to the environment."""
    env = {**os.environ, "TQDM_DISABLE": "1", **(env or {})}
    start = time.perf_counter()
    proc = subprocess.Popen([*CLI, *map(str, args)], cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    if signal_after is not None:
        time.sleep(signal_after[1])
        proc.send_signal(signal_after[0])
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out, err, time.perf_counter() - start


def one_line_error(rc, err, *words, status=2):
    if rc != status:
        raise Failed(f"exit status {rc} (wanted {status}): {err.strip()[-300:]}")
    lines = err.strip().splitlines()
    if len(lines) != 1 or "Traceback" in err:
        raise Failed(f"{len(lines)} lines on stderr: {err.strip()[-300:]}")
    missing = [w for w in words if w not in err]
    if missing:
        raise Failed(f"message without {missing}: {err.strip()}")
    if TEMPORARY_TAG in err:
        raise Failed(f"the message names the temporary file: {err.strip()}")


def no_leftovers(folder: Path):
    left = sorted(p.name for p in folder.iterdir() if TEMPORARY_TAG in p.name or p.name.startswith("."))
    if left:
        raise Failed(f"left in {folder}: {left}")


def digest(path: Path) -> str:
    if path.is_dir():
        return hashlib.sha256(b"".join(p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file())).hexdigest()
    return hashlib.sha256(path.read_bytes()).hexdigest()


def folder() -> Path:
    return Path(tempfile.mkdtemp(prefix="clsas-issue27-"))


def small_echo(n_rx=2, n_p=5, n_s=64, data=None):
    return fixtures()["compressed"] if data is None else dataclasses.replace(fixtures()["compressed"], data=data)


def cli_echo(where: Path) -> Path:
    """A tiny echo file the CLI can image (16 pulses of huang2022)."""
    path = where / "s.nc"
    if not path.exists():
        rc, _, err, _ = cli("simulate", "huang2022", "--pulses", "16", "-o", path, cwd=where)
        if rc != 0:
            raise Failed(f"clsas simulate for the fixture failed: {err.strip()[-200:]}")
    return path



def in_thread(call, seconds=20.0):
    caught = []

    def run():
        try:
            caught.append(call())
        except BaseException as err:  # noqa: BLE001
            caught.append(err)

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(seconds)
    if worker.is_alive():
        raise Failed(f"no answer in {seconds:g} s (blocked)")
    return caught[0]

