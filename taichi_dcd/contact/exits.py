"""Which way a contact leaves the other body: convex edges of rigid and static meshes (found once,
in numpy), the nearest exit through a convex neighbour's face, and the edge-edge normal where
two convex edges meet."""

import numpy as np
import taichi as ti

from ..core import runtime
from ..core.geometry import barycentric, closest_on_segments, longest_edge_sq
from ..core.model import SOFT, Model

vec3 = ti.math.vec3

# Resting edge rows (add_resting_contacts) go along convex edges of rigid and static bodies whose
# faces' normals differ by more than this.
SHARP_EDGE_DEGREES = 30.0

# A contact row between rigid or static bodies, deeper than one substep's allowance, whose
# point is nearer the plane of a convex neighbour of the other triangle than this fraction of
# its depth leaves through that neighbour instead (contact.exits.nearest_exit). Rows within the
# allowance keep their face: re-aimed too, a spike leaning on a block's edge, its points there
# always nearly on the side plane, jittered at 1-3 mm/s (at 0.5 and at 0.01 alike). Edges whose
# faces' normals differ by less than CONVEX_EDGE_DEGREES are not edges of the shape (a flat
# face split in two).
NEAREST_EXIT_FRACTION = 0.01
CONVEX_EDGE_DEGREES = 1.0


def convex_edges(model: Model, vertex_x: np.ndarray):
    """Convex edges between two rigid or static triangles of one body: a list of
    (t0, k0, t1, k1, cos) with t0 < t1, edge k0 of t0 (vertex k0 to k0+1) the same as edge
    k1 of t1, cos the dot product of the faces' unit normals. vertex_x (V, 3): any pose
    (rigid motion keeps it)."""
    tri = model.tri_indices_np
    if model.n_tris == 0:
        return []
    p = vertex_x[tri]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    normals = normals / np.where(lengths > 0.0, lengths, 1.0)[:, None]
    rigid = model.body_kind_np[model.tri_body_np] != SOFT
    owner = {}
    for t in np.flatnonzero(rigid):
        for k in range(3):
            a, b = int(tri[t, k]), int(tri[t, (k + 1) % 3])
            owner.setdefault((min(a, b), max(a, b)), []).append((t, k))
    edges = []
    for faces in owner.values():
        if len(faces) != 2:
            continue
        (t0, k0), (t1, k1) = sorted(faces)
        apart = [v for v in range(3) if tri[t1, v] not in tri[t0]]
        if len(apart) != 1 or lengths[t0] == 0.0 or lengths[t1] == 0.0:
            continue
        if normals[t0].dot(p[t1, apart[0]] - p[t0, 0]) < 0.0:
            edges.append((int(t0), k0, int(t1), k1, float(normals[t0].dot(normals[t1]))))
    return edges


def sharp_edge_bits(model: Model, vertex_x: np.ndarray) -> np.ndarray:
    """(T,) int32: bit k set when edge k (vertex k to k+1) of a rigid or static triangle is a
    convex edge whose two faces' normals differ by more than SHARP_EDGE_DEGREES, set on one
    of its two faces only (the lower index). vertex_x (V, 3): any pose."""
    bits = np.zeros(max(model.n_tris, 1), np.int32)
    cos_sharp = np.cos(np.radians(SHARP_EDGE_DEGREES))
    for t0, k0, _, _, cos in convex_edges(model, vertex_x):
        if cos < cos_sharp:
            bits[t0] |= 1 << k0
    return bits


def convex_neighbours(model: Model, vertex_x: np.ndarray) -> np.ndarray:
    """(max(T, 1), 3) int32: the triangle across edge k of each rigid or static triangle when
    that edge is convex by more than CONVEX_EDGE_DEGREES, else -1. vertex_x (V, 3): any pose."""
    nbr = np.full((max(model.n_tris, 1), 3), -1, np.int32)
    cos_edge = np.cos(np.radians(CONVEX_EDGE_DEGREES))
    for t0, k0, t1, k1, cos in convex_edges(model, vertex_x):
        if cos < cos_edge:
            nbr[t0, k0], nbr[t1, k1] = t1, t0
    return nbr


@ti.func
def behind_plane(sim: ti.template(), t: ti.i32, point: vec3):
    """How far `point` lies behind triangle t's plane (m, along its unit normal; negative in
    front). Returns (whether t has area, its unit normal, that distance, the rounding floor
    below which the sign means nothing: the tolerance times t's longest edge)."""
    tol = ti.static(runtime.tolerance())
    idx = sim.model.tri_indices[t]
    q0, q1, q2 = sim.state.vertex_x[idx[0]], sim.state.vertex_x[idx[1]], sim.state.vertex_x[idx[2]]
    raw = (q1 - q0).cross(q2 - q0)
    length = raw.norm()
    has_area = length > 0.0
    n_t = raw / ti.select(has_area, length, 1.0)
    d = n_t.dot(q0 - point)
    floor = tol * ti.sqrt(longest_edge_sq(q0, q1, q2))
    return has_area, n_t, d, floor


@ti.func
def beyond_convex_edge(sim: ti.template(), t: ti.i32, point: vec3) -> bool:
    """Whether `point` lies in front of the plane of a convex neighbour of triangle t
    (tri_convex_nbr) by more than rounding: outside t's body past that edge, however far
    behind t's own plane it is."""
    beyond = False
    nbr = sim.tri_convex_nbr[t]
    for k in ti.static(range(3)):
        if nbr[k] >= 0:
            has_area, _, d, floor = behind_plane(sim, nbr[k], point)
            if has_area and d < -floor:
                beyond = True
    return beyond


@ti.func
def nearest_exit(sim: ti.template(), t_other: ti.i32, point: vec3, depth: float, normal: vec3, may_hold: bool,
                 exit_first: bool):
    """The face a contact's point leaves the other body through: t_other's plane, where
    the narrow phase measured `depth` along `normal`, or the plane of a convex neighbour
    of t_other (tri_convex_nbr) behind which the point lies by less than
    NEAREST_EXIT_FRACTION of that. Eq. 6 sees one pair: a wedge resting on a block's
    edge sinks ~1e-5 m a substep into the top face, its end faces then cross the block's
    side face, and the pair's depth is how far the wedge's base reaches in past the side
    (0.24 m), not the 1e-5 m it is below the top; pushed along the side's normal every
    substep, the wedge crept off the edge. A point on a convex neighbour's plane (within
    rounding) is on the other body's surface, not in it; where the caller found the row
    a grazing one (`may_hold`: add_pair_contact), it becomes a row along that neighbour's
    normal at depth 0, holding the point there; with `exit_first`, only if no neighbour is
    an exit. Returns (triangle, depth, unit normal, whether the point is held on the
    surface)."""
    t_best, d_best, n_best = t_other, depth, normal
    on_surface = False
    t_surface, n_surface = t_other, normal
    nbr = sim.tri_convex_nbr[t_other]
    for k in ti.static(range(3)):
        t = nbr[k]
        if t >= 0:
            has_area, n_t, d, floor = behind_plane(sim, t, point)
            if has_area:
                # A point on the neighbour's plane up to rounding (coplanar faces: the
                # end faces of the parallel wedges) is not nearer it: which sign rounding
                # gives differs when the scene is scaled or moved.
                if d > floor and d < NEAREST_EXIT_FRACTION * depth and d < d_best:
                    t_best, d_best, n_best = t, d, n_t
                elif ti.abs(d) <= floor and not on_surface and may_hold:
                    on_surface = True
                    t_surface, n_surface = t, n_t
    if exit_first and t_best != t_other:
        on_surface = False
    if on_surface:
        t_best, d_best, n_best = t_surface, 0.0, n_surface
    return t_best, d_best, n_best, on_surface


@ti.func
def convex_edge_of(sim: ti.template(), t: ti.i32, x: vec3):
    """The convex edge of triangle t (tri_convex_nbr) that x lies on (within √eps in
    barycentric weight, not at a vertex). Returns (found, its start, its end, the triangle
    across it); the ends are t's vertices in t's order."""
    idx = sim.model.tri_indices[t]
    q = [sim.state.vertex_x[idx[0]], sim.state.vertex_x[idx[1]], sim.state.vertex_x[idx[2]]]
    bary = barycentric(x, q[0], q[1], q[2])
    tol = ti.static(ti.sqrt(runtime.machine_eps()))
    nbr = sim.tri_convex_nbr[t]
    found = False
    start, end = q[0], q[0]
    t_across = -1
    for j in ti.static(range(3)):
        k = ti.static((j + 1) % 3)  # the edge opposite vertex j runs from vertex k to k+1
        k1 = ti.static((j + 2) % 3)
        if ti.abs(bary[j]) <= tol and bary[k] > tol and bary[k1] > tol and nbr[k] >= 0:
            found = True
            start, end, t_across = q[k], q[k1], nbr[k]
    return found, start, end, t_across


@ti.func
def in_front_of(sim: ti.template(), t: ti.i32, x: vec3) -> float:
    """How far x lies in front of triangle t's plane along its unit normal (m; negative
    behind it, 0 for a triangle without area)."""
    has_area, _, behind, _ = behind_plane(sim, t, x)
    return ti.select(has_area, -behind, 0.0)


@ti.func
def edges_interlock(sim: ti.template(), a_m: vec3, b_m: vec3, faces_m: ti.math.ivec2, a_o: vec3, b_o: vec3,
                    faces_o: ti.math.ivec2, margin: float) -> bool:
    """Whether the edges a_m-b_m (between the triangles faces_m) and a_o-b_o (between faces_o)
    pass through each other: the midpoint of the two segments' closest points lies behind, or
    no more than `margin` (m) in front of, all four faces."""
    c_m, c_o = closest_on_segments(a_m, b_m, a_o, b_o)
    mid = 0.5 * (c_m + c_o)
    return (in_front_of(sim, faces_m[0], mid) <= margin and in_front_of(sim, faces_m[1], mid) <= margin
            and in_front_of(sim, faces_o[0], mid) <= margin and in_front_of(sim, faces_o[1], mid) <= margin)


@ti.func
def edge_edge_normal(sim: ti.template(), t_moved: ti.i32, t_other: ti.i32, point: vec3, depth: float, normal: vec3,
                     only_interlocked: bool, margin: float):
    """A contact whose point is an edge crossing, on a convex edge of the moved
    triangle, and whose target point + depth·normal is on a convex edge of the other, is
    two edges of the shapes meeting: it is pushed along e_m × e_o (oriented as `normal`),
    by the distance between the edge lines along it, depth·(N_ee·N). Eq. 6 gives one
    face's normal instead: a wedge leaning on a block's top edge got rows along the block's
    side and top normals from its end face, pushing it away from the block every substep,
    and it slid down at 5.7 mm/s. With `only_interlocked`, only where the two edges pass
    through each other (edges_interlock, within `margin` m): two skew edges far apart outside
    both bodies are no contact of edges. Returns (depth, unit normal)."""
    found_m, a_m, b_m, across_m = convex_edge_of(sim, t_moved, point)
    found_o, a_o, b_o, across_o = convex_edge_of(sim, t_other, point + depth * normal)
    e_m = ti.select(found_m, b_m - a_m, vec3(0.0))
    e_o = ti.select(found_o, b_o - a_o, vec3(0.0))
    n_ee = e_m.cross(e_o)
    length = n_ee.norm()
    d_out, n_out = depth, normal
    if length > 1e-3 * e_m.norm() * e_o.norm():  # false when either is no edge (zero)
        meet = True
        if only_interlocked:
            meet = edges_interlock(sim, a_m, b_m, ti.math.ivec2(t_moved, across_m), a_o, b_o,
                                   ti.math.ivec2(t_other, across_o), margin)
        if meet:
            n_ee = n_ee / length
            cos = n_ee.dot(normal)
            if cos < 0.0:
                n_ee, cos = -n_ee, -cos
            if cos > 0.0:
                d_out, n_out = depth * cos, n_ee
    return d_out, n_out
