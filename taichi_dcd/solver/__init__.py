"""XPBD time stepping: integration, contact projection, islands, soft constraints, substep
choice, and the solver object that sequences their kernels."""
