"""XPBD time stepping: integration, contact projection, islands, soft constraints, substep
choice, and the solver object that sequences their kernels."""

from ..core import frontend

# Taichi's frontend memos in place before this package's kernels are decorated (core.frontend).
frontend.speed_up()
