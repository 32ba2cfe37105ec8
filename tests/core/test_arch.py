"""`--arch cuda`: the same run as on the CPU where a GPU is present, a one-line error where not."""

import json

import numpy as np
import trimesh
from cli_helpers import assert_one_line_error, run_cli

# Few frames: on a GPU the serial solve runs on one GPU thread. The spike starts 0.1 mm above
# the groove's bottom, so it is in contact from the first frame.
RUN = ("run", "spike-in-crack", "--frames", "10", "--no-frames", "--quiet")


def test_cuda_run_gives_the_cpu_result_or_says_cuda_is_missing(tmp_path):
    """On a machine with a CUDA GPU, 10 frames of `spike-in-crack` on `--arch cuda` end with
    the spike where the CPU puts it (within 1e-6 m: the kernels are the same, the rounding
    order of a GPU's arithmetic may differ) and the same depths. Without one (CI), the run
    stops before writing anything: one line naming the arch, exit status 2, no output folder."""
    cuda = run_cli(*RUN, "--arch", "cuda", "--out", str(tmp_path / "cuda"), cwd=tmp_path, timeout=900)
    if "could not start on arch 'cuda'" in cuda.stderr:
        assert_one_line_error(cuda, 2, "cuda")
        assert not (tmp_path / "cuda").exists()
        return
    assert cuda.returncode == 0, cuda.stderr
    cpu = run_cli(*RUN, "--arch", "cpu", "--out", str(tmp_path / "cpu"), cwd=tmp_path)
    assert cpu.returncode == 0, cpu.stderr
    on_gpu = json.loads((tmp_path / "cuda" / "metrics.json").read_text())
    on_cpu = json.loads((tmp_path / "cpu" / "metrics.json").read_text())
    assert on_gpu["complete"] and on_gpu["frames"] == on_cpu["frames"]
    for key in ("max_penetration_depth", "final_penetration_depth"):
        assert abs(on_gpu[key] - on_cpu[key]) <= 1e-6, key
    spike_gpu = trimesh.load(tmp_path / "cuda" / "final" / "dropped_spike.obj", process=False).vertices
    spike_cpu = trimesh.load(tmp_path / "cpu" / "final" / "dropped_spike.obj", process=False).vertices
    assert np.abs(spike_gpu - spike_cpu).max() <= 1e-6


def test_cuda_sweep_runs_or_stops_before_any_run(tmp_path):
    """`sweep --arch cuda` without a GPU stops before starting a run: one line naming the
    arch, exit status 2, no output folder (it used to run every setting into the same
    error and recommend one of them). With a GPU the one run completes."""
    out = tmp_path / "sweep"
    result = run_cli("sweep", "spike-in-crack", "--substeps", "2", "--iterations", "2", "--frames", "3",
                     "--arch", "cuda", "--quiet", "--out", str(out), cwd=tmp_path, timeout=900)
    if "could not start on arch 'cuda'" in result.stderr:
        assert_one_line_error(result, 2, "cuda")
        assert not out.exists()
        return
    assert result.returncode == 0, result.stderr
    assert (out / "sweep.csv").read_text().count("\n") == 2
