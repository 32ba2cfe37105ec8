"""Two boxes whose edges cross deep inside each other, no vertex of either inside the other:
the pose two boxes of pile-1000 reached in a landing (tests/data/interlocked_box_*.obj)."""

from pathlib import Path

import numpy as np
import pytest

from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.mark.xfail(strict=True, reason=(
    "each crossing pair's candidate point lies on the other box's surface (where the edge enters it), "
    "so nearest_exit turns the pair's 5-15 mm into a row of depth ~1e-10 m held there; with the rule off "
    "the boxes part (docs/experiments.md, 2026-12-02, fourth session)"))
def test_interlocked_boxes_are_pushed_apart(f64_scene):
    """Without gravity, two boxes interlocked 1.35 cm deep at crossing edges are pushed apart
    within 0.5 s: the independent measure finds no overlap deeper than 1e-4 m."""
    config = scene_from_dict({"sim": {"gravity": [0.0, 0.0, 0.0]}, "body": [
        {"name": "a", "kind": "rigid", "mesh": "interlocked_box_a.obj"},
        {"name": "b", "kind": "rigid", "mesh": "interlocked_box_b.obj"}]}, name="interlock", base_dir=DATA)
    scene = Scene(config)
    start = scene.penetration()
    assert start.depth > 0.013 and start.pair == ("a", "b")
    scene.step(50)
    assert np.isfinite(scene.vertices()).all()
    assert scene.penetration().depth <= 1e-4
