"""Two boxes whose edges cross deep inside each other, no vertex of either inside the other:
the pose two boxes of pile-1000 reached in a landing (tests/data/interlocked_box_*.obj)."""

from pathlib import Path

import numpy as np

from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene

DATA = Path(__file__).resolve().parents[1] / "data"


def test_interlocked_boxes_are_pushed_apart(f64_scene):
    """Without gravity, two boxes interlocked 1.35 cm deep at crossing edges are pushed apart
    within 0.5 s: the independent measure finds no overlap deeper than 1e-4 m. Each crossing
    pair's point is where one box's edge enters the other, on a neighbour face's plane: before
    deep edge crossings took the edge-edge normal first (contact.pair_rows.add_pair_contact),
    nearest_exit held those points there at depth ~1e-10 m and the boxes stayed 1.35 cm deep;
    with edge_edge_normal off they still do."""
    config = scene_from_dict({"sim": {"gravity": [0.0, 0.0, 0.0]}, "body": [
        {"name": "a", "kind": "rigid", "mesh": "interlocked_box_a.obj"},
        {"name": "b", "kind": "rigid", "mesh": "interlocked_box_b.obj"}]}, name="interlock", base_dir=DATA)
    scene = Scene(config)
    start = scene.penetration()
    assert start.depth > 0.013 and start.pair == ("a", "b")
    scene.step(50)
    assert np.isfinite(scene.vertices()).all()
    assert scene.penetration().depth <= 1e-4


def test_skew_edges_apart_outside_both_bodies_push_nothing(f64_scene):
    """A wedge lying on the ground against a standing wedge, its ridge on the standing wedge's
    slanted face where that face meets the end cap, sliding at 0.13 m/s (the pose `wedges`
    reached at 3.51 s at 12 substeps × 4 sweeps; tests/data/wedge_at_end_cap.obj), stays out of
    it: no overlap deeper than 1e-4 m over 0.1 s (seen: 2.9e-5 m in the first frame, then none).
    The end cap's bottom edge and the lying wedge's ridge are skew edges 1.1 m apart outside
    both bodies; before edges_interlock their common normal turned a 1.1 m row between them
    2.5° toward the standing wedge, and the lying wedge went 1.6 cm into it."""
    config = scene_from_dict({"sim": {"frame_dt": 0.01, "substeps": 12, "iterations": 4}, "body": [
        {"name": "ground", "kind": "static", "shape": "ground", "position": [0.0, -3.0, 0.0]},
        {"name": "standing", "kind": "static", "shape": "wedge", "position": [0.0, -3.0, 0.0]},
        {"name": "lying", "kind": "rigid", "mesh": "wedge_at_end_cap.obj",
         "velocity": [0.0887, -0.0874, -0.0327]}]}, name="end-cap", base_dir=DATA)
    scene = Scene(config)
    assert scene.penetration().depth < 1e-5
    worst = 0.0
    for _ in range(10):
        scene.step(1)
        worst = max(worst, scene.penetration().depth)
    assert worst <= 1e-4
