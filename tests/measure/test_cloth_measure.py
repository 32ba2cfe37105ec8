"""The cloth's independent penetration measure (measure/cloth.py) against analytic answers and
brute force on seeded random data."""

import numpy as np
import trimesh

from taichi_dcd.measure.cloth import poke_depths, sheet_crossings, sheet_inside_depth, winding_numbers
from taichi_dcd.measure.self_intersection import triangles_cross
from taichi_dcd.scene.shapes import box, sheet, spike


def test_winding_number_is_one_inside_a_box_and_zero_outside():
    points = np.random.default_rng(7).uniform(-1.0, 1.0, (3000, 3))
    inside = (np.abs(points) < 0.5).all(axis=1)
    w = winding_numbers(points, box((1.0, 1.0, 1.0)))
    assert np.array_equal(w > 0.5, inside)
    assert np.abs(w - inside).max() < 1e-9


def test_a_sheet_through_a_box_is_as_deep_as_the_nearer_face():
    """A sheet across a unit box 0.3 above its centre lies 0.2 under the top face at its deepest."""
    cloth = sheet(2.0, 10)
    cloth.vertices[:, 1] += 0.3
    assert abs(sheet_inside_depth(cloth, box((1.0, 1.0, 1.0))) - 0.2) < 1e-12
    cloth.vertices[:, 1] += 0.2 + 1e-9  # just above the top face
    assert sheet_inside_depth(cloth, box((1.0, 1.0, 1.0))) == 0.0


def test_a_pierced_sheet_is_found_though_no_vertex_is_inside():
    """A spike's tip 0.3 m through a coarse sheet, between its vertices: the disc of sheet inside
    the tip's square section (half-width 0.05) is 0.05·cos(atan(1/6)) deep at its centre."""
    cloth = sheet(2.0, 4)  # vertices 0.5 apart: none of them inside the tip
    cloth.vertices[:, [0, 2]] += 0.25
    cloth.vertices[:, 1] += 2.7
    tip = spike(1.0, 3.0)
    assert not (winding_numbers(np.asarray(cloth.vertices), tip) > 0.5).any()
    assert abs(sheet_inside_depth(cloth, tip) - 0.05 * np.cos(np.arctan(1.0 / 6.0))) < 2e-3


def test_poke_depth_of_a_triangle_through_another_is_the_shorter_side():
    flat = np.array([[[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 0.0, 1.0]]])
    upright = np.array([[[0.0, -0.1, 0.0], [0.0, 0.3, 0.2], [0.0, 0.3, -0.2]]])
    assert np.allclose(poke_depths(upright, flat), 0.1)
    assert np.allclose(poke_depths(upright, flat[:, ::-1]), 0.1)  # either winding


def test_crossings_between_two_meshes_match_brute_force():
    """Two crumpled random sheets: every crossing pair, counted as an all-pairs loop counts it."""
    rng = np.random.default_rng(11)
    a, b = sheet(1.0, 6), sheet(1.0, 6)
    a.vertices[:, 1] += rng.normal(0.0, 0.08, len(a.vertices))
    b.vertices[:, 1] += rng.normal(0.0, 0.08, len(b.vertices))
    b.vertices[:, 0] += 0.1
    ta, tb = a.triangles, b.triangles
    i, j = np.meshgrid(np.arange(len(ta)), np.arange(len(tb)), indexing="ij")
    brute = int(triangles_cross(ta[i.ravel()], tb[j.ravel()]).sum())
    count, deepest = sheet_crossings(a.vertices, a.faces, b.vertices, b.faces)
    assert brute > 10 and count == brute and deepest > 0.0
    apart = trimesh.Trimesh(b.vertices + [0.0, 1.0, 0.0], b.faces, process=False)
    assert sheet_crossings(a.vertices, a.faces, apart.vertices, apart.faces) == (0, 0.0)
