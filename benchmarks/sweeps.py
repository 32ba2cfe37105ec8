"""Where the contact solve's sweeps go: for each scene, how many inner Gauss-Seidel sweeps its
block solves run (solver/islands.py: a normal phase, then a friction phase, each up to a cap)
and how often a phase runs to its cap without converging. "rows" is the mean rows a solve
projects in each sweep, "projections" the row projections a solve makes in all. A lone rigid
body's block (Erleben's scenes) has a cap of BLOCK_SWEEPS per phase, an island of several
bodies (stacks, piles) COUPLED_SWEEPS. Counted by the solver's sweep statistics (a kernel
variant of their own), over --seconds of each scene with its own setting; no timing.

Usage: python benchmarks/sweeps.py [SCENE ...] [--seconds S]
"""

import argparse
import sys

from common import machine_line
from stacks import SCENES as STACKS
from stacks import scene_of

import taichi_dcd
from taichi_dcd.scene.builtin import ERLEBEN_SIX, KNOWN
from taichi_dcd.solver.islands import BLOCK_SWEEPS, COUPLED_SWEEPS

DEFAULT = ERLEBEN_SIX + list(STACKS)


def count(name: str, seconds: float) -> dict:
    """The sweep statistics of `name` over its first `seconds` (at most its own frames)."""
    from taichi_dcd.scene.scene import Scene

    config = scene_of(name)
    scene = Scene(config, sweep_stats=True)
    frames = min(int(round(seconds / config.sim.frame_dt)), config.sim.frames)
    for f in range(frames):
        scene.step(1)
        if (f + 1) % 50 == 0:
            print(f"  {name}: t = {scene.time:.2f} s", file=sys.stderr, flush=True)
    return scene.solver.sweep_stats()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenes", nargs="*", default=DEFAULT, help=f"default: {' '.join(DEFAULT)}")
    parser.add_argument("--seconds", type=float, default=1.0, help="simulated seconds of each scene (default 1)")
    args = parser.parse_args()
    known = set(KNOWN) | set(STACKS)
    unknown = [s for s in args.scenes if s not in known]
    if unknown:
        parser.error(f"unknown scene {unknown[0]!r} (known: {', '.join(sorted(known))})")
    if args.seconds <= 0:
        parser.error("--seconds must be positive")
    taichi_dcd.init(arch="cpu", precision="f64")
    print(machine_line())
    print(f"f64, each scene's own setting, its first {args.seconds:g} s; caps: {BLOCK_SWEEPS} sweeps a phase "
          f"for a lone body, {COUPLED_SWEEPS} for an island of several")
    print(f"{'scene':16} {'block':8} {'solves':>8} {'rows':>6} {'normal sweeps':>13} {'at cap':>7} "
          f"{'friction sweeps':>15} {'at cap':>7} {'projections':>11}")
    for name in args.scenes:
        stats = count(name, args.seconds)
        for kind in ("lone", "coupled"):
            part = stats[kind]
            if part["solves"]:
                projections = part["rows"] * (part["normal_sweeps"] + part["friction_sweeps"])
                print(f"{name:16} {kind:8} {part['solves']:>8} {part['rows']:>6.1f} {part['normal_sweeps']:>13.1f} "
                      f"{part['normal_at_cap']:>7.0%} {part['friction_sweeps']:>15.1f} {part['friction_at_cap']:>7.0%} "
                      f"{projections:>11.0f}", flush=True)


if __name__ == "__main__":
    main()
