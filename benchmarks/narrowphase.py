"""Narrow-phase throughput: triangle pairs per second, one thread and all threads.

Compares, on the same seeded random pairs (vertices uniform in the unit cube,
about 28% intersecting):
- the plain per-pair NumPy reference (`taichi_dcd.collision.reference`), on a subset;
- our full method (`taichi_dcd.collide_triangle_pairs`: Möller, candidates,
  Eq. 6, normal and point, input checks and fresh output arrays included) in f32 and
  f64, which on CPU computes a batch of pairs at once in SIMD lanes;
- the same method one pair per loop iteration, the code path the solver runs inside
  its kernels (`narrowphase._collide_pairs_kernel`, kernel alone, one thread);
- Warp's `wp.intersect_tri_tri` on CPU in f32 and f64 when warp-lang is installed
  (a yes/no Möller test only, so the comparison is conservative for us; Warp runs
  a CPU launch on one thread).

Usage: python benchmarks/narrowphase.py [--pairs N] [--repeat R]
"""

import argparse
import os
import time

import numpy as np
from common import machine_line

import taichi_dcd
from taichi_dcd.core import runtime
from taichi_dcd.collision.narrowphase import _collide_pairs_kernel
from taichi_dcd.collision.reference import collide_triangle_pairs_reference


def best_rate(fn, n: int, repeat: int) -> float:
    fn()  # compile / warm up
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return n / best


def bench_ours(a, b, precision: str, threads: int | None, repeat: int) -> float:
    runtime.init(precision=precision, cpu_threads=threads)
    dtype = runtime.real_dtype()
    a_t, b_t = a.astype(dtype), b.astype(dtype)
    return best_rate(lambda: taichi_dcd.collide_triangle_pairs(a_t, b_t), len(a), repeat)


def bench_one_pair_path(a, b, precision: str, repeat: int) -> float:
    runtime.init(precision=precision, cpu_threads=1)
    dtype = runtime.real_dtype()
    a_t, b_t = a.astype(dtype), b.astype(dtype)
    n = len(a)
    out = (np.empty(n, np.int8), np.empty(n, dtype), np.empty((n, 3), dtype), np.empty(n, np.int8),
           np.empty((n, 3), dtype))
    return best_rate(lambda: _collide_pairs_kernel(a_t, b_t, *out), n, repeat)


def bench_warp(a, b, precision: str, repeat: int) -> float | None:
    try:
        import warp as wp
    except ImportError:
        return None
    wp.config.quiet = True
    wp.init()
    vec = wp.vec3d if precision == "f64" else wp.vec3
    dtype = np.float64 if precision == "f64" else np.float32

    @wp.kernel
    def tri_tri(a: wp.array2d(dtype=vec), b: wp.array2d(dtype=vec), out: wp.array(dtype=wp.int32)):
        i = wp.tid()
        out[i] = wp.intersect_tri_tri(a[i, 0], a[i, 1], a[i, 2], b[i, 0], b[i, 1], b[i, 2])

    wa = wp.array(a.astype(dtype), dtype=vec, device="cpu")
    wb = wp.array(b.astype(dtype), dtype=vec, device="cpu")
    out = wp.zeros(len(a), dtype=wp.int32, device="cpu")

    def run():
        wp.launch(tri_tri, dim=len(a), inputs=[wa, wb, out], device="cpu")
        wp.synchronize_device("cpu")

    rate = best_rate(run, len(a), repeat)
    hit_ours = taichi_dcd.collide_triangle_pairs(a, b).hit
    agree = np.mean(out.numpy().astype(bool) == hit_ours)
    print(f"  (warp {precision} agrees with our hit flag on {agree:.4%} of pairs)")
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pairs", type=int, default=2_000_000, help="random pairs per timing (default 2,000,000)")
    parser.add_argument("--reference-pairs", type=int, default=5_000, help="pairs for the slow NumPy reference")
    parser.add_argument("--repeat", type=int, default=5, help="timings per row; the best is reported")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    print(machine_line())
    rng = np.random.default_rng(args.seed)
    a = rng.random((args.pairs, 3, 3))
    b = rng.random((args.pairs, 3, 3))
    all_threads = os.cpu_count() or 1

    rows = []
    n_ref = min(args.reference_pairs, args.pairs)
    t0 = time.perf_counter()
    ref = collide_triangle_pairs_reference(a[:n_ref], b[:n_ref])
    rate_ref = n_ref / (time.perf_counter() - t0)
    print(f"pairs: {args.pairs:,} random unit-cube pairs, {ref['hit'].mean():.1%} intersecting "
          f"(reference on the first {n_ref:,})")
    rows.append(("NumPy reference (per pair)", "f64", "1", rate_ref))
    for precision in ("f32", "f64"):
        for threads in (1, all_threads):
            rows.append(("taichi_dcd full method", precision, str(threads),
                         bench_ours(a, b, precision, threads, args.repeat)))
        rows.append(("  one pair per iteration (kernel)", precision, "1",
                     bench_one_pair_path(a, b, precision, args.repeat)))
    runtime.init(precision="f64")
    for precision in ("f32", "f64"):
        rate = bench_warp(a, b, precision, args.repeat)
        if rate is None:
            print("  (warp-lang not installed: pip install -e .[bench] to compare)")
            break
        rows.append(("Warp intersect_tri_tri (yes/no)", precision, "1", rate))

    print()
    print(f"{'method':34s} {'prec':5s} {'threads':>7s} {'pairs/s':>12s}")
    for name, precision, threads, rate in rows:
        print(f"{name:34s} {precision:5s} {threads:>7s} {rate:12.3e}")


if __name__ == "__main__":
    main()
