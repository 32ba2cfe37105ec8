"""Scenes: validated configuration, procedural shapes, the builder (numpy to Model, the only
allocation site), the built-in scene files and the Scene that steps them frame by frame."""
