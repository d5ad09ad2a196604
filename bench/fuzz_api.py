"""Fuzz of the public API as issue #27 ran it: tiny scenes, one argument of a valid call replaced by
NaN, inf, 1e300, 3e38, 0, a negative number, 2**64 or a value of the wrong kind, about 450 calls
a seed; each outcome judged by the project's rule (docs/design.md, clsas.validate):

- ``crash``: an exception other than TypeError, ValueError (MemoryBudgetError, ScenarioFileError
  and DataFileError are ValueErrors), OSError or EstimationError;
- ``unnamed``: a TypeError/ValueError whose message does not name the parameter;
- ``kind``: a value of the wrong kind (a string, None where None is not allowed, a bool, a
  complex number, an object, a list for a number) refused with a ValueError, not a TypeError;
- ``choice``: a value not among a choice's options refused with anything but a ValueError (a
  choice is judged by membership, whatever the value's kind: docs/design.md, ``validate.choice``);
- ``accepted``: a value of the wrong kind, or a nonsense string for a choice, accepted;
- ``nonfinite``: a finite input (1e300, 3e38, 0, ...) giving NaN or inf in the result;
- ``hang``: no answer within ``--timeout`` seconds.

    python bench/fuzz_api.py --seeds 1 2 --json fuzz.json     # about 900 calls, a few minutes

Prints each defect once (function, parameter, value, what happened) with the owner of the
module it sits in, then a count by owner; ``--json`` writes them all.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import random
import signal
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import clsas  # noqa: E402
from clsas.errors import EstimationError  # noqa: E402

#: module prefix -> the developer who owns it (docs: /work/team; the issue's owners)
OWNERS = (("clsas.estimate.moving", "moving"), ("clsas.estimate.dpca", "dpca"), ("clsas.image.ffbp", "ffbp"),
          ("clsas.image.backprojection", "bp2"), ("clsas.image.ptrs", "papers"), ("clsas.image.inclined", "papers"),
          ("clsas.image.rangecomp", "seafloor"), ("clsas.scene.seafloor", "seafloor"),
          ("clsas.synthesis", "seafloor"), ("clsas.image", "strip"), ("clsas.interp", "papers"), ("clsas", "harden"))

REAL_BAD = (math.nan, math.inf, -math.inf, 1e300, -1e300, 3e38, 0.0, -1.0, 2**64)
WRONG_KIND = ("a", None, True, 1j, object(), [1.0, 2.0])
CHOICE_BAD = ("", "NONE", "unknown")


@dataclass(frozen=True)
class Param:
    """A parameter of a fuzzed call: its kind ("real", "int", "flag", "choice", "vector",
    "other") and whether None is a valid value of it (the default)."""

    name: str
    kind: str
    none_ok: bool = False


@dataclass(frozen=True)
class Target:
    name: str
    call: object  # call(**{param: value}) with every other argument valid
    params: tuple
    module: str


class Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise Timeout()


def owner(module: str) -> str:
    return next(who for prefix, who in OWNERS if module == prefix or module.startswith(prefix + "."))


def values_for(p: Param) -> list:
    wrong = [v for v in WRONG_KIND if not (v is None and p.none_ok)]
    if p.kind == "real":
        return list(REAL_BAD) + wrong
    if p.kind == "int":
        return [0, -1, 2**64, 10**30, 2.5, 2.0] + wrong
    if p.kind == "flag":
        return ["no", "yes", 0, 1, 1.0] + [v for v in wrong if v is not True]
    if p.kind == "choice":
        return list(CHOICE_BAD) + [v for v in wrong if v != "a"]
    if p.kind == "vector":
        return [(math.nan, 0.0, 0.0), (1e300, 0.0, 0.0), (math.inf, 0.0, 0.0), (1.0, 2.0), "abc"] + \
            [v for v in wrong if not isinstance(v, (str, list))]
    return list(REAL_BAD[:3]) + wrong


def wrong_kind(p: Param, value) -> bool:
    """Whether ``value`` is of the wrong kind for ``p`` (then a TypeError is the rule)."""
    if value is None:
        return not p.none_ok
    if isinstance(value, bool):
        return p.kind != "flag"
    if p.kind == "real":
        return not isinstance(value, (int, float))
    if p.kind == "int":
        return not isinstance(value, int)
    if p.kind == "flag":
        return True
    if p.kind == "choice":
        return not isinstance(value, str)
    if p.kind == "vector":
        return isinstance(value, (str, complex)) or type(value) is object
    return isinstance(value, complex) or type(value) is object


def finite_result(result, depth: int = 0) -> bool:
    """No NaN or inf in ``result``'s arrays and floats (dicts, tuples, dataclasses and objects'
    ``image`` / ``data`` searched, three levels down)."""
    if isinstance(result, (float, complex, np.floating, np.complexfloating)):
        return bool(np.isfinite(result))
    if isinstance(result, np.ndarray):
        return result.dtype.kind not in "fc" or bool(np.all(np.isfinite(result)))
    if depth > 2:
        return True
    if isinstance(result, dict):
        return all(finite_result(v, depth + 1) for v in result.values())
    if isinstance(result, tuple):
        return all(finite_result(v, depth + 1) for v in result)
    if dataclasses.is_dataclass(result):
        return all(finite_result(getattr(result, f.name), depth + 1) for f in dataclasses.fields(result))
    return all(finite_result(getattr(result, a), depth + 1) for a in ("image", "data") if hasattr(result, a))


def judge(target: Target, p: Param, value, timeout: float) -> str | None:
    """None when the call kept the rule, else what went wrong (one line)."""
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(int(timeout))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = target.call(**{p.name: value})
    except Timeout:
        return f"hang: no answer in {timeout:g} s"
    except (TypeError, ValueError) as err:
        text = str(err)
        named = p.name in text or p.name.replace("_", " ") in text
        if not named and target.name.split(".")[-1] not in text:  # may name another parameter its value clashes with
            return f"unnamed: {type(err).__name__}: {text[:160]}"
        if p.kind == "choice":  # judged by membership: anything not among the options, a ValueError
            return None if isinstance(err, ValueError) else \
                f"choice: {type(err).__name__} for a value not among the options (a ValueError): {text[:120]}"
        if wrong_kind(p, value) and not isinstance(err, TypeError) and not isinstance(value, list):
            return f"kind: ValueError for a value of the wrong kind: {text[:120]}"
        return None
    except (OSError, EstimationError):
        return None
    except Exception as err:  # noqa: BLE001 - the defect this fuzz looks for
        return f"crash: {type(err).__name__}: {str(err)[:160]}"
    finally:
        signal.alarm(0)
    if wrong_kind(p, value) or (p.kind == "choice" and value in CHOICE_BAD):
        return "accepted: " + ("a value of the wrong kind" if wrong_kind(p, value) else "a nonsense choice")
    finite_in = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) or \
        isinstance(value, tuple) and all(isinstance(v, float) and math.isfinite(v) for v in value)
    if finite_in and not finite_result(result):
        return "nonfinite: NaN or inf from finite input"
    return None


# --- the tiny scenes and the targets --------------------------------------------------------------

@functools.cache
def fixtures() -> dict:
    from clsas.estimate import dpca, moving
    from clsas.scene import presets

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        point = presets.point_scene("heremans2009", n_pulses=8)
        echo = clsas.simulate(point, progress=False, backend="numpy")
        strip = clsas.simulate(presets.point_scene("huang2022", n_pulses=16), progress=False)
        kiang = clsas.simulate(presets.kiang2022_case(1, n_pulses=128), progress=False)
        mono = clsas.range_compress(clsas.simulate(dataclasses.replace(point, array=clsas.Array(rx_offsets=[[0.0, 0.0, 0.0]])),
                                                   progress=False, backend="numpy"))
    compressed = clsas.range_compress(echo)
    strip_c = clsas.range_compress(strip)
    pairs = dpca.estimate(compressed, point.array, point.platform.speed)
    track = dpca.integrate(pairs, compressed.eta, point.platform.speed, point.array)
    still = dataclasses.replace(track, along=np.zeros_like(track.along), cross=np.zeros_like(track.cross),
                                heading=np.zeros_like(track.heading))  # the true track: no motion
    folder = Path(tempfile.mkdtemp(prefix="clsas-fuzz-"))
    rng = np.random.default_rng(0)
    img = (0.01 * (rng.standard_normal((64, 16)) + 1j * rng.standard_normal((64, 16)))).astype(np.complex64)
    img[32, ::4] += 10
    return {"scene": point, "echo": echo, "compressed": compressed, "strip": strip_c,
            "record": clsas.pca_record(strip_c), "kiang": kiang, "layout": moving.layout_of(kiang),
            "pairs": pairs, "track": still, "mono": mono, "motion": clsas.estimate_motion(kiang),
            "grid": clsas.Grid.plane(np.linspace(95, 105, 8), np.linspace(-2, 2, 8), point.platform.start[2]),
            "image": clsas.Image(img, ("y", "x"), {"y": np.arange(64) * 0.01, "x": np.arange(16) * 0.01}),
            "folder": folder, "saved": clsas.save(compressed, folder / "e.nc"),
            "toml": clsas.scenario_to_toml(point, folder / "scene.toml")}


def targets() -> list:
    from clsas import metrics
    from clsas.estimate import autofocus, dpca, moving
    from clsas.image.backprojection import prepare

    f = fixtures()
    R, I, F, C, V = "real", "int", "flag", "choice", "vector"

    def t(name, call, module, *params):
        return Target(name, call, tuple(Param(*p) if isinstance(p, tuple) else p for p in params), module)

    def kw(fn, *args, **fixed):
        return lambda **k: fn(*args, **{**fixed, **k})

    scene, comp, strip, rec = f["scene"], f["compressed"], f["strip"], f["record"]
    track = scene.platform.start[2]
    out = [
        t("Grid.plane", lambda x=np.arange(3.0), y=np.arange(2.0), z=0.0: clsas.Grid.plane(x, y, z), "clsas.model.grid",
          ("z", R)),
        t("Medium", kw(clsas.Medium), "clsas.model.medium", ("sound_speed", R), ("temperature", R), ("salinity", R)),
        t("Waveform", kw(clsas.Waveform, f0=50e3, bandwidth=10e3, duration=2e-3, fs=20e3), "clsas.model.waveform",
          ("f0", R), ("bandwidth", R), ("duration", R), ("fs", R)),
        t("simulate", kw(clsas.simulate, scene, progress=False, backend="numpy"), "clsas.synthesis",
          ("snr_db", R, True), ("seed", I, True), ("stop_and_go", F), ("multipath", I)),
        t("range_compress", kw(clsas.range_compress, f["echo"]), "clsas.image.rangecomp",
          ("window", C), ("upsample", I)),
        t("backproject", kw(clsas.backproject, comp, f["grid"], progress=False), "clsas.image.backprojection",
          ("upsample", I, True), ("interp", C, True), ("aperture", R, True), ("stop_and_go", F)),
        t("ffbp", kw(clsas.ffbp, comp, f["grid"], progress=False), "clsas.image.ffbp",
          ("factor", I), ("tolerance", R), ("upsample", I), ("aperture", R, True), ("stop_and_go", F), ("first", I, True)),
        t("prepare", kw(prepare, comp), "clsas.image.backprojection", ("upsample", I), ("interp", C),
          ("workers", I, True)),
        t("omega_k", kw(clsas.omega_k, rec), "clsas.image.omegak", ("window", C), ("depth", R, True),
          ("deconvolve", F), ("interp", C)),
        t("range_doppler", kw(clsas.range_doppler, rec), "clsas.image.rda", ("window", C), ("depth", R, True)),
        t("chirp_scaling", kw(clsas.chirp_scaling, rec), "clsas.image.csa", ("window", C), ("depth", R, True)),
        t("nonlinear_chirp_scaling", kw(clsas.nonlinear_chirp_scaling, rec), "clsas.image.ncs", ("window", C),
          ("depth", R, True)),
        t("ptrs_image", kw(clsas.ptrs_image, strip, block_width=8.0), "clsas.image.ptrs", ("block_width", R, True),
          ("deconvolve", F), ("rcmc", F), ("depth", R, True), ("window", C)),
        t("correct_inclined_array", kw(clsas.correct_inclined_array, strip), "clsas.image.inclined",
          ("depth", R, True), ("r_ref", R, True), ("stop_and_go", F, True), ("yaw", R, True), ("pitch", R, True)),
        t("estimate_motion", kw(clsas.estimate_motion, f["kiang"]), "clsas.estimate.moving",
          ("position", V, True)),
        t("solve_velocity", kw(moving.solve_velocity, f["layout"], (1989.0, 0.0, -350.0), {"A": 10.0, "B": -5.0, "C": 3.0}),
          "clsas.estimate.moving", ("v_max", R), ("step", R), ("model", C)),
        t("closed_forms", lambda position=(1989.0, 0.0, -350.0), velocity=(5.0, 5.0, 0.0), **k: moving.closed_forms(
            f["layout"], position, velocity, **k), "clsas.estimate.moving", ("position", V), ("velocity", V),
          ("eta_ref", R, True), ("model", C)),
        t("dpca.nominal_shift", lambda prf=scene.schedule.prf, speed=scene.platform.speed: dpca.nominal_shift(
            scene.array, speed, prf), "clsas.estimate.dpca", ("prf", R), ("speed", R)),
        t("dpca.delay_records", lambda f0=50e3, fs=20e3: dpca.delay_records(np.ones((2, 3, 16), np.complex64),
                                                                           np.zeros((2, 3)), f0, fs),
          "clsas.estimate.dpca", ("f0", R), ("fs", R)),
        t("pga", kw(autofocus.pga, f["image"]), "clsas.estimate.autofocus", ("tolerance", R), ("max_iterations", I),
          ("select_db", R), ("window_db", R), ("min_contrast", R), ("min_window", I), ("workers", I, True)),
        t("apply_phase_correction", lambda axis=0, workers=None: autofocus.apply_phase_correction(
            f["image"].data, np.zeros(64), axis, workers), "clsas.estimate.autofocus", ("axis", I), ("workers", I, True)),
        t("metrics.point_response", kw(metrics.point_response, np.sinc((np.arange(64) - 32.3) / 2)), "clsas.metrics",
          ("upsample", I), ("extent", R), ("near", R, True)),
        t("metrics.contrast", lambda data=np.ones(4): metrics.contrast(data), "clsas.metrics", ("data", "other")),
        t("save", lambda compression=1, overwrite=True: clsas.save(comp, f["folder"] / "s.nc", compression=compression,
                                                                   overwrite=overwrite), "clsas.io.files",
          ("compression", I), ("overwrite", F)),
        t("load", lambda path=f["saved"]: clsas.load(path), "clsas.io.files", ("path", "other")),
        t("load_scenario", lambda path=f["toml"]: clsas.load_scenario(path), "clsas.io.toml", ("path", "other")),
        t("EchoData.replace", kw(comp.replace), "clsas.model.echo", ("fs", R), ("compressed", F)),
        t("use_memory_budget", lambda nbytes="1G": clsas.use_memory_budget(nbytes).__enter__(), "clsas.budget",
          ("nbytes", "other", True)),
        # added since the first hardening (session 3): the seafloor and the water, simulate's new
        # options, the moving-target chain's entry points, DPCA, the conversions
        t("Seafloor", kw(clsas.Seafloor, extent=(90.0, 110.0, -5.0, 5.0), z=-10.0), "clsas.scene.seafloor",
          ("z", R), ("spacing", R), ("ripple_wavelength", R), ("ripple_height", R), ("ripple_direction", R),
          ("scatterers_per_cell", R), ("facet_spacing", R, True), ("beam_nulls", I), ("seed", I), ("law", C),
          ("sediment", "other")),  # a name or a Sediment: other kinds are TypeErrors
        t("Sediment", kw(clsas.Sediment), "clsas.scene.seafloor", ("density_ratio", R), ("sound_speed_ratio", R),
          ("loss", R), ("spectral_exponent", R), ("spectral_strength", R), ("volume_ratio", R),
          ("lambert_mu_db", R, True)),
        t("SeaSurface", kw(clsas.SeaSurface), "clsas.scene.surface", ("z", R), ("rms_height", R)),
        t("Medium.absorption", kw(clsas.Medium), "clsas.model.medium", ("depth", R), ("ph", R)),
        t("absorption_db_per_km", lambda frequency_hz=50e3: clsas.absorption_db_per_km(frequency_hz),
          "clsas.synthesis", ("frequency_hz", "other")),  # a number or an array of them
        t("simulate.options", kw(clsas.simulate, scene, progress=False, backend="numpy"), "clsas.synthesis",
          ("intra_pulse", C), ("compressed_level_db", R), ("precision", C), ("reuse_tolerance", R)),
        t("estimate_motions", kw(clsas.estimate_motions, f["kiang"], n_targets=1), "clsas.estimate.moving",
          ("n_targets", I), ("p0", R), ("threshold_db", R)),
        t("focus_moving", kw(clsas.focus_moving, f["kiang"], f["motion"], half_size=2.0, spacing=0.1),
          "clsas.estimate.moving", ("tau_span", R, True), ("sharpen", F), ("method", C), ("spacing", R, True),
          ("half_size", "other", True)),  # a number or (range, along-track)
        t("dpca.estimate", kw(dpca.estimate, comp, scene.array, scene.platform.speed), "clsas.estimate.dpca",
          ("speed", R), ("lags", I), ("t_lags", I), ("block", I), ("n_angles", I), ("min_coherence", R)),
        t("dpca.integrate", lambda speed=scene.platform.speed, heading0=0.0: dpca.integrate(
            f["pairs"], comp.eta, speed, scene.array, heading0=heading0), "clsas.estimate.dpca", ("speed", R),
          ("heading0", R)),
        t("dpca.compensate_record", kw(dpca.compensate_record, comp, f["track"], scene, list(range(4, 11))),
          "clsas.estimate.dpca", ("depth", R, True), ("subaperture", I), ("workers", I, True)),
        t("line_record", kw(clsas.line_record, f["mono"]), "clsas.image.record", ("interp", C), ("tap_window", C),
          ("stop_and_go", F, True)),
        t("scenario_to_toml", lambda inline_meshes=None: clsas.scenario_to_toml(scene, inline_meshes=inline_meshes),
          "clsas.io.toml", ("inline_meshes", F, True)),
        t("to_xarray", lambda obj=comp: clsas.to_xarray(obj), "clsas.io.dataset", ("obj", "other")),
        t("from_xarray", lambda ds=clsas.to_xarray(comp): clsas.from_xarray(ds), "clsas.io.dataset", ("ds", "other")),
        t("use_backend", lambda name="numpy": clsas.use_backend(name).__exit__(None, None, None), "clsas.backend",
          ("name", C)),
    ]
    return out


def baseline(all_targets: list) -> list:
    """The targets whose valid call (no argument replaced) returns: a fuzz of a call that fails
    anyway would blame the values."""
    kept = []
    for target in all_targets:
        try:
            with warnings.catch_warnings(), clsas.use_memory_budget(clsas.memory_budget()):
                warnings.simplefilter("ignore")
                target.call()
        except Exception as err:  # noqa: BLE001 - reported, the target left out
            print(f"[{owner(target.module)}] {target.name}(): the valid call fails ({type(err).__name__}: "
                  f"{str(err)[:120]}); left out")
        else:
            kept.append(target)
    return kept


def run(seeds, calls_per_seed: int | None, timeout: float) -> tuple[list, int]:
    """The defects found (each once) and the number of calls: per seed, ``calls_per_seed`` of
    the (function, parameter, value) combinations drawn without repeats (None: all of them)."""
    found, calls = {}, 0
    combos = [(target, p, value) for target in baseline(targets()) for p in target.params for value in values_for(p)]
    for seed in seeds:
        order = random.Random(seed).sample(combos, len(combos) if calls_per_seed is None else
                                           min(calls_per_seed, len(combos)))
        for target, p, value in order:
            with clsas.use_memory_budget(clsas.memory_budget()):  # the budget back after a use_memory_budget call
                verdict = judge(target, p, value, timeout)
            calls += 1
            if verdict is not None:
                key = (target.name, p.name, repr(value)[:40], verdict.split(":")[0])
                found.setdefault(key, dict(function=target.name, parameter=p.name, value=repr(value)[:60],
                                           verdict=verdict, owner=owner(target.module), seed=seed))
    return list(found.values()), calls


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--calls", type=int, default=450, help="calls a seed (default 450; 0: every combination)")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds a call may take")
    parser.add_argument("--json", default=None, help="write the defects found there")
    args = parser.parse_args()
    start = time.perf_counter()
    defects, calls = run(args.seeds, args.calls or None, args.timeout)
    for d in sorted(defects, key=lambda d: (d["owner"], d["function"], d["parameter"])):
        print(f"[{d['owner']}] {d['function']}({d['parameter']}={d['value']}): {d['verdict']}")
    owners = {}
    for d in defects:
        owners[d["owner"]] = owners.get(d["owner"], 0) + 1
    print(f"{len(defects)} distinct defects in {calls} calls ({time.perf_counter() - start:.0f} s): "
          + ", ".join(f"{k} {v}" for k, v in sorted(owners.items())))
    if args.json:
        Path(args.json).write_text(json.dumps({"seeds": args.seeds, "calls": calls,
                                               "defects": defects}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
