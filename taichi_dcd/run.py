"""Running a scene into an output folder (DESIGN.md §4): final meshes, metrics.json
(written atomically) and metrics.csv, with progress on stderr."""

from __future__ import annotations

import csv
import json
import os
import sys
import time
from pathlib import Path

from . import runtime
from .scene import Scene
from .solver import SimulationError


def write_json_atomic(path: Path, data: dict) -> None:
    """Write JSON to a temporary file beside `path`, then rename it over `path`."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def run_scene(scene: Scene, out_dir, frames: int | None = None, progress=sys.stderr) -> dict:
    """Simulate `frames` frames (default: the scene's) and write the run's files into out_dir:
    final/<body>.obj, metrics.csv (one row per frame: time, kinetic energy, contacts) and
    metrics.json. Returns the metrics. A failed run (NaN, explosion) or an interrupt still
    writes metrics.json, with "complete": false and the reason."""
    out = Path(out_dir)
    (out / "final").mkdir(parents=True, exist_ok=True)
    sim = scene.config.sim
    frames = sim.frames if frames is None else int(frames)
    rows = []
    error = None
    interrupted = False
    start = time.perf_counter()
    last_report = start
    first_frame_end = None
    try:
        for f in range(frames):
            contacts = scene.step(1)
            rows.append((scene.time, scene.kinetic_energy(), contacts))
            now = time.perf_counter()
            if f == 0:
                first_frame_end = now
            if progress is not None and (now - last_report > 1.0 or f == frames - 1):
                print(f"  frame {f + 1}/{frames}  t = {scene.time:.3f} s  contacts {contacts}  "
                      f"wall {now - start:.1f} s", file=progress, flush=True)
                last_report = now
    except SimulationError as exc:
        error = str(exc)
    except KeyboardInterrupt:
        interrupted = True
    wall = time.perf_counter() - start
    # The first frame compiles the kernels (seconds); the rate is measured without it.
    first_frame = first_frame_end - start if first_frame_end else wall
    steady_time = scene.time - (rows[0][0] if rows else 0.0)
    with open(out / "metrics.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(["time", "kinetic_energy", "contact_count"])
        writer.writerows(rows)
    for name in scene.body_names:
        scene.body_mesh(name).export(out / "final" / f"{name}.obj")
    metrics = {
        "scene": scene.name,
        "frames": len(rows),
        "sim_time": scene.time,
        "wall_time_s": wall,
        "first_frame_wall_s": first_frame,
        "wall_time_per_sim_second": (wall - first_frame) / steady_time if steady_time > 0 else None,
        "nan_detected": error is not None and "NaN" in error,
        "complete": error is None and not interrupted,
        "error": error or ("interrupted" if interrupted else None),
        "final_kinetic_energy": rows[-1][1] if rows else None,
        "contact_buffer_growths": scene.solver.contact_growths,
        "settings": {
            "frame_dt": sim.frame_dt, "dt": sim.frame_dt / sim.substeps, "substeps": sim.substeps,
            "iterations": sim.iterations, "precision": runtime.precision(), "arch": runtime.settings()["arch"],
            "broad_phase": "grid" if scene.solver.use_grid else "all-pairs",
        },
    }
    write_json_atomic(out / "metrics.json", metrics)
    if interrupted:
        raise KeyboardInterrupt
    return metrics
