"""Pure Taichi functions on points and triangles (no fields, no side effects), and a mesh's
vertex neighbours for the self-collision pairs' exclusion.

Points are `ti.math.vec3` in the kernels' float type or, for the functions the narrow
phase shares with its SIMD batches, anything indexable by component (see `lanes`); a
triangle is three vertices whose order gives its outward normal by the right-hand rule.
"""

import numpy as np
import taichi as ti

from .lanes import cross, cross2, dot, make2, make3, max3, min3, norm_sqr, scale, sub, sub2

vec2 = ti.math.vec2
vec3 = ti.math.vec3


@ti.func
def longest_edge_sq(p0, p1, p2):
    """Squared length of the longest edge of triangle (p0, p1, p2)."""
    return ti.max(norm_sqr(sub(p1, p0)), norm_sqr(sub(p2, p1)), norm_sqr(sub(p0, p2)))


@ti.func
def has_area(n_raw, edge_sq, tol: float):
    """Whether a triangle with raw normal n_raw = (p1-p0)×(p2-p0) and longest squared
    edge edge_sq has a reliable plane: doubled area > tol·(longest edge)²."""
    return norm_sqr(n_raw) > tol * tol * edge_sq * edge_sq


@ti.func
def snap_to_zero(s, tol_sq):
    """Entries whose square is at most tol_sq become exactly zero (touching)."""
    return make3(ti.select(s.x * s.x <= tol_sq, 0.0, s.x), ti.select(s.y * s.y <= tol_sq, 0.0, s.y),
                 ti.select(s.z * s.z <= tol_sq, 0.0, s.z))


@ti.func
def straddles(s):
    """Whether signed distances s have both signs (Möller's rejection, threshold 0)."""
    return (min3(s) < 0.0) & (max3(s) > 0.0)


@ti.func
def plane_frame(q0, q1, n):
    """Orthonormal in-plane axes (t1, t2) of a triangle with unit normal n, t1 × t2 = n.

    Coordinates (t1·x, t2·x) are the image of x projected along n onto the plane,
    with the triangle's own winding counter-clockwise.
    """
    edge = sub(q1, q0)
    t1 = scale(edge, 1.0 / ti.sqrt(norm_sqr(edge)))
    return t1, cross(n, t1)


@ti.func
def to_frame(x, t1, t2):
    """2-D coordinates of x in the frame (t1, t2)."""
    return make2(dot(t1, x), dot(t2, x))


@ti.func
def strictly_inside_2d(p0, p1, p2, x):
    """Whether x lies strictly inside the 2-D triangle (p0, p1, p2) of either winding."""
    c0 = cross2(sub2(p1, p0), sub2(x, p0))
    c1 = cross2(sub2(p2, p1), sub2(x, p1))
    c2 = cross2(sub2(p0, p2), sub2(x, p2))
    return ((c0 > 0.0) & (c1 > 0.0) & (c2 > 0.0)) | ((c0 < 0.0) & (c1 < 0.0) & (c2 < 0.0))


@ti.func
def lex_compare(u, v):
    """-1, 0 or 1 as u is lexicographically smaller than, equal to or larger than v."""
    result = ti.select(u.z < v.z, -1, ti.select(u.z > v.z, 1, 0))
    result = ti.select(u.y < v.y, -1, ti.select(u.y > v.y, 1, result))
    return ti.select(u.x < v.x, -1, ti.select(u.x > v.x, 1, result))


@ti.func
def closest_on_segments(p0: vec3, p1: vec3, q0: vec3, q1: vec3):
    """The closest points (on p0-p1, on q0-q1) of two segments: minimise |p(s) - q(t)|² over
    s, t in [0, 1], p(s) = p0 + s·(p1 - p0), q(t) = q0 + t·(q1 - q0); for parallel segments
    s = 0 and t its best. Either segment may be a point."""
    d_p = p1 - p0
    d_q = q1 - q0
    r = p0 - q0
    a = d_p.dot(d_p)
    e = d_q.dot(d_q)
    b = d_p.dot(d_q)
    c = d_p.dot(r)
    f = d_q.dot(r)
    s = 0.0
    t = 0.0
    if a <= 0.0 and e > 0.0:
        t = ti.math.clamp(f / e, 0.0, 1.0)
    elif a > 0.0 and e <= 0.0:
        s = ti.math.clamp(-c / a, 0.0, 1.0)
    elif a > 0.0:
        den = a * e - b * b
        if den > 0.0:
            s = ti.math.clamp((b * f - c * e) / den, 0.0, 1.0)
        t = (b * s + f) / e
        # t outside [0, 1]: clamp it and take s best for the clamped t.
        if t < 0.0:
            t = 0.0
            s = ti.math.clamp(-c / a, 0.0, 1.0)
        elif t > 1.0:
            t = 1.0
            s = ti.math.clamp((b - c) / a, 0.0, 1.0)
    return p0 + s * d_p, q0 + t * d_q


@ti.func
def barycentric(p: vec3, a: vec3, b: vec3, c: vec3) -> vec3:
    """Barycentric weights (u, v, w) of p's projection onto the plane of triangle
    (a, b, c), u·a + v·b + w·c; (1/3, 1/3, 1/3) for a zero-area triangle."""
    e0 = b - a
    e1 = c - a
    d = p - a
    d00 = e0.dot(e0)
    d01 = e0.dot(e1)
    d11 = e1.dot(e1)
    d20 = d.dot(e0)
    d21 = d.dot(e1)
    den = d00 * d11 - d01 * d01
    out = vec3(1.0 / 3.0)
    if den > 0.0:
        v = (d11 * d20 - d01 * d21) / den
        w = (d00 * d21 - d01 * d20) / den
        out = vec3(1.0 - v - w, v, w)
    return out


@ti.func
def shares_vertex(a, b) -> bool:
    """Whether two triangles of one mesh, given as vertex indices a and b (ivec3), share a
    vertex: such neighbours meet by construction and are never a self-contact."""
    shared = False
    for i in ti.static(range(3)):
        for j in ti.static(range(3)):
            shared = shared or a[i] == b[j]
    return shared


@ti.func
def near_in_mesh(a, b, nbr_range: ti.template(), nbr: ti.template()) -> bool:
    """Whether two triangles of one mesh, given as vertex indices a and b (ivec3), are near
    neighbours: they share a vertex, or an edge of the mesh joins a vertex of one to a vertex
    of the other (nbr_range[v]: [first, end) of vertex v's neighbours in nbr;
    vertex_neighbours). Such triangles lie within two edges of each other on the surface and
    cross only where the mesh folds back within about an edge length, tighter than it can
    resolve, so they are never a self-contact: kept as pairs, a curved sheet's neighbours
    moved together by its gap "touch" (all 8,347 self-contacts of a falling 9,800-triangle
    cloth were such pairs)."""
    near = shares_vertex(a, b)
    if not near:
        for i in ti.static(range(3)):
            r = nbr_range[a[i]]
            for k in range(r[0], r[1]):
                v = nbr[k]
                near = near or v == b[0] or v == b[1] or v == b[2]
    return near


def vertex_neighbours(tri_indices: np.ndarray, n_vertices: int, tri_mask: np.ndarray | None = None):
    """Each vertex's neighbours along the edges of the triangles tri_indices (T, 3) (those
    with tri_mask (T,) True, if given): (nbr_range (n_vertices, 2) int32, each vertex's
    [first, end) in nbr; nbr (K,) int32, K ≤ 6T, at least one entry), for near_in_mesh."""
    tris = np.asarray(tri_indices, dtype=np.int64).reshape(-1, 3)
    if tri_mask is not None:
        tris = tris[np.asarray(tri_mask, dtype=bool)]
    ends = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    ends = np.unique(np.concatenate([ends, ends[:, ::-1]]), axis=0)  # by vertex, then neighbour
    counts = np.bincount(ends[:, 0], minlength=n_vertices)[:n_vertices]
    first = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    nbr_range = np.stack([first, first + counts], axis=1).astype(np.int32).reshape(n_vertices, 2)
    nbr = ends[:, 1].astype(np.int32)
    return nbr_range, nbr if len(nbr) else np.zeros(1, np.int32)
