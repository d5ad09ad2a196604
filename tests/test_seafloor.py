"""The seafloor: sediment reflection and backscatter laws, bathymetry, speckle facets, TOML."""

from __future__ import annotations

import numpy as np
import pytest

import clsas
from clsas.errors import ScenarioFileError
from clsas.io.toml import scenario_from_toml
from clsas.scene import presets
from clsas.scene.seafloor import SEDIMENTS, Seafloor, Sediment, generate
from clsas.scene.seafloor.facets import BAND_FACETS, cell_uniforms, facet_spacing, resolution_cell
from clsas.scene.surface import SeaSurface

DEG = np.pi / 180


def test_table_has_the_named_sediments_and_names_resolve():
    assert {"mud", "sand", "gravel", "rock"} <= set(SEDIMENTS)
    assert Seafloor((0, 1, 0, 1), -5.0, sediment="mud").sediment is SEDIMENTS["mud"]
    with pytest.raises(ValueError, match="sediment: must be one of"):
        Seafloor((0, 1, 0, 1), -5.0, sediment="peat")


@pytest.mark.parametrize("name", sorted(SEDIMENTS))
def test_reflection_at_normal_incidence_and_grazing(name):
    s = SEDIMENTS[name]
    impedance = s.density_ratio * s.sound_speed_ratio
    v = s.reflection_coefficient(np.pi / 2)
    # normal incidence: P = kappa, so V = (rho nu - 1 - i delta) / (rho nu + 1 + i delta)
    assert abs(v - (impedance - 1 - 1j * s.loss) / (impedance + 1 + 1j * s.loss)) < 1e-12
    assert abs(s.reflection_coefficient(0.0) + 1) < 1e-12  # grazing incidence: -1
    theta = np.linspace(0, np.pi / 2, 91)
    assert np.all(np.abs(s.reflection_coefficient(theta)) <= 1 + 1e-12)  # a lossy bed returns no more


def test_lossless_fast_bed_totally_reflects_below_the_critical_angle():
    s = Sediment(density_ratio=1.9, sound_speed_ratio=1.2, loss=0.0)
    critical = np.arccos(1 / 1.2)
    below, above = np.linspace(0.01, critical - 1e-3, 50), np.linspace(critical + 1e-3, np.pi / 2, 50)
    np.testing.assert_allclose(np.abs(s.reflection_coefficient(below)), 1.0, atol=1e-12)
    assert np.all(np.abs(s.reflection_coefficient(above)) < 1 - 1e-3)
    lossy = Sediment(density_ratio=1.9, sound_speed_ratio=1.2, loss=0.02)
    assert np.all(np.abs(lossy.reflection_coefficient(below)) < 1)  # the loss leaks energy into the bed


def test_perturbation_term_equals_the_bistatic_form_at_backscatter():
    """APL-94's monostatic sigma_pr against Williams & Jackson's bistatic 1/4 k^4 |1+V|^4 |G|^2 W
    with S = cos(theta_i) cos(theta_s) cos(phi) = -cos^2(theta) (backscatter), written out here."""
    s = SEDIMENTS["sand"]
    k = 2 * np.pi * 100e3 / 1500
    theta = np.linspace(5, 55, 11) * DEG
    kappa2 = s.kappa**2
    p = s._p(np.cos(theta))
    rho = s.density_ratio
    g = (1 / rho - 1) * (-np.cos(theta) ** 2 - p * p / rho) + 1 - kappa2 / rho
    bistatic = 0.25 * k**4 * np.abs(1 + s._reflection(theta)) ** 4 * np.abs(g) ** 2 \
        * s.roughness_spectrum(2 * k * np.cos(theta))
    np.testing.assert_allclose(s._perturbation(theta, k), bistatic, rtol=1e-10)


def test_volume_term_reduces_to_the_half_space_result_for_water():
    """rho = nu = 1: sigma_v -> 5 sigma2 sin(theta) / ln(10) as delta -> 0."""
    s = Sediment(density_ratio=1.0, sound_speed_ratio=1.0, loss=1e-6, volume_ratio=0.003)
    theta = np.linspace(10, 80, 8) * DEG
    np.testing.assert_allclose(s._volume(theta, 400.0), 5 * 0.003 * np.sin(theta) / np.log(10), rtol=1e-4)


def test_laws_levels_and_ordering():
    """Physical model at 100 kHz: harder beds scatter more (rock > gravel > sand > mud at 10-60
    deg); the crossover is continuous; Lambert's fitted mu is within 3 dB of the model over the
    fit's angles (sand) and its own law is exactly mu sin^2."""
    theta = np.linspace(10, 60, 26) * DEG
    levels = {n: SEDIMENTS[n].backscatter_strength_db(theta, 100e3) for n in ("rock", "gravel", "sand", "mud")}
    assert np.all(levels["rock"].mean() > levels["gravel"].mean())
    assert np.all(levels["gravel"] > levels["sand"]) and np.all(levels["sand"] > levels["mud"])
    assert np.all((levels["sand"] > -40) & (levels["sand"] < -10))
    fine = np.linspace(55, 80, 501) * DEG
    assert np.max(np.abs(np.diff(SEDIMENTS["sand"].backscatter_strength_db(fine, 100e3)))) < 0.1
    lambert = SEDIMENTS["sand"].backscatter_strength_db(theta, 100e3, law="lambert")
    assert np.max(np.abs(lambert - levels["sand"])) < 3.0
    mu = Sediment(lambert_mu_db=-27.0).backscatter_strength_db(theta, 100e3, law="lambert")
    np.testing.assert_allclose(mu, -27 + 20 * np.log10(np.sin(theta)), atol=1e-9)


def test_law_arguments_are_checked():
    s = SEDIMENTS["sand"]
    with pytest.raises(ValueError, match=r"grazing angles must be in \[0, pi/2\]"):
        s.backscatter_strength_db(2.0, 1e5)
    with pytest.raises(ValueError, match="f_hz: must be in"):
        s.backscatter_strength_db(0.3, -1.0)
    with pytest.raises(ValueError, match="law: must be one of"):
        s.backscatter_strength_db(0.3, 1e5, law="phong")
    with pytest.raises(ValueError, match="Sediment.density_ratio"):
        Sediment(density_ratio=0.0)
    with pytest.raises(TypeError, match="Sediment.loss"):
        Sediment(loss="0.01")


def test_surface_reflection():
    flat = SeaSurface(z=0.0)
    np.testing.assert_array_equal(flat.reflection_coefficient(np.array([0.1, 1.0]), 1e5), -1.0)
    rough = SeaSurface(z=0.0, rms_height=0.01)
    k = 2 * np.pi * 1e5 / 1500
    assert rough.reflection_coefficient(0.5, 1e5) == pytest.approx(-np.exp(-2 * (k * 0.01 * np.sin(0.5)) ** 2))
    with pytest.raises(ValueError, match="SeaSurface.rms_height"):
        SeaSurface(rms_height=-1.0)


def test_height_gradient_and_normal_of_ripples_slope_and_map():
    rng = np.random.default_rng(1)
    heights = rng.normal(scale=0.2, size=(12, 14))
    floor = Seafloor((0.0, 20.0, -10.0, 10.0), -12.0, slope=(0.05, -0.02), heights=heights, spacing=2.0,
                     origin=(-2.0, -12.0), ripple_wavelength=0.7, ripple_height=0.06, ripple_direction=0.4)
    x, y = rng.uniform(0, 20, 200), rng.uniform(-10, 10, 200)
    h = 1e-5
    gx, gy = floor.gradient(x, y)
    np.testing.assert_allclose(gx, (floor.height(x + h, y) - floor.height(x - h, y)) / (2 * h), atol=1e-6)
    np.testing.assert_allclose(gy, (floor.height(x, y + h) - floor.height(x, y - h)) / (2 * h), atol=1e-6)
    n = floor.normal(x, y)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0)
    np.testing.assert_allclose(n[:, 0] / n[:, 2], -gx)
    # the map's samples are reproduced (bicubic spline through them)
    np.testing.assert_allclose(Seafloor((0.0, 20.0, -10.0, 10.0), -12.0, heights=heights, spacing=2.0,
                                        origin=(-2.0, -12.0)).height(-2.0 + 2.0 * 3, -12.0 + 2.0 * 5),
                               -12.0 + heights[5, 3], atol=1e-9)
    point, normal = floor.reflection_plane()
    np.testing.assert_allclose(point, [0, 0, -12.0])
    np.testing.assert_allclose(normal, np.array([-0.05, 0.02, 1.0]) / np.linalg.norm([-0.05, 0.02, 1.0]))
    lo, hi = floor.height_range()
    assert lo < floor.height(x, y).min() and hi > floor.height(x, y).max()


def test_a_height_function_is_used_and_differentiated():
    floor = Seafloor((0, 10, 0, 10), -5.0, heights=lambda x, y: 0.1 * np.sin(x) * np.cos(y))
    x, y = np.array([1.0, 2.0]), np.array([0.5, 3.0])
    np.testing.assert_allclose(floor.height(x, y), -5 + 0.1 * np.sin(x) * np.cos(y))
    np.testing.assert_allclose(floor.gradient(x, y)[0], 0.1 * np.cos(x) * np.cos(y), atol=1e-7)
    with pytest.raises(TypeError, match="sample it first"):
        clsas.scenario_to_toml(presets.heremans2009(n_pulses=4).replace(seafloor=floor))


def test_seafloor_checks_name_the_field():
    with pytest.raises(ValueError, match="Seafloor.extent: must be"):
        Seafloor((1, 0, 0, 1), -5.0)
    with pytest.raises(ValueError, match="Seafloor.ripple_wavelength"):
        Seafloor((0, 1, 0, 1), -5.0, ripple_height=0.1)
    with pytest.raises(ValueError, match="must cover extent"):
        Seafloor((0, 10, 0, 10), -5.0, heights=np.zeros((3, 3)), spacing=1.0)
    with pytest.raises(TypeError, match="Seafloor.seed"):
        Seafloor((0, 1, 0, 1), -5.0, seed=1.5)
    with pytest.raises(TypeError, match="Scenario.seafloor must be a Seafloor"):
        presets.heremans2009(n_pulses=4).replace(seafloor="sand")
    with pytest.raises(ValueError, match="must lie above the seafloor"):
        presets.heremans2009(n_pulses=4).replace(seafloor=Seafloor((0, 1, 0, 1), 2.0), surface=SeaSurface(z=1.0))
    with pytest.raises(ValueError, match="must lie above the platform"):
        presets.heremans2009(n_pulses=4).replace(surface=SeaSurface(z=-1.0))


def test_facets_density_reach_and_determinism():
    scene = presets.heremans2009(n_pulses=16)
    floor = Seafloor((60.0, 80.0, -40.0, 40.0), -10.0, ripple_wavelength=0.6, ripple_height=0.04, seed=3)
    facets = generate(floor, scene)
    across, along = resolution_cell(scene)
    assert facets.spacing == pytest.approx(np.sqrt(across * along / 4))
    y = facets.positions[:, 1]
    # sorted by along-track band, then x: a pulse's reach is one index range of whole bands
    assert np.all(np.diff(facets.bands) >= 0)
    same = np.diff(facets.bands) == 0
    assert np.all(np.diff(facets.positions[:, 0])[same] >= 0)
    np.testing.assert_array_equal(facets.bands, np.floor(y / (BAND_FACETS * facets.spacing)))
    for t in scene.tx_position(scene.eta[[0, 7, 15]]):
        first, stop = facets.reach_span(t, 81.0)  # no facet is farther across than 81 m
        inside = np.zeros(facets.count, dtype=bool)
        inside[first:stop] = True
        assert np.all(inside[facets.in_reach(t)]) and stop - first < facets.count
    ext = floor.extent
    assert np.all((facets.positions[:, 0] >= ext[0]) & (facets.positions[:, 0] <= ext[1]))
    # the drawn region holds every facet some pulse reaches (drawn everywhere, then kept where
    # reached), and little more (its bounds are conservative)
    everywhere = generate(Seafloor((60.0, 80.0, -40.0, 40.0), -10.0, ripple_wavelength=0.6, ripple_height=0.04,
                                   seed=3, beam_nulls=0), scene)
    tx = scene.tx_position(scene.eta)
    reached = np.zeros(everywhere.count, dtype=bool)
    for t in tx:
        reached |= np.abs(everywhere.positions[:, 1] - t[1]) <= facets.reach * np.hypot(
            *(everywhere.positions[:, [0, 2]] - t[[0, 2]]).T)
    assert np.isin(everywhere.positions[reached, 1], y).all()
    assert facets.count < 1.01 * reached.sum() and reached.sum() < everywhere.count
    assert everywhere.count == pytest.approx(20.0 * 80.0 / facets.spacing**2, rel=0.01)  # one per s^2
    np.testing.assert_allclose(facets.positions[:, 2], floor.height(facets.positions[:, 0], y))
    gx, gy = floor.gradient(facets.positions[:, 0], y)
    np.testing.assert_allclose(np.abs(facets.refl) ** 2, facets.spacing**2 * np.sqrt(1 + gx * gx + gy * gy))
    # a longer track draws more of the seafloor, and the shared cells are the same facets
    longer = generate(floor, presets.heremans2009(n_pulses=64))
    assert longer.count > facets.count
    common = np.isin(longer.positions[:, 1], y)
    assert common.sum() == facets.count
    np.testing.assert_array_equal(longer.refl[common], facets.refl)
    # the phases are uniform: the mean phasor of N facets is ~1/sqrt(N)
    assert abs(np.mean(facets.refl / np.abs(facets.refl))) < 5 / np.sqrt(facets.count)


def test_cell_uniforms_are_uniform_and_independent():
    i, j = np.meshgrid(np.arange(-300, 300), np.arange(-200, 200))
    u = cell_uniforms(i, j, seed=7, streams=3)
    assert u.min() >= 0 and u.max() < 1
    for s in range(3):
        assert abs(u[s].mean() - 0.5) < 0.005 and abs(u[s].var() - 1 / 12) < 0.002
    assert abs(np.corrcoef(u[0].ravel(), u[1].ravel())[0, 1]) < 0.01
    assert abs(np.corrcoef(u[0, :, 1:].ravel(), u[0, :, :-1].ravel())[0, 1]) < 0.01  # neighbours
    assert not np.array_equal(u, cell_uniforms(i, j, seed=8, streams=3))


def test_facet_spacing_from_the_resolution_and_an_omnidirectional_array():
    scene = presets.kiang2022(n_pulses=4)  # omnidirectional: lambda / 4 along track
    across, along = resolution_cell(scene)
    assert along == pytest.approx(0.25 * 1500 / 150e3) and across == pytest.approx(1500 / 40e3)
    floor = Seafloor((0, 1, 0, 1), -50.0, scatterers_per_cell=2.0)
    assert facet_spacing(floor, scene) == pytest.approx(np.sqrt(across * along / 2))
    assert facet_spacing(Seafloor((0, 1, 0, 1), -50.0, facet_spacing=0.1), scene) == 0.1


def test_facets_refuse_what_the_budget_cannot_hold():
    floor = Seafloor((0, 1e5, -1e5, 1e5), -50.0, facet_spacing=0.01, beam_nulls=0)
    with clsas.use_memory_budget("1G"), pytest.raises(ValueError, match="Seafloor facets"):
        generate(floor, presets.heremans2009(n_pulses=4))


def test_seafloor_and_surface_round_trip_through_toml(tmp_path):
    rng = np.random.default_rng(0)
    floor = Seafloor((40, 100, -50, 50), -10.0, sediment="gravel", slope=(0.01, 0.0), heights=rng.normal(size=(5, 5)),
                     spacing=30.0, ripple_wavelength=0.6, ripple_height=0.05, ripple_direction=0.3, seed=11)
    scene = presets.heremans2009(n_pulses=4).replace(seafloor=floor, surface=SeaSurface(z=5.0, rms_height=0.1))
    back = clsas.load_scenario(clsas.scenario_to_toml(scene, tmp_path / "floor.toml"))
    for name in ("extent", "slope", "heights", "origin"):
        np.testing.assert_array_equal(getattr(back.seafloor, name), getattr(floor, name))
    for name in ("z", "law", "spacing", "ripple_wavelength", "ripple_height", "ripple_direction",
                 "scatterers_per_cell", "facet_spacing", "beam_nulls", "seed"):
        assert getattr(back.seafloor, name) == getattr(floor, name)
    assert back.seafloor.sediment is SEDIMENTS["gravel"] or back.seafloor.sediment == SEDIMENTS["gravel"]
    assert back.surface == scene.surface
    custom = scene.replace(seafloor=Seafloor((40, 100, -50, 50), -10.0, sediment=Sediment("silty", 1.3, 1.02, 0.01)))
    text = clsas.scenario_to_toml(custom)
    assert "[seafloor.sediment]" in text
    assert scenario_from_toml(text).seafloor.sediment == custom.seafloor.sediment


def test_toml_errors_in_the_seafloor_tables_name_the_key():
    text = clsas.scenario_to_toml(presets.heremans2009(n_pulses=4).replace(
        seafloor=Seafloor((40, 100, -50, 50), -10.0, sediment=Sediment("silty", 1.3, 1.02, 0.01))))
    with pytest.raises(ScenarioFileError, match=r"\[seafloor.sediment\].loss: must be in"):
        scenario_from_toml(text.replace("loss = 0.01", "loss = -1.0"))
    with pytest.raises(ScenarioFileError, match=r"\[seafloor\].ripple_heigth.*did you mean 'ripple_height'"):
        scenario_from_toml(text.replace("ripple_height =", "ripple_heigth ="))
    with pytest.raises(ScenarioFileError, match=r"\[seafloor\]: missing key z"):
        scenario_from_toml(text.replace("\nz = -10.0", ""))


def test_heremans_seafloor_preset():
    scene = presets.heremans2009_seafloor(n_pulses=8)
    assert scene.seafloor.z == -15.0 and scene.seafloor.sediment is SEDIMENTS["sand"]
    np.testing.assert_allclose(scene.targets[0].positions[:, 2], -15.0)
    np.testing.assert_allclose(np.abs(scene.targets[0].reflectivity), 0.1)
    assert scene.n_receivers == 15
    with pytest.raises(ValueError, match="altitude"):
        presets.heremans2009_seafloor(altitude=-1.0)


def test_the_seafloor_examples_load_as_their_presets():
    from pathlib import Path

    examples = Path(__file__).resolve().parents[1] / "examples"
    dpca = clsas.load_scenario(examples / "heremans2009_seafloor.toml")
    preset = presets.heremans2009_seafloor()
    np.testing.assert_array_equal(dpca.seafloor.extent, preset.seafloor.extent)
    assert (dpca.seafloor.z, dpca.seafloor.seed, dpca.seafloor.sediment) == (-15.0, 5, preset.seafloor.sediment)
    np.testing.assert_array_equal(dpca.targets[0].positions, preset.targets[0].positions)
    mines = clsas.load_scenario(examples / "mine_scene.toml")
    preset = presets.mine_scene(max_facet=0.1)
    assert mines.seafloor.ripple_height == 0.04 and mines.seafloor.ripple_wavelength == 0.5
    for read, made in zip(mines.targets, preset.targets):
        np.testing.assert_array_equal(read.mesh.vertices, made.mesh.vertices)
        assert (read.gain, read.speckle_seed, read.heading) == (made.gain, made.speckle_seed, made.heading)
