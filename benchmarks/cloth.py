"""What a cloth costs as it grows: the built-in `cloth-on-spike` (a square cloth with
self_collision on, dropped onto a spike's apex) with its sheet cut into more cells, against
the target of 0.2 s of wall time per frame for ~10k triangles on 2 cores.

Prints, per size: triangles, broad phase, wall seconds per frame of the steps alone (the
first frame, which compiles, not timed) and where they went on the grid path (predict, broad,
narrow, projection: the contact rows and the serial solve), the independent measure's
seconds per frame, the deepest point of the sheet inside the spike over the run, and the
pairs of the sheet's own triangles that cross at the end (measure/cloth.py).

Usage: python benchmarks/cloth.py [--cells 24,48,70] [--frames N] [--threads T] [--iterations K]
                                  [--arch cpu|cuda]
"""

import argparse
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor

from common import machine_line

import taichi_dcd
from taichi_dcd.scene.builtin import builtin_scene


def bench(cells: int, frames: int, threads: int | None, iterations: int | None, arch: str = "cpu") -> dict:
    """One run in this (fresh, spawned) process."""
    from taichi_dcd.scene.scene import Scene

    taichi_dcd.init(arch=arch, precision="f64", cpu_threads=threads)
    config = builtin_scene("cloth-on-spike")
    if iterations:
        config.sim.iterations = iterations
    for body in config.bodies:
        if body.kind == "cloth":
            body.params = dict(body.params, cells=cells)
    scene = Scene(config)
    scene.step(1)  # compiles
    scene.solver.phase_seconds = {} if scene.solver.use_grid else None
    stepping = measuring = deepest = 0.0
    for _ in range(frames - 1):
        t0 = time.perf_counter()
        scene.step(1)
        t1 = time.perf_counter()
        deepest = max(deepest, scene.penetration().depth)
        measuring += time.perf_counter() - t1
        stepping += t1 - t0
    pairs, _ = scene.self_penetration()["cloth"]
    phases = {k: v / (frames - 1) for k, v in (scene.solver.phase_seconds or {}).items()}
    return dict(tris=scene.model.bodies[-1].tri_count, grid=scene.solver.use_grid, per_frame=stepping / (frames - 1),
                phases=phases, measure=measuring / (frames - 1), deepest=deepest, pairs=pairs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cells", default="24,48,70", help="cells along the sheet's side, a list (default 24,48,70)")
    parser.add_argument("--frames", type=int, default=60, help="frames per run (default 60: the fall and the landing)")
    parser.add_argument("--threads", type=int, default=None, help="CPU threads (default: all)")
    parser.add_argument("--iterations", type=int, default=None, help="sweeps per substep (default: the scene's 16)")
    parser.add_argument("--arch", default="cpu", choices=["cpu", "cuda"], help="Taichi backend (default cpu)")
    args = parser.parse_args()
    try:
        sizes = [int(c) for c in args.cells.split(",")]
    except ValueError:
        parser.error(f"--cells must be a comma-separated list of whole numbers, got {args.cells!r}")
    if args.frames < 2 or min(sizes) < 1:
        parser.error("--frames must be at least 2 and every --cells at least 1")
    print(machine_line())
    print(f"cloth-on-spike, arch {args.arch}, f64, 12 x {args.iterations or 16}, {args.frames} frames, "
          f"threads {args.threads or 'all'}; target: "
          "0.2 s per frame at ~10k triangles")
    print(f"{'cells':>5} {'tris':>6} {'broad':>5} {'s/frame':>8} {'predict':>8} {'broad':>7} {'narrow':>7} "
          f"{'project':>8} {'measure s':>9} {'deepest m':>10} {'self pairs':>10}")
    for cells in sizes:
        with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
            r = pool.submit(bench, cells, args.frames, args.threads, args.iterations, args.arch).result()
        ph = r["phases"]
        print(f"{cells:>5} {r['tris']:>6} {'grid' if r['grid'] else 'all':>5} {r['per_frame']:>8.3f} "
              f"{ph.get('predict', 0):>8.3f} {ph.get('broad', 0):>7.3f} {ph.get('narrow', 0):>7.3f} "
              f"{ph.get('projection', 0):>8.3f} {r['measure']:>9.3f} {r['deepest']:>10.2e} {r['pairs']:>10}",
              flush=True)


if __name__ == "__main__":
    main()
