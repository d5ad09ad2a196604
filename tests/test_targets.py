"""Targets: point scatterers and meshes (loading, pose, subdivision, reflectivity), the submarine."""

from __future__ import annotations

import os

import numpy as np
import pytest

import clsas
from clsas.scene import presets
from clsas.scene.hulls import box, cylinder, sphere, submarine
from clsas.scene.targets import MeshTarget, PointTargets, pose_rotation, scatterers_of


def test_mesh_from_file_and_facets(tmp_path):
    path = tmp_path / "box.stl"
    box((2.0, 1.0, 0.5)).export(path)
    target = MeshTarget(str(path), position=(10.0, 0.0, -5.0))
    assert target.n_facets == 12
    scat = target.scatterers()
    assert scat.count == 12
    np.testing.assert_allclose(np.sum(scat.refl.real), 2 * (2 * 1 + 2 * 0.5 + 1 * 0.5))  # total area
    np.testing.assert_allclose(scat.p0.mean(axis=0), [10.0, 0.0, -5.0], atol=1e-12)
    with pytest.raises(FileNotFoundError, match="missing.stl: no such file"):
        MeshTarget(str(tmp_path / "missing.stl"))
    os.mkfifo(tmp_path / "pipe.stl")  # reading a FIFO would block: refused without opening it
    with pytest.raises(FileNotFoundError, match="pipe.stl: not a regular file"):
        MeshTarget(tmp_path / "pipe.stl")
    (tmp_path / "junk.format").write_bytes(b"\x00" * 10)
    with pytest.raises(ValueError, match="cannot load .*junk.format"):
        MeshTarget(tmp_path / "junk.format")
    with pytest.raises(TypeError, match="MeshTarget.mesh: must be a trimesh.Trimesh or the path"):
        MeshTarget(None)


def test_pose_rotation_conventions():
    # heading turns the bow (+x_b) towards +y; pitch raises it; roll turns the sail (+z_b) to starboard (-y)
    np.testing.assert_allclose(pose_rotation(np.pi / 2, 0, 0) @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(pose_rotation(0, 0.3, 0) @ [1, 0, 0], [np.cos(0.3), 0, np.sin(0.3)], atol=1e-12)
    np.testing.assert_allclose(pose_rotation(0, 0, 0.2) @ [0, 0, 1], [0, -np.sin(0.2), np.cos(0.2)], atol=1e-12)
    r = pose_rotation(0.4, -0.2, 0.7)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    target = MeshTarget(box(), position=(5, 6, 7), heading=0.4, pitch=-0.2, roll=0.7, velocity=(1, 2, 3))
    world = target.facets_world()[0]
    np.testing.assert_allclose(target.to_body(world + 2.0 * np.array([1, 2, 3]), 2.0), target.mesh.triangles_center,
                               atol=1e-12)


def test_subdivision_bounds_facet_size():
    target = MeshTarget(sphere(2.0, 1), max_facet=0.3)
    edges = target.mesh.edges_unique_length
    assert edges.max() <= 0.3 + 1e-9
    assert target.n_facets > 80 * 4


def test_speckle_is_seeded_and_keeps_magnitudes():
    a = MeshTarget(box(), speckle_seed=3).scatterers().refl
    b = MeshTarget(box(), speckle_seed=3).scatterers().refl
    c = MeshTarget(box(), speckle_seed=4).scatterers().refl
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    np.testing.assert_allclose(np.abs(a), box().area_faces)


def test_angular_laws():
    n = np.array([[0.0, 0.0, 1.0]])
    up = np.array([[0.0, 0.0, 1.0]])
    slant = np.array([[np.sin(0.5), 0.0, np.cos(0.5)]])
    lam = MeshTarget(box())
    spec = MeshTarget(box(), law="specular", exponent=20)
    np.testing.assert_allclose(lam.angular_gain(n, up, up), 1.0)
    np.testing.assert_allclose(lam.angular_gain(n, slant, slant), np.cos(0.5))
    np.testing.assert_allclose(spec.angular_gain(n, slant, slant), np.cos(0.5) ** 20)
    np.testing.assert_allclose(lam.angular_gain(n, -up, -up), 0.0)  # from behind: dark


def test_submarine_shape():
    sub = submarine()
    assert sub.is_watertight
    extent = sub.bounds[1] - sub.bounds[0]
    assert abs(sub.bounds[1, 0] - 62.1 / 2) < 1e-9  # bow at +L/2
    assert 62.1 < extent[0] < 62.1 * 1.03  # the propeller disc sticks out a little
    body = sub.vertices[(np.abs(sub.vertices[:, 0]) < 20)]  # away from sail planes
    assert abs(np.max(np.hypot(body[:, 1], np.minimum(body[:, 2], 0))) - 4.2) < 0.05  # beam 8.4 m
    assert sub.bounds[1, 2] > 4.2 + 0.4 * 8.4  # the sail rises above the hull
    small, large = submarine(sections=24, stations=30), submarine(sections=96, stations=120)
    assert len(small.faces) < len(sub.faces) < len(large.faces)


def test_simple_shapes_are_closed():
    for mesh in (sphere(), cylinder(), box()):
        assert mesh.is_watertight and mesh.volume > 0


def test_points_and_meshes_mix_in_one_scene(opencl_device):
    sc = presets.kiang2022(n_pulses=4)
    mesh = MeshTarget(sphere(2.0, 2), position=(1989.0, 10.0, -350.0))
    points = PointTargets([[1989.0, -10.0, -350.0]])
    scene = sc.replace(targets=(points, mesh))
    assert scatterers_of(scene.targets).count == 1 + mesh.n_facets
    echo = clsas.simulate(scene, backend="opencl", progress=False)
    alone = clsas.simulate(sc.replace(targets=(points,)), backend="opencl", progress=False)
    assert np.linalg.norm(echo.data) > np.linalg.norm(alone.data)
