"""find_contacts equals the narrow phase run on every pair of triangles of different bodies."""

import numpy as np
import pytest
import taichi as ti
import trimesh

import taichi_dcd
from taichi_dcd.collision.pipeline import CollisionPipeline


def brute_contacts(meshes) -> dict:
    """{(body_a, tri_a, body_b, tri_b): (depth, normal, side, point)} for every hit, all pairs tested."""
    out = {}
    for ba in range(len(meshes)):
        for bb in range(ba + 1, len(meshes)):
            ta = meshes[ba][0][meshes[ba][1]]
            tb = meshes[bb][0][meshes[bb][1]]
            ia, ib = np.meshgrid(np.arange(len(ta)), np.arange(len(tb)), indexing="ij")
            ia, ib = ia.ravel(), ib.ravel()
            r = taichi_dcd.collide_triangle_pairs(ta[ia], tb[ib])
            for k in np.flatnonzero(r.hit):
                out[(ba, int(ia[k]), bb, int(ib[k]))] = (r.depth[k], r.normal[k], r.side[k], r.point[k])
    return out


def assert_same_as_brute(result, meshes):
    expected = brute_contacts(meshes)
    keys = list(zip(result.body_a.tolist(), result.tri_a.tolist(), result.body_b.tolist(), result.tri_b.tolist()))
    assert keys == sorted(keys), "rows are not sorted"
    assert set(keys) == set(expected), (
        f"missing {sorted(set(expected) - set(keys))[:5]}, extra {sorted(set(keys) - set(expected))[:5]}")
    assert len(keys) == len(set(keys))
    assert result.hit.all()
    assert (result.body_a < result.body_b).all()
    for k, key in enumerate(keys):
        depth, normal, side, point = expected[key]
        assert result.depth[k] == depth and result.side[k] == side
        np.testing.assert_array_equal(result.normal[k], normal)
        np.testing.assert_array_equal(result.point[k], point)
    return expected


def random_meshes(seed: int, n_bodies: int, tris: int = 8):
    rng = np.random.default_rng(seed)
    meshes = []
    for _ in range(n_bodies):
        centre = rng.uniform(-0.2, 0.2, 3)
        v = centre + 0.4 * rng.uniform(-1, 1, (3 * tris, 3))
        meshes.append((v, np.arange(3 * tris).reshape(tris, 3)))
    return meshes


@pytest.mark.parametrize("seed", range(4))
def test_find_contacts_equals_brute_force_on_random_soups(f64, seed):
    meshes = random_meshes(seed, n_bodies=3 + 4 * seed)
    expected = assert_same_as_brute(taichi_dcd.find_contacts(meshes), meshes)
    assert len(expected) > 5


def test_find_contacts_on_overlapping_tori(f64):
    a = trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12)
    b = a.copy()
    b.apply_translation([0.3, 0.0, 0.0])
    c = a.copy()
    c.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    c.apply_translation([1.5, 0.0, 0.0])  # its tube crosses a's tube, 0.2 deep
    meshes = [(m.vertices, m.faces) for m in (a, b, c)]
    expected = assert_same_as_brute(taichi_dcd.find_contacts(meshes), meshes)
    assert {(k[0], k[2]) for k in expected} == {(0, 1), (0, 2)}  # b and c stay 0.1 apart


def test_find_contacts_f32(f32):
    meshes = [(v.astype(np.float32), f) for v, f in random_meshes(7, n_bodies=6)]
    result = taichi_dcd.find_contacts(meshes)
    assert result.depth.dtype == np.float32
    assert_same_as_brute(result, meshes)


def test_overflowing_buffers_grow_and_give_the_same_contacts(f64):
    meshes = random_meshes(3, n_bodies=10)
    x = np.concatenate([v for v, _ in meshes])
    faces = np.concatenate([f + 24 * k for k, (_, f) in enumerate(meshes)])
    body = np.repeat(np.arange(10), 8)
    px = ti.ndarray(ti.types.vector(3, ti.f64), shape=len(x))
    px.from_numpy(x)
    small = CollisionPipeline(faces, body, pair_capacity=1, contact_capacity=1)
    large = CollisionPipeline(faces, body, pair_capacity=100_000, contact_capacity=100_000)
    n_small, n_large = small.run(px), large.run(px)
    assert n_small == n_large > 1
    assert small.contacts.capacity >= n_small and small.grid.pair_capacity >= small.grid.n_pairs

    def rows(p):
        c = p.contacts.to_numpy()
        return sorted(zip(map(tuple, c.pair.tolist()), c.depth.tolist(), c.side.tolist()))

    assert rows(small) == rows(large)


def test_no_bodies_and_a_single_body_give_no_contacts(f64):
    assert len(taichi_dcd.find_contacts([])) == 0
    box = trimesh.creation.box()
    assert len(taichi_dcd.find_contacts([(box.vertices, box.faces)])) == 0


def test_touching_boxes_are_not_in_contact_and_overlapping_ones_are(f64):
    box = trimesh.creation.box()
    touching = [(box.vertices, box.faces), (box.vertices + [1.0, 0.0, 0.0], box.faces)]
    assert len(taichi_dcd.find_contacts(touching)) == 0
    overlapping = [(box.vertices, box.faces), (box.vertices + [0.9, 0.1, 0.2], box.faces)]
    result = taichi_dcd.find_contacts(overlapping)
    assert len(result) > 0 and result.depth.max() > 0


@pytest.mark.parametrize("meshes, message", [
    ([(np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), np.array([[0, 1, 2]]))],
     "mesh 0: vertex 2 has a NaN or infinite coordinate"),
    ([(np.zeros((3, 3)), np.array([[0, 1, 3]]))], r"mesh 0: face indices must lie in \[0, 3\)"),
    ([(np.zeros((3, 2)), np.array([[0, 1, 2]]))], "mesh 0: vertices must be a numeric"),
    ([(np.zeros((3, 3)), np.array([[0.0, 1.0, 2.0]]))], "mesh 0: faces must be an integer"),
    ([np.zeros((3, 3))], "mesh 0 must be a"),
])
def test_bad_meshes_give_one_clear_error(f64, meshes, message):
    with pytest.raises(ValueError, match=message):
        taichi_dcd.find_contacts(meshes)
