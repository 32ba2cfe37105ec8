"""Cloth: an open sheet with edge and bending constraints and no volume, whose faces are
two-sided in contact (collision/two_sided.py), judged by the independent measure
(measure/cloth.py)."""

import numpy as np
import pytest

from taichi_dcd.scene.builder import bending_pairs, wavefront_order
from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene
from taichi_dcd.scene.shapes import sheet


def test_a_sheet_has_one_bending_pair_per_inner_edge_and_its_mass_from_its_area():
    """n × n cells: 2n(n−1) inner grid edges and n² diagonals, each with its two tips."""
    n = 5
    mesh = sheet(1.0, n)
    pairs = bending_pairs(mesh)
    assert len(pairs) == 2 * n * (n - 1) + n * n
    # Each pair's tips are the two vertices of the faces across an edge that the edge lacks.
    faces = {frozenset(f) for f in mesh.faces.tolist()}
    for p, q in pairs.tolist():
        assert p != q and not any({p, q} <= f for f in faces)


def xpbd_sweep(x: np.ndarray, w: np.ndarray, edges: np.ndarray, rest: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """One Gauss-Seidel sweep of XPBD edge constraints in list order (plain NumPy, λ from 0)."""
    x = x.copy()
    for (i, j), length, a in zip(edges.tolist(), rest, alpha):
        d = x[i] - x[j]
        norm = np.sqrt(d @ d)
        dl = -(norm - length) / (w[i] + w[j] + a)
        x[i] += w[i] * dl * d / norm
        x[j] -= w[j] * dl * d / norm
    return x


def test_the_wavefront_order_gives_the_mesh_orders_sweep_bit_for_bit():
    """The edge and bending constraints of a sheet, solved in wavefront_order, land every vertex
    on the same bits as in the mesh's order (seeded random positions, masses, rest lengths and
    compliances), and almost no constraint reads a vertex the one before it wrote (in the mesh's
    order a third do)."""
    rng = np.random.default_rng(7)
    mesh = sheet(1.0, 8)
    edges = np.concatenate([np.asarray(mesh.edges_unique, np.int64), bending_pairs(mesh)])
    x = np.asarray(mesh.vertices) + rng.normal(0.0, 0.02, (len(mesh.vertices), 3))
    w = rng.uniform(0.5, 2.0, len(x))
    rest = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1) * rng.uniform(0.9, 1.1, len(edges))
    alpha = rng.choice([0.0, 1e-3, 1.0], len(edges))
    order = wavefront_order(edges)
    assert sorted(order.tolist()) == list(range(len(edges)))
    reordered = edges[order]

    def reads_last_write(e):
        return (e[1:, :, None] == e[:-1, None, :]).any(axis=(1, 2)).mean()

    assert reads_last_write(edges) > 0.25 and reads_last_write(reordered) < 0.05
    assert np.array_equal(xpbd_sweep(x, w, edges, rest, alpha),
                          xpbd_sweep(x, w, reordered, rest[order], alpha[order]))
    # The order matters: the same constraints sorted by their second vertex land elsewhere.
    other = np.argsort(edges[:, 1], kind="stable")
    assert not np.array_equal(xpbd_sweep(x, w, edges, rest, alpha),
                              xpbd_sweep(x, w, edges[other], rest[other], alpha[other]))


def cloth_on_block(flip: bool, frames: int = 60) -> Scene:
    """A 0.6 m cloth (128 triangles) dropped 2 cm onto a 1 m block; `flip` reverses its
    winding (its normals face down)."""
    scene = Scene(scene_from_dict({"sim": {"substeps": 12, "iterations": 16}, "body": [
        {"name": "block", "kind": "static", "shape": "box", "params": {"size": [1.0, 0.2, 1.0]}},
        {"name": "cloth", "kind": "cloth", "shape": "sheet", "params": {"size": 0.6, "cells": 8},
         "position": [0.0, 0.12, 0.0], "rotation": [180.0, 0.0, 0.0] if flip else [0.0, 0.0, 0.0],
         "compliance": 1e-6, "bending": 1e-3, "damping": 10.0, "drag": 1.0}]}, name="cloth"))
    scene.step(frames)
    return scene


def test_a_cloth_rests_flat_on_a_block_whichever_way_its_faces_point(f64_scene):
    """Dropped face up or face down, the sheet lies on the block's top (y = 0.1) within 0.1 mm,
    flat, its own size, and nowhere inside the block by more than 1e-4 m."""
    heights = []
    for flip in (False, True):
        scene = cloth_on_block(flip)
        normals = np.cross(*np.diff(scene.body_vertices("cloth")[scene.body_faces("cloth")], axis=1).transpose(1, 0, 2))
        assert abs(abs(normals[:, 1]).min() / np.linalg.norm(normals, axis=1).max() - 1.0) < 1e-3  # flat
        assert (np.sign(normals[:, 1]) == (-1.0 if flip else 1.0)).all()  # not turned over
        y = scene.body_vertices("cloth")[:, 1]
        assert np.abs(y - 0.1).max() < 1e-4
        assert np.ptp(scene.body_vertices("cloth")[:, 0]) > 0.59
        assert scene.penetration().depth <= 1e-4
        heights.append(y.mean())
        del scene
    assert abs(heights[0] - heights[1]) < 1e-5


def test_two_sheets_dropped_on_each_other_keep_their_gap(f64_scene):
    """Two 0.6 m sheets, the upper turned 30°, dropped 1 cm apart onto a block: the lower rests
    on the block, the upper (where it lies over the lower) on the lower at their gap (CLOTH_GAP_FRACTION of the 7.5 cm
    spacing: 1.5 mm), and no triangle of one crosses the other. (Without the gap the two came
    to lie in one plane.)"""
    from taichi_dcd.contact.cloth import CLOTH_GAP_FRACTION
    from taichi_dcd.measure.cloth import sheet_crossings

    def sheet_body(name, y, turn):
        return {"name": name, "kind": "cloth", "shape": "sheet", "params": {"size": 0.6, "cells": 8},
                "position": [0.0, y, 0.0], "rotation": [0.0, turn, 0.0], "compliance": 1e-6, "bending": 1e-3,
                "damping": 10.0, "drag": 3.0}

    scene = Scene(scene_from_dict({"sim": {"substeps": 12, "iterations": 16}, "body": [
        {"name": "block", "kind": "static", "shape": "box", "params": {"size": [1.0, 0.2, 1.0]}},
        sheet_body("lower", 0.12, 0.0), sheet_body("upper", 0.13, 30.0)]}, name="two"))
    scene.step(40)
    lower, upper = scene.body_vertices("lower"), scene.body_vertices("upper")
    gap = CLOTH_GAP_FRACTION * 0.6 / 8 * (1.0 + (2.0 ** 0.5 - 1.0) / 3.0)  # mean edge: sides and diagonals
    assert np.abs(lower[:, 1] - 0.1).max() < 1e-4
    over = (np.abs(upper[:, 0]) < 0.2) & (np.abs(upper[:, 2]) < 0.2)  # well inside the lower's square
    assert over.sum() > 20 and np.abs(upper[over, 1] - 0.1 - gap).max() < 0.1 * gap
    assert sheet_crossings(lower, scene.body_faces("lower"), upper, scene.body_faces("upper")) == (0, 0.0)


@pytest.mark.slow
def test_the_built_in_cloth_on_spike_drapes_without_being_pierced(f64_scene):
    """`cloth-on-spike` (self_collision on, the grid): over its first 2 s, through the landing on
    the tip and the drape, the tip stays out of the sheet (1e-4 m) and the sheet never crosses
    itself."""
    from taichi_dcd.scene.builtin import builtin_scene

    scene = Scene(builtin_scene("cloth-on-spike"))
    assert scene.solver.use_grid
    for _ in range(20):
        scene.step(10)
        assert scene.penetration().depth <= 1e-4
        assert scene.self_penetration()["cloth"][0] == 0
    low = scene.body_vertices("cloth")[:, 1].min()
    assert low < -0.5  # it hangs down the spike's sides


@pytest.mark.slow
def test_two_cloths_on_the_box_settle(f64_scene):
    """`two-cloths-on-box` from 2 s to 3 s: no vertex moves faster than the settle speed (1 mm/s
    between frames), the sheets do not cross each other or themselves, and nothing is inside
    the box. Two things kept it moving: where the lower sheet lies on a corner of the box under
    the upper one, the box's row and the upper sheet's rows disagree by ~77 µm, and when the row
    solved last won the corner vertex went up and down by that much every substep (7.7 mm/s
    between frames); and a fold of one sheet inside a fold of the other, whose rows were let go
    whenever it drifted to the edge of the sheets' gap, rattled wall to wall every 13 substeps
    (0.5-2.6 mm/s)."""
    from taichi_dcd.measure.cloth import sheet_crossings
    from taichi_dcd.scene.builtin import builtin_scene

    scene = Scene(builtin_scene("two-cloths-on-box"))
    scene.step(200)
    x = scene.vertices().copy()
    for _ in range(100):
        scene.step(1)
        speed = np.linalg.norm(scene.vertices() - x, axis=1).max() / 0.01
        assert speed < 1e-3, f"a vertex moves at {speed:.2e} m/s at t = {scene.time:.2f} s"
        x = scene.vertices().copy()
    lower, upper = scene.body_vertices("lower_cloth"), scene.body_vertices("upper_cloth")
    assert sheet_crossings(lower, scene.body_faces("lower_cloth"), upper, scene.body_faces("upper_cloth"))[0] == 0
    assert all(count == 0 for count, _ in scene.self_penetration().values())
    assert scene.penetration().depth <= 1e-4


def test_a_spinning_flapping_cloth_keeps_its_momentum_and_angular_momentum(f64_scene):
    """A 0.6 m cloth (128 triangles) in zero gravity, spinning at 3 rad/s about a tilted axis,
    stretched outward at 0.5 m/s per metre and flapping (seeded random velocities up to
    0.3 m/s): its edges and bending pairs take up the load and turn within each substep, and
    momentum and angular momentum stay within 1e-10 of their start. (With the edges moved
    along their end-of-substep direction the angular momentum drifted by 3e-3: a cloth
    hanging from a spike's apex was spun about the vertical for good.)"""
    scene = Scene(scene_from_dict({"sim": {"gravity": [0.0, 0.0, 0.0]}, "body": [
        {"name": "cloth", "kind": "cloth", "shape": "sheet", "params": {"size": 0.6, "cells": 8},
         "compliance": 1e-6, "bending": 1e-3}]}, name="flap"))
    x = scene.body_vertices("cloth")
    r = x - x.mean(axis=0)
    rng = np.random.default_rng(7)
    axis = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])
    v = np.cross(3.0 * axis, r) + 0.5 * r + rng.uniform(-0.3, 0.3, size=r.shape)
    scene.state.vertex_v.from_numpy(v.astype(scene.state.vertex_v.to_numpy().dtype))
    m = 1.0 / scene.model.vertex_inv_mass.to_numpy()[: len(x), None]

    def momenta():
        x, v = scene.body_vertices("cloth"), scene.state.vertex_v.to_numpy()[: len(r)].astype(np.float64)
        return (m * v).sum(axis=0), (m * np.cross(x, v)).sum(axis=0)

    p0, l0 = momenta()
    scene.step(40)
    p1, l1 = momenta()
    assert np.linalg.norm(p1 - p0) <= 1e-10 * np.linalg.norm(p0)
    assert np.linalg.norm(l1 - l0) <= 1e-10 * np.linalg.norm(l0)
    # The load was real: the edges' pull bent the particles' paths.
    assert np.abs(scene.state.vertex_v.to_numpy()[: len(r)] - v).max() > 0.1
