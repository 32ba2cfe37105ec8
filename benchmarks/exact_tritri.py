"""Exact triangle–triangle classification in rational arithmetic, to judge disagreements.

Float coordinates convert to Fractions exactly, so the orientation signs below are
the true signs for the given floats: no rounding, no tolerance. Slow (~1 ms a pair);
meant for the few hundred pairs where two implementations disagree.
"""

from fractions import Fraction

import numpy as np


def _orient(a, b, c, d) -> int:
    """Sign of det[b-a, c-a, d-a]: which side of plane abc the point d lies on."""
    u = [b[k] - a[k] for k in range(3)]
    v = [c[k] - a[k] for k in range(3)]
    w = [d[k] - a[k] for k in range(3)]
    det = (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
           + u[2] * (v[0] * w[1] - v[1] * w[0]))
    return (det > 0) - (det < 0)


def _edge_meets_triangle(p, q, tri) -> str:
    """'cross' if segment pq passes through the triangle's interior with its ends strictly
    on both sides, 'touch' if they meet otherwise, 'apart' if not; 'coplanar' if pq
    lies in the triangle's plane."""
    a, b, c = tri
    op, oq = _orient(a, b, c, p), _orient(a, b, c, q)
    if op == 0 and oq == 0:
        return "coplanar"
    if op * oq > 0:
        return "apart"
    sides = [_orient(p, q, a, b), _orient(p, q, b, c), _orient(p, q, c, a)]
    if all(s >= 0 for s in sides) or all(s <= 0 for s in sides):
        strict = op * oq < 0 and (all(s > 0 for s in sides) or all(s < 0 for s in sides))
        return "cross" if strict else "touch"
    return "apart"


def classify(t1: np.ndarray, t2: np.ndarray) -> str:
    """Exact relation of two triangles (3, 3): 'cross' (an edge of one passes through the
    other's interior), 'touch' (they meet only at boundary points or with a vertex on
    the other's plane), 'apart', or 'coplanar' (an edge lies in the other's plane;
    not decided further)."""
    a = [[Fraction(float(x)) for x in v] for v in t1]
    b = [[Fraction(float(x)) for x in v] for v in t2]
    results = []
    for tri, other in ((a, b), (b, a)):
        for i in range(3):
            results.append(_edge_meets_triangle(tri[i], tri[(i + 1) % 3], other))
    for kind in ("cross", "touch", "coplanar"):
        if kind in results:
            return kind
    return "apart"
