"""Issue #27's text, walked one reproducer at a time against the checkout this runs from.

Each check is one sentence of the issue (its reproducer, as written there, on the fuzz's tiny
scenes) and what the project's rule wants of it: the named error (TypeError for a wrong kind,
ValueError naming the parameter, DataFileError/OSError naming the path, EstimationError,
MemoryBudgetError before the allocation) or the right result. A check that fails prints what
happened instead, with the owner of the code it sits in.

    python bench/issue27_check.py                 # every check, ~1-2 min on 2 cores
    python bench/issue27_check.py -k budget cli   # the checks whose name holds a word
    python bench/issue27_check.py --json out.json
    python bench/issue27_check.py -k heavy        # the 10 GiB huang2022 run (minutes, ~12 GB)

Exit status 0 when every check passes, 1 otherwise.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import signal
import stat
import subprocess
import sys
import tempfile
import threading
import time
import tracemalloc
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import clsas  # noqa: E402
from clsas.atomic import TEMPORARY_TAG  # noqa: E402
from clsas.errors import DataFileError, EstimationError, MemoryBudgetError, ScenarioFileError  # noqa: E402
from clsas.validate import CoverageWarning  # noqa: E402
from fuzz_api import fixtures  # noqa: E402  (the fuzz's tiny scenes)

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
    from fuzz_api import finite_result
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

def _in_thread(call, seconds=20.0):
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


@check("hang", "harden")
def load_of_a_fifo_is_refused():
    """`clsas.load(fifo)` blocks forever."""
    where = folder()
    os.mkfifo(where / "pipe.nc")
    err = _in_thread(lambda: clsas.load(where / "pipe.nc"))
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


# --- Memory budget ------------------------------------------------------------------------------

@check("budget", "ffbp")
def ffbp_300_squared_under_2m():
    """`with clsas.use_memory_budget("2M"): clsas.ffbp(...)` on a 300 x 300 grid allocates
    ~20 MiB without refusing (both backends, its default and sinc8 interpolation)."""
    f = fixtures()
    grid = clsas.Grid.plane(np.linspace(95, 105, 300), np.linspace(-2, 2, 300), f["scene"].platform.start[2])
    for backend in ("opencl", "numpy"):
        for interp in (None, "sinc8"):
            options = {} if interp is None else {"interp": interp}
            try:
                within_budget(lambda: clsas.ffbp(f["compressed"], grid, progress=False, backend=backend, **options),
                              "2M")
            except Failed as err:
                raise Failed(f"backend={backend} interp={interp or 'default'}: {err}") from None


@check("budget", "harden")
def grid_points_of_a_broadcast_input():
    """`Grid.points` on a broadcast input ignores the budget."""
    big = np.broadcast_to(np.zeros(3), (10**7, 3))
    within_budget(lambda: clsas.Grid.points(big), "16M", "Grid.points")


@check("budget", "bp2")
def prepare_upsample_64():
    """`prepare(upsample=64)` under a 2M budget allocates past it."""
    from clsas.image.backprojection import prepare
    within_budget(lambda: prepare(fixtures()["compressed"], upsample=64), "2M")


@check("budget", "papers")
def ptrs_image_refuses_before_allocating():
    """`ptrs_image` refuses only after allocating."""
    within_budget(lambda: clsas.ptrs_image(fixtures()["strip"], block_width=8.0), "1M")


@check("budget", "papers")
def correct_inclined_array_keeps_the_budget():
    """`correct_inclined_array` ignores the budget."""
    within_budget(lambda: clsas.correct_inclined_array(fixtures()["strip"]), "256K")


@check("budget", "dpca")
def dpca_estimate_n_angles_1e7():
    """`dpca.estimate(n_angles=10**7)` (1.3 GiB, MemoryError)."""
    from clsas.estimate import dpca
    f = fixtures()
    try:
        within_budget(lambda: dpca.estimate(f["compressed"], f["scene"].array, f["scene"].platform.speed,
                                            n_angles=10**7), "256M")
    except Failed as err:
        if "ValueError" not in str(err) or "n_angles" not in str(err):
            raise


@check("budget", "moving")
def solve_velocity_step_005():
    """`solve_velocity(step=0.05)` (6 GB)."""
    from clsas.estimate import moving
    f = fixtures()
    within_budget(lambda: moving.solve_velocity(f["layout"], (1989.0, 0.0, -350.0), {"A": 10.0, "B": -5.0, "C": 3.0},
                                                step=0.05), "64M")


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


@check("budget", "moving")
def focus_moving_29_tib():
    """(session 3) `focus_moving(echo, est, half_size=1e4, spacing=0.01)` asks for 29 TiB (MemoryError)."""
    f = fixtures()
    within_budget(lambda: clsas.focus_moving(f["kiang"], f["motion"], half_size=1e4, spacing=0.01), "16M")


@check("budget", "dpca")
def compensate_record_keeps_the_budget():
    """(session 3) `compensate_record` allocates 1.6-3.4 MB before refusing under 1 MiB."""
    from clsas.estimate import dpca
    f = fixtures()
    within_budget(lambda: dpca.compensate_record(f["compressed"], f["track"], f["scene"], list(range(4, 11))), "1M")


# --- NaN/inf from finite input ------------------------------------------------------------------

@check("nonfinite", "moving")
def closed_forms_sound_speed_velocity_and_huge_positions():
    """`closed_forms(sc, C, (1500, 0, 0))`, position or `eta_ref` 1e300."""
    from clsas.estimate import moving
    lay = fixtures()["layout"]
    raises(lambda: moving.closed_forms(lay, (1989.0, 0.0, -350.0), (1500.0, 0.0, 0.0)), ValueError, "velocity")
    raises(lambda: moving.closed_forms(lay, (1e300, 0.0, -350.0), (5.0, 0.0, 0.0)), ValueError, "position")
    raises(lambda: moving.closed_forms(lay, (1989.0, 0.0, -350.0), (5.0, 0.0, 0.0), eta_ref=1e300), ValueError,
           "eta_ref")


@check("nonfinite", "moving")
def delay_history_at_1e300():
    """`delay_history(..., [1e300])`."""
    from clsas.estimate import moving
    lay = fixtures()["layout"]
    finite_or_refused(lambda: moving.delay_history(lay, lay.names[0], (1989.0, 0.0, -350.0), (5.0, 0.0, 0.0),
                                                   [1e300]), "eta")


@check("nonfinite", "dpca")
def dpca_integrate_speed_1e300():
    """`dpca.integrate(pairs, eta, 1e300, A)`."""
    from clsas.estimate import dpca
    f = fixtures()
    raises(lambda: dpca.integrate(f["pairs"], f["compressed"].eta, 1e300, f["scene"].array), ValueError, "speed")


@check("nonfinite", "harden")
def autofocus_contrast_of_1e200():
    """`autofocus.contrast(np.full(4, 1e200))` inf/NaN."""
    from clsas.estimate import autofocus
    finite_or_refused(lambda: autofocus.contrast(np.full(4, 1e200)))
    value = autofocus.contrast(np.full(4, 1e200))
    if value != 0.0:
        raise Failed(f"contrast of a constant is {value}, not 0")


@check("nonfinite", "papers")
def correct_inclined_array_r_ref_1e300():
    """`correct_inclined_array(echo, r_ref=1e300)`."""
    finite_or_refused(lambda: clsas.correct_inclined_array(fixtures()["strip"], r_ref=1e300), "r_ref")


@check("nonfinite", "papers")
def inclined_and_ptrs_on_samples_of_3e38():
    """inclined and `ptrs_image` on samples of 3e38 return inf."""
    strip = fixtures()["strip"]
    loud = strip.replace(data=np.full_like(strip.data, 3e38))
    finite_or_refused(lambda: clsas.correct_inclined_array(loud), "data")
    finite_or_refused(lambda: clsas.ptrs_image(loud, block_width=8.0), "data")


# --- Crashes ------------------------------------------------------------------------------------

@check("crash", "moving")
def estimate_motion_position_1e300():
    """`estimate_motion(echo, position=(1e300, 0, 0))` IndexError."""
    raises(lambda: clsas.estimate_motion(fixtures()["kiang"], position=(1e300, 0.0, 0.0)), ValueError, "position")


@check("crash", "moving")
def estimate_motion_with_eta_all_zero():
    """`estimate_motion(echo with eta all 0)` ZeroDivisionError."""
    kiang = fixtures()["kiang"]
    raises(lambda: clsas.estimate_motion(kiang.replace(eta=np.zeros_like(kiang.eta))), (ValueError, EstimationError),
           "eta")


@check("crash", "moving")
def solve_velocity_fm_rate_nan():
    """`solve_velocity(fm_rates={'A': nan})` ZeroDivisionError."""
    from clsas.estimate import moving
    raises(lambda: moving.solve_velocity(fixtures()["layout"], (1989.0, 0.0, -350.0), {"A": 10.0, "B": -5.0, "C": 3.0},
                                         fm_rates={"A": np.nan}), ValueError, "fm_rates")


@check("crash", "dpca")
def dpca_integrate_bad_inputs():
    """`dpca.integrate` with equal eta, `pairs=None`, `array=''`, `speed=inf`."""
    from clsas.estimate import dpca
    f = fixtures()
    eta, A, v = f["compressed"].eta, f["scene"].array, f["scene"].platform.speed
    raises(lambda: dpca.integrate(f["pairs"], np.zeros_like(eta), v, A), ValueError, "eta")
    raises(lambda: dpca.integrate(None, eta, v, A), TypeError, "pairs")
    raises(lambda: dpca.integrate(f["pairs"], eta, v, ""), TypeError, "array")
    raises(lambda: dpca.integrate(f["pairs"], eta, np.inf, A), ValueError, "speed")


@check("crash", "dpca")
def dpca_geometry_zeros():
    """`dpca.nominal_shift(A, v, 0.0)`, `beam_sin2(A, 0.0, c)`, `delay_records` of 0 samples."""
    from clsas.estimate import dpca
    from clsas.estimate.dpca.geometry import beam_sin2
    A = fixtures()["scene"].array
    raises(lambda: dpca.nominal_shift(A, 1.0, 0.0), ValueError, "prf")
    raises(lambda: beam_sin2(A, 0.0, 1500.0), ValueError, "f0")
    try:
        out = dpca.delay_records(np.ones((2, 3, 0), np.complex64), np.zeros((2, 3)), 50e3, 20e3)
    except ValueError as err:
        if "data" not in str(err) and "samples" not in str(err):
            raise Failed(f"delay_records of 0 samples: unnamed ValueError: {err}") from None
    except Exception as err:  # noqa: BLE001
        raise Failed(f"delay_records of 0 samples: {type(err).__name__}: {err}") from None
    else:
        if out.shape != (2, 3, 0):
            raise Failed(f"delay_records of 0 samples returned shape {out.shape}")


@check("crash", "harden")
def pga_on_a_constant_y_axis():
    """`pga` on an Image with a constant y axis crashes."""
    from clsas.estimate import autofocus
    image = fixtures()["image"]
    flat = clsas.Image(image.data, image.dims, {"y": np.zeros(image.data.shape[0]), "x": image.axes["x"]})
    raises(lambda: autofocus.pga(flat), (ValueError, EstimationError), "y")


@check("crash", "harden")
def apply_phase_correction_axis_5():
    """`apply_phase_correction(d, phi, 5)` crashes."""
    from clsas.estimate import autofocus
    raises(lambda: autofocus.apply_phase_correction(fixtures()["image"].data, np.zeros(64), 5), ValueError, "axis")


@check("crash", "papers")
def ptrs_block_width_1e300():
    """`ptrs_image(block_width=1e300)` (Newton RuntimeError)."""
    raises(lambda: clsas.ptrs_image(fixtures()["strip"], block_width=1e300), ValueError, "block_width")


@check("crash", "harden")
def load_of_a_bit_flipped_nc():
    """`load` of a bit-flipped .nc (h5py RuntimeError, not DataFileError)."""
    where = folder()
    echo = small_echo()
    path = clsas.save(echo, where / "c.nc", compression=0)
    raw = bytearray(path.read_bytes())
    at = raw.find(echo.data.tobytes()[:64])
    if at < 0:
        raise Failed("the samples were not found in the file")
    raw[at + 17] ^= 0x10
    path.write_bytes(bytes(raw))
    raises(lambda: clsas.load(path), DataFileError, "c.nc")
    rng = np.random.default_rng(27)
    good = bytearray(clsas.save(echo, where / "d.nc").read_bytes())
    for position in rng.integers(0, len(good), 40):
        flipped = bytearray(good)
        flipped[position] ^= 1 << int(rng.integers(8))
        (where / "f.nc").write_bytes(bytes(flipped))
        try:
            back = clsas.load(where / "f.nc")
        except DataFileError:
            continue
        except Exception as err:  # noqa: BLE001
            raise Failed(f"flip at byte {position}: {type(err).__name__}: {str(err)[:160]}") from None
        if not np.array_equal(back.data, echo.data):
            raise Failed(f"flip at byte {position}: other data loaded")


@check("crash", "harden")
def load_scenario_of_what_is_not_toml():
    """`load_scenario` of TOML nested 600 deep (RecursionError), of a non-UTF-8 file or of
    `echo.nc` (UnicodeDecodeError)."""
    where = folder()
    (where / "deep.toml").write_text("a = " + "[" * 600 + "]" * 600 + "\n")
    raises(lambda: clsas.load_scenario(where / "deep.toml"), ScenarioFileError, "deep.toml")
    (where / "latin1.toml").write_bytes("# caf\xe9\n".encode("latin-1"))
    raises(lambda: clsas.load_scenario(where / "latin1.toml"), ScenarioFileError, "latin1.toml")
    echo = clsas.save(small_echo(), where / "echo.nc")
    raises(lambda: clsas.load_scenario(echo), ScenarioFileError, "echo.nc")


@check("crash", "harden")
def grid_of_points_without_axes():
    """`Grid(np.zeros((2, 3)), ("i",), None)` AttributeError."""
    try:
        grid = clsas.Grid(np.zeros((2, 3)), ("i",), None)
    except (TypeError, ValueError) as err:
        if "Grid" not in str(err):
            raise Failed(f"unnamed: {err}") from None
        return
    except Exception as err:  # noqa: BLE001
        raise Failed(f"{type(err).__name__}: {err}") from None
    if grid.shape != (2,):
        raise Failed(f"shape {grid.shape}")


@check("crash", "strip")
def stolt_c_0_and_zero_rows():
    """`stolt` with `c=0`, or 0 rows on OpenCL."""
    from clsas.image.stolt import StoltAxes, stolt
    raises(lambda: StoltAxes(f_first=-1e3, df=10.0, n_src=8, kx_first=-1.0, dkx=0.1, n_out=8, f0=50e3, c=0.0),
           ValueError, "c")
    axes = StoltAxes(f_first=-1e3, df=10.0, n_src=8, kx_first=-1.0, dkx=0.1, n_out=8, f0=50e3, c=1500.0)
    for backend in ("opencl", "numpy"):
        try:
            out = stolt(np.zeros((0, 8), np.complex64), np.zeros(0), axes, backend=backend)
        except ValueError as err:
            if "spectrum" not in str(err):
                raise Failed(f"{backend}: unnamed: {err}") from None
        except Exception as err:  # noqa: BLE001
            raise Failed(f"{backend}: {type(err).__name__}: {err}") from None
        else:
            if out.shape != (0, 8):
                raise Failed(f"{backend}: shape {out.shape}")


# --- Silently accepted ------------------------------------------------------------------------------

@check("accepted", "ffbp")
def ffbp_stop_and_go_no():
    """`ffbp(stop_and_go="no")` (a string read as True)."""
    f = fixtures()
    raises(lambda: clsas.ffbp(f["compressed"], f["grid"], stop_and_go="no", progress=False), TypeError, "stop_and_go")


@check("accepted", "papers")
def inclined_stop_and_go_and_ptrs_deconvolve_no():
    """`correct_inclined_array(stop_and_go="no")`, `ptrs_image(deconvolve="no")`."""
    strip = fixtures()["strip"]
    raises(lambda: clsas.correct_inclined_array(strip, stop_and_go="no"), TypeError, "stop_and_go")
    raises(lambda: clsas.ptrs_image(strip, block_width=8.0, deconvolve="no"), TypeError, "deconvolve")


@check("accepted", "harden")
def echo_replace_compressed_no_and_duplicate_receivers():
    """`EchoData.replace(compressed="no")`, duplicate receiver names."""
    echo = small_echo()
    raises(lambda: echo.replace(compressed="no"), TypeError, "compressed")
    same = ("r",) * echo.data.shape[0]
    raises(lambda: echo.replace(receivers=same), ValueError, "receivers")


@check("accepted", "harden")
def grid_axes_with_nan():
    """`Grid` axes with NaN."""
    raises(lambda: clsas.Grid.plane(np.array([0.0, np.nan]), np.arange(2.0), 0.0), ValueError, "x")


@check("accepted", "dpca")
def dpca_integrate_speed_0():
    """`dpca.integrate(..., speed=0.0)`."""
    from clsas.estimate import dpca
    f = fixtures()
    raises(lambda: dpca.integrate(f["pairs"], f["compressed"].eta, 0.0, f["scene"].array), ValueError, "speed")


@check("accepted", "moving")
def closed_forms_eta_ref_nan():
    """`closed_forms(eta_ref=nan)`."""
    from clsas.estimate import moving
    raises(lambda: moving.closed_forms(fixtures()["layout"], (1989.0, 0.0, -350.0), (5.0, 0.0, 0.0), eta_ref=np.nan),
           ValueError, "eta_ref")


@check("accepted", "harden")
def a_yaw_of_10_rad_as_a_function():
    """A yaw of 10 rad given as a function (the same as an array is refused)."""
    scene = fixtures()["scene"]
    platform = dataclasses.replace(scene.platform, yaw=lambda t: np.full(np.shape(t), 10.0))
    raises(lambda: platform.position_and_attitude(np.zeros(2)) if hasattr(platform, "position_and_attitude")
           else platform.rotation(np.zeros(2)), ValueError, "yaw")
    raises(lambda: clsas.simulate(dataclasses.replace(scene, platform=platform), progress=False, backend="numpy"),
           ValueError, "yaw")


# --- Valid input refused -------------------------------------------------------------------------

@check("valid", "ffbp")
def ffbp_of_one_point_images():
    """`ffbp(comp, Grid.points([[20, 0, 0]]))` says "the sonar never sees this grid" where
    `backproject` images it."""
    f = fixtures()
    z = f["scene"].platform.start[2]
    for point in ([[20.0, 0.0, z]], [[100.0, 0.0, z]]):
        grid = clsas.Grid.points(point)
        with warnings.catch_warnings():
            warnings.simplefilter("error", CoverageWarning)
            try:
                bp = clsas.backproject(f["compressed"], grid, progress=False)
            except (ValueError, CoverageWarning):
                continue  # backproject does not see it either: no disagreement
        fast = clsas.ffbp(f["compressed"], grid, progress=False)
        scale = max(float(np.abs(bp.data).max()), 1e-30)
        err = float(np.abs(fast.data - bp.data).max()) / scale
        if err > 0.05:
            raise Failed(f"at {point[0]}: ffbp departs from backproject by {err:.3f} of its peak")


# --- Messages that do not name the parameter ------------------------------------------------------

@check("messages", "papers")
def correct_inclined_array_depth_a():
    """`correct_inclined_array(depth="a")`."""
    raises(lambda: clsas.correct_inclined_array(fixtures()["strip"], depth="a"), TypeError, "depth")


@check("messages", "ffbp")
def ffbp_aperture_a():
    """`ffbp(aperture="a")`."""
    f = fixtures()
    raises(lambda: clsas.ffbp(f["compressed"], f["grid"], aperture="a", progress=False), TypeError, "aperture")


@check("messages", "moving")
def focus_moving_tau_span_a():
    """`focus_moving(tau_span="a")`."""
    f = fixtures()
    raises(lambda: clsas.focus_moving(f["kiang"], f["motion"], tau_span="a"), TypeError, "tau_span")


@check("messages", "harden")
def load_none_and_ragged_mesh():
    """`load(None)`, a TOML mesh with ragged faces."""
    raises(lambda: clsas.load(None), TypeError, "load path")
    where = folder()
    text = (EXAMPLES / "sphere_and_buoy.toml").read_text()
    ragged = text.replace('kind = "mesh"', 'kind = "mesh"\nvertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\n'
                                           'faces = [[0, 1, 2], [0, 1]]', 1)
    ragged = "\n".join(line for line in ragged.splitlines() if not line.startswith("mesh = ")) + "\n"
    (where / "ragged.toml").write_text(ragged)
    raises(lambda: clsas.load_scenario(where / "ragged.toml"), ScenarioFileError, "ragged.toml", "faces")


# --- CLI ----------------------------------------------------------------------------------------

@check("cli", "harden")
def cli_ctrl_c_prints_one_line():
    """A traceback on Ctrl-C (and an interrupted save leaves no temporary: SIGINT and SIGTERM)."""
    for signum, status in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        where = folder()
        rc, _, err, _ = cli("simulate", "huang2022", "--pulses", "256", "-o", "x.nc", cwd=where,
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", nargs="+", default=None,
                        help="run the checks whose section or name holds a word (the heavy ones only so)")
    parser.add_argument("--json", default=None, help="write the outcomes there")
    args = parser.parse_args()
    chosen = [c for c in CHECKS if (args.k is None and c[0] != "heavy") or
              args.k is not None and any(w in c[0] or w in c[1] for w in args.k)]
    rows = []
    for section, name, owner, fn in chosen:
        start = time.perf_counter()
        try:
            with clsas.use_memory_budget(clsas.memory_budget()):
                fn()
            outcome = None
        except Failed as err:
            outcome = str(err)
        except Exception as err:  # noqa: BLE001 - the check itself broke: a failure too
            outcome = f"the check broke: {type(err).__name__}: {str(err)[:200]}"
        seconds = time.perf_counter() - start
        rows.append(dict(section=section, check=name, owner=owner, issue=" ".join(fn.__doc__.split()),
                         passed=outcome is None, outcome=outcome, seconds=round(seconds, 2)))
        print(f"{'ok  ' if outcome is None else 'FAIL'} [{owner}] {section}: {name} ({seconds:.1f} s)"
              + ("" if outcome is None else f"\n       {outcome}"), flush=True)
    failed = [r for r in rows if not r["passed"]]
    by_owner = {}
    for r in failed:
        by_owner[r["owner"]] = by_owner.get(r["owner"], 0) + 1
    print(f"{len(rows) - len(failed)} of {len(rows)} checks pass; failing by owner: "
          + (", ".join(f"{k} {v}" for k, v in sorted(by_owner.items())) or "none"))
    if args.json:
        Path(args.json).write_text(json.dumps({"load": os.getloadavg(), "checks": rows}, indent=1))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
