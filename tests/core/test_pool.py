"""Scenes share field sets (core.pool) and with them compiled kernels: a set is never handed
to a scene while another uses it, a scene gets the set a larger one left, and what that set
held before does not change a bit of the motion."""

import gc

import numpy as np

from taichi_dcd.core import pool, runtime
from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene
from taichi_dcd.solver.kernels import frames_all_pairs


def box(name, size, position, kind="rigid", **extra):
    return {"name": name, "kind": kind, "shape": "box", "params": {"size": list(size)},
            "position": list(position), **extra}


def box_on_block() -> Scene:
    """A tilted box dropped onto a block: contacts, friction and spin within 30 frames."""
    return Scene(scene_from_dict({"body": [
        box("box", (0.2, 0.3, 0.25), (0.05, 0.3, -0.02), rotation=[20.0, 10.0, 5.0], velocity=[0.5, 0.0, 0.0]),
        box("block", (2.0, 0.2, 2.0), (0.0, -0.1, 0.0), kind="static")]}, name="small"))


def three_boxes_on_a_block() -> Scene:
    return Scene(scene_from_dict({"body": [
        box("a", (0.4, 0.2, 0.4), (0.0, 0.15, 0.0)), box("b", (0.4, 0.2, 0.4), (0.1, 0.4, 0.0)),
        box("c", (0.4, 0.2, 0.4), (-0.1, 0.65, 0.05), velocity=[0.0, -1.0, 0.0]),
        box("block", (2.0, 0.2, 2.0), (0.0, -0.1, 0.0), kind="static")]}, name="big"))


def motion(scene: Scene, frames: int) -> np.ndarray:
    out = []
    for _ in range(frames):
        scene.step(1)
        out.append(np.concatenate([scene.body_positions().ravel(), scene.body_rotations().ravel()]))
    return np.array(out)


def test_a_scene_reuses_the_fields_a_larger_one_left_and_moves_bit_for_bit_the_same(f64_scene):
    runtime.reset()  # no sets left over from the file's earlier tests
    runtime.init(precision="f64")
    held = box_on_block()
    alone = motion(held, 30)
    assert alone[-1, 1] < 0.25  # it fell and landed
    first_set = held.model.field_set

    larger = three_boxes_on_a_block()
    assert larger.model.field_set is not first_set  # in use by `held`
    larger_set = larger.model.field_set
    motion(larger, 20)
    compiled = len(frames_all_pairs._primal.compiled_kernels)
    del larger
    gc.collect()

    again = box_on_block()
    assert again.model.field_set is larger_set
    np.testing.assert_array_equal(motion(again, 30), alone)
    assert len(frames_all_pairs._primal.compiled_kernels) == compiled  # nothing compiled again


def test_rows_for_give_every_count_room_in_a_power_of_two():
    for count in (0, 1, 63, 64, 65, 1000, 65_537):
        rows = pool.rows_for(count)
        assert rows >= max(count, pool.ROWS_FLOOR)
        assert rows & (rows - 1) == 0
        assert rows < 2 * max(count, pool.ROWS_FLOOR)
