"""The speed/accuracy sweep: its rows are the runs' own metrics, its Pareto front and
recommendation are right, bad settings are usage errors, and Ray gives the same rows."""

import json
import random

import pytest
from PIL import Image

from taichi_dcd.cli import main
from taichi_dcd.output.sweep import TIMING_COLUMNS, SweepRun, pareto_front, read_csv, recommend, run_one, run_sweep

from cli_helpers import assert_one_line_error, run_cli, snapshot

FRAMES = 6


def test_sweep_rows_are_the_runs_metrics_and_the_plot_is_written(tmp_path, capsys):
    """Each sweep.csv row holds its own settings and the same penetration figures as a
    `taichi-dcd run` of that scene at those settings; pareto.png is a real image."""
    out = tmp_path / "sweep"
    status = main(["sweep", "spike-in-crack", "--substeps", "2,5", "--iterations", "4", "--frames", str(FRAMES),
                   "--workers", "2", "--quiet", "--out", str(out)])
    assert status == 0
    rows = read_csv(out / "sweep.csv")
    assert [(r["scene"], r["substeps"], r["iterations"], r["precision"]) for r in rows] == [
        ("spike-in-crack", 2, 4, "f64"), ("spike-in-crack", 5, 4, "f64")]
    for r in rows:
        assert r["dt"] == pytest.approx(0.01 / r["substeps"])
        assert r["wall_time_per_sim_second"] > 0
        assert r["settled"] is False and r["passed"] is False and r["verdict"] == "not settled"
        direct = tmp_path / f"direct{r['substeps']}"
        assert main(["run", "spike-in-crack", "--substeps", str(r["substeps"]), "--iterations", "4", "--frames",
                     str(FRAMES), "--no-frames", "--quiet", "--out", str(direct)]) == 0
        metrics = json.loads((direct / "metrics.json").read_text())
        for key in ("final_penetration_depth", "max_penetration_depth", "final_overlap_volume", "energy_drift"):
            assert r[key] == pytest.approx(metrics[key], rel=1e-9, abs=1e-15), key
        run_folder = out / "runs" / "spike-in-crack" / f"s{r['substeps']}-i4-f64"
        assert json.loads((run_folder / "metrics.json").read_text())["frames"] == FRAMES
    with Image.open(out / "pareto.png") as image:
        assert image.size[0] >= 600 and image.size[1] >= 400
    assert "recommended: --substeps" in capsys.readouterr().out


def test_a_run_that_explodes_is_a_failed_row_not_a_crash(tmp_path):
    """A scene whose run fails (here: NaN from an absurd initial velocity) comes back as a
    row with the reason; the sweep itself goes on."""
    scene = tmp_path / "bad.toml"
    scene.write_text('[sim]\nframes = 3\n[[body]]\nname = "b"\nkind = "rigid"\nshape = "box"\n'
                     'velocity = [1e308, 1e308, 0.0]\n[[body]]\nname = "g"\nkind = "static"\nshape = "ground"\n'
                     'position = [0.0, -5.0, 0.0]\n')
    row = run_one(SweepRun(str(scene), 1, 1, "f64"), str(tmp_path / "out"), cpu_threads=1)
    assert row["passed"] is False
    assert row["verdict"].startswith("failed: frame 1"), row["verdict"]


def test_pareto_front_matches_brute_force():
    rng = random.Random(3)
    for _ in range(200):
        points = [(rng.choice([1, 2, 3, 4, 5]), rng.choice([1e-6, 1e-5, 1e-4, 1e-3])) for _ in range(rng.randint(1, 12))]
        expected = sorted({p for p in points
                           if not any(q[0] <= p[0] and q[1] <= p[1] and q != p for q in points)})
        # Among equal points one is kept; dominated ties (same cost, higher error) are not.
        assert pareto_front(points) == expected


def test_recommend_picks_the_fastest_setting_that_passes_most_scenes():
    def row(scene, s, i, passed, cost):
        return {"scene": scene, "substeps": s, "iterations": i, "precision": "f64", "passed": passed,
                "wall_time_per_sim_second": cost}
    rows = [row("a", 1, 1, True, 0.01), row("b", 1, 1, False, 0.01),     # cheapest, passes 1 of 2
            row("a", 4, 4, True, 0.20), row("b", 4, 4, True, 0.30),      # passes both, 0.5
            row("a", 8, 4, True, 0.10), row("b", 8, 4, True, 0.15),      # passes both, 0.25: the answer
            row("a", 16, 1, True, 0.01)]                                 # not run on every scene
    best = recommend(rows)
    assert (best["substeps"], best["iterations"], best["passed"], best["scenes"]) == (8, 4, 2, 2)
    assert best["cost"] == pytest.approx(0.25)


@pytest.mark.parametrize("args, culprit", [
    (["--substeps", "0,2"], "must be at least 1"),
    (["--iterations", "two"], "not an integer"),
    (["--precision", "f16"], "'f16' is not one of f32, f64"),
])
def test_bad_sweep_settings_are_usage_errors(tmp_path, args, culprit):
    result = run_cli("sweep", "spikes", *args, "--out", "sw", cwd=tmp_path)
    assert_one_line_error(result, 2, culprit)
    assert not (tmp_path / "sw").exists()


def test_unknown_scene_stops_the_sweep_before_it_starts(tmp_path):
    result = run_cli("sweep", "spikes", "spikez", "--out", "sw", cwd=tmp_path)
    assert_one_line_error(result, 2, "unknown scene 'spikez'")
    assert not (tmp_path / "sw").exists()


def test_sweep_refuses_a_folder_with_other_files(tmp_path):
    (tmp_path / "sw").mkdir()
    (tmp_path / "sw" / "notes.txt").write_text("mine")
    before = snapshot(tmp_path)
    result = run_cli("sweep", "spikes", "--substeps", "1", "--iterations", "1", "--frames", "1", "--out", "sw",
                     cwd=tmp_path)
    assert_one_line_error(result, 2, "notes.txt")
    assert snapshot(tmp_path) == before


def test_ray_gives_the_same_rows_as_the_process_pool(tmp_path):
    """`--ray local` (the cluster extra) runs the same runs as Ray tasks: same rows but for
    the wall times."""
    pytest.importorskip("ray")
    runs = [SweepRun("spike-in-hole", s, 2, "f64") for s in (2, 3)]
    pool = run_sweep(runs, tmp_path / "pool", workers=2, frames=FRAMES, progress=None)
    ray_rows = run_sweep(runs, tmp_path / "ray", workers=2, frames=FRAMES, ray_address="local", progress=None)
    strip = lambda rows: [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]  # noqa: E731
    assert strip(pool) == strip(ray_rows)
    assert read_csv(tmp_path / "ray" / "sweep.csv")[1]["substeps"] == 3
