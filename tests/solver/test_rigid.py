"""XPBD rigid bodies against answers known in advance: free fall, resting contact,
Coulomb friction on an incline, momentum conservation, and a tilted box settling flat.

The free collision runs in Taichi's debug mode (bounds checks through the frame kernel,
contacts included); the others run without it (`f64_scene`): each debug-mode scene
compiles its kernel for ~45 s here."""

import math

import numpy as np
import pytest

from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene, quat_to_matrix

G = 9.8


def make_scene(bodies, broad_phase="auto", **sim) -> Scene:
    return Scene(scene_from_dict({"sim": sim, "body": bodies}, name="test"), broad_phase=broad_phase)


def box(name, size, position, kind="rigid", **extra):
    return {"name": name, "kind": kind, "shape": "box", "params": {"size": list(size)},
            "position": list(position), **extra}


def rotation_angle(q) -> float:
    """Angle (rad) of the rotation of unit quaternion q = (w, x, y, z)."""
    return 2.0 * math.acos(min(1.0, abs(q[0])))


def test_free_fall_follows_the_parabola_exactly(f64_scene):
    """No contacts: x(t) = x0 + v0·t + g·t²/2 to 1e-9 m, and the rotation stays identity."""
    x0, v0 = np.array([0.1, 2.0, -0.3]), np.array([0.5, 3.0, -1.0])
    scene = make_scene([box("b", (0.2, 0.3, 0.4), x0, velocity=list(v0))], gravity=[0.0, -G, 0.0])
    for _ in range(5):
        scene.step(10)
        t = scene.time
        expected = x0 + v0 * t + 0.5 * np.array([0.0, -G, 0.0]) * t * t
        np.testing.assert_allclose(scene.body_positions()[0], expected, rtol=0, atol=1e-9)
        np.testing.assert_allclose(scene.body_rotations()[0], [1.0, 0.0, 0.0, 0.0], atol=1e-12)


def test_box_dropped_flat_rests_on_the_block_without_drift(f64_scene):
    """A 0.2 m box dropped 5 cm onto a static block comes to rest with its bottom face on the
    block's top face (within 1e-5 of its size), unrotated, then holds still for 1,000 frames:
    moves less than 1e-5 of its size and keeps its kinetic energy below 1e-8 of the impact energy."""
    size, gap = 0.2, 0.05
    scene = make_scene([box("box", (size,) * 3, (0.0, size / 2 + gap, 0.0)),
                        box("block", (2.0, 0.2, 2.0), (0.0, -0.1, 0.0), kind="static")])
    impact_energy = 8.0 * G * gap  # m = 1000 kg/m³ · 0.008 m³
    scene.step(100)
    rest = scene.body_positions()[0]
    assert abs(rest[1] - size / 2) <= 1e-5 * size  # bottom face at y = 0, the block's top
    assert rotation_angle(scene.body_rotations()[0]) < 1e-3
    for _ in range(10):
        scene.step(100)
        assert scene.kinetic_energy() < 1e-8 * impact_energy
    assert np.linalg.norm(scene.body_positions()[0] - rest) < 1e-5 * size
    bottom = scene.body_vertices("box")[:, 1].min()
    assert -1e-5 * size <= bottom <= 1e-5 * size


INCLINES = [15.0, 20.0, 25.0, 30.0, 40.0]  # degrees; tan θ = μ = 0.5 at 26.57°


@pytest.fixture(scope="module")
def inclines():
    """One scene with a 0.2 m box resting on a static 6 m plank per angle of INCLINES (about z,
    downhill is -x, μ = 0.5), 2 m apart along z (one kernel to compile, not five). Runs 1 s.
    Returns {angle: (downhill distance at the start, at 1 s, the times and downhill distances
    every 2 frames from 0.12 s to 0.9 s, the box's turn at the end (rad; a body's frame starts
    unrotated))}."""
    import taichi_dcd

    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    bodies = []
    for k, theta_deg in enumerate(INCLINES):
        th = math.radians(theta_deg)
        normal = np.array([-math.sin(th), math.cos(th), 0.0])
        along = np.array([0.0, 0.0, 2.0 * k])
        # The plank is 0.2 thick: its top face passes through the box's line.
        bodies += [box(f"box{k}", (0.2, 0.2, 0.2), (0.1 + 1e-5) * normal + along, rotation=[0.0, 0.0, theta_deg],
                       friction=0.5),
                   box(f"plank{k}", (6.0, 0.2, 1.0), -0.1 * normal + along, kind="static",
                       rotation=[0.0, 0.0, theta_deg], friction=0.5)]
    scene = make_scene(bodies)

    def downhill():
        x = scene.body_positions()[0::2]
        return {a: float(x[k] @ [-math.cos(math.radians(a)), -math.sin(math.radians(a)), 0.0])
                for k, a in enumerate(INCLINES)}

    start = downhill()
    scene.step(10)
    times, series = [], []
    for _ in range(40):
        scene.step(2)
        times.append(scene.time)
        series.append(downhill())
    scene.step(10)
    end = downhill()
    turn = scene.body_rotations()[0::2]
    return {a: (start[a], end[a], np.array(times), np.array([d[a] for d in series]),
                rotation_angle(turn[k])) for k, a in enumerate(INCLINES)}


@pytest.mark.parametrize("theta_deg", [15.0, 20.0, 25.0])
def test_box_stays_on_incline_below_the_friction_angle(inclines, theta_deg):
    """tan θ < μ = 0.5 (θ < 26.57°): static friction holds the box (moves < 0.1 mm in 1 s).
    Seen: 9e-9 m at 22°, 3e-9 m at 25°; at 26°, 0.57° below the friction angle, 4e-5 m."""
    start, end = inclines[theta_deg][:2]
    assert abs(end - start) < 1e-4


@pytest.mark.parametrize("theta_deg", [30.0, 40.0])
def test_box_slides_down_incline_with_coulomb_acceleration(inclines, theta_deg):
    """tan θ > μ = 0.5: the box slides with a = g(sin θ − μ cos θ), within 2%, flat (turning
    less than 0.01 rad)."""
    _, _, times, dist, turn = inclines[theta_deg]
    accel = 2.0 * np.polyfit(times, dist, 2)[0]
    th = math.radians(theta_deg)
    expected = G * (math.sin(th) - 0.5 * math.cos(th))
    assert accel == pytest.approx(expected, rel=0.02)
    assert abs(turn) < 1e-2  # slides flat, does not tumble


def momenta(scene: Scene):
    """Total linear momentum (3,) and angular momentum about the origin (3,) of rigid bodies."""
    m = scene.model
    mass = 1.0 / m.body_inv_mass.to_numpy()[: m.n_bodies]
    inertia = m.body_inertia.to_numpy()[: m.n_bodies]
    x, v, w, q = scene.body_positions(), scene.body_velocities(), scene.body_angular_velocities(), \
        scene.body_rotations()
    p = (mass[:, None] * v).sum(axis=0)
    ang = np.zeros(3)
    for k in range(m.n_bodies):
        r = quat_to_matrix(q[k])
        ang += mass[k] * np.cross(x[k], v[k]) + r @ inertia[k] @ r.T @ w[k]
    return p, ang


def test_free_collision_conserves_linear_and_angular_momentum(f64_then_debug):
    """Two boxes meet off-centre without gravity: the impact turns them (the lighter, flat
    box then tumbles about all three axes), and total linear momentum holds to 1e-9 relative,
    angular momentum about the origin to 1e-6 (seen: 1e-13)."""
    scene = make_scene([
        box("a", (0.2, 0.2, 0.2), (-0.3, 0.05, 0.0), velocity=[2.0, 0.0, 0.0]),
        box("b", (0.3, 0.1, 0.2), (0.3, -0.05, 0.02), velocity=[-1.0, 0.0, 0.0], density=500.0),
    ], gravity=[0.0, 0.0, 0.0])
    p0, l0 = momenta(scene)
    scene.step(40)
    p1, l1 = momenta(scene)
    assert np.linalg.norm(scene.body_angular_velocities()[0]) > 0.1  # the collision did happen off-centre
    assert np.linalg.norm(p1 - p0) <= 1e-9 * np.linalg.norm(p0)
    assert np.linalg.norm(l1 - l0) <= 1e-6 * np.linalg.norm(l0)


TILTED = [box("box", (0.2,) * 3, (0.0, 0.2, 0.0), rotation=[0.0, 0.0, 30.0]),
          box("block", (2.0, 0.2, 2.0), (0.0, -0.1, 0.0), kind="static")]


@pytest.fixture(scope="module")
def tilted_box():
    """A 0.2 m box dropped turned 30° about z onto a block, 200 frames on the all-pairs path:
    the box's vertices after 20, 40, 60 and 80 frames and at the end, and the final kinetic
    energy (one run for the two tests below)."""
    import taichi_dcd

    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    scene = make_scene(TILTED, broad_phase="brute")
    landing = []
    for _ in range(4):
        scene.step(20)
        landing.append(scene.body_vertices("box").copy())
    scene.step(120)
    return {"landing": landing, "final": scene.body_vertices("box").copy(), "energy": scene.kinetic_energy()}


def test_tilted_box_lands_on_an_edge_and_settles_on_a_face(tilted_box):
    """Dropped turned 30° about z, the box lands on an edge, tips over and comes to rest on a
    face: four vertices on the block and four a box height above (within 1e-4 of the size; seen:
    3e-6 m)."""
    size = 0.2
    assert tilted_box["energy"] < 1e-8
    y = np.sort(tilted_box["final"][:, 1])
    assert np.all(np.abs(y[:4]) <= 1e-4 * size)
    # Flat on a face: the other four vertices a box height above (on an edge they would not be).
    assert np.all(np.abs(y[4:] - size) <= 1e-4 * size)


def test_grid_path_moves_the_tilted_box_as_the_all_pairs_path_does(tilted_box):
    """Large scenes run each substep through the uniform grid (with reused candidate pairs,
    touching pairs kept) instead of the in-kernel all-pairs test: the same contacts, so the
    same motion. The tilted box through its landing and tipping, both ways: poses equal to
    1e-9 m (seen: identical to the printed 9 digits)."""
    grid = make_scene(TILTED, broad_phase="grid")
    assert grid.solver.use_grid
    for brute_vertices in tilted_box["landing"]:
        grid.step(20)
        np.testing.assert_allclose(grid.body_vertices("box"), brute_vertices, atol=1e-9)
    assert grid.solver.pipeline.grid.rebuilds < grid.solver.pipeline.grid.queries  # pairs were reused


def test_many_frames_in_one_launch_move_the_bodies_as_frames_stepped_one_by_one(f64_scene):
    """`step(n)` runs the all-pairs frames in one launch, stopping for frames whose substeps
    the device check declines (the landing) and for a contact buffer that overflows (grown,
    the frame rerun). The tilted box thrown down (its landing frames take more substeps),
    with a one-row buffer: the same poses, bit for bit, as 120 single frames, the same
    frame count, time and substep choices."""
    from taichi_dcd.contact.rows import ContactConstraints

    bodies = [box("box", (0.2,) * 3, (0.0, 0.3, 0.0), rotation=[0.0, 0.0, 30.0], velocity=[0.0, -4.0, 0.0]),
              box("block", (2.0, 0.2, 2.0), (0.0, -0.1, 0.0), kind="static")]
    at_once, one_by_one = make_scene(bodies), make_scene(bodies)
    at_once.solver.contacts = ContactConstraints(1)
    at_once.step(120)
    for _ in range(120):
        one_by_one.step(1)
    assert at_once.solver.contact_growths >= 1
    assert one_by_one.fast_frames > 0 and at_once.fast_frames == one_by_one.fast_frames
    assert at_once.frame == one_by_one.frame == 120 and at_once.time == one_by_one.time
    np.testing.assert_array_equal(at_once.body_vertices("box"), one_by_one.body_vertices("box"))
    np.testing.assert_array_equal(at_once.body_velocities(), one_by_one.body_velocities())


@pytest.mark.parametrize("broad_phase", ["brute", "grid"])
def test_wedge_overhanging_a_block_edge_rests(f64_scene, broad_phase):
    """A wedge (scaled 0.3: base 0.3 x 0.6) standing on a block's top face with 0.057 m of its
    base past the block's edge, its centre of mass 0.1 m inside, rests: over 1 s after landing
    it moves less than 1e-5 m and turns less than 1e-4 rad. Gravity sinks it ~1e-5 m a
    substep; its end faces then cross the block's side face, and Eq. 6 on that pair measures
    its inner base vertices 0.24 m behind the side face along a horizontal normal: pushed
    sideways every substep, it crept off the edge at 2.6 cm/s. Such a row now leaves through
    the block's top face, 1e-5 m away (contact.exits.nearest_exit). What is left is a bounded
    rocking of about 1e-6 m, as the support along the block's edge line comes and goes."""
    scene = Scene(scene_from_dict({"sim": {"frame_dt": 0.01}, "body": [
        {"name": "block", "kind": "static", "shape": "box", "params": {"size": [2.0, 1.0, 2.0]},
         "position": [3.0, 0.0, 1.0]},
        {"name": "wedge", "kind": "rigid", "shape": "wedge", "position": [3.9, 0.5, 1.0], "scale": 0.3}]},
        name="overhang"), broad_phase=broad_phase)
    scene.step(10)
    x0, q0 = scene.body_positions()[1].copy(), scene.body_rotations()[1].copy()
    scene.step(100)
    assert np.linalg.norm(scene.body_positions()[1] - x0) < 1e-5
    turn = 2.0 * math.acos(min(1.0, abs(float(np.dot(scene.body_rotations()[1], q0)))))
    assert turn < 1e-4


def lying_spike_scene(broad_phase: str) -> Scene:
    """A spike lying along a crack block's groove, its axis along z and its base square
    turned 45°, dropped from 1.3 cm: its two lower faces (44.3° from horizontal) land on the
    groove's two rims, the edges where the 45° walls meet the block's top."""
    return Scene(scene_from_dict({"sim": {"frame_dt": 0.01}, "body": [
        {"name": "crack", "kind": "static", "shape": "crack_block"},
        {"name": "spike", "kind": "rigid", "shape": "spike", "rotation": [90.0, 0.0, 45.0],
         "position": [0.0, 1.2, -1.0]}]}, name="lying"), broad_phase=broad_phase)


@pytest.mark.slow  # 12 s of rest, both broad phases; its rule's quick test: tests/contact/test_rules.py
@pytest.mark.parametrize("broad_phase", ["brute", "grid"])
def test_spike_lying_across_a_groove_rests_on_both_rims(f64_scene, broad_phase):
    """The lying spike (1000 kg) is held by both rims at once. Detection finds only the rim
    the predicted pose crosses; pushed off it, the spike ended each substep inside the other
    rim, and the next substep pushed it back: it rocked by ~0.15 mm every substep with 3.6 J
    of kinetic energy (at 12 x 8, either broad phase), for good. The last substep's rows are
    now offered again (contact.carried.carried_rows): from 1 s on its kinetic energy stays below
    1e-3 J, and from 11 s it moves less than 1e-5 m in a second, no deeper than 1e-4 m."""
    scene = lying_spike_scene(broad_phase)
    scene.step(100)
    energy = []
    for _ in range(100):
        scene.step(1)
        energy.append(scene.kinetic_energy())
    assert max(energy) < 1e-3
    scene.step(1000)
    x0 = scene.body_vertices("spike").copy()
    scene.step(100)
    assert np.abs(scene.body_vertices("spike") - x0).max() < 1e-5
    assert scene.kinetic_energy() < 1e-6
    assert scene.penetration().depth <= 1e-4


def spike_lying_on_its_face(friction: float = 0.5) -> Scene:
    """A spike on the ground, one side face down (its normal turned to −y, 99.46° about x),
    dropped from 1 mm."""
    return Scene(scene_from_dict({"sim": {"frames": 200}, "body": [
        {"name": "ground", "kind": "static", "shape": "ground", "friction": friction},
        {"name": "spike", "kind": "rigid", "shape": "spike", "friction": friction,
         "rotation": [90.0 + math.degrees(math.atan(1.0 / 6.0)), 0.0, 0.0],
         "position": [0.0, 0.49419696, 0.0]}]}, name="lying"))


def test_spike_lying_on_its_face_rests_on_the_ground_at_the_default_sweeps(f64_scene):
    """A body resting on three points, friction included, at the default 12 x 8: its rows
    against the static ground are solved as one block (solver.islands.solve_blocks).
    Projected one at a time, each push turned the spike and slid the other points for
    friction to undo, and it rested 3.5e-8 m deep (2.4e-9 m³ of overlap; 1.7e-11 m without
    friction). Now it rests on the ground, no deeper than 1e-10 m by the independent
    measure, face flat, still to round-off (kinetic energy seen: 1e-29 J)."""
    scene = spike_lying_on_its_face()
    start = scene.body_vertices("spike")
    scene.step(200)
    spike = scene.body_vertices("spike")
    low = np.sort(spike[:, 1])[:3]
    # The face's corners on the ground: two to round-off, the third within 1e-6 m (seen: 5.9e-7;
    # rows where the face's edges cross the ground's triangles share the support).
    assert np.abs(low).max() <= 1e-6
    assert np.abs(spike[:, [0, 2]] - start[:, [0, 2]]).max() < 1e-4   # no slide
    measured = scene.penetration()
    assert measured.depth <= 1e-10 and measured.volume <= 1e-12
    assert scene.kinetic_energy() < 1e-12


def test_inverse_mass_matrix_moves_a_point_as_an_impulse_does(f64):
    """rigid.inv_mass_matrix_world against the rigid-body formula in NumPy on seeded random
    bodies, levers and impulses: K·p is the velocity change p/m + (I_w⁻¹(r × p)) × r of the
    point at lever r, and n·K·n is generalized_inv_mass along n."""
    import taichi as ti

    from taichi_dcd.core.rigid import generalized_inv_mass, inv_mass_matrix_world, quat_matrix

    rng = np.random.default_rng(7)
    count = 50
    q = rng.normal(size=(count, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    axes = rng.uniform(0.1, 3.0, size=(count, 3))
    inv_inertia_body = np.array([np.diag(1.0 / a) for a in axes])
    inv_mass = rng.uniform(0.01, 10.0, size=count)
    lever, impulse, normal = rng.normal(size=(3, count, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    moved, along_n = np.zeros((count, 3)), np.zeros(count)

    vec3, vec4, mat3 = ti.math.vec3, ti.math.vec4, ti.math.mat3

    @ti.kernel
    def apply(q: ti.types.ndarray(dtype=vec4, ndim=1), ib: ti.types.ndarray(dtype=mat3, ndim=1),
              im: ti.types.ndarray(ndim=1), r: ti.types.ndarray(dtype=vec3, ndim=1),
              p: ti.types.ndarray(dtype=vec3, ndim=1), n: ti.types.ndarray(dtype=vec3, ndim=1),
              out: ti.types.ndarray(dtype=vec3, ndim=1), w: ti.types.ndarray(ndim=1)):
        for i in range(q.shape[0]):
            rot = quat_matrix(q[i])
            k_mat = inv_mass_matrix_world(im[i], rot @ ib[i] @ rot.transpose(), r[i])
            out[i] = k_mat @ p[i]
            w[i] = n[i].dot(k_mat @ n[i]) - generalized_inv_mass(im[i], q[i], ib[i], r[i], n[i])

    apply(q, inv_inertia_body, inv_mass, lever, impulse, normal, moved, along_n)
    for i in range(count):
        rot = quat_to_matrix(q[i])
        inv_inertia_world = rot @ inv_inertia_body[i] @ rot.T
        expected = inv_mass[i] * impulse[i] + np.cross(inv_inertia_world @ np.cross(lever[i], impulse[i]), lever[i])
        np.testing.assert_allclose(moved[i], expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    assert np.abs(along_n).max() <= 1e-12


def test_convex_neighbours_of_a_box_are_across_its_edges_not_its_face_diagonals(f64_scene):
    """contact.exits.convex_neighbours on a static box beside a rigid wedge: each of the box's 12
    triangles has exactly two neighbours, across the two of its edges that are box edges
    (the faces meet at 90°), and none across its face diagonal (a flat edge); every
    neighbour is on the same body and lists the triangle back across the same edge."""
    from taichi_dcd.contact.exits import convex_neighbours

    scene = Scene(scene_from_dict({"body": [
        {"name": "block", "kind": "static", "shape": "box", "params": {"size": [2.0, 1.0, 4.0]}},
        {"name": "wedge", "kind": "rigid", "shape": "wedge", "position": [0.0, 3.0, 0.0]}]}, name="nbr"))
    model = scene.model
    x = scene.vertices()
    nbr = convex_neighbours(model, x)
    tri = model.tri_indices_np
    normals = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    b0 = model.bodies[0]
    block = range(b0.tri_start, b0.tri_start + b0.tri_count)
    assert len(block) == 12
    for t in block:
        assert (nbr[t] >= 0).sum() == 2
        for k in range(3):
            u = nbr[t, k]
            edge = {tri[t, k], tri[t, (k + 1) % 3]}
            if u < 0:  # the face diagonal: the triangle across it is coplanar
                other = [s for s in block if s != t and edge <= set(tri[s])]
                assert len(other) == 1 and normals[t] @ normals[other[0]] > 0.999
                continue
            assert model.tri_body_np[u] == model.tri_body_np[t]
            assert abs(normals[t] @ normals[u]) < 1e-9  # 90° apart
            back = [j for j in range(3) if {tri[u, j], tri[u, (j + 1) % 3]} == edge]
            assert back and nbr[u, back[0]] == t
