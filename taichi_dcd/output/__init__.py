"""What a run leaves behind: the run folder and its frames loop, the rasteriser, the sweep."""
