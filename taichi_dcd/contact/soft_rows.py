"""Resting rows of soft bodies: soft vertices just in front of a rigid or static face, and sharp
convex edges under a soft triangle."""

import taichi as ti

from ..core.model import SOFT, body_vertex_box
from .cloth import is_cloth
from .rows import is_duplicate, write_contact
from .vertex_rows import vertex_over_face

vec3 = ti.math.vec3

# A soft triangle's box is inflated by this fraction of its body's thickness: a patch
# sagged wholly behind a flat face has a box that no longer meets the face's (flat) box,
# and would drop out of the broad phase before pressed_through could see it. The contacts
# keep a sag to about one substep's motion, far below this; 5% (5 cm on the soft ball)
# doubled the soft ball's stepping time in candidate pairs.
SOFT_BOX_MARGIN = 0.01

# Resting rows the grid path makes room for per soft vertex (add_resting_contacts): a vertex
# against a face, an edge (two faces) or a corner (three); edge rows share the room.
RESTING_ROWS_PER_SOFT_VERTEX = 3


@ti.func
def add_resting_contacts(sim: ti.template(), rows: ti.template(), total: ti.i32, max_push: float) -> ti.i32:
    """The resting rows of soft bodies (rules `resting_rows` and `sharp_edge_rows`), after row
    total-1 while they fit; returns the rows needed."""
    n_rows = total
    if ti.static(sim.model.has_soft and (sim.rules.resting_rows or sim.rules.sharp_edge_rows)):
        solid_boxes(sim)
    if ti.static(sim.model.has_soft and sim.rules.resting_rows):
        n_rows = add_resting_vertex_rows(sim, rows, n_rows, max_push)
    if ti.static(sim.model.has_soft and sim.rules.sharp_edge_rows):
        n_rows = add_sharp_edge_rows(sim, rows, n_rows, max_push)
    return n_rows


@ti.func
def solid_boxes(sim: ti.template()):
    """Each rigid or static body's vertex box now (solid_lo, solid_hi): a soft vertex or
    triangle whose box, padded by the skin, misses it meets none of that body's faces or
    edges, and the rows below skip the body's triangles (a 9,800-triangle cloth spent 3.3 ms
    a substep testing each of its triangles against every face of a spike it was far from)."""
    for b in range(sim.model.body_count[0]):
        if sim.model.body_kind[b] != SOFT:
            lo, hi = body_vertex_box(sim.model, sim.state, b)
            sim.solid_lo[b] = lo
            sim.solid_hi[b] = hi


@ti.func
def add_resting_vertex_rows(sim: ti.template(), rows: ti.template(), total: ti.i32, max_push: float) -> ti.i32:
    """Rule `resting_rows`: rows for soft vertices resting on a face of a rigid or static body:
    in front of the face's plane by at most SOFT_BOX_MARGIN of the soft body's thickness,
    projecting onto the face, and not already a row. (Not behind it: beside a convex edge a
    vertex outside the body is behind the other face's plane.) Prevents: the unified test only
    sees pairs that cross, so a membrane held against a face by its volume constraint sits at
    depth 0 after its correction, gets no row in the next substep, is pressed in again, and
    chatters (a ball draped on a spike: 8 mm/s). With a row, C ≥ 0 holds it in every sweep; a
    row in front of the face does nothing until it is crossed. Returns the rows needed."""
    n_rows = total
    for i in range(sim.model.vertex_count[0]):
        b_s = sim.model.vertex_body[i]
        if sim.model.body_kind[b_s] == SOFT:
            v = sim.state.vertex_x[i]
            skin = ti.static(SOFT_BOX_MARGIN) * sim.body_thickness[b_s]
            t_m = sim.vertex_tri[i]
            for b in range(sim.model.body_count[0]):
                if (sim.model.body_kind[b] != SOFT and (v >= sim.solid_lo[b] - skin).all()
                        and (v <= sim.solid_hi[b] + skin).all()):
                    for t in range(sim.model.body_tri_range[b][0], sim.model.body_tri_range[b][1]):
                        if sim.model.tri_hidden[t] == 0:
                            io = sim.model.tri_indices[t]
                            q0, q1, q2 = (sim.state.vertex_x[io[0]], sim.state.vertex_x[io[1]],
                                          sim.state.vertex_x[io[2]])
                            if (v >= ti.min(q0, q1, q2) - skin).all() and (v <= ti.max(q0, q1, q2) + skin).all():
                                cross = (q1 - q0).cross(q2 - q0)
                                if cross.norm() > 0.0:
                                    n_rows = vertex_over_face(sim, rows, n_rows, t_m, t, v, cross.normalized(), -skin,
                                                              0.0, max_push)
    return n_rows


@ti.func
def add_sharp_edge_rows(sim: ti.template(), rows: ti.template(), total: ti.i32, max_push: float) -> ti.i32:
    """Rule `sharp_edge_rows`: rows for the sharp convex edges of rigid and static bodies
    (tri_sharp_edges) under soft triangles (edge_under_soft_triangle). Prevents: a membrane
    draped over an edge is cut by it between its vertices, where no vertex row can hold it.
    Returns the rows needed."""
    n_rows = total
    for t_s in range(sim.model.tri_count[0]):
        b_s = sim.model.tri_body[t_s]
        if sim.model.body_kind[b_s] == SOFT:
            skin = ti.static(SOFT_BOX_MARGIN) * sim.body_thickness[b_s]
            im = sim.model.tri_indices[t_s]
            p0, p1, p2 = sim.state.vertex_x[im[0]], sim.state.vertex_x[im[1]], sim.state.vertex_x[im[2]]
            lo, hi = ti.min(p0, p1, p2) - skin, ti.max(p0, p1, p2) + skin
            cross = (p1 - p0).cross(p2 - p0)
            if cross.norm() > 0.0:
                n_s = cross.normalized()
                for b in range(sim.model.body_count[0]):
                    if (sim.model.body_kind[b] != SOFT and (sim.solid_hi[b] >= lo).all()
                            and (sim.solid_lo[b] <= hi).all()):
                        for t in range(sim.model.body_tri_range[b][0], sim.model.body_tri_range[b][1]):
                            if sim.tri_sharp_edges[t] != 0 and sim.model.tri_hidden[t] == 0:
                                n_rows = edge_under_soft_triangle(sim, rows, n_rows, t_s, t, n_s, lo, hi, skin,
                                                                  max_push)
    return n_rows


@ti.func
def facing_edge(sim: ti.template(), t: ti.i32, k: ti.i32, n_s: vec3) -> vec3:
    """A cloth triangle's unit normal n_s turned to face edge k of triangle t: against the
    edge's outward direction, the sum of the unit normals of t and of the face across the
    edge (tri_convex_nbr). Not against t's normal alone, as in the narrow phase: a ridge's
    edge may belong to the face across the ridge from the cloth, whose normal would turn
    the cloth away from the ridge."""
    io = sim.model.tri_indices[t]
    q0 = sim.state.vertex_x[io[0]]
    out = (sim.state.vertex_x[io[1]] - q0).cross(sim.state.vertex_x[io[2]] - q0).normalized()
    nbr = sim.tri_convex_nbr[t][k]
    if nbr >= 0:
        ib = sim.model.tri_indices[nbr]
        p0 = sim.state.vertex_x[ib[0]]
        out += (sim.state.vertex_x[ib[1]] - p0).cross(sim.state.vertex_x[ib[2]] - p0).normalized()
    return ti.select(n_s.dot(out) > 0.0, -n_s, n_s)


@ti.func
def edge_under_soft_triangle(sim: ti.template(), rows: ti.template(), total: ti.i32, t_s: ti.i32, t: ti.i32,
                             n_s: vec3, lo: vec3, hi: vec3, skin: float, max_push: float) -> ti.i32:
    """Rows for the sharp edges of triangle t under soft triangle t_s (vertices p0, p1, p2, unit
    normal n_s, box lo..hi padded by skin): the part of the edge whose projection along n_s falls in t_s (clipped
    against t_s's three edge lines), at its end nearest to t_s's back, when that end is
    within `skin` of t_s's plane in front or behind. The row moves t at that point along
    n_s (C = n_s·(p_soft − q) ≥ 0: the edge stays outside the soft body), which pushes
    only t_s when t is static."""
    n_rows = total
    im, io = sim.model.tri_indices[t_s], sim.model.tri_indices[t]
    p0, p1, p2 = sim.state.vertex_x[im[0]], sim.state.vertex_x[im[1]], sim.state.vertex_x[im[2]]
    bits = sim.tri_sharp_edges[t]
    pts = [p0, p1, p2]
    for k in ti.static(range(3)):
        if (bits >> k) & 1:
            qa, qb = sim.state.vertex_x[io[k]], sim.state.vertex_x[io[(k + 1) % 3]]
            n_face = n_s
            if ti.static(sim.model.has_cloth):
                if is_cloth(sim, t_s):
                    n_face = facing_edge(sim, t, k, n_s)
            if (ti.max(qa, qb) >= lo).all() and (ti.min(qa, qb) <= hi).all():
                t0, t1 = 0.0, 1.0
                e = qb - qa
                for i in ti.static(range(3)):
                    inward = n_s.cross(pts[(i + 1) % 3] - pts[i])
                    g0 = inward.dot(qa - pts[i])
                    dg = inward.dot(e)
                    # Keep t with g0 + t·dg ≥ 0.
                    if dg > 0.0:
                        t0 = ti.max(t0, -g0 / dg)
                    elif dg < 0.0:
                        t1 = ti.min(t1, -g0 / dg)
                    elif g0 < 0.0:
                        t1 = -1.0
                if t0 <= t1:
                    d0 = n_face.dot(qa + t0 * e - p0)
                    d1 = n_face.dot(qa + t1 * e - p0)
                    d = ti.min(d0, d1)
                    q = qa + ti.select(d0 <= d1, t0, t1) * e
                    if ti.abs(d) <= skin and not is_duplicate(sim, rows, ti.min(n_rows, rows.tri.shape[0]), t, t_s,
                                                              n_face, q):
                        if n_rows < rows.tri.shape[0]:
                            write_contact(sim, rows, n_rows, t, t_s, -d, n_face, q, max_push)
                        n_rows += 1
    return n_rows
