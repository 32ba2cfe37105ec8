"""Erleben-style contact test `spike-in-pit` (see `taichi-dcd list`). Takes the flags of
`taichi-dcd run`, e.g. `python scenes/spike-in-pit.py --no-frames --out DIR`."""
import sys

from taichi_dcd.cli import main

if __name__ == "__main__":
    sys.exit(main(["run", "spike-in-pit", *sys.argv[1:]]))
