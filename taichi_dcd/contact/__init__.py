"""The contact rules: how the narrow phase's triangle-pair results become the solver's contact
rows (one small named function per rule), the row buffer and the anchors rows are tied to."""

from ..core import frontend

# Taichi's frontend memos in place before this package's kernels are decorated (core.frontend).
frontend.speed_up()
