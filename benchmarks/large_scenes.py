"""The large scenes (issue 6): `pile` (100 spikes and wedges onto a bed of cracks and holes,
63,756 triangles) and `spike-in-crack-hires` (every body remeshed to >= 20k triangles,
98,304 in all), run until settled (every vertex slower than 1e-3 m/s for 0.2 s) or 5 s.

Prints, per scene: its setting (substeps x sweeps), triangles, frames, wall time per
simulated second (kernel compilation, i.e. the first frame, not timed), the share of the
stepping time spent predicting, in the broad phase, the narrow phase, projection (contacts
+ velocities) and the rest (Python per frame: the substep choice, reading state back), peak
resident memory of the process (and its size after Taichi's start, before the scene), the
most substeps a frame took, and the penetration by the independent measure (measure/penetration.py):
deepest over the frames it was taken on (every --measure-every frames and the last) and at
the end, with the overlap volume at the end.

Usage: python benchmarks/large_scenes.py [SCENE ...] [--frames N] [--measure-every K]
                                         [--threads T] [--arch cpu|cuda]
                                         [--substeps S] [--iterations I] [--progress-every P]
"""

import argparse
import multiprocessing
import resource
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from common import machine_line

import taichi_dcd
from taichi_dcd.scene.builtin import LARGE, builtin_scene

PHASES = ("predict", "broad", "narrow", "projection")


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux reports KiB


def bench(name: str, frames: int | None, measure_every: int, arch: str, threads: int | None,
          substeps: int | None = None, iterations: int | None = None, progress_every: int = 50) -> dict:
    """One scene in this (fresh, spawned) process, so that its peak memory is its own."""
    from taichi_dcd.output.run import SettleClock
    from taichi_dcd.scene.scene import Scene

    taichi_dcd.init(arch=arch, precision="f64", cpu_threads=threads)
    config = builtin_scene(name)
    sim = config.sim
    sim.substeps = substeps or sim.substeps
    sim.iterations = iterations or sim.iterations
    frames = frames or sim.frames
    rss_before = peak_rss_mib()
    build_start = time.perf_counter()
    scene = Scene(config)
    build = time.perf_counter() - build_start
    scene.solver.phase_seconds = {}
    x_prev = scene.vertices()
    clock = SettleClock(sim)
    deepest = 0.0
    step_wall = 0.0
    settled = False
    f = 0
    for f in range(frames):
        t0 = time.perf_counter()
        scene.step(1)
        wall = time.perf_counter() - t0
        if f == 0:
            scene.solver.phase_seconds = {}  # the first frame compiles
        else:
            step_wall += wall
        x = scene.vertices()
        speed = float(np.max(np.linalg.norm(x - x_prev, axis=1))) / sim.frame_dt
        x_prev = x
        settled = clock.update(scene.time, speed)
        if (f + 1) % measure_every == 0:
            deepest = max(deepest, scene.penetration(x).depth)
        if (f + 1) % progress_every == 0 or settled:
            print(f"  {name}: frame {f + 1}  t = {scene.time:.2f} s  speed {speed:.1e} m/s  "
                  f"stepping {step_wall:.1f} s  substeps {scene.most_substeps}  asleep {len(scene.sleeping_bodies())}", file=sys.stderr, flush=True)
        if settled:
            break
    final = scene.penetration(scene.vertices())
    speeds = np.linalg.norm(scene.body_velocities(), axis=1)
    fastest = int(np.argmax(speeds))
    if not settled:
        print(f"  {name}: not settled; fastest body {scene.body_names[fastest]!r} at {speeds[fastest]:.2g} m/s, "
              f"at {np.round(scene.body_positions()[fastest], 2).tolist()}", file=sys.stderr, flush=True)
    phases = scene.solver.phase_seconds
    shares = {p: phases.get(p, 0.0) / step_wall for p in PHASES}
    shares["other"] = 1.0 - sum(shares.values())
    return dict(name=name, setting=f"{sim.substeps} x {sim.iterations}", tris=scene.model.n_tris,
                bodies=len(scene.model.bodies), frames=f + 1,
                settled=settled, sim_time=scene.time, build_s=build,
                per_sim_s=step_wall / max(sim.frame_dt * f, 1e-12), shares=shares,
                peak_mib=peak_rss_mib(), rss_before=rss_before, most_substeps=scene.most_substeps,
                deepest=max(deepest, final.depth), final_depth=final.depth, final_volume=final.volume)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenes", nargs="*", default=list(LARGE), help=f"default: {' '.join(LARGE)}")
    parser.add_argument("--frames", type=int, default=None, help="most frames (default: the scene's, 5 s)")
    parser.add_argument("--measure-every", type=int, default=10, help="frames between penetration measures")
    parser.add_argument("--threads", type=int, default=None, help="CPU threads (default: all)")
    parser.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    parser.add_argument("--substeps", type=int, default=None, help="substeps per frame (default: the scene's)")
    parser.add_argument("--iterations", type=int, default=None, help="solver sweeps per substep (default: the scene's)")
    parser.add_argument("--progress-every", type=int, default=50, help="frames between progress lines (default 50)")
    args = parser.parse_args()
    unknown = [s for s in args.scenes if s not in LARGE]
    if unknown:
        parser.error(f"unknown large scene {unknown[0]!r} (known: {', '.join(LARGE)})")
    if any(v is not None and v < 1 for v in (args.substeps, args.iterations)):
        parser.error("--substeps and --iterations must be positive")
    print(machine_line())
    setting = f"substeps {args.substeps or 'default'}, iterations {args.iterations or 'default'}"
    print(f"arch {args.arch}, f64, threads {args.threads or 'all'}, {setting}, "
          f"penetration measured every {args.measure_every} frames")
    head = (f"{'scene':21} {'setting':>8} {'tris':>6} {'bodies':>6} {'frames':>6} {'settled':>7} {'wall s/sim s':>12} "
            + " ".join(f"{p:>10}" for p in (*PHASES, "other"))
            + f" {'init MiB':>8} {'peak MiB':>8} {'max sub':>7} {'max depth m':>11} {'end depth m':>11} {'end vol m3':>10}")
    rows = []
    for name in args.scenes:
        with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
            rows.append(pool.submit(bench, name, args.frames, args.measure_every, args.arch, args.threads,
                                     args.substeps, args.iterations, args.progress_every).result())
    print(head)
    for r in rows:
        print(f"{r['name']:21} {r['setting']:>8} {r['tris']:>6} {r['bodies']:>6} {r['frames']:>6} {str(r['settled']):>7} "
              f"{r['per_sim_s']:>12.1f} "
              + " ".join(f"{100 * r['shares'][p]:>9.1f}%" for p in (*PHASES, "other"))
              + f" {r['rss_before']:>8.0f} {r['peak_mib']:>8.0f} {r['most_substeps']:>7} {r['deepest']:>11.2e} {r['final_depth']:>11.2e}"
              f" {r['final_volume']:>10.1e}")


if __name__ == "__main__":
    main()
