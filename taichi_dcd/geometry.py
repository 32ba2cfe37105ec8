"""Pure Taichi functions on points and triangles (no fields, no side effects).

Vectors are `ti.math.vec3` in the kernels' float type; a triangle is three
vertices whose order gives its outward normal by the right-hand rule.
"""

import taichi as ti

vec2 = ti.math.vec2
vec3 = ti.math.vec3


@ti.func
def longest_edge_sq(p0: vec3, p1: vec3, p2: vec3) -> float:
    """Squared length of the longest edge of triangle (p0, p1, p2)."""
    return ti.max((p1 - p0).norm_sqr(), (p2 - p1).norm_sqr(), (p0 - p2).norm_sqr())


@ti.func
def has_area(n_raw: vec3, edge_sq: float, tol: float) -> bool:
    """Whether a triangle with raw normal n_raw = (p1-p0)×(p2-p0) and longest squared
    edge edge_sq has a reliable plane: doubled area > tol·(longest edge)²."""
    return n_raw.norm_sqr() > tol * tol * edge_sq * edge_sq


@ti.func
def snap_to_zero(s: vec3, tol_sq: float) -> vec3:
    """Entries whose square is at most tol_sq become exactly zero (touching)."""
    out = s
    for k in ti.static(range(3)):
        if s[k] * s[k] <= tol_sq:
            out[k] = 0.0
    return out


@ti.func
def straddles(s: vec3) -> bool:
    """Whether signed distances s have both signs (Möller's rejection, threshold 0)."""
    return s.min() < 0.0 and s.max() > 0.0


@ti.func
def cross2(u: vec2, v: vec2) -> float:
    """z-component of the 2-D cross product u × v."""
    return u.x * v.y - u.y * v.x


@ti.func
def plane_frame(q0: vec3, q1: vec3, n: vec3):
    """Orthonormal in-plane axes (t1, t2) of a triangle with unit normal n, t1 × t2 = n.

    Coordinates (t1·x, t2·x) are the image of x projected along n onto the plane,
    with the triangle's own winding counter-clockwise.
    """
    t1 = (q1 - q0).normalized()
    return t1, n.cross(t1)


@ti.func
def to_frame(x: vec3, t1: vec3, t2: vec3) -> vec2:
    """2-D coordinates of x in the frame (t1, t2)."""
    return vec2(t1.dot(x), t2.dot(x))


@ti.func
def strictly_inside_2d(p0: vec2, p1: vec2, p2: vec2, x: vec2) -> bool:
    """Whether x lies strictly inside the 2-D triangle (p0, p1, p2) of either winding."""
    c0 = cross2(p1 - p0, x - p0)
    c1 = cross2(p2 - p1, x - p1)
    c2 = cross2(p0 - p2, x - p2)
    return ((c0 > 0.0) & (c1 > 0.0) & (c2 > 0.0)) | ((c0 < 0.0) & (c1 < 0.0) & (c2 < 0.0))


@ti.func
def lex_compare(u: vec3, v: vec3) -> int:
    """-1, 0 or 1 as u is lexicographically smaller than, equal to or larger than v."""
    result = 0
    for k in ti.static(range(3)):
        if result == 0:
            if u[k] < v[k]:
                result = -1
            elif u[k] > v[k]:
                result = 1
    return result


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
