"""The speed/accuracy study (`taichi-dcd sweep`): every combination of substeps,
iterations and precision for each scene, each run in a fresh process, gathered into
sweep.csv and pareto.png.

A run is one scene at one setting, simulated as `taichi-dcd run NAME --no-frames` would
(its metrics.json, metrics.csv and final meshes under runs/<scene>/<setting>/) and judged
by the contact test's limits (metrics.verdict). Runs go to a pool of spawned worker
processes (a forked child of an initialised Taichi hangs), each running one run after
another, or, with `ray_address`, to Ray tasks; either way the rows are the same.
"""

from __future__ import annotations

import csv
import itertools
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .run import prepare_output

SWEEP_COLUMNS = [
    "scene", "substeps", "iterations", "precision", "dt", "wall_time_per_sim_second", "wall_time_s",
    "final_penetration_depth", "max_penetration_depth", "final_overlap_volume", "settled",
    "time_to_settle", "energy_drift", "passed", "verdict",
]
# Columns that depend on the machine's load, not on the simulation.
TIMING_COLUMNS = ("wall_time_per_sim_second", "wall_time_s")


class SweepError(ValueError):
    """The sweep cannot start (bad settings, Ray unavailable); the message says why."""


@dataclass(frozen=True)
class SweepRun:
    """One scene at one setting."""

    scene: str          # built-in name or scene file path
    substeps: int
    iterations: int
    precision: str

    @property
    def tag(self) -> str:
        return f"s{self.substeps}-i{self.iterations}-{self.precision}"


def sweep_runs(scenes, substeps, iterations, precisions) -> list[SweepRun]:
    """Every combination, scene by scene, cheapest settings first."""
    return [SweepRun(sc, s, i, p) for sc, p, s, i in itertools.product(scenes, precisions, substeps, iterations)]


def run_one(run: SweepRun, out_root: str, arch: str = "cpu", cpu_threads: int | None = 1,
            frames: int | None = None) -> dict:
    """Simulate one run in this process and return its sweep.csv row (a dict of
    SWEEP_COLUMNS). Never raises: a bad scene or a failed simulation is a row whose
    verdict says so. Meant to run in a worker process (Taichi is initialised here with the
    run's precision; a worker's later runs of the same precision reuse its kernels)."""
    os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "False")
    row = {"scene": run.scene, "substeps": run.substeps, "iterations": run.iterations,
           "precision": run.precision, "passed": False}
    try:
        from ..core import runtime
        from ..scene.builtin import scene_config
        from ..measure.penetration import verdict
        from .run import run_scene
        from ..scene.scene import Scene

        config = scene_config(run.scene)
        row["scene"] = config.name
        config.sim.substeps, config.sim.iterations = run.substeps, run.iterations
        runtime.init(arch=arch, precision=run.precision, cpu_threads=cpu_threads)
        scene = Scene(config)
        out = Path(out_root) / "runs" / config.name / run.tag
        metrics = run_scene(scene, out, frames=frames, progress=None, render=False, notices=None)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # noqa: BLE001 — the row carries the reason; the sweep goes on
        row["verdict"] = f"error: {type(exc).__name__}: {exc}".replace("\n", " ")
        return row
    for key in SWEEP_COLUMNS:
        if key in metrics:
            row[key] = metrics[key]
    row["dt"] = metrics["settings"]["dt"]
    reason = verdict(metrics)
    row["passed"] = reason is None
    row["verdict"] = reason or "pass"
    return row


class ProgressBar:
    """A one-line bar on a terminal (a line per run otherwise): runs done, passed, time left."""

    def __init__(self, total: int, stream=sys.stderr, width: int = 30):
        self.total, self.stream, self.width = total, stream, width
        self.done = self.passed = 0
        self.start = time.perf_counter()
        self.tty = stream is not None and hasattr(stream, "isatty") and stream.isatty()

    def update(self, run: SweepRun, row: dict) -> None:
        self.done += 1
        self.passed += bool(row.get("passed"))
        if self.stream is None:
            return
        elapsed = time.perf_counter() - self.start
        left = elapsed / self.done * (self.total - self.done)
        filled = int(self.width * self.done / self.total)
        line = (f"sweep [{'#' * filled}{'.' * (self.width - filled)}] {self.done}/{self.total} runs, "
                f"{self.passed} passed, {_minutes(elapsed)} elapsed, ~{_minutes(left)} left  "
                f"| {row['scene']} {run.tag}: {row.get('verdict')}")
        if self.tty:
            print("\r" + line[:200].ljust(200), end="" if self.done < self.total else "\n",
                  file=self.stream, flush=True)
        else:
            print(line, file=self.stream, flush=True)


def _minutes(seconds: float) -> str:
    return f"{int(seconds // 60)}m{int(seconds % 60):02d}s"


def _run_in_pool(jobs, workers: int, bar: ProgressBar) -> list[dict]:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    rows: list[dict | None] = [None] * len(jobs)
    # Spawned workers (a forked child of an initialised Taichi hangs), each running one run
    # after another: a run after the first of its precision and kind of scene reuses the
    # kernels compiled for it (core.pool), which a fresh process per run compiled again.
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
    try:
        futures = {pool.submit(run_one, *job): k for k, job in enumerate(jobs)}
        for future in as_completed(futures):
            k = futures[future]
            try:
                rows[k] = future.result()
            except Exception as exc:  # noqa: BLE001 — a crashed process is that run's failure
                rows[k] = _failed_row(jobs[k][0], f"process failed: {type(exc).__name__}: {exc}")
            bar.update(jobs[k][0], rows[k])
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    return rows


def _run_on_ray(jobs, address: str, workers: int, bar: ProgressBar) -> list[dict]:
    try:
        import ray
    except ImportError:
        raise SweepError("--ray needs Ray: pip install 'taichi_dcd[cluster]'") from None
    local = address == "local"
    try:
        if local:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                     configure_logging=False)
        else:
            ray.init(address=address, log_to_driver=False, configure_logging=False)
    except Exception as exc:  # noqa: BLE001 — Ray raises many types for a bad address
        raise SweepError(f"cannot connect to the Ray cluster at {address!r}: {exc}".replace("\n", " ")) from None
    try:
        # One CPU and one fresh worker process per run, like the pool.
        task = ray.remote(num_cpus=1, max_calls=1)(run_one)
        pending = {task.remote(*job): k for k, job in enumerate(jobs)}
        rows: list[dict | None] = [None] * len(jobs)
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                k = pending.pop(ref)
                try:
                    rows[k] = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 — a lost worker is that run's failure
                    rows[k] = _failed_row(jobs[k][0], f"ray task failed: {type(exc).__name__}")
                bar.update(jobs[k][0], rows[k])
        return rows
    finally:
        ray.shutdown()


FAILED_PREFIXES = ("failed", "error", "process failed", "ray task failed")


def run_failed(row: dict) -> bool:
    """Whether a row's run did not complete (NaN, explosion, a bad scene, a lost process),
    as opposed to completing and failing the contact test."""
    return str(row.get("verdict", "")).startswith(FAILED_PREFIXES)


def _failed_row(run: SweepRun, reason: str) -> dict:
    return {"scene": run.scene, "substeps": run.substeps, "iterations": run.iterations,
            "precision": run.precision, "passed": False, "verdict": reason}


def run_sweep(runs: list[SweepRun], out_dir, workers: int | None = None, arch: str = "cpu",
              frames: int | None = None, ray_address: str | None = None, force: bool = False,
              progress=sys.stderr) -> list[dict]:
    """Run every SweepRun in its own process and write out_dir/sweep.csv (one row per run,
    SWEEP_COLUMNS, in the order of `runs`) and out_dir/pareto.png. `workers` processes at
    a time (default: one per CPU core), each Taichi on cpu_count/workers threads (at least
    one). Returns the rows. Raises OutputError for a folder holding other files (unless
    `force`), SweepError when Ray is asked for and cannot be used."""
    if not runs:
        raise SweepError("nothing to sweep: no scenes or no settings")
    cores = os.cpu_count() or 1
    workers = max(1, min(workers or cores, len(runs)))
    threads = max(1, cores // workers)
    out = Path(out_dir)
    prepare_output(out, ["sweep.csv", "pareto.png"], force=force, folders=("runs",))
    jobs = [(run, str(out), arch, 1 if ray_address else threads, frames) for run in runs]
    bar = ProgressBar(len(jobs), progress)
    if ray_address:
        rows = _run_on_ray(jobs, ray_address, workers, bar)
    else:
        rows = _run_in_pool(jobs, workers, bar)
    write_csv(out / "sweep.csv", rows)
    plot_pareto(rows, out / "pareto.png")
    return rows


def write_csv(path: Path, rows: list[dict]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, SWEEP_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in SWEEP_COLUMNS})
    os.replace(tmp, path)


def read_csv(path) -> list[dict]:
    """sweep.csv back as rows with numbers and booleans parsed (empty cells are None)."""
    ints = {"substeps", "iterations"}
    text = {"scene", "precision", "verdict"}
    rows = []
    with open(path, newline="", encoding="utf-8") as fh:
        for raw in csv.DictReader(fh):
            row = {}
            for k, v in raw.items():
                if v == "" or k in text:
                    row[k] = v if k in text else None
                elif k in ("settled", "passed"):
                    row[k] = v == "True"
                else:
                    row[k] = int(v) if k in ints else float(v)
            rows.append(row)
    return rows


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The points (cost, error) that no other point beats in both, cheapest first."""
    front, best = [], float("inf")
    for cost, error in sorted(points):
        if error < best:
            front.append((cost, error))
            best = error
    return front


def recommend(rows: list[dict]) -> dict | None:
    """The setting (substeps, iterations, precision) that passes the most scenes, the
    fastest (summed wall time per simulated second) among those; None without complete
    settings. Returns {"substeps", "iterations", "precision", "passed", "scenes", "cost"}."""
    scenes = sorted({r["scene"] for r in rows})
    by_setting: dict[tuple, list[dict]] = {}
    for r in rows:
        by_setting.setdefault((r["substeps"], r["iterations"], r["precision"]), []).append(r)
    best = None
    for (s, i, p), group in by_setting.items():
        if sorted(r["scene"] for r in group) != scenes:
            continue
        passed = sum(bool(r.get("passed")) for r in group)
        cost = sum(r.get("wall_time_per_sim_second") or float("inf") for r in group)
        key = (-passed, cost)
        if best is None or key < best[0]:
            best = (key, {"substeps": s, "iterations": i, "precision": p, "passed": passed,
                          "scenes": len(scenes), "cost": cost})
    return best[1] if best else None


# Depths at or below this are drawn on the plot's floor (a log axis has no zero).
PLOT_FLOOR = 1e-12


def plot_pareto(rows: list[dict], path: Path) -> None:
    """Wall time per simulated second against maximum penetration depth, log-log, one
    colour per scene (filled f64, hollow f32, × for runs that errored, a black ring around
    runs that ended but failed the contact test), each scene's Pareto front as a line, and the
    contact test's 5 mm limit."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..measure.penetration import PASS_MAX_DEPTH

    fig, ax = plt.subplots(figsize=(9, 6), dpi=100)
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    colors = plt.get_cmap("tab10")
    for k, scene in enumerate(scenes):
        color = colors(k % 10)
        mine = [r for r in rows if r["scene"] == scene and r.get("wall_time_per_sim_second")
                and r.get("max_penetration_depth") is not None]
        done = [r for r in mine if not run_failed(r)]
        for precision, face in (("f64", color), ("f32", "none")):
            pts = [r for r in done if r["precision"] == precision]
            if pts:
                ax.scatter([r["wall_time_per_sim_second"] for r in pts],
                           [max(r["max_penetration_depth"], PLOT_FLOOR) for r in pts],
                           s=28, facecolors=face, edgecolors=color, linewidths=1.2,
                           label=f"{scene} ({precision})")
        judged_failed = [r for r in done if r.get("passed") is False]
        if judged_failed:
            ax.scatter([r["wall_time_per_sim_second"] for r in judged_failed],
                       [max(r["max_penetration_depth"], PLOT_FLOOR) for r in judged_failed],
                       s=70, facecolors="none", edgecolors="black", linewidths=0.8)
        broken = [r for r in mine if r not in done]
        if broken:
            ax.scatter([r["wall_time_per_sim_second"] for r in broken],
                       [max(r["max_penetration_depth"], PLOT_FLOOR) for r in broken], marker="x", color=color)
        front = pareto_front([(r["wall_time_per_sim_second"], max(r["max_penetration_depth"], PLOT_FLOOR))
                              for r in done])
        if front:
            ax.step([c for c, _ in front], [e for _, e in front], where="post", color=color, linewidth=1.5)
    ax.axhline(PASS_MAX_DEPTH, color="black", linestyle="--", linewidth=1)
    ax.set_xscale("log")
    ax.set_yscale("log")
    # x in the axes' own fraction: placed in data units before the log scale, it left the plot.
    ax.text(0.01, PASS_MAX_DEPTH, "5 mm limit", va="bottom", fontsize=8, transform=ax.get_yaxis_transform())
    ax.set_xlabel("wall time per simulated second (s)")
    ax.set_ylabel("maximum penetration depth over the run (m)")
    ax.set_title("Speed against accuracy\n(lines: each scene's Pareto front; black ring: failed the "
                 "contact test; ×: run errored)", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    if scenes:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    tmp = path.with_name(path.name + ".tmp")
    fig.savefig(tmp, format="png")
    plt.close(fig)
    os.replace(tmp, path)


def parse_list(text: str, kind: type, allowed=None) -> list:
    """'1,2,4' → [1, 2, 4] (or strings for kind=str), checked; ValueError in words."""
    items = [t.strip() for t in text.split(",") if t.strip()]
    if not items:
        raise ValueError(f"empty list {text!r}")
    values = []
    for item in items:
        if kind is int:
            try:
                v = int(item)
            except ValueError:
                raise ValueError(f"not an integer: {item!r}") from None
            if v < 1:
                raise ValueError(f"must be at least 1, got {v}")
        else:
            v = item
            if allowed and v not in allowed:
                raise ValueError(f"{v!r} is not one of {', '.join(allowed)}")
        if v not in values:
            values.append(v)
    return values
