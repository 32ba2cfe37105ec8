"""What a soft body's self-collision costs and buys: the built-in `soft-coil` (a soft tube wound
three times, 1,616 triangles, dropped onto the ground) with `self_collision` off and on, on the
all-pairs and the grid broad phase.

Prints, per run: wall time per simulated second of the steps alone (the first frame, which
compiles, not timed), the wall time of the independent self-intersection measure per frame,
the deepest crossing of the coil with itself over the run, and the pairs of its triangles that
cross at the end (measure/self_intersection.py).

Usage: python benchmarks/self_collision.py [--frames N] [--threads T]
"""

import argparse
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor

from common import machine_line

import taichi_dcd
from taichi_dcd.scene.builtin import builtin_scene

RUNS = (("off", "auto"), ("on", "brute"), ("on", "grid"))


def bench(self_collision: str, broad_phase: str, frames: int, threads: int | None) -> dict:
    """One run in this (fresh, spawned) process."""
    from taichi_dcd.scene.scene import Scene

    taichi_dcd.init(precision="f64", cpu_threads=threads)
    config = builtin_scene("soft-coil")
    for body in config.bodies:
        if body.kind == "soft":
            body.self_collision = self_collision == "on"
    scene = Scene(config, broad_phase=broad_phase)
    stepping = measuring = deepest = 0.0
    pairs = 0
    for f in range(frames):
        t0 = time.perf_counter()
        scene.step(1)
        t1 = time.perf_counter()
        pairs, depth = scene.self_penetration()["coil"]
        measuring += time.perf_counter() - t1
        if f > 0:
            stepping += t1 - t0
        deepest = max(deepest, depth)
    sim_s = config.sim.frame_dt * (frames - 1)
    return dict(self_collision=self_collision, broad_phase="grid" if scene.solver.use_grid else "all-pairs",
                per_sim_s=stepping / sim_s, measure_ms=1e3 * measuring / frames, deepest=deepest, pairs=pairs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=150, help="frames per run (default 150: the landing and 1 s after)")
    parser.add_argument("--threads", type=int, default=None, help="CPU threads (default: all)")
    args = parser.parse_args()
    if args.frames < 2:
        parser.error("--frames must be at least 2")
    print(machine_line())
    print(f"soft-coil, f64, its own setting (12 x 16), {args.frames} frames, threads {args.threads or 'all'}")
    print(f"{'self':>4} {'broad phase':>11} {'wall s/sim s':>12} {'measure ms/frame':>16} {'deepest m':>10} "
          f"{'pairs at end':>12}")
    for self_collision, broad_phase in RUNS:
        with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
            r = pool.submit(bench, self_collision, broad_phase, args.frames, args.threads).result()
        print(f"{r['self_collision']:>4} {r['broad_phase']:>11} {r['per_sim_s']:>12.2f} {r['measure_ms']:>16.1f} "
              f"{r['deepest']:>10.2e} {r['pairs']:>12}", flush=True)


if __name__ == "__main__":
    main()
