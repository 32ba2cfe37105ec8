"""Invariants of the method on random intersecting pairs, and where f32 stops agreeing with f64."""

import numpy as np
import pytest

import taichi_dcd

from conftest import random_pairs, random_rotation


@pytest.fixture(scope="module")
def constrained_pairs():
    taichi_dcd.init(precision="f64", debug=True)
    a, b = random_pairs(6000, seed=7)
    r = taichi_dcd.collide_triangle_pairs(a, b)
    keep = r.side >= 0
    return a[keep], b[keep], r.depth[keep], r.normal[keep], r.side[keep], r.point[keep]


def test_swapping_a_and_b_swaps_side_and_keeps_the_constraint(f64, constrained_pairs):
    a, b, depth, normal, side, point = constrained_pairs
    r = taichi_dcd.collide_triangle_pairs(b, a)
    np.testing.assert_array_equal(r.side, 1 - side)
    np.testing.assert_allclose(r.depth, depth, rtol=1e-12)
    np.testing.assert_allclose(r.normal, normal, atol=1e-12)
    np.testing.assert_allclose(r.point, point, atol=1e-12)


def test_rigid_motion_keeps_depth_and_moves_normal_and_point(f64, constrained_pairs):
    a, b, depth, normal, side, point = constrained_pairs
    rng = np.random.default_rng(11)
    rot = random_rotation(rng)
    shift = rng.uniform(-5, 5, size=3)
    r = taichi_dcd.collide_triangle_pairs(a @ rot.T + shift, b @ rot.T + shift)
    np.testing.assert_array_equal(r.side, side)
    np.testing.assert_allclose(r.depth, depth, rtol=1e-9, atol=1e-13)
    np.testing.assert_allclose(r.normal, normal @ rot.T, atol=1e-12)
    np.testing.assert_allclose(r.point, point @ rot.T + shift, atol=1e-11)


@pytest.mark.parametrize("scale", [1e-4, 1e-2, 1e2, 1e4])
def test_scaling_both_triangles_scales_depth(f64, constrained_pairs, scale):
    a, b, depth, normal, side, point = constrained_pairs
    r = taichi_dcd.collide_triangle_pairs(a * scale, b * scale)
    np.testing.assert_array_equal(r.side, side)
    np.testing.assert_allclose(r.depth, depth * scale, rtol=1e-9)
    np.testing.assert_allclose(r.normal, normal, atol=1e-12)
    np.testing.assert_allclose(r.point, point * scale, rtol=0, atol=1e-12 * scale)


def f32_disagreement(a, b, ref_side, ref_depth, transform, unit):
    """(fraction of pairs whose side differs, 99th percentile of |depth error| / unit) in f32."""
    taichi_dcd.init(precision="f32", debug=True)
    try:
        ta, tb = transform(a), transform(b)
        r = taichi_dcd.collide_triangle_pairs(ta, tb)
    finally:
        taichi_dcd.init(precision="f64", debug=True)
    side_off = np.mean(r.side != ref_side)
    err = np.abs(r.depth.astype(np.float64) - ref_depth * unit) / unit
    return side_off, np.percentile(err, 99)


def test_where_f32_stops_agreeing_with_f64(f64):
    """Measured on unit-cube triangles (edges ~0.5-1), f32 against f64:

    - Pure scaling: f32 keeps the f64 verdicts (same side on > 99.9% of pairs, depth error
      99th percentile < 1e-6 of the triangle size) from size 1e-5 up to 1e7. At size 1e-6
      it breaks (a quarter of the verdicts differ): the squared quantities in the
      tolerance tests (~size^6) fall into f32's subnormal range.
    - Distance from the origin: f32 resolves coordinates to ~6e-8 of their magnitude, so
      the depth error grows linearly with the offset: 99th percentile ~2e-5 of the
      triangle size at offset 100, ~2e-2 at offset 1e5, where ~1% of the verdicts differ.
      f32 is fine for unit triangles within ~100 of the origin and wrong beyond ~1e4.
    """
    a, b = random_pairs(5000, seed=5)
    a, b = a - 0.5, b - 0.5
    ref = taichi_dcd.collide_triangle_pairs(a, b)

    for size in (1e-5, 1.0, 1e7):
        side_off, err = f32_disagreement(a, b, ref.side, ref.depth, lambda x: x * size, size)
        assert side_off < 1e-3 and err < 1e-6, (size, side_off, err)
    side_off, err = f32_disagreement(a, b, ref.side, ref.depth, lambda x: x * 1e-6, 1e-6)
    assert side_off > 0.1, "f32 at size 1e-6 was expected to fail"

    side_off, err = f32_disagreement(a, b, ref.side, ref.depth, lambda x: x + 100.0, 1.0)
    assert side_off < 1e-3 and err < 1e-4, (side_off, err)
    side_off, err = f32_disagreement(a, b, ref.side, ref.depth, lambda x: x + 1e5, 1.0)
    assert side_off > 2e-3 and err > 3e-3, (side_off, err)
