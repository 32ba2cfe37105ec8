"""Where the seconds of `taichi-dcd run all` go: each built-in scene of `all` run as the command
runs it (frames rendered, the independent measure on every frame), in one process, with the
parts timed: Taichi's start, building the scene, the first step (compiling the frame kernels;
run twice on the same machine to see it with a warm kernel cache), the other steps, the
penetration measure, a soft body's check of its own crossings ("self"), rasterising, PNG
encoding and writing, plots.png, and the rest (final
meshes, metrics files). The page (index.html) is timed once at the end; the contact sheet is
not made.

Prints one row per scene and the total, and the machine. Output goes to a temporary folder.

Usage: python benchmarks/run_all_profile.py [SCENE ...] [--frames N]
"""

import argparse
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from common import machine_line

import taichi_dcd
from taichi_dcd.output import render, report, run
from taichi_dcd.scene import scene as scene_module
from taichi_dcd.scene.builtin import ALL, builtin_scene

PARTS = ("build", "first step", "steps", "measure", "self", "rasterise", "png", "plots", "other")
seconds: dict[str, float] = defaultdict(float)


def timed(part: str, fn):
    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            seconds[part] += time.perf_counter() - t0
    return wrapper


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenes", nargs="*", default=list(ALL), help="default: every scene of `run all`")
    parser.add_argument("--frames", type=int, default=None, help="most frames per scene (default: the scene's)")
    args = parser.parse_args()
    unknown = [s for s in args.scenes if s not in ALL]
    if unknown:
        parser.error(f"unknown scene {unknown[0]!r} (known: {', '.join(ALL)})")
    print(machine_line())
    t0 = time.perf_counter()
    taichi_dcd.init(arch="cpu", precision="f64")
    start = time.perf_counter() - t0

    Scene = scene_module.Scene
    step = Scene.step
    first = {"pending": True}

    def step_timed(self, n=1):
        part = "first step" if first["pending"] else "steps"
        first["pending"] = False
        return timed(part, step)(self, n)

    Scene.step = step_timed
    Scene.penetration = timed("measure", Scene.penetration)
    Scene.self_penetration = timed("self", Scene.self_penetration)
    render.Rasterizer.render = timed("rasterise", render.Rasterizer.render)
    render.write_png = timed("png", render.write_png)
    report.plot_run = timed("plots", report.plot_run)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for name in args.scenes:
            seconds.clear()
            first["pending"] = True
            t_scene = time.perf_counter()
            config = builtin_scene(name)
            scene = timed("build", Scene)(config)
            run.run_scene(scene, root / name, frames=args.frames, progress=None, render=True, notices=None)
            total = time.perf_counter() - t_scene
            parts = {p: seconds[p] for p in PARTS[:-1]}
            parts["other"] = total - sum(parts.values())
            rows.append((name, scene.frame, total, parts))
            del scene  # gone before the next is built, so that it gets this one's fields (core.pool)
            print(f"  {name}: {total:.1f} s", file=sys.stderr, flush=True)
        t_end = time.perf_counter()
        report.write_index(root, list(args.scenes))
        index = time.perf_counter() - t_end
    print(f"Taichi start {start:.2f} s; index.html {index:.2f} s")
    print(f"{'scene':20} {'frames':>6} {'total s':>8} " + " ".join(f"{p:>10}" for p in PARTS))
    sums = defaultdict(float)
    for name, frames, total, parts in rows:
        print(f"{name:20} {frames:>6} {total:>8.1f} " + " ".join(f"{parts[p]:>10.2f}" for p in PARTS))
        sums["total"] += total
        for p in PARTS:
            sums[p] += parts[p]
    print(f"{'all':20} {'':>6} {sums['total']:>8.1f} " + " ".join(f"{sums[p]:>10.2f}" for p in PARTS))


if __name__ == "__main__":
    main()
