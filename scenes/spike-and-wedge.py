"""Erleben-style contact test `spike-and-wedge` (see `taichi-dcd list`). Takes the flags of
`taichi-dcd run`, e.g. `python scenes/spike-and-wedge.py --no-frames --out DIR`."""
import sys

from taichi_dcd.cli import main

if __name__ == "__main__":
    sys.exit(main(["run", "spike-and-wedge", *sys.argv[1:]]))
