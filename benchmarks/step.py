"""Solver step cost: wall time per simulated second and per substep, and Taichi kernel
launches per substep, at 10 substeps per 0.01 s frame, stepped a frame per call
(`scene.step(1)`, as `taichi-dcd run` does) and N frames in one call (`scene.step(N)`:
on the all-pairs path one kernel launch runs them all).

- small: a 1 m rigid box resting on a static 4 × 1 × 4 block (24 triangles; the whole
  frame runs in one kernel with the all-pairs broad phase);
- large: a rigid icosphere (81,920 triangles) resting on a static box whose faces are
  split into 49,152 triangles (131,072 in all; uniform grid every substep).
The bodies are settled first, so the timed frames have steady resting contacts.
Kernel compilation (the first frame) is not timed. Launches are counted by wrapping
Taichi's kernel call.

Usage: python benchmarks/step.py [--frames N] [--threads T] [--arch cpu|cuda]
"""

import argparse
import time

from common import machine_line

import taichi_dcd
from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene


def count_launches():
    """Wrap taichi's Kernel.__call__, and our bound launches that bypass it, so that every
    launch increments counter[0]."""
    from taichi.lang import kernel_impl

    from taichi_dcd.core.launch import BoundKernel

    counter = [0]
    original = kernel_impl.Kernel.__call__
    original_bound = BoundKernel.__call__

    def counted(self, *args, **kwargs):
        counter[0] += 1
        return original(self, *args, **kwargs)

    def counted_bound(self, *scalars):
        counter[0] += self._fast  # the fallback goes through Kernel.__call__
        return original_bound(self, *scalars)

    kernel_impl.Kernel.__call__ = counted
    BoundKernel.__call__ = counted_bound
    return counter


SCENES = {
    "small": [
        {"name": "box", "kind": "rigid", "shape": "box", "params": {"size": [1.0, 1.0, 1.0]},
         "position": [0.0, 0.5, 0.0]},
        {"name": "block", "kind": "static", "shape": "box", "params": {"size": [4.0, 1.0, 4.0]},
         "position": [0.0, -0.5, 0.0]},
    ],
    "large": [
        {"name": "ball", "kind": "rigid", "shape": "icosphere", "params": {"radius": 0.5, "subdivisions": 6},
         "position": [0.0, 0.5, 0.0]},
        {"name": "block", "kind": "static", "shape": "box", "params": {"size": [4.0, 1.0, 4.0], "subdivisions": 6},
         "position": [0.0, -0.5, 0.0]},
    ],
}


def bench(name: str, frames: int, counter) -> dict:
    """Time `frames` frames stepped one call per frame (as `taichi-dcd run` does, reading
    metrics between frames) and as one `step(frames)` call (one launch on the all-pairs path)."""
    sim = {"frame_dt": 0.01, "substeps": 10}
    scene = Scene(scene_from_dict({"sim": sim, "body": SCENES[name]}, name=name))
    n_tris = scene.model.n_tris
    scene.step(1)  # compile
    scene.step(20)  # settle into resting contact
    launches0 = counter[0]
    t0 = time.perf_counter()
    for _ in range(frames):
        scene.step(1)
    each = time.perf_counter() - t0
    launches = counter[0] - launches0
    t0 = time.perf_counter()
    scene.step(frames)
    at_once = time.perf_counter() - t0
    substeps = frames * scene.config.sim.substeps
    sim_s = frames * scene.config.sim.frame_dt
    return dict(name=name, tris=n_tris, broad="grid" if scene.solver.use_grid else "all-pairs",
                each_per_sim_s=each / sim_s, at_once_per_sim_s=at_once / sim_s,
                per_substep_us=at_once / substeps * 1e6, launches=launches / substeps,
                contacts=scene.solver.last_contact_count, iterations=scene.config.sim.iterations)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=100,
                        help="timed frames per scene and way of stepping (default 100; a tenth for large)")
    parser.add_argument("--threads", type=int, default=None, help="CPU threads (default: all)")
    parser.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    args = parser.parse_args()
    taichi_dcd.init(arch=args.arch, precision="f64", cpu_threads=args.threads)
    print(machine_line())
    print(f"arch {args.arch}, f64, threads {args.threads or 'all'}, 10 substeps per 0.01 s frame, "
          f"{args.frames} timed frames")
    counter = count_launches()
    print(f"{'scene':6} {'triangles':>9} {'broad phase':>11} {'iters':>5} {'contacts':>8} "
          f"{'ms/sim s, step(1)':>17} {'ms/sim s, step(N)':>17} {'us/substep, step(N)':>19} "
          f"{'launches/substep, step(1)':>25}")
    for name in SCENES:
        frames = args.frames if name == "small" else max(1, args.frames // 10)
        r = bench(name, frames, counter)
        print(f"{r['name']:6} {r['tris']:>9} {r['broad']:>11} {r['iterations']:>5} {r['contacts']:>8} "
              f"{r['each_per_sim_s'] * 1e3:>17.1f} {r['at_once_per_sim_s'] * 1e3:>17.1f} "
              f"{r['per_substep_us']:>19.1f} {r['launches']:>25.2f}", flush=True)


if __name__ == "__main__":
    main()
