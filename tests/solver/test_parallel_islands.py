"""On the grid path the islands of touching rigid bodies are swept side by side
(kernels.end_substep with islands): the motion is the same bits as with the islands swept one after
another, on two threads and on one; and the contacts they are swept in come out in one order
on any number of threads."""

import numpy as np

import taichi_dcd
from taichi_dcd.core import runtime
from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene


def box(name, size, position, kind="rigid", **extra):
    return {"name": name, "kind": kind, "shape": "box", "params": {"size": list(size)},
            "position": list(position), **extra}


def islands_scene() -> Scene:
    """Three two-box stacks and two lone boxes, tilted, dropped onto a block: five islands
    (two of two bodies) as soon as they land, on the grid path."""
    bodies = [box("block", (3.0, 0.2, 3.0), (0.0, -0.1, 0.0), kind="static")]
    for k, x in enumerate((-1.0, -0.3, 0.4)):
        bodies.append(box(f"low{k}", (0.3, 0.1, 0.3), (x, 0.06, 0.0), rotation=[0.0, 10.0 * k, 2.0]))
        bodies.append(box(f"high{k}", (0.2, 0.1, 0.2), (x + 0.03, 0.17, 0.02), rotation=[3.0, 5.0, 0.0]))
    bodies.append(box("lone0", (0.2, 0.2, 0.2), (1.0, 0.12, 0.8), rotation=[8.0, 0.0, 4.0]))
    bodies.append(box("lone1", (0.25, 0.1, 0.2), (-0.8, 0.07, -0.9), velocity=[0.3, 0.0, 0.0]))
    return Scene(scene_from_dict({"body": bodies}, name="islands"), broad_phase="grid")


def motion(parallel: bool, frames: int = 25):
    """Each frame's poses and velocities, and the most islands with rows in any sweep."""
    scene = islands_scene()
    assert scene.solver.use_grid
    scene.solver.parallel_islands = parallel
    out, most_islands = [], 0
    for _ in range(frames):
        scene.step(1)
        sim = scene.solver.sim
        most_islands = max(most_islands, int((sim.block_len.to_numpy()[: scene.model.n_bodies] > 0).sum()))
        out.append(np.concatenate([scene.body_positions().ravel(), scene.body_rotations().ravel(),
                                   scene.body_velocities().ravel()]))
    return np.array(out), most_islands


def test_islands_swept_side_by_side_move_as_one_after_another():
    taichi_dcd.init(arch="cpu", precision="f64", cpu_threads=2)
    serial, _ = motion(parallel=False)
    parallel, islands = motion(parallel=True)
    assert islands >= 4  # the boxes landed, in separate islands
    assert np.array_equal(serial, parallel)
    taichi_dcd.init(arch="cpu", precision="f64", cpu_threads=1)
    one_thread, _ = motion(parallel=True)
    assert np.array_equal(serial, one_thread)


def test_a_scene_takes_the_parallel_sweep_only_with_threads_to_share(f64_scene):
    taichi_dcd.init(arch="cpu", precision="f64", cpu_threads=1)
    assert not islands_scene().solver.parallel_islands
    taichi_dcd.init(arch="cpu", precision="f64", cpu_threads=2)
    assert islands_scene().solver.parallel_islands


def balls_scene() -> Scene:
    """Three icospheres of 1,280 triangles on a subdivided block, one rolling into another and one
    dropped on top: thousands of binned triangles and candidate pairs, enough for the broad and
    narrow phases' loops to be shared among threads."""
    def ball(name, position, **extra):
        return {"name": name, "kind": "rigid", "shape": "icosphere", "params": {"radius": 0.3, "subdivisions": 3},
                "position": list(position), **extra}
    block = {"name": "block", "kind": "static", "shape": "box",
             "params": {"size": [3.0, 0.2, 3.0], "subdivisions": 4}, "position": [0.0, -0.1, 0.0]}
    bodies = [block, ball("low", (0.0, 0.31, 0.0)), ball("rolling", (0.35, 0.31, 0.3), velocity=[-0.5, 0.0, 0.0]),
              ball("dropped", (0.1, 0.85, 0.05))]
    return Scene(scene_from_dict({"body": bodies}, name="balls"), broad_phase="grid")


def ball_poses(frames: int = 30) -> np.ndarray:
    scene = balls_scene()
    out = []
    for _ in range(frames):
        scene.step(1)
        out.append(np.concatenate([scene.body_positions().ravel(), scene.body_rotations().ravel()]))
    assert scene.solver.last_contact_count > 0
    return np.array(out)


def test_contacts_come_out_in_one_order_on_any_number_of_threads(monkeypatch):
    # Loops of any length shared among threads, as in a scene of over 200,000 triangles: with
    # their contacts appended in the order the threads happened to finish, three runs on two
    # threads moved the balls three different ways.
    monkeypatch.setattr(runtime, "PARALLEL_MIN_WORK", 0)
    taichi_dcd.init(arch="cpu", precision="f64", cpu_threads=2)
    first, second = ball_poses(), ball_poses()
    assert np.array_equal(first, second)
    taichi_dcd.init(arch="cpu", precision="f64", cpu_threads=1)
    assert np.array_equal(first, ball_poses())
