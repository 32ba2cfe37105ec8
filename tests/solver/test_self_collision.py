"""A soft body touching itself (`self_collision`): the turns of a soft coil that land on each
other, judged by the independent self-intersection measure (measure/self_intersection.py)."""


import pytest

from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene

SMALL_COIL = {"coil_radius": 0.3, "tube_radius": 0.06, "pitch": 0.14, "turns": 2.0, "segments_per_turn": 16}


def coil_scene(self_collision: bool, broad_phase: str = "auto") -> Scene:
    """A soft coil of two turns (592 triangles, 2 cm between its turns) dropped from 0.3 m."""
    return Scene(scene_from_dict({"sim": {"substeps": 12, "iterations": 16}, "body": [
        {"name": "ground", "kind": "static", "shape": "ground"},
        {"name": "coil", "kind": "soft", "shape": "coil", "params": SMALL_COIL, "position": [0.0, 0.3, 0.0],
         "compliance": 1e-5, "damping": 20.0, "self_collision": self_collision}]}, name="coil"),
                 broad_phase=broad_phase)


def self_crossings(scene: Scene, frames: int = 60) -> tuple[int, float]:
    """The most pairs of the coil's triangles crossing each other in any of `frames` frames,
    and the deepest crossing (m); checks that it stays out of the ground too."""
    most, worst = 0, 0.0
    for _ in range(frames):
        scene.step(1)
        pairs, depth = scene.self_penetration()["coil"]
        most, worst = max(most, pairs), max(worst, depth)
    assert scene.penetration().depth <= 1e-4
    return most, worst


def test_a_landing_coil_keeps_its_turns_apart_only_with_self_collision(f64_scene):
    """Without self_collision the upper turn falls through the lower one: pairs of its own
    triangles cross by more than 1 cm. With it (its walls keeping their gap), no pair crosses
    in any frame."""
    scene = coil_scene(False)
    assert self_crossings(scene)[1] > 1e-2
    del scene  # its fields go back to the pool: the second scene compiles nothing
    assert self_crossings(coil_scene(True)) == (0, 0.0)


@pytest.mark.slow
def test_the_grid_keeps_the_coils_turns_apart_too(f64_scene):
    """The same coil on the grid broad phase (its skin makes pairs of walls facing each other
    across the tube's inside candidates): no pair crosses in any frame."""
    assert self_crossings(coil_scene(True, "grid")) == (0, 0.0)


@pytest.mark.slow
def test_the_built_in_soft_coil_lands_without_crossing_itself_and_comes_to_rest(f64_scene):
    """`soft-coil` (1,616 triangles, on the grid): over its first 2.5 s, through the landing and
    the turns settling on each other, no pair of its triangles crosses in any frame, and then
    it is at rest (every vertex slower than 1 mm/s; it settles at ~2.1 s)."""
    from taichi_dcd.scene.builtin import builtin_scene

    scene = Scene(builtin_scene("soft-coil"))
    assert scene.solver.use_grid
    assert self_crossings(scene, 250) == (0, 0.0)
    before = scene.body_vertices("coil")
    scene.step(1)
    assert abs(scene.body_vertices("coil") - before).max() / scene.config.sim.frame_dt < 1e-3


@pytest.mark.slow
def test_the_built_in_soft_torus_grips_the_spike_without_crossing_itself(f64_scene):
    """`soft-torus-on-spike` (self_collision on): the ring slides down the spike until it grips
    it, no pair of its triangles crossing in any frame, and comes to rest out of the spike,
    its centre still on the spike's axis."""
    from taichi_dcd.scene.builtin import builtin_scene

    scene = Scene(builtin_scene("soft-torus-on-spike"))
    start = scene.body_vertices("ring").mean(axis=0)
    for _ in range(160):
        scene.step(1)
        assert scene.self_penetration()["ring"] == (0, 0.0)
    before = scene.body_vertices("ring")
    scene.step(1)
    assert abs(scene.body_vertices("ring") - before).max() / scene.config.sim.frame_dt < 1e-3  # at rest
    assert scene.penetration().depth <= 1e-4
    centre = before.mean(axis=0)
    assert centre[1] < start[1] - 0.1 and abs(centre[[0, 2]]).max() < 0.01


def test_the_all_pairs_path_offers_the_coils_own_pairs_but_near_neighbours(f64_scene):
    """The all-pairs broad phase (the frame kernel's, `broad_phase="brute"`) offers as candidates
    exactly the pairs a NumPy brute force finds: triangles of different bodies, not both static,
    and the coil's own pairs that are not near neighbours (a vertex shared, or two vertices
    joined by an edge), whose padded boxes overlap. Checked on the coil as it starts, its turns
    2 cm apart (seen: 229 own pairs offered, 4,154 near neighbours' boxes meeting)."""
    import numpy as np

    from taichi_dcd.collision.broadphase import BOX_SLACK
    from taichi_dcd.core.model import STATIC
    from taichi_dcd.core.runtime import tolerance
    from taichi_dcd.solver.kernels import rows_at_state_kernel

    scene = coil_scene(True, broad_phase="brute")
    m, solver = scene.model, scene.solver
    x = scene.vertices()
    tris = x[m.tri_indices_np]
    lo, hi = tris.min(axis=1), tris.max(axis=1)
    pad = BOX_SLACK * tolerance() * (hi - lo).max(axis=1) + solver.sim.box_margin_np[m.tri_body_np]
    lo, hi = lo - pad[:, None], hi + pad[:, None]
    body, static, hidden = m.tri_body_np, m.body_kind_np[m.tri_body_np] == STATIC, m.tri_hidden_np != 0
    edges = {frozenset((int(f[i]), int(f[j]))) for f in m.tri_indices_np for i, j in ((0, 1), (1, 2), (2, 0))}
    expected = own = near = 0
    for a in range(m.n_tris):
        overlap = (lo[a] <= hi).all(axis=1) & (lo <= hi[a]).all(axis=1)
        for b in np.flatnonzero(overlap[a + 1:]) + a + 1:
            if body[a] != body[b]:
                expected += not (static[a] and static[b]) and not (hidden[a] or hidden[b])
            elif any(va == vb or frozenset((int(va), int(vb))) in edges
                     for va in m.tri_indices_np[a] for vb in m.tri_indices_np[b]):
                near += 1
            else:
                expected += 1
                own += 1
    solver.contacts.grow(expected + 1024)
    needed, rows = (int(v) for v in rows_at_state_kernel(solver.sim, 0.0, *solver.contacts.arrays()))
    assert own > 100 and near > 1000 and rows == 0
    assert needed == expected
