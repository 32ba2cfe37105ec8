"""The substep guards of discrete detection (solver/tunnelling.py): wall thickness from ray casts
against analytic boxes, and the impact-depth substep rule against a per-pair loop."""

import math
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from taichi_dcd.solver.tunnelling import mesh_thickness, substeps_for_impacts


@pytest.mark.parametrize("size", [(1.0, 1.0, 1.0), (2.0, 0.01, 2.0), (3e-4, 1e-4, 2e-4)])
def test_thickness_of_a_box_is_its_thinnest_side(size):
    box = trimesh.creation.box(extents=size)
    assert mesh_thickness(box.vertices, box.faces) == pytest.approx(min(size), rel=1e-9)


def impacts_by_loops(lo, hi, velocity, spin, moving, dt, g, step, substeps):
    """Every pair of bodies, one at a time: how far can they close in this frame, can
    their grown boxes touch, and how many substeps keep that within `step` per substep?"""
    best = substeps
    for a in range(len(spin)):
        for b in range(len(spin)):
            if a == b or not (moving[a] or moving[b]):
                continue
            va = velocity[a] if moving[a] else np.zeros(3)
            vb = velocity[b] if moving[b] else np.zeros(3)
            closing = math.dist(va, vb) + (spin[a] if moving[a] else 0.0) + (spin[b] if moving[b] else 0.0) + g * dt
            reach = closing * dt
            separated = any(lo[a][k] - hi[b][k] > reach or lo[b][k] - hi[a][k] > reach for k in range(3))
            if not separated:
                best = max(best, math.ceil(reach / step))
    return best


def test_impact_substeps_match_a_loop_over_pairs():
    rng = np.random.default_rng(7)
    for trial in range(300):
        n = int(rng.integers(2, 12))
        lo = rng.uniform(-2.0, 2.0, (n, 3))
        hi = lo + rng.uniform(0.01, 1.0, (n, 3))
        velocity = rng.normal(0.0, 10.0, (n, 3)) * (rng.random((n, 1)) < 0.8)
        spin = rng.uniform(0.0, 5.0, n)
        moving = rng.random(n) < 0.7
        substeps = int(rng.integers(1, 20))
        got, a, b = substeps_for_impacts(lo, hi, velocity, spin, moving, 0.01, 9.8, 2e-3, substeps)
        assert got == impacts_by_loops(lo, hi, velocity, spin, moving, 0.01, 9.8, 2e-3, substeps), trial
        if got > substeps:
            assert moving[a] or moving[b]


def test_a_body_falling_onto_the_ground_takes_substeps_for_its_speed_only_when_near():
    """A 1 m box 5 cm above a static ground, falling at 9.902 m/s: with |g|·dt it closes in
    by up to 0.1 m in the 0.01 s frame, which at 2 mm per substep takes 50 substeps; 1 m
    above the ground it takes the 10. A second box falling beside it at the same speed
    asks for nothing more."""
    ground = ([-5.0, -1.0, -5.0], [5.0, 0.0, 5.0])
    fall = [0.0, -9.902, 0.0]
    near = substeps_for_impacts(np.array([ground[0], [-0.5, 0.05, -0.5]]), np.array([ground[1], [0.5, 1.05, 0.5]]),
                                np.array([[0.0] * 3, fall]), np.zeros(2), np.array([False, True]), 0.01, 9.8, 2e-3, 10)
    assert near == (50, 0, 1)
    far = substeps_for_impacts(np.array([ground[0], [-0.5, 1.0, -0.5]]), np.array([ground[1], [0.5, 2.0, 0.5]]),
                               np.array([[0.0] * 3, fall]), np.zeros(2), np.array([False, True]), 0.01, 9.8, 2e-3, 10)
    assert far == (10, -1, -1)
    side_by_side = substeps_for_impacts(np.array([[-0.5, 1.0, -0.5], [0.51, 1.0, -0.5]]),
                                        np.array([[0.5, 2.0, 0.5], [1.51, 2.0, 0.5]]), np.array([fall, fall]),
                                        np.zeros(2), np.array([True, True]), 0.01, 9.8, 2e-3, 10)
    assert side_by_side == (10, -1, -1)
    # Two static bodies that overlap never ask for substeps.
    assert substeps_for_impacts(np.zeros((2, 3)), np.ones((2, 3)), np.ones((2, 3)), np.ones(2),
                                np.array([False, False]), 0.01, 9.8, 2e-3, 10) == (10, -1, -1)


@pytest.mark.parametrize("debug", [pytest.param(False, id="fast"),
                                   pytest.param(True, id="debug", marks=pytest.mark.slow)])
def test_the_frames_own_substep_check_and_choice_agree_with_the_numpy_choice(debug):
    """The all-pairs frame checks on the device whether the configured substeps suffice
    (solver.summary.substeps_needed) and only otherwise leaves the choice to numpy
    (Scene._substeps_for_next_frame): on seeded random states of a static ground, two rigid
    bodies and a soft ball (moved apart or together, random linear and angular velocities,
    a random wobble of the ball's particles), the frame runs exactly when numpy would keep
    the configured substeps, and leaves the state untouched when it would not. Asked to
    choose, it runs as many substeps as numpy chooses and ends in the same state, to the bit,
    as the frame stepped with numpy's count.

    Run in a fresh process: in three of about eight full runs the test worker died here
    without a word after a few hundred earlier tests (never when run alone; README, Tests);
    a process of its own keeps that from ending the suite and shows whatever it prints if it
    dies. In debug mode (bounds checks) in the slow suite: its frame kernel then compiles for
    minutes."""
    out = subprocess.run([sys.executable, "-X", "faulthandler", __file__, "substep-check", str(int(debug))],
                         capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, f"exit status {out.returncode}\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    assert "checked" in out.stdout


def substep_check_trials(debug: bool):
    """The body of the test above."""
    import taichi_dcd
    from taichi_dcd.scene.config import scene_from_dict
    from taichi_dcd.scene.scene import Scene

    taichi_dcd.init(arch="cpu", precision="f64", debug=debug)

    scene = Scene(scene_from_dict({"sim": {"gravity": [0.0, -9.8, 0.0]}, "body": [
        {"name": "ground", "kind": "static", "shape": "ground"},
        {"name": "spike", "kind": "rigid", "shape": "spike", "position": [0.0, 1.0, 0.0]},
        {"name": "box", "kind": "rigid", "shape": "box", "position": [3.0, 1.0, 0.0]},
        {"name": "ball", "kind": "soft", "shape": "icosphere", "params": {"radius": 0.5, "subdivisions": 1},
         "position": [-3.0, 2.0, 0.0]}]}, name="check"))
    sim, state, model = scene.config.sim, scene.state, scene.model
    rigid = [model.body_index("spike"), model.body_index("box")]
    ball = model.bodies[model.body_index("ball")]
    rng = np.random.default_rng(11)
    x0, vertex0, q0 = state.body_x.to_numpy(), state.vertex_x.to_numpy(), state.body_q.to_numpy()
    outcomes = []
    for trial in range(60):
        # Heights from touching the ground to 1 m clear of it; speeds up to ~8 m/s.
        x, vertex_x = x0.copy(), vertex0.copy()
        v, w = np.zeros_like(x0), np.zeros_like(x0)
        vertex_v = np.zeros_like(vertex0)
        for b in [*rigid, model.body_index("ball")]:
            body = model.bodies[b]
            shift = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.9, 0.1), rng.uniform(-0.5, 0.5)])
            rows = slice(body.vertex_start, body.vertex_start + body.vertex_count)
            vertex_x[rows] += shift
            x[b] += shift
            v[b] = rng.normal(0.0, 3.0, 3) * (rng.random() < 0.7)
            w[b] = rng.normal(0.0, 3.0, 3) * (rng.random() < 0.5)
        rows = slice(ball.vertex_start, ball.vertex_start + ball.vertex_count)
        vertex_v[rows] = v[model.body_index("ball")] + rng.normal(0.0, 0.5, (ball.vertex_count, 3))
        for field, value in [(state.body_x, x), (state.body_v, v), (state.body_w, w), (state.vertex_x, vertex_x),
                             (state.vertex_v, vertex_v)]:
            field.from_numpy(value)
        numpy_substeps = scene._substeps_for_next_frame()
        expected = numpy_substeps == sim.substeps
        substeps_done = state.substeps_done
        count = scene.solver.step_frame(sim.frame_dt, sim.substeps, sim.iterations,
                                        max_impact_motion=sim.max_impact_motion)
        assert (count is not None) == expected, trial
        if count is None:
            np.testing.assert_array_equal(state.vertex_x.to_numpy(), vertex_x)
            np.testing.assert_array_equal(state.body_v.to_numpy(), v)
        outcomes.append(expected)
        ends = []
        for choose in (True, False):
            for field, value in [(state.body_x, x), (state.body_v, v), (state.body_w, w),
                                 (state.body_q, q0), (state.vertex_x, vertex_x), (state.vertex_v, vertex_v)]:
                field.from_numpy(value)
            scene.solver.sim.carry_count[0] = 0
            state.substeps_done = substeps_done
            if choose:
                ran, _ = scene.solver.step_frames(1, sim.frame_dt, sim.substeps, sim.iterations,
                                                  max_impact_motion=sim.max_impact_motion, choose_substeps=True)
                assert ran == 1, trial
                assert (scene.solver.more_substeps[1] or sim.substeps) == numpy_substeps, trial
            else:
                scene.solver.step_frames(1, sim.frame_dt, numpy_substeps, sim.iterations)
            ends.append([state.body_x.to_numpy(), state.body_q.to_numpy(), state.vertex_x.to_numpy()])
        for chosen_here, chosen_by_numpy in zip(*ends):
            np.testing.assert_array_equal(chosen_here, chosen_by_numpy)
    assert 10 <= sum(outcomes) <= 50  # both answers are exercised
    print("checked", len(outcomes), "states")


if __name__ == "__main__" and sys.argv[1:2] == ["substep-check"]:
    substep_check_trials(sys.argv[2:] == ["1"])
