"""Many boxes resting on each other: the built-in `stack` (ten 0.4 x 0.2 x 0.4 m boxes set
1e-5 m apart), a three-box stack (its lowest three boxes) and `pyramid` (fifteen boxes in rows
of 5-4-3-2-1, side faces touching), each run for --seconds of simulated time with the scene's
setting.

Each box has a place where it should rest: where it was set, lowered by the gaps below it
(1e-5 m a row). Prints, per scene and thread count: wall time per simulated second (the first
frame, which compiles, not timed), the farthest any box vertex ends from its place (m), the
deepest overlap and the overlap volume at the end by the independent measure
(measure/penetration.py), the largest body speed at the end, the bodies asleep at the end
(the scenes sleep; --no-sleep simulates them throughout), and the targets of the parallel
contact solve (each box within 1e-5 m of its place, overlap <= 1e-9 m^3; 0.2 s per simulated
second for the stack, 0.3 s for the pyramid).

Usage: python benchmarks/stacks.py [SCENE ...] [--seconds S] [--threads T[,T...]] [--arch cpu|cuda] [--no-sleep]
"""

import argparse
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from common import machine_line

import taichi_dcd
from taichi_dcd.scene.builtin import builtin_scene

SCENES = ("stack-3", "stack", "pyramid")
GAP = 1e-5  # m between rows as the scene files set them
ROW_HEIGHT = 0.2  # m, the boxes' height
TARGET_WALL = {"stack-3": 0.2, "stack": 0.2, "pyramid": 0.3}  # s per simulated second


def scene_of(name: str):
    """The SceneConfig of a benchmark scene: `stack-3` is `stack` cut to its lowest three boxes."""
    if name == "stack-3":
        config = builtin_scene("stack")
        config.bodies = config.bodies[:4]
        return config
    return builtin_scene(name)


def bench(name: str, seconds: float, arch: str, threads: int | None, sleep: bool) -> dict:
    """One scene in this (fresh, spawned) process, so that its thread count is its own."""
    from taichi_dcd.scene.scene import Scene

    taichi_dcd.init(arch=arch, precision="f64", cpu_threads=threads)
    config = scene_of(name)
    config.sim.sleep = sleep
    scene = Scene(config)
    start = scene.vertices()
    places = start.copy()
    for body in scene.model.bodies:
        if body.kind == "rigid":
            rows = round((start[body.vertex_start:body.vertex_start + body.vertex_count, 1].min() - GAP) / ROW_HEIGHT)
            places[body.vertex_start:body.vertex_start + body.vertex_count, 1] -= GAP * (rows + 1)
    frames = int(round(seconds / scene.config.sim.frame_dt))
    wall = 0.0
    for f in range(frames):
        t0 = time.perf_counter()
        scene.step(1)
        if f > 0:
            wall += time.perf_counter() - t0
        if (f + 1) % 50 == 0:
            print(f"  {name}, {threads or 'all'} threads: t = {scene.time:.2f} s, stepping {wall:.0f} s",
                  file=sys.stderr, flush=True)
    x = scene.vertices()
    final = scene.penetration(x)
    return dict(name=name, threads=threads, bodies=len(scene.model.bodies) - 1, sim_time=scene.time,
                per_sim_s=wall / max(scene.time - scene.config.sim.frame_dt, 1e-12),
                off_place=float(np.abs(x - places).max()), depth=final.depth, volume=final.volume,
                speed=float(np.linalg.norm(scene.body_velocities(), axis=1).max()),
                asleep=len(scene.sleeping_bodies()), sleep=sleep)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenes", nargs="*", default=list(SCENES), help=f"default: {' '.join(SCENES)}")
    parser.add_argument("--seconds", type=float, default=3.0, help="simulated seconds (default 3)")
    parser.add_argument("--threads", default=None, help="CPU thread counts, comma-separated (default: all)")
    parser.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    parser.add_argument("--no-sleep", action="store_true", help="simulate bodies at rest too (the scenes sleep)")
    args = parser.parse_args()
    unknown = [s for s in args.scenes if s not in SCENES]
    if unknown:
        parser.error(f"unknown scene {unknown[0]!r} (known: {', '.join(SCENES)})")
    if args.seconds <= 0:
        parser.error("--seconds must be positive")
    try:
        threads = [int(t) for t in args.threads.split(",")] if args.threads else [None]
    except ValueError:
        parser.error(f"--threads takes whole numbers separated by commas, not {args.threads!r}")
    if any(t is not None and t < 1 for t in threads):
        parser.error("--threads must be positive")
    print(machine_line())
    print(f"arch {args.arch}, f64, each scene's own setting, {args.seconds:g} s simulated, "
          f"sleeping {'off' if args.no_sleep else 'on'}")
    rows = []
    for name in args.scenes:
        for t in threads:
            with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
                rows.append(pool.submit(bench, name, args.seconds, args.arch, t, not args.no_sleep).result())
    print(f"{'scene':8} {'boxes':>5} {'threads':>7} {'wall s/sim s':>12} {'target':>6} {'off place m':>11} "
          f"{'depth m':>9} {'volume m3':>9} {'speed m/s':>9} {'asleep':>6}")
    for r in rows:
        print(f"{r['name']:8} {r['bodies']:>5} {str(r['threads'] or 'all'):>7} {r['per_sim_s']:>12.2f} "
              f"{TARGET_WALL[r['name']]:>6.1f} {r['off_place']:>11.1e} {r['depth']:>9.1e} {r['volume']:>9.1e} "
              f"{r['speed']:>9.1e} {r['asleep'] if r['sleep'] else '-':>6}")
    print("targets: each box within 1e-5 m of its place, overlap volume <= 1e-9 m^3")


if __name__ == "__main__":
    main()
