"""Penetration measured from meshes alone, independently of the solver (DESIGN.md §5).

For closed bodies A and B the overlap is the solid I = A ∩ B (manifold3d, in double
precision). Its boundary is made of A's surface inside B and B's surface inside A, so
A's deepest point inside B, measured as its distance to B's surface, lies on I's
boundary, and so does B's deepest point inside A. The pair's depth is the largest
distance, to the other body's surface, of a point of I's boundary: I's vertices, points
along its edges and a barycentric grid on its faces (the grid spacing bounds how much a
depth inside a face can be underestimated; vertices and edges are exact). The scene's
depth is the largest over pairs of bodies that are not both static.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

# Points per edge and per face side of the overlap's sampling grid (at most).
EDGE_SAMPLES = 32


@dataclass
class Penetration:
    """depth: largest distance (m) of a surface point of one body inside the other to the
    other's surface; volume: overlap volume (m³); pair: the two body names (or None)."""

    depth: float = 0.0
    volume: float = 0.0
    pair: tuple[str, str] | None = None


def _manifold(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray):
    import manifold3d

    mesh = manifold3d.Mesh64(vert_properties=np.ascontiguousarray(vertices - origin, np.float64),
                             tri_verts=np.ascontiguousarray(faces, np.uint64))
    return manifold3d.Manifold(mesh)


def overlap(a: trimesh.Trimesh, b: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray, float]:
    """The solid A ∩ B as (vertices (n, 3), faces (m, 3), volume m³); empty when they do not
    overlap. Coordinates are shifted to the boxes' common centre for the boolean, so that
    large offsets do not cost precision."""
    lo = np.maximum(a.bounds[0], b.bounds[0])
    hi = np.minimum(a.bounds[1], b.bounds[1])
    if np.any(lo > hi):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), 0.0
    origin = 0.5 * (lo + hi)
    solid = _manifold(np.asarray(a.vertices), np.asarray(a.faces), origin) ^ \
        _manifold(np.asarray(b.vertices), np.asarray(b.faces), origin)
    out = solid.to_mesh64()
    v = np.asarray(out.vert_properties, np.float64)[:, :3] + origin
    f = np.asarray(out.tri_verts, np.int64).reshape(-1, 3)
    return v, f, max(float(solid.volume()), 0.0)


def surface_samples(vertices: np.ndarray, faces: np.ndarray, per_edge: int = EDGE_SAMPLES) -> np.ndarray:
    """Points on a triangle mesh: its vertices, points along its edges and a barycentric
    grid on its faces, with spacing = (longest edge of the mesh) / per_edge."""
    if len(faces) == 0:
        return np.zeros((0, 3))
    tri = vertices[faces]
    longest = float(np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)))
    points = [vertices]
    for f in range(len(faces)):
        t = tri[f]
        size = float(np.max(np.linalg.norm(t - np.roll(t, 1, axis=0), axis=1)))
        n = int(np.clip(np.ceil(per_edge * size / longest), 1, per_edge)) if longest > 0 else 1
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        u, v = i[keep] / n, j[keep] / n
        points.append(t[0] + u[:, None] * (t[1] - t[0]) + v[:, None] * (t[2] - t[0]))
    return np.concatenate(points)


def distance_to_surface(points: np.ndarray, mesh: trimesh.Trimesh, chunk: int = 200_000) -> np.ndarray:
    """Unsigned distance (m) of each point (n, 3) to the mesh's surface (brute force over the
    triangles near the points' box)."""
    if len(points) == 0:
        return np.zeros(0)
    tris = np.asarray(mesh.triangles)
    # Only triangles within reach matter: any point's distance is at most its distance to
    # the nearest vertex, so drop triangles whose box is further than the largest such bound.
    lo, hi = points.min(axis=0), points.max(axis=0)
    vertex_bound = np.sqrt(np.min(((points[:, None, :] - _subsample(np.asarray(mesh.vertices), 64)[None]) ** 2)
                                  .sum(axis=2), axis=1)).max()
    t_lo, t_hi = tris.min(axis=1), tris.max(axis=1)
    near = np.all((t_lo <= hi + vertex_bound) & (t_hi >= lo - vertex_bound), axis=1)
    tris = tris[near]
    best = np.full(len(points), np.inf)
    step = max(1, chunk // max(len(tris), 1))
    for start in range(0, len(points), step):
        p = points[start:start + step]
        pp = np.repeat(p, len(tris), axis=0)
        tt = np.tile(tris, (len(p), 1, 1))
        closest = trimesh.triangles.closest_point(tt, pp)
        d = np.linalg.norm(closest - pp, axis=1).reshape(len(p), len(tris))
        best[start:start + step] = d.min(axis=1)
    return best


def _subsample(v: np.ndarray, n: int) -> np.ndarray:
    return v if len(v) <= n else v[np.linspace(0, len(v) - 1, n).astype(int)]


def pair_penetration(a: trimesh.Trimesh, b: trimesh.Trimesh) -> tuple[float, float]:
    """(depth m, overlap volume m³) of two closed meshes, as in the module docstring."""
    v, f, volume = overlap(a, b)
    if len(f) == 0:
        return 0.0, 0.0
    points = surface_samples(v, f)
    depth = np.maximum(distance_to_surface(points, a), distance_to_surface(points, b))
    # A point of I's boundary is on one surface (distance ~0 to it) and at `depth` from the other.
    return float(depth.max()), volume


def scene_penetration(bodies: list[tuple[str, str, trimesh.Trimesh]]) -> Penetration:
    """The deepest pair and the total overlap volume over pairs of bodies (name, kind,
    world mesh) that are not both static."""
    result = Penetration()
    for i in range(len(bodies)):
        for j in range(i + 1, len(bodies)):
            (name_a, kind_a, a), (name_b, kind_b, b) = bodies[i], bodies[j]
            if kind_a == "static" and kind_b == "static":
                continue
            depth, volume = pair_penetration(a, b)
            result.volume += volume
            if depth > result.depth or (result.pair is None and volume > 0):
                result.depth, result.pair = depth, (name_a, name_b)
    return result
