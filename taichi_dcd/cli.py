"""Command line: `taichi-dcd` (also `python -m taichi_dcd`).

Exit status: 0 success, 1 a run that failed, 2 bad usage or bad input.
"""

from __future__ import annotations

import argparse
import os
import sys

from . import __version__


def _triangle(text: str):
    """Parse 'x,y,z x,y,z x,y,z' (or nine comma/space separated numbers) into a (3, 3) list."""
    parts = text.replace(",", " ").split()
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number in triangle {text!r}") from None
    if len(values) != 9:
        raise argparse.ArgumentTypeError(f"a triangle needs 9 coordinates, got {len(values)} in {text!r}")
    return [values[0:3], values[3:6], values[6:9]]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="taichi-dcd",
        description="Triangle-mesh contact in Taichi: the unified discrete collision method of "
                    "Kikuchi & Kanai (EG 2025).",
    )
    parser.add_argument("--version", action="version", version=f"taichi-dcd {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    collide = sub.add_parser(
        "collide",
        help="test one triangle pair and print the constraint (depth, normal, moved side, point)",
        description="Test triangles A and B with the unified DCD method and print hit, depth C "
                    "(Eq. 6), the push normal, which triangle moves, and the deepest candidate point.",
    )
    collide.add_argument("a", type=_triangle, help="triangle A as 'x,y,z x,y,z x,y,z' (vertex order = outward normal)")
    collide.add_argument("b", type=_triangle, help="triangle B, same form")
    collide.add_argument("--precision", choices=["f32", "f64"], default="f64", help="kernel float type (default f64)")
    collide.add_argument("--arch", choices=["cpu", "cuda", "vulkan"], default="cpu", help="Taichi backend (default cpu)")
    sub.add_parser("list", help="list the built-in scenes", description="List the built-in scenes, one line each.")
    union = sub.add_parser(
        "union",
        help="write the solid covered by a mesh's overlapping parts (fixes a self-intersecting mesh)",
        description="Read MESH (any format trimesh reads), join its connected parts into one solid by "
                    "a boolean union (manifold3d) and write it to OUT. This is the fix for a mesh made "
                    "of parts that overlap, such as two boxes saved into one OBJ: as given, its "
                    "volume, mass and inertia count the overlap twice. A part whose own triangles "
                    "cross cannot be fixed this way. OUT is never overwritten unless --force.",
    )
    union.add_argument("mesh", help="the mesh file to fix")
    union.add_argument("out", help="the file to write (its extension picks the format, e.g. .obj)")
    union.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    run = sub.add_parser(
        "run",
        help="simulate a scene and write frames, final meshes and metrics",
        description="Simulate SCENE (a built-in name from `taichi-dcd list`, `all` for every built-in "
                    "scene, or a TOML scene file: docs/scene-format.md) and write frames/, final/<body>.obj, "
                    "metrics.json and metrics.csv into the output folder. `all` also writes "
                    "outputs/contact-sheet.png. Exit status 0 on success, 1 if the simulation failed "
                    "(NaN, explosion), 2 for bad usage or input.",
    )
    run.add_argument("scene", help="built-in scene name, `all`, or path to a scene file (.toml)")
    run.add_argument("--frames", type=_positive_int, help="frames to simulate (default: the scene's)")
    run.add_argument("--substeps", type=_positive_int, help="substeps per frame (default: the scene's)")
    run.add_argument("--iterations", type=_positive_int, help="solver sweeps per substep (default: the scene's)")
    run.add_argument("--precision", choices=["f32", "f64"], default="f64", help="kernel float type (default f64)")
    run.add_argument("--scale", type=_positive_float, default=1.0,
                     help="scale the scene's lengths by this factor and its times by the square root "
                          "(same motion, L times larger; default 1)")
    run.add_argument("--arch", choices=["cpu", "cuda", "vulkan"], default="cpu", help="Taichi backend (default cpu)")
    run.add_argument("--out", help="output folder (default outputs/<scene>/; with `all`, the parent folder)")
    run.add_argument("--no-frames", action="store_true", help="render no frames (faster)")
    run.add_argument("--gif", action="store_true", help="also write animation.gif")
    run.add_argument("--contacts", action="store_true", help="draw the contact points in the frames")
    run.add_argument("--force", action="store_true",
                     help="write into an output folder that holds other files (never overwriting them)")
    run.add_argument("--quiet", action="store_true", help="no progress lines")
    run.add_argument("--jobs", type=_positive_int, default=None,
                     help="with `all`: scenes run side by side in this many processes (default: one per core, "
                          "at most 4; 1 runs them in this process, with progress lines)")
    sweep = sub.add_parser(
        "sweep",
        help="the speed/accuracy study: every setting combination per scene, sweep.csv + pareto.png",
        description="Run each SCENE at every combination of --substeps, --iterations and --precision, "
                    "each run in its own process (no frames), and write sweep.csv (one row per run: "
                    "settings, wall time per simulated second, final and maximum penetration, settled, "
                    "time to settle, energy drift, verdict) and pareto.png (wall time against maximum "
                    "penetration, each scene's Pareto front) into --out, with each run's metrics under "
                    "runs/<scene>/<setting>/. Prints the recommended setting: the fastest that passes "
                    "the most scenes. Exit status 0 when every run completed, 1 if any failed (NaN, "
                    "explosion), 2 for bad usage.",
    )
    sweep.add_argument("scenes", nargs="+", metavar="SCENE",
                       help="built-in scene names (`erleben` for Erleben's six) or scene files")
    sweep.add_argument("--substeps", default="1,2,4,8,16,32", help="comma list (default 1,2,4,8,16,32)")
    sweep.add_argument("--iterations", default="1,2,4,8,16", help="comma list (default 1,2,4,8,16)")
    sweep.add_argument("--precision", default="f64", help="comma list of f32, f64 (default f64)")
    sweep.add_argument("--frames", type=_positive_int, help="frames per run (default: each scene's)")
    sweep.add_argument("--workers", type=_positive_int,
                       help="runs at a time (default: one per CPU core; each Taichi gets cores/workers threads)")
    sweep.add_argument("--ray", metavar="ADDRESS",
                       help="run on a Ray cluster at ADDRESS (`local` starts one here); needs the cluster extra")
    sweep.add_argument("--arch", choices=["cpu", "cuda", "vulkan"], default="cpu", help="Taichi backend (default cpu)")
    sweep.add_argument("--out", default="outputs/sweep", help="output folder (default outputs/sweep)")
    sweep.add_argument("--force", action="store_true",
                       help="write into an output folder that holds other files (never overwriting them)")
    sweep.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


INTERRUPTED = 130  # _run_one's status after Ctrl-C; the command line exits 1


def _run_one(config, args, out) -> tuple[int, dict | None]:
    from .core import runtime
    from .scene.config import SceneError, scale_scene
    from .output.run import OutputError, run_scene
    from .scene.scene import Scene

    try:
        if args.scale != 1.0:
            config = scale_scene(config, args.scale)
        if args.substeps:
            config.sim.substeps = args.substeps
        if args.iterations:
            config.sim.iterations = args.iterations
        runtime.init_when_needed(arch=args.arch, precision=args.precision)
        if not args.quiet:
            print(f"taichi-dcd: building {config.name} ({len(config.bodies)} bodies)", file=sys.stderr)
        scene = Scene(config)
    except (SceneError, RuntimeError) as exc:
        print(f"taichi-dcd: error: {exc}", file=sys.stderr)
        return 2, None
    for line in scene.warnings:
        print(f"taichi-dcd: warning: {line}", file=sys.stderr)
    try:
        metrics = run_scene(scene, out, frames=args.frames, progress=None if args.quiet else sys.stderr,
                            render=not args.no_frames, gif=args.gif, draw_contacts=args.contacts,
                            force=args.force)
    except OutputError as exc:
        print(f"taichi-dcd: error: {exc}", file=sys.stderr)
        return 2, None
    except OSError as exc:
        print(f"taichi-dcd: error: cannot write to {out}: {exc.strerror or exc}", file=sys.stderr)
        return 2, None
    except KeyboardInterrupt:
        print(f"taichi-dcd: interrupted; partial results in {out}", file=sys.stderr)
        return INTERRUPTED, None
    if not metrics["complete"]:
        print(f"taichi-dcd: error: {metrics['error']} (last good state in {out})", file=sys.stderr)
        return 1, metrics
    verdict = "settled" if metrics["settled"] else "not settled"
    print(f"{config.name}: {metrics['frames']} frames, {metrics['sim_time']:.2f} s simulated in "
          f"{metrics['wall_time_s']:.1f} s wall, {verdict}; penetration final "
          f"{metrics['final_penetration_depth']:.2e} m, max {metrics['max_penetration_depth']:.2e} m, "
          f"overlap {metrics['final_overlap_volume']:.2e} m³; results in {out}")
    return 0, metrics


def default_jobs() -> int:
    """Processes for `run all`: one per core, at most MAX_JOBS."""
    return max(1, min(os.cpu_count() or 1, MAX_JOBS))


# `run all` runs at most this many scenes side by side by default (each process holds a Taichi
# program and compiles the frame kernels once).
MAX_JOBS = 4


def _run_all_here(names, args, root) -> dict:
    """Each scene in turn in this process: {name: _run_one's status}."""
    from .scene.builtin import scene_config

    codes = {}
    for name in names:
        codes[name] = _run_one(scene_config(name), args, root / name)[0]
        if codes[name] == INTERRUPTED:
            break
    return codes


def _run_scenes_in_worker(names: list[str], args, root, cache_slot: int) -> dict:
    """Scenes of `run all` one after another in a worker process (spawned: a forked child of an
    initialised Taichi hangs), without progress lines; the later ones run with the kernels the
    first compiled, and the kernel cache folder `cache_slot` is tried first
    (core.kernel_cache). Returns {name: _run_one's status}."""
    from .core import kernel_cache

    os.environ[kernel_cache.ENV_PREFERRED_SLOT] = str(cache_slot)
    args.quiet = True
    return _run_all_here(names, args, root)


# Relative cost of a frame of a scene with a soft body (more substeps, a 1,280-triangle
# membrane to measure) against a rigid scene's, for sharing scenes out among workers.
SOFT_FRAME_COST = 5.0


def plan_workers(scenes: list[tuple[str, int, bool]], jobs: int) -> list[list[str]]:
    """Scenes (name, frames, has a soft body) shared out among at most `jobs` workers so that
    no worker compiles both the soft and the rigid frame kernel: workers go to the two kinds
    in proportion to their frames (weighted by SOFT_FRAME_COST), at least one each, and each
    kind's scenes to its workers longest first, each to the least loaded."""
    kinds = {}
    for name, frames, soft in scenes:
        kinds.setdefault(soft, []).append((name, frames * (SOFT_FRAME_COST if soft else 1.0)))
    total = sum(cost for items in kinds.values() for _, cost in items)
    plans = []
    left = jobs
    for k, (soft, items) in enumerate(sorted(kinds.items(), key=lambda kv: -sum(c for _, c in kv[1]))):
        share = sum(c for _, c in items) / total
        workers = left if k == len(kinds) - 1 else max(1, min(left - (len(kinds) - 1 - k), round(jobs * share)))
        workers = max(1, min(workers, len(items)))
        left -= workers
        loads = [[0.0, []] for _ in range(workers)]
        for name, cost in sorted(items, key=lambda item: -item[1]):
            least = min(loads, key=lambda load: load[0])
            least[0] += cost
            least[1].append(name)
        plans += [names for _, names in loads]
    return plans


def _run_all_in_processes(names, args, root, jobs: int) -> dict:
    """The scenes in `jobs` worker processes (plan_workers), each scene's files as a run in
    this process would write them: {name: _run_one's status}."""
    import copy
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    from .scene.builtin import scene_config

    configs = {name: scene_config(name) for name in names}
    plans = plan_workers([(name, c.sim.frames, any(b.kind in ("soft", "cloth") for b in c.bodies))
                          for name, c in configs.items()], jobs)
    if not args.quiet:
        print(f"taichi-dcd: running {len(names)} scenes in {len(plans)} processes (--jobs)", file=sys.stderr)
    codes = {}
    pool = ProcessPoolExecutor(max_workers=len(plans), mp_context=multiprocessing.get_context("spawn"))
    try:
        futures = {pool.submit(_run_scenes_in_worker, plan, copy.copy(args), root, slot): plan
                   for slot, plan in enumerate(plans)}
        for future in as_completed(futures):
            try:
                codes.update(future.result())
            except Exception as exc:  # noqa: BLE001 — a crashed worker fails the scenes it had
                plan = futures[future]
                print(f"taichi-dcd: error: the worker process running {', '.join(plan)} failed "
                      f"({type(exc).__name__}: {exc})", file=sys.stderr)
                codes.update({name: 1 for name in plan if name not in codes})
    except KeyboardInterrupt:
        pool.shutdown(wait=False, cancel_futures=True)
        print("taichi-dcd: interrupted; finished scenes are in " + str(root), file=sys.stderr)
        return {**codes, "": INTERRUPTED}
    pool.shutdown()
    return codes


def _cmd_run(args) -> int:
    from pathlib import Path

    from .scene.builtin import scene_config
    from .scene.config import SceneError

    if args.scene == "all":
        from .scene.builtin import builtin_names

        from .output.run import MANIFEST, manifest_files, write_json_atomic

        from .output.report import INDEX, write_index

        root = Path(args.out) if args.out else Path("outputs")
        sheet, index = root / "contact-sheet.png", root / INDEX
        for path in (sheet, index):
            if path.exists() and path.name not in manifest_files(root):
                print(f"taichi-dcd: error: {path} was not written by this tool and would be overwritten; "
                      "choose another --out", file=sys.stderr)
                return 2
        names = builtin_names()
        jobs = min(args.jobs or default_jobs(), len(names))
        codes = _run_all_in_processes(names, args, root, jobs) if jobs > 1 else _run_all_here(names, args, root)
        if INTERRUPTED in codes.values():
            return 1
        status = max(codes.values(), default=0)
        finished = [name for name in names if (root / name / "metrics.json").is_file()]
        ours = [index.name] + ([] if args.no_frames else [sheet.name])
        write_json_atomic(root / MANIFEST, {"written_by": "taichi-dcd", "files": ours})
        if not args.no_frames:
            from .output.render import write_contact_sheet

            write_contact_sheet([(n, root / n / "frames") for n in finished], sheet)
            print(f"contact sheet: {sheet}")
        print(f"report: {write_index(root, finished)}")
        return status
    try:
        config = scene_config(args.scene)
    except SceneError as exc:
        print(f"taichi-dcd: error: {exc}", file=sys.stderr)
        return 2
    suffix = f"-x{args.scale:g}" if args.scale != 1.0 else ""
    out = Path(args.out) if args.out else Path("outputs") / f"{config.name}{suffix}"
    code = _run_one(config, args, out)[0]
    return 1 if code == INTERRUPTED else code



def _cmd_sweep(args) -> int:
    from .scene.builtin import ERLEBEN_SIX, scene_config
    from .scene.config import SceneError
    from .output.run import OutputError
    from .output.sweep import SweepError, parse_list, recommend, run_failed, run_sweep, sweep_runs

    try:
        substeps = parse_list(args.substeps, int)
        iterations = parse_list(args.iterations, int)
        precisions = parse_list(args.precision, str, allowed=("f32", "f64"))
    except ValueError as exc:
        print(f"taichi-dcd: error: {exc}", file=sys.stderr)
        return 2
    scenes = [s for name in args.scenes for s in (ERLEBEN_SIX if name == "erleben" else [name])]
    try:
        for name in dict.fromkeys(scenes):
            scene_config(name)  # a bad name or file fails here, before any process starts
    except SceneError as exc:
        print(f"taichi-dcd: error: {exc}", file=sys.stderr)
        return 2
    if args.arch != "cpu" and not args.ray:
        # Every run would fail alike in its own process; say so once, before any starts. (On
        # a Ray cluster the workers' machines, not this one, need the GPU.)
        from .core import runtime

        try:
            runtime.init(arch=args.arch)
        except RuntimeError as exc:
            print(f"taichi-dcd: error: {exc}", file=sys.stderr)
            return 2
        runtime.reset()
    runs = sweep_runs(list(dict.fromkeys(scenes)), substeps, iterations, precisions)
    if not args.quiet:
        print(f"taichi-dcd: sweeping {len(runs)} runs into {args.out}", file=sys.stderr)
    try:
        rows = run_sweep(runs, args.out, workers=args.workers, arch=args.arch, frames=args.frames,
                         ray_address=args.ray, force=args.force, progress=None if args.quiet else sys.stderr)
    except (OutputError, SweepError) as exc:
        print(f"taichi-dcd: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"taichi-dcd: interrupted; finished runs are in {args.out}/runs (no sweep.csv written)",
              file=sys.stderr)
        return 1
    passed = sum(bool(r.get("passed")) for r in rows)
    failed = [r for r in rows if run_failed(r)]
    print(f"sweep: {len(rows)} runs, {passed} passed the contact test, {len(failed)} failed to run; "
          f"{args.out}/sweep.csv, {args.out}/pareto.png")
    best = recommend(rows)
    if best and best["cost"] == float("inf"):
        print("recommended: none (no setting ran every scene to the end)")
    elif best:
        print(f"recommended: --substeps {best['substeps']} --iterations {best['iterations']} --precision "
              f"{best['precision']} (passes {best['passed']} of {best['scenes']} scenes, "
              f"{best['cost']:.3g} s wall per simulated second summed over them)")
    for r in failed:
        print(f"taichi-dcd: {r['scene']} s{r['substeps']}-i{r['iterations']}-{r['precision']}: {r['verdict']}",
              file=sys.stderr)
    return 1 if failed else 0


def _cmd_list(args) -> int:
    from .scene.builtin import ALL, KNOWN, describe

    width = max(len(n) for n in KNOWN)
    for name in ALL:
        print(f"{name:<{width}}  {describe(name)}")
    for name in KNOWN[len(ALL):]:
        print(f"{name:<{width}}  {describe(name)} (not in `all`)")
    return 0


def _cmd_union(args) -> int:
    from pathlib import Path

    import trimesh

    from .measure.self_intersection import crossing_pairs
    from .scene.mesh_check import checked_mesh, union_of_parts

    source, out = Path(args.mesh), Path(args.out)
    if not source.is_file():
        print(f"taichi-dcd: error: mesh file {source} does not exist", file=sys.stderr)
        return 2
    if out.exists() and (not args.force or out.resolve() == source.resolve()):
        why = "is the input" if out.resolve() == source.resolve() else "exists (use --force to overwrite it)"
        print(f"taichi-dcd: error: {out} {why}", file=sys.stderr)
        return 2
    try:
        given = trimesh.load(source, force="mesh", process=False)
        mesh, _ = checked_mesh(source.stem, given.vertices, given.faces, str(source), crossings=False)
    except Exception as exc:  # noqa: BLE001 — trimesh raises many types for unparsable files
        print(f"taichi-dcd: error: cannot use {source}: {exc}", file=sys.stderr)
        return 2
    if len(crossing_pairs(mesh.vertices, mesh.faces)) == 0:
        print(f"taichi-dcd: {source}: no two of its triangles cross; nothing to fix, nothing written",
              file=sys.stderr)
        return 0
    solid = union_of_parts(mesh)
    if solid is None:
        print(f"taichi-dcd: error: {source}: no union of its parts removes its crossings (it is one part, "
              "or a part crosses itself); repair it in a modeller", file=sys.stderr)
        return 2
    partial = out.with_name(out.name + ".partial" + out.suffix)
    try:
        solid.export(partial)
        os.replace(partial, out)
    except (OSError, ValueError) as exc:
        partial.unlink(missing_ok=True)
        print(f"taichi-dcd: error: cannot write {out}: {exc}", file=sys.stderr)
        return 2
    print(f"{out}: {len(solid.faces)} triangles, volume {solid.volume:.6g} (as given: {mesh.volume:.6g})")
    return 0


def _cmd_collide(args) -> int:
    import numpy as np

    from .core import runtime
    from .collision.narrowphase import collide_triangle_pairs

    try:
        runtime.init(arch=args.arch, precision=args.precision)
        r = collide_triangle_pairs(np.array([args.a]), np.array([args.b]))
    except (ValueError, RuntimeError) as exc:
        print(f"taichi-dcd: error: {exc}", file=sys.stderr)
        return 2
    side = {0: "A", 1: "B", -1: "none"}[int(r.side[0])]
    fmt = lambda v: "(" + ", ".join(f"{x:.9g}" for x in v) + ")"  # noqa: E731
    print(f"hit:    {bool(r.hit[0])}")
    print(f"depth:  {r.depth[0]:.9g}")
    print(f"moves:  {side}")
    print(f"normal: {fmt(r.normal[0])}")
    print(f"point:  {fmt(r.point[0])}")
    return 0


def main(argv: list[str] | None = None) -> int:
    # Taichi prints a version banner on import; a command line tool's output is its own.
    os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "False")
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return _dispatch(parser, args)
    except BrokenPipeError:
        # The reader went away (`taichi-dcd list | head -1`): nothing left to say to it, and
        # Python's own flush at exit must not fail on the closed pipe either.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except Exception as exc:  # noqa: BLE001 — a command line tool answers in one line, not a traceback
        if os.environ.get("TAICHI_DCD_TRACEBACK"):
            raise
        print(f"taichi-dcd: error: internal error, please report it (set TAICHI_DCD_TRACEBACK=1 for details): "
              f"{type(exc).__name__}: {exc}".replace("\n", " "), file=sys.stderr)
        return 1


def _dispatch(parser, args) -> int:
    if args.command is None:
        parser.print_help()
        return 0
    if args.command == "collide":
        return _cmd_collide(args)
    if args.command == "run":
        return _cmd_run(args)
    if args.command == "list":
        return _cmd_list(args)
    if args.command == "sweep":
        return _cmd_sweep(args)
    if args.command == "union":
        return _cmd_union(args)
    parser.error(f"unknown command {args.command!r}")
    return 2
