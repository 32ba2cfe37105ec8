"""What a run leaves behind: the run folder and its frames loop, the rasteriser, the sweep."""

from ..core import frontend

# Taichi's frontend memos in place before this package's kernels are decorated (core.frontend).
frontend.speed_up()
