"""Soft drop `soft-ball-on-spike` (see `taichi-dcd list`). Takes the flags of
`taichi-dcd run`, e.g. `python scenes/soft-ball-on-spike.py --no-frames --out DIR`."""
import sys

from taichi_dcd.cli import main

if __name__ == "__main__":
    sys.exit(main(["run", "soft-ball-on-spike", *sys.argv[1:]]))
