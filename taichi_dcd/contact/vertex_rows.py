"""Vertex rows: every candidate vertex of a moved triangle, not only the deepest one, becomes a
row against the other triangle's face."""

import taichi as ti

from ..core import runtime
from ..core.geometry import barycentric
from ..core.model import SOFT
from .anchors import anchor_world, involves_soft
from .cloth import facing_against
from .exits import beyond_convex_edge
from .rows import is_duplicate, write_contact

vec3 = ti.math.vec3

# Contact rows a triangle pair can need: its deepest point and up to three more vertices
# of the moved triangle, and with a soft body up to three of the other's.
VERTEX_ROWS_PER_PAIR = 4
VERTEX_ROWS_PER_PAIR_SOFT = 7


@ti.func
def vertex_over_face(sim: ti.template(), rows: ti.template(), total: ti.i32, t_moved: ti.i32, t_other: ti.i32,
                     v: vec3, normal: vec3, min_depth: float, max_depth: float, max_push: float) -> ti.i32:
    """Vertex v of t_moved as a contact against the face of t_other, plane normal `normal`:
    when it lies behind the plane by min_depth < d ≤ max_depth (negative: in front), projects
    onto the face (edges included) and is not already a row. Writes row `total` if it fits;
    returns the rows needed so far."""
    tol = ti.static(runtime.tolerance())
    io = sim.model.tri_indices[t_other]
    q0, q1, q2 = sim.state.vertex_x[io[0]], sim.state.vertex_x[io[1]], sim.state.vertex_x[io[2]]
    n_rows = total
    d = normal.dot(q0 - v)
    if d > min_depth and d <= max_depth:
        w = barycentric(v + d * normal, q0, q1, q2)
        if w.min() >= -tol and not is_duplicate(sim, rows, ti.min(n_rows, rows.tri.shape[0]), t_moved, t_other,
                                                normal, v):
            if n_rows < rows.tri.shape[0]:
                write_contact(sim, rows, n_rows, t_moved, t_other, d, normal, v, max_push)
            n_rows += 1
    return n_rows


@ti.func
def add_vertex_contacts(sim: ti.template(), rows: ti.template(), n: ti.i32, max_push: float) -> ti.i32:
    """Rule `vertex_rows`: after the n rows of the narrow phase, every other vertex of a moved
    triangle that is one of its candidate points too (behind the other triangle's plane along
    N, no deeper than the row's C, projecting inside the other triangle) becomes a row with
    its own depth. Prevents: Eq. 6 keeps only the deepest candidate, so a face resting on a
    face hangs on one corner per triangle pair and tilts into the support. Between rigid or
    static bodies, not a vertex beyond a convex edge of the other triangle (in front of a
    convex neighbour's plane: outside that body, contact.exits.beyond_convex_edge). Prevents:
    a wedge dropped turned 4.9° onto a standing wedge's ridge slid along it; the standing
    ridge's end vertex, 3.8 cm outside the dropped wedge beyond its ridge but 0.13 m behind
    its far face, got a row along that face's normal, and the pushes drove the dropped wedge
    sideways through the standing one, 4.5 cm deep (benchmarks/variants.py --seed 7, wedges
    v0).

    Rule `soft_feature_rows`: when the moved triangle is soft, the other triangle's vertices
    behind it (within half the soft body's thickness) get rows too. Prevents: a membrane
    pushed along a sharp feature's face normal slides off the feature sideways while the
    feature's tip stays inside it. Rows go after row n-1 while they fit; returns the rows
    needed."""
    total = n
    tol = ti.static(runtime.tolerance())
    for j in range(n):
        tri = rows.tri[j]
        normal = rows.normal[j]
        p_m = anchor_world(sim, tri[0], rows.bary_moved[j], False)
        p_o = anchor_world(sim, tri[1], rows.bary_other[j], False)
        depth_main = normal.dot(p_o - p_m)
        im, io = sim.model.tri_indices[tri[0]], sim.model.tri_indices[tri[1]]
        if ti.static(sim.rules.vertex_rows):
            rigid_pair = not involves_soft(sim, tri[0], tri[1])
            for k in ti.static(range(3)):
                v = sim.state.vertex_x[im[k]]
                take = True
                if rigid_pair:
                    take = not beyond_convex_edge(sim, tri[1], v)
                if take:
                    total = vertex_over_face(sim, rows, total, tri[0], tri[1], v, normal, 0.0,
                                             depth_main * (1.0 + tol), max_push)
        # A soft triangle moved along a sharp feature's face normal can slide off the
        # feature sideways while the feature's vertex stays inside it: the membrane
        # wraps a spike's apex. The other triangle's vertices behind the soft one's
        # plane (over its face, within half its body's thickness) push it out too.
        b_m = sim.model.tri_body[tri[0]]
        if ti.static(sim.rules.soft_feature_rows and sim.model.has_soft):
            if sim.model.body_kind[b_m] == SOFT:
                m0, m1, m2 = sim.state.vertex_x[im[0]], sim.state.vertex_x[im[1]], sim.state.vertex_x[im[2]]
                cross_m = (m1 - m0).cross(m2 - m0)
                if cross_m.norm() > 0.0:
                    n_m = facing_against(sim, tri[0], cross_m.normalized(), normal)
                    for k in ti.static(range(3)):
                        total = vertex_over_face(sim, rows, total, tri[1], tri[0], sim.state.vertex_x[io[k]], n_m, 0.0,
                                                 0.5 * sim.body_thickness[b_m], max_push)
    return total
