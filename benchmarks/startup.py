"""How long a run takes to start: `taichi-dcd run SCENE` timed from the command to its first
simulated frame on disk (frames/frame_00001.png), Taichi's kernel cache warm, with
taichi_dcd's changes to Taichi's frontend (core.frontend's memos, core.traced_ops' vector
helpers) and without them (TAICHI_DCD_PLAIN_FRONTEND=1), taking turns. Then one process's
parts, timed inside it: importing and starting Taichi, building the scene, rendering frame 0
and the first step: "its frontend" turns the frame kernel's source into Taichi's IR, "the
rest" is mostly loading the compiled kernel from the cache and making machine code of it.
And, untimed, how many AST nodes Taichi's frontend visits in that first step (a count that
does not vary with the machine's load).

An untimed run first fills the kernel cache. Prints medians (and the fastest) over --repeat
runs and the machine.

Usage: python benchmarks/startup.py [SCENE ...] [--repeat N]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import machine_line

from taichi_dcd.core.frontend import PLAIN_ENV

PARTS_SCRIPT = r"""
import json, sys, tempfile, time
t0 = time.perf_counter()
import taichi_dcd
from pathlib import Path
from taichi_dcd.output.run import FrameWriter
from taichi_dcd.scene.builtin import builtin_scene
from taichi_dcd.scene.scene import Scene
taichi_dcd.init()
t1 = time.perf_counter()
scene = Scene(builtin_scene(sys.argv[1]))
t2 = time.perf_counter()
import taichi.lang.kernel_impl as kernel_impl
materialize = kernel_impl.Kernel.materialize
frontend = [0.0]
def timed(self, *args, **kwargs):
    start = time.perf_counter()
    try:
        return materialize(self, *args, **kwargs)
    finally:
        frontend[0] += time.perf_counter() - start
kernel_impl.Kernel.materialize = timed
with tempfile.TemporaryDirectory() as out:
    FrameWriter(scene, Path(out)).write(scene.vertices())
    t3 = time.perf_counter()
    frontend[0] = 0.0
    scene.step(1)
    t4 = time.perf_counter()
print(json.dumps({"import and init": t1 - t0, "build": t2 - t1, "frame 0": t3 - t2, "first step": t4 - t3,
                  "its frontend": frontend[0], "the rest": t4 - t3 - frontend[0]}))
"""


NODES_SCRIPT = r"""
import sys
import taichi_dcd
from taichi.lang.ast import ast_transformer_utils
from taichi_dcd.scene.builtin import builtin_scene
from taichi_dcd.scene.scene import Scene
taichi_dcd.init()
scene = Scene(builtin_scene(sys.argv[1]))
visits = [0]
visit = ast_transformer_utils.Builder.__call__
def counted(self, ctx, node):
    visits[0] += 1
    return visit(self, ctx, node)
ast_transformer_utils.Builder.__call__ = counted
scene.step(1)
print(visits[0])
"""


def environment(plain: bool) -> dict:
    """This process's environment, with Taichi's frontend left plain or not."""
    env = dict(os.environ)
    env.pop(PLAIN_ENV, None)
    if plain:
        env[PLAIN_ENV] = "1"
    return env


def script_result(script: str, scene: str, plain: bool) -> str:
    """The last line a Python script prints, run on SCENE in a fresh process."""
    out = subprocess.run([sys.executable, "-c", script, scene], env=environment(plain), capture_output=True,
                         text=True, check=True)
    return out.stdout.strip().splitlines()[-1]


def first_frame_seconds(scene: str, plain: bool) -> float:
    """Seconds from starting `taichi-dcd run SCENE` to its frame_00001.png existing."""
    env = environment(plain)
    with tempfile.TemporaryDirectory() as out:
        frame = Path(out) / "frames" / "frame_00001.png"
        start = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "taichi_dcd", "run", scene, "--out", out, "--force"],
                                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            while not frame.exists():
                if proc.poll() is not None:
                    raise SystemExit(f"taichi-dcd run {scene} ended (exit {proc.returncode}) before its first frame")
                time.sleep(0.01)
            return time.perf_counter() - start
        finally:
            proc.kill()
            proc.wait()


def parts(scene: str, plain: bool) -> dict:
    """Seconds of one process's parts (PARTS_SCRIPT)."""
    return json.loads(script_result(PARTS_SCRIPT, scene, plain))


def frontend_nodes(scene: str, plain: bool) -> int:
    """AST nodes Taichi's frontend visits in the scene's first step (kernel cache warm)."""
    return int(script_result(NODES_SCRIPT, scene, plain))


def median(values):
    s = sorted(values)
    return s[len(s) // 2] if len(s) % 2 else 0.5 * (s[len(s) // 2 - 1] + s[len(s) // 2])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenes", nargs="*", default=["spike-in-crack", "soft-ball-on-spike"])
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of each kind (default 5)")
    args = parser.parse_args()
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    print(machine_line())
    print(f"{'scene':20} {'frontend':9} {'AST nodes':>9} {'first frame s (median)':>22} {'fastest':>8}   "
          "parts (median s): import and init, build, frame 0, first step (its frontend, the rest)")
    for scene in args.scenes:
        first_frame_seconds(scene, False)  # fills the kernel cache
        times = {False: [], True: []}
        split = {False: [], True: []}
        for _ in range(args.repeat):
            for plain in (True, False):
                times[plain].append(first_frame_seconds(scene, plain))
                split[plain].append(parts(scene, plain))
        for plain in (True, False):
            keys = split[plain][0].keys()
            summary = ", ".join(f"{median([p[k] for p in split[plain]]):.2f}" for k in keys)
            print(f"{scene:20} {'plain' if plain else 'ours':9} {frontend_nodes(scene, plain):>9} "
                  f"{median(times[plain]):>22.2f} "
                  f"{min(times[plain]):>8.2f}   {summary}", flush=True)


if __name__ == "__main__":
    main()
