"""Issue #27's reproducers in the files and the command line (data loss, hang, the budget of
loading and of `clsas simulate`, interruption, the CLI's outputs) and deliverables 2, 5 and 6:
the checks bench/issue27_check.py runs."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
from _issue27 import (CLI, Failed, check, cli, cli_echo, digest, fixtures, folder, in_thread, no_leftovers,
                      one_line_error, raises, small_echo, within_budget)

import clsas
from clsas.errors import DataFileError


# --- Data loss ------------------------------------------------------------------------------------

@check("data loss", "harden")
def zarr_save_over_a_store_is_one_exchange():
    """`clsas.save(x, "a.zarr")` over an existing store is two renames: a failure or a kill
    between them leaves nothing at the path."""
    where = folder()
    path = clsas.save(small_echo(), where / "a.zarr")
    touched = []
    originals = {name: getattr(os, name) for name in ("rename", "replace")}
    for name, fn in originals.items():
        setattr(os, name, lambda a, b, _f=fn, **kw: (touched.append((a, b)) if path in (Path(a), Path(b)) else None)
                or _f(a, b, **kw))
    try:
        clsas.save(fixtures()["compressed"].replace(fs=fixtures()["compressed"].fs), path, overwrite=True)
    finally:
        for name, fn in originals.items():
            setattr(os, name, fn)
    if touched:
        raise Failed(f"renames touching the path: {touched}")
    import clsas.io.files as files
    original = files.write.write

    def failing(ds, target, level):
        original(ds, target, level)
        raise OSError("disk full (simulated)")

    files.write.write = failing
    try:
        raises(lambda: clsas.save(small_echo(), path, overwrite=True), OSError)
    finally:
        files.write.write = original
    back = clsas.load(path)
    if not np.array_equal(back.data, small_echo().data):
        raise Failed("the old store changed after a failed save")
    no_leftovers(where)


@check("data loss", "harden")
def a_plain_folder_is_never_deleted():
    """`clsas.save(x, "notes.zarr")` where `notes.zarr` is a plain folder deletes it with its files."""
    where = folder()
    (where / "notes.zarr").mkdir()
    (where / "notes.zarr" / "todo.txt").write_text("keep me")
    raises(lambda: clsas.save(small_echo(), where / "notes.zarr", overwrite=True), FileExistsError, "notes.zarr",
           "not a clsas zarr store")
    if (where / "notes.zarr" / "todo.txt").read_text() != "keep me":
        raise Failed("the folder's file changed")


@check("data loss", "harden")
def cli_image_never_writes_over_its_input():
    """`clsas image s.nc -a omegak -o s.nc` replaces the input echo with the image."""
    where = folder()
    echo = cli_echo(where)
    before = digest(echo)
    for extra in ([], ["--overwrite"]):
        rc, _, err, _ = cli("image", echo.name, "-a", "omegak", "-o", echo.name, *extra, cwd=where)
        one_line_error(rc, err, "s.nc")
    rc, _, err, _ = cli("image", echo.name, "-a", "omegak", "-o", "s.nc", "--png", "s.nc", cwd=where)
    one_line_error(rc, err, "s.nc")
    if digest(echo) != before:
        raise Failed("the input changed")


@check("data loss", "harden")
def a_store_with_deleted_chunks_does_not_load_as_zeros():
    """A zarr store whose chunks were deleted loads as zeros."""
    where = folder()
    path = clsas.save(small_echo(), where / "z.zarr")
    chunk = sorted(p for p in (path / "echo").iterdir() if not p.name.startswith("."))[-1]
    chunk.unlink()
    raises(lambda: clsas.load(path), DataFileError, "z.zarr", "lacks chunk")



# --- Hang ---------------------------------------------------------------------------------------


@check("hang", "harden")
def load_of_a_fifo_is_refused():
    """`clsas.load(fifo)` blocks forever."""
    where = folder()
    os.mkfifo(where / "pipe.nc")
    err = in_thread(lambda: clsas.load(where / "pipe.nc"))
    if not isinstance(err, DataFileError) or "pipe.nc" not in str(err):
        raise Failed(f"{type(err).__name__}: {err}")


@check("hang", "harden")
def cli_image_of_a_fifo_is_refused():
    """`clsas image pipe.nc` blocks forever."""
    where = folder()
    os.mkfifo(where / "pipe.nc")
    try:
        rc, _, err, _ = cli("image", "pipe.nc", "-o", "i.nc", cwd=where, timeout=30)
    except subprocess.TimeoutExpired:
        raise Failed("no answer in 30 s (blocked)") from None
    one_line_error(rc, err, "pipe.nc")


# --- CLI ----------------------------------------------------------------------------------------

@check("cli", "harden")
def cli_ctrl_c_prints_one_line():
    """A traceback on Ctrl-C (and an interrupted save leaves no temporary: SIGINT and SIGTERM)."""
    for signum, status in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        where = folder()
        rc, _, err, _ = cli("simulate", "huang2022", "--pulses", "1024", "-o", "x.nc", cwd=where,
                            signal_after=(signum, 4.0))
        if rc == 0:
            raise Failed(f"signal {signum.name} after 4 s: the command had finished (make it longer)")
        if rc not in (status, -signum):
            raise Failed(f"{signum.name}: exit status {rc} (wanted {status}): {err.strip()[-200:]}")
        if "Traceback" in err or len(err.strip().splitlines()) > 1:
            raise Failed(f"{signum.name}: {err.strip()[-300:]}")
        if list(where.iterdir()):
            raise Failed(f"{signum.name}: left {sorted(p.name for p in where.iterdir())}")


@check("cli", "harden")
def cli_300_character_output_name():
    """A traceback on a 300-character output name."""
    where = folder()
    rc, _, err, _ = cli("simulate", "huang2022", "--pulses", "16", "-o", "a" * 300 + ".nc", cwd=where)
    one_line_error(rc, err, "-o")


@check("cli", "harden")
def cli_png_under_a_file():
    """A traceback on `--png i.nc/x.png`."""
    where = folder()
    echo = cli_echo(where)
    rc, _, err, _ = cli("image", echo.name, "-a", "omegak", "-o", "i.nc", "--png", "s.nc/x.png", cwd=where)
    one_line_error(rc, err, "--png")
    if (where / "i.nc").exists():
        raise Failed("the image was written although --png was refused")


@check("cli", "harden")
def cli_missing_output_folder_fails_before_the_job():
    """`-o /nonexistent/x.nc` fails only after the whole job ran."""
    where = folder()
    rc, _, err, seconds = cli("simulate", "huang2022", "--pulses", "256", "-o", "/nonexistent/x.nc", cwd=where)
    one_line_error(rc, err, "/nonexistent")
    if seconds > 15:
        raise Failed(f"refused after {seconds:.0f} s")


@check("cli", "harden")
def cli_existing_output_needs_overwrite():
    """`-o` over an existing file overwrites silently."""
    where = folder()
    echo = cli_echo(where)
    before = digest(echo)
    rc, _, err, _ = cli("simulate", "huang2022", "--pulses", "16", "--seed", "3", "-o", echo.name, cwd=where)
    one_line_error(rc, err, "--overwrite")
    if digest(echo) != before:
        raise Failed("replaced without --overwrite")
    rc, _, err, _ = cli("simulate", "huang2022", "--pulses", "16", "--seed", "3", "-o", echo.name, "--overwrite",
                        cwd=where)
    if rc != 0 or digest(echo) == before:
        raise Failed(f"--overwrite did not replace it (status {rc}): {err.strip()[-200:]}")


@check("cli", "harden")
def cli_unknown_extension_refused():
    """`-o x.txt` writes HDF5 into a .txt."""
    where = folder()
    rc, _, err, _ = cli("simulate", "huang2022", "--pulses", "16", "-o", "x.txt", cwd=where)
    one_line_error(rc, err, "x.txt")
    if (where / "x.txt").exists():
        raise Failed("x.txt written")


@check("cli", "harden")
def cli_plot_takes_o():
    """`clsas plot` has no `-o`."""
    where = folder()
    echo = cli_echo(where)
    rc, _, err, _ = cli("plot", echo.name, "-o", "p.png", cwd=where)
    if rc != 0 or not (where / "p.png").is_file() or (where / "p.png").read_bytes()[:4] != b"\x89PNG":
        raise Failed(f"status {rc}: {err.strip()[-200:]}")
    rc, _, err, _ = cli("plot", echo.name, "-o", "p.png", cwd=where)
    one_line_error(rc, err, "--overwrite")


@check("cli", "harden")
def to_toml_writes_with_the_umask_mode():
    """`to_toml` writes files mode 0600 under umask 022."""
    where = folder()
    old = os.umask(0o022)
    try:
        path = clsas.scenario_to_toml(fixtures()["scene"], where / "s.toml")
    finally:
        os.umask(old)
    mode = stat.S_IMODE(path.stat().st_mode)
    if mode != 0o644:
        raise Failed(f"mode {mode:o}")


# --- Deliver 2, 5 and 6 -------------------------------------------------------------------------

@check("deliver", "harden")
def use_backend_and_budget_are_per_thread():
    """`clsas.use_backend` / `use_memory_budget` as context variables: a `with` block in one
    thread does not change another's."""
    seen = {}
    inside = threading.Event()
    done = threading.Event()

    def holder():
        with clsas.use_backend("numpy"), clsas.use_memory_budget("1M"):
            inside.set()
            done.wait(10)

    worker = threading.Thread(target=holder)
    worker.start()
    inside.wait(10)
    from clsas import backend
    seen["budget"] = clsas.memory_budget()
    seen["backend"] = backend.current() if hasattr(backend, "current") else None
    done.set()
    worker.join()
    if seen["budget"] == 2**20:
        raise Failed("another thread's use_memory_budget changed this thread's budget")
    if seen["backend"] == "numpy":
        raise Failed("another thread's use_backend changed this thread's backend")


@check("deliver", "harden")
def the_test_extra_holds_matplotlib():
    """`pip install -e '.[test]'` alone runs the whole suite (matplotlib in the test extra)."""
    import tomllib
    project = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())["project"]
    test = " ".join(project["optional-dependencies"]["test"])
    missing = [name for name in ("matplotlib", "hypothesis", "pytest", "dask") if name not in test]
    if missing:
        raise Failed(f"the test extra lacks {missing}")




# --- Memory budget of the files and the command line ---------------------------------------------

@check("budget", "harden")
def load_counts_against_the_budget():
    """`clsas.load` has its own `max_bytes` and ignores the budget."""
    where = folder()
    echo = small_echo()
    big = echo.replace(data=np.zeros(echo.data.shape[:2] + (8192,), np.complex64))  # 7.5 MiB of samples
    for suffix in (".nc", ".zarr"):
        path = clsas.save(big, where / f"e{suffix}")
        within_budget(lambda: clsas.load(path), "1M", "load", f"e{suffix}")
    import inspect
    if "max_bytes" in inspect.signature(clsas.load).parameters:
        raise Failed("load still takes max_bytes")


@check("budget", "harden")
def cli_simulate_huang2022_2048_pulses_refused_up_front():
    """`clsas simulate huang2022 --pulses 2048 -o keep.nc` builds a 10.5 GiB cube, is killed at
    20 GB during the save and leaves a hidden 389 MB temp file. (Under an 8 GiB budget, so that
    the check costs nothing; the default budget, half of this machine's memory, may hold the
    cube: then ``--heavy`` runs it in full, see heavy_cli_simulate_huang2022_2048_pulses.)"""
    where = folder()
    rc, _, err, seconds = cli("simulate", "huang2022", "--pulses", "2048", "-o", "keep.nc", cwd=where, timeout=120,
                              env={"CLSAS_MEMORY_BUDGET": "8G"})
    one_line_error(rc, err, "budget", "8 GiB")
    if seconds > 30:
        raise Failed(f"refused only after {seconds:.0f} s")
    if list(where.iterdir()):
        raise Failed(f"left {sorted(p.name for p in where.iterdir())}")


@check("heavy", "harden")
def heavy_cli_simulate_huang2022_2048_pulses():
    """The same under the default budget: refused up front, or (the cube within the budget)
    written whole with a peak memory at most ~1.2x the cube (the save streams), no temporary."""
    where = folder()
    env = {**os.environ, "TQDM_DISABLE": "1"}
    start = time.perf_counter()
    proc = subprocess.Popen([*CLI, "simulate", "huang2022", "--pulses", "2048", "-o", "keep.nc"], cwd=where, env=env,
                            stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(proc.pid, 0)
    err = proc.stderr.read()
    rc = os.waitstatus_to_exitcode(status)
    seconds = time.perf_counter() - start
    peak = usage.ru_maxrss * 1024
    if rc != 0:
        one_line_error(rc, err, "budget")
        if seconds > 30:
            raise Failed(f"refused only after {seconds:.0f} s")
        return
    try:
        cube = clsas.load(where / "keep.nc").data.nbytes
        if peak > 1.25 * cube + (1 << 30):
            raise Failed(f"peak RSS {peak / 2**30:.2f} GiB for a {cube / 2**30:.2f} GiB cube")
        print(f"       written in {seconds:.0f} s, peak RSS {peak / 2**30:.2f} GiB for a {cube / 2**30:.2f} GiB cube "
              f"(budget {clsas.memory_budget() / 2**30:.2f} GiB)")
        no_leftovers(where)
    finally:
        (where / "keep.nc").unlink(missing_ok=True)
