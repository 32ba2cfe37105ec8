"""The grid pipeline's two-sided (cloth) pairs against a plain NumPy reference: each cloth
triangle turned to face the other triangle of its pair, two cloth triangles moved together by
their gap, then the public narrow phase on every pair (collision/two_sided.py)."""

import numpy as np
import pytest
import taichi as ti

import taichi_dcd
from taichi_dcd.collision.pipeline import CollisionPipeline


def facing(tri_a, tri_b, prev_a, prev_b, two_a, two_b, gap):
    """NumPy reference of two_sided_flips + flipped + moved_together on (k, 3, 3) triangles."""
    def normal(t):
        return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])

    both = two_a & two_b
    toward_b = prev_b.mean(axis=1) - prev_a.mean(axis=1)
    face_away = np.einsum("ij,ij->i", normal(tri_a), normal(tri_b)) > 0
    flip_a = np.where(both, np.einsum("ij,ij->i", normal(prev_a), toward_b) < 0, two_a & face_away)
    flip_b = np.where(both, np.einsum("ij,ij->i", normal(prev_b), toward_b) > 0, two_b & face_away)
    a, b = tri_a.copy(), tri_b.copy()
    a[flip_a] = a[flip_a][:, [0, 2, 1]]
    b[flip_b] = b[flip_b][:, [0, 2, 1]]
    for t in (a, b):
        n = normal(t)
        t += np.where(both, 0.5 * gap, 0.0)[:, None, None] * (n / np.linalg.norm(n, axis=1)[:, None])[:, None, :]
    return a, b


@pytest.mark.parametrize("seed", range(3))
def test_the_grids_cloth_pairs_match_a_numpy_reference(f64, seed):
    """Two crumpled sheets (cloth, 2 mm gap, one of them colliding with itself) and a box: every
    intersecting pair and its depth and normal, as the reference finds them on all pairs."""
    rng = np.random.default_rng(seed)
    n = 6
    t = np.linspace(-0.5, 0.5, n + 1)
    gx, gz = np.meshgrid(t, t, indexing="ij")
    grid_v = np.column_stack([gx.ravel(), np.zeros(gx.size), gz.ravel()])
    cells = [(i * (n + 1) + j, (i + 1) * (n + 1) + j) for i in range(n) for j in range(n)]
    sheet_f = np.array([f for a, b in cells for f in ((a, a + 1, b + 1), (a, b + 1, b))])
    sheets = [grid_v + [0.0, 0.0, 0.0], grid_v + [0.05, 0.0, 0.02]]
    for s in sheets:
        s[:, 1] += rng.normal(0.0, 0.04, len(s))
    box_v = np.array([[x, y, z] for x in (-0.2, 0.2) for y in (-0.3, 0.05) for z in (-0.2, 0.2)])
    box_f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    x = np.concatenate([sheets[0], sheets[1], box_v])
    nv = len(grid_v)
    faces = np.concatenate([sheet_f, sheet_f + nv, box_f + 2 * nv]).astype(np.int32)
    body = np.repeat([0, 1, 2], [len(sheet_f), len(sheet_f), len(box_f)]).astype(np.int32)
    gap = 0.002
    tri_gap = np.where(body < 2, gap, 0.0)
    prev = x + rng.normal(0.0, 0.005, x.shape)
    self_pairs = np.array([True, False, False])

    pipe = CollisionPipeline(faces, body, tri_static=body == 2, body_self=self_pairs, tri_sheet_gap=tri_gap,
                             cell_size=0.1, margin=gap)
    px, pp = (ti.ndarray(ti.types.vector(3, ti.f64), shape=len(x)) for _ in range(2))
    px.from_numpy(x)
    pp.from_numpy(prev)
    pipe.run(px, particle_x_prev=pp)
    c = pipe.contacts.to_numpy()
    got = {(int(a), int(b)): (d, nrm) for (a, b), d, nrm in zip(c.pair, c.depth, c.normal)}

    # Every pair of different bodies, and sheet 0's own pairs that share no vertex.
    i, j = np.triu_indices(len(faces), 1)
    keep = (body[i] != body[j]) | ((body[i] == 0) & (body[j] == 0))
    i, j = i[keep], j[keep]
    keep = ~(faces[i][:, :, None] == faces[j][:, None, :]).any(axis=(1, 2))
    i, j = i[keep], j[keep]
    two = body < 2
    a, b = facing(x[faces[i]], x[faces[j]], prev[faces[i]], prev[faces[j]], two[i], two[j], gap)
    ref = taichi_dcd.collide_triangle_pairs(a, b)
    expected = {(int(p), int(q)): (d, nrm) for p, q, h, d, nrm in zip(i, j, ref.hit, ref.depth, ref.normal) if h}
    assert len(expected) > 20
    assert set(got) == set(expected)
    for pair, (d, nrm) in expected.items():
        assert got[pair][0] == pytest.approx(d, abs=1e-12)
        np.testing.assert_allclose(got[pair][1], nrm, atol=1e-12)
