"""Triangle-pair collision: the unified narrow phase, the uniform-grid broad phase, the pipeline
that joins them for whole meshes, the contact buffer and a slow NumPy reference."""
