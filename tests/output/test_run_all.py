"""`taichi-dcd run all` side by side in worker processes writes what it writes in one process."""

import json

import pytest
from cli_helpers import run_cli, snapshot

# metrics.json keys that time the run on the machine rather than describe the simulation.
WALL_KEYS = ("wall_time_s", "first_frame_wall_s", "wall_time_per_sim_second")


@pytest.mark.slow  # two whole `run all`s, each compiling its frame kernels: ~75 s
def test_run_all_in_two_processes_writes_the_same_files_as_in_one(tmp_path):
    """Every file the same bytes (frames, metrics.csv, final meshes, plots, contact sheet),
    metrics.json the same but for its wall times; index.html shows those and is left out."""
    folders = {}
    for jobs in ("1", "2"):
        out = tmp_path / f"jobs-{jobs}"
        result = run_cli("run", "all", "--frames", "2", "--jobs", jobs, "--quiet", "--out", str(out), cwd=tmp_path,
                         timeout=600)
        assert result.returncode == 0, result.stderr
        folders[jobs] = out
    one, two = (snapshot(folders[j]) for j in ("1", "2"))
    assert sorted(one) == sorted(two)
    assert any(name.endswith("frames/frame_00002.png") for name in one)
    for name in one:
        if name == "index.html":
            continue
        if name.endswith("metrics.json"):
            a, b = (json.loads((folders[j] / name).read_text()) for j in ("1", "2"))
            for key in WALL_KEYS:
                a.pop(key), b.pop(key)
            assert a == b, name
        else:
            assert one[name] == two[name], name
