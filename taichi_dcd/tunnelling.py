"""How far a body may move in one substep before discrete collision detection can miss
a contact, and how many substeps a frame needs so that none is missed.

Detection is discrete: a triangle pair is tested where the bodies are at the end of a
substep. A vertex that crosses more than half of the body it enters within one substep
is nearer to that body's far side than to its near side, and the depth and normal the
narrow phase finds push it on through; a body thinner than one substep's motion can be
passed without any pair ever intersecting. So a substep may move a body relative to any
other by at most TUNNEL_FRACTION of the thinnest body's thickness.
"""

from __future__ import annotations

import math

import numpy as np

TUNNEL_FRACTION = 0.5
# A frame may run at most this many times the configured substeps before the run stops
# and says which body is too fast.
MAX_SUBSTEP_FACTOR = 64
# Thickness is measured from at most this many face centroids (the largest faces).
THICKNESS_RAYS = 2000


def mesh_thickness(vertices: np.ndarray, faces: np.ndarray, rays: int = THICKNESS_RAYS) -> float:
    """The thinnest wall of a closed, outward mesh (m): the shortest distance from a face's
    centroid, inward along the face's normal, to the next surface, over the `rays` largest
    faces. Thin features between centroids (a sharp ridge's last millimetres) are not
    seen; a thin plate or wall is."""
    v = np.asarray(vertices, np.float64)
    tris = v[np.asarray(faces)]
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area2 = np.linalg.norm(cross, axis=1)
    order = np.argsort(-area2)[:rays]
    origin = tris[order].mean(axis=1)
    direction = -cross[order] / area2[order, None]
    size = float(np.max(v.max(axis=0) - v.min(axis=0)))
    best = np.full(len(order), np.inf)
    chunk = max(1, 2_000_000 // max(len(tris), 1))
    for start in range(0, len(order), chunk):
        t = _ray_hits(origin[start:start + chunk], direction[start:start + chunk], tris)
        t[np.arange(len(t)), order[start:start + chunk]] = np.inf   # a ray leaves its own face
        t[t <= 1e-9 * size] = np.inf                                # or grazes a neighbour at its start
        best[start:start + chunk] = t.min(axis=1)
    finite = best[np.isfinite(best)]
    return float(finite.min()) if len(finite) else size


def _ray_hits(origin: np.ndarray, direction: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(R, T) distance along each ray to each triangle, inf where it misses (Möller–Trumbore)."""
    e1 = tris[:, 1] - tris[:, 0]
    e2 = tris[:, 2] - tris[:, 0]
    p = np.cross(direction[:, None, :], e2[None])
    det = np.einsum("rtk,tk->rt", p, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = origin[:, None, :] - tris[None, :, 0]
        u = np.einsum("rtk,rtk->rt", s, p) * inv
        q = np.cross(s, e1[None])
        w = np.einsum("rtk,rk->rt", q, direction) * inv
        t = np.einsum("rtk,tk->rt", q, e2) * inv
        hit = (np.abs(det) > 0) & (u >= 0) & (w >= 0) & (u + w <= 1) & (t > 0)
    return np.where(hit, t, np.inf)


def substeps_for_motion(motion_per_frame: float, thinnest: float, substeps: int) -> int:
    """The substeps a frame needs (at least `substeps`) so that a relative motion of
    `motion_per_frame` metres moves at most TUNNEL_FRACTION·thinnest per substep."""
    if not (0 < motion_per_frame < math.inf) or not thinnest > 0:
        return substeps  # NaN or infinite speeds are the solver's explosion check's to report
    return max(substeps, math.ceil(motion_per_frame / (TUNNEL_FRACTION * thinnest)))
