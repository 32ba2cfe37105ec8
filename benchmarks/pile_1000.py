"""A pile of 1,000 bodies: 1,000 small boxes and wedges (one in three a wedge at 0.08 scale,
the boxes' sides 0.12-0.25 m) turned at random (seed 2026) and set 0.5 m apart in five layers
of 20 x 10, 0.55 m apart, dropped onto the ground (10,668 triangles). It is generated here,
not shipped: it does not yet settle in a time a run can wait for.

Prints, every --every frames: simulated time, wall seconds per simulated second of the steps
over those frames (the first frame, which compiles, not timed), the independent measure's
seconds per frame, contact rows, the deepest overlap now and so far (measure/penetration.py),
the fastest body and the bodies asleep.

Usage: python benchmarks/pile_1000.py [--frames N] [--every K] [--threads T] [--write FILE]
"""

import argparse
import random
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from common import machine_line

import taichi_dcd

LAYERS, ROWS, COLUMNS = 5, 20, 10
SPACING, LAYER_SPACING, FIRST_LAYER = 0.5, 0.55, 0.3  # m
SEED = 2026


def pile_scene_text() -> str:
    """The scene file of the pile (docs/scene-format.md)."""
    rng = random.Random(SEED)
    lines = ["# pile-1000: 1,000 small boxes and wedges dropped in five layers onto the ground",
             "", "[sim]", "frame_dt = 0.01", "sleep = true", "frames = 800", "stop_when_settled = true", "",
             "[[body]]", 'name = "ground"', 'kind = "static"', 'shape = "ground"',
             "params = { size = [16.0, 1.0, 16.0] }", ""]
    k = 0
    for layer in range(LAYERS):
        for i in range(ROWS):
            for j in range(COLUMNS):
                x, z = (i - (ROWS - 1) / 2) * SPACING, (j - (COLUMNS - 1) / 2) * SPACING
                y = FIRST_LAYER + layer * LAYER_SPACING
                rotation = [round(rng.uniform(-180, 180), 1) for _ in range(3)]
                lines += ["[[body]]", f'name = "part_{k}"', 'kind = "rigid"']
                if k % 3 == 2:
                    lines += ['shape = "wedge"', "scale = 0.08"]
                else:
                    size = [round(rng.uniform(0.12, 0.25), 3) for _ in range(3)]
                    lines += ['shape = "box"', f"params = {{ size = {size} }}"]
                lines += [f"position = [{x:.3f}, {y:.3f}, {z:.3f}]", f"rotation = {rotation}", ""]
                k += 1
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=100, help="frames to run (default 100: the first second)")
    parser.add_argument("--every", type=int, default=10, help="frames between printed lines (default 10)")
    parser.add_argument("--threads", type=int, default=None, help="CPU threads (default: all)")
    parser.add_argument("--write", type=Path, help="write the scene file here and stop")
    args = parser.parse_args()
    if args.write:
        args.write.write_text(pile_scene_text(), encoding="utf-8")
        return
    from taichi_dcd.scene.config import scene_from_dict
    from taichi_dcd.scene.scene import Scene

    print(machine_line())
    taichi_dcd.init(precision="f64", cpu_threads=args.threads)
    scene = Scene(scene_from_dict(tomllib.loads(pile_scene_text()), name="pile-1000"))
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
