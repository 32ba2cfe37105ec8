"""Erleben-style contact test `wedge-in-crack` (see `taichi-dcd list`). Takes the flags of
`taichi-dcd run`, e.g. `python scenes/wedge-in-crack.py --no-frames --out DIR`."""
import sys

from taichi_dcd.cli import main

if __name__ == "__main__":
    sys.exit(main(["run", "wedge-in-crack", *sys.argv[1:]]))
