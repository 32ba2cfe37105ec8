"""Erleben's contact tests with the settings a user gets (`taichi-dcd run NAME
--no-frames`): no NaN, settled within 5 s, penetration by the independent measure
(measure/penetration.py) at most 1e-4 m and 1e-9 m³ at the end and 5 mm over the run.

Every built-in scene runs here, the soft one included. The ones that fail today are strict
expected failures with the reason (the README's table has their figures): when one starts
passing, its entry must go."""

import json

import pytest

from taichi_dcd.cli import main
from taichi_dcd.scene.config import DEFAULT_ITERATIONS, DEFAULT_SUBSTEPS
from taichi_dcd.measure.penetration import verdict

RIGID_SCENES = ["spikes", "spike-and-wedge", "wedges", "wedges-crossed", "spike-in-hole", "spike-in-pit",
                "spike-in-crack", "wedge-in-crack"]
SOFT_SCENES = ["soft-ball-on-spike"]
# Scenes that fail today, with why (strict: a scene that starts passing must leave the list).
KNOWN_FAILING: dict[str, str] = {}


# The soft scene's whole 4 s run (about 80 s here) is in the slow suite; its landing and draping
# over the first 1.6 s are checked in the default suite (tests/solver/test_soft.py).
@pytest.mark.parametrize("name", [
    pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=KNOWN_FAILING[n])) if n in KNOWN_FAILING else
    pytest.param(n, marks=pytest.mark.slow) if n in SOFT_SCENES else n
    for n in RIGID_SCENES + SOFT_SCENES])
def test_scene_settles_without_penetrating(scene_run, name):
    metrics = scene_run(name)
    assert metrics["complete"] and not metrics["nan_detected"]
    default = {"substeps": DEFAULT_SUBSTEPS, "iterations": DEFAULT_ITERATIONS}
    # The soft scene keeps the setting its damping and compliance were tuned at (its file's [sim]).
    settings = {"substeps": 12, "iterations": 16} if name in SOFT_SCENES else default
    assert {k: metrics["settings"][k] for k in settings} == settings
    assert verdict(metrics) is None, verdict(metrics)
    assert metrics["time_to_settle"] <= 5.0 - 0.2


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="at 64 sweeps the dropped wedge still slides at 0.2-0.4 m/s at 5 s; the cause is the "
                   "velocity pass likely, measuring at the anchors but pushing at their midpoint (docs/experiments.md, "
                   "2026-11-28 afternoon)")
def test_more_sweeps_still_settle_the_wedges(f64, tmp_path):
    """Raising the sweeps (the accuracy setting users trade speed for) must not keep a body
    moving."""
    assert main(["run", "wedges", "--no-frames", "--quiet", "--iterations", "64", "--out", str(tmp_path)]) == 0
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["settings"]["iterations"] == 64
    assert verdict(metrics) is None, verdict(metrics)
    assert metrics["time_to_settle"] <= 5.0 - 0.2

def test_run_command_reports_and_writes_the_run(f64, tmp_path, capsys):
    assert main(["run", "spike-in-hole", "--no-frames", "--quiet", "--frames", "20", "--out", str(tmp_path)]) == 0
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["frames"] == 20 and metrics["complete"]
    assert (tmp_path / "final" / "dropped_spike.obj").is_file()
    assert len((tmp_path / "metrics.csv").read_text().splitlines()) == 21
    assert "spike-in-hole: 20 frames" in capsys.readouterr().out


def test_list_names_every_builtin_scene(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in RIGID_SCENES + SOFT_SCENES:
        assert name in out


def test_unknown_scene_name_is_a_usage_error(capsys):
    assert main(["run", "spikez", "--no-frames"]) == 2
    assert "unknown scene 'spikez'" in capsys.readouterr().err


def test_frames_are_rendered_and_identical_for_identical_runs(f64, tmp_path):
    """A short rendered run writes frame 0 (the initial state) and one PNG per frame; a
    second run of the same scene writes the same bytes."""
    for out in ("a", "b"):
        assert main(["run", "spike-in-hole", "--frames", "3", "--quiet", "--contacts", "--gif",
                     "--out", str(tmp_path / out)]) == 0
    frames = sorted((tmp_path / "a" / "frames").glob("frame_*.png"))
    assert [f.name for f in frames] == [f"frame_{k:05d}.png" for k in range(4)]
    for f in frames:
        assert f.read_bytes() == (tmp_path / "b" / "frames" / f.name).read_bytes()
    assert (tmp_path / "a" / "animation.gif").stat().st_size > 0


def test_wedge_dropped_turned_stays_out_of_the_standing_ridge(f64_scene, tmp_path):
    """`wedges` with the dropped wedge turned 4.9° about the vertical, 1.5 cm off along the
    ridge and 5.8 cm higher (`benchmarks/variants.py --seed 7`, wedges v0) passes like the
    scene itself. It balances on the crossing ridges, pitches and slides along the standing
    ridge; before vertex rows beyond a convex edge of the other body were left out
    (contact.vertex_rows), the standing ridge's end vertex, outside the dropped wedge, pushed
    it sideways through the standing wedge, 4.5 cm deep at 1.39 s."""
    from dataclasses import replace

    from taichi_dcd.output.run import run_scene
    from taichi_dcd.scene.builtin import scene_config
    from taichi_dcd.scene.scene import Scene

    config = scene_config("wedges")
    k = [b.name for b in config.bodies].index("dropped_wedge")
    config.bodies[k] = replace(config.bodies[k], rotation=(180.0, -4.882059744574941, 0.0),
                               position=(0.009812406123610255, 3.057820643195593, -0.01514910467836015))
    metrics = run_scene(Scene(config), tmp_path, progress=None, notices=None)
    assert metrics["complete"] and not metrics["nan_detected"]
    assert verdict(metrics) is None, verdict(metrics)
