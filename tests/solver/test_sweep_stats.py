"""The block solves' sweep statistics (XPBDSolver.sweep_stats): counted by a kernel variant of
their own, they must not change the simulation, and they must count what the solver did."""

import numpy as np
import pytest

import taichi_dcd
from taichi_dcd.scene.config import DEFAULT_ITERATIONS, DEFAULT_SUBSTEPS, scene_from_dict
from taichi_dcd.scene.scene import Scene
from taichi_dcd.solver.islands import BLOCK_SWEEPS, COUPLED_SWEEPS

FRAMES = 4  # counted after the first frame, in which the boxes land


def box(name: str, position) -> dict:
    return {"name": name, "kind": "rigid", "shape": "box", "params": {"size": [0.4, 0.2, 0.4]},
            "position": list(position)}


def two_islands(sweep_stats: bool) -> Scene:
    """A box alone on the ground (a lone body's block) and, 2 m away, two boxes stacked on it
    (an island of two), each set 1e-5 m above what it rests on."""
    bodies = [{"name": "ground", "kind": "static", "shape": "ground"},
              box("alone", (0.0, 0.1 + 1e-5, 0.0)),
              box("lower", (2.0, 0.1 + 1e-5, 0.0)), box("upper", (2.0, 0.3 + 2e-5, 0.0))]
    return Scene(scene_from_dict({"sim": {"frame_dt": 0.01}, "body": bodies}, name="two-islands"),
                 sweep_stats=sweep_stats)


@pytest.fixture(scope="module")
def runs():
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    out = {}
    for counted in (False, True):
        scene = two_islands(counted)
        scene.step(1)
        if counted:
            scene.solver.reset_sweep_stats()
        scene.step(FRAMES)
        out[counted] = scene
    return out


def test_counting_the_sweeps_leaves_the_simulation_the_same_bits(runs):
    assert np.array_equal(runs[True].vertices(), runs[False].vertices())


def test_every_substeps_sweep_solves_each_island_once(runs):
    stats = runs[True].solver.sweep_stats()
    solves = FRAMES * DEFAULT_SUBSTEPS * DEFAULT_ITERATIONS  # both islands touch the ground throughout
    assert stats["lone"]["solves"] == solves
    assert stats["coupled"]["solves"] == solves


def test_sweep_counts_stay_within_the_caps(runs):
    stats = runs[True].solver.sweep_stats()
    for name, cap in (("lone", BLOCK_SWEEPS), ("coupled", COUPLED_SWEEPS)):
        part = stats[name]
        # A phase runs at least one sweep; a converged normal phase can end at its first.
        assert 1.0 <= part["normal_sweeps"] <= cap and 1.0 <= part["friction_sweeps"] <= cap
        for share in ("normal_at_cap", "friction_at_cap"):
            assert 0.0 <= part[share] <= 1.0
        # A phase at its cap ran all `cap` sweeps: the mean is at least the capped share of cap.
        assert part["friction_sweeps"] >= part["friction_at_cap"] * cap


def test_the_island_of_two_boxes_solves_more_rows_than_the_lone_box(runs):
    stats = runs[True].solver.sweep_stats()
    # The lower box has the lone box's ground rows, and the rows to the box on it come on top.
    assert 1.0 <= stats["lone"]["rows"] < stats["coupled"]["rows"]
    assert stats["coupled"]["rows"] < 100  # 3 × 12 triangles: far fewer rows than pairs


def test_statistics_of_a_solver_that_does_not_count_are_an_error(runs):
    with pytest.raises(RuntimeError, match="sweep statistics are off"):
        runs[False].solver.sweep_stats()
