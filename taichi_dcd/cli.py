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
    return parser


def _cmd_collide(args) -> int:
    import numpy as np

    from . import runtime
    from .narrowphase import collide_triangle_pairs

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
    if args.command is None:
        parser.print_help()
        return 0
    if args.command == "collide":
        return _cmd_collide(args)
    parser.error(f"unknown command {args.command!r}")
    return 2
