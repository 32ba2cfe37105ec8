"""Penetration of a cloth (an open sheet), measured from meshes alone, independently of the
solver and of the way it turns a cloth's faces.

A sheet has no inside, so the closed bodies' measure (an overlap solid) does not apply:

- cloth against a closed body: the deepest point of the sheet inside the solid, as its
  distance to the solid's surface. Points: the sheet's vertices and a barycentric grid on its
  faces (penetration.surface_samples); inside: the solid's winding number at the point (the
  sum of its faces' solid angles over 4π, Van Oosterom & Strackee 1983) above one half.
  A tip pushed through the sheet leaves the sheet's disc around it inside the tip, so a
  pierced sheet is found too.
- cloth against cloth, and a cloth against itself: crossing triangle pairs (an edge of one
  through the other's interior, self_intersection.triangles_cross); a pair's depth is the
  smaller of the two triangles' pokes through the other's plane, each the lesser of how far
  it reaches on either side (a sheet may come from either side).
"""

from __future__ import annotations

import numpy as np
import trimesh

from .penetration import distance_to_surface, surface_samples
from .self_intersection import PAIR_CHUNK, _box_pairs, triangles_cross

# Sheet samples tested against a solid at once (memory: ~10 doubles per sample and face).
SAMPLE_CHUNK = 2_000_000


def winding_numbers(points: np.ndarray, mesh: trimesh.Trimesh) -> np.ndarray:
    """(n,) the closed, outward mesh's winding number at each point (n, 3): 1 inside, 0
    outside, from the solid angles its faces subtend."""
    tris = np.asarray(mesh.triangles, np.float64)
    out = np.zeros(len(points))
    step = max(1, SAMPLE_CHUNK // max(len(tris), 1))
    for start in range(0, len(points), step):
        p = points[start:start + step]
        a, b, c = (tris[None, :, k, :] - p[:, None, :] for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        det = np.einsum("ijk,ijk->ij", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ijk,ijk->ij", a, b) * lc + np.einsum("ijk,ijk->ij", b, c) * la
               + np.einsum("ijk,ijk->ij", c, a) * lb)
        out[start:start + step] = np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi)
    return out


def sheet_inside_depth(sheet: trimesh.Trimesh, solid: trimesh.Trimesh) -> float:
    """How deep (m) the sheet's deepest sampled point lies inside the closed solid; 0 if none is."""
    lo, hi = solid.bounds
    points, _, _ = surface_samples(np.asarray(sheet.vertices, np.float64), np.asarray(sheet.faces, np.int64))
    points = points[((points >= lo) & (points <= hi)).all(axis=1)]
    if not len(points):
        return 0.0
    inside = points[winding_numbers(points, solid) > 0.5]
    return float(distance_to_surface(inside, solid).max()) if len(inside) else 0.0


def poke_depths(tri_a: np.ndarray, tri_b: np.ndarray) -> np.ndarray:
    """(k,) for triangle pairs tri_a[k], tri_b[k] ((k, 3, 3) m): the smaller of the two
    triangles' pokes through the other's plane, a poke being the lesser of how far the
    triangle reaches in front of and behind the plane (orientation-free)."""
    def poke(tri, other):
        n = np.cross(other[:, 1] - other[:, 0], other[:, 2] - other[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
        side = np.einsum("ij,ikj->ik", n, tri - other[:, :1, :])
        return np.minimum(np.maximum(side.max(axis=1), 0.0), np.maximum(-side.min(axis=1), 0.0))

    return np.minimum(poke(tri_a, tri_b), poke(tri_b, tri_a))


def sheet_crossings(va: np.ndarray, fa: np.ndarray, vb: np.ndarray, fb: np.ndarray) -> tuple[int, float]:
    """(crossing pairs, the deepest poke_depths of them in m) between two meshes' triangles."""
    ta, tb = np.asarray(va, np.float64)[fa], np.asarray(vb, np.float64)[fb]
    corners = np.concatenate([ta, tb])
    pairs = _box_pairs(corners.min(axis=1), corners.max(axis=1))
    pairs = pairs[(pairs[:, 0] < len(ta)) & (pairs[:, 1] >= len(ta))]
    count, deepest = 0, 0.0
    for start in range(0, len(pairs), PAIR_CHUNK):
        i, j = pairs[start:start + PAIR_CHUNK, 0], pairs[start:start + PAIR_CHUNK, 1] - len(ta)
        hit = triangles_cross(ta[i], tb[j])
        if hit.any():
            count += int(hit.sum())
            deepest = max(deepest, float(poke_depths(ta[i[hit]], tb[j[hit]]).max()))
    return count, deepest


def cloth_pair_depth(a: trimesh.Trimesh, kind_a: str, b: trimesh.Trimesh, kind_b: str) -> float:
    """Depth (m) between two bodies at least one of which is a cloth: a sheet inside a solid,
    or two sheets' deepest crossing."""
    if kind_a == "cloth" and kind_b == "cloth":
        return sheet_crossings(a.vertices, a.faces, b.vertices, b.faces)[1]
    sheet, solid = (a, b) if kind_a == "cloth" else (b, a)
    return sheet_inside_depth(sheet, solid)
