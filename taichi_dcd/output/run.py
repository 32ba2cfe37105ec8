"""Running a scene into an output folder (docs/scene-format.md, 'Output folder'): frames, final meshes,
metrics.json (written atomically) and metrics.csv, with progress on stderr."""

from __future__ import annotations

import csv
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

from ..core import runtime
from ..core.model import RIGID
from ..scene.scene import Scene
from ..solver.solver import SimulationError


def write_json_atomic(path: Path, data: dict) -> None:
    """Write JSON to a temporary file beside `path`, then rename it over `path`."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    os.replace(tmp, path)


MANIFEST = ".taichi-dcd-run.json"   # the files a run wrote, so that a re-run replaces only those
FRAME_PATTERN = "frame_[0-9][0-9][0-9][0-9][0-9].png"


class OutputError(ValueError):
    """The output folder cannot be used without losing files the run did not write."""


def run_files(body_names: list[str]) -> list[str]:
    """The files a run writes besides its frames, relative to the output folder."""
    return ["metrics.json", "metrics.csv", "plots.png", "animation.gif"] + [f"final/{n}.obj" for n in body_names]


def _manifest_list(folder: Path, key: str) -> list[str]:
    """The strings under `key` in folder's manifest; [] without one."""
    try:
        listed = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))[key]
    except (OSError, ValueError, KeyError, TypeError):
        return []
    return [name for name in listed if isinstance(name, str)] if isinstance(listed, list) else []


def manifest_files(folder: Path) -> list[str]:
    """The files (relative paths) that folder's manifest says this tool wrote; [] without one."""
    return _manifest_list(folder, "files")


def _files_of_earlier_run(out: Path) -> set[Path]:
    """Files in `out` that an earlier run recorded as its own (with their .tmp siblings):
    the files its manifest lists, its frames, and everything under the folders it lists."""
    listed = manifest_files(out)
    if not listed:
        return set()
    ours = {out / name for name in listed}
    ours |= set((out / "frames").glob(FRAME_PATTERN))
    for folder in _manifest_list(out, "folders"):
        if folder and ".." not in Path(folder).parts:
            ours |= {p for p in (out / folder).rglob("*") if p.is_file() or p.is_symlink()}
    ours |= {p.with_name(p.name + ".tmp") for p in list(ours)}
    return ours


def prepare_output(out: Path, files: list[str], force: bool = False, folders: tuple[str, ...] = ()) -> None:
    """Make `out` ready for a run that writes `files` (paths relative to `out`; frames too,
    frames/frame_NNNNN.png, and whatever goes under `folders`): create it, or reuse an
    earlier run's folder after deleting that run's files (and only those). A folder holding
    anything else is refused unless `force`; even then a file of someone else's with a name
    the run writes is never overwritten. Raises OutputError naming the folder or the file."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"output folder {out} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    ours = _files_of_earlier_run(out)
    present = {p for p in out.rglob("*") if p.is_file() or p.is_symlink()}
    foreign = sorted(present - ours - {out / MANIFEST})
    if foreign and not force:
        raise OutputError(f"output folder {out} holds files this tool did not write (e.g. "
                          f"{foreign[0].relative_to(out)}); choose another --out or pass --force")
    ours_next = {out / name for name in files}
    clash = [p for p in foreign if p in ours_next or (p.parent == out / "frames" and p.match(FRAME_PATTERN))
             or any(out / f in p.parents for f in folders)]
    if clash:
        raise OutputError(f"{clash[0]} was not written by this tool and would be overwritten; "
                          "choose another --out")
    for p in ours & present:
        p.unlink()
    write_json_atomic(out / MANIFEST, {"written_by": "taichi-dcd", "files": list(files),
                                       "folders": list(folders), "frames": f"frames/{FRAME_PATTERN}"})


class FrameWriter:
    """Renders the scene's frames to frames/frame_NNNNN.png with a camera fixed at the start,
    framing every body but static ones much larger than the moving ones (a ground), widened
    on x and z by the largest moving body's size so that a toppled body stays in view."""

    def __init__(self, scene: Scene, out: Path, width: int = 800, height: int = 600, contacts: bool = False,
                 gif: bool = False):
        from .render import Rasterizer, body_colors, framing_camera

        self.scene, self.dir, self.contacts = scene, out / "frames", contacts
        self.dir.mkdir(parents=True, exist_ok=True)
        self.rasterizer = Rasterizer(width, height)
        bodies = scene.model.bodies
        colors = body_colors([b.kind for b in bodies])
        self.faces = np.concatenate([b.faces + b.vertex_start for b in bodies])
        self.face_rgb = np.concatenate([np.tile(colors[k], (b.tri_count, 1)) for k, b in enumerate(bodies)])
        # Rigid and static bodies are closed and outward-oriented (scene.mesh_check) and keep
        # their shape, so their faces turned away are never seen; soft ones may fold over.
        self.one_sided = np.concatenate([np.full(b.tri_count, b.kind in ("rigid", "static")) for b in bodies])
        x = scene.vertices()
        boxes = [(x[b.vertex_start:b.vertex_start + b.vertex_count].min(axis=0),
                  x[b.vertex_start:b.vertex_start + b.vertex_count].max(axis=0)) for b in bodies]
        moving = [bx for bx, b in zip(boxes, bodies) if b.kind != "static"] or boxes
        reach = max(float(np.linalg.norm(hi - lo)) for lo, hi in moving)
        framed = [bx for bx, b in zip(boxes, bodies)
                  if b.kind != "static" or np.linalg.norm(bx[1] - bx[0]) <= 3.0 * reach]
        lo, hi = np.min([lo for lo, _ in framed], axis=0), np.max([hi for _, hi in framed], axis=0)
        # A body that topples lands up to its own size away: keep that ring in view.
        size = max(float(np.max(bx[1] - bx[0])) for bx in moving)
        ring = np.array([size, 0.0, size])
        self.camera = framing_camera(lo - ring, hi + ring)
        self.gif_frames = [] if gif else None
        self.count = 0

    def write(self, vertices: np.ndarray) -> None:
        """Render the scene with its vertices (V, 3) as the next frame."""
        from .render import write_png

        points = self.scene.contact_points() if self.contacts else None
        image = self.rasterizer.render(vertices, self.faces, self.face_rgb, self.camera, points,
                                       one_sided=self.one_sided)
        path = self.dir / f"frame_{self.count:05d}.png"
        tmp = path.with_name(path.name + ".tmp")  # an interrupt never leaves half a PNG
        try:
            write_png(tmp, image)
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        if self.gif_frames is not None and self.count % GIF_EVERY == 0:
            self.gif_frames.append(image[::2, ::2].copy())
        self.count += 1

    def write_gif(self, path: Path, frame_dt: float) -> None:
        from PIL import Image

        if not self.gif_frames:
            return
        images = [Image.fromarray(f) for f in self.gif_frames]
        tmp = path.with_name(path.name + ".tmp")
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], loop=0,
                       duration=max(20, int(round(1000 * frame_dt * GIF_EVERY))))
        os.replace(tmp, path)


# The GIF keeps every GIF_EVERY-th frame at half resolution (real time at 0.01 s frames).
GIF_EVERY = 4
# A scene without sim.sleep whose every body has been at rest (SettleClock) this long (s, times
# √length_scale) gets one notice that sleeping would stop simulating it.
REST_NOTICE_TIME = 1.0
CSV_COLUMNS = ["time", "penetration_depth", "overlap_volume", "kinetic_energy", "potential_energy",
               "contact_count", "max_vertex_speed"]
# With soft bodies: their own crossing triangle pairs and the deepest (Scene.self_penetration).
SELF_COLUMNS = ["self_intersections", "self_penetration_depth"]


class SettleClock:
    """Whether a scene has settled: every vertex slower than sim.settle_speed (m/s, its
    displacement over a frame / frame_dt) for sim.settle_time seconds."""

    def __init__(self, sim):
        self.sim = sim
        self.calm_since: float | None = None  # s: start of the frame since which all has been calm

    def update(self, time_s: float, max_vertex_speed: float) -> bool:
        """Feed the frame that ended at `time_s`; True once settled."""
        if max_vertex_speed < self.sim.settle_speed:
            if self.calm_since is None:
                self.calm_since = time_s - self.sim.frame_dt
        else:
            self.calm_since = None
        return self.calm_since is not None and time_s - self.calm_since >= self.sim.settle_time * (1 - 1e-9)

    def at_rest_for(self, time_s: float) -> float:
        """s for which every vertex has been calm at `time_s` (0 if it is not)."""
        return 0.0 if self.calm_since is None else time_s - self.calm_since


def energy_drift(energy_start: float, kinetic, potential) -> float:
    """The largest rise of mechanical energy (kinetic + gravitational) above its value at
    the start, as a fraction of the largest kinetic energy reached: > 0 means the run gained
    energy it was never given; a drop test that loses energy to contact gives ≤ 0."""
    kinetic, potential = np.asarray(kinetic, float), np.asarray(potential, float)
    if kinetic.size == 0 or not kinetic.max() > 0.0:
        return 0.0
    with np.errstate(over="ignore", invalid="ignore"):  # a failed run's energies may be inf
        return float(np.max(kinetic + potential - energy_start) / kinetic.max())


def run_scene(scene: Scene, out_dir, frames: int | None = None, progress=sys.stderr, render: bool = False,
              gif: bool = False, draw_contacts: bool = False, force: bool = False, notices=sys.stderr) -> dict:
    """Simulate `frames` frames (default: the scene's; fewer once settled if the scene's
    sim.stop_when_settled) and write the run's files into out_dir (docs/scene-format.md, 'Output folder'):
    final/<body>.obj, metrics.csv (one row per frame), metrics.json, and with `render`
    frames/frame_NNNNN.png (frame 0 = the initial state), with `gif` animation.gif.
    Penetration is measured every frame from the meshes alone (measure/penetration.py). Returns the
    metrics. A failed run (NaN, explosion) or an interrupt still writes metrics.json, with
    "complete": false and the reason, and final meshes of the last good frame. The folder is
    checked first (prepare_output: OutputError); contact buffer growth is reported on
    `notices` when it happens."""
    out = Path(out_dir)
    prepare_output(out, run_files(scene.body_names), force)
    (out / "final").mkdir(parents=True, exist_ok=True)
    sim = scene.config.sim
    frames = sim.frames if frames is None else int(frames)
    writer = FrameWriter(scene, out, contacts=draw_contacts, gif=gif) if render else None
    moving = scene.moving_vertex_mask()
    last_good = scene.vertices()
    if writer:
        writer.write(last_good)
    x_prev = last_good[moving]
    energy_start = scene.kinetic_energy() + scene.potential_energy()
    growths = scene.solver.contact_growths
    fast_reported = False
    rest_reported = sim.sleep or not (scene.model.body_kind_np == RIGID).any()
    rows = []
    error = None
    interrupted = False
    clock = SettleClock(sim)
    settled = False
    max_depth = 0.0
    has_soft = scene.model.has_soft
    columns = CSV_COLUMNS + (SELF_COLUMNS if has_soft else [])
    self_measure = {b.name: {"self_collision": b.self_collision, "final_pairs": 0, "max_depth": 0.0}
                    for b in scene.model.bodies if b.deformable}
    measured_pairs = apart_pairs = 0
    step_times = []             # wall time of each frame's simulation alone
    start = time.perf_counter()
    last_report = start
    first_frame_end = None
    try:
        for f in range(frames):
            t0 = time.perf_counter()
            try:
                contacts = scene.step(1)
            except SimulationError as exc:
                raise SimulationError(f"frame {f + 1}: {exc}") from None
            step_times.append(time.perf_counter() - t0)
            if scene.fast_notice and not fast_reported and notices is not None:
                print(f"taichi-dcd: frame {f + 1}: {scene.fast_notice}", file=notices, flush=True)
                fast_reported = True
            if scene.solver.contact_growths != growths and notices is not None:
                growths = scene.solver.contact_growths
                print(f"taichi-dcd: frame {f + 1}: contact buffer grown to {scene.solver.contacts.capacity} rows "
                      "(the frame was rerun)", file=notices, flush=True)
            last_good = scene.vertices()
            x = last_good[moving]
            speed = float(np.max(np.linalg.norm(x - x_prev, axis=1)) / sim.frame_dt) if len(x) else 0.0
            x_prev = x
            pen = scene.penetration(last_good)
            measured_pairs += pen.pairs
            apart_pairs += pen.pairs_apart
            max_depth = max(max_depth, pen.depth)
            row = (scene.time, pen.depth, pen.volume, scene.kinetic_energy(), scene.potential_energy(),
                   contacts, speed)
            if has_soft:
                per_body = scene.self_penetration(last_good)
                for name, (crossing, self_depth) in per_body.items():
                    self_measure[name]["final_pairs"] = crossing
                    self_measure[name]["max_depth"] = max(self_measure[name]["max_depth"], self_depth)
                row += (sum(c for c, _ in per_body.values()), max(d for _, d in per_body.values()))
            rows.append(row)
            if writer:
                writer.write(last_good)
            settled = clock.update(scene.time, speed)
            if not rest_reported and notices is not None and clock.at_rest_for(scene.time) >= REST_NOTICE_TIME * np.sqrt(
                    sim.length_scale):
                print(f"taichi-dcd: frame {f + 1}: every body has been at rest since t = {clock.calm_since:.3g} s and "
                      "is still simulated in full; `sleep = true` under [sim] stops simulating bodies at rest "
                      "(docs/scene-format.md)", file=notices, flush=True)
                rest_reported = True
            now = time.perf_counter()
            if f == 0:
                first_frame_end = now
            if progress is not None and (now - last_report > 1.0 or f == frames - 1 or settled):
                print(f"  frame {f + 1}/{frames}  t = {scene.time:.3f} s  contacts {contacts}  "
                      f"depth {pen.depth:.2e} m  speed {speed:.1e} m/s  wall {now - start:.1f} s",
                      file=progress, flush=True)
                last_report = now
            if settled and sim.stop_when_settled:
                break
    except SimulationError as exc:
        error = str(exc)
    except KeyboardInterrupt:
        interrupted = True
    wall = time.perf_counter() - start
    # The first frame compiles the kernels (seconds); the rate is measured without it, and
    # without the rendering and penetration measurement around the steps.
    first_frame = first_frame_end - start if first_frame_end else wall
    steady_time = sim.frame_dt * (len(step_times) - 1)
    with open(out / "metrics.csv.tmp", "w", newline="", encoding="utf-8") as fh:
        csv_writer = csv.writer(fh)
        csv_writer.writerow(columns)
        csv_writer.writerows(rows)
    os.replace(out / "metrics.csv.tmp", out / "metrics.csv")
    for b in scene.model.bodies:
        mesh = trimesh.Trimesh(last_good[b.vertex_start:b.vertex_start + b.vertex_count], b.faces, process=False)
        mesh.export(out / "final" / f"{b.name}.obj")
    if writer and gif:
        writer.write_gif(out / "animation.gif", sim.frame_dt)
    if rows:
        from .report import PLOTS, plot_run

        plot_run({name: np.array([r[k] for r in rows], dtype=np.float64) for k, name in enumerate(columns)},
                 out / PLOTS, scene.name, sim.length_scale)
    final = rows[-1] if rows else (0.0, 0.0, 0.0, 0.0, 0.0, 0, 0.0)
    metrics = {
        "scene": scene.name,
        "frames": len(rows),
        "sim_time": scene.time,
        "wall_time_s": wall,
        "first_frame_wall_s": first_frame,
        "wall_time_per_sim_second": sum(step_times[1:]) / steady_time if steady_time > 0 else None,
        "final_penetration_depth": final[1],
        "max_penetration_depth": max_depth,
        "final_overlap_volume": final[2],
        "settled": settled,
        "time_to_settle": clock.calm_since if settled else None,
        "final_max_vertex_speed": final[6],
        "nan_detected": error is not None and "NaN" in error,
        "complete": error is None and not interrupted,
        "error": error or ("interrupted" if interrupted else None),
        "final_kinetic_energy": final[3],
        "energy_drift": energy_drift(energy_start, [r[3] for r in rows], [r[4] for r in rows]),
        "start_overlaps": scene.start_overlaps,
        # The independent measure ran on every frame; pairs whose boxes were apart cost no
        # boolean (their overlap is 0). Nothing is reused between frames.
        "measure": {"frames": len(rows), "body_pairs": measured_pairs, "body_pairs_apart": apart_pairs},
        "contact_buffer_growths": scene.solver.contact_growths,
        "frames_with_extra_substeps": scene.fast_frames,
        "most_substeps_in_a_frame": scene.most_substeps,
        "sleeping_bodies": scene.sleeping_bodies(),
        # Soft bodies only: pairs of a body's own triangles that cross (measure.self_intersection).
        **({"self_intersection": self_measure} if has_soft else {}),
        "settings": {
            "frame_dt": sim.frame_dt, "dt": sim.frame_dt / sim.substeps, "substeps": sim.substeps,
            "iterations": sim.iterations, "precision": runtime.precision(), "arch": runtime.settings()["arch"],
            "broad_phase": "grid" if scene.solver.use_grid else "all-pairs",
            "stop_when_settled": sim.stop_when_settled, "length_scale": sim.length_scale, "sleep": sim.sleep,
        },
    }
    write_json_atomic(out / "metrics.json", metrics)
    if interrupted:
        raise KeyboardInterrupt
    return metrics
