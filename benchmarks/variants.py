"""Erleben's rigid scenes in poses they were not tuned on: seeded variants of each built-in scene,
judged by the same verdict as `taichi-dcd run` (measure/penetration.verdict).

Each variant moves the scene's moving body (its last rigid body): shifted up to --shift m in x
and z, turned up to --turn degrees about the vertical (added to the second angle of its
rotation, R = Rz·Ry·Rx), lifted 0 to --lift m, and its velocity scaled by 0.7-1.3. A variant
whose bodies start overlapping deeper than the scene's tolerance is reported as such, not
judged. Prints one row per run: the variant, settle time, final and maximum depth, final
overlap, wall time per simulated second and the verdict; then the count that pass.

Usage: python benchmarks/variants.py [SCENE ...] [--seed N] [--count K] [--workers W]
"""

import argparse
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace

import numpy as np
from common import machine_line

RIGID_SCENES = ("spikes", "spike-and-wedge", "wedges", "wedges-crossed", "spike-in-hole", "spike-in-pit",
                "spike-in-crack", "wedge-in-crack")


@dataclass(frozen=True)
class Variant:
    scene: str
    index: int
    shift: tuple      # (dx, dz) m
    turn: float       # degrees about the vertical
    lift: float       # m
    speed: float      # factor on the velocity

    def label(self) -> str:
        return (f"{self.scene}-v{self.index}: shift ({self.shift[0]:+.3f}, {self.shift[1]:+.3f}) m, "
                f"turn {self.turn:+.1f}°, lift {self.lift:.3f} m, speed ×{self.speed:.2f}")


def variants(scenes, seed: int, count: int, shift: float, turn: float, lift: float) -> list[Variant]:
    """`count` variants of each scene, drawn in order from one seeded generator."""
    rng = np.random.default_rng(seed)
    out = []
    for name in scenes:
        for index in range(count):
            dx, dz = (float(v) for v in rng.uniform(-shift, shift, 2))
            out.append(Variant(name, index, (dx, dz), float(rng.uniform(-turn, turn)), float(rng.uniform(0.0, lift)),
                               float(rng.uniform(0.7, 1.3))))
    return out


def run_variant(variant: Variant) -> dict:
    """Simulate one variant in this process with the scene's own settings; returns its row."""
    from taichi_dcd.core import runtime
    from taichi_dcd.measure.penetration import verdict
    from taichi_dcd.output.run import run_scene
    from taichi_dcd.scene.builtin import scene_config
    from taichi_dcd.scene.scene import Scene

    runtime.init(arch="cpu", precision="f64", cpu_threads=1)
    config = scene_config(variant.scene)
    k = max(i for i, b in enumerate(config.bodies) if b.kind == "rigid")
    body = config.bodies[k]
    x, y, z = body.position
    rx, ry, rz = body.rotation
    config.bodies[k] = replace(body, position=(x + variant.shift[0], y + variant.lift, z + variant.shift[1]),
                               rotation=(rx, ry + variant.turn, rz),
                               velocity=tuple(variant.speed * v for v in body.velocity))
    scene = Scene(config)
    row = {"variant": variant, "starts_overlapping": bool(scene.start_overlaps)}
    with tempfile.TemporaryDirectory() as out:
        metrics = run_scene(scene, out, progress=None, render=False, notices=None)
    row["metrics"] = metrics
    row["verdict"] = verdict(metrics)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="*", default=list(RIGID_SCENES))
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--count", type=int, default=3, help="variants per scene (default 3)")
    parser.add_argument("--shift", type=float, default=0.03, help="largest shift in x and z, m (default 0.03)")
    parser.add_argument("--turn", type=float, default=5.0, help="largest turn about the vertical, degrees (default 5)")
    parser.add_argument("--lift", type=float, default=0.3, help="largest lift, m (default 0.3)")
    parser.add_argument("--workers", type=int, default=2, help="runs side by side (default 2)")
    args = parser.parse_args()
    jobs = variants(args.scenes, args.seed, args.count, args.shift, args.turn, args.lift)
    print(machine_line())
    print(f"seed {args.seed}, {len(jobs)} variants, f64, each scene's own setting, {args.workers} runs at a time")
    print()
    print("| variant | settled (s) | final depth (m) | max depth (m) | final overlap (m³) | wall s / sim s | verdict |")
    print("|---|---|---|---|---|---|---|")
    passed = judged = 0
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for row in pool.map(run_variant, jobs):
            m = row["metrics"]
            if row["starts_overlapping"]:
                verdict = "starts overlapping (not judged)"
            else:
                judged += 1
                passed += row["verdict"] is None
                verdict = "pass" if row["verdict"] is None else "FAIL: " + row["verdict"]
            settled = f"{m['time_to_settle']:.2f}" if m["settled"] else "no"
            print(f"| {row['variant'].label()} | {settled} | {m['final_penetration_depth']:.1e} "
                  f"| {m['max_penetration_depth']:.1e} | {m['final_overlap_volume']:.1e} "
                  f"| {m['wall_time_per_sim_second']:.2f} | {verdict} |", flush=True)
    print()
    print(f"{passed} of {judged} judged variants pass")


if __name__ == "__main__":
    main()
