"""A run without sim.sleep tells the user once when everything has been at rest for a while,
and how to stop paying for it; a sleeping scene, or one stopped when settled, is not told."""

import io

import pytest

from taichi_dcd.output.run import REST_NOTICE_TIME, run_scene
from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene


def box_on_block(**sim) -> Scene:
    """A 0.2 m box set on a static block (touching), settled from its first frames."""
    return Scene(scene_from_dict({"sim": dict(frame_dt=0.01, **sim), "body": [
        {"name": "block", "kind": "static", "shape": "box", "params": {"size": [1.0, 0.2, 1.0]},
         "position": [0.0, -0.1, 0.0]},
        {"name": "box", "kind": "rigid", "shape": "box", "params": {"size": [0.2, 0.2, 0.2]},
         "position": [0.0, 0.1, 0.0]}]}, name="rest"))


@pytest.mark.parametrize("sleep", [False, True])
def test_a_scene_at_rest_is_told_once_that_it_could_sleep(f64_scene, tmp_path, sleep):
    frames = int(round((REST_NOTICE_TIME + 0.3) / 0.01))
    notices = io.StringIO()
    metrics = run_scene(box_on_block(sleep=sleep), tmp_path / "out", frames=frames, progress=None, notices=notices)
    assert metrics["complete"] and metrics["settled"]
    told = [line for line in notices.getvalue().splitlines() if "sleep = true" in line]
    if sleep:
        assert told == []
        assert metrics["sleeping_bodies"] == ["box"]
    else:
        assert len(told) == 1
        assert "every body has been at rest since t = " in told[0]
        assert metrics["sleeping_bodies"] == []


def test_a_run_stopped_when_settled_is_not_told(f64_scene, tmp_path):
    notices = io.StringIO()
    metrics = run_scene(box_on_block(stop_when_settled=True), tmp_path / "out", frames=200, progress=None,
                        notices=notices)
    assert metrics["settled"] and metrics["frames"] < 100
    assert "sleep = true" not in notices.getvalue()
