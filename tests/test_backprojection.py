"""Back-projection: OpenCL kernel vs NumPy reference, focusing physics, multistatic and moving targets."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _tolerances import phase_error, rel_l2

import clsas
from clsas import metrics
from clsas.model import Grid
from clsas.geometry import legs
from clsas.image.backprojection import GridPlan, TileKernel, backproject, prepare
from clsas.image.backprojection.records import UPSAMPLE_BLOCK, reach, upsample_blocks
from clsas.image.backprojection.tiles import PHASE_BUDGET, plan_tiles, tile_half_extent
from clsas.image.rangecomp import upsample_records
from clsas.scene import presets
from clsas.scene.targets import PointTargets


def oversampled(scenario, factor=2.0):
    wf = scenario.waveform
    return scenario.replace(waveform=dataclasses.replace(wf, fs=factor * wf.bandwidth))


def compressed(scenario, **kw):
    return clsas.range_compress(clsas.simulate(scenario, backend="opencl", progress=False, **kw))


def around(p, dx, dy, nx=24, ny=24):
    return Grid.plane(p[0] + dx * np.arange(-nx, nx + 1), p[1] + dy * np.arange(-ny, ny + 1), p[2])


# ---------------------------------------------------------------- kernel vs reference

@pytest.fixture(scope="module")
def kiang_echo():
    """Kiang & Kiang 2022 geometry (A, towed B, sonobuoy C): targets at 30 m and 2 km, moving."""
    sc = oversampled(presets.kiang2022(n_pulses=24)).replace(targets=(
        PointTargets([[1989.0, 0.0, -350.0], [30.0, 1.0, -43.0]], velocity=(0.5, -1.0, 0.0)),))
    # the kernel and its reference place each path's pulse at one delay (stop-in-pulse): so does the echo
    return compressed(sc, intra_pulse="none")


@pytest.mark.parametrize("interp", ["linear", "sinc8"])
@pytest.mark.parametrize("centre", [(1989.0, 0.0, -350.0), (30.0, 1.0, -43.0)])
def test_kernel_matches_reference(opencl_device, kiang_echo, interp, centre):
    grid = around(centre, 0.02, 0.05, 12, 12)
    kw = dict(interp=interp, upsample=4, target_velocity=(0.5, -1.0, 0.0), progress=False)
    ref = backproject(kiang_echo, grid, backend="numpy", **kw)
    got = backproject(kiang_echo, grid, backend="opencl", **kw)
    # float32 budget: relative L2 < 5e-3, phase at the peak < 0.01 rad; delays and carrier
    # cycles are double in the kernel, so both are met by orders of magnitude: measured relative
    # L2 1.3e-6 to 8.5e-6 and peak phase 2.4e-9 to 9.6e-9 rad over the four cases (session 16); bounds ~6-10x
    assert rel_l2(got.data, ref.data) < 5e-5
    peak = metrics.peak_index(ref.data)
    assert metrics.peak_index(got.data) == peak
    assert phase_error(got.data[peak], ref.data[peak]) < 1e-7
    dbl = backproject(kiang_echo, grid, backend="opencl", precision="double", **kw)
    assert rel_l2(dbl.data, ref.data) < 1e-7


@pytest.mark.parametrize("options", [dict(stop_and_go=True), dict(aperture=0.2), dict(receivers=["C"])])
def test_kernel_matches_reference_options(opencl_device, kiang_echo, options):
    grid = around((1989.0, 0.0, -350.0), 0.02, 0.05, 8, 8)
    ref = backproject(kiang_echo, grid, backend="numpy", progress=False, **options)
    got = backproject(kiang_echo, grid, backend="opencl", progress=False, **options)
    assert rel_l2(got.data, ref.data) < 2e-4  # measured 1.3e-5 to 2.2e-5


@pytest.mark.parametrize("stop_and_go", [False, True])
def test_the_avx512_and_the_portable_reads_give_the_same_image(opencl_device, kiang_echo, monkeypatch, stop_and_go):
    """bp_tile's linear interpolation reads its samples by CLSAS_READ16 (inline assembly, built
    where the target has AVX512F and AVX512VL) or by TRANSPOSE8 (AVX2 and every other target):
    the same floats moved, so the same image bit for bit. An AVX-512 machine builds only READ16 by
    default: the second image is built with CLSAS_NO_READ16, so both paths run here (a lane
    swapped in either fails this or test_kernel_matches_reference)."""
    from clsas import opencl

    grid = around((30.0, 1.0, -43.0), 0.02, 0.05, 12, 12)
    kw = dict(interp="linear", upsample=4, target_velocity=(0.5, -1.0, 0.0), stop_and_go=stop_and_go,
              progress=False)
    default = backproject(kiang_echo, grid, backend="opencl", **kw)
    build = opencl.kernel

    def portable(name, kernel_name, defines=None, **options):
        if name == "bp_tile":
            defines = {**(defines or {}), "CLSAS_NO_READ16": 1}
        return build(name, kernel_name, defines=defines, **options)

    monkeypatch.setattr(opencl, "kernel", portable)
    got = backproject(kiang_echo, grid, backend="opencl", **kw)
    assert np.array_equal(got.data, default.data)
    ref = backproject(kiang_echo, grid, backend="numpy", **kw)
    assert rel_l2(got.data, ref.data) < 5e-5  # as test_kernel_matches_reference


def test_aperture_sums_only_the_pulses_that_see_a_tile(opencl_device):
    """With an aperture, bp_tile sums for each tile only the pulses of its PULSE_SPAN
    (TileKernel.spans): a track 4x longer than the beam's footprint, a grid
    along all of it (several tiles). Every pulse the exact mask keeps for a pixel lies in its
    tile's span, most pulses are culled, and the image matches the NumPy reference."""
    sc = clsas.Scenario(medium=clsas.Medium(1500.0), waveform=clsas.Waveform(f0=150e3, bandwidth=20e3, duration=2e-3, fs=25e3),
                        platform=clsas.Platform(speed=1.0),
                        array=clsas.Array(rx_offsets=[[0.0, 0.0, 0.0]], tx_length=0.1, rx_length=0.1),
                        schedule=clsas.PulseSchedule(prf=40.0, n_pulses=512),
                        targets=(PointTargets([[10.0, y, -2.0] for y in (-5.0, -1.0, 3.0, 6.0)]),))
    echo = clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False), upsample=4)
    grid = Grid.plane(np.arange(9.0, 11.0, 0.05), np.arange(-6.4, 6.4, 0.1), -2.0)
    half_sin, pixels = np.sin(0.1), grid.positions.reshape(-1, 3)
    tiling = plan_tiles(pixels, 150e3, 1500.0)
    pulses = np.arange(echo.n_pulses)
    tile = TileKernel("linear", aperture=0.2)
    ref, _ = tile.references(echo, 0, pulses, tiling.centres, echo.fs, tiling.half_extent)
    spans = tile.spans(ref, tiling.half_extent, 1500.0, 0)
    assert tiling.centres.shape[0] >= 4
    _, q, _, _ = legs(echo, 0, pulses, pixels, np.zeros(3), False)
    d = q - echo.tx_pos[pulses][:, None, :]
    kept = np.abs(d[..., 1] / np.linalg.norm(d, axis=-1)) <= half_sin     # (P, M): the reference's mask
    tile = np.empty(pixels.shape[0], int)
    tile[tiling.order[tiling.real]] = np.repeat(tiling.tile, TileKernel.LANES * tiling.rows)[tiling.real]
    p_idx, m_idx = np.nonzero(kept)
    assert np.all((spans[tile[m_idx], 0] <= p_idx) & (p_idx < spans[tile[m_idx], 1]))
    culled = 1 - (spans[:, 1] - spans[:, 0]).sum() / (spans.shape[0] * echo.n_pulses)
    assert culled > 0.45  # measured 0.554 (the beam's footprint is a quarter of the track; tiles ~3.9 m)
    kw = dict(aperture=0.2, progress=False)
    ref_img = backproject(echo, grid, backend="numpy", **kw)
    got = backproject(echo, grid, backend="opencl", **kw)
    assert rel_l2(got.data, ref_img.data) < 5e-5  # measured 4.8e-6


@pytest.mark.parametrize("stop_and_go", [True, False])
def test_bp_tile_store_starts_the_image(opencl_device, kiang_echo, monkeypatch, stop_and_go):
    """bp_tile with store=True (BP_STORE: ffbp's first stage, and each lane's first launch without CARRY in the
    launcher, launcher.FIRST_LAUNCH_STORES) stores a launch's sums instead of adding them: calls whose image
    buffers (the lanes' sums) start as NaN give the image of calls that zero them and add every launch, bit for
    bit, on one lane, on two and with carried blocks (whose first launch adds into zeroed sums); store with a
    scatter index is refused."""
    import pyopencl as cl

    from clsas.image.backprojection import launcher, records, tile_kernel

    grid = around((1989.0, 0.0, -350.0), 0.02, 0.05, 40, 40)
    kw = dict(backend="opencl", stop_and_go=stop_and_go, progress=False)
    lane_init, launch, stored = launcher._Lane.__init__, tile_kernel.TileKernel.launch, []

    def poisoned(self, ctx, queue, n):  # the sums as NaN where the call made them
        lane_init(self, ctx, queue, n)
        cl.enqueue_fill_buffer(queue, self.sums, np.full(1, np.nan, np.complex128), 0, 16 * n)

    def recording(self, queue, **args):
        stored.append((args["image"].int_ptr, args["store"], args["carry_mode"]))
        return launch(self, queue, **args)

    monkeypatch.setattr(launcher._Lane, "__init__", poisoned)
    monkeypatch.setattr(tile_kernel.TileKernel, "launch", recording)
    for two_lanes, record_bytes in ((False, 2**40), (True, 2**40), (False, 1)):
        monkeypatch.setattr(launcher, "TWO_LANES", two_lanes)
        monkeypatch.setattr(records, "LAUNCH_RECORD_BYTES", record_bytes)
        monkeypatch.setattr(launcher, "FIRST_LAUNCH_STORES", False)
        expected = backproject(kiang_echo, grid, **kw).data
        assert not np.isnan(expected).any()
        stored.clear()
        monkeypatch.setattr(launcher, "FIRST_LAUNCH_STORES", True)
        got = backproject(kiang_echo, grid, **kw).data
        launches = {}  # image buffer -> its launches' (store, carry_mode)
        for image, store, mode in stored:
            launches.setdefault(image, []).append((store, mode))
        assert len(launches) == 1 + two_lanes and len(stored) > len(launches)  # later launches added
        for first, *later in launches.values():
            assert first == ((True, 0) if record_bytes > 1 else (False, 2))  # carried: zeroed sums, added into
            assert not any(store for store, _ in later)
        assert np.array_equal(got, expected)
    with pytest.raises(ValueError, match="store=True"):
        launch(TileKernel("linear"), opencl_device.queue, pixels=None, tile_of=None, refs=None, ref_stride=0,
               ref_first=0, records=None, n_samples=0, taps=None, params=None, p_first=0, p_count=0, image=None,
               index=object(), store=True)


def test_records_in_place_and_copied_give_the_same_image(opencl_device, kiang_echo):
    """The kernel reads a C-contiguous complex64 echo in place (no copy) and any other layout from
    a copy: both give the same image."""
    strided = np.zeros(kiang_echo.data.shape[:2] + (2 * kiang_echo.n_samples,), np.complex64)[..., ::2]
    strided[...] = kiang_echo.data
    other = kiang_echo.replace(data=strided)
    assert not other.data.flags.c_contiguous
    grid = around((1989.0, 0.0, -350.0), 0.02, 0.05, 8, 8)
    kw = dict(interp="sinc8", backend="opencl", progress=False)
    assert np.array_equal(backproject(other, grid, **kw).data, backproject(kiang_echo, grid, **kw).data)


@pytest.mark.parametrize("centre", [(1989.0, 0.0, -350.0), (30.0, 1.0, -43.0)])
def test_full_size_tiles_match_reference(opencl_device, kiang_echo, centre):
    """A grid wider than a tile (every float32 offset as large as the tiling allows): the
    relative-geometry kernel stays inside the float32 budget at 30 m and at 2 km."""
    grid = around(centre, 0.5, 0.5, 16, 16)  # 16 m x 16 m: several tiles of ~3.9 m
    kw = dict(interp="sinc8", target_velocity=(0.5, -1.0, 0.0), progress=False)
    ref = backproject(kiang_echo, grid, backend="numpy", **kw)
    got = backproject(kiang_echo, grid, backend="opencl", **kw)
    assert got.provenance["exact_fallback_blocks"] == 0
    # measured: relative L2 3.2e-5 and 4.6e-5, phase 1.1e-4 and 2.6e-4 rad (the tiles' float32
    # offsets at full size, within PHASE_BUDGET = 2e-3 by construction); bounds ~10x
    assert rel_l2(got.data, ref.data) < 5e-4
    # phase at the 20 strongest pixels (the target's response), not only at the peak
    strongest = np.argsort(np.abs(ref.data).ravel())[-20:]
    assert np.max(phase_error(got.data.ravel()[strongest], ref.data.ravel()[strongest])) < 3e-3
    assert metrics.peak_index(got.data) == metrics.peak_index(ref.data)


def _slot_offsets(tiles, pixels):
    """|pixel - its tile's reference point| of every real slot of a tiling."""
    real = tiles.real
    slot_tile = np.repeat(tiles.tile, TileKernel.LANES * tiles.rows)
    return np.linalg.norm(pixels[tiles.order[real]] - tiles.centres[slot_tile[real]], axis=-1)


def test_tiles_cover_every_pixel_once_within_the_phase_budget(rng):
    pixels = rng.uniform(-40.0, 40.0, (5000, 3)) + [2000.0, 0.0, -300.0]
    tiles = plan_tiles(pixels, 150e3, 1500.0)
    assert np.array_equal(np.sort(tiles.order[tiles.real]), np.arange(len(pixels)))
    assert tiles.order.size % (TileKernel.LANES * tiles.rows) == 0
    assert tile_half_extent(150e3, 1500.0) == pytest.approx(3.34, abs=0.01)
    assert _slot_offsets(tiles, pixels).max() <= tile_half_extent(150e3, 1500.0)
    assert tiles.phase_bound <= PHASE_BUDGET
    with pytest.raises(ValueError, match="half_extent"):
        plan_tiles(pixels, 150e3, 1500.0, half_extent=0.0)


@pytest.mark.parametrize("shape", [(300, 517), (7, 1000), (1, 64), (1000, 3)])
def test_a_two_axis_grid_is_tiled_in_index_space(shape):
    """A grid with two pixel axes is cut into rectangles of its index space (no sort): every pixel
    once, within the budget, and (on a plane of square-ish tiles) fewer tiles than cubic cells of
    the same budget need."""
    ny, nx = shape
    grid = Grid.plane(np.linspace(40.0, 40.0 + 0.11 * (nx - 1), nx), np.linspace(-3.0, -3.0 + 0.05 * (ny - 1), ny), -5.0)
    pixels = grid.positions.reshape(-1, 3)
    tiles = plan_tiles(grid.positions, 150e3, 1500.0)
    assert np.array_equal(np.sort(tiles.order[tiles.real]), np.arange(len(pixels)))
    assert _slot_offsets(tiles, pixels).max() <= tile_half_extent(150e3, 1500.0) * (1 + 1e-12)
    cubes = plan_tiles(pixels, 150e3, 1500.0)
    assert tiles.centres.shape[0] <= cubes.centres.shape[0]
    if shape == (300, 517):
        assert tiles.centres.shape[0] < 0.8 * cubes.centres.shape[0]  # measured 39 against 60


def test_a_sheared_grid_falls_back_to_cubic_cells():
    """Rectangles of index space whose boxes exceed the budget (a strongly sheared grid) are not
    used: the tiling still keeps every pixel within the budget."""
    grid = Grid.slant((40.0, 0.0, -5.0), (1.0, 0.0, 0.0), (np.cos(0.05), np.sin(0.05), 0.0),
                      u=np.arange(200) * 0.1, v=np.arange(300) * 0.1)
    pixels = grid.positions.reshape(-1, 3)
    tiles = plan_tiles(grid.positions, 150e3, 1500.0)
    assert np.array_equal(np.sort(tiles.order[tiles.real]), np.arange(len(pixels)))
    assert _slot_offsets(tiles, pixels).max() <= tile_half_extent(150e3, 1500.0) * (1 + 1e-12)


def test_leg_polynomial_within_its_stated_error():
    """tile_kernel.LEG_POLY, the polynomial bp_tile evaluates for leg 1 (the module docstring's
    derivation): within 2.1e-8 relative of g(x) = 2 / (1 + sqrt(1 + x)) over its domain, which
    holds every x = N1 / |B|^2 of a tile within RHO_MAX of its reference's range."""
    from clsas.image.backprojection.tile_kernel import LEG_POLY, LEG_POLY_DOMAIN, RHO_MAX

    lo, hi = LEG_POLY_DOMAIN
    assert lo <= RHO_MAX ** 2 - 2 * RHO_MAX and RHO_MAX ** 2 + 2 * RHO_MAX <= hi
    x = np.linspace(lo, hi, 100001)
    poly = np.polynomial.polynomial.polyval(x, LEG_POLY)
    assert np.max(np.abs(poly * (1 + np.sqrt(1 + x)) / 2 - 1)) < 2.5e-8  # measured 2.14e-8


def peak_increase_mb(n_pix, n_rx, n_pulses, n_samples, upload_bytes):
    """Peak resident memory (MB) added by one back-projection, measured in a fresh process
    (tests/_bp_memory.py: after start-up and kernel builds, sampled every 2 ms)."""
    out = subprocess.run([sys.executable, str(Path(__file__).with_name("_bp_memory.py")), str(n_pix), str(n_rx),
                          str(n_pulses), str(n_samples), str(upload_bytes)],
                         capture_output=True, text=True, check=True, timeout=300)
    row = json.loads(out.stdout.strip().splitlines()[-1])
    return row["peak_mb"] - row["before_mb"]


def test_memory_of_a_4096_square_image_is_bounded_per_pixel(opencl_device):
    """A 4096^2 plane (16.8 M pixels; its positions, 384 MB, exist before the call): the call adds
    at most 80 bytes a pixel (flat complex128 image 16, the Image's complex64 8, tiling order and
    tile indices 16, float32 pixel fields 16 and their device copy, one 2^22-pixel chunk's device
    image, one coordinate's float64 temporaries), ~1.3 GB, whatever the pulses."""
    assert peak_increase_mb(4096, 1, 2, 256, 64 * 2**20) < 80 * 4096**2 / 2**20


def test_memory_does_not_grow_with_pulses_and_receivers(opencl_device):
    """32 receivers x 250 vs 1000 pulses (31 vs 125 MB of records; 250 vs 1000 MB once upsampled
    x 8): records are upsampled and uploaded UPLOAD_BYTES at a time (4 MB here, to reach the
    plateau with few pulses), so four times the pulses add nothing beyond that.

    The bounds follow from the sizes, not from one machine's allocator (the plateau itself, a few
    upload blocks with their FFT temporaries plus the OpenCL runtime's buffers in flight, varies
    between runs and CPUs: 23 to 76 MB measured, the 1000-pulse call sometimes the lower): the extra pulses may add at most 5 % of their
    upsampled records (37 MB; keeping them would add 750 MB), and the larger call may not hold a
    quarter of its upsampled records (250 MB) at once."""
    upsampled_mb = {n: 32 * n * 512 * 8 * np.dtype(np.complex64).itemsize / 2**20 for n in (250, 1000)}
    few = peak_increase_mb(128, 32, 250, 512, 4 * 2**20)
    many = peak_increase_mb(128, 32, 1000, 512, 4 * 2**20)
    assert many < few + 0.05 * (upsampled_mb[1000] - upsampled_mb[250]), (few, many)
    assert many < 0.25 * upsampled_mb[1000], (few, many)


def test_receiver_with_a_kink_falls_back_to_the_exact_kernel(opencl_device, kiang_echo):
    """Receiver C given nodes every 0.25 ms, every other one 1 mm off the line (a zigzag, kinks
    closer than any tile's delay span): the float32 kernel's linear receiver motion would be
    wrong by more than lambda / 2000, so its blocks run on the exact double kernel, which
    follows the nodes like the reference; receiver A (straight) stays on the float32 kernel."""
    k = 2
    tau = np.arange(0.0, kiang_echo.rx_tau[k][-1] + 2.5e-4, 2.5e-4)
    pos = np.stack([kiang_echo.rx_position(h, np.broadcast_to(tau, (kiang_echo.n_pulses, tau.size)))
                    for h in range(kiang_echo.n_rx)])
    pos[k, :, 1::2, 2] += 1e-3
    echo = kiang_echo.replace(rx_tau=[tau] * kiang_echo.n_rx, rx_pos=pos)
    grid = around((1989.0, 0.0, -350.0), 0.02, 0.05, 8, 8)
    kw = dict(receivers=["C"], target_velocity=(0.5, -1.0, 0.0), progress=False)
    ref = backproject(echo, grid, backend="numpy", **kw)
    got = backproject(echo, grid, backend="opencl", **kw)
    assert got.provenance["exact_fallback_blocks"] > 0
    assert rel_l2(got.data, ref.data) < 5e-3
    # the exact kernel on prepared records (one buffer of all pulses) for a sub-aperture
    part = backproject(echo, grid, backend="opencl", pulses=(4, 20), **kw)
    assert np.array_equal(backproject(prepare(echo, receivers=["C"]), grid, backend="opencl", pulses=(4, 20),
                                      **dict(kw, receivers=None)).data, part.data)
    straight = backproject(echo, grid, backend="opencl", **dict(kw, receivers=["A"]))
    assert straight.provenance["exact_fallback_blocks"] == 0


# ---------------------------------------------------------------- prepared records, grid plans

@pytest.mark.parametrize("interp", ["linear", "sinc8"])
def test_prepared_records_give_the_identical_image(backend, kiang_echo, interp):
    """Records prepared once (whole records, or only the grid's reach) give the image a plain call
    gives, bit for bit, on both backends; a subset of the prepared receivers too."""
    grid = around((1989.0, 0.0, -350.0), 0.02, 0.05, 8, 8)
    kw = dict(backend=backend, target_velocity=(0.5, -1.0, 0.0), progress=False)
    plain = backproject(kiang_echo, grid, interp=interp, upsample=4, **kw)
    whole = prepare(kiang_echo, upsample=4, interp=interp)
    patch = prepare(kiang_echo, upsample=4, interp=interp, grid=grid, target_velocity=(0.5, -1.0, 0.0))
    if interp == "linear":
        assert np.all(patch.length < whole.length)  # only the patch's reach is upsampled
    else:
        assert np.all(patch.length == whole.length) and patch.nbytes == whole.nbytes  # the echo's own, in place
    for records in (whole, patch, whole):  # the second use of ``whole`` reads its device buffers again
        image = backproject(records, GridPlan(grid), **kw)
        assert np.array_equal(image.data, plain.data)
        assert image.provenance["prepared_records"] and image.provenance["interp"] == interp
    one = backproject(kiang_echo, grid, interp=interp, upsample=4, receivers=["C"], **kw)
    assert np.array_equal(backproject(whole, grid, receivers=["C"], **kw).data, one.data)
    # a sub-aperture (factorised back-projection's first stage): pulses 5..16 of the prepared records
    early = backproject(kiang_echo, grid, interp=interp, upsample=4, pulses=(0, 5), **kw)
    late = backproject(kiang_echo, grid, interp=interp, upsample=4, pulses=range(5, kiang_echo.n_pulses), **kw)
    assert np.array_equal(backproject(whole, grid, pulses=slice(5, None), **kw).data, late.data)
    assert rel_l2(early.data + late.data, plain.data) < 1e-6  # measured <= 8e-8 (complex64 images)


def test_a_grid_plan_images_its_grid_again(opencl_device, kiang_echo):
    grid = around((30.0, 1.0, -43.0), 0.5, 0.5, 16, 16)  # several tiles
    plan = GridPlan(grid)
    kw = dict(backend="opencl", interp="sinc8", progress=False)
    first = backproject(kiang_echo, plan, **kw)
    assert np.array_equal(backproject(kiang_echo, plan, **kw).data, first.data)
    assert np.array_equal(backproject(kiang_echo, grid, **kw).data, first.data)
    assert first.provenance["kernel_seconds"] > 0


def test_reach_holds_every_delay(kiang_echo, rng):
    """The fast-time span reach() gives each receiver holds the exact two-way delay of every pixel
    of the grid at every pulse (moving pixels, a towed receiver and a sonobuoy)."""
    pixels = rng.uniform(-20.0, 20.0, (200, 3)) + [1989.0, 0.0, -350.0]
    v = np.array([0.5, -1.0, 0.0])
    spans = reach(kiang_echo, range(kiang_echo.n_rx), pixels, v)
    for h in range(kiang_echo.n_rx):
        t1, _, t2, _ = legs(kiang_echo, h, np.arange(kiang_echo.n_pulses), pixels, v, False)
        tau = t1 + t2
        assert spans[h, 0] <= tau.min() and tau.max() <= spans[h, 1]
        assert spans[h, 1] - spans[h, 0] < 1.5 * (tau.max() - tau.min()) + 0.01  # a bound, not the record


def test_records_prepared_for_one_grid_refuse_another(kiang_echo):
    near = around((1989.0, 0.0, -350.0), 0.02, 0.05, 4, 4)
    records = prepare(kiang_echo, grid=near)
    with pytest.raises(ValueError, match="do not cover"):
        backproject(records, around((30.0, 1.0, -43.0), 0.02, 0.05, 4, 4), backend="numpy", progress=False)
    with pytest.raises(ValueError, match="contradicts"):
        backproject(records, near, backend="numpy", interp="sinc8", progress=False)
    with pytest.raises(ValueError, match="not prepared"):
        backproject(prepare(kiang_echo, receivers=["A"], grid=(2.5, 2.7)), near, backend="numpy", receivers=["B"])


def test_prepare_bad_input(kiang_echo):
    raw = kiang_echo.replace(compressed=False)
    with pytest.raises(ValueError, match="range_compress"):
        prepare(raw)
    with pytest.raises(TypeError, match="EchoData"):
        prepare(np.zeros((1, 2, 3)))
    with pytest.raises(ValueError, match="upsample"):
        prepare(kiang_echo, upsample=100)
    with pytest.raises(ValueError, match="interp"):
        prepare(kiang_echo, interp="cubic")
    with pytest.raises(ValueError, match="receivers"):
        prepare(kiang_echo, receivers=["D"])
    with pytest.raises(TypeError, match="grid"):
        prepare(kiang_echo, grid="all")
    with pytest.raises(ValueError, match="start < stop"):
        prepare(kiang_echo, grid=(3.0, 2.0))
    with pytest.raises(ValueError, match="workers"):
        prepare(kiang_echo, workers=0)
    with pytest.raises(ValueError, match="target_velocity"):
        prepare(kiang_echo, target_velocity=(1.0, 2.0))
    grid = around((1989.0, 0.0, -350.0), 0.1, 0.1, 2, 2)
    for pulses in ((3, 3), (0, kiang_echo.n_pulses + 1), slice(0, 8, 2), 4):
        with pytest.raises(ValueError, match="pulses"):
            backproject(kiang_echo, grid, backend="numpy", pulses=pulses)


def test_block_upsampling_is_local_and_close_to_one_fft(kiang_echo):
    """A block's upsampled samples do not depend on the span asked for, and the blocks agree with
    one FFT of the whole zero-padded record (measured 1.3e-4 relative L2 on this echo)."""
    records = kiang_echo.data[0, :4]
    n = records.shape[1]
    whole = upsample_blocks(records, 8, 0, n)
    part = upsample_blocks(records, 8, UPSAMPLE_BLOCK, 3 * UPSAMPLE_BLOCK)
    assert np.array_equal(part, whole[:, 8 * UPSAMPLE_BLOCK:24 * UPSAMPLE_BLOCK])
    one = upsample_records(records, 8)
    assert rel_l2(whole, one) < 1.5e-3
    with pytest.raises(ValueError, match="multiple"):
        upsample_blocks(records, 8, 3, n)


# ---------------------------------------------------------------- physics

@pytest.fixture(scope="module")
def heremans():
    sc = oversampled(presets.point_scene("heremans2009", n_pulses=48))
    return sc, compressed(sc)


def test_heremans_nine_points_focus(opencl_device, heremans):
    sc, echo = heremans
    d = sc.array.rx_length[0]
    rres = sc.medium.sound_speed / (2 * sc.waveform.bandwidth)
    lam = sc.waveform.wavelength(sc.medium)
    for p in sc.targets[0].positions:
        img = backproject(echo, around(p, rres / 8, d / 16, 48, 64), backend="opencl", progress=False)
        res = metrics.analyse_point(img, near=(p[1], p[0]), radius=d)
        assert abs(res["y"].location - p[1]) < 0.1 * d / 2  # 1/10 of a resolution cell
        assert abs(res["x"].location - p[0]) < 0.1 * rres
        assert abs(res["x"].irw / (0.886 * rres) - 1) < 0.1  # range IRW: 0.886 c / (2B), unweighted
        assert abs(res["x"].pslr_db + 13.3) < 1.0
    # along-track resolution D/2 (Heremans 2009 eq. 47 without a window): integrating over the
    # beam's angular span lambda / D; the whole illuminated aperture (no limit) does better
    p = sc.targets[0].positions[4]
    limited = backproject(echo, around(p, rres / 8, d / 16, 48, 96), backend="opencl", aperture=lam / d,
                          progress=False)
    irw = metrics.analyse_point(limited, near=(p[1], p[0]), radius=d)["y"].irw
    assert abs(irw / (d / 2) - 1) < 0.1


def test_huang_six_points_focus_with_32_receivers(opencl_device):
    sc = oversampled(presets.point_scene("huang2022", n_pulses=64))
    echo = compressed(sc)
    assert echo.n_rx == 32
    rres = sc.medium.sound_speed / (2 * sc.waveform.bandwidth)
    cell = sc.array.tx_length / 2
    # With the whole illuminated aperture the along-track response of unequal elements (0.08 m
    # transmitter, 0.04 m receivers) is the transform of sinc x sinc: a trapezoid whose flat top
    # shows two humps 0.2 dB apart. Integrating over the transmitter's beam, lambda / D_tx,
    # weights the aperture almost uniformly and gives a single, sinc-like peak to locate.
    aperture = sc.waveform.wavelength(sc.medium) / sc.array.tx_length
    for p in sc.targets[0].positions:
        img = backproject(echo, around(p, rres / 8, cell / 8, 32, 64), backend="opencl", aperture=aperture,
                          progress=False)
        res = metrics.analyse_point(img, near=(p[1], p[0]), radius=cell)
        assert abs(res["y"].location - p[1]) < 0.1 * cell
        assert abs(res["x"].location - p[0]) < 0.1 * rres


@pytest.mark.filterwarnings("ignore::clsas.scene.scenario.SamplingWarning")  # Zhang's table as printed
def test_zhang_eighteen_points_focus(opencl_device):
    sc = oversampled(presets.point_scene("zhang2019", n_pulses=64))
    echo = clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False), upsample=8)
    rres = sc.medium.sound_speed / (2 * sc.waveform.bandwidth)
    cell = sc.array.tx_length / 2
    aperture = sc.waveform.wavelength(sc.medium) / sc.array.tx_length  # see the Huang test
    assert len(sc.targets[0].positions) == 18
    for p in sc.targets[0].positions:
        img = backproject(echo, around(p, rres / 8, cell / 8, 24, 48), backend="opencl", aperture=aperture,
                          upsample=1, progress=False)  # upsampled once, by range_compress
        res = metrics.analyse_point(img, near=(p[1], p[0]), radius=cell)
        assert abs(res["y"].location - p[1]) < 0.1 * cell
        assert abs(res["x"].location - p[0]) < 0.1 * rres


@pytest.mark.parametrize("receiver", ["A", "B", "C"])
def test_multistatic_point_focuses_from_each_receiver(opencl_device, receiver):
    p = (1989.0, 0.0, -350.0)
    sc = oversampled(presets.kiang2022(n_pulses=128)).replace(targets=(PointTargets([p]),))
    echo = compressed(sc)
    rres = sc.medium.sound_speed / (2 * sc.waveform.bandwidth)
    img = backproject(echo, around(p, rres / 4, 0.25, 24, 24), backend="opencl", receivers=[receiver],
                      progress=False)
    peak = metrics.peak_index(img.data)
    assert abs(img.axes["x"][peak[1]] - p[0]) <= rres / 4
    assert abs(img.axes["y"][peak[0]] - p[1]) <= 0.25


def test_moving_target_focuses_only_with_its_velocity(opencl_device):
    p, v = (1989.0, 0.0, -350.0), (0.0, -4.0, 0.0)
    sc = oversampled(presets.kiang2022(n_pulses=256)).replace(targets=(PointTargets([p], velocity=v),))
    echo = compressed(sc)
    grid = around(p, 0.02, 0.1, 20, 30)
    right = backproject(echo, grid, backend="opencl", receivers=["A"], target_velocity=v, progress=False)
    wrong = backproject(echo, grid, backend="opencl", receivers=["A"], progress=False)
    peak = metrics.peak_index(right.data)
    assert abs(right.axes["y"][peak[0]] - p[1]) <= 0.1 and abs(right.axes["x"][peak[1]] - p[0]) <= 0.02
    assert np.abs(right.data).max() > 2 * np.abs(wrong.data).max()


# ---------------------------------------------------------------- bad input

def test_bad_input(kiang_echo):
    grid = around((1989.0, 0.0, -350.0), 0.1, 0.1, 2, 2)
    with pytest.raises(ValueError, match="empty"):
        Grid.points(np.zeros((0, 3)))
    with pytest.raises(ValueError, match="finite"):
        Grid.points([[np.nan, 0.0, 0.0]])
    raw = clsas.simulate(presets.kiang2022(n_pulses=2).replace(targets=(PointTargets([[1989.0, 0, -350.0]]),)),
                         backend="numpy", progress=False)
    with pytest.raises(ValueError, match="range_compress"):
        backproject(raw, grid, backend="numpy")
    with pytest.raises(ValueError, match="receivers"):
        backproject(kiang_echo, grid, backend="numpy", receivers=[3])
    with pytest.raises(ValueError, match="receivers"):
        backproject(kiang_echo, grid, backend="numpy", receivers=["D"])
    with pytest.raises(ValueError, match="interp"):
        backproject(kiang_echo, grid, backend="numpy", interp="cubic")
    with pytest.raises(ValueError, match="upsample"):
        backproject(kiang_echo, grid, backend="numpy", upsample=0)
    with pytest.raises(ValueError, match="aperture"):
        backproject(kiang_echo, grid, backend="numpy", aperture=-1.0)
    with pytest.raises(TypeError, match="Grid"):
        backproject(kiang_echo, np.zeros((3, 3)), backend="numpy")


def test_grid_constructors():
    g = Grid.plane([1.0, 2.0, 3.0], [0.0, 0.5], -10.0)
    assert g.shape == (2, 3) and g.dims == ("y", "x")
    np.testing.assert_array_equal(g.positions[1, 2], [3.0, 0.5, -10.0])
    s = Grid.slant((0, 0, 0), (1, 0, 0), (0, 1, 0), u=[1.0, 2.0], v=[0.0, 1.0, 2.0])
    assert s.shape == (3, 2)
    np.testing.assert_array_equal(s.positions[2, 1], [2.0, 2.0, 0.0])
    vol = Grid.points(np.zeros((2, 3, 4, 3)))
    assert vol.dims == ("i0", "i1", "i2") and vol.size == 24


def test_prepare_checks_the_memory_budget_before_upsampling(kiang_echo):
    """Issue 27: prepare(upsample=64) refuses within a small budget before it allocates."""
    with clsas.use_memory_budget("2M"):
        with pytest.raises(clsas.budget.MemoryBudgetError, match="upsample=64"):
            prepare(kiang_echo, upsample=64)


@pytest.mark.parametrize("options", [dict(), dict(stop_and_go=True), dict(velocity=(0.5, -1.0, 0.0)),
                                     dict(velocity=(0.5, -1.0, 0.0), stop_and_go=True)])
def test_references_on_the_device_match_the_host(opencl_device, kiang_echo, options):
    """bp_refs (the references in double on the device) against TileKernel.references, their NumPy
    twin: every field within float32 rounding of the same double value (the integer sample index
    exactly), for the monostatic receiver A, the towed receiver B and the sonobuoy C."""
    import pyopencl as cl

    centres = np.array([[30.0, 1.0, -43.0], [1989.0, 0.0, -350.0], [31.5, -2.0, -41.0]])
    pulses = np.arange(3, 19)
    buf = cl.Buffer(opencl_device.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=centres)
    for h in range(kiang_echo.n_rx):
        tile = TileKernel("linear", **options).for_receiver(kiang_echo, h)
        host, linear = tile.references(kiang_echo, h, pulses, centres, kiang_echo.fs, 2.5, offset=17)
        assert linear
        dev = tile.references_on_device(opencl_device.queue, kiang_echo, h, pulses, buf, len(centres), kiang_echo.fs,
                                        2.5, offset=17)
        got = np.empty_like(host)
        cl.enqueue_copy(opencl_device.queue, got, dev)
        _same_references(got, host, h)
    # receivers B and C (the same legs) in one launch, each with its own records' offset: (T, 2, P)
    tile = TileKernel("linear", **options).for_receiver(kiang_echo, 1)
    dev = tile.references_on_device(opencl_device.queue, kiang_echo, [1, 2], pulses, buf, len(centres),
                                    kiang_echo.fs, 2.5, offset=np.array([17, 5]))
    got = np.empty((len(centres), 2, pulses.size), tile.reference_dtype)
    cl.enqueue_copy(opencl_device.queue, got, dev)
    for j, (h, offset) in enumerate(((1, 17), (2, 5))):
        host, _ = tile.references(kiang_echo, h, pulses, centres, kiang_echo.fs, 2.5, offset=offset)
        _same_references(got[:, j], host, h)


@pytest.mark.parametrize("options", [dict(), dict(stop_and_go=True)])
def test_references_from_a_first_pulse_per_tile(opencl_device, kiang_echo, options):
    """bp_refs with a first pulse per tile (TILE_FIRST: ffbp's sub-apertures in one launch): each
    tile's row equals a call on that tile's own pulses, bit for bit; firsts that do not fit, or
    several receivers, are refused."""
    import pyopencl as cl

    ctx, queue = opencl_device.context, opencl_device.queue
    centres = np.array([[30.0, 1.0, -43.0], [1989.0, 0.0, -350.0], [31.5, -2.0, -41.0]])
    pulses, first = np.arange(2, 24), np.array([0, 5, 11])
    per_tile = pulses.size - first.max()

    def buffer(a):
        return cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))

    tile = TileKernel("linear", **options).for_receiver(kiang_echo, 0)
    dev = tile.references_on_device(queue, kiang_echo, 0, pulses, buffer(centres), 3, kiang_echo.fs, 2.5, offset=17,
                                    tile_first=first)
    got = np.empty((3, per_tile), tile.reference_dtype)
    cl.enqueue_copy(queue, got, dev)
    for t in range(3):
        own = tile.references_on_device(queue, kiang_echo, 0, pulses[first[t]:first[t] + per_tile],
                                        buffer(centres[t:t + 1]), 1, kiang_echo.fs, 2.5, offset=17)
        expected = np.empty((1, per_tile), tile.reference_dtype)
        cl.enqueue_copy(queue, expected, own)
        assert got[t].tobytes() == expected[0].tobytes()
    for bad, h in (([0, 5], 0), ([0, 5, 22], 0), ([-1, 0, 0], 0), ([0, 0, 0], [0, 1])):
        with pytest.raises(ValueError, match="tile_first"):
            tile.references_on_device(queue, kiang_echo, h, pulses, buffer(centres), 3, kiang_echo.fs, 2.5,
                                      tile_first=np.array(bad))


def _same_references(got, host, h):
    for name in host.dtype.names:
        a, b = got[name].astype(np.float64), host[name].astype(np.float64)
        if name in ("k_ref", "poly"):
            assert np.array_equal(a, b), (h, name)
        else:
            scale = np.max(np.abs(b), axis=-1, keepdims=True) if b.ndim == 3 else np.abs(b)
            assert np.all(np.abs(a - b) <= 2e-7 * np.maximum(scale, 1e-30) + 1e-30), (h, name)


@pytest.mark.parametrize("case", ["kiang", "kiang-stop-and-go", "kiang-aperture", "huang"])
def test_references_of_several_receivers_at_once_give_the_identical_image(opencl_device, kiang_echo, monkeypatch,
                                                                          case):
    """A call computes consecutive receivers' references (same legs) in one bp_refs launch and each
    receiver's bp_tile launch reads its slice: the image is bit-identical to one bp_refs launch a
    receiver (REF_BYTES 0), for receivers of mixed legs (Kiang: A alone, B and C together), with an
    aperture (each receiver's pulse spans from its slice) and for Huang's 32 receivers."""
    from clsas.image.backprojection import launcher

    if case == "huang":
        echo = compressed(presets.point_scene("huang2022", n_pulses=16))
        grid = Grid.plane(np.linspace(40.0, 80.0, 40), np.linspace(-4.0, 4.0, 24), 0.0)
    else:
        echo, grid = kiang_echo, around((30.0, 1.0, -43.0), 0.1, 0.1, 10, 10)
    kw = dict(stop_and_go=case == "kiang-stop-and-go", aperture=0.3 if case == "kiang-aperture" else None,
              progress=False)
    groups = []
    monkeypatch.setattr(launcher, "_groups", lambda *a, _f=launcher._groups: groups.append(_f(*a)) or groups[-1])
    together = backproject(echo, grid, **kw).data
    assert [len(g) for g in groups[-1]] == ([32] if case == "huang" else [1, 2])
    monkeypatch.setattr(launcher, "REF_BYTES", 0)
    alone = backproject(echo, grid, **kw).data
    assert all(len(g) == 1 for g in groups[-1])
    assert np.array_equal(together, alone)


@pytest.mark.parametrize("case", ["plain", "prepared", "aperture", "pulses", "sinc8", "kiang-stop-and-go",
                                  "pulses-16", "pulses-32"])
def test_a_block_over_several_launches_gives_the_identical_image(opencl_device, kiang_echo, monkeypatch, case):
    """Records whose block of PULSE_BLOCK pulses exceeds LAUNCH_RECORD_BYTES are summed over several
    bp_tile launches carrying their float sums (CARRY): the image is bit-identical to one launch a
    block, with blocks cut short by the span's end, an aperture, a pulse range starting inside a
    block (with launches of 4, 16 and 32 pulses: a span end that is not a multiple of them),
    prepared records, sinc8 and the one-leg kernel; a carry with store is refused."""
    from clsas.image.backprojection import launcher, records, tile_kernel

    sub = int(case.split("-")[1]) if case.startswith("pulses-") else 4
    case = "pulses" if case.startswith("pulses-") else case
    if case == "kiang-stop-and-go":
        echo, grid, kw = kiang_echo, around((30.0, 1.0, -43.0), 0.1, 0.1, 10, 10), dict(stop_and_go=True)
    else:
        echo = compressed(presets.point_scene("huang2022", n_pulses=150))
        grid = Grid.plane(np.linspace(40.0, 80.0, 40), np.linspace(-4.0, 4.0, 24), 0.0)
        kw = {"aperture": dict(aperture=0.3), "pulses": dict(pulses=(7, 131)), "sinc8": dict(interp="sinc8")}.get(case, {})
    source = prepare(echo) if case == "prepared" else echo
    launches = []
    monkeypatch.setattr(tile_kernel.TileKernel, "launch",
                        lambda self, queue, _f=tile_kernel.TileKernel.launch, **a: launches.append(a) or _f(self, queue, **a))
    monkeypatch.setattr(records, "LAUNCH_RECORD_BYTES", 2**40)
    whole = backproject(source, grid, progress=False, **kw).data
    assert all(a["carry"] is None for a in launches)
    launches.clear()
    monkeypatch.setattr(records, "LAUNCH_RECORD_BYTES", 1)  # the fewest pulses a launch: 4
    assert records.launch_pulses(100, 64) == 4
    if sub != 4:
        monkeypatch.setattr(launcher, "launch_pulses", lambda n_samples, block: sub)
    carried = backproject(source, grid, progress=False, **kw).data
    modes = {a["carry_mode"] for a in launches if a["carry"] is not None}
    assert max(a["p_count"] for a in launches) == sub and modes == ({1, 2} if sub == 32 else {1, 2, 3})
    if case == "pulses":  # the last launch of the span (7, 131) sums fewer than sub pulses: 124 % sub
        assert launches[-1]["p_count"] == (124 % sub or sub) and launches[-1]["carry_mode"] == 1
    assert np.array_equal(carried, whole)
    with pytest.raises(ValueError, match="carry"):
        launcher.TileKernel("linear").launch(opencl_device.queue, pixels=None, tile_of=None, refs=None, ref_stride=0,
                                             ref_first=0, records=None, n_samples=0, taps=None, params=None, p_first=0,
                                             p_count=0, image=None, store=True, carry=object())


@pytest.mark.parametrize("cut", ["references", "upload"])
def test_a_block_cut_by_a_reference_block_or_a_job_is_added_not_dropped(opencl_device, monkeypatch, cut):
    """A carried block (CARRY) cut by the end of a block of REF_PULSES pulses or of an upload job
    (neither a multiple of PULSE_BLOCK) is added into the image in parts, not stored for a launch
    that may not come: with REF_PULSES 48 and the references of pulses 48 .. 95 on the exact
    fallback (bp_tile then never finishes the block of pulses 0 .. 63), or jobs of 48 pulses from
    pulse 7, the image agrees with the reference as the uncut one does (the upload case also with
    the uncut image, to float rounding)."""
    from clsas.image.backprojection import launcher, records, tile_kernel

    echo = compressed(presets.point_scene("huang2022", n_pulses=96))
    grid = Grid.plane(np.linspace(40.0, 80.0, 40), np.linspace(-4.0, 4.0, 24), 0.0)
    kw = dict(receivers=[0, 5], progress=False, pulses=(7, 96) if cut == "upload" else None)
    ref = backproject(echo, grid, backend="numpy", **kw).data
    whole = backproject(echo, grid, **kw)
    assert whole.provenance["exact_fallback_blocks"] == 0
    monkeypatch.setattr(records, "LAUNCH_RECORD_BYTES", 1)  # launches of 4 pulses, blocks carried
    if cut == "references":
        monkeypatch.setattr(launcher, "REF_PULSES", 48)
        kernel = tile_kernel.TileKernel
        on_device, on_host = kernel.references_on_device, kernel.references
        monkeypatch.setattr(kernel, "references_on_device", lambda self, queue, echo, h, pulses, *a: None
                            if pulses[0] == 48 else on_device(self, queue, echo, h, pulses, *a))
        monkeypatch.setattr(kernel, "references", lambda self, echo, h, pulses, *a: (
            lambda r: (r[0], r[1] and pulses[0] != 48))(on_host(self, echo, h, pulses, *a)))
    else:
        monkeypatch.setattr(records.PreparedRecords, "upload_pulses", lambda self: 48)
    cut_image = backproject(echo, grid, **kw)
    assert cut_image.provenance["exact_fallback_blocks"] == (2 if cut == "references" else 0)
    # measured against the reference: uncut 2.0e-4 (bp_tile's float32 error on this scene), cut 1.5e-4
    # (references: half the pulses on the exact kernel) and 2.0e-4 (upload; 1.3e-7 from the uncut
    # image); a dropped or stale carry is an error of order 1
    assert rel_l2(cut_image.data, ref) < 2e-3
    if cut == "upload":
        assert rel_l2(cut_image.data, whole.data) < 1.5e-6


def test_one_leg_for_a_monostatic_receiver(opencl_device, kiang_echo):
    """bp_tile computes one leg for receiver A (at the transmitter): t2 = t1 with stop-and-go
    (SAME_LEGS), the closed form of the return leg with exact delays for pixels at rest (MONO);
    the two-leg kernel otherwise. The images match the reference as closely as the two-leg
    kernel's."""
    stop, exact = TileKernel("linear", stop_and_go=True), TileKernel("linear")
    assert [stop.legs_for(kiang_echo, h) for h in range(kiang_echo.n_rx)] == ["same", "two", "two"]
    assert [exact.legs_for(kiang_echo, h) for h in range(kiang_echo.n_rx)] == ["mono", "two", "two"]
    assert TileKernel("linear", velocity=(0.5, -1.0, 0.0)).legs_for(kiang_echo, 0) == "two"  # moving pixels
    assert "SAME_LEGS" in stop.for_receiver(kiang_echo, 0).defines
    assert "MONO" in exact.for_receiver(kiang_echo, 0).defines
    with pytest.raises(ValueError, match="legs"):
        TileKernel("linear", legs="same")
    grid = around((30.0, 1.0, -43.0), 0.5, 0.5, 16, 16)
    for options in ({"stop_and_go": True}, {}):
        kw = dict(receivers=["A"], progress=False, **options)
        ref = backproject(kiang_echo, grid, backend="numpy", **kw)
        got = backproject(kiang_echo, grid, backend="opencl", **kw)
        assert rel_l2(got.data, ref.data) < 1.5e-3  # measured 1.6e-4 and 2.0e-4 (full-size tiles, as above)

def test_rows_of_a_work_item_leave_the_image_unchanged(opencl_device, kiang_echo):
    """GridPlan's rows (of 16 pixels a bp_tile work-item) change only how the tiles are padded and
    launched, not a pixel's tile or arithmetic: the images are identical bit for bit."""
    grid = around((30.0, 1.0, -43.0), 0.05, 0.05, 20, 20)
    images = [backproject(kiang_echo, GridPlan(grid, rows=r), receivers=["A"], stop_and_go=True,
                          progress=False).data for r in (4, 6, 8)]
    assert np.array_equal(images[0], images[1]) and np.array_equal(images[0], images[2])
    with pytest.raises(ValueError, match="rows"):
        GridPlan(grid, rows=0)
    with pytest.raises(TypeError, match="rows"):
        GridPlan(grid, rows=6.0)


def test_numpy_reference_keeps_its_working_set_within_the_budget():
    """The NumPy reference works on as many pixel-pulses at a time as the memory budget holds
    (WORK_BYTES each): 48^2 pixels x 32 pulses took all 73728 pixel-pulses at once whatever the
    budget (~150 bytes each); under an 8 MiB budget its peak (traced by tracemalloc) stays within
    it, and the image is the same."""
    import tracemalloc

    from _bp_memory import echo_of

    echo = echo_of(1, 32, 512)
    grid = Grid.plane(np.linspace(40.0, 45.0, 48), np.linspace(-5.0, 5.0, 48), 0.0)
    images = []
    for limit in (8 << 20, 1 << 30):
        with clsas.use_memory_budget(limit):
            tracemalloc.start()
            try:
                images.append(clsas.backproject(echo, grid, backend="numpy", progress=False).data)
                peak = tracemalloc.get_traced_memory()[1]
            finally:
                tracemalloc.stop()
        assert peak < limit, (limit, peak)
    np.testing.assert_allclose(images[0], images[1], rtol=0, atol=1e-9 * np.abs(images[1]).max())


def _random_echo(nodes, rng, n_pulses: int = 6):
    """Three receivers' all-zero echo of ``n_pulses`` pulses, the transmitter and the receivers' position
    ``nodes`` (s from emission) at random places (what the delay bounds and references read)."""
    from clsas import EchoData, Medium, Waveform

    n_rx, tau = 3, np.asarray(nodes)
    return EchoData(data=np.zeros((n_rx, n_pulses, 16), np.complex64), eta=np.arange(n_pulses) / 10.0,
                    t0=np.full(n_rx, 0.1), fs=40e3, tx_pos=rng.normal(size=(n_pulses, 3)),
                    rx_pos=rng.normal(size=(n_rx, n_pulses, tau.size, 3)), rx_tau=np.tile(tau, (n_rx, 1)),
                    waveform=Waveform(f0=150e3, bandwidth=20e3, duration=1e-3, fs=40e3), medium=Medium(1500.0),
                    receivers=("A", "B", "C"), compressed=True)


@pytest.mark.parametrize("nodes", [[0.0], [0.0, 0.2], [-0.05, 0.05, 0.1, 0.3], [0.01, 0.2, 0.4]])
def test_receivers_at_emission_for_the_references(nodes, rng):
    """bp_refs' receiver positions at emission, all receivers at once (tile_kernel._at_emission),
    are EchoData.rx_position(h, 0)'s to the last bit, for one node, two, several from before the
    emission and several all after it (extrapolated)."""
    from clsas.image.backprojection.tile_kernel import _at_emission

    echo = _random_echo(nodes, rng)
    pulses = np.arange(1, 5)
    want = np.stack([echo.rx_position(h, np.zeros(pulses.size), pulses=pulses) for h in (2, 0)])
    assert np.array_equal(_at_emission(echo, np.array([2, 0]), pulses), want)


@pytest.mark.parametrize("nodes", [[0.0], [0.0, 0.2], [-0.05, 0.05, 0.1, 0.3]])
def test_reach_from_a_plans_pixel_box_is_the_reach_from_the_pixels(nodes, rng):
    """reach with the pixel box a GridPlan keeps (what a call on a Grid passes) is reach from the
    pixels, bit for bit, for one, two and several receiver nodes; the box holds every pixel and is
    attained (the smallest and largest coordinates). With the box, positions are not read: one
    pixel and the box give the reach of all of them."""
    echo = _random_echo(nodes, rng)
    grid = Grid.points(rng.normal(size=(50, 3)) * [30.0, 10.0, 2.0] + [60.0, 0.0, -5.0])
    plan = GridPlan(grid)
    pts = grid.positions.reshape(-1, 3)
    assert np.array_equal(plan.box, [pts.min(axis=0), pts.max(axis=0)])
    for velocity in (None, [0.3, -0.2, 0.0]):
        every = reach(echo, [2, 0], grid.positions, velocity)
        assert np.array_equal(reach(echo, [2, 0], grid.positions, velocity, plan.box), every)
        assert np.array_equal(reach(echo, [2, 0], grid.positions[:1], velocity, plan.box), every)


def test_bp_order_puts_the_slot_sums_in_the_grids_order_as_astype_rounds(opencl_device, rng):
    # a grid of one chunk: bp_order (launcher._Chunk.in_grid_order) against the host's order (made here from the
    # tiling's order, not from slot_of) and numpy's rounding; padding slots hold values that must not appear
    import types

    import pyopencl as cl

    from clsas.image.backprojection import launcher

    pixels = rng.uniform(-40.0, 40.0, (5000, 3)) + [2000.0, 0.0, -300.0]
    tiles = plan_tiles(pixels, 150e3, 1500.0)
    sums = (rng.standard_normal(2 * tiles.order.size) * 10.0 ** rng.uniform(-30, 40, 2 * tiles.order.size))
    sums = sums.view(np.complex128)  # some past float's range (inf), some below its normal range
    sums[~tiles.real] = np.nan
    expected = np.empty(len(pixels), np.complex128)
    expected[tiles.order[tiles.real]] = sums[tiles.real]
    with np.errstate(over="ignore"):
        expected = expected.astype(np.complex64)
    buf = cl.Buffer(opencl_device.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=sums)
    chunk = types.SimpleNamespace(sums=buf)
    image = launcher._Chunk.in_grid_order(chunk, opencl_device.queue, tiles, TileKernel("linear", rows=tiles.rows))
    assert image.dtype == np.complex64 and image.shape == (len(pixels),)
    assert np.isinf(expected.real).any() and np.isfinite(image).sum() > len(pixels) // 2
    assert image.tobytes() == expected.tobytes()


def test_a_plans_kept_device_inputs_serve_its_next_calls_and_only_their_own_configuration(opencl_device, kiang_echo,
                                                                                          monkeypatch):
    # a grid of one chunk keeps its device inputs (slot indices, bp_fields' pixel fields) with its plan: the next
    # call makes no bp_fields and gives the image a fresh plan gives, bit for bit; a call at another target velocity
    # (other fields: dv = delta . v) makes its own and replaces them; release() drops them; a grid of several
    # chunks keeps none
    from clsas.image.backprojection import launcher, tile_kernel

    made, fields = [], tile_kernel.TileKernel.fields

    def counted(self, queue, **args):
        made.append(args["n_slots"])
        return fields(self, queue, **args)

    monkeypatch.setattr(tile_kernel.TileKernel, "fields", counted)
    grid = around((30.0, 1.0, -43.0), 0.05, 0.05, 20, 20)
    plan = GridPlan(grid)
    kw = dict(backend="opencl", upsample=4, progress=False)

    def image(on, velocity):
        return backproject(kiang_echo, on, target_velocity=velocity, **kw).data

    for velocity, fresh in ((None, 1), (None, 0), ((0.5, -1.0, 0.0), 1), ((0.5, -1.0, 0.0), 0), ((0.2, 0.3, 0.0), 1),
                            (None, 1)):
        before = len(made)
        got = image(plan, velocity)
        assert len(made) - before == fresh, (velocity, made)
        assert np.array_equal(got, image(GridPlan(grid), velocity)), velocity
    assert plan._kept is not None
    plan.release()
    assert plan._kept is None
    before = len(made)
    assert np.array_equal(image(plan, None), image(GridPlan(grid), None)) and len(made) - before == 2
    monkeypatch.setattr(launcher, "PIXEL_CHUNK", 2 * TileKernel.LANES * plan.rows)  # several chunks
    several = GridPlan(grid)
    assert np.array_equal(image(several, None), image(plan, None))  # added on the host: the same roundings
    assert several._kept is None


@pytest.mark.parametrize("case", ["plain", "carried", "chunks"])
def test_two_lanes_of_jobs_give_the_one_lane_image(opencl_device, monkeypatch, case):
    # a small chunk's jobs alternate between two queues (launcher.TWO_LANES), each lane adding into its own sums, the
    # second's added into the first's at the end: every receiver's pulses counted once, as one lane counts them
    # (carried blocks: each lane its own carry; several chunks: each chunk's lanes merged before the host adds)
    from clsas.image.backprojection import launcher, records, tile_kernel

    echo = compressed(presets.point_scene("huang2022", n_pulses=32))
    grid = Grid.plane(np.linspace(40.0, 80.0, 40), np.linspace(-4.0, 4.0, 24), 0.0)
    if case == "carried":
        monkeypatch.setattr(records, "LAUNCH_RECORD_BYTES", 1)
    if case == "chunks":
        monkeypatch.setattr(launcher, "PIXEL_CHUNK", 4 * TileKernel.LANES * GridPlan(grid).rows)
    queues, launch = [], tile_kernel.TileKernel.launch
    monkeypatch.setattr(tile_kernel.TileKernel, "launch",
                        lambda self, queue, **a: queues.append(queue.int_ptr) or launch(self, queue, **a))
    monkeypatch.setattr(launcher, "TWO_LANES", False)
    one = backproject(echo, grid, progress=False).data
    assert len(set(queues)) == 1
    queues.clear()
    monkeypatch.setattr(launcher, "TWO_LANES", True)
    two = backproject(echo, grid, progress=False).data
    assert len(set(queues)) == 2 and queues.count(queues[0]) == len(queues) // 2  # 32 receivers: 16 jobs a lane
    assert rel_l2(two, one) < 1e-7  # measured 0 (the double sums' other order rounds to the same floats here)
    queues.clear()
    monkeypatch.setattr(launcher, "TWO_LANE_SLOTS", TileKernel.LANES)  # a grid above it: one queue
    assert np.array_equal(backproject(echo, grid, progress=False).data, one) and len(set(queues)) == 1


def test_a_small_chunks_launches_read_more_records(opencl_device, monkeypatch):
    # a chunk on two lanes (at most TWO_LANE_SLOTS slots) counts its records at 1 / SMALL_LAUNCH_RECORDS against
    # LAUNCH_RECORD_BYTES: a block whose records are 2.5 times the limit is one launch there, and carried over
    # launches of fewer pulses on a larger chunk; the same image bit for bit
    from clsas.image.backprojection import launcher, records, tile_kernel

    echo = compressed(presets.point_scene("huang2022", n_pulses=64))
    grid = Grid.plane(np.linspace(40.0, 80.0, 40), np.linspace(-4.0, 4.0, 24), 0.0)
    counts, launch = [], tile_kernel.TileKernel.launch
    monkeypatch.setattr(tile_kernel.TileKernel, "launch",
                        lambda self, queue, **a: counts.append(a["p_count"]) or launch(self, queue, **a))
    n_samples = prepare(echo, grid=grid).length.max()  # a plain call's records (the grid's reach, x8)
    monkeypatch.setattr(records, "LAUNCH_RECORD_BYTES", int(8 * n_samples * TileKernel.PULSE_BLOCK / 2.5))
    small = backproject(echo, grid, progress=False).data
    assert set(counts) == {TileKernel.PULSE_BLOCK}
    counts.clear()
    monkeypatch.setattr(launcher, "TWO_LANE_SLOTS", TileKernel.LANES)  # the grid is a large chunk now
    assert np.array_equal(backproject(echo, grid, progress=False).data, small)
    assert max(counts) == TileKernel.PULSE_BLOCK // 4


def test_the_second_lane_waits_for_the_pixel_fields_of_the_first(opencl_device, monkeypatch):
    # bp_fields runs on the first lane's queue; the second lane's launches read its output: they must wait for it
    # (review 14 M1). bp_fields is held back by a user event for 0.3 s, on a grid no call imaged before (fresh
    # memory), with groups of one receiver (no shared references, whose barrier would order them anyway)
    import threading

    import pyopencl as cl

    from clsas.image.backprojection import launcher, tile_kernel

    monkeypatch.setattr(launcher, "REF_BYTES", 1)
    echo = compressed(presets.point_scene("huang2022", n_pulses=32))
    backproject(echo, Grid.plane(np.linspace(40.5, 80.5, 40), np.linspace(-4.0, 4.0, 24), 0.0), progress=False)
    fields, queues, launch = tile_kernel.TileKernel.fields, [], tile_kernel.TileKernel.launch

    def held(self, queue, **args):
        gate = cl.UserEvent(queue.context)
        cl.enqueue_barrier(queue, wait_for=[gate])
        threading.Timer(0.3, lambda: gate.set_status(cl.command_execution_status.COMPLETE)).start()
        return fields(self, queue, **args)

    monkeypatch.setattr(tile_kernel.TileKernel, "launch",
                        lambda self, queue, **a: queues.append(queue.int_ptr) or launch(self, queue, **a))
    shifted = Grid.plane(np.linspace(40.75, 80.75, 40), np.linspace(-4.0, 4.0, 24), 0.0)  # stale fields are wrong
    expected = backproject(echo, shifted, backend="numpy", progress=False).data
    monkeypatch.setattr(tile_kernel.TileKernel, "fields", held)
    got = backproject(echo, shifted, progress=False).data
    assert len(set(queues)) == 2
    assert rel_l2(got, expected) < 7e-3  # measured 7.4e-4 (bp_tile's float32 error against the reference)


def test_kernel_seconds_count_overlapping_kernels_once(opencl_device):
    # two lanes' kernels overlap in time: kernel_seconds is the union of their intervals (review 14 L2), so a call's
    # kernel time is at most its wall time
    import time

    from clsas.image.backprojection.launcher import _union_seconds

    assert _union_seconds([(20, 25), (0, 10), (5, 15), (6, 9)]) == pytest.approx(20e-9)
    assert _union_seconds([]) == 0.0
    echo = compressed(presets.point_scene("huang2022", n_pulses=32))
    grid = Grid.plane(np.linspace(40.0, 80.0, 40), np.linspace(-4.0, 4.0, 24), 0.0)
    backproject(echo, grid, progress=False)
    for _ in range(3):
        start = time.perf_counter()
        image = backproject(echo, grid, progress=False)
        assert 0 < image.provenance["kernel_seconds"] <= time.perf_counter() - start


def test_the_plans_kept_inputs_stay_within_their_bound(opencl_device, monkeypatch):
    # every live Grid's plan may keep its device inputs (review 14 L1): all of them together stay within
    # tiles.kept_limit, the least recently used let go first; the latest call's are kept; inputs larger than the
    # bound are not kept at all; a grid imaged again after being let go gives the same image
    from clsas.image.backprojection import tiles

    echo = compressed(presets.point_scene("huang2022", n_pulses=8))
    grids = [Grid.plane(np.linspace(40.0 + k, 80.0 + k, 40), np.linspace(-4.0, 4.0, 24), 0.0) for k in range(4)]
    plans = [GridPlan(g) for g in grids]
    for other in list(tiles._KEPT.keys()):  # earlier tests' plans, still alive
        other.release()
    first = backproject(echo, plans[0], progress=False).data
    one = tiles.kept_bytes()
    assert one > 0 and plans[0]._kept is not None
    monkeypatch.setattr(tiles, "KEPT_BYTES", int(2.5 * one))  # room for two grids' inputs
    for plan in plans[1:]:
        backproject(echo, plan, progress=False)
        assert tiles.kept_bytes() <= tiles.kept_limit() and plan._kept is not None
    assert [p._kept is not None for p in plans] == [False, False, True, True]
    assert np.array_equal(backproject(echo, plans[0], progress=False).data, first)
    assert [p._kept is not None for p in plans] == [True, False, False, True]  # plans[2] the least recently used
    monkeypatch.setattr(tiles, "KEPT_BYTES", one // 2)  # smaller than one grid's inputs: nothing kept
    backproject(echo, plans[1], progress=False)
    assert plans[1]._kept is None and tiles.kept_bytes() <= one


def test_a_call_that_raises_finishes_the_commands_it_queued(opencl_device, kiang_echo, monkeypatch):
    """backproject_opencl queues the first job's upload and upsampling before its set-up (review 13
    L4): when the set-up raises, the call waits for those commands (they read host arrays that
    unwind with it) before the error leaves it. The queue is held shut by a user event that a
    timer opens 0.3 s later: the error may leave only after that."""
    import threading
    import time

    import pyopencl as cl

    from clsas import opencl
    from clsas.image.backprojection import launcher

    grid = around((30.0, 1.0, -43.0), 0.02, 0.05, 12, 12)

    def broken(*args, **kwargs):
        raise RuntimeError("set-up failed")

    monkeypatch.setattr(launcher.TileKernel, "for_receiver", broken)
    rt = opencl.runtime()
    gate = cl.UserEvent(rt.context)
    cl.enqueue_barrier(rt.queue, wait_for=[gate])
    opened = []

    def open_gate():
        opened.append(time.monotonic())
        gate.set_status(cl.command_execution_status.COMPLETE)

    timer = threading.Timer(0.3, open_gate)
    timer.start()
    try:
        with pytest.raises(RuntimeError, match="set-up failed"):
            backproject(kiang_echo, grid, backend="opencl", interp="linear", upsample=4, progress=False)
        raised = time.monotonic()
    finally:
        timer.join()
    assert opened and raised >= opened[0]



def test_bp_order_sees_the_pixels_not_zero_and_not_finite(opencl_device, rng):
    # bp_order's checks (launcher._Chunk.in_grid_order's seen, which replace the call's passes of np.any and
    # finite_result over a grid of one chunk's image): bit 1 when a pixel is not zero, bit 2 when one is not finite
    # (past float's range or NaN), padding slots (NaN here) not counted; each pixel tried alone, at the ends of the
    # work-items' runs of pixels and past them
    import types

    import pyopencl as cl

    from clsas.image.backprojection import launcher

    pixels = rng.uniform(-40.0, 40.0, (5000, 3)) + [2000.0, 0.0, -300.0]
    tiles = plan_tiles(pixels, 150e3, 1500.0)
    tile = TileKernel("linear", rows=tiles.rows)

    def seen_of(sums):
        sums = sums.copy()
        sums[~tiles.real] = np.nan
        buf = cl.Buffer(opencl_device.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=sums)
        seen = []
        image = launcher._Chunk.in_grid_order(types.SimpleNamespace(sums=buf), opencl_device.queue, tiles, tile, seen)
        expected = np.any(image) | 2 * (not np.all(np.isfinite(image)))
        assert seen == [expected]
        return seen[0]

    zeros = np.zeros(tiles.order.size, np.complex128)
    assert seen_of(zeros) == 0 and seen_of(zeros - 0.0 - 0.0j * 0) == 0
    assert seen_of(np.full_like(zeros, -0.0)) == 0
    run = launcher.ORDER_RUN
    for m in sorted({0, run - 1, run, 2 * run + 5, len(pixels) - 1, int(rng.integers(len(pixels)))}):
        for value, bits in ((1e-30 + 0j, 1), (-3j, 1), (1e-46 + 0j, 0), (1e39 + 0j, 3), (complex(0, np.nan), 3),
                            (complex(-np.inf, 0), 3)):
            one = zeros.copy()
            one[tiles.slot_of[m]] = value  # pixel m alone (1e-46 rounds to float 0; 1e39 past float's range)
            assert seen_of(one) == bits, (m, value)


def test_records_not_upsampled_are_read_whole_without_the_grids_reach(opencl_device, kiang_echo, monkeypatch):
    # a call whose records are not upsampled (upsample=1, or sinc8) reads them whole in place without computing the
    # grid's reach (records.records_for): the same image as records prepared with the grid's reach, bit for bit; a
    # grid outside every record still images zeros, with the coverage warning
    from clsas.image.backprojection import records as bp_records
    from clsas.validate import CoverageWarning

    calls = []
    reach_of = bp_records.reach
    monkeypatch.setattr(bp_records, "reach", lambda *a, **k: calls.append(1) or reach_of(*a, **k))
    grid = around((1989.0, 0.0, -350.0), 0.02, 0.05, 16, 16)
    for interp, upsample in (("linear", 1), ("sinc8", None)):
        got = backproject(kiang_echo, grid, backend="opencl", interp=interp, upsample=upsample, progress=False)
        assert not calls
        held = prepare(kiang_echo, upsample=upsample or 8, interp=interp, grid=grid)
        assert calls  # prepare's reach, as before
        calls.clear()
        assert got.data.tobytes() == backproject(held, grid, backend="opencl", progress=False).data.tobytes()
        with pytest.warns(CoverageWarning, match="all zeros"):
            far = backproject(kiang_echo, around((20000.0, 0.0, -350.0), 0.02, 0.05, 8, 8), backend="opencl",
                              interp=interp, upsample=upsample, progress=False)
        assert not np.any(far.data) and not calls
    backproject(kiang_echo, grid, backend="opencl", interp="linear", upsample=2, progress=False)
    assert calls  # upsampled records: only the span the grid reaches


def test_held_records_staged_for_their_kernels_give_the_same_image(opencl_device, kiang_echo, monkeypatch):
    # a call on prepared (held) records copies each job's rows, up to records.STAGE_BYTES, into its queue's scratch
    # buffer before the kernels read them (PreparedRecords.buffer(staged=True)): the same image bit for bit as the
    # held buffer read in place and as the plain call, on one lane and two, for all pulses and for a sub-aperture
    # (rows copied from a pulse after the first); double precision reads the held buffer
    import pyopencl as cl

    from clsas.image.backprojection import launcher, records

    grid = around((1989.0, 0.0, -350.0), 0.02, 0.05, 24, 24)
    held = prepare(kiang_echo, upsample=4, grid=grid)
    assert 8 * kiang_echo.n_pulses * int(held.length.max()) <= records.STAGE_BYTES  # every receiver's job staged
    copy, copies, stage_bytes = cl.enqueue_copy, [], records.STAGE_BYTES
    monkeypatch.setattr(cl, "enqueue_copy", lambda *a, **k: copies.append(k.get("src_offset")) or copy(*a, **k))
    for two_lanes in (False, True):
        monkeypatch.setattr(launcher, "TWO_LANES", two_lanes)
        for pulses in (None, (7, 21)):
            kw = dict(backend="opencl", pulses=pulses, progress=False)
            plain = backproject(kiang_echo, grid, upsample=4, **kw).data
            copies.clear()
            staged = backproject(held, grid, **kw).data
            first = 0 if pulses is None else pulses[0]
            assert sorted(copies) == sorted(8 * first * int(n) for n in held.length)  # each receiver's rows, once
            monkeypatch.setattr(records, "STAGE_BYTES", 8 * int(held.length.min()) - 1)  # no job fits: in place
            copies.clear()
            in_place = backproject(held, grid, **kw).data
            monkeypatch.setattr(records, "STAGE_BYTES", stage_bytes)
            assert not copies
            assert staged.tobytes() == in_place.tobytes() == plain.tobytes()
    copies.clear()
    backproject(held, grid, backend="opencl", precision="double", progress=False)
    assert not copies


def test_two_threads_on_the_same_held_records_get_their_own_staging(opencl_device):
    # review 15 M1: calls on two threads with the same prepared (held) records share the runtime's queue; each
    # stages its jobs' rows into buffers the call owns (the launcher's staging dict, records.PreparedRecords.buffer),
    # so that the other's copy cannot land between its copy and its kernels: every image equals the one-thread
    # image, bit for bit (with one scratch a queue kept on the records, 5 of 40 calls came out wrong, rel L2 0.33)
    import threading

    sc = oversampled(presets.kiang2022(n_pulses=96)).replace(targets=(
        PointTargets([[1989.0, 0.0, -350.0], [30.0, 1.0, -43.0]], velocity=(0.5, -1.0, 0.0)),))
    echo = compressed(sc, intra_pulse="none")
    grids = [around((1989.0, 0.0, -350.0), 0.02, 0.05, 24, 24), around((1989.3, 0.1, -350.0), 0.02, 0.05, 24, 24)]
    held = prepare(echo, upsample=4, grid=around((1989.15, 0.05, -350.0), 0.04, 0.1, 24, 24))
    kw = dict(backend="opencl", progress=False)
    truth = [backproject(held, g, **kw).data for g in grids]
    wrong, failed = [0, 0], []

    def run(k):
        try:
            for _ in range(15):
                wrong[k] += not np.array_equal(backproject(held, grids[k], **kw).data, truth[k])
        except BaseException as error:  # (a thread's exception would otherwise not fail the test)
            failed.append(error)

    threads = [threading.Thread(target=run, args=(k,)) for k in (0, 1)]
    [t.start() for t in threads]
    [t.join() for t in threads]
    assert not failed and wrong == [0, 0]


def _monostatic_echo(velocity, n_pulses: int = 96, n_samples: int = 1024):
    """A monostatic sonar's echo (random records, seeded) for exact delays with one leg (MONO): the
    receiver at the transmitter at emission, moving on at ``velocity(p)`` (m/s, a (P, 3) array) for
    0.25 s (two position nodes); the transmitter along y at 1.6 m/s."""
    from clsas import EchoData, Medium, Waveform

    eta = (np.arange(n_pulses) - n_pulses / 2) / 16.0
    tx = np.column_stack([np.zeros(n_pulses), 1.6 * eta, np.zeros(n_pulses)])
    rx = np.stack([tx, tx + 0.25 * velocity], axis=1)[None]
    rng = np.random.default_rng(5)
    data = (rng.standard_normal((1, n_pulses, n_samples)) + 1j * rng.standard_normal((1, n_pulses, n_samples)))
    return EchoData(data=data.astype(np.complex64), eta=eta, t0=[2 * 30.0 / 1500.0], fs=40e3, tx_pos=tx, rx_pos=rx,
                    rx_tau=[[0.0, 0.25]], waveform=Waveform(f0=150e3, bandwidth=20e3, duration=5e-3, fs=40e3),
                    medium=Medium(1500.0), receivers=("A",), compressed=True)


@pytest.mark.parametrize("velocity", ["constant", "along y", "three axes"])
def test_one_leg_with_a_constant_or_a_varying_receiver_velocity(opencl_device, velocity):
    """With exact delays and one leg (MONO), bp_tile makes each row's w . delta once and again only
    on a pulse whose w (2 v_r / (c^2 - |v_r|^2)) differs from the one it holds in any component: a
    receiver at constant velocity (the same w on every pulse), one whose speed along track changes
    from pulse to pulse (only w.y changes) and one whose velocity changes along all three axes (a
    new w on every pulse, over two launches of pulses) all match the NumPy reference. A kernel that
    kept the first pulse's w fails both varying cases; one that remade wd only when every component
    of w changed fails the case along y."""
    n_pulses = 96
    p = np.arange(n_pulses)[:, None]
    v = {"constant": np.hstack([0 * p, 1.6 + 0 * p, 0 * p]),
         "along y": np.hstack([0 * p, 1.6 + 0.8 * np.cos(p / 5.0), 0 * p]),
         "three axes": np.hstack([0.8 * np.sin(p / 3.0), 1.6 + 0.8 * np.cos(p / 5.0), 0.3 * np.sin(p / 4.0)])}
    echo = _monostatic_echo(v[velocity], n_pulses)
    assert TileKernel("linear").legs_for(echo, 0) == "mono"
    grid = Grid.plane(np.linspace(36.0, 60.0, 64), np.linspace(-6.0, 6.0, 64), 0.0)
    kw = dict(interp="linear", upsample=1, progress=False)
    ref = backproject(echo, grid, backend="numpy", **kw)
    got = backproject(echo, grid, backend="opencl", **kw)
    assert rel_l2(got.data, ref.data) < 2e-3  # measured 2.3e-4 (constant), 1.7e-4 (along y and three axes)


def test_held_records_are_staged_only_where_the_grid_reaches_most_of_them(opencl_device, kiang_echo, monkeypatch):
    # a patch of records prepared whole reads a narrow span of each row: the call reads them in place (no copy),
    # and the image is bit for bit the staged one's; records prepared for the grid's reach are staged
    # (launcher._stage_worth_it, STAGE_SHARE)
    import pyopencl as cl

    from clsas.image.backprojection import launcher, records

    grid = around((1989.0, 0.0, -350.0), 0.02, 0.05, 24, 24)
    whole, fitted = prepare(kiang_echo, upsample=4), prepare(kiang_echo, upsample=4, grid=grid)
    monkeypatch.setattr(records, "STAGE_BYTES", 2**30)  # every job small enough to stage, whole rows too
    copy, copies = cl.enqueue_copy, []
    monkeypatch.setattr(cl, "enqueue_copy", lambda *a, **k: copies.append(k.get("src_offset")) or copy(*a, **k))
    in_place = backproject(whole, grid, backend="opencl", progress=False).data
    assert not copies
    monkeypatch.setattr(launcher, "STAGE_SHARE", 0.0)  # stage whatever the grid reaches
    staged = backproject(whole, grid, backend="opencl", progress=False).data
    assert len(copies) == len(whole.receivers)
    assert staged.tobytes() == in_place.tobytes()
    monkeypatch.setattr(launcher, "STAGE_SHARE", 0.5)
    copies.clear()
    backproject(fitted, grid, backend="opencl", progress=False)
    assert len(copies) == len(fitted.receivers)


def test_a_call_on_held_records_computes_the_grids_reach_once(opencl_device, kiang_echo, monkeypatch):
    # records.records_for computes the reach of a call on held records not prepared whole (their coverage) and hands
    # it to the launcher's staging choice (launcher._stage_worth_it), which computes its own only for records
    # prepared whole (no coverage to check): one reach a call either way, and the staging choice unchanged
    # (records prepared for the grid staged, a patch of records prepared whole read in place)
    import pyopencl as cl

    from clsas.image.backprojection import launcher, records

    calls = []

    def counted(of):
        return lambda *a, **k: calls.append(of) or spans_reach(*a, **k)

    spans_reach = records.reach
    monkeypatch.setattr(records, "reach", counted("records"))
    monkeypatch.setattr(launcher, "reach", counted("launcher"))
    monkeypatch.setattr(records, "STAGE_BYTES", 2**30)  # every job small enough to stage, whole rows too
    copy, copies = cl.enqueue_copy, []
    monkeypatch.setattr(cl, "enqueue_copy", lambda *a, **k: copies.append(1) or copy(*a, **k))
    grid = around((1989.0, 0.0, -350.0), 0.02, 0.05, 24, 24)
    whole, fitted = prepare(kiang_echo, upsample=4), prepare(kiang_echo, upsample=4, grid=grid)
    calls.clear()
    backproject(fitted, grid, backend="opencl", progress=False)
    assert calls == ["records"] and len(copies) == len(fitted.receivers)
    calls.clear(), copies.clear()
    backproject(whole, grid, backend="opencl", progress=False)
    assert calls == ["launcher"] and not copies
    calls.clear()
    backproject(fitted, grid, backend="numpy", progress=False)
    assert calls == ["records"]


def test_a_calls_record_buffers_count_against_the_memory_budget(opencl_device, kiang_echo, monkeypatch):
    # review 14 L3, review 16 L1: a call's buffers for its records count with its pixels in the memory budget
    # (records.record_bytes, checked by backproject on both backends), single and double precision: records made per
    # call (single: the FIR's scratch buffer of each of two lanes; double: complex128 jobs in flight), held records
    # (single: the rows two lanes stage, each lane's buffer made at the call's largest rows, which here grow from one
    # receiver to the next on a lane; double: the complex128 copies the first double call makes and keeps). A budget a
    # byte too small refuses the call, naming it, before any of its records are made; a budget that holds them runs
    # it, the image as under the default budget bit for bit, the records' device buffers alive at once within the
    # count (single: equal to it), a held double call's copies the count
    import weakref

    import pyopencl as cl

    from clsas.image.backprojection import direct, launcher, records

    made, alive, inside, real = [], [0, 0], [0], cl.Buffer

    class Counted(real):  # the buffers records' methods make that are not the host's arrays in place
        def __init__(self, *a, **k):
            real.__init__(self, *a, **k)
            if inside[0] and not (a[1] if len(a) > 1 else k.get("flags", 0)) & cl.mem_flags.USE_HOST_PTR:
                alive[0] += self.size
                alive[1] = max(alive)
                weakref.finalize(self, lambda n=self.size: alive.__setitem__(0, alive[0] - n))

    for name in ("buffer", "samples", "_upsampled_on_device", "_scratch_of"):
        def counted(self, *a, _m=getattr(records.PreparedRecords, name), _n=name, **k):
            made.append(_n)
            inside[0] += 1
            try:
                return _m(self, *a, **k)
            finally:
                inside[0] -= 1
        monkeypatch.setattr(records.PreparedRecords, name, counted)
    grid = around((1989.0, 0.0, -350.0), 0.2, 0.5, 32, 32)
    for precision, double in (("single", False), ("double", True)):
        for held in (False, True):
            def source():
                return prepare(kiang_echo, upsample=8, grid=grid) if held else kiang_echo
            plain, _, span, _ = records.records_for(source(), grid, None, None, None, None, None)
            extra = records.record_bytes(plain, span, double)
            need = direct.BYTES_PER_PIXEL * grid.size + extra
            assert extra > direct.BYTES_PER_PIXEL * grid.size  # the records' buffers weigh here
            expected = backproject(source(), grid, backend="opencl", progress=False, precision=precision).data
            for backend in ("opencl", "numpy"):
                echo = source()
                made.clear()
                with clsas.use_memory_budget(need - 1), pytest.raises(clsas.errors.MemoryBudgetError,
                                                                      match=f"backproject onto {grid.size} pixels and"):
                    backproject(echo, grid, backend=backend, progress=False, precision=precision)
                assert not made, (precision, held, backend)
            echo = source()
            monkeypatch.setattr(cl, "Buffer", Counted)
            alive[:] = [0, 0]
            with clsas.use_memory_budget(need):
                got = backproject(echo, grid, backend="opencl", progress=False, precision=precision).data
            monkeypatch.setattr(cl, "Buffer", real)
            assert got.tobytes() == expected.tobytes(), (precision, held)
            # (records made per call in double: the host arrays of the job being made, complex64 and complex128, are
            # counted beside the device's jobs)
            job = min(plain.upload_pulses(), span[1] - span[0]) * int(plain.length.max())
            host = 24 * job if double and not held else 0
            assert (alive[1] <= extra - host) if double else (alive[1] == extra), (precision, held, alive, extra)
            if held and double:  # the copies made and kept: the count, then nothing more to make
                assert sum(host.nbytes for (_, _, d), (_, host) in echo._device.items() if d) == extra
                assert records.record_bytes(echo, span, True) == 0


@pytest.mark.parametrize("n_pulses", [1, 7, 13])
def test_references_on_the_device_for_pulse_counts_not_a_multiple_of_eight(opencl_device, kiang_echo, n_pulses):
    """bp_refs computes eight consecutive pulses of a tile a work-item (double8 lanes, REF_LANES): a
    job whose pulse count leaves a partial last group still gets every (tile, pulse) reference within
    float32 rounding of the NumPy twin's, for each receiver's legs and for two receivers in one
    launch (whose rows of 2 x 13 pulses leave a partial group too). A launch of n_pulses // 8
    groups a tile (floor instead of ceiling) fails every count here."""
    import pyopencl as cl

    centres = np.array([[30.0, 1.0, -43.0], [1989.0, 0.0, -350.0], [31.5, -2.0, -41.0], [29.0, 0.5, -44.0],
                        [33.0, 2.0, -40.0]])
    pulses = np.arange(5, 5 + n_pulses)
    buf = cl.Buffer(opencl_device.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=centres)
    for h in range(kiang_echo.n_rx):
        tile = TileKernel("linear").for_receiver(kiang_echo, h)
        host, _ = tile.references(kiang_echo, h, pulses, centres, kiang_echo.fs, 2.5, offset=3)
        dev = tile.references_on_device(opencl_device.queue, kiang_echo, h, pulses, buf, len(centres), kiang_echo.fs,
                                        2.5, offset=3)
        got = np.empty_like(host)
        cl.enqueue_copy(opencl_device.queue, got, dev)
        _same_references(got, host, h)
    tile = TileKernel("linear").for_receiver(kiang_echo, 1)
    dev = tile.references_on_device(opencl_device.queue, kiang_echo, [1, 2], pulses, buf, len(centres),
                                    kiang_echo.fs, 2.5, offset=np.array([3, 9]))
    got = np.empty((len(centres), 2, n_pulses), tile.reference_dtype)
    cl.enqueue_copy(opencl_device.queue, got, dev)
    for j, (h, offset) in enumerate(((1, 3), (2, 9))):
        host, _ = tile.references(kiang_echo, h, pulses, centres, kiang_echo.fs, 2.5, offset=offset)
        _same_references(got[:, j], host, h)


def test_w_runs_count_the_following_pulses_with_the_same_float_bits():
    """tile_kernel.w_runs, legs "mono"'s w_run: for each pulse, how many of the pulses that follow
    it have a w of the same float32 bits (bp_tile makes w . delta once for them). Values that differ
    only beyond float32 (1 + 1e-12) are the same; -0.0 and 0.0 are not (different bits)."""
    from clsas.image.backprojection.tile_kernel import w_runs

    w = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0 + 1e-12], [1.0, 2.0, 4.0], [1.0, 2.0, 4.0], [1.0, 2.0, 4.0],
                  [0.0, 0.0, 0.0], [-0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    assert w_runs(w).tolist() == [1, 0, 2, 1, 0, 0, 0, 0]
    assert w_runs(w[:1]).tolist() == [0] and w_runs(np.zeros((0, 3))).tolist() == []
    assert w_runs(np.ones((5, 3))).tolist() == [4, 3, 2, 1, 0]
