"""Hull occlusion: Embree against the Moller-Trumbore reference, shadow geometry, effect on the echo."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import clsas
from clsas.scene.hulls import box, sphere
from clsas.scene.scenario import (
    Array,
    Medium,
    Platform,
    PulseSchedule,
    Scenario,
    Waveform,
)
from clsas.scene.targets import MeshTarget
from clsas.synthesis.occlusion import (
    PathWeights,
    RayCaster,
    occluded_reference,
    visibility,
)


def random_soup(rng, n):
    """n random triangles in a 2 m cube (not a closed mesh: a hard case for ray casting)."""
    centres = rng.uniform(-1, 1, (n, 1, 3))
    return trimesh.Trimesh(*_soup_arrays(centres + rng.normal(scale=0.3, size=(n, 3, 3))), process=False)


def _soup_arrays(tris):
    return tris.reshape(-1, 3), np.arange(tris.shape[0] * 3).reshape(-1, 3)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_embree_equals_moller_trumbore(seed):
    rng = np.random.default_rng(seed)
    mesh = random_soup(rng, 60)
    k = 4000
    origins = rng.uniform(-2, 2, (k, 3))
    d = rng.normal(size=(k, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tfar = rng.uniform(0.1, 4.0, k)
    embree = RayCaster(mesh, "embree").occluded(origins, d, tfar)
    tris = np.asarray(mesh.triangles)
    inner = occluded_reference(tris, origins, d, tfar, margin=-1e-6)
    outer = occluded_reference(tris, origins, d, tfar, margin=1e-6)
    grazing = inner != outer  # within 1e-6 of an edge or of the segment's ends
    assert 0.05 < inner.mean() < 0.95  # the test sees both outcomes
    assert grazing.mean() < 0.01
    np.testing.assert_array_equal(embree[~grazing], inner[~grazing])
    np.testing.assert_array_equal(RayCaster(mesh, "reference").occluded(origins, d, tfar)[~grazing], inner[~grazing])


def seen_from(caster, target, point):
    """visibility of every facet of ``target`` towards ``point`` (rays from 1e-5 m off the facets)."""
    normals = target.mesh.face_normals
    start = target.mesh.triangles_center + 1e-5 * normals
    d = (np.asarray(point, dtype=float) - start).T[:, None, :].astype(np.float32)
    facing = np.einsum("ij,ij->i", normals, d[:, 0].T)[None] > 0
    return visibility(caster, start, d, facing)[0]


def test_sphere_from_far_is_half_lit():
    target = MeshTarget(sphere(1.0, 3))
    lit = seen_from(RayCaster(target.mesh), target, [800.0, 300.0, -200.0])
    assert abs(lit.mean() - 0.5) < 0.02
    np.testing.assert_array_equal(lit, seen_from(RayCaster(target.mesh, "reference"), target, [800.0, 300.0, -200.0]))


def test_box_behind_larger_box_is_shadowed():
    wall, small = box((1.0, 10.0, 10.0)), box((1.0, 1.0, 1.0))
    small.apply_translation([-5.0, 0.0, 0.0])
    target = MeshTarget(trimesh.util.concatenate([wall, small]))
    lit = seen_from(RayCaster(target.mesh), target, [200.0, 0.0, 0.0])
    assert not lit[12:].any()  # the small box: all dark
    assert lit[:12].sum() == 2  # the wall's face towards the source (two triangles)


def shadow_scene(n_pulses=41):
    """A wall (x = 98 m, |y| < 0.5 m) in front of a cube 4 m behind it, both one rigid target moving
    along +y at 0.5 m/s, seen from a platform passing at 2 m/s along y."""
    wall, cube = box((0.2, 1.0, 4.0)), box((0.5, 0.5, 0.5))
    cube.apply_translation([4.0, 0.0, 0.0])
    target = MeshTarget(trimesh.util.concatenate([wall, cube]), position=(98.0, 0.0, 0.0), velocity=(0.0, 0.5, 0.0))
    sc = Scenario(Medium(1500.0), Waveform(f0=100e3, bandwidth=10e3, duration=2e-3, fs=12.5e3),
                  Platform(speed=2.0), Array(rx_offsets=[[0.0, 0.0, 0.0]]), PulseSchedule(prf=2.0, n_pulses=n_pulses),
                  targets=(target,))
    return sc, target


@pytest.mark.parametrize("tolerance", [0.0, 5e-4, 0.5])  # every ray cast; the default; reuse over whole blocks
def test_moving_facet_crosses_into_shadow_at_the_predicted_pulse(tolerance):
    sc, target = shadow_scene()
    weights = PathWeights(sc, stop_and_go=True, reuse_tolerance=tolerance)(slice(None))[0]  # (pulses, facets)
    normals = target.mesh.face_normals
    front = np.flatnonzero((normals[:, 0] < -0.9) & (target.mesh.triangles_center[:, 0] > 3.0))  # cube's -x face
    assert front.size == 2
    eta = sc.eta
    tx = sc.tx_position(eta)
    centre = target.facets_world()[0][front[0]] + np.outer(eta, target.velocity)
    wall_x = 98.0 + 0.1  # the wall's back face
    s = (centre[:, 0] - wall_x) / (centre[:, 0] - tx[:, 0])
    y_hit = centre[:, 1] + s * (tx[:, 1] - centre[:, 1]) - 0.5 * eta  # in the moving wall's frame
    predicted = np.abs(y_hit) < 0.5
    margin = np.abs(np.abs(y_hit) - 0.5) > 0.02  # pulses not grazing the wall's edge
    assert predicted[margin].any() and (~predicted[margin]).any()  # the facet does cross
    observed_dark = weights[:, front[0]] == 0
    np.testing.assert_array_equal(observed_dark[margin], predicted[margin])


def test_hidden_inner_body_adds_nothing_to_the_echo():
    shell, inner = box((4.0, 4.0, 4.0)), box((1.0, 1.0, 1.0))
    sc, _ = shadow_scene(6)
    shell_only = sc.replace(targets=(MeshTarget(shell, position=(98.0, 0.0, 0.0)),))
    both = sc.replace(targets=(MeshTarget(trimesh.util.concatenate([shell, inner]), position=(98.0, 0.0, 0.0)),))
    w = PathWeights(both)(slice(None))
    assert not w[:, :, 12:].any()  # the inner box: all paths dark
    a = clsas.simulate(both, backend="numpy", progress=False).data
    b = clsas.simulate(shell_only, backend="numpy", progress=False).data
    np.testing.assert_allclose(a, b, atol=1e-6)


def test_occlusion_changes_the_echo(opencl_device):
    sc, target = shadow_scene(8)
    with_hull = clsas.simulate(sc, backend="opencl", progress=False)
    without = clsas.simulate(sc, backend="opencl", progress=False, hull_occlusion=False)
    w_on = PathWeights(sc)(slice(None))
    w_off = PathWeights(sc, hull_occlusion=False)(slice(None))
    assert (w_on > 0).sum() < (w_off > 0).sum()  # fewer contributing facets
    assert np.linalg.norm(with_hull.data) < np.linalg.norm(without.data)
    assert with_hull.provenance["hull_occlusion"] and not without.provenance["hull_occlusion"]


def test_bad_meshes():
    with pytest.raises(ValueError, match="empty"):
        MeshTarget(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=int)))
    open_mesh = box()
    open_mesh.update_faces(np.arange(10))  # two faces removed: not watertight
    with pytest.warns(UserWarning, match="not watertight"):
        MeshTarget(open_mesh)
    degenerate = trimesh.Trimesh(np.vstack([box().vertices, [[0, 0, 0]]]),
                                 np.vstack([box().faces, [[0, 0, 0]]]), process=False)
    with pytest.warns(UserWarning, match="degenerate"):
        cleaned = MeshTarget(degenerate)
    assert cleaned.n_facets == 12
    with pytest.raises(ValueError, match="law"):
        MeshTarget(box(), law="phong")
    with pytest.raises(ValueError, match="method"):
        RayCaster(box(), "optix")


def test_scan_image_projects_the_lit_face():
    from clsas.synthesis.occlusion import scan_image

    sc, _ = shadow_scene(4)
    sc = sc.replace(targets=(MeshTarget(box((1.0, 4.0, 4.0)), position=(100.0, 0.0, 0.0)),))
    img = scan_image(sc, r=np.arange(95.0, 105.0, 0.1), y=np.arange(-5.0, 5.0, 0.1))
    assert img.dims == ("y", "r")
    values = img.data.real
    lit_r = img.axes["r"][np.nonzero(values.sum(axis=0))[0]]
    assert lit_r.min() >= 99.4 and lit_r.max() <= 99.7  # only the face at x = 99.5 m
    assert 15.9 < values.sum() <= 16.0  # its area (16 m^2) x the Lambertian law (~1 at broadside)
    with pytest.raises(ValueError, match="mesh"):
        scan_image(shadow_scene(2)[0].replace(targets=(clsas.PointTargets([[100.0, 0, 0]]),)), np.arange(3.0),
                   np.arange(3.0))


def pole_scene(n_pulses=64):
    """A thin pole (6 cm square, 2 m tall) 2 m in front of a small wall (0.4 m x 1 m, facets of
    5 cm), 100 m from a platform passing at 2 m/s, 20 pulses/s: from a facet of the wall the pole
    subtends ~0.03 rad and the platform turns by ~1e-3 rad per pulse, so the pole's shadow
    crosses some facets for ~30 pulses, starting and ending inside 64 pulses."""
    wall, pole = box((0.2, 0.4, 1.0)), box((0.06, 0.06, 2.0))
    pole.apply_translation([-2.0, 0.0, 0.0])
    target = MeshTarget(trimesh.util.concatenate([wall, pole]), position=(100.0, 0.0, 0.0), velocity=(0.0, 0.3, 0.0),
                        max_facet=0.05)
    sc = Scenario(Medium(1500.0), Waveform(f0=100e3, bandwidth=10e3, duration=2e-3, fs=12.5e3),
                  Platform(speed=2.0), Array(rx_offsets=[[0.0, 0.0, 0.0]]), PulseSchedule(prf=20.0, n_pulses=n_pulses),
                  targets=(target,))
    return sc, target


def test_reuse_within_tolerance_equals_full_cast_and_tolerance_matters():
    sc, _ = pole_scene()
    full = PathWeights(sc, reuse_tolerance=0.0, pulses_per_block=64)
    w_full = full(slice(None))
    caster = full.parts[0][3]
    assert caster.rays_cast == caster.queries  # every answered path cast
    lit = w_full[0] > 0  # (pulses, facets)
    passing = lit[0] & lit[-1] & ~lit.all(axis=0)  # lit at both ends, shadowed in between
    assert passing.sum() >= 3
    fine = PathWeights(sc, reuse_tolerance=0.01, pulses_per_block=64)  # under the pole's ~0.03 rad
    np.testing.assert_array_equal(fine(slice(None)), w_full)
    assert fine.parts[0][3].queries == caster.queries
    assert fine.parts[0][3].rays_cast < caster.rays_cast / 3
    coarse = PathWeights(sc, reuse_tolerance=0.1, pulses_per_block=64)  # wider than the block's sweep
    w_coarse = coarse(slice(None))
    assert (w_coarse[0] > 0)[:, passing].all()  # the passing shadow is missed: lit throughout
    assert coarse.parts[0][3].rays_cast < fine.parts[0][3].rays_cast


def test_reuse_equals_full_cast_on_the_moving_submarine():
    from clsas.scene import presets

    sc = presets.kiang2022_case(5, n_pulses=48, sections=32, stations=40)  # a moving, turning-free hull
    reused, full = PathWeights(sc, pulses_per_block=48), PathWeights(sc, reuse_tolerance=0.0)
    np.testing.assert_array_equal(reused(slice(None)), full(slice(None)))
    assert reused.parts[0][3].queries == full.parts[0][3].queries
    assert reused.parts[0][3].rays_cast < full.parts[0][3].queries / 4


def test_reuse_tolerance_is_checked():
    sc, _ = pole_scene(4)
    with pytest.raises(ValueError, match="reuse_tolerance"):
        PathWeights(sc, reuse_tolerance=-1e-3)
    with pytest.raises(ValueError, match="pulses_per_block"):
        PathWeights(sc, pulses_per_block=0)


def test_simulate_passes_the_reuse_tolerance(opencl_device):
    """simulate(reuse_tolerance=) reaches the path weights: casting every ray and the default
    reuse give the same echo on the pole scene, and the tolerance is recorded and checked."""
    sc, _ = pole_scene()
    exact = clsas.simulate(sc, backend="opencl", progress=False, reuse_tolerance=0.0)
    reused = clsas.simulate(sc, backend="opencl", progress=False)
    np.testing.assert_array_equal(reused.data, exact.data)
    assert exact.provenance["reuse_tolerance"] == 0.0 and reused.provenance["reuse_tolerance"] == 5e-4
    with pytest.raises(ValueError, match="reuse_tolerance"):
        clsas.simulate(sc, backend="opencl", progress=False, reuse_tolerance=-1.0)
