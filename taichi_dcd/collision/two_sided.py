"""Which way a two-sided (cloth) triangle faces in one pair.

The unified test measures each triangle's depth behind the other's plane, so it needs each
triangle's outward side. A closed body's faces have one; a cloth's have none: the sheet has
no inside, and its winding says nothing about which side another body comes from. So for
each pair, a cloth triangle is turned (two of its vertices swapped) to face the other one:

- against a one-sided face (rigid, static or a closed soft body's), the cloth triangle faces
  into that face's outward normal, n_cloth · n_other ≤ 0, as two closed bodies' faces at a
  contact do. It reads the current pose only, and does not depend on where the two triangles'
  centres happen to lie, which on a large flat face says little.
- against another cloth triangle (another cloth, or its own sheet folded), each faces the
  other's centroid as they were at the start of the substep, before the prediction that may
  have carried one through the other.

The sheet then resists being crossed from either side, and a fold meeting itself is two
sides of the sheet meeting from outside (docs/method.md, 'Cloth').
"""

import taichi as ti

vec3 = ti.math.vec3


@ti.func
def two_sided_flips(a0: vec3, a1: vec3, a2: vec3, b0: vec3, b1: vec3, b2: vec3,
                    pa0: vec3, pa1: vec3, pa2: vec3, pb0: vec3, pb1: vec3, pb2: vec3,
                    a_two_sided: bool, b_two_sided: bool):
    """(flip A, flip B): whether to swap a triangle's last two vertices so that it faces the
    other triangle of the pair. a*, b*: the vertices now; pa*, pb*: at the substep's start
    (read only when both are two-sided). A one-sided triangle is never flipped."""
    flip_a = False
    flip_b = False
    if a_two_sided and b_two_sided:
        n_a = (pa1 - pa0).cross(pa2 - pa0)
        n_b = (pb1 - pb0).cross(pb2 - pb0)
        towards_b = (pb0 + pb1 + pb2 - pa0 - pa1 - pa2) / 3.0
        flip_a = n_a.dot(towards_b) < 0.0
        flip_b = n_b.dot(towards_b) > 0.0
    elif a_two_sided or b_two_sided:
        n_a = (a1 - a0).cross(a2 - a0)
        n_b = (b1 - b0).cross(b2 - b0)
        facing_away = n_a.dot(n_b) > 0.0
        flip_a = a_two_sided and facing_away
        flip_b = b_two_sided and facing_away
    return flip_a, flip_b


@ti.func
def flipped(p0: vec3, p1: vec3, p2: vec3, flip: bool):
    """The triangle's vertices, the last two swapped when `flip` (its normal reversed)."""
    q1 = ti.select(flip, p2, p1)
    q2 = ti.select(flip, p1, p2)
    return p0, q1, q2


@ti.func
def moved_together(a0: vec3, a1: vec3, a2: vec3, b0: vec3, b1: vec3, b2: vec3, gap: float):
    """Two triangles facing each other, each moved gap/2 along its own unit normal (towards
    the other): they cross when the real ones are closer than the gap."""
    n_a = (a1 - a0).cross(a2 - a0)
    n_b = (b1 - b0).cross(b2 - b0)
    len_a, len_b = n_a.norm(), n_b.norm()
    # A triangle crushed to zero area has no normal to move along: it stays.
    shift_a = ti.select(len_a > 0.0, 0.5 * gap / ti.select(len_a > 0.0, len_a, 1.0), 0.0) * n_a
    shift_b = ti.select(len_b > 0.0, 0.5 * gap / ti.select(len_b > 0.0, len_b, 1.0), 0.0) * n_b
    return a0 + shift_a, a1 + shift_a, a2 + shift_a, b0 + shift_b, b1 + shift_b, b2 + shift_b


@ti.func
def faced_pair(a0: vec3, a1: vec3, a2: vec3, b0: vec3, b1: vec3, b2: vec3,
               pa0: vec3, pa1: vec3, pa2: vec3, pb0: vec3, pb1: vec3, pb2: vec3,
               a_two_sided: bool, b_two_sided: bool, gap: float):
    """The pair's vertices as the narrow phase takes them: a two-sided triangle turned to face
    the other (two_sided_flips, flipped), two two-sided ones then moved together by `gap` (m,
    moved_together). Arguments as for two_sided_flips."""
    flip_a, flip_b = two_sided_flips(a0, a1, a2, b0, b1, b2, pa0, pa1, pa2, pb0, pb1, pb2, a_two_sided, b_two_sided)
    a0, a1, a2 = flipped(a0, a1, a2, flip_a)
    b0, b1, b2 = flipped(b0, b1, b2, flip_b)
    if a_two_sided and b_two_sided:
        a0, a1, a2, b0, b1, b2 = moved_together(a0, a1, a2, b0, b1, b2, gap)
    return a0, a1, a2, b0, b1, b2
