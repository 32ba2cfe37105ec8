"""Runs the built-in scene this file is named after: each scenes/<name>.py is a link to this
file, and the scene itself is the file taichi_dcd ships (`taichi-dcd list`; the package's
scene/files/<name>.toml). Takes the flags of `taichi-dcd run`, e.g.
`python scenes/spikes.py --no-frames --out DIR`."""
import sys
from pathlib import Path

from taichi_dcd.cli import main

if __name__ == "__main__":
    sys.exit(main(["run", Path(sys.argv[0]).stem, *sys.argv[1:]]))
