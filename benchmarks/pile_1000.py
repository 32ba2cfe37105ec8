"""A pile of 1,000 bodies: the built-in scene `pile-1000` (taichi_dcd/scene/files/pile-1000.toml),
1,000 small boxes and wedges turned at random and set 0.5 m apart in five layers of 20 x 10,
dropped onto the ground (10,680 triangles with the ground's).

Prints, every --every frames: simulated time, wall seconds per simulated second of the steps
over those frames (the first frame, which compiles, not timed), the independent measure's
seconds per frame, contact rows, the deepest overlap now and so far (measure/penetration.py),
the fastest body and the bodies asleep.

Usage: python benchmarks/pile_1000.py [--frames N] [--every K] [--threads T]
"""

import argparse
import sys
import time

import numpy as np
from common import machine_line

import taichi_dcd


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=100, help="frames to run (default 100: the first second)")
    parser.add_argument("--every", type=int, default=10, help="frames between printed lines (default 10)")
    parser.add_argument("--threads", type=int, default=None, help="CPU threads (default: all)")
    args = parser.parse_args()
    from taichi_dcd.scene.builtin import builtin_scene
    from taichi_dcd.scene.scene import Scene

    print(machine_line())
    taichi_dcd.init(precision="f64", cpu_threads=args.threads)
    scene = Scene(builtin_scene("pile-1000"))
    print(f"pile-1000: {len(scene.model.bodies) - 1} bodies, {scene.model.n_tris} triangles, f64, "
          f"threads {args.threads or 'all'}")
    print("   t s  wall s/sim s  measure s/frame  rows   depth m  deepest m  fastest m/s  asleep", flush=True)
    scene.step(1)  # compiles
    deepest = 0.0
    wall = measure = 0.0
    done = 1
    while done < args.frames:
        k = min(args.every, args.frames - done)
        start = time.perf_counter()
        rows = scene.step(k)
        wall += time.perf_counter() - start
        start = time.perf_counter()
        depth = scene.penetration().depth
        measure += time.perf_counter() - start
        deepest = max(deepest, depth)
        done += k
        speed = float(np.linalg.norm(scene.body_velocities(), axis=1).max())
        print(f"{scene.time:6.2f}  {wall / (k * scene.config.sim.frame_dt):12.1f}  {measure:15.2f}  {rows:5d}"
              f"  {depth:8.1e}  {deepest:9.1e}  {speed:11.2f}  {len(scene.sleeping_bodies()):6d}", flush=True)
        wall = measure = 0.0


if __name__ == "__main__":
    sys.exit(main())
