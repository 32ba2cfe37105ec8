"""taichi_dcd: drop tests of triangle meshes around the unified discrete collision
method of Kikuchi & Kanai (EG 2025), on Taichi kernels.

Importing the package imports neither Taichi nor its kernels, and never
initialises Taichi: call `taichi_dcd.init(...)` to choose the arch and precision,
or let the first call that needs a kernel use the defaults (CPU, f64).
"""

__version__ = "0.1.0"

# Public name -> module that defines it, imported on first access.
_LAZY = {
    "init": "core.runtime",
    "is_initialized": "core.runtime",
    "collide_triangle_pairs": "collision.narrowphase",
    "PairContacts": "collision.narrowphase",
    "find_contacts": "collision.pipeline",
    "MeshContacts": "collision.pipeline",
    "load_scene": "scene.scene",
    "Scene": "scene.scene",
    "SceneError": "scene.config",
    "SimulationError": "solver.solver",
}

__all__ = ["__version__", *_LAZY]


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        module = importlib.import_module(f".{_LAZY[name]}", __name__)
        return getattr(module, name)
    raise AttributeError(f"module 'taichi_dcd' has no attribute {name!r}")
