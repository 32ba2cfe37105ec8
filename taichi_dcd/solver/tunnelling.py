"""How far a body may move in one substep before discrete collision detection can miss
a contact, and how many substeps a frame needs so that none is missed.

Detection is discrete: a triangle pair is tested where the bodies are at the end of a
substep. A vertex that crosses more than half of the body it enters within one substep
is nearer to that body's far side than to its near side, and the depth and normal the
narrow phase finds push it on through; a body thinner than one substep's motion can be
passed without any pair ever intersecting. So a substep may move a body relative to any
other by at most TUNNEL_FRACTION of the thinnest body's thickness.

The same blindness sets how deep a landing goes: a body found overlapping another at the
end of a substep has moved up to its relative motion in that substep past first contact.
So while two bodies are within one frame's motion of each other, a substep may move them
together by at most the scene's impact depth (SimConfig.max_impact_motion).
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


def substeps_for_impacts(box_lo: np.ndarray, box_hi: np.ndarray, velocity: np.ndarray, spin: np.ndarray,
                         moving: np.ndarray, frame_dt: float, g_norm: float, max_impact_motion: float,
                         substeps: int) -> tuple[int, int, int]:
    """The substeps a frame needs (at least `substeps`) so that no two bodies that can meet
    in this frame close in by more than `max_impact_motion` m per substep.

    box_lo, box_hi: (B, 3) world bounding boxes (m); velocity: (B, 3) linear velocities
    (m/s); spin: (B,) bound on a surface point's speed relative to the body's velocity
    (|ω|·reach, m/s); moving: (B,) bool, False for static bodies. Two bodies close in over
    the frame by at most (|v_a − v_b| + spin_a + spin_b + |g|·dt)·dt, so bodies falling
    side by side need nothing; they can meet when their boxes, grown by that, overlap.
    Returns (substeps, a, b) with (a, b) the pair that needs them, or (substeps, -1, -1)."""
    if len(spin) < 2 or not max_impact_motion > 0:
        return substeps, -1, -1
    lo, hi = np.asarray(box_lo, np.float64), np.asarray(box_hi, np.float64)
    moving = np.asarray(moving, bool)
    v = np.where(moving[:, None], np.asarray(velocity, np.float64), 0.0)
    spin = np.where(moving, np.asarray(spin, np.float64), 0.0)
    closing = np.linalg.norm(v[:, None, :] - v[None, :, :], axis=2) + spin[:, None] + spin[None, :] + g_norm * frame_dt
    pair_motion = np.nan_to_num(closing * frame_dt, nan=0.0, posinf=0.0)  # NaN: the explosion check's to report
    gap = np.maximum(lo[:, None, :] - hi[None, :, :], lo[None, :, :] - hi[:, None, :]).max(axis=2)
    meet = (gap <= pair_motion) & (moving[:, None] | moving[None, :])
    np.fill_diagonal(meet, False)
    need = np.where(meet, np.ceil(pair_motion / max_impact_motion), 0.0)
    a, b = np.unravel_index(int(np.argmax(need)), need.shape)
    if need[a, b] <= substeps:
        return substeps, -1, -1
    return int(need[a, b]), int(a), int(b)
