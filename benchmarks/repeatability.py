"""Does a run repeat its own bits, and how far is it from a one-thread CPU run? Runs each scene
for --frames frames --runs times in one process on --arch (and --threads), then once on one CPU
thread in a fresh process, and prints per run the hash of the final vertices, whether the runs
agree bit for bit, the largest vertex distance from the CPU run (m) and the stepping seconds.

The check a GPU session runs first: the solver's contacts, and so its Gauss-Seidel order, must
come out in one order whatever the threads (core/scan.py), so every run on a GPU should hash
the same, and differ from the CPU's only by rounding (different instruction choices).

Usage: python benchmarks/repeatability.py [SCENE ...] [--frames N] [--runs R] [--arch cpu|cuda]
                                          [--threads T] [--min-work W]
--min-work sets runtime.PARALLEL_MIN_WORK (0: every loop shared among the CPU's threads).
"""

import argparse
import hashlib
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from common import machine_line

import taichi_dcd


def run_scene(name: str, frames: int, runs: int, arch: str, threads: int | None,
              min_work: int | None) -> list[tuple[np.ndarray, float]]:
    """`runs` runs of `name` in this (fresh) process: (final vertices, stepping seconds) each."""
    from taichi_dcd.core import runtime
    from taichi_dcd.scene.builtin import builtin_scene
    from taichi_dcd.scene.scene import Scene

    taichi_dcd.init(arch=arch, precision="f64", cpu_threads=threads)
    if min_work is not None:
        runtime.PARALLEL_MIN_WORK = min_work
    out = []
    for _ in range(runs):
        scene = Scene(builtin_scene(name))
        scene.step(1)  # compiles
        start = time.perf_counter()
        scene.step(frames - 1)
        out.append((scene.vertices().astype(np.float64), time.perf_counter() - start))
    return out


def digest(x: np.ndarray) -> str:
    return hashlib.sha1(np.ascontiguousarray(x).tobytes()).hexdigest()[:16]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenes", nargs="*", default=["pile", "spike-in-crack"], help="default: pile spike-in-crack")
    parser.add_argument("--frames", type=int, default=40, help="frames per run (default 40)")
    parser.add_argument("--runs", type=int, default=2, help="runs per scene in one process (default 2)")
    parser.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    parser.add_argument("--threads", type=int, default=None, help="CPU threads (default: all)")
    parser.add_argument("--min-work", type=int, default=None,
                        help="runtime.PARALLEL_MIN_WORK for the runs (default: as shipped)")
    args = parser.parse_args()
    if args.frames < 2 or args.runs < 1:
        parser.error("--frames must be at least 2 and --runs at least 1")
    print(machine_line())
    print(f"arch {args.arch}, threads {args.threads or 'all'}, min work {args.min_work}, "
          f"{args.frames} frames, {args.runs} runs; reference: cpu, 1 thread")
    print(f"{'scene':16s} {'run':>3s} {'hash':16s} {'repeats':>7s} {'from cpu m':>10s} {'steps s':>8s}")
    context = multiprocessing.get_context("spawn")
    all_repeat = True
    for name in args.scenes:
        with ProcessPoolExecutor(1, mp_context=context) as pool:
            runs = pool.submit(run_scene, name, args.frames, args.runs, args.arch, args.threads,
                               args.min_work).result()
        with ProcessPoolExecutor(1, mp_context=context) as pool:
            (reference, _), = pool.submit(run_scene, name, args.frames, 1, "cpu", 1, None).result()
        first = digest(runs[0][0])
        for k, (x, seconds) in enumerate(runs):
            same = digest(x) == first
            all_repeat &= same
            away = float(np.linalg.norm(x - reference, axis=1).max())
            print(f"{name:16s} {k:3d} {digest(x):16s} {'yes' if same else 'NO':>7s} {away:10.1e} {seconds:8.2f}",
                  flush=True)
    return 0 if all_repeat else 1


if __name__ == "__main__":
    sys.exit(main())
