"""The Erleben shapes are closed solids of the stated size, and the independent
penetration measure (docs/method.md) gives known answers."""

import math

import numpy as np
import pytest
import trimesh

from taichi_dcd.scene import shapes
from taichi_dcd.measure.penetration import distance_to_surface, overlap, pair_penetration, scene_penetration
from taichi_dcd.scene.scene import rotation_matrix


def placed(mesh, rotation=(0.0, 0.0, 0.0), position=(0.0, 0.0, 0.0)):
    v = np.asarray(mesh.vertices) @ rotation_matrix(rotation).T + np.asarray(position)
    return trimesh.Trimesh(v, mesh.faces, process=False)


@pytest.mark.parametrize("name, params, volume, bounds", [
    ("spike", {}, 1.0, [[-0.5, 0, -0.5], [0.5, 3, 0.5]]),
    ("wedge", {}, 3.0, [[-0.5, 0, -1], [0.5, 3, 1]]),
    ("crack_block", {}, 8.0 - 0.5 * 1.0 * 0.5 * 4.0, [[-1, 0, -2], [1, 1, 2]]),
    ("hole_block", {}, 4.0 - 0.5, [[-1, 0, -1], [1, 1, 1]]),
    ("hole_block", {"pit": True}, 4.0 - 0.5 / 3, [[-1, 0, -1], [1, 1, 1]]),
    ("ground", {"size": [12.0, 1.0, 12.0]}, 144.0, [[-6, -1, -6], [6, 0, 6]]),
    ("spike", {"subdivisions": 3}, 1.0, [[-0.5, 0, -0.5], [0.5, 3, 0.5]]),
    ("crack_block", {"subdivisions": 2}, 8.0 - 0.5 * 1.0 * 0.5 * 4.0, [[-1, 0, -2], [1, 1, 2]]),
    ("hole_block", {"pit": True, "subdivisions": 2}, 4.0 - 0.5 / 3, [[-1, 0, -1], [1, 1, 1]]),
])
def test_shape_is_a_closed_outward_solid_of_the_stated_size(name, params, volume, bounds):
    mesh = shapes.make_shape(name, params)
    welded = trimesh.Trimesh(mesh.vertices, mesh.faces)  # merges duplicate vertices
    assert len(welded.vertices) == len(mesh.vertices), "duplicate vertices would hide open seams"
    assert mesh.is_watertight and mesh.is_winding_consistent
    # Watertight with every edge shared by exactly two faces also rules out T-junctions.
    assert mesh.volume == pytest.approx(volume, rel=1e-12)
    np.testing.assert_allclose(mesh.bounds, bounds, atol=1e-12)


@pytest.mark.parametrize("name", ["spike", "wedge", "crack_block", "hole_block"])
def test_subdivisions_split_every_face_into_four_on_the_same_surface(name):
    coarse, fine = shapes.make_shape(name, {}), shapes.make_shape(name, {"subdivisions": 2})
    assert len(fine.faces) == 16 * len(coarse.faces)
    # Every fine vertex lies on the coarse surface.
    assert distance_to_surface(np.asarray(fine.vertices), coarse).max() <= 1e-12


def test_crack_groove_opens_at_ninety_degrees():
    mesh = shapes.crack_block()
    groove = [n for n in mesh.face_normals if abs(n[2]) < 1e-12 and 0 < n[1] < 1 and abs(n[0]) > 1e-12]
    assert len(groove) == 4
    left, right = [n for n in groove if n[0] > 0][0], [n for n in groove if n[0] < 0][0]
    assert math.degrees(math.acos(np.dot(left, right))) == pytest.approx(90.0, abs=1e-9)


def test_bad_shape_parameters_are_named():
    with pytest.raises(ValueError, match="groove"):
        shapes.crack_block(width=3.0)
    with pytest.raises(ValueError, match="height must be positive"):
        shapes.spike(height=0.0)
    with pytest.raises(ValueError, match="unknown shape"):
        shapes.make_shape("cone", {})
    for bad in (-1, 1.5, 11, True):
        with pytest.raises(ValueError, match="subdivisions must be a whole number"):
            shapes.make_shape("wedge", {"subdivisions": bad})


def test_vertex_pushed_into_a_face_gives_its_depth():
    """A spike's apex 0.01 below a box's top face: depth 0.01, overlap the pyramid tip's
    volume (a/3 · d)² · d / 3 with the base shrinking 1/3 per unit of depth."""
    block = placed(shapes.box((2.0, 1.0, 2.0)), position=(0.0, -0.5, 0.0))
    spike = placed(shapes.spike(), (180.0, 0.0, 0.0), (0.1, 3.0 - 0.01, 0.05))
    depth, volume = pair_penetration(spike, block)
    assert depth == pytest.approx(0.01, rel=1e-9)
    assert volume == pytest.approx((0.01 / 3) ** 2 * 0.01 / 3, rel=1e-6)


def test_crossed_ridges_give_the_depth_of_the_ridge_inside_the_other_wedge():
    """Ridges crossing at 90°, 0.01 deep: no vertex is inside the other body. A ridge point
    0.01 below the other ridge is d·sin α from that wedge's faces (α = atan(0.5/3), the
    half-angle at the ridge)."""
    lower = placed(shapes.wedge(), position=(0.0, -3.0, 0.0))
    upper = placed(shapes.wedge(), (180.0, 90.0, 0.0), (0.0, 3.0 - 0.01, 0.0))
    depth, volume = pair_penetration(lower, upper)
    assert depth == pytest.approx(0.01 * math.sin(math.atan(0.5 / 3.0)), rel=1e-6)
    assert 0 < volume < 1e-6


@pytest.mark.parametrize("order", ["spike, block", "block, spike"])
def test_overlap_faces_are_told_to_the_surface_they_lie_on(order):
    """Each face of A ∩ B is attributed to the surface it lies on (its centroid within rounding
    of that body's surface and inside the other body by the depth), so the measure takes each
    face point's depth from the other body alone."""
    block = placed(shapes.box((2.0, 1.0, 2.0)), position=(0.0, -0.5, 0.0))
    spike = placed(shapes.spike(), (180.0, 0.0, 0.0), (0.1, 3.0 - 0.01, 0.05))
    a, b = (spike, block) if order == "spike, block" else (block, spike)
    v, f, volume, side = overlap(a, b)
    assert len(f) > 0 and set(np.unique(side)) == {0, 1}
    centroids = v[f].mean(axis=1)
    for on, own, other in ((0, a, b), (1, b, a)):
        at = side == on
        assert distance_to_surface(centroids[at], own).max() < 1e-12
        assert distance_to_surface(centroids[at], other).max() <= 0.01 + 1e-12
    # The apex's faces lie on the spike; the block's top face, cut to the tip's section, on the block.
    on_block = side == (1 if a is spike else 0)
    assert np.allclose(centroids[on_block][:, 1], 0.0, atol=1e-12)


@pytest.mark.parametrize("gap", [0.0, 1e-9, 1e-3])
def test_touching_or_separate_bodies_measure_zero(gap):
    block = placed(shapes.box((2.0, 1.0, 2.0)), position=(0.0, -0.5, 0.0))
    cube = placed(shapes.box((0.5, 0.5, 0.5)), position=(0.3, 0.25 + gap, -0.2))
    depth, volume = pair_penetration(cube, block)
    assert depth < 1e-12 and volume < 1e-15  # zero up to round-off


def test_scene_measure_skips_static_pairs_and_names_the_deepest_pair():
    ground = placed(shapes.ground())
    block = placed(shapes.box((1.0, 1.0, 1.0)), position=(0.0, 0.5 - 0.2, 0.0))   # static, 0.2 deep
    cube = placed(shapes.box((0.5, 0.5, 0.5)), position=(0.0, 0.8 + 0.25 - 0.003, 0.0))  # 3 mm into it
    result = scene_penetration([("ground", "static", ground), ("block", "static", block), ("cube", "rigid", cube)])
    assert result.pair == ("block", "cube")
    assert result.depth == pytest.approx(0.003, rel=1e-9)
    assert result.volume == pytest.approx(0.25 * 0.003, rel=1e-6)
    # Two pairs measured (ground-cube, block-cube); the cube's box is clear of the ground's.
    assert (result.pairs, result.pairs_apart) == (2, 1)


def test_pruned_distance_equals_brute_force_on_seeded_points():
    """distance_to_surface skips triangles by bounding spheres; it must equal the distance
    to every triangle, on points inside, outside and on a deformed ball."""
    from taichi_dcd.measure.penetration import distance_to_surface

    rng = np.random.default_rng(7)
    ball = shapes.icosphere(0.5, 2)
    ball = trimesh.Trimesh(np.asarray(ball.vertices) * (1 + 0.1 * rng.random((len(ball.vertices), 1))), ball.faces,
                           process=False)
    points = np.concatenate([rng.normal(size=(200, 3)) * 0.3, rng.normal(size=(100, 3)) * 2.0,
                             np.asarray(ball.vertices)[:50]])
    tris = np.asarray(ball.triangles)
    brute = np.array([point_triangle_distances(tris, p).min() for p in points])
    np.testing.assert_allclose(distance_to_surface(points, ball), brute, rtol=0, atol=1e-12)
    # Points in a small box (as an overlap's are) leave out most triangles before the spheres.
    for centre in (np.asarray(ball.vertices)[3], np.zeros(3), np.array([0.0, 1.2, 0.3])):
        cluster = centre + rng.normal(size=(200, 3)) * 0.02
        brute = np.array([point_triangle_distances(tris, p).min() for p in cluster])
        np.testing.assert_allclose(distance_to_surface(cluster, ball), brute, rtol=0, atol=1e-12)


def point_triangle_distances(tris: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Reference: distance from p to each triangle (n, 3, 3), the plain way: the distance
    to the plane if p projects inside the triangle, else to the nearest of its edges."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n = n / np.linalg.norm(n, axis=1)[:, None]
    height = np.einsum("ij,ij->i", p - tris[:, 0], n)
    foot = p - height[:, None] * n
    inside = np.ones(len(tris), bool)
    edges = []
    for k in range(3):
        a, e = tris[:, k], tris[:, (k + 1) % 3] - tris[:, k]
        inside &= np.einsum("ij,ij->i", np.cross(e, foot - a), n) >= 0
        t = np.clip(np.einsum("ij,ij->i", p - a, e) / np.einsum("ij,ij->i", e, e), 0, 1)
        edges.append(np.linalg.norm(p - a - t[:, None] * e, axis=1))
    return np.where(inside, np.abs(height), np.min(edges, axis=0))


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e-6, 1e3])
def test_closest_points_are_exact_at_every_scale(scale):
    """The closest point on a triangle agrees with the plain reference on seeded random
    pairs at every scale, and lies on the triangle (trimesh's closest_point, with an
    absolute tolerance, is off by up to 75% at 1e-3)."""
    from taichi_dcd.measure.penetration import closest_points_on_triangles

    rng = np.random.default_rng(11)
    tris, points = rng.random((1500, 3, 3)), rng.random((1500, 3)) * 2 - 0.5
    expected = np.array([point_triangle_distances(t[None], p)[0] for t, p in zip(tris, points)])
    closest = closest_points_on_triangles(tris * scale, points * scale)
    np.testing.assert_allclose(np.linalg.norm(closest - points * scale, axis=1) / scale, expected,
                               rtol=1e-9, atol=1e-12)
    bary = [np.linalg.lstsq((t[1:] - t[0]).T * scale, q - t[0] * scale, rcond=None)[0]
            for t, q in zip(tris, closest)]
    assert all(b.min() >= -1e-9 and b.sum() <= 1 + 1e-9 for b in bary)


def test_closest_point_on_a_zero_area_triangle_is_on_its_segment():
    from taichi_dcd.measure.penetration import closest_points_on_triangles

    tris = np.array([[[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0.0, 0, 0], [0, 0, 0], [0, 0, 0]]])
    points = np.array([[1.5, 1.0, 0.0], [0.0, 0.0, 2.0]])
    np.testing.assert_allclose(closest_points_on_triangles(tris, points), [[1.5, 0, 0], [0, 0, 0]])


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_penetration_measure_scales_with_the_scene(scale):
    """The tip-into-face and crossed-ridge cases scaled by L give L times the depth and L³
    times the volume (with trimesh's closest_point the ridges read 5× too deep at 1e-3)."""
    block = placed(shapes.box((2.0, 1.0, 2.0)), position=(0.0, -0.5, 0.0))
    spike = placed(shapes.spike(), (180.0, 0.0, 0.0), (0.1, 3.0 - 0.01, 0.05))
    lower = placed(shapes.wedge(), position=(0.0, -3.0, 0.0))
    upper = placed(shapes.wedge(), (180.0, 90.0, 0.0), (0.0, 3.0 - 0.01, 0.0))
    for pair in ((spike, block), (lower, upper)):
        unscaled = pair_penetration(*pair)
        depth, volume = pair_penetration(*(trimesh.Trimesh(np.asarray(m.vertices) * scale, m.faces, process=False)
                                           for m in pair))
        assert depth == pytest.approx(unscaled[0] * scale, rel=1e-9)
        assert volume == pytest.approx(unscaled[1] * scale ** 3, rel=1e-6)


def test_torus_is_a_closed_outward_ring_about_y():
    """The faceted ring's volume is Pappus's: its 12-gon section's area 6·r²·sin(30°) swept
    round a 48-gon of radius R (2πR·sin(7.5°)/(7.5° in rad))."""
    ring = shapes.make_shape("torus", {"major_radius": 0.4, "minor_radius": 0.1})
    welded = trimesh.Trimesh(ring.vertices, ring.faces)
    assert len(welded.vertices) == len(ring.vertices)
    assert ring.is_watertight and ring.is_winding_consistent and ring.volume > 0
    section = 6 * 0.1 ** 2 * math.sin(2 * math.pi / 12)
    sweep = 2 * math.pi * 0.4 * math.sin(2 * math.pi / 48) / (2 * math.pi / 48)
    assert ring.volume == pytest.approx(section * sweep, rel=1e-9)
    np.testing.assert_allclose(ring.bounds, [[-0.5, -0.1, -0.5], [0.5, 0.1, 0.5]], atol=1e-12)
    with pytest.raises(ValueError, match="minor_radius must be below major_radius"):
        shapes.make_shape("torus", {"major_radius": 0.1, "minor_radius": 0.2})


@pytest.mark.parametrize("seed", [0, 1])
def test_the_pairs_whose_boxes_meet_are_those_boxes_apart_keeps_on_random_bodies(seed, monkeypatch):
    """box_pairs tests every pair of bodies at once (in blocks of rows): on 60 random boxes,
    some static, it returns exactly the pairs, not both static, that boxes_apart does not
    separate, in order, and the count of pairs not both static; scene_penetration's counts
    agree."""
    from taichi_dcd.measure import penetration

    monkeypatch.setattr(penetration, "BOX_BLOCK", 7)  # several blocks, the last one short
    rng = np.random.default_rng(seed)
    bodies = []
    for k in range(60):
        mesh = trimesh.creation.box(extents=rng.uniform(0.05, 0.6, 3))
        mesh.apply_translation(rng.uniform(-1.0, 1.0, 3))
        bodies.append((f"b{k}", "static" if k % 5 == 0 else "rigid", mesh))
    expected = [(i, j) for i in range(60) for j in range(i + 1, 60)
                if not (bodies[i][1] == bodies[j][1] == "static")
                and not penetration.boxes_apart(bodies[i][2], bodies[j][2])]
    total = sum(1 for i in range(60) for j in range(i + 1, 60) if not (bodies[i][1] == bodies[j][1] == "static"))
    meeting, counted = penetration.box_pairs(bodies)
    assert [tuple(p) for p in meeting.tolist()] == expected and counted == total
    assert 0 < len(expected) < total
    result = scene_penetration(bodies)
    assert (result.pairs, result.pairs_apart) == (total, total - len(expected))
