"""Erleben-style contact test `wedges` (see `taichi-dcd list`). Takes the flags of
`taichi-dcd run`, e.g. `python scenes/wedges.py --no-frames --out DIR`."""
import sys

from taichi_dcd.cli import main

if __name__ == "__main__":
    sys.exit(main(["run", "wedges", *sys.argv[1:]]))
