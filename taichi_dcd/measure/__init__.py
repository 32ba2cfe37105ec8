"""The independent penetration measure: overlap volume and depth from the final meshes alone."""
