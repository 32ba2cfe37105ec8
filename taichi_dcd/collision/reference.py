"""A plain per-pair NumPy implementation of the unified triangle-pair DCD method.

It is the slow, obvious reference the Taichi kernels are checked against: every
step is written out in 3-D as the paper states it (explicit projections onto the
other plane, line-plane intersections for Eq. 5, segment intersections of the
projected edges), with the same documented decisions as `narrowphase` (zero-area
triangles, snapping of near-zero distances, parallel planes, ties). It is not
used by the simulator.
"""

from __future__ import annotations

import numpy as np

from ..core.runtime import TOL_ULPS


def _longest_edge(t: np.ndarray) -> float:
    return max(np.linalg.norm(t[1] - t[0]), np.linalg.norm(t[2] - t[1]), np.linalg.norm(t[0] - t[2]))


def _plane(t: np.ndarray, tol: float):
    """Unit normal and offset d with s(p) = N·p + d, or None for a zero-area triangle."""
    n = np.cross(t[1] - t[0], t[2] - t[0])
    area2 = np.linalg.norm(n)
    if area2 == 0.0 or area2 <= tol * _longest_edge(t) ** 2:
        return None
    n = n / area2
    return n, -np.dot(n, t[0])


def _interval(t: np.ndarray, s: np.ndarray, line: np.ndarray):
    """Parameters along `line` of the segment where triangle t crosses the other plane."""
    params = []
    for i in range(3):
        j = (i + 1) % 3
        if s[i] == 0.0:
            params.append(np.dot(line, t[i]))
        if (s[i] < 0.0 < s[j]) or (s[j] < 0.0 < s[i]):
            x = t[i] + (t[j] - t[i]) * (s[i] / (s[i] - s[j]))
            params.append(np.dot(line, x))
    return min(params), max(params)


def _inside(t: np.ndarray, p: np.ndarray) -> bool:
    """Whether p, a point of t's plane, lies strictly inside t (the listing's test)."""
    c1 = np.cross(t[1] - t[0], p - t[1])
    c2 = np.cross(t[2] - t[1], p - t[2])
    c3 = np.cross(t[0] - t[2], p - t[0])
    return np.dot(c1, c2) > 0.0 and np.dot(c1, c3) > 0.0


def _depth_of(p_tri, s_p, n_p, d_p, q_tri, s_q, n_q, d_q, tol, margin):
    """(depth, point): deepest candidate of triangle P below Q's plane, floor 0. The
    three kinds of candidate (P's vertices, Q's vertices moved onto P, edge crossings)
    are ranked in that order when their depths are within `margin`."""
    best = [[0.0, np.zeros(3)] for _ in range(3)]
    kind = 0

    def consider(x):
        depth = -(np.dot(n_q, x) + d_q)
        if depth > best[kind][0]:
            best[kind] = [depth, x]

    projected = [p_tri[i] - s_p[i] * n_q for i in range(3)]  # Eq. 4
    for i in range(3):
        if _inside(q_tri, projected[i]):
            consider(p_tri[i])
    kind = 1
    cos_pq = np.dot(n_p, n_q)
    if abs(cos_pq) > tol:  # Eq. 5: from Q's vertices along N_Q onto P's plane
        for j in range(3):
            t = -(np.dot(n_p, q_tri[j]) + d_p) / cos_pq
            x = q_tri[j] + t * n_q
            if _inside(p_tri, x):
                consider(x)
    kind = 2
    for i in range(3):  # projected edges of P against Q's edges
        e1 = projected[(i + 1) % 3] - projected[i]
        for j in range(3):
            e2 = q_tri[(j + 1) % 3] - q_tri[j]
            n = np.cross(e1, e2)
            n_len = np.linalg.norm(n)
            if n_len <= tol * np.linalg.norm(e1) * np.linalg.norm(e2):
                continue
            v = q_tri[j] - projected[i]
            u = np.dot(np.cross(v, e2), n) / n_len**2
            w = np.dot(np.cross(v, e1), n) / n_len**2
            if 0.0 <= u <= 1.0 and 0.0 <= w <= 1.0:
                consider(p_tri[i] + u * (p_tri[(i + 1) % 3] - p_tri[i]))
    depth, point = best[0]
    for later_depth, later_point in best[1:]:
        if later_depth > depth + margin:
            depth, point = later_depth, later_point
    return depth, point


def _lex_key(t: np.ndarray, n: np.ndarray):
    return tuple(t.sum(axis=0)) + tuple(n)


def collide_pair_reference(a, b, eps: float = float(np.finfo(np.float64).eps)) -> dict:
    """The method on one pair a, b of shape (3, 3), in float64 with the tolerances of
    a kernel whose machine epsilon is `eps`. Returns a dict with hit, depth,
    normal, side and point as `collide_triangle_pairs` defines them."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    tol = TOL_ULPS * eps
    out = dict(hit=False, depth=0.0, normal=np.zeros(3), side=-1, point=np.zeros(3))
    plane_a, plane_b = _plane(a, tol), _plane(b, tol)
    if plane_a is None or plane_b is None:
        return out
    (n_a, d_a), (n_b, d_b) = plane_a, plane_b
    length = max(_longest_edge(a), _longest_edge(b))
    s_a = np.array([np.dot(n_b, x) + d_b for x in a])
    s_b = np.array([np.dot(n_a, x) + d_a for x in b])
    s_a[np.abs(s_a) <= tol * length] = 0.0
    s_b[np.abs(s_b) <= tol * length] = 0.0
    if s_a.min() >= 0.0 or s_a.max() <= 0.0 or s_b.min() >= 0.0 or s_b.max() <= 0.0:
        return out
    line = np.cross(n_a, n_b)
    if np.linalg.norm(line) <= tol:
        return out
    ta = _interval(a, s_a, line)
    tb = _interval(b, s_b, line)
    if not (ta[1] >= tb[0] and tb[1] >= ta[0]):
        return out
    out["hit"] = True
    margin = tol * length
    depth_a, point_a = _depth_of(a, s_a, n_a, d_a, b, s_b, n_b, d_b, tol, margin)
    depth_b, point_b = _depth_of(b, s_b, n_b, d_b, a, s_a, n_a, d_a, tol, margin)
    if min(depth_a, depth_b) <= margin:
        return out
    if abs(depth_a - depth_b) > margin:
        move_a = depth_a < depth_b
    else:
        move_a = _lex_key(a, n_a) <= _lex_key(b, n_b)
    if move_a:
        out.update(depth=depth_a, normal=n_b, side=0, point=point_a)
    else:
        out.update(depth=depth_b, normal=n_a, side=1, point=point_b)
    return out


def collide_triangle_pairs_reference(a, b, eps: float = float(np.finfo(np.float64).eps)) -> dict:
    """`collide_pair_reference` over arrays a, b of shape (n, 3, 3); returns a dict of arrays."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    rows = [collide_pair_reference(a[i], b[i], eps) for i in range(len(a))]
    n = len(rows)
    return dict(
        hit=np.array([r["hit"] for r in rows], dtype=bool).reshape(n),
        depth=np.array([r["depth"] for r in rows], dtype=np.float64).reshape(n),
        normal=np.array([r["normal"] for r in rows], dtype=np.float64).reshape(n, 3),
        side=np.array([r["side"] for r in rows], dtype=np.int8).reshape(n),
        point=np.array([r["point"] for r in rows], dtype=np.float64).reshape(n, 3),
    )
