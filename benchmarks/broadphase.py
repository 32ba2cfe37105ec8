"""Whole-mesh contact query: our grid + narrow phase against python-fcl, and its scaling.

Two tori (R = 1, r = 0.35, ~10k triangles each by default) in three placements:
- links: the second turned 90° about x and moved 1.5 along x, tubes crossing like
  chain links;
- shift: moved 0.3 along x (large overlap);
- coax: moved 0.02 along the common axis (near-coincident surfaces).
For each, the steady-state time of our full contact query (`CollisionPipeline.run`:
boxes, grid, candidate pairs, unified narrow phase into the contact buffer; built
once, vertices already in place) against python-fcl's `collide()` between two
prebuilt BVH models with every contact requested, both on one thread; the median
of the repeats is reported, the two queries taking turns. Both contact counts are
printed, and every pair only one side reports is classified in exact rational
arithmetic (touching, coplanar, crossing, apart).

Then the scaling curve: the shift placement from 1k to 1M triangles in total,
time per query and per triangle, printed and plotted.

Usage: python benchmarks/broadphase.py [--sections M] [--repeat R] [--max-triangles N] [--out DIR]
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

PLACEMENTS = ("links", "shift", "coax")
FCL_PAPER_MS = {"links": 1.6, "shift": 8.4, "coax": 12.2}  # FCL's times measured on this kind of machine before this benchmark existed


def torus_pair(major_sections: int, placement: str) -> tuple[trimesh.Trimesh, trimesh.Trimesh]:
    a = trimesh.creation.torus(1.0, 0.35, major_sections=major_sections, minor_sections=major_sections // 2)
    b = a.copy()
    if placement == "links":
        b.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
        b.apply_translation([1.5, 0.0, 0.0])
    elif placement == "shift":
        b.apply_translation([0.3, 0.0, 0.0])
    elif placement == "coax":
        b.apply_translation([0.0, 0.0, 0.02])
    else:
        raise ValueError(placement)
    return a, b


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


class Ours:
    """Our contact query on two meshes, built once."""

    def __init__(self, a: trimesh.Trimesh, b: trimesh.Trimesh):
        x = np.concatenate([a.vertices, b.vertices])
        faces = np.concatenate([a.faces, b.faces + len(a.vertices)])
        body = np.repeat([0, 1], [len(a.faces), len(b.faces)])
        self.n_a = len(a.faces)
        self.pipeline = CollisionPipeline(faces, body)
        self.x = ti.ndarray(ti.types.vector(3, ti.f64), shape=len(x))
        self.x.from_numpy(x)

    def query(self) -> int:
        return self.pipeline.run(self.x)

    def pairs(self) -> set:
        c = self.pipeline.contacts.to_numpy()
        return {(int(p[0]), int(p[1]) - self.n_a) for p in c.pair}


class FCL:
    """python-fcl collide() between two prebuilt BVH models, all contacts requested."""

    def __init__(self, a: trimesh.Trimesh, b: trimesh.Trimesh):
        import fcl

        self.fcl = fcl
        self.objects = [fcl.CollisionObject(self._bvh(m), fcl.Transform()) for m in (a, b)]
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


def classify_pairs(pairs, a, b, limit: int, rng) -> str:
    pairs = sorted(pairs)
    if not pairs:
        return "none"
    sample = pairs if len(pairs) <= limit else [pairs[i] for i in rng.choice(len(pairs), limit, replace=False)]
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
        a, b = torus_pair(sections, placement)
        ours = Ours(a, b)
        theirs = FCL(a, b) if fcl_ok else None
        t_ours, t_fcl = median_times([ours.query, theirs.query], repeat) if fcl_ok else (
            median_times([ours.query], repeat)[0], None)
        n_ours = ours.query()
        line = [placement, len(a.faces) + len(b.faces), t_ours, n_ours, ours.pipeline.grid.n_pairs]
        if fcl_ok:
            n_fcl = theirs.query()
            line += [t_fcl, n_fcl]
            only_fcl = theirs.pairs() - ours.pairs()
            only_ours = ours.pairs() - theirs.pairs()
            print(f"  {placement}: pairs only FCL reports: {len(only_fcl)} "
                  f"[exact: {classify_pairs(only_fcl, a, b, 300, rng)}]; "
                  f"only we report: {len(only_ours)} [exact: {classify_pairs(only_ours, a, b, 300, rng)}]")
        rows.append(line)

    print()
    print(f"{'placement':10s} {'triangles':>9s} {'ours ms':>8s} {'FCL ms':>8s} {'FCL/ours':>8s} "
          f"{'contacts ours':>13s} {'contacts FCL':>12s} {'candidates':>10s}  (FCL measured earlier)")
    for line in rows:
        placement, n_tris, t_ours, n_ours, n_cand = line[:5]
        if fcl_ok:
            t_fcl, n_fcl = line[5:]
            fcl_cols = f"{1e3 * t_fcl:8.2f} {t_fcl / t_ours:8.2f}"
            n_fcl_col = f"{n_fcl:12d}"
        else:
            fcl_cols, n_fcl_col = f"{'-':>8s} {'-':>8s}", f"{'-':>12s}"
        print(f"{placement:10s} {n_tris:9d} {1e3 * t_ours:8.2f} {fcl_cols} {n_ours:13d} {n_fcl_col} {n_cand:10d}"
              f"  ({FCL_PAPER_MS[placement]} ms)")


def scaling(max_triangles: int, repeat: int, fcl_ok: bool, out_dir: str) -> None:
    targets = [t for t in (1_000, 3_000, 10_000, 30_000, 100_000, 300_000, 1_000_000) if t <= max_triangles]
    rows = []
    print()
    print(f"scaling, shift placement: {'triangles':>9s} {'ours ms':>9s} {'ns/tri':>7s} {'FCL ms':>9s} {'contacts':>9s}")
    for target in targets:
        # Two tori of M × M/2 quads, 2 triangles each: 2·M² triangles in all.
        sections = max(8, int(round(np.sqrt(target / 2))))
        a, b = torus_pair(sections, "shift")
        n_tris = len(a.faces) + len(b.faces)
        ours = Ours(a, b)
        reps = max(3, min(repeat, int(2e6 // n_tris)))
        if fcl_ok:
            t_ours, t_fcl = median_times([ours.query, FCL(a, b).query], reps)
        else:
            t_ours, t_fcl = median_times([ours.query], reps)[0], float("nan")
        rows.append((n_tris, t_ours, t_fcl))
        print(f"{'':26s} {n_tris:9d} {1e3 * t_ours:9.2f} {1e9 * t_ours / n_tris:7.1f} {1e3 * t_fcl:9.2f} "
              f"{ours.query():9d}", flush=True)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("(matplotlib not installed: no plot; pip install -e .[bench])")
        return
    n, t_o, t_f = (np.array(col) for col in zip(*rows))
    fig, ax = plt.subplots(figsize=(6, 4.2))
    ax.loglog(n, 1e3 * t_o, "o-", label="taichi_dcd grid + unified narrow phase")
    if fcl_ok:
        ax.loglog(n, 1e3 * t_f, "s--", label="python-fcl collide (BVH, all contacts)")
    ax.loglog(n, 1e3 * t_o[-1] * n / n[-1], ":", color="gray", label="linear")
    ax.set_xlabel("triangles (two tori, shifted 0.3)")
    ax.set_ylabel("time per contact query [ms], one thread")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "broadphase_scaling.png")
    fig.savefig(path, dpi=120)
    print(f"plot: {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sections", type=int, default=100,
                        help="major sections of each torus (minor: half as many): 100 gives 2 × 10,000 triangles")
    parser.add_argument("--repeat", type=int, default=30, help="timed queries per figure; the median is reported")
    parser.add_argument("--max-triangles", type=int, default=1_000_000, help="largest size in the scaling curve")
    parser.add_argument("--no-scaling", action="store_true", help="skip the scaling curve")
    parser.add_argument("--threads", type=int, default=1, help="CPU threads for our kernels (FCL uses one)")
    parser.add_argument("--out", default="outputs/benchmarks", help="where the plot goes")
    args = parser.parse_args()

    runtime.init(precision="f64", cpu_threads=args.threads)
    print(machine_line())
    fcl_ok = have_fcl()
    if not fcl_ok:
        print("(python-fcl not installed: pip install -e .[bench] to compare)")
    print(f"our threads: {args.threads}; f64; cell size: automatic")
    placements_table(args.sections, args.repeat, fcl_ok)
    if not args.no_scaling:
        scaling(args.max_triangles, args.repeat, fcl_ok, args.out)


if __name__ == "__main__":
    main()
