"""Built-in procedural shapes, usable in scene files as `shape = "..."` with their
parameters in `[body.params]`. Each returns a closed, outward-oriented trimesh.Trimesh
(y up, metres) centred on the origin. The Erleben shapes join them with the scenes.
"""

import trimesh


def box(size=(1.0, 1.0, 1.0), subdivisions: int = 0) -> trimesh.Trimesh:
    """An axis-aligned box of extents `size` (x, y, z), each face split `subdivisions`
    times into four."""
    mesh = trimesh.creation.box(extents=[float(s) for s in size])
    for _ in range(int(subdivisions)):
        mesh = mesh.subdivide()
    return mesh


def icosphere(radius: float = 0.5, subdivisions: int = 3) -> trimesh.Trimesh:
    """An icosphere (20·4^subdivisions triangles)."""
    return trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=float(radius))


SHAPES = {"box": box, "icosphere": icosphere}


def make_shape(name: str, params: dict) -> trimesh.Trimesh:
    """The built-in shape `name` with keyword `params`; ValueError for an unknown name or parameter."""
    if name not in SHAPES:
        raise ValueError(f"unknown shape {name!r} (built-in: {', '.join(SHAPES)})")
    try:
        return SHAPES[name](**params)
    except TypeError as exc:
        raise ValueError(f"shape {name!r}: bad parameters {params} ({exc})") from None
