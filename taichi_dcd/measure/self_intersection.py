"""Triangles of one mesh that cross each other, found with NumPy alone (independently of the
solver's narrow phase): a mesh's self-intersections.

Candidates come from a uniform grid over the triangles' bounding boxes; two triangles that
share a vertex are never candidates (they meet by construction). A pair crosses when an edge
of one passes through the other's interior: the edge's ends lie strictly on opposite sides of
the other's plane, and the edge's line passes strictly inside its three edges (three signed
volumes of one sign), each volume beyond rounding. Triangles that only touch (a vertex or an
edge in the other's plane) or that are coplanar do not count: what is counted is a crossing a
solid cannot have.
"""

from __future__ import annotations

import numpy as np

# Grid cell: this quantile of the triangles' largest box extents; a triangle whose box spans
# more than BIG_SPAN cells along an axis is tested against every box instead of binned.
CELL_QUANTILE = 0.9
BIG_SPAN = 4
# A signed volume smaller than this times the cube of the pair's box diagonal counts as zero:
# rounding makes coplanar neighbours (a subdivided face, rotated) look as if they crossed.
VOLUME_TOLERANCE = 1e-12
PAIR_CHUNK = 200_000  # candidate pairs tested at once (memory: ~100 doubles each)


def _box_pairs(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(k, 2) index pairs i < j of boxes (n, 3) that overlap (closed intervals), each once."""
    n = len(lo)
    if n < 2:
        return np.zeros((0, 2), np.int64)
    extent = (hi - lo).max(axis=1)
    cell = float(np.quantile(extent, CELL_QUANTILE))
    if not cell > 0.0:
        cell = float(extent.max()) or 1.0
    origin = lo.min(axis=0)
    ilo = np.floor((lo - origin) / cell).astype(np.int64)
    span = np.floor((hi - origin) / cell).astype(np.int64) - ilo + 1
    big = span.max(axis=1) > BIG_SPAN
    small = np.flatnonzero(~big)
    tri, cells = [], []
    for offset in np.ndindex(*span[small].max(axis=0, initial=1)):
        o = np.array(offset)
        keep = small[(o < span[small]).all(axis=1)]
        tri.append(keep)
        cells.append(ilo[keep] + o)
    tri = np.concatenate(tri)
    cells = np.concatenate(cells)
    pairs = [np.zeros((0, 2), np.int64)]
    if len(tri):
        dims = cells.max(axis=0) + 1
        if float(np.prod(dims.astype(np.float64))) < 2.0 ** 62:
            key = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
        else:  # a grid too fine for one integer key (a huge mesh with a few tiny triangles)
            key = np.unique(cells, axis=0, return_inverse=True)[1].ravel()
        order = np.argsort(key)
        tri, key = tri[order], key[order]
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        ends = np.r_[starts[1:], len(key)]
        end_of = np.repeat(ends, ends - starts)
        after = end_of - np.arange(len(key)) - 1      # later entries in the same cell
        first = np.repeat(np.arange(len(key)), after)
        second = first + 1 + (np.arange(len(first)) - np.repeat(np.cumsum(after) - after, after))
        pairs.append(np.stack([tri[first], tri[second]], axis=1))
    for b in np.flatnonzero(big):
        meets = np.flatnonzero((lo <= hi[b]).all(axis=1) & (hi >= lo[b]).all(axis=1))
        meets = meets[meets != b]
        pairs.append(np.stack([np.full(len(meets), b), meets], axis=1))
    pairs = np.sort(np.concatenate(pairs), axis=1)
    code = np.sort(pairs[:, 0] * n + pairs[:, 1])
    code = code[np.r_[True, code[1:] != code[:-1]]]
    pairs = np.stack([code // n, code % n], axis=1)
    i, j = pairs[:, 0], pairs[:, 1]
    overlap = (lo[i] <= hi[j]).all(axis=1) & (lo[j] <= hi[i]).all(axis=1)
    return pairs[overlap]


def _volume(a, b, c, d) -> np.ndarray:
    """Six times the signed volume of the tetrahedra (a, b, c, d), rows of (k, 3) arrays."""
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a)


def _edge_crosses(p, q, a, b, c, tol) -> np.ndarray:
    """(k,) True where segment pq passes through the interior of triangle abc, every signed
    volume deciding it larger than tol (k,) in magnitude."""
    sp, sq = _volume(a, b, c, p), _volume(a, b, c, q)
    straddles = ((sp > tol) & (sq < -tol)) | ((sp < -tol) & (sq > tol))
    u, v, w = _volume(p, q, a, b), _volume(p, q, b, c), _volume(p, q, c, a)
    inside = ((u > tol) & (v > tol) & (w > tol)) | ((u < -tol) & (v < -tol) & (w < -tol))
    return straddles & inside


def _clip(poly: np.ndarray, count: np.ndarray, normal: np.ndarray, point: np.ndarray):
    """Polygons poly (k, MAX_CORNERS, 3), their first count[k] corners valid, cut to the part where
    normal·(x − point) >= 0 (Sutherland-Hodgman); returns the new (poly, count)."""
    k = len(poly)
    out = np.zeros_like(poly)
    n_out = np.zeros(k, np.int64)
    rows = np.arange(k)
    side = np.einsum("ij,ikj->ik", normal, poly - point[:, None, :])
    for j in range(poly.shape[1]):
        valid = j < count
        nxt = np.where(j + 1 < count, j + 1, 0)
        sj, sn = side[:, j], side[rows, nxt]
        keep = valid & (sj >= 0.0)
        out[rows[keep], n_out[keep]] = poly[keep, j]
        n_out += keep
        cut = valid & ((sj >= 0.0) != (sn >= 0.0))
        t = sj[cut] / (sj[cut] - sn[cut])
        out[rows[cut], n_out[cut]] = poly[cut, j] + t[:, None] * (poly[rows[cut], nxt[cut]] - poly[cut, j])
        n_out += cut
    return out, n_out


MAX_CORNERS = 7  # a triangle cut by four planes has at most 3 + 4 corners


def _depth_behind(tri: np.ndarray, other: np.ndarray) -> np.ndarray:
    """(k,) how deep the deepest point of tri (k, 3, 3) lies behind other's plane within other's
    footprint: tri is cut to the prism over `other` along its normal and to the half-space
    behind it, and the deepest corner of what is left counts (0 if nothing is left)."""
    a, b, c = other[:, 0], other[:, 1], other[:, 2]
    n = np.cross(b - a, c - a)
    length = np.linalg.norm(n, axis=1)
    unit = n / np.where(length > 0.0, length, 1.0)[:, None]
    poly = np.zeros((len(tri), MAX_CORNERS, 3))
    poly[:, :3] = tri
    count = np.full(len(tri), 3, np.int64)
    for p, q in ((a, b), (b, c), (c, a)):
        poly, count = _clip(poly, count, np.cross(unit, q - p), p)
    poly, count = _clip(poly, count, -unit, a)
    behind = -np.einsum("ij,ikj->ik", unit, poly - a[:, None, :])
    behind = np.where(np.arange(MAX_CORNERS)[None, :] < count[:, None], behind, 0.0)
    return np.where(length > 0.0, np.maximum(behind.max(axis=1), 0.0), 0.0)


def crossing_depths(tri_a: np.ndarray, tri_b: np.ndarray) -> np.ndarray:
    """(k,) the depth of crossing triangle pairs tri_a[k], tri_b[k] ((k, 3, 3) m): of the two
    triangles, the smaller depth of the deepest point of one behind the other's plane within
    the other's footprint (_depth_behind), by polygon clipping: the least the crossing asks one
    of them to move. Coordinates are taken relative to tri_a's first corner, so that a mesh far
    from the origin loses no precision here."""
    origin = tri_a[:, :1, :]
    a, b = tri_a - origin, tri_b - origin
    return np.minimum(_depth_behind(a, b), _depth_behind(b, a))


def self_penetration(vertices: np.ndarray, faces: np.ndarray, depths=None) -> tuple[int, float]:
    """(number of crossing pairs, the deepest of them in m as `depths` (crossing_depths by
    default; a sheet's: cloth.poke_depths) has it) of one mesh (vertices (n, 3) m, faces
    (m, 3)): pairs that share no vertex, found without the solver."""
    pairs = crossing_pairs(vertices, faces)
    if not len(pairs):
        return 0, 0.0
    corners = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    return len(pairs), float((depths or crossing_depths)(corners[pairs[:, 0]], corners[pairs[:, 1]]).max())


def triangles_cross(tri_a: np.ndarray, tri_b: np.ndarray) -> np.ndarray:
    """(k,) True where triangle tri_a[k] and tri_b[k] (each (k, 3, 3), m) cross: an edge of one
    passes through the other's interior. Coordinates are taken relative to tri_a's first
    corner, so that a mesh far from the origin loses no precision here."""
    origin = tri_a[:, :1, :]
    a, b = tri_a - origin, tri_b - origin
    both = np.concatenate([a, b], axis=1)
    size = np.linalg.norm(both.max(axis=1) - both.min(axis=1), axis=1)
    tol = VOLUME_TOLERANCE * size ** 3
    hit = np.zeros(len(a), bool)
    for s, t in ((a, b), (b, a)):
        for e in range(3):
            p, q = s[:, e], s[:, (e + 1) % 3]
            hit |= _edge_crosses(p, q, t[:, 0], t[:, 1], t[:, 2], tol)
    return hit


def crossing_pairs(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(k, 2) face index pairs i < j of one mesh (vertices (n, 3) m, faces (m, 3)) that share no
    vertex and cross each other, sorted."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    corners = v[f]
    pairs = _box_pairs(corners.min(axis=1), corners.max(axis=1))
    if len(pairs):
        fi, fj = f[pairs[:, 0]], f[pairs[:, 1]]
        shared = (fi[:, :, None] == fj[:, None, :]).any(axis=(1, 2))
        pairs = pairs[~shared]
    found = []
    for start in range(0, len(pairs), PAIR_CHUNK):
        chunk = pairs[start:start + PAIR_CHUNK]
        found.append(chunk[triangles_cross(corners[chunk[:, 0]], corners[chunk[:, 1]])])
    return np.concatenate(found) if found else np.zeros((0, 2), np.int64)
