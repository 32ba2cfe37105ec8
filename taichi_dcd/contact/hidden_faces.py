"""Faces of static bodies hidden against another static body's face.

Static blocks set side by side (a floor of tiles, a bed of blocks) share faces that lie
inside the solid they make together. A body resting across the seam sinks a little into
the top faces, as every resting contact does, and then also crosses the hidden side
faces: those contacts push it sideways, one block's face one way and the neighbour's the
other, and it never comes to rest (a spike lying across two abutting blocks jittered at
0.1 m/s). A hidden face can only be reached through another body, so it takes no part
in collision.
"""

from __future__ import annotations

import numpy as np

# A face is hidden when these points of it (vertices, edge midpoints, centroid, as
# barycentric weights) each lie on a face of one other static body that is coplanar with
# it and faces the other way.
_SAMPLE_WEIGHTS = np.array([
    [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0],
    [0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5],
    [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
])
# Facing the other way: unit normals within ~0.1° of opposite.
_OPPOSITE_COS = -1.0 + 1e-6
# Face pairs compared at once (bounds the temporary matrices to ~100 MiB).
_PAIRS_PER_BLOCK = 1 << 22


def hidden_static_faces(meshes: list[tuple[np.ndarray, np.ndarray]], static: list[bool],
                        rel_tol: float = 1e-7) -> list[np.ndarray]:
    """Per body, a (faces,) bool mask of the static faces hidden against another static body.

    meshes: per body (vertices (n, 3) in world space (m), faces (f, 3)); static: which bodies
    are static (only those are compared, and only their faces can be hidden). A face is
    hidden when its vertices, edge midpoints and centroid all lie, within rel_tol of the
    scene's size, on faces of one other static body that are coplanar with it and face the
    other way. A face only partly covered (the end of a block against a grooved block's
    notched end) stays a face. Zero-area faces are never hidden.
    """
    masks = [np.zeros(len(f), bool) for _, f in meshes]
    which = [k for k, s in enumerate(static) if s and len(meshes[k][1])]
    if len(which) < 2:
        return masks
    every = np.concatenate([np.asarray(meshes[k][0], np.float64) for k in which])
    tol = rel_tol * max(float(np.ptp(every, axis=0).max()), float(np.abs(every).max()), 1e-30)
    tris = {k: np.asarray(meshes[k][0], np.float64)[np.asarray(meshes[k][1])] for k in which}
    boxes = {k: (t.reshape(-1, 3).min(axis=0) - tol, t.reshape(-1, 3).max(axis=0) + tol) for k, t in tris.items()}
    for a in which:
        for b in which:
            if a == b or np.any(boxes[a][0] > boxes[b][1]) or np.any(boxes[b][0] > boxes[a][1]):
                continue
            masks[a] |= _covered_by(tris[a], tris[b], tol)
    return masks


def _unit_normals(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit normals (n, 3), whether each face has area, and twice each face's area."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    length = np.linalg.norm(n, axis=1)
    ok = length > 0.0
    n[ok] /= length[ok, None]
    return n, ok, length


def _covered_by(tris_a: np.ndarray, tris_b: np.ndarray, tol: float) -> np.ndarray:
    """(len(tris_a),) bool: faces of A whose sample points all lie on coplanar, opposite faces of B."""
    n_a, ok_a, _ = _unit_normals(tris_a)
    n_b, ok_b, double_area_b = _unit_normals(tris_b)
    samples = np.einsum("sk,tkd->tsd", _SAMPLE_WEIGHTS, tris_a)  # (A, S, 3)
    offset_b = np.einsum("jd,jd->j", n_b, tris_b[:, 0])
    # Only faces whose boxes come within reach: a sample inside B by the test below lies
    # within tol·L²/area of B in its plane (weight slack times a height, twice), and
    # off it by tol plus what the normals' 0.1° leaves over A's size.
    lo_a, hi_a = tris_a.min(axis=1), tris_a.max(axis=1)
    size_a = float((hi_a - lo_a).max(initial=0.0))
    longest_b_sq = ((np.roll(tris_b, -1, axis=1) - tris_b) ** 2).sum(axis=2).max(axis=1)  # (B,) m²
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.where(ok_b, tol * (1.0 + 2.0 * longest_b_sq / double_area_b), 0.0) + tol + 2e-3 * size_a
    lo_b, hi_b = tris_b.min(axis=1) - reach[:, None], tris_b.max(axis=1) + reach[:, None]
    # A's faces a block at a time, in order along x so that a block is a thin slab, against
    # the faces of B whose boxes reach the block's: whole, the (A, B) matrices of a
    # 25k-face block on a 50k-face ground took 19 GiB.
    ia, jb = [], []
    block = max(1, _PAIRS_PER_BLOCK // max(len(tris_b), 1))
    order = np.argsort(lo_a[:, 0] + hi_a[:, 0], kind="stable")
    for start in range(0, len(tris_a), block):
        part = order[start:start + block]
        cand = np.flatnonzero(((lo_b <= hi_a[part].max(axis=0)) & (hi_b >= lo_a[part].min(axis=0))).all(axis=1))
        opposite = (n_a[part] @ n_b[cand].T < _OPPOSITE_COS) & ok_a[part, None] & ok_b[None, cand]
        coplanar = np.abs(samples[part, -1] @ n_b[cand].T - offset_b[None, cand]) <= tol
        rows, cols = np.nonzero(opposite & coplanar)
        rows, cols = part[rows], cand[cols]
        near = ((lo_a[rows] <= hi_b[cols]) & (hi_a[rows] >= lo_b[cols])).all(axis=1)
        ia.append(rows[near])
        jb.append(cols[near])
    ia, jb = np.concatenate(ia or [np.zeros(0, np.int64)]), np.concatenate(jb or [np.zeros(0, np.int64)])
    if len(ia) == 0:
        return np.zeros(len(tris_a), bool)
    # Barycentric weights of every sample of face ia in face jb (the samples lie in its plane).
    origin, e0, e1 = tris_b[jb, 0], tris_b[jb, 1] - tris_b[jb, 0], tris_b[jb, 2] - tris_b[jb, 0]
    d00, d01, d11 = (np.einsum("pd,pd->p", u, v) for u, v in ((e0, e0), (e0, e1), (e1, e1)))
    den = d00 * d11 - d01 * d01
    rel = samples[ia] - origin[:, None, :]                      # (P, S, 3)
    d20, d21 = np.einsum("psd,pd->ps", rel, e0), np.einsum("psd,pd->ps", rel, e1)
    v = (d11[:, None] * d20 - d01[:, None] * d21) / den[:, None]
    w = (d00[:, None] * d21 - d01[:, None] * d20) / den[:, None]
    # Within tol of the face in length: a weight's slack is tol over the face's smallest
    # height, 2·area / longest edge = sqrt(den) / longest edge.
    slack = (tol * np.sqrt(np.maximum(np.maximum(d00, d11), np.einsum("pd,pd->p", e1 - e0, e1 - e0)))
             / np.sqrt(den))[:, None]
    inside = (v >= -slack) & (w >= -slack) & (v + w <= 1.0 + slack)  # (P, S)
    sample_covered = np.zeros((len(tris_a), len(_SAMPLE_WEIGHTS)), bool)
    np.logical_or.at(sample_covered, ia, inside)
    return sample_covered.all(axis=1)
