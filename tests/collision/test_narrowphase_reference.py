"""The Taichi kernel against the plain per-pair NumPy reference on seeded random pairs."""

import numpy as np

import taichi_dcd
from taichi_dcd.collision.reference import collide_triangle_pairs_reference

from conftest import random_pairs


def test_kernel_matches_numpy_reference_on_20000_random_pairs(f64):
    a, b = random_pairs(20_000, seed=20250)
    ref = collide_triangle_pairs_reference(a, b)
    got = taichi_dcd.collide_triangle_pairs(a, b)

    assert 0.25 < ref["hit"].mean() < 0.35, "the sample should be about 30% intersecting"
    np.testing.assert_array_equal(got.hit, ref["hit"])
    np.testing.assert_array_equal(got.side, ref["side"])
    np.testing.assert_allclose(got.normal, ref["normal"], rtol=0, atol=1e-12)
    constrained = ref["side"] >= 0
    assert constrained.sum() > 5000
    np.testing.assert_allclose(got.depth[constrained], ref["depth"][constrained], rtol=1e-9, atol=0)
    assert np.all(got.depth[~constrained] == 0.0)

    # The point lies on the moved triangle, at the reported depth below the other's plane
    # (where several candidates are equally deep, either is right).
    idx = np.flatnonzero(constrained)
    moved = np.where((got.side[idx] == 0)[:, None, None], a[idx], b[idx])
    other = np.where((got.side[idx] == 0)[:, None, None], b[idx], a[idx])
    p = got.point[idx]
    e1, e2 = moved[:, 1] - moved[:, 0], moved[:, 2] - moved[:, 0]
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.abs(np.einsum("ij,ij->i", p - moved[:, 0], n)).max() < 1e-12, "point off the moved triangle's plane"
    # Barycentric coordinates of p in the moved triangle.
    gram = np.stack([np.stack([np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e1, e2)], -1),
                     np.stack([np.einsum("ij,ij->i", e2, e1), np.einsum("ij,ij->i", e2, e2)], -1)], -2)
    rhs = np.stack([np.einsum("ij,ij->i", p - moved[:, 0], e1), np.einsum("ij,ij->i", p - moved[:, 0], e2)], -1)
    uv = np.linalg.solve(gram, rhs[..., None])[..., 0]
    assert uv.min() > -1e-9 and (uv.sum(axis=1)).max() < 1 + 1e-9, "point outside the moved triangle"
    n_other = np.cross(other[:, 1] - other[:, 0], other[:, 2] - other[:, 0])
    n_other /= np.linalg.norm(n_other, axis=1, keepdims=True)
    np.testing.assert_allclose(got.normal[idx], n_other, atol=1e-12)
    depth_at_point = -np.einsum("ij,ij->i", p - other[:, 0], n_other)
    np.testing.assert_allclose(depth_at_point, got.depth[idx], rtol=1e-9, atol=1e-12)
