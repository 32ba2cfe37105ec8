"""Each contact rule (taichi_dcd.contact.rules.ContactRules) on the smallest configuration that
needs it: two or three bodies for a fraction of a second, every rule on. Each test fails when
its rule is switched off: `TAICHI_DCD_RULES_OFF=<rule> python -m pytest tests/contact` runs
these (and every other test) with that rule off. docs/method.md describes the rules; the soft
bodies' rules are guarded by the soft scenes of tests/solver/test_soft.py (named there)."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import taichi_dcd
from taichi_dcd.scene.builtin import builtin_scene
from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene

from conftest import rules_under_test

DATA = Path(__file__).parent.parent / "data"


def box(name: str, size, position, kind: str = "rigid", **keys) -> dict:
    return {"name": name, "kind": kind, "shape": "box", "params": {"size": list(size)}, "position": list(position),
            **keys}


def run(bodies: list, frames: int) -> dict:
    """Run `bodies` for `frames` frames of 0.01 s at the default setting (f64, no debug mode:
    a whole frame kernel). Returns the scene, each vertex's largest displacement (m), the
    largest kinetic energy over the second half (J) and the independent penetration depth (m)."""
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    scene = Scene(scene_from_dict({"sim": {"frame_dt": 0.01}, "body": bodies}, name="rule"), rules=rules_under_test())
    start = scene.vertices().copy()
    energy = []
    for _ in range(frames):
        scene.step(1)
        energy.append(scene.kinetic_energy())
    return {"scene": scene, "moved": np.abs(scene.vertices() - start).max(), "energy": max(energy[frames // 2:]),
            "depth": scene.penetration().depth}


@pytest.fixture(scope="module")
def box_on_its_own_footprint():
    """A 1 m cube set exactly on a static 1 m cube: every pair of its faces with the block's
    touches (side faces in the side planes, bottom in the top, edges on edges). 0.3 s."""
    return run([box("block", (1.0, 1.0, 1.0), (0.0, -0.5, 0.0), "static"),
                box("box", (1.0, 1.0, 1.0), (0.0, 0.5, 0.0))], frames=30)


def test_touching_pairs_hold_a_box_set_on_its_own_footprint(box_on_its_own_footprint):
    """touching_pairs: the box does not sink 10 µm (without the rule no pair has a depth and the
    box falls through the block: 0.44 m in 0.3 s)."""
    box_vertices = box_on_its_own_footprint["scene"].body_vertices("box")
    assert box_vertices[:, 1].min() > -1e-5


def test_touching_rows_keep_the_box_on_its_footprint_from_jumping(box_on_its_own_footprint):
    """touching_rows: no vertex of the box moves 10 µm (seen: 1.8 µm). Without the rule, rows at
    rounding depth along the coincident vertical edges come in pairs pushing opposite ways,
    their multipliers grow, and they let go at once: the box jumps 0.8 mm."""
    assert box_on_its_own_footprint["moved"] < 1e-5


def test_surface_points_leave_the_box_on_its_footprint_where_it_was_set(box_on_its_own_footprint):
    """surface_points (resting rows on the other body's surface): no vertex of the box moves
    10 µm. Without the rule, pairs of the box's side faces with the block's side faces around
    the corners measure the box's sink sideways, and those rows push it 1.5 cm sideways and
    tilt it."""
    assert box_on_its_own_footprint["moved"] < 1e-5


def test_next_vertex_keeps_the_box_on_its_footprint_where_it_was_set(box_on_its_own_footprint):
    """next_vertex: no vertex of the box moves 10 µm. A touching row gives way to the next
    vertex of its triangle over the face; without the rule it is simply dropped, the box keeps
    fewer supports than it rests on, and it tilts (56 µm)."""
    assert box_on_its_own_footprint["moved"] < 1e-5


@pytest.mark.parametrize("offset", [(1e-12, 0.0), (0.3, 0.0), (1e-4, 1e-4)],
                         ids=["a-hair-off-its-footprint", "along-one-side", "off-both-ways"])
def test_surface_points_leave_a_box_sharing_a_blocks_side_plane_where_it_was_set(offset):
    """surface_points against a static body: a 1 m cube set on a static 1 m cube with a side
    plane in common (1e-12 m off its footprint, 0.3 m along one side, 0.1 mm off both ways) stays
    where it was set: no vertex moves 20 µm over 0.3 s (one substep's sink is 7 µm). Without the
    rule for rows against static bodies, a row from the block's side face, its point on the box's
    bottom edge, measured 0.7 m along the box's end face and threw the box 1-4 cm."""
    result = run([box("block", (1.0, 1.0, 1.0), (0.0, -0.5, 0.0), "static"),
                  box("box", (1.0, 1.0, 1.0), (offset[0], 0.5, offset[1]))], frames=30)
    assert result["moved"] < 2e-5


def test_duplicates_leave_a_box_resting_flat_on_a_free_box_still():
    """duplicates: a 0.6 × 0.3 × 0.6 m box set 0.1 mm above a free 1 m box on the ground comes to
    rest: over the second half of 0.4 s the kinetic energy stays below 1e-15 J (seen: 9e-27).
    A corner shared by several triangles is reported by each triangle pair; without the rule
    every copy is a row, the point weighs several times in the Gauss-Seidel sweeps, the result
    depends on the triangulation, and the box keeps turning (6e-10 J)."""
    result = run([{"name": "ground", "kind": "static", "shape": "ground"},
                  box("low", (1.0, 1.0, 1.0), (0.0, 0.5, 0.0)),
                  box("top", (0.6, 0.3, 0.6), (0.1, 1.15 + 1e-4, -0.1))], frames=40)
    assert result["energy"] < 1e-15


def test_nearest_exit_holds_a_box_overhanging_a_block_edge():
    """nearest_exit: a box resting with 0.15 m of its 0.4 m past a block's edge (its centre of
    mass over the block) stays within 10 µm over 0.4 s. Without the rule, once it sinks into the
    top face, its end faces cross the block's side face and the rows of those pairs push it
    sideways: it slides off the edge (5 cm in 0.4 s)."""
    result = run([box("block", (1.0, 0.2, 1.0), (0.0, -0.1, 0.0), "static"),
                  box("box", (0.4, 0.2, 0.4), (0.35, 0.1, 0.0))], frames=40)
    assert result["moved"] < 1e-5


def test_shock_propagation_keeps_a_heavy_box_from_driving_a_light_one_into_the_ground():
    """shock_propagation: a 640 kg box resting on a 1.6 kg box on the ground (mass ratio 400):
    neither goes 10 µm into anything (without the rule, Gauss-Seidel cannot carry the heavy
    box's weight down through the light one in a substep's sweeps: both sink 0.1 m into the
    ground in 0.3 s)."""
    result = run([box("ground", (2.0, 0.2, 2.0), (0.0, -0.1, 0.0), "static"),
                  box("light", (0.4, 0.1, 0.4), (0.0, 0.05, 0.0), density=10.0),
                  box("heavy", (0.4, 0.4, 0.4), (0.0, 0.3, 0.0), density=10000.0)], frames=30)
    assert result["depth"] < 1e-5
    assert result["moved"] < 1e-5


def three_box_stack(rules) -> dict:
    """The built-in stack's lowest three boxes (0.4 × 0.2 × 0.4 m, one footprint) set 1e-5 m
    apart on the ground, after 0.6 s, every box asleep by then. Returns how far a box vertex
    ends from where it should rest (m: where it was set, lowered by the gaps under it) and the
    independent penetration measure at the end."""
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    boxes = [box(f"box_{k}", (0.4, 0.2, 0.4), (0.0, 0.1 + 0.2 * k + 1e-5 * (k + 1), 0.0)) for k in range(3)]
    scene = Scene(scene_from_dict({"sim": {"frame_dt": 0.01, "sleep": True},
                                   "body": [{"name": "ground", "kind": "static", "shape": "ground"}] + boxes},
                                  name="stack"), rules=rules)
    places = scene.vertices().copy()
    for k, body in enumerate(scene.model.bodies[1:]):
        places[body.vertex_start:body.vertex_start + body.vertex_count, 1] -= 1e-5 * (k + 1)
    scene.step(60)
    x = scene.vertices()
    return {"off_place": np.abs(x - places).max(), "penetration": scene.penetration(x),
            "asleep": len(scene.sleeping_bodies())}


@pytest.fixture(scope="module")
def stack_of_three_boxes():
    return three_box_stack(rules_under_test())


def test_carried_hold_keeps_a_landed_stack_of_boxes_in_place():
    """carried_hold: where no gap rows are made (the grid broad phase of larger scenes; here
    the all-pairs path with that rule off), each box of the three-box stack rests within 1e-5 m
    of its place (seen: 9.1 µm). Without the rule the rows carried from the landing corners
    push the boxes sideways: the top one rests 0.12 mm off. (With gap rows the three land
    together and rest 10 µm off with the rule or 9 µm without; the ten-box stack 25 µm with
    it, 50 µm without.)"""
    stack = three_box_stack(dataclasses.replace(rules_under_test(), gap_rows=False))
    assert stack["asleep"] == 3
    assert stack["off_place"] < 1e-5


def test_near_vertex_lets_a_landed_stack_of_boxes_rest_without_overlap(stack_of_three_boxes):
    """near_vertex: the three-box stack rests with at most 1e-9 m³ of overlap, the target of
    issue 34 (seen: 1.8e-13 m³, 3e-10 m deep). Without the rule the corner rows run out of
    budget as the boxes tilt: they rest 6.4 µm and 5e-7 m³ into each other."""
    assert stack_of_three_boxes["penetration"].volume <= 1e-9
    assert stack_of_three_boxes["penetration"].depth <= 1e-7


def test_moving_exit_lets_the_pyramid_rest_without_overlap():
    """moving_exit: the built-in pyramid (fifteen 0.4 × 0.2 × 0.4 m boxes in rows of 5-4-3-2-1,
    side faces touching, rows 1e-5 m apart) is asleep after 0.5 s with at most 1e-9 m³ of
    overlap, the target of issue 34 (seen: 3.0e-10 m³, 1.5e-7 m deep). Without the rule, rows
    whose depth was measured past a lower box's side face, just under its top edge, pushed
    boxes sideways into their neighbours: 2.2e-9 m³ and 2.3e-7 m at rest, 1.5e-8 m³ on the way."""
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    scene = Scene(builtin_scene("pyramid"), rules=rules_under_test())
    scene.step(50)
    assert len(scene.sleeping_bodies()) == 15
    assert scene.penetration().volume <= 1e-9


def test_support_pass_rests_the_ten_box_stack_without_overlap():
    """support_pass: the built-in ten-box stack (0.4 × 0.2 × 0.4 m boxes of one footprint, 1e-5 m
    apart) is asleep after 0.5 s, the boxes at most 1e-7 m and 1e-9 m³ into each other (seen:
    none). Without the rule, the island's 16 + 16 sweeps a substep do not carry the upper
    boxes' weight down to the ground: the boxes fall asleep 1.9e-5 m and 1.3e-6 m³ into each
    other (the pyramid of the test above: 5.6e-7 m, 7.9e-9 m³)."""
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    scene = Scene(builtin_scene("stack"), rules=rules_under_test())
    scene.step(50)
    assert len(scene.sleeping_bodies()) == 10
    penetration = scene.penetration()
    assert penetration.depth <= 1e-7 and penetration.volume <= 1e-9


def test_gap_rows_land_the_ten_box_stack_in_its_places():
    """gap_rows: the built-in ten-box stack (boxes of one footprint set 1e-5 m apart) lands in
    its first 0.3 s with no box vertex more than 5e-5 m from its place (where it was set,
    lowered by the gaps under it; seen: 2.6e-5 m) and no box more than 1e-5 m into another at
    any frame's end (seen: 4.7e-8 m). Without the rule only the box whose gap the detection had
    seen close was stopped in a substep, stopping it pushed it into the next, still falling,
    and each box landed deeper than the one below (0.14 mm within the first frame; 1.1e-4 m
    at its end), the deep side-face crossings pushing the boxes 0.1 mm sideways."""
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    scene = Scene(builtin_scene("stack"), rules=rules_under_test())
    start = scene.vertices().copy()
    places = start.copy()
    for k, body in enumerate(scene.model.bodies[1:]):
        places[body.vertex_start:body.vertex_start + body.vertex_count, 1] -= 1e-5 * (k + 1)
    deepest = 0.0
    for _ in range(30):
        scene.step(1)
        deepest = max(deepest, scene.penetration().depth)
    assert deepest <= 1e-5
    assert np.abs(scene.vertices() - places).max() <= 5e-5


def test_surface_points_hold_a_box_resting_on_a_free_box():
    """surface_points (grazing rows between moving bodies, held on the surface): a 1 m box set
    0.1 mm above a free box of its size, 0.2 m off centre and turned 7°, comes to rest: over the
    second half of 0.6 s the kinetic energy stays below 1e-4 J and no vertex has moved 1 mm.
    Without the rule, pairs of the boxes' side faces measured from one box's corner push the
    upper box sideways every substep: it jitters with ~9 J and moves 4 cm."""
    result = run([{"name": "ground", "kind": "static", "shape": "ground"},
                  {"name": "low", "kind": "rigid", "shape": "box", "position": [0.0, 0.5, 0.0]},
                  {"name": "top", "kind": "rigid", "shape": "box", "position": [0.2, 1.5001, 0.0],
                   "rotation": [0.0, 7.0, 0.0]}], frames=60)
    assert result["energy"] < 1e-4
    assert result["moved"] < 1e-3


def test_carried_rows_hold_a_spike_lying_on_both_rims_of_a_groove():
    """carried_rows: a spike at rest lying along a groove on both of its rims (the pose it came
    to rest in, tests/data/spike_on_groove_rims.obj) stays at rest: over the second half of 0.4 s
    its kinetic energy stays below 1e-9 J and it goes no deeper than 1 µm into the block.
    Without the rule, detection finds only the rim the predicted pose crosses; pushed off it, the
    spike ends each substep inside the other rim and rocks between them with ~4 J, 70 µm deep."""
    result = run([{"name": "crack", "kind": "static", "shape": "crack_block"},
                  {"name": "spike", "kind": "rigid", "mesh": str(DATA / "spike_on_groove_rims.obj")}], frames=40)
    assert result["energy"] < 1e-9
    assert result["depth"] < 1e-6


def test_edge_edge_normal_pushes_crossed_ridges_straight_apart():
    """edge_edge_normal: two wedges whose ridges cross at right angles, 1 mm into each other
    (the upper one upside down), are pushed apart along the ridges' common normal (±y), the
    direction that parts two crossing edges by the least motion. Without the rule each row
    pushes along one face's normal, (±0.89, 0.45, 0): sideways as much as apart, which slid a
    wedge leaning on a block's edge off it."""
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    wedge = {"base": 1.0, "height": 1.0, "length": 2.0}
    bodies = [{"name": "upper", "kind": "rigid", "shape": "wedge", "params": wedge,
               "position": [0.0, 2.0 - 1e-3, 0.0], "rotation": [180.0, 90.0, 0.0]},
              {"name": "lower", "kind": "static", "shape": "wedge", "params": wedge}]
    scene = Scene(scene_from_dict({"body": bodies}, name="ridges"), rules=rules_under_test())
    rows = scene.solver.contact_rows(h=0.01 / 12)
    pushing = rows["depth"] > 0.0
    assert pushing.sum() >= 2
    np.testing.assert_allclose(np.abs(rows["normal"][pushing]), [[0.0, 1.0, 0.0]] * int(pushing.sum()), atol=1e-12)
    # Each row's point lies on a ridge, within a few millimetres of where they cross.
    assert np.abs(rows["point"][pushing] - [0.0, 0.9995, 0.0]).max() < 3e-3


def test_vertex_rows_hold_every_sunk_corner_of_a_pyramid_base():
    """vertex_rows: a square pyramid (0.5 m base, 0.4 m high) set with its base 1 mm into a
    block whose top is split into 0.5 m triangles, the base tipped 0.06° so that no two corners
    are equally deep: each of the four sunk corners gets a row pushing it straight up by its own
    depth. Without the rule, the pair of the corner's base triangle with the top triangle under
    it keeps only the pair's deepest point, and the pairs of the corner's side faces with that
    triangle measure how far the triangle reaches behind the side face (less than the corner's
    depth): one corner has no row up. Pushed out over 0.4 s, the pyramid then slides up to
    1.5 mm sideways (0.9 mm with the rule, from those side-face rows)."""
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    block = {"size": [2.0, 1.0, 2.0], "subdivisions": 1}
    bodies = [{"name": "block", "kind": "static", "shape": "box", "params": block, "position": [0.0, -0.5, 0.0]},
              {"name": "pyramid", "kind": "rigid", "shape": "spike", "params": {"base": 0.5, "height": 0.4},
               "position": [0.3, 0.0, 0.2], "rotation": [0.065, 122.36, 0.057]}]
    placed = Scene(scene_from_dict({"body": bodies}, name="pyramid"))
    bodies[1]["position"][1] = -placed.body_vertices("pyramid")[:, 1].min() - 1e-3
    scene = Scene(scene_from_dict({"body": bodies}, name="pyramid"), rules=rules_under_test())
    rows = scene.solver.contact_rows(h=0.01 / 12)
    corners = scene.body_vertices("pyramid")[:4]
    assert (corners[:, 1] < 0.0).all()
    for corner in corners:
        at_corner = np.linalg.norm(rows["point"] - corner, axis=1) < 1e-9
        up = at_corner & (rows["normal"] @ [0.0, 1.0, 0.0] > 1.0 - 1e-12)
        assert up.any(), f"no row pushes the corner at {corner} up"
        np.testing.assert_allclose(rows["depth"][up], -corner[1], rtol=1e-9)


def test_opposed_rows_let_a_turned_box_rest_on_a_box_without_sinking():
    """opposed_rows: a 1 × 0.2 × 1 m box set 0.1 mm above a free box of its size on the ground,
    turned 15° about the vertical, comes to rest with no overlap deeper than 1 µm after 0.6 s
    (seen: none). Where its bottom edges cross the lower box's top edges, the two boxes' side
    faces give rows pushing about opposite ways; without the rule both are carried into every
    later substep, undo each other in the sweeps, and the boxes end 12 µm into each other."""
    result = run([box("ground", (4.0, 1.0, 4.0), (0.0, -0.5, 0.0), "static"),
                  box("lower", (1.0, 0.2, 1.0), (0.0, 0.1, 0.0)),
                  box("upper", (1.0, 0.2, 1.0), (0.0, 0.3 + 1e-4, 0.0), rotation=[0.0, 15.0, 0.0])], frames=60)
    assert result["depth"] < 1e-6
