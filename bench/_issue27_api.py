"""Issue #27's reproducers in the estimators and imagers (memory budget, NaN/inf from finite
input, crashes, silently accepted values, valid input refused, messages): the checks
bench/issue27_check.py runs, each naming the developer who owns the code."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
from _issue27 import EXAMPLES, Failed, check, finite_or_refused, fixtures, folder, raises, small_echo, within_budget

import clsas
from clsas.errors import DataFileError, EstimationError, ScenarioFileError
from clsas.validate import CoverageWarning


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
