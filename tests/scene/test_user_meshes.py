"""A user's own odd meshes and scenes: what is wrong with them is said before it becomes a
wrong result (bodies placed into each other, a mesh that crosses itself, two parts meeting
along an edge, a scene far from the origin)."""

import numpy as np
import pytest
import trimesh
from cli_helpers import assert_one_line_error, run_cli, snapshot

from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene, load_scene

TETRA = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n"


def cube_obj_lines(offset, first: int) -> list[str]:
    """A unit cube's 8 vertices at `offset` and its 12 outward faces, numbered from `first` (1-based)."""
    corners = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    lines = [f"v {x + offset[0]} {y + offset[1]} {z + offset[2]}" for x, y, z in corners]
    for a, b, c, d in quads:
        lines += [f"f {first + a} {first + b} {first + c}", f"f {first + a} {first + c} {first + d}"]
    return lines


def one_body_scene(mesh: str, position=(0.0, 1.0, 0.0)) -> str:
    return (f'[sim]\nframes = 1\n\n[[body]]\nname = "part"\nkind = "rigid"\nmesh = "{mesh}"\n'
            f'position = {list(position)}\n\n[[body]]\nname = "floor"\nkind = "static"\nshape = "ground"\n')


# ---------------------------------------------------------------- bodies placed into each other
def test_bodies_that_start_inside_each_other_are_named_with_their_depth(f64, tmp_path):
    (tmp_path / "tetra.obj").write_text(TETRA)
    bodies = [{"name": "a", "kind": "rigid", "mesh": "tetra.obj", "position": [0.0, 0.5, 0.0]},
              {"name": "b", "kind": "rigid", "mesh": "tetra.obj", "position": [0.2, 0.5, 0.0]},
              {"name": "floor", "kind": "static", "shape": "ground"}]
    scene = Scene(scene_from_dict({"body": bodies}, "overlap", tmp_path))
    # Tetrahedron b is a moved 0.2 m along x: they share the tetrahedron 0.8 the size, and no
    # point of either is more than 0.2 m inside the other.
    [overlap] = scene.start_overlaps
    assert overlap["bodies"] == ["a", "b"] and 0.1 < overlap["depth"] <= 0.2 + 1e-9
    assert overlap["volume"] == pytest.approx((1 - 0.2) ** 3 / 6, rel=1e-6)  # a tetrahedron 0.8 the size
    [line] = [w for w in scene.warnings if "overlap at the start" in w]
    assert "'a' and 'b'" in line and f"{overlap['depth']:.2e} m deep" in line and "move them apart" in line


def test_bodies_resting_on_each_other_or_apart_get_no_overlap_warning(f64):
    bodies = [{"name": "box", "kind": "rigid", "shape": "box", "position": [0.0, 0.5, 0.0]},
              {"name": "top", "kind": "rigid", "shape": "box", "position": [0.2, 1.5, 0.1]},
              {"name": "floor", "kind": "static", "shape": "ground"}]
    scene = Scene(scene_from_dict({"body": bodies}, "stacked"))
    assert scene.start_overlaps == [] and scene.warnings == []


def test_a_box_started_inside_a_block_is_pushed_out_gradually_and_not_launched(f64_scene):
    """What the docs promise for a starting overlap: the depth is undone over several frames
    (each contact's older depth at most depenetration_speed), and the push does not become a
    launch velocity."""
    depth = 0.05
    bodies = [{"name": "box", "kind": "rigid", "shape": "box", "position": [0.0, 0.5 - depth, 0.0]},
              {"name": "block", "kind": "static", "shape": "box", "params": {"size": [4.0, 1.0, 4.0]},
               "position": [0.0, -0.5, 0.0]}]
    scene = Scene(scene_from_dict({"sim": {"frames": 40}, "body": bodies}, "sunk"))
    assert scene.start_overlaps[0]["depth"] == pytest.approx(depth, rel=1e-9)
    depths, lowest, rising = [], [], []
    for _ in range(40):
        scene.step(1)
        depths.append(scene.penetration().depth)
        lowest.append(scene.body_vertices("box")[:, 1].min())
        rising.append(scene.body_velocities()[0, 1])
    # 0.2 m/s per contact, four corners and more pushing: measured 0.24-0.9 m/s of rise.
    assert depths[0] > depth - 0.01 and depths[3] > 0.0     # not at once
    assert depths[29] == 0.0 and depths[-1] == 0.0           # parted within 0.3 s, and stays so
    assert max(lowest) < 1e-5 and max(rising) < 0.01         # rests on the block, no hop


# ---------------------------------------------------------------- meshes that cross themselves
def test_self_intersecting_mesh_is_warned_with_its_volume_and_the_fix_works(f64, tmp_path):
    lines = cube_obj_lines((0.0, 0.0, 0.0), 1) + cube_obj_lines((0.5, 0.3, 0.2), 9)
    (tmp_path / "two.obj").write_text("\n".join(lines) + "\n")
    (tmp_path / "scene.toml").write_text(one_body_scene("two.obj"))
    [warning] = load_scene(tmp_path / "scene.toml").warnings
    # Two unit cubes overlapping in a 0.5 × 0.7 × 0.8 box: 2 m³ as given, 1.72 m³ as a solid.
    assert warning.startswith(f"body 'part' ({tmp_path / 'two.obj'}): the mesh intersects itself")
    assert "mass and inertia count the overlap twice" in warning
    assert "2 m³ as given, 1.72 m³ as one solid" in warning
    assert f"taichi-dcd union {tmp_path / 'two.obj'} FIXED.obj" in warning

    fixed = run_cli("union", "two.obj", "fixed.obj", cwd=tmp_path)
    assert fixed.returncode == 0, fixed.stderr
    solid = trimesh.load(tmp_path / "fixed.obj", force="mesh")
    assert solid.is_watertight and solid.volume == pytest.approx(1.72, rel=1e-9)
    before = snapshot(tmp_path)
    assert_one_line_error(run_cli("union", "two.obj", "fixed.obj", cwd=tmp_path), 2, "fixed.obj", "exists")
    assert snapshot(tmp_path) == before

    (tmp_path / "scene.toml").write_text(one_body_scene("fixed.obj"))
    scene = load_scene(tmp_path / "scene.toml")
    assert scene.warnings == [] and scene.model.bodies[0].mass == pytest.approx(1000 * 1.72, rel=1e-9)


def test_union_refuses_a_mesh_it_cannot_fix_and_leaves_no_file(tmp_path):
    (tmp_path / "tetra.obj").write_text(TETRA)
    result = run_cli("union", "tetra.obj", "out.obj", cwd=tmp_path)
    assert result.returncode == 0 and "nothing to fix" in result.stderr
    assert not (tmp_path / "out.obj").exists()


# ---------------------------------------------------------------- parts meeting along an edge
def test_two_cubes_sharing_an_edge_are_refused_naming_that_edge(tmp_path):
    # The second cube, moved by (1, 1, 0), shares the first's edge from (1, 1, 0) to (1, 1, 1):
    # the first cube's vertices 6 and 7, counting from 0.
    lines = cube_obj_lines((0.0, 0.0, 0.0), 1) + cube_obj_lines((1.0, 1.0, 0.0), 9)
    (tmp_path / "edge.obj").write_text("\n".join(lines) + "\n")
    (tmp_path / "scene.toml").write_text(one_body_scene("edge.obj"))
    before = snapshot(tmp_path)
    result = run_cli("run", "scene.toml", "--no-frames", "--out", "out", cwd=tmp_path)
    assert_one_line_error(result, 2, "edge.obj", "not manifold", "between vertices 6 and 7", "shared by 4 faces")
    assert "boundary" not in result.stderr.splitlines()[-1]
    assert snapshot(tmp_path) == before


def test_an_open_mesh_names_an_edge_of_its_hole(tmp_path):
    (tmp_path / "open.obj").write_text(TETRA.rsplit("f", 1)[0])  # the face 1 4 3 missing
    (tmp_path / "scene.toml").write_text(one_body_scene("open.obj"))
    result = run_cli("run", "scene.toml", "--no-frames", "--out", "out", cwd=tmp_path)
    assert_one_line_error(result, 2, "not closed (3 boundary edges", "belongs to one face only")


# ---------------------------------------------------------------- a scene far from the origin
def test_a_drop_at_a_billion_metres_lands_as_it_does_at_the_origin(f64_scene):
    """f64 resolves 1e9 m to ~1e-7 m: a body placed there is not an explosion, and it rests on
    the block's top as it would at the origin."""
    far = 1e9
    bodies = [{"name": "cube", "kind": "rigid", "shape": "box", "params": {"size": [0.3, 0.3, 0.3]},
               "position": [far, 0.3, 0.0]},
              {"name": "block", "kind": "static", "shape": "box", "params": {"size": [2.0, 1.0, 2.0]},
               "position": [far, -0.5, 0.0]}]
    scene = Scene(scene_from_dict({"sim": {"frames": 60}, "body": bodies}, "far"))
    scene.step(60)
    cube = scene.body_vertices("cube")
    assert np.abs(cube[:, 1].min()) < 1e-4                  # on the block's top (y = 0), not in it
    assert np.abs(cube[:, 0] - far).max() == pytest.approx(0.15, abs=1e-4)  # where it was dropped
    assert scene.penetration().depth < 1e-4


def test_a_lone_small_body_thrown_fast_flies_on_and_is_not_an_explosion(f64_scene):
    """A 1 cm cube alone at 300 m/s moves 3 m, 170 scene sizes, a frame: fast, not exploded
    (no speed under 1e4 m/s is). Its centre follows x = v·t + g·t²/2."""
    bodies = [{"name": "pellet", "kind": "rigid", "shape": "box", "params": {"size": [0.01, 0.01, 0.01]},
               "velocity": [300.0, 0.0, 0.0]}]
    scene = Scene(scene_from_dict({"sim": {"frames": 5}, "body": bodies}, "pellet"))
    scene.step(5)
    t = scene.time
    np.testing.assert_allclose(scene.body_positions()[0], [300.0 * t, -0.5 * 9.8 * t * t, 0.0], atol=1e-6)
