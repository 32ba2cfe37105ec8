"""The self-intersection measure (NumPy only) against brute force and against the narrow phase."""

import numpy as np
import pytest
import trimesh

from taichi_dcd.collision.narrowphase import collide_triangle_pairs
from taichi_dcd.measure.self_intersection import crossing_depths, crossing_pairs, self_penetration, triangles_cross
from taichi_dcd.scene.shapes import coil


def triangle_soup(seed: int, n: int, spread: float = 0.15):
    rng = np.random.default_rng(seed)
    corners = rng.random((n, 1, 3)) + spread * rng.standard_normal((n, 3, 3))
    return corners.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_grid_finds_the_same_crossing_pairs_as_testing_every_pair(seed):
    vertices, faces = triangle_soup(seed, 400)
    i, j = np.triu_indices(len(faces), 1)
    every = np.stack([i, j], axis=1)
    expected = every[triangles_cross(vertices[faces[i]], vertices[faces[j]])]
    found = crossing_pairs(vertices, faces)
    assert len(expected) > 100
    np.testing.assert_array_equal(found, expected)


def test_crossing_agrees_with_the_narrow_phase_on_random_pairs(f64):
    rng = np.random.default_rng(7)
    centre = rng.random((3000, 1, 3))
    a = centre + 0.3 * rng.standard_normal((3000, 3, 3))
    b = centre + 0.3 * rng.standard_normal((3000, 3, 3))
    narrow = collide_triangle_pairs(a, b).hit.astype(bool)
    measure = triangles_cross(a, b)
    assert 500 < narrow.sum() < 2500
    np.testing.assert_array_equal(measure, narrow)


def test_two_overlapping_boxes_in_one_mesh_cross_and_a_box_does_not():
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    assert len(crossing_pairs(box.vertices, box.faces)) == 0
    other = box.copy()
    other.apply_translation((0.5, 0.3, 0.2))
    both = trimesh.util.concatenate([box, other])
    pairs = crossing_pairs(both.vertices, both.faces)
    # Every crossing is between the two boxes (faces 0-11 and 12-23), none within one.
    assert len(pairs) > 0 and (pairs[:, 0] < 12).all() and (pairs[:, 1] >= 12).all()


def test_a_subdivided_rotated_face_far_from_the_origin_does_not_cross_itself():
    # Coplanar neighbours that touch at a point: rounding must not make them cross.
    mesh = trimesh.creation.box((1.0, 0.3, 2.0)).subdivide().subdivide()
    mesh.apply_transform(trimesh.transformations.rotation_matrix(0.7, (0.3, 1.0, 0.2)))
    mesh.apply_translation((1e6, -3e5, 2e6))
    assert len(crossing_pairs(mesh.vertices, mesh.faces)) == 0


def test_crossing_depth_is_the_narrow_phases_depth_on_random_crossing_pairs(f64):
    # Polygon clipping in NumPy against the kernels' candidate points: two ways to the least
    # move along the other's normal that ends a crossing (Eq. 6's C).
    rng = np.random.default_rng(11)
    a, b = rng.standard_normal((4000, 3, 3)), rng.standard_normal((4000, 3, 3))
    crossing = triangles_cross(a, b)
    assert crossing.sum() > 500
    narrow = collide_triangle_pairs(a[crossing], b[crossing])
    np.testing.assert_allclose(crossing_depths(a[crossing], b[crossing]), narrow.depth, rtol=0, atol=1e-12)


def test_a_triangle_pushed_through_a_larger_one_is_as_deep_as_its_tip():
    big = np.array([[[-1.0, 0.0, -1.0], [0.0, 0.0, 2.0], [1.0, 0.0, -1.0]]])       # in y = 0, normal +y
    for tip in (0.01, 0.2):
        small = np.array([[[-0.1, 0.5, 0.0], [0.1, 0.5, 0.0], [0.0, -tip, 0.0]]])   # tip below y = 0
        assert triangles_cross(small, big)[0]
        assert crossing_depths(small, big)[0] == pytest.approx(tip, rel=1e-12)


def test_a_coil_whose_pitch_is_below_its_tube_diameter_crosses_itself():
    # Apart: no crossing pair. Turns closer than the tube's diameter: the tube passes through
    # the turn below it by (diameter - pitch) at most.
    apart = coil(tube_radius=0.08, pitch=0.2)
    assert apart.is_watertight and apart.volume > 0
    assert self_penetration(apart.vertices, apart.faces) == (0, 0.0)
    pressed = coil(tube_radius=0.08, pitch=0.15)
    count, deepest = self_penetration(pressed.vertices, pressed.faces)
    assert count > 0 and 0.0 < deepest <= 0.16 - 0.15 + 1e-9
