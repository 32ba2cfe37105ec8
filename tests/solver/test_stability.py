"""Stability at the extremes: Erleben's scenes scaled by 1e-3 and 1e3, mass ratios of
1000, fast drops, a long rest, bodies touching or with coincident faces at the start,
and sliver triangles inside a mesh. Each test asserts the outcome, judged by the
independent penetration measure where penetration is the question."""

import csv
import json

import numpy as np
import pytest
import trimesh

from taichi_dcd.scene.builtin import ERLEBEN_SIX, builtin_scene
from taichi_dcd.cli import main
from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.measure.penetration import verdict
from taichi_dcd.output.run import run_scene
from taichi_dcd.scene.scene import Scene

# Frames (0.01 s each at scale 1) through the first contact's aftermath, compared between
# scales; later, rounding differences grow wherever a body balances on an edge or apex.
FRAMES_COMPARED = 25


def csv_rows(folder) -> np.ndarray:
    with open(folder / "metrics.csv", newline="") as fh:
        return np.array([[float(x) for x in row] for row in list(csv.reader(fh))[1:]])


# Scaled runs whose verdict differs, with the reason (strict: a pass must update this).
SCALE_FAILURES: dict = {}


@pytest.mark.slow
@pytest.mark.parametrize("name, scale", [
    pytest.param(n, s, marks=pytest.mark.xfail(strict=True, reason=SCALE_FAILURES[n, s])) if (n, s) in SCALE_FAILURES
    else (n, s) for n in ERLEBEN_SIX for s in (1e-3, 1e3)])
def test_scaled_scene_gives_the_same_verdict_and_motion(scene_run, name, scale):
    """Lengths ×L and times ×√L: the same verdict (passing, or failing on the same
    criterion), and frame by frame through the first contact, depths ×L and kinetic
    energies ×L⁴ within 1% of their largest value (spikes and spike-in-crack agree to
    ~1e-11; where a pair only touches, rounding decides whether it becomes a contact, and
    spike-and-wedge parts by ~0.5% from frame 18)."""
    base, scaled = scene_run(name), scene_run(name, scale)
    assert scaled["complete"] and base["complete"]
    reason_base, reason_scaled = verdict(base), verdict(scaled, scale)
    assert (reason_base is None) == (reason_scaled is None), (reason_base, reason_scaled)
    if reason_base:
        assert reason_base.split()[:2] == reason_scaled.split()[:2], (reason_base, reason_scaled)
    a, b = csv_rows(base["out"])[:FRAMES_COMPARED], csv_rows(scaled["out"])[:FRAMES_COMPARED]
    np.testing.assert_allclose(b[:, 1] / scale, a[:, 1], rtol=0, atol=1e-2 * max(a[:, 1].max(), 1e-12))
    np.testing.assert_allclose(b[:, 3] / scale ** 4, a[:, 3], rtol=0, atol=1e-2 * a[:, 3].max())


def run_table(table: dict, out, name: str = "scene") -> dict:
    scene = Scene(scene_from_dict(table, name=name))
    return dict(run_scene(scene, out, progress=None, notices=None), scene=scene)


def spike_on_wedge(spike_density: float, wedge_density: float) -> dict:
    """A free wedge standing ridge up on the ground and a spike dropped apex down 1e-4
    above its ridge, 1% off centre."""
    return {"sim": {"frames": 300}, "body": [
        {"name": "ground", "kind": "static", "shape": "ground"},
        {"name": "wedge", "kind": "rigid", "shape": "wedge", "density": wedge_density},
        {"name": "spike", "kind": "rigid", "shape": "spike", "density": spike_density,
         "rotation": [180.0, 0.0, 0.0], "position": [0.01, 6.0001, 0.0]}]}


@pytest.mark.slow
@pytest.mark.parametrize("spike_density, wedge_density", [(1e6, 1e3), (1e3, 1e6)])
def test_mass_ratio_of_a_thousand_neither_penetrates_nor_explodes(f64_scene, tmp_path, spike_density, wedge_density):
    """A spike 1000× denser than the free wedge it lands on, and the reverse, at the default
    settings: the spike slides off the ridge onto the ground; nothing sinks into anything
    (shock propagation holds the light wedge still under the heavy spike) and no energy is
    gained. Before the static blocks the spike lay on its face with 6e-8 m³ of overlap at 8
    sweeps (a strict expected failure; 16 sweeps passed)."""
    m = run_table(spike_on_wedge(spike_density, wedge_density), tmp_path)
    assert m["complete"] and not m["nan_detected"]
    assert m["max_penetration_depth"] <= 5e-3
    assert m["final_penetration_depth"] <= 1e-4 and m["final_overlap_volume"] <= 1e-9
    assert m["energy_drift"] <= 0.01
    wedge = m["scene"].body_vertices("wedge")
    assert wedge[:, 1].min() >= -1e-4  # the wedge is not driven into the ground


def spike_thrown_into_crack(speed: float) -> dict:
    """The spike-in-crack scene with the apex at the block's top (0.5 m above the groove
    bottom) and thrown down at `speed` m/s, still sliding at 1 m/s."""
    body = {"name": "spike", "kind": "rigid", "shape": "spike", "rotation": [180.0, 0.0, 0.0],
            "position": [0.0, 4.0, 0.0], "velocity": [1.0, -speed, 0.0]}
    return {"sim": {"frame_dt": 0.01, "frames": 500, "stop_when_settled": True}, "body": [
        {"name": "ground", "kind": "static", "shape": "ground"},
        {"name": "crack_block", "kind": "static", "shape": "crack_block"}, body]}


@pytest.mark.slow
@pytest.mark.parametrize("speed", [1.0, 10.0, 50.0])
def test_spike_thrown_into_the_crack_never_tunnels(f64_scene, tmp_path, speed):
    """At 50 m/s the spike would move 5 cm per substep, a tenth of the thinnest body: no
    tunnel, but a 5 cm deep landing. The frames near the block run more substeps, so the
    landing stays within 5 mm at every speed, and the spike settles outside the block and
    above the ground, with no overlap."""
    m = run_table(spike_thrown_into_crack(speed), tmp_path)
    assert m["complete"] and m["settled"]
    assert m["final_penetration_depth"] <= 1e-4 and m["final_overlap_volume"] <= 1e-9
    spike = m["scene"].body_vertices("spike")
    assert spike[:, 1].min() >= -1e-4
    assert m["max_penetration_depth"] <= 5e-3
    if speed >= 10.0:
        assert m["most_substeps_in_a_frame"] >= speed * 0.01 / 2e-3


def plates(speed: float) -> dict:
    """A 1 cm plate thrown flat at `speed` m/s onto a static 1 cm plate 1 m below."""
    return {"sim": {"frames": 100, "stop_when_settled": True}, "body": [
        {"name": "floor_plate", "kind": "static", "shape": "box", "params": {"size": [2.0, 0.01, 2.0]}},
        {"name": "plate", "kind": "rigid", "shape": "box", "params": {"size": [1.0, 0.01, 1.0]},
         "position": [0.0, 1.0, 0.0], "velocity": [0.0, -speed, 0.0]}]}


@pytest.mark.slow
def test_thin_plate_too_fast_for_the_substeps_gets_more_substeps(f64_scene, tmp_path):
    """At 50 m/s a 1 cm plate would cross a 1 cm plate within one of the 10 substeps: the
    frames that fast run more substeps, and the plate lands on the other, not through it."""
    m = run_table(plates(50.0), tmp_path)
    assert m["complete"]
    assert m["frames_with_extra_substeps"] >= 1 and m["most_substeps_in_a_frame"] >= 100
    plate = m["scene"].body_vertices("plate")
    assert plate[:, 1].min() >= 0.005 - 1e-4          # on top of the static plate (top at y = 0.005)
    assert m["final_penetration_depth"] <= 1e-4


def test_body_too_fast_even_for_more_substeps_stops_with_the_setting_that_fixes_it(tmp_path, capsys):
    (tmp_path / "fast.toml").write_text(
        '[sim]\nframes = 5\n[[body]]\nname = "floor_plate"\nkind = "static"\nshape = "box"\n'
        'params = {size = [2.0, 0.01, 2.0]}\n[[body]]\nname = "plate"\nkind = "rigid"\nshape = "box"\n'
        'params = {size = [1.0, 0.01, 1.0]}\nposition = [0.0, 100.0, 0.0]\nvelocity = [0.0, -5000.0, 0.0]\n')
    status = main(["run", str(tmp_path / "fast.toml"), "--no-frames", "--quiet", "--out", str(tmp_path / "out")])
    assert status == 1
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert "frame 1: body 'plate' moves" in last and "--substeps" in last, last
    assert json.loads((tmp_path / "out" / "metrics.json").read_text())["complete"] is False


LONG_REST_SUBSTEPS = 100_000

# The spike of `spike-in-crack` does not stay in the groove (sliding at 1 m/s, it tips out and
# ends leaning on the block's edge); this one lies in it from the start.
LYING_IN_THE_CRACK = {"sim": {"frame_dt": 0.01}, "body": [
    {"name": "ground", "kind": "static", "shape": "ground"},
    {"name": "crack_block", "kind": "static", "shape": "crack_block"},
    {"name": "dropped_spike", "kind": "rigid", "shape": "spike", "rotation": [90.0, 0.0, 45.0],
     "position": [0.0, 1.2, -1.0]}]}


@pytest.mark.slow
@pytest.mark.parametrize("table", [pytest.param(LYING_IN_THE_CRACK, id="lying-in-the-groove"),
                                   pytest.param(None, id="spike-in-crack")])
def test_long_rest_in_the_crack_neither_drifts_nor_gains_energy(f64_scene, table):
    """A spike at rest in the crack, then 100,000 substeps more (none added for landing): it
    moves less than 1e-6 m, its kinetic energy stays at round-off, and its potential energy
    rises by less than lifting it 1e-7 m would add. Two rests: a spike lying along the
    groove on both rims (dropped from 1.3 cm, at rest after 3 s), and `spike-in-crack`'s
    spike after 2 s, toppled and leaning on the block's edge (it crept 4.4e-4 m at the default
    8 sweeps before the static blocks, a strict expected failure)."""
    scene = Scene(scene_from_dict(table, name="lying") if table else builtin_scene("spike-in-crack"))
    scene.step(300 if table else 200)
    start = scene.body_vertices("dropped_spike")
    energy = scene.kinetic_energy() + scene.potential_energy()
    before = scene.solver.state.substeps_done  # the landing frames took extra substeps
    frames = -(-LONG_REST_SUBSTEPS // scene.config.sim.substeps)
    scene.step(frames)
    assert scene.solver.state.substeps_done - before == frames * scene.config.sim.substeps  # resting takes none
    assert np.abs(scene.body_vertices("dropped_spike") - start).max() < 1e-6
    weight = scene.model.bodies[scene.model.body_index("dropped_spike")].mass * 9.8
    assert scene.kinetic_energy() < 1e-12
    assert scene.kinetic_energy() + scene.potential_energy() - energy < weight * 1e-7
    assert scene.penetration().depth <= 1e-4


def box_on(support: dict, size=(1.0, 1.0, 1.0), gap: float = 0.0, mesh: str | None = None) -> dict:
    box = {"name": "box", "kind": "rigid", "position": [0.0, 0.5 * size[1] + gap, 0.0]}
    box.update({"mesh": mesh} if mesh else {"shape": "box", "params": {"size": list(size)}})
    return {"sim": {"frames": 100}, "body": [support, box]}


GROUND = {"name": "ground", "kind": "static", "shape": "ground"}
SAME_FOOTPRINT = {"name": "block", "kind": "static", "shape": "box", "params": {"size": [1.0, 1.0, 1.0]},
                  "position": [0.0, -0.5, 0.0]}


@pytest.mark.slow
@pytest.mark.parametrize("support", [GROUND, SAME_FOOTPRINT], ids=["touching", "coincident-faces"])
def test_box_touching_at_the_start_stays_put(f64_scene, tmp_path, support):
    """A box whose bottom face lies exactly on the support at t = 0 (on a large ground,
    or on a block with the very same face, edges on edges) stays where it is, within
    1e-5 of its size (the resting tolerance of the solver tests): no jump, no sinking,
    no spin, no slide. On the block, until resting rows on the block's surface and rows
    that only touch were left out (add_pair_contact), rows along the side faces' normals
    pushed the box 0.15 mm sideways and tilted it by 4e-5 m in its first 0.1 s."""
    m = run_table(box_on(support), tmp_path)
    box = m["scene"].body_vertices("box")
    assert m["complete"]
    assert abs(box[:, 1].min()) < 1e-5 and abs(box[:, 1].max() - 1.0) < 1e-5
    assert np.abs(box[:, [0, 2]]).max() < 0.5 + 1e-5
    assert m["max_penetration_depth"] <= 1e-5
    assert m["final_max_vertex_speed"] < 1e-4


def test_box_resting_on_a_free_box_holds_still(f64_scene, tmp_path):
    """A box set 0.1 mm above a free box of its size on the ground, 0.2 m off centre and
    turned 7° about the vertical: both come to rest (every vertex below 1e-3 m/s, the
    settle speed) where they were set, neither sinking into the other, and by the end
    not inside each other (within 1e-8 m: the two boxes' rows are solved as one block,
    solve_blocks; projected one at a time they kept 2.9e-7 m)."""
    m = run_table({"sim": {"frames": 60}, "body": [
        GROUND,
        {"name": "low", "kind": "rigid", "shape": "box", "position": [0.0, 0.5, 0.0]},
        {"name": "top", "kind": "rigid", "shape": "box", "position": [0.2, 1.5001, 0.0],
         "rotation": [0.0, 7.0, 0.0]}]}, tmp_path)
    scene = m["scene"]
    assert m["complete"]
    assert m["final_max_vertex_speed"] < 1e-3
    assert m["max_penetration_depth"] <= 1e-5
    assert m["final_penetration_depth"] <= 1e-8
    low, top = scene.body_positions()[1:]
    np.testing.assert_allclose(low, [0.0, 0.5, 0.0], atol=1e-5)
    np.testing.assert_allclose(top, [0.2, 1.5, 0.0], atol=2e-4)


def test_a_resting_box_sleeps_and_wakes_when_another_lands_on_it(f64_scene):
    """sim.sleep: a box resting on the ground falls asleep once it has been calm for 0.5 s, and
    holds still; a box dropped onto it wakes it before they touch, so the landing is the same as
    without sleeping (both boxes' heights within 1e-7 m through the impact: the same bits up to
    it, but the woken box starts without the rows it would have carried awake, and the rows of
    boxes four times each other's mass, which may spend five times their budget
    (islands.load_budget_factor), draw that out to 1.5e-9 m; rows between the moving boxes that
    leave through a neighbour's face (rule moving_exit), a choice so small a difference can
    flip, to 7.5e-8 m two frames after the impact; woken only on touching, the lower box was
    pushed into the ground without its rows and jumped 5 mm), and the two then rest and sleep
    together, 0.3 m apart as set."""
    bodies = [GROUND,
              {"name": "low", "kind": "rigid", "shape": "box", "params": {"size": [0.4, 0.2, 0.4]},
               "position": [0.0, 0.1001, 0.0]},
              {"name": "drop", "kind": "rigid", "shape": "box", "params": {"size": [0.2, 0.2, 0.2]},
               "position": [0.1, 10.4, 0.05]}]
    runs = {}
    for sleep in (False, True):
        scene = Scene(scene_from_dict({"sim": {"sleep": sleep}, "body": bodies}, name="sleep"))
        heights, asleep = [], []
        for _ in range(160):
            scene.step(1)
            heights.append(scene.body_positions()[1:, 1].copy())
            asleep.append(scene.sleeping_bodies())
        runs[sleep] = (scene, np.array(heights), asleep)
    scene, heights, asleep = runs[True]
    assert asleep[40] == [] and asleep[60] == ["low"]           # calm from ~0.05 s, asleep by 0.6 s
    assert np.all(heights[60:140, 0] == heights[60, 0])          # asleep: not one bit of motion
    impact = int(np.argmax(np.diff(runs[False][1][:, 1]) > 0))   # the frame the drop stopped falling
    assert "low" not in asleep[impact]
    np.testing.assert_allclose(heights[impact - 5:impact + 10], runs[False][1][impact - 5:impact + 10], atol=1e-7)
    scene.step(80)
    assert scene.sleeping_bodies() == ["low", "drop"]
    np.testing.assert_allclose(scene.body_positions()[1:, 1], [0.1, 0.3], atol=1e-5)
    assert scene.penetration().depth <= 1e-5


def leaning_slab_on_a_chip(loads: int, slab_over_chip: float = 40.0) -> list[dict]:
    """A 0.1 x 0.04 x 0.1 m chip on the ground and a 0.4 x 0.1 x 0.4 m slab (`slab_over_chip`
    times its mass: 40 at equal densities) leaning on it: one bottom edge on the ground at
    x = -0.25 m, the bottom face on the chip's near top edge; `loads` more slabs stacked flush
    on the leaning one, each 1 µm above it."""
    import math
    tilt = math.atan(0.04 / 0.35)
    corner = np.array([-0.25, 0.0])
    turn = np.array([[math.cos(tilt), -math.sin(tilt)], [math.sin(tilt), math.cos(tilt)]])
    bodies = [dict(GROUND, params={"size": [4.0, 1.0, 4.0]}),
              {"name": "chip", "kind": "rigid", "shape": "box", "params": {"size": [0.1, 0.04, 0.1]},
               "position": [0.15, 0.02, 0.0], "density": 1000.0 * 40.0 / slab_over_chip}]
    for k in range(loads + 1):
        x, y = corner + turn @ np.array([0.2, 0.05 + 0.1 * k])
        bodies.append({"name": f"slab{k}", "kind": "rigid", "shape": "box", "params": {"size": [0.4, 0.1, 0.4]},
                       "position": [float(x), float(y) + 1e-6 * (k + 1), 0.0],
                       "rotation": [0.0, 0.0, math.degrees(tilt)]})
    return bodies


@pytest.mark.parametrize("slab_over_chip", [40.0, 6.0])
def test_light_chip_under_a_loaded_leaning_slab_stays_on_the_ground(f64_scene, slab_over_chip):
    """The chip, the leaning slab (40 or 6 times the chip's mass) and two slabs on it, 0.6 s:
    the chip stays on the ground (its lowest vertex above -1e-5 m), nothing ends deeper in
    anything than 1e-4 m, and the slabs stay where they were set (0.1 mm). The slab rests on
    the ground too, so the chip and it are on the same contact level and shock propagation
    does not hold the chip still. At 40 times: before the rows of such an island held the depth
    they may leave (islands.leaves_depth), the chip's rows against the ground spent their
    budget pushing back each substep and the slab drove the chip into the ground: 8 mm at
    0.1 s, 3.6 cm at 0.6 s. At 6 times (below that rule's ratio): before the rows of loaded
    bodies could spend more of their budget (islands.load_budget_factor), the slab ended
    3.9 mm deep in the chip."""
    bodies = leaning_slab_on_a_chip(loads=2, slab_over_chip=slab_over_chip)
    scene = Scene(scene_from_dict({"sim": {"frames": 60, "sleep": False}, "body": bodies}, name="lean"))
    start = scene.body_positions()[2:].copy()
    scene.step(60)
    x = scene.vertices()
    chip = scene.model.bodies[1]
    assert x[chip.vertex_start:chip.vertex_start + chip.vertex_count, 1].min() >= -1e-5
    assert scene.penetration(x).depth <= 1e-4
    np.testing.assert_allclose(scene.body_positions()[2:], start, atol=1e-4)


@pytest.mark.slow
def test_stack_of_five_boxes_holds_still(f64_scene, tmp_path):
    """Five unit boxes stacked 0.1 mm apart, each 5 cm further along x and turned 7° more
    about the vertical than the one below: no box is inside another by more than Erleben's
    final-depth limit (1e-4 m) as they land; from 1 s to 2 s no vertex moves by more than
    5 µm, and at 2 s every vertex is below a tenth of the settle speed (1e-4 m/s), no box
    moved sideways by more than 0.1 mm. Before the grazing rows between moving bodies were
    held on the surface (add_pair_contact) the stack jittered at 0.04-0.16 m/s; before the
    boxes' rows were solved as one block (solve_blocks) it shifted ~0.2 mm as it landed and
    crept on at 3-6e-5 m/s. Awake, it still creeps a little: 3.5 µm from 1 s to 2 s at
    COUPLED_SWEEPS = 16 with the support pass (3.3 µm without the pass; 6.8 µm at 32 with
    it; 3.0 µm with 64 friction sweeps). Below 1 µm it held only at 128 sweeps, without the
    pass: 15 and 55 µm at 64 and 32 then. (The stacks of the built-in scenes sleep.)"""
    n = 5
    boxes = [{"name": f"box{k}", "kind": "rigid", "shape": "box",
              "position": [0.05 * k, 0.5 + k * 1.0001 + 1e-4, 0.0], "rotation": [0.0, 7.0 * k, 0.0]}
             for k in range(n)]
    m = run_table({"sim": {"frames": 100, "stop_when_settled": False}, "body": [GROUND] + boxes}, tmp_path)
    assert m["complete"]
    assert m["max_penetration_depth"] <= 1e-4
    scene = m["scene"]
    at_one_second = scene.vertices()
    scene.step(99)
    before_last = scene.vertices()
    scene.step(1)
    at_two_seconds = scene.vertices()
    assert scene.time == pytest.approx(2.0)
    assert np.linalg.norm(at_two_seconds - at_one_second, axis=1).max() < 5e-6
    last_speed = np.linalg.norm(at_two_seconds - before_last, axis=1).max() / scene.config.sim.frame_dt
    assert last_speed < 1e-4
    assert scene.penetration(at_two_seconds).depth <= 1e-4
    pos = scene.body_positions()[1:]
    np.testing.assert_allclose(pos[:, [0, 2]], [[0.05 * k, 0.0] for k in range(n)], atol=1e-4)
    np.testing.assert_allclose(pos[:, 1], 0.5 + np.arange(n), atol=1e-4)


@pytest.mark.slow
def test_box_on_a_block_of_the_same_footprint_does_not_sink_through(f64_scene, tmp_path):
    """Every triangle pair of a box set exactly on a block of its own footprint only
    touches (its side faces lie in the block's side planes); without the solver's
    touching-pair contacts it fell through the block in free fall."""
    m = run_table(box_on(SAME_FOOTPRINT), tmp_path)
    box = m["scene"].body_vertices("box")
    assert m["complete"]
    assert box[:, 1].min() > -1e-4
    assert m["max_penetration_depth"] <= 1e-4


@pytest.mark.slow
def test_sliver_triangles_in_the_contact_face_are_harmless(f64_scene, tmp_path):
    """A box whose bottom face is fanned around a point 1e-12 from one edge, so that one
    triangle has ~1e-12 of the mean triangle area: dropped flat from 1 mm it settles flat
    on the ground without penetrating."""
    box = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    v = np.asarray(box.vertices)
    keep = [f for f in np.asarray(box.faces) if not np.allclose(v[f][:, 1], -0.5)]
    corners = [int(i) for i in np.flatnonzero(np.isclose(v[:, 1], -0.5))]
    ring = sorted(corners, key=lambda i: np.arctan2(v[i, 2], v[i, 0]))    # counter-clockwise seen from +y
    a, b = v[ring[0]], v[ring[1]]
    midpoint, centre = 0.5 * (a + b), np.array([0.0, -0.5, 0.0])
    inner = midpoint + 1e-12 * (centre - midpoint) / np.linalg.norm(centre - midpoint)  # just inside edge ab
    v = np.vstack([v, inner])
    centre = len(v) - 1
    fan = np.array([[ring[k], ring[(k + 1) % 4], centre] for k in range(4)])
    mesh = trimesh.Trimesh(v, np.vstack([keep, fan]), process=False)
    if not mesh.is_winding_consistent:
        mesh = trimesh.Trimesh(v, np.vstack([keep, fan[:, ::-1]]), process=False)
    assert mesh.volume > 0
    areas = mesh.area_faces
    assert mesh.is_watertight and areas.min() < 1e-11 * areas.mean()
    (tmp_path / "sliver_box.obj").write_text(trimesh.exchange.obj.export_obj(mesh, digits=17))
    table = box_on(GROUND, gap=1e-3, mesh=str(tmp_path / "sliver_box.obj"))
    table["sim"]["frames"] = 60
    m = run_table(table, tmp_path / "out")
    assert m["complete"] and not m["nan_detected"]
    box_v = m["scene"].body_vertices("box")
    assert abs(box_v[:, 1].min()) < 1e-4 and abs(box_v[:, 1].max() - 1.0) < 1e-4   # flat on the ground
    assert m["final_penetration_depth"] <= 1e-4 and m["max_penetration_depth"] <= 1e-3


def test_f32_warns_where_it_cannot_resolve_the_scene(tmp_path, capsys):
    """In f32 the spike in the crack (|x| ≤ 3.5 m, 1 ms substeps) carries ~4e-4 m/s of
    rounding noise, half the settle speed: it never settles in 5 s. The run says so and
    names the fix; the same run in f64 has no warning."""
    out = str(tmp_path / "f32")
    assert main(["run", "spike-in-crack", "--precision", "f32", "--frames", "2", "--no-frames", "--quiet",
                 "--out", out]) == 0
    err = capsys.readouterr().err
    assert "taichi-dcd: warning: f32 resolves positions here only to 4.2e-07 m (coordinates up to 3.5 m)" in err, err
    assert "use --precision f64" in err
    assert main(["run", "spike-in-crack", "--frames", "2", "--no-frames", "--quiet", "--out", str(tmp_path / "f64")]) == 0
    assert "warning" not in capsys.readouterr().err
