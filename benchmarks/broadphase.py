"""Whole-mesh contact query: our two pipelines against python-fcl, and their scaling.

Two tori (R = 1, r = 0.35, ~10k triangles each by default) in three placements:
- links: the second turned 90° about x and moved 1.5 along x, tubes crossing like
  chain links;
- shift: moved 0.3 along x (large overlap);
- coax: moved 0.02 along the common axis (near-coincident surfaces).
Each torus is one rigid body: its mesh in its own frame and a pose. Timed, steady state
(built once, then queried with the bodies in place), all on one thread by default:
- "rigid": our `RigidPipeline.run` (grids built once in each body's frame; the poses in,
  every intersecting pair out, through the unified narrow phase);
- "world": our `CollisionPipeline.run` on the posed vertices (the grid built at every
  query, as for deforming bodies);
- FCL: python-fcl's `collide()` between the two prebuilt BVH models at their poses, every
  contact requested.
The median of the repeats is reported, the queries taking turns. Contact counts are
printed, and every pair only one side reports is classified in exact rational arithmetic
(touching, coplanar, crossing, apart).

Then the scaling curve: each placement (or those of --placements) from 1k to 1M triangles in
total, time per query, printed and plotted.

Usage: python benchmarks/broadphase.py [--sections M] [--repeat R] [--max-triangles N]
       [--placements P,...] [--threads T] [--out DIR]
"""

import argparse
import os
import time
from collections import Counter

import numpy as np
import taichi as ti
import trimesh
from common import machine_line
from exact_tritri import classify

from taichi_dcd.core import runtime
from taichi_dcd.collision.pipeline import CollisionPipeline
from taichi_dcd.collision.rigid_pipeline import RigidPipeline

PLACEMENTS = ("links", "shift", "coax")


def torus_pair(major_sections: int, placement: str) -> tuple[trimesh.Trimesh, np.ndarray]:
    """The torus (in its own frame) and the 4 x 4 pose of the second one."""
    a = trimesh.creation.torus(1.0, 0.35, major_sections=major_sections, minor_sections=major_sections // 2)
    if placement == "links":
        pose = trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0])
        pose[:3, 3] = [1.5, 0.0, 0.0]
    elif placement == "shift":
        pose = trimesh.transformations.translation_matrix([0.3, 0.0, 0.0])
    elif placement == "coax":
        pose = trimesh.transformations.translation_matrix([0.0, 0.0, 0.02])
    else:
        raise ValueError(placement)
    return a, pose


def median_times(fns, repeat: int) -> list[float]:
    """Median wall time of each function, the calls interleaved (one of each per round), so
    that this machine's drift (up to 50% over a minute) falls on all of them alike."""
    for fn in fns:
        fn()  # compile, grow buffers
    times = [[] for _ in fns]
    for _ in range(repeat):
        for fn, spent in zip(fns, times):
            t0 = time.perf_counter()
            fn()
            spent.append(time.perf_counter() - t0)
    return [float(np.median(spent)) for spent in times]


class OursRigid:
    """Our rigid-body query: each torus's grid built once in its frame, the poses given."""

    def __init__(self, a: trimesh.Trimesh, pose: np.ndarray):
        self.n_a = len(a.faces)
        self.pipeline = RigidPipeline([(a.vertices, a.faces), (a.vertices, a.faces)])
        self.rotation = np.stack([np.eye(3), pose[:3, :3]])
        self.translation = np.stack([np.zeros(3), pose[:3, 3]])

    def query(self) -> int:
        return self.pipeline.run(self.rotation, self.translation)

    def candidates(self) -> int:
        return self.pipeline.candidates()[1]

    def pairs(self) -> set:
        c = self.pipeline.contacts.to_numpy()
        return {(int(p[0]), int(p[1]) - self.n_a) for p in c.pair}


class OursWorld:
    """Our per-vertex query on the posed vertices (the grid built at every query)."""

    def __init__(self, a: trimesh.Trimesh, pose: np.ndarray):
        b = a.copy()
        b.apply_transform(pose)
        x = np.concatenate([a.vertices, b.vertices])
        faces = np.concatenate([a.faces, b.faces + len(a.vertices)])
        body = np.repeat([0, 1], [len(a.faces), len(b.faces)])
        self.pipeline = CollisionPipeline(faces, body)
        self.x = ti.ndarray(ti.types.vector(3, ti.f64), shape=len(x))
        self.x.from_numpy(x)

    def query(self) -> int:
        return self.pipeline.run(self.x)


class FCL:
    """python-fcl collide() between two prebuilt BVH models at their poses, all contacts requested."""

    def __init__(self, a: trimesh.Trimesh, pose: np.ndarray):
        import fcl

        self.fcl = fcl
        model = self._bvh(a)
        self.objects = [fcl.CollisionObject(model, fcl.Transform()),
                        fcl.CollisionObject(self._bvh(a), fcl.Transform(pose[:3, :3], pose[:3, 3]))]
        self.request = fcl.CollisionRequest(num_max_contacts=10**8, enable_contact=True)
        self.result = None

    def _bvh(self, mesh):
        model = self.fcl.BVHModel()
        model.beginModel(len(mesh.vertices), len(mesh.faces))
        model.addSubModel(mesh.vertices, mesh.faces)
        model.endModel()
        return model

    def query(self) -> int:
        self.result = self.fcl.CollisionResult()
        self.fcl.collide(*self.objects, self.request, self.result)
        return len(self.result.contacts)

    def pairs(self) -> set:
        return {(c.b1, c.b2) for c in self.result.contacts}


def classify_pairs(pairs, a, pose, limit: int, rng) -> str:
    pairs = sorted(pairs)
    if not pairs:
        return "none"
    sample = pairs if len(pairs) <= limit else [pairs[i] for i in rng.choice(len(pairs), limit, replace=False)]
    b = a.copy()
    b.apply_transform(pose)
    ta, tb = a.vertices[a.faces], b.vertices[b.faces]
    counts = Counter(classify(ta[i], tb[j]) for i, j in sample)
    note = "" if len(sample) == len(pairs) else f" (of a sample of {len(sample)})"
    return ", ".join(f"{k} {v}" for k, v in counts.most_common()) + note


def have_fcl() -> bool:
    try:
        import fcl  # noqa: F401
    except ImportError:
        return False
    return True


def placements_table(sections: int, repeat: int, fcl_ok: bool) -> None:
    rng = np.random.default_rng(0)
    rows = []
    for placement in PLACEMENTS:
        a, pose = torus_pair(sections, placement)
        rigid, world = OursRigid(a, pose), OursWorld(a, pose)
        fns = [rigid.query, world.query]
        if fcl_ok:
            theirs = FCL(a, pose)
            fns.append(theirs.query)
        times = median_times(fns, repeat) + ([] if fcl_ok else [float("nan")])
        n_rigid, n_world = rigid.query(), world.query()
        assert n_rigid == n_world, f"{placement}: the rigid and world pipelines disagree ({n_rigid} vs {n_world})"
        n_fcl = theirs.query() if fcl_ok else -1
        if fcl_ok:
            only_fcl = theirs.pairs() - rigid.pairs()
            only_ours = rigid.pairs() - theirs.pairs()
            print(f"  {placement}: pairs only FCL reports: {len(only_fcl)} "
                  f"[exact: {classify_pairs(only_fcl, a, pose, 300, rng)}]; "
                  f"only we report: {len(only_ours)} [exact: {classify_pairs(only_ours, a, pose, 300, rng)}]")
        rows.append((placement, 2 * len(a.faces), *times, n_rigid, n_fcl, rigid.candidates()))

    print()
    print(f"{'placement':10s} {'triangles':>9s} {'rigid ms':>9s} {'world ms':>9s} {'FCL ms':>8s} "
          f"{'ours/FCL':>8s} {'contacts ours':>13s} {'contacts FCL':>12s} {'candidates':>10s}")
    for placement, n_tris, t_rigid, t_world, t_fcl, n_ours, n_fcl, n_cand in rows:
        print(f"{placement:10s} {n_tris:9d} {1e3 * t_rigid:9.2f} {1e3 * t_world:9.2f} {1e3 * t_fcl:8.2f} "
              f"{t_rigid / t_fcl:8.2f} {n_ours:13d} {n_fcl:12d} {n_cand:10d}")


def scaling(max_triangles: int, repeat: int, fcl_ok: bool, out_dir: str, placements=PLACEMENTS) -> None:
    """Time per query from 1k to `max_triangles` triangles in each placement; printed, and
    plotted (times in the shift placement, ours against FCL in every placement)."""
    targets = [t for t in (1_000, 3_000, 10_000, 30_000, 100_000, 300_000, 1_000_000) if t <= max_triangles]
    rows = []
    print()
    print(f"scaling: {'placement':>9s} {'triangles':>9s} {'rigid ms':>9s} {'world ms':>9s} {'FCL ms':>9s} "
          f"{'rigid/FCL':>9s} {'world/FCL':>9s} {'contacts':>9s} {'build s':>7s}")
    for placement in placements:
        for target in targets:
            # Two tori of M × M/2 quads, 2 triangles each: 2·M² triangles in all.
            sections = max(8, int(round(np.sqrt(target / 2))))
            a, pose = torus_pair(sections, placement)
            n_tris = 2 * len(a.faces)
            start = time.perf_counter()
            rigid = OursRigid(a, pose)
            build = time.perf_counter() - start
            world = OursWorld(a, pose)
            reps = max(3, min(repeat, int(2e6 // n_tris)))
            fns = [rigid.query, world.query] + ([FCL(a, pose).query] if fcl_ok else [])
            times = median_times(fns, reps) + ([] if fcl_ok else [float("nan")])
            rows.append((placement, n_tris, *times))
            print(f"{'':8s} {placement:>9s} {n_tris:9d} {1e3 * times[0]:9.2f} {1e3 * times[1]:9.2f} "
                  f"{1e3 * times[2]:9.2f} {times[0] / times[2]:9.2f} {times[1] / times[2]:9.2f} "
                  f"{rigid.query():9d} {build:7.2f}", flush=True)
            del rigid, world, fns
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("(matplotlib not installed: no plot; pip install -e .[bench])")
        return
    fig, (ax, ax_ratio) = plt.subplots(1, 2, figsize=(11, 4.2))
    shown = "shift" if "shift" in placements else placements[0]
    def curve(placement):
        """(triangles, rigid s, world s, FCL s) arrays of one placement's rows."""
        return (np.array(col) for col in zip(*[r[1:] for r in rows if r[0] == placement]))

    n, t_r, t_w, t_f = curve(shown)
    ax.loglog(n, 1e3 * t_r, "o-", label="taichi_dcd rigid (grids built once per body)")
    ax.loglog(n, 1e3 * t_w, "^-", label="taichi_dcd world (grid built per query)")
    if fcl_ok:
        ax.loglog(n, 1e3 * t_f, "s--", label="python-fcl collide (BVH, all contacts)")
    ax.loglog(n, 1e3 * t_w[-1] * n / n[-1], ":", color="gray", label="linear")
    ax.set_xlabel(f"triangles (two tori, {shown} placement)")
    ax.set_ylabel("time per contact query [ms]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    if fcl_ok:
        for placement, marker in zip(placements, "osd"):
            n, t_r, t_w, t_f = curve(placement)
            ax_ratio.semilogx(n, t_r / t_f, marker + "-", label=f"rigid, {placement}")
            ax_ratio.semilogx(n, t_w / t_f, marker + ":", alpha=0.6, label=f"world, {placement}")
        ax_ratio.axhline(1.0, color="gray", lw=1)
        ax_ratio.axhline(0.5, color="gray", lw=1, ls="--")
        ax_ratio.set_yscale("log")
        ax_ratio.set_xlabel("triangles (two tori)")
        ax_ratio.set_ylabel("our time / FCL's (below 1: faster)")
        ax_ratio.grid(True, which="both", alpha=0.3)
        ax_ratio.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "broadphase_scaling.png")
    fig.savefig(path, dpi=120)
    print(f"plot: {path}")


def time_rigid(sections: int, repeat: int) -> float:
    """Median ms of the rigid query, shift placement (run in a process of its own thread count)."""
    a, pose = torus_pair(sections, "shift")
    rigid = OursRigid(a, pose)
    return 1e3 * median_times([rigid.query], repeat)[0]


def thread_speedup(sections: int, repeat: int, rounds: int) -> None:
    """The rigid query on 1 and on 2 threads, each in a fresh process (Taichi's thread count is
    fixed per process), the two taking turns `rounds` times."""
    import subprocess
    import sys

    times = {1: [], 2: []}
    for _ in range(rounds):
        for threads in (1, 2):
            out = subprocess.run([sys.executable, __file__, "--time-rigid", str(sections), "--threads", str(threads),
                                  "--repeat", str(repeat)], capture_output=True, text=True, check=True).stdout
            times[threads].append(float(out.strip().splitlines()[-1]))
    one, two = min(times[1]), min(times[2])
    mid_one, mid_two = float(np.median(times[1])), float(np.median(times[2]))
    print()
    print(f"threads, shift placement, {4 * sections * (sections // 2)} triangles, rigid query, {rounds} processes "
          f"each, taking turns: best 1 thread {one:.2f} ms, 2 threads {two:.2f} ms, speedup {one / two:.2f}x; "
          f"median {mid_one:.2f} against {mid_two:.2f} ms, {mid_one / mid_two:.2f}x")
    print(f"  all, ms: 1 thread {', '.join(f'{t:.1f}' for t in times[1])}; "
          f"2 threads {', '.join(f'{t:.1f}' for t in times[2])}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sections", type=int, default=100,
                        help="major sections of each torus (minor: half as many): 100 gives 2 × 10,000 triangles")
    parser.add_argument("--repeat", type=int, default=30, help="timed queries per figure; the median is reported")
    parser.add_argument("--max-triangles", type=int, default=1_000_000, help="largest size in the scaling curve")
    parser.add_argument("--no-scaling", action="store_true", help="skip the scaling curve")
    parser.add_argument("--placements", default=",".join(PLACEMENTS),
                        help=f"comma list of the scaling curve's placements (default {','.join(PLACEMENTS)})")
    parser.add_argument("--threads", type=int, default=1, help="CPU threads for our kernels (FCL uses one)")
    parser.add_argument("--out", default="outputs/benchmarks", help="where the plot goes")
    parser.add_argument("--speedup-sections", type=int, default=320,
                        help="major sections of the tori for the 1-against-2-threads comparison (320: 204,800 "
                             "triangles; 0 skips it)")
    parser.add_argument("--time-rigid", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()

    placements = tuple(p for p in args.placements.split(",") if p)
    unknown = [p for p in placements if p not in PLACEMENTS]
    if unknown or not placements:
        parser.error(f"--placements: unknown placement {unknown[0] if unknown else '(none)'!r} "
                     f"(known: {', '.join(PLACEMENTS)})")
    runtime.init(precision="f64", cpu_threads=args.threads)
    if args.time_rigid:
        print(time_rigid(args.time_rigid, args.repeat))
        return
    print(machine_line())
    fcl_ok = have_fcl()
    if not fcl_ok:
        print("(python-fcl not installed: pip install -e .[bench] to compare)")
    print(f"our threads: {args.threads}; f64; cell size: automatic")
    placements_table(args.sections, args.repeat, fcl_ok)
    if not args.no_scaling:
        scaling(args.max_triangles, args.repeat, fcl_ok, args.out, placements)
    if args.speedup_sections:
        thread_speedup(args.speedup_sections, args.repeat, rounds=5)


if __name__ == "__main__":
    main()
