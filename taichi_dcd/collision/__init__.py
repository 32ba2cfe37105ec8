"""Triangle-pair collision: the unified narrow phase, the uniform-grid broad phase, the pipeline
that joins them for whole meshes, the contact buffer and a slow NumPy reference."""

from ..core import frontend

# Taichi's frontend memos in place before this package's kernels are decorated (core.frontend).
frontend.speed_up()
