"""The strip-map imager template (clsas.image.strip): one signature and one default rule for
every imager, the checks made before anything is built, the cost of secondary range
compression against numerical PTRS."""

from __future__ import annotations

import inspect
import time
import warnings

import numpy as np
import pytest
from _line_scenes import MONO_D, mono_grid

import clsas
from clsas.image.ptrs import StationaryPoints
from clsas.image.record import line_record
from clsas.image.strip import strip_job
from clsas.scene import presets
from clsas.scene.targets import PointTargets

IMAGERS = ["omega_k", "range_doppler", "chirp_scaling", "nonlinear_chirp_scaling"]


def test_every_imager_has_the_template_signature():
    """The same parameters, defaults and kinds: ``data`` then keyword-only options."""
    template = inspect.signature(strip_job)
    expected = list(template.parameters.values())[1:]
    for name in IMAGERS:
        params = list(inspect.signature(getattr(clsas, name)).parameters.values())
        assert params == expected, name
        assert all(p.kind in (p.KEYWORD_ONLY, p.VAR_KEYWORD) for p in params[1:]), name
    assert template.parameters["window"].default == "none"


@pytest.mark.parametrize("name", IMAGERS)
def test_options_are_keyword_only(name):
    _, echo = mono_grid()
    with pytest.raises(TypeError, match="positional"):
        getattr(clsas, name)(echo, 0)


@pytest.mark.parametrize("name", IMAGERS)
def test_default_is_unweighted(opencl_device, name):
    """The default image equals the one asked for with window="none", for every imager."""
    _, echo = mono_grid()
    imager = getattr(clsas, name)
    default = imager(echo, elements=(MONO_D, MONO_D))
    assert default.provenance["window"] == "none"
    assert np.array_equal(default.data, imager(echo, elements=(MONO_D, MONO_D), window="none").data)


def test_only_the_processed_band_is_computed(opencl_device):
    """With elements, the rows outside |k_u| <= 2 pi / D are not computed (their weight is 0)."""
    _, echo = mono_grid()
    rec = line_record(echo)
    job = strip_job("range_doppler", rec, elements=(MONO_D, MONO_D))
    assert np.all(np.abs(job.ku) <= 2 * np.pi / MONO_D)
    assert 0 < job.rows.size < job.n_ku
    assert strip_job("range_doppler", rec).rows.size == job.n_ku


@pytest.mark.parametrize("name", IMAGERS)
def test_one_compressed_echo_check(name):
    _, echo = mono_grid()
    with pytest.raises(ValueError, match=rf"{name} data: must be a range-compressed echo \(EchoData.compressed True\), "
                                         "got a raw one; call clsas.range_compress"):
        getattr(clsas, name)(echo.replace(compressed=False), backend="numpy")


def test_line_record_is_validated():
    _, echo = mono_grid()
    rec = line_record(echo, backend="numpy")
    with pytest.raises(ValueError, match="LineRecord.fs"):
        rec.replace(fs=0.0)
    with pytest.raises(ValueError, match="LineRecord.du"):
        rec.replace(du=np.nan)
    with pytest.raises(TypeError, match="LineRecord.data"):
        rec.replace(data=rec.data.real)
    with pytest.raises(TypeError, match="LineRecord.nonstop"):
        rec.replace(nonstop="no")
    bad = rec.data.copy()
    bad[3, 4] = np.nan
    with pytest.raises(ValueError, match="range_doppler data: the LineRecord's samples must be finite"):
        clsas.range_doppler(rec.replace(data=bad), backend="numpy")
    with pytest.raises(ValueError, match="omega_k receiver"):
        clsas.omega_k(rec, receiver=1, backend="numpy")


def zhang_quick():
    """The quick scene of bench/bench_strip.py: Zhang 2019's sonar, 2 points, 32 pulses."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = presets.zhang2019(n_pulses=32, receivers=30, pri=0.15)
        sc = sc.replace(targets=(PointTargets([[44.0, -1.0, 0.0], [54.0, 1.0, 0.0]]),))
        return clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


def test_pca_strip_imaging_costs_less_than_ptrs_with_8_sub_blocks(opencl_device):
    """PCA + range-Doppler and PCA + chirp scaling no slower than numerical PTRS with
    8 sub-blocks on Zhang's sonar, as a ratio of times in one process (the minimum of 3
    interleaved runs each, so that a loaded machine slows all alike)."""
    echo = zhang_quick()
    swath = echo.medium.sound_speed * echo.n_samples / echo.fs / 2
    common = {"elements": (0.04, 0.02), "deconvolve": False, "backend": "opencl"}
    points = StationaryPoints()
    runs = {
        "ptrs8": lambda: clsas.ptrs_image(echo, block_width=swath / 8, points=points, **common),
        "rda": lambda: clsas.range_doppler(clsas.pca_record(echo, backend="opencl"), **common),
        "csa": lambda: clsas.chirp_scaling(clsas.pca_record(echo, backend="opencl"), **common),
    }
    for run in runs.values():
        run()
    best = {name: np.inf for name in runs}
    for _ in range(3):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            best[name] = min(best[name], time.perf_counter() - start)
    assert best["rda"] < best["ptrs8"], best
    assert best["csa"] < best["ptrs8"], best


def test_strip_imagers_refuse_what_they_cannot_image():
    _, echo = mono_grid()
    with pytest.raises(TypeError, match="range_doppler data: must be a LineRecord"):
        clsas.range_doppler(echo.data[0])
    with pytest.raises(TypeError, match="chirp_scaling deconvolve"):
        clsas.chirp_scaling(echo, deconvolve="no", backend="numpy")
    with pytest.raises(ValueError, match="omega_k interp"):
        clsas.omega_k(echo, interp="cubic", backend="numpy")
    with pytest.raises(TypeError, match="unknown window option"):
        clsas.range_doppler(echo, hamming_alpha=0.5, backend="numpy")
