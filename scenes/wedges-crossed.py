"""Erleben-style contact test `wedges-crossed` (see `taichi-dcd list`). Takes the flags of
`taichi-dcd run`, e.g. `python scenes/wedges-crossed.py --no-frames --out DIR`."""
import sys

from taichi_dcd.cli import main

if __name__ == "__main__":
    sys.exit(main(["run", "wedges-crossed", *sys.argv[1:]]))
