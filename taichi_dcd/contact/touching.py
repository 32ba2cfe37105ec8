"""Contacts the narrow phase leaves without a constraint: touching pairs (one triangle only in
the other's plane) and soft patches pressed through a face, and the next vertex over a face
when a pair's deepest point is already another pair's row."""

import taichi as ti

from ..collision.narrowphase import pressed_through, touching_planes
from ..core import runtime
from ..core.geometry import barycentric
from ..core.model import STATIC
from .anchors import involves_soft
from .cloth import pair_vertices
from .rows import is_duplicate

vec3 = ti.math.vec3


@ti.func
def deepest_vertex_behind(p0: vec3, p1: vec3, p2: vec3, q0: vec3, q1: vec3, q2: vec3, n_q: vec3, floor: float,
                          reach: float, tol: float):
    """(depth, vertex) of P's deepest vertex behind Q's plane by more than `floor` and at
    most `reach`, that projects into Q (edges included); depth 0 if none."""
    depth = 0.0
    point = vec3(0.0)
    for p in ti.static([p0, p1, p2]):
        d = n_q.dot(q0 - p)
        if d > floor and d <= reach and d > depth:
            if barycentric(p + d * n_q, q0, q1, q2).min() >= -tol:
                depth, point = d, p
    return depth, point


@ti.func
def touching_pair_contact(sim: ti.template(), t_a: ti.i32, t_b: ti.i32):
    """A contact the narrow phase reports as touching: one triangle crosses the other's
    plane while the other only touches its plane (a vertex or an edge in it,
    supplement Fig. 8). Alone, such a pair has no depth; between bodies it can hide a
    real one: a box set down exactly on a block of the same footprint has its side
    faces in the block's side planes, so every pair it forms with the block touches,
    and the box would sink through unopposed. Returns (found, moved triangle, other
    triangle, depth, normal, point): the crossing triangle's deepest vertex behind the
    touching one, by more than tol·L and at most half the touching body's thickness,
    projecting into it (edges included); add_vertex_contacts adds its other vertices.
    With a soft body, failing that, a pair pressed through each other (a soft patch
    sagged wholly behind a face, narrowphase.pressed_through) gives the same contact
    for the triangle behind the other's plane."""
    a0, a1, a2, b0, b1, b2 = pair_vertices(sim, t_a, t_b)
    tol = ti.static(runtime.tolerance())
    t_m, t_o = t_a, t_b
    depth = 0.0
    normal = vec3(0.0)
    point = vec3(0.0)
    static_a = sim.model.body_kind[sim.model.tri_body[t_a]] == STATIC
    static_b = sim.model.body_kind[sim.model.tri_body[t_b]] == STATIC
    which, n_a, n_b, floor = touching_planes(a0, a1, a2, b0, b1, b2)
    # The crossing triangle moves: a static one would push the other body from its
    # own side, a second copy of the same contact.
    which = ti.select((which == 0 and static_a) or (which == 1 and static_b), -1, which)
    if ti.static(not sim.rules.touching_pairs):
        which = -1
    if ti.static(sim.rules.pressed_through and sim.model.has_soft):
        # Not within one body: two walls of a closed body facing each other across its inside
        # are each wholly behind the other's plane by construction.
        if which < 0 and involves_soft(sim, t_a, t_b) and sim.model.tri_body[t_a] != sim.model.tri_body[t_b]:
            # A soft patch sagged through a face: the triangle behind the other's plane moves.
            a_behind, b_behind, n_a, n_b, floor = pressed_through(a0, a1, a2, b0, b1, b2)
            which = ti.select(a_behind and not static_a, 0, ti.select(b_behind and not static_b, 1, -1))
    if which == 0:
        depth, point = deepest_vertex_behind(a0, a1, a2, b0, b1, b2, n_b, floor,
                                             0.5 * sim.body_thickness[sim.model.tri_body[t_b]], tol)
        normal = n_b
    elif which == 1:
        depth, point = deepest_vertex_behind(b0, b1, b2, a0, a1, a2, n_a, floor,
                                             0.5 * sim.body_thickness[sim.model.tri_body[t_a]], tol)
        normal = n_a
        t_m, t_o = t_b, t_a
    found = depth > 0.0
    return found, t_m, t_o, depth, normal, point


@ti.func
def next_vertex_over_face(sim: ti.template(), rows: ti.template(), n: ti.i32, t_moved: ti.i32, t_other: ti.i32,
                          normal: vec3, max_depth: float):
    """The deepest vertex of t_moved behind t_other's plane (unit normal `normal`) by
    0 < d ≤ max_depth·(1 + tol), projecting onto t_other (edges included) and not yet a
    row of rows [0, n). Returns (d, vertex); d = 0 if there is none."""
    tol = ti.static(runtime.tolerance())
    im, io = sim.model.tri_indices[t_moved], sim.model.tri_indices[t_other]
    o0, o1, o2 = sim.state.vertex_x[io[0]], sim.state.vertex_x[io[1]], sim.state.vertex_x[io[2]]
    best = 0.0
    vertex = vec3(0.0)
    for k in ti.static(range(3)):
        v = sim.state.vertex_x[im[k]]
        d = normal.dot(o0 - v)
        if d > best and d <= max_depth * (1.0 + tol):
            if barycentric(v + d * normal, o0, o1, o2).min() >= -tol and not is_duplicate(sim, rows, n, t_moved,
                                                                                          t_other, normal, v):
                best, vertex = d, v
    return best, vertex
