"""Degenerate and touching inputs: no division by zero, no false constraint, clear errors."""

import numpy as np
import pytest

import taichi_dcd

from conftest import random_rotation

# A triangle crossing the plane y = 0 and the triangle it pierces.
PIERCER = np.array([[0.1, -0.2, 0.05], [0.3, 0.6, 0.05], [-0.2, 0.6, 0.05]])
FLOOR = np.array([[-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 0.0, -1.0]])


def collide(a, b):
    return taichi_dcd.collide_triangle_pairs(np.asarray(a, float), np.asarray(b, float))


def assert_no_constraint(r, hit=False):
    assert np.all(np.isfinite(r.depth)) and np.all(np.isfinite(r.normal)) and np.all(np.isfinite(r.point))
    np.testing.assert_array_equal(r.side, -1)
    np.testing.assert_array_equal(r.depth, 0.0)
    np.testing.assert_array_equal(r.normal, 0.0)
    if hit is not None:
        np.testing.assert_array_equal(r.hit, hit)


def test_the_crossing_pair_used_below_is_a_contact(f64):
    r = collide([PIERCER], [FLOOR])
    assert r.hit[0] and r.side[0] == 0 and r.depth[0] == pytest.approx(0.2)


@pytest.mark.parametrize("degenerate", [
    [[0.1, -0.2, 0.05], [0.1, -0.2, 0.05], [0.1, -0.2, 0.05]],   # a point
    [[0.1, -0.2, 0.05], [0.3, 0.6, 0.05], [0.2, 0.2, 0.05]],     # collinear, crossing y = 0
    [[0.1, -0.2, 0.05], [0.3, 0.6, 0.05], [0.3, 0.6, 0.05]],     # repeated vertex
    [[0.0, -0.5, 0.0], [1e-17, 0.5, 0.0], [0.0, 0.5, 1e-17]],    # sliver far below f64 resolution
])
def test_zero_area_triangles_give_no_constraint(f64, degenerate):
    assert_no_constraint(collide([degenerate, FLOOR], [FLOOR, degenerate]))


def test_identical_triangles_are_not_a_contact(f64):
    rng = np.random.default_rng(2)
    tris = rng.random((200, 3, 3))
    assert_no_constraint(collide(tris, tris.copy()))


def test_coplanar_overlapping_triangles_are_touching(f64):
    """Overlapping triangles in one plane, axis-aligned and in 100 random orientations."""
    a = FLOOR
    b = np.array([[-0.2, 0.0, 0.3], [0.9, 0.0, 0.2], [0.1, 0.0, -0.6]])
    rng = np.random.default_rng(3)
    rots = [np.eye(3)] + [random_rotation(rng) for _ in range(100)]
    shifts = [np.zeros(3)] + [rng.uniform(-3, 3, 3) for _ in range(100)]
    aa = np.array([a @ r.T + s for r, s in zip(rots, shifts)])
    bb = np.array([b @ r.T + s for r, s in zip(rots, shifts)])
    assert_no_constraint(collide(aa, bb))


@pytest.mark.parametrize("gap", [0.0, 1e-12, -1e-12])
def test_parallel_planes_give_no_contact(f64, gap):
    b = np.array([[-0.2, gap, 0.3], [0.9, gap, 0.2], [0.1, gap, -0.6]])
    assert_no_constraint(collide([FLOOR, b], [b, FLOOR]))


def test_shared_vertex_is_touching(f64):
    """A shares its first vertex with B and otherwise stays above B's plane; in 100 random
    frames the shared vertex's distance is rounding noise, which must read as touching."""
    a = np.array([[0.0, 0.0, -1.0], [0.5, 0.7, 0.2], [-0.4, 0.5, 0.3]])
    rng = np.random.default_rng(4)
    frames = [(np.eye(3), np.zeros(3))] + [(random_rotation(rng), rng.uniform(-3, 3, 3)) for _ in range(100)]
    aa = np.array([a @ r.T + s for r, s in frames])
    bb = np.array([FLOOR @ r.T + s for r, s in frames])
    assert_no_constraint(collide(aa, bb))
    assert_no_constraint(collide(bb, aa))


def test_shared_edge_is_touching(f64):
    """A hinge: A shares B's edge (1,0,1)-(0,0,-1) and folds up out of B's plane."""
    a = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 1.0], [1.2, 0.8, -0.5]])
    rng = np.random.default_rng(5)
    frames = [(np.eye(3), np.zeros(3))] + [(random_rotation(rng), rng.uniform(-3, 3, 3)) for _ in range(100)]
    aa = np.array([a @ r.T + s for r, s in frames])
    bb = np.array([FLOOR @ r.T + s for r, s in frames])
    assert_no_constraint(collide(aa, bb))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("where", ["a", "b"])
def test_non_finite_input_names_the_first_bad_pair(f64, bad, where):
    a = np.repeat(PIERCER[None], 6, axis=0)
    b = np.repeat(FLOOR[None], 6, axis=0)
    (a if where == "a" else b)[3, 1, 2] = bad
    (a if where == "a" else b)[5, 0, 0] = bad
    with pytest.raises(ValueError, match=rf"^pair 3: triangle {where} has a NaN or infinite coordinate$"):
        collide(a, b)


def test_bad_shapes_are_rejected(f64):
    with pytest.raises(ValueError, match=r"a must have shape \(n, 3, 3\)"):
        collide(np.zeros((4, 3)), np.zeros((4, 3, 3)))
    with pytest.raises(ValueError, match="same number of triangles"):
        collide(np.zeros((4, 3, 3)), np.zeros((5, 3, 3)))
    with pytest.raises(ValueError, match="numeric"):
        taichi_dcd.collide_triangle_pairs(np.full((1, 3, 3), "x"), np.zeros((1, 3, 3)))


def test_empty_batch(f64):
    r = collide(np.zeros((0, 3, 3)), np.zeros((0, 3, 3)))
    assert len(r) == 0 and r.hit.shape == (0,) and r.normal.shape == (0, 3) and r.point.shape == (0, 3)
    assert r.hit.dtype == bool and r.side.dtype == np.int8


def test_f32_works_and_agrees_on_the_crossing_pair(f32):
    r = collide([PIERCER], [FLOOR])
    assert r.depth.dtype == np.float32
    assert r.side[0] == 0 and r.depth[0] == pytest.approx(0.2, rel=1e-6)
