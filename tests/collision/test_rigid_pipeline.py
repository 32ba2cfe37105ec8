"""The rigid-body pipeline (grids built once in each body's frame) finds exactly the contacts
the narrow phase finds on every pair of triangles of the posed bodies."""

import numpy as np
import pytest
import trimesh

import taichi_dcd
from taichi_dcd.collision.rigid_pipeline import RigidPipeline
from taichi_dcd.collision.contacts import Contacts


def random_rotation(rng) -> np.ndarray:
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def brute_contacts(meshes, rotation, translation) -> dict:
    """{(tri_a, tri_b): (depth, normal, side)} in global triangle indices for every hit of the
    posed bodies, every pair of triangles of different bodies tested."""
    offsets = np.cumsum([0] + [len(f) for _, f in meshes])
    posed = [v @ r.T + t for (v, _), r, t in zip(meshes, rotation, translation)]
    out = {}
    for ba in range(len(meshes)):
        for bb in range(ba + 1, len(meshes)):
            ta, tb = posed[ba][meshes[ba][1]], posed[bb][meshes[bb][1]]
            ia, ib = (g.ravel() for g in np.meshgrid(np.arange(len(ta)), np.arange(len(tb)), indexing="ij"))
            r = taichi_dcd.collide_triangle_pairs(ta[ia], tb[ib])
            for k in np.flatnonzero(r.hit):
                out[(int(ia[k] + offsets[ba]), int(ib[k] + offsets[bb]))] = (r.depth[k], r.normal[k], r.side[k])
    return out


def assert_matches_brute(pipeline: RigidPipeline, meshes, rotation, translation, atol: float = 1e-9) -> dict:
    n = pipeline.run(rotation, translation)
    got = pipeline.contacts.to_numpy()
    keys = [tuple(p) for p in got.pair.tolist()]
    assert len(keys) == n == len(set(keys)), "a pair was reported twice"
    expected = brute_contacts(meshes, rotation, translation)
    assert set(keys) == set(expected), (
        f"missing {sorted(set(expected) - set(keys))[:5]}, extra {sorted(set(keys) - set(expected))[:5]}")
    for k, key in enumerate(keys):
        depth, normal, side = expected[key]
        assert got.side[k] == side
        assert abs(got.depth[k] - depth) <= atol
        np.testing.assert_allclose(got.normal[k], normal, atol=atol)
    return expected


def soup_bodies(rng, n_bodies: int, tris: int, size: float):
    """Bodies of random triangles around their own origins, each triangle `size` across at most
    (the first body's 20 times larger, so that the grid has levels both ways)."""
    meshes = []
    for k in range(n_bodies):
        scale = size * (20.0 if k == 0 else rng.uniform(0.3, 1.0))
        v = rng.uniform(-1.0, 1.0, (tris, 1, 3)) * 0.3 + scale * rng.uniform(-0.5, 0.5, (tris, 3, 3))
        meshes.append((v.reshape(-1, 3), np.arange(3 * tris).reshape(tris, 3)))
    return meshes


@pytest.mark.parametrize("seed", range(4))
def test_random_posed_soups_match_brute_force(f64, seed):
    rng = np.random.default_rng(seed)
    meshes = soup_bodies(rng, n_bodies=2 + 2 * seed, tris=30, size=0.1)
    pipeline = RigidPipeline(meshes)
    total = 0
    # The grids are built once; the bodies are posed three times.
    for _ in range(3):
        rotation = np.stack([random_rotation(rng) for _ in meshes])
        translation = rng.uniform(-0.2, 0.2, (len(meshes), 3))
        total += len(assert_matches_brute(pipeline, meshes, rotation, translation))
    assert total > 10


def test_turned_tori_match_brute_force(f64):
    a = trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12)
    meshes = [(a.vertices, a.faces)] * 3
    rotation = np.stack([np.eye(3), random_rotation(np.random.default_rng(1)),
                         trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0])[:3, :3]])
    translation = np.array([[0.0, 0.0, 0.0], [0.3, 0.1, 0.05], [1.5, 0.0, 0.0]])
    expected = assert_matches_brute(RigidPipeline(meshes), meshes, rotation, translation)
    assert {(k[0] // len(a.faces), k[1] // len(a.faces)) for k in expected} == {(0, 1), (0, 2), (1, 2)}


def test_box_resting_exactly_on_a_box_finds_the_touching_faces(f64):
    """Faces in one plane, edges on edges: the ties the narrow phase decides as touching or
    hits are found as the brute force finds them."""
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    meshes = [(box.vertices, box.faces), (box.vertices * 0.5, box.faces)]
    rotation = np.stack([np.eye(3), np.eye(3)])
    for lift in (0.75, 0.75 - 1e-3):
        translation = np.array([[0.0, 0.0, 0.0], [0.25, 0.25, lift]])
        expected = assert_matches_brute(RigidPipeline(meshes), meshes, rotation, translation, atol=0.0)
        assert (len(expected) > 0) == (lift < 0.75)


def test_bodies_apart_give_no_contacts(f64):
    rng = np.random.default_rng(5)
    meshes = soup_bodies(rng, n_bodies=3, tris=10, size=0.1)
    pipeline = RigidPipeline(meshes)
    translation = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, -10.0, 0.0]])
    assert pipeline.run(np.stack([np.eye(3)] * 3), translation) == 0


def test_overflowing_buffers_grow_and_give_the_same_contacts(f64):
    rng = np.random.default_rng(8)
    meshes = soup_bodies(rng, n_bodies=4, tris=40, size=0.2)
    rotation = np.stack([random_rotation(rng) for _ in meshes])
    translation = rng.uniform(-0.1, 0.1, (4, 3))
    pipeline = RigidPipeline(meshes)
    import taichi as ti
    from taichi_dcd.collision.broadphase import ivec2

    pipeline.query = ti.ndarray(ivec2, shape=1)
    pipeline.room = 1
    pipeline._allocate_pairs()
    pipeline.contacts = Contacts(1)
    pipeline._allocate_directions(1)
    expected = assert_matches_brute(pipeline, meshes, rotation, translation)
    assert len(expected) > 1


def test_f32(f32):
    rng = np.random.default_rng(3)
    meshes = [(v.astype(np.float32), f) for v, f in soup_bodies(rng, n_bodies=3, tris=30, size=0.1)]
    rotation = np.stack([random_rotation(rng) for _ in meshes])
    translation = rng.uniform(-0.2, 0.2, (3, 3))
    pipeline = RigidPipeline(meshes)
    assert pipeline.contacts.depth.dtype == taichi_dcd.core.runtime.real_type()
    assert_matches_brute(pipeline, meshes, rotation, translation, atol=1e-4)


def test_bad_input_is_refused_with_one_line(f64):
    box = trimesh.creation.box()
    with pytest.raises(ValueError, match="mesh 1: faces must be an integer"):
        RigidPipeline([(box.vertices, box.faces), (box.vertices, box.faces.astype(float))])
    with pytest.raises(ValueError, match="cell_size must be a positive"):
        RigidPipeline([(box.vertices, box.faces)], cell_size=-1.0)
    pipeline = RigidPipeline([(box.vertices, box.faces)] * 2)
    with pytest.raises(ValueError, match=r"rotation \(2, 3, 3\)"):
        pipeline.run(np.eye(3), np.zeros((2, 3)))
    rotation = np.stack([np.eye(3)] * 2)
    rotation[1, 0, 0] = np.nan
    with pytest.raises(ValueError, match="body 1's pose has a NaN"):
        pipeline.run(rotation, np.zeros((2, 3)))


def test_parallel_loops_find_the_same_contacts(f64, monkeypatch):
    """Large queries run their loops in parallel, chunks of kept triangles shared out among
    workers as they come free: the same contacts as the brute force."""
    from taichi_dcd.collision import rigid_pipeline

    monkeypatch.setattr(rigid_pipeline.runtime, "serial_loops", lambda work: False)
    rng = np.random.default_rng(11)
    meshes = soup_bodies(rng, n_bodies=5, tris=60, size=0.15)
    rotation = np.stack([random_rotation(rng) for _ in meshes])
    translation = rng.uniform(-0.1, 0.1, (5, 3))
    expected = assert_matches_brute(RigidPipeline(meshes), meshes, rotation, translation)
    assert len(expected) > 20


@pytest.mark.parametrize("scale, offset", [(1e-3, 1e3), (1e3, 0.0), (1.0, 1e4)])
def test_tiny_huge_and_far_bodies_match_brute_force(f64, scale, offset):
    """Millimetre bodies a kilometre from the origin, kilometre bodies, and a box resting
    exactly on a box 10 km away: the change of frame's rounding is padded by the size of the
    world coordinates, so no pair the narrow phase finds there is missed."""
    rng = np.random.default_rng(21)
    meshes = [(v * scale, f) for v, f in soup_bodies(rng, n_bodies=3, tris=30, size=0.1)]
    rotation = np.stack([random_rotation(rng) for _ in meshes])
    translation = offset + scale * rng.uniform(-0.2, 0.2, (3, 3))
    expected = assert_matches_brute(RigidPipeline(meshes), meshes, rotation, translation, atol=1e-9 * scale)
    assert len(expected) > 3
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    boxes = [(box.vertices * scale, box.faces), (box.vertices * 0.5 * scale, box.faces)]
    resting = np.array([[offset, offset, offset], [offset + 0.25 * scale, offset, offset + 0.75 * scale]])
    assert_matches_brute(RigidPipeline(boxes), boxes, np.stack([np.eye(3)] * 2), resting, atol=0.0)


def test_static_bodies_are_not_paired_with_each_other(f64):
    rng = np.random.default_rng(4)
    meshes = soup_bodies(rng, n_bodies=3, tris=30, size=0.1)
    rotation = np.stack([random_rotation(rng) for _ in meshes])
    translation = rng.uniform(-0.05, 0.05, (3, 3))
    everything = brute_contacts(meshes, rotation, translation)
    offsets = np.cumsum([0] + [len(f) for _, f in meshes])
    body = np.repeat(np.arange(3), np.diff(offsets))
    pipeline = RigidPipeline(meshes, static=[True, True, False])
    pipeline.run(rotation, translation)
    got = {tuple(p) for p in pipeline.contacts.to_numpy().pair.tolist()}
    wanted = {k for k in everything if body[k[1]] == 2}
    assert any(body[k[1]] == 1 for k in everything), "the two static bodies should overlap"
    assert got == wanted and len(wanted) > 0
    with pytest.raises(ValueError, match="static needs one flag per body"):
        RigidPipeline(meshes, static=[True])


def test_each_cells_slab_holds_its_triangles_and_a_plates_faces_turn_nothing_away(f64):
    """Every vertex of every triangle listed in a cell lies within that cell's slab (a
    triangle outside it is then parted from all of them); a cell holding both faces of a
    thin plate, whose normals cancel, has an unbounded slab."""
    a = trimesh.creation.torus(1.0, 0.35, major_sections=40, minor_sections=20)
    plate = trimesh.creation.box(extents=(0.3, 0.3, 1e-4)).subdivide().subdivide()
    plate.apply_translation([0.0, 0.0, 0.0123])  # both faces within one layer of cells
    meshes = [(a.vertices, a.faces), (plate.vertices, plate.faces)]
    pipeline = RigidPipeline(meshes)
    grid = pipeline.grid
    x = np.concatenate([a.vertices, plate.vertices])
    faces = np.concatenate([a.faces, plate.faces + len(a.vertices)])
    normal, bounds = (arr.to_numpy().astype(np.float64) for arr in (pipeline.slab_normal, pipeline.slab_range))
    bounded = 0
    for start, end in grid.runs:
        tris = grid.items[start:end]
        along = x[faces[tris]] @ normal[start]
        assert along.min() >= bounds[start, 0] and along.max() <= bounds[start, 1]
        if np.isfinite(bounds[start]).all():
            bounded += 1
            assert abs(np.linalg.norm(normal[start]) - 1.0) < 1e-6
    assert bounded > 0.9 * len(grid.runs)
    up = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])[:, 2]
    plate = np.arange(len(faces)) >= len(a.faces)
    both_faces = [s for s, e in grid.runs
                  if (plate[grid.items[s:e]] & (up[grid.items[s:e]] > 0)).any()
                  and (plate[grid.items[s:e]] & (up[grid.items[s:e]] < 0)).any()]
    assert both_faces and all(np.isinf(bounds[s]).all() for s in both_faces)


@pytest.mark.parametrize("gap", [0.02, 1e-9, 0.0])
def test_near_coincident_surfaces_match_brute_force(f64, gap):
    """Two tori on one axis `gap` apart (their surfaces parallel, within the gap, over most of
    their area, where cells' slabs part them) and a plate laid on another plate's face,
    touching or a hair above it: every pair the narrow phase finds is found."""
    a = trimesh.creation.torus(1.0, 0.35, major_sections=32, minor_sections=16)
    meshes = [(a.vertices, a.faces)] * 2
    rotation = np.stack([np.eye(3), np.eye(3)])
    expected = assert_matches_brute(RigidPipeline(meshes), meshes, rotation, np.array([[0, 0, 0], [0, 0, gap]]))
    assert len(expected) > 0  # crossing, or (gap 0) coincident faces touching
    plate = trimesh.creation.box(extents=(0.5, 0.5, 0.01))
    plates = [(plate.vertices, plate.faces), (plate.vertices * [0.5, 0.5, 1.0], plate.faces)]
    lifted = np.array([[0.0, 0.0, 0.0], [0.05, 0.02, 0.01 + gap]])
    assert_matches_brute(RigidPipeline(plates), plates, rotation, lifted, atol=0.0)


def test_plates_touching_in_f32_match_brute_force(f32):
    """In f32 the narrow phase's touching tolerance is wide (~4e-6 of an edge): plates laid on
    each other, overlapping by a little more or a little less than it, or a hair apart, give
    through the cells' slabs what the brute force gives."""
    plate = trimesh.creation.box(extents=(0.5, 0.5, 0.01)).subdivide()
    plates = [(plate.vertices.astype(np.float32), plate.faces),
              (plate.vertices.astype(np.float32) * np.float32([0.5, 0.5, 1.0]), plate.faces)]
    rotation = np.stack([np.eye(3), np.eye(3)])
    found = []
    for gap in (-1e-5, -1e-6, -1e-7, -1e-8, 0.0, 1e-7):
        lifted = np.array([[0.0, 0.0, 0.0], [0.05, 0.02, 0.01 + gap]])
        found.append(len(assert_matches_brute(RigidPipeline(plates), plates, rotation, lifted, atol=1e-4)))
    assert found[0] > 0  # within the tolerance the plates only touch: no hits
