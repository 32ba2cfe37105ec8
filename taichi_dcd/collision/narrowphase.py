"""Triangle-pair discrete collision: Kikuchi & Kanai, "A Unified Discrete Collision
Framework for Triangle Primitives" (EG 2025), as pure Taichi functions.

For triangles A and B the method (paper §3; docs/method.md) is:
1. planes N_A, N_B (Eq. 1) and the signed distances of each triangle's vertices
   to the other's plane;
2. Möller's interval-overlap test on the line N_A × N_B (threshold 0);
3. candidate points of A: A's vertices whose projection along N_B falls strictly
   inside B (Eq. 4), points of A's plane reached from B's vertices along N_B that
   fall strictly inside A (Eq. 5), points of A's edges whose projection along N_B
   crosses an edge of B; symmetrically for B;
4. depth_A = max(0, max over A's candidates of -s_B(q)), likewise depth_B;
5. C = min(depth_A, depth_B) (Eq. 6): the shallower triangle is moved, along the
   other triangle's normal (-∇C = N, supplement §3).

Choices beyond the published listing (eps = machine epsilon of the kernels' float
type, tol = TOL_ULPS·eps from `runtime`, L = longest edge of the pair):
- Zero-area triangles (doubled area ≤ tol·longest edge²) have no plane: no hit,
  no constraint, and no division by their zero normal.
- Signed distances within tol·L of zero are snapped to exactly zero, so a vertex
  touching the other plane is touching whatever the rounding; Möller's test with
  threshold 0 then reports touching pairs (shared vertices, shared edges, a
  projection that degenerates onto an edge of the other triangle: supplement
  Fig. 8) as not intersecting.
- Parallel planes (|N_A × N_B| ≤ tol) never intersect; the Möller line is not
  normalised at all, so nothing divides by its length.
- Eq. 5's points are skipped when |N_A·N_B| ≤ tol (perpendicular planes: the
  line from a vertex along one normal never meets the other plane, or lies in
  it; the inclusive edge crossings cover that case). Edge crossings whose
  projected edges are within tol of parallel (|e1 × e2| ≤ tol·|e1||e2|, both
  edges projected into the other plane) are skipped likewise.
- A constraint needs C > tol·L (the listing uses the absolute 1e-7, which is not
  scale invariant and is below f32 noise at unit scale).
- Equal positive depths are a tie the listing drops; here depths within tol·L of
  each other are a tie (symmetric configurations, such as apex on apex, come out
  equal only up to rounding, which differs when the scene is scaled or moved),
  resolved by moving the triangle whose vertex sum (then normal) is
  lexicographically smaller, which does not depend on argument order.
The contact point is the deepest candidate of the moved triangle; candidates of
different kinds within tol·L of each other are a tie won by a vertex of the moved
triangle, then a vertex of the other, then an edge crossing.

One code path (`collide_pair_lanes`) serves one pair and a batch: the solver calls it on
vec3 points inside its kernels; `collide_triangle_pairs` on CPU calls it on a batch of
pairs at once, each coordinate a vector with one pair per lane, which LLVM compiles to
SIMD instructions (see `lanes`). Both give the same bits for the same pair.
"""

from dataclasses import dataclass

import numpy as np
import taichi as ti

from ..core import runtime
from ..core.geometry import (has_area, lex_compare, longest_edge_sq, plane_frame, snap_to_zero, straddles,
                       strictly_inside_2d, to_frame, vec3)
from ..core.lanes import (absolute, add, any_lane, at, cross, cross2, dot, fill, keep3, make2, make3, max3, min3, norm_sqr,
                    norm_sqr2, lane_ints, negate, scale, sub, sub2)


# pressed_through needs a pair to face each other this squarely (N_A·N_B ≤ -cos 45°): a
# patch sagged through a face stays close to parallel to it, while a membrane draped over
# a sharp edge, behind one face's plane but outside the body, is not parallel to that face.
PRESSED_MIN_FACING = 0.7071


@ti.func
def crossing_interval(p0, p1, p2, s, line):
    """Möller's interval: where triangle (p0, p1, p2) crosses the other plane, as
    parameters along `line`. s are its vertices' signed distances to that plane,
    with both signs present. Returns (t_min, t_max)."""
    t_proj = [dot(p0, line), dot(p1, line), dot(p2, line)]
    t_min = ti.max(ti.max(t_proj[0], t_proj[1]), t_proj[2])
    t_max = ti.min(ti.min(t_proj[0], t_proj[1]), t_proj[2])
    for i in ti.static(range(3)):
        j = ti.static((i + 1) % 3)
        on_plane = at(s, i) == 0.0
        crosses = ((at(s, i) < 0.0) & (at(s, j) > 0.0)) | ((at(s, i) > 0.0) & (at(s, j) < 0.0))
        t_cross = t_proj[i] + (t_proj[j] - t_proj[i]) * (at(s, i) / ti.select(crosses, at(s, i) - at(s, j), 1.0))
        t_min = ti.select(on_plane, ti.min(t_min, t_proj[i]), t_min)
        t_max = ti.select(on_plane, ti.max(t_max, t_proj[i]), t_max)
        t_min = ti.select(crosses, ti.min(t_min, t_cross), t_min)
        t_max = ti.select(crosses, ti.max(t_max, t_cross), t_max)
    return t_min, t_max


@ti.func
def intervals_overlap(a0, a1, a2, na_raw, s_a, b0, b1, b2, nb_raw, s_b):
    """Möller's interval-overlap test for triangles that each straddle the other's plane.

    na_raw, nb_raw: the triangles' unnormalised normals; s_a, s_b: each triangle's
    vertex distances to the other's plane, in any positive scale (a crossing is a
    ratio of two of them). The intervals where the triangles cross the other plane
    are compared along na_raw × nb_raw, which is not normalised either: nothing
    divides by a length, so no square root stands between the loads and the verdict.
    The caller rejects (near-)parallel planes, for which the verdict means nothing.
    """
    line = cross(na_raw, nb_raw)
    ta_min, ta_max = crossing_interval(a0, a1, a2, s_a, line)
    tb_min, tb_max = crossing_interval(b0, b1, b2, s_b, line)
    return (ta_max >= tb_min) & (tb_max >= ta_min)


@ti.func
def moved_side(depth_a, depth_b, sum_a, sum_b, n_a, n_b, min_depth):
    """Eq. 6's decision: C = min(depth_A, depth_B); the shallower triangle moves.

    Returns 0 if A moves, 1 if B moves, -1 if C <= min_depth (no constraint). On a
    tie (depths within min_depth of each other) the triangle whose vertex sum (then
    normal) is lexicographically smaller moves, which does not depend on argument order.
    """
    order = lex_compare(sum_a, sum_b)
    order = ti.select(order == 0, lex_compare(n_a, n_b), order)
    side = ti.select(absolute(depth_a - depth_b) <= min_depth, ti.select(order <= 0, 0, 1),
                     ti.select(depth_a < depth_b, 0, 1))
    return ti.select(ti.min(depth_a, depth_b) > min_depth, side, -1)


@ti.func
def deeper(depth0, point0, depth1, point1):
    """The deeper of two (depth, point) candidates; the first on a tie."""
    take1 = depth1 > depth0
    return ti.select(take1, depth1, depth0), keep3(take1, point1, point0)


@ti.func
def clearly_deeper(depth0, point0, depth1, point1, margin):
    """The second candidate only if it is deeper than the first by more than `margin`."""
    take1 = depth1 > depth0 + margin
    return ti.select(take1, depth1, depth0), keep3(take1, point1, point0)


@ti.func
def deepest_candidate(p0, p1, p2, s_p, q0, q1, q2, n_q, s_q, cos_pq, tol: float, margin):
    """Depth of triangle P in triangle Q's half-space and the deepest candidate point.

    s_p: P's vertices' signed distances to Q's plane; s_q: Q's to P's plane;
    n_q: Q's unit normal; cos_pq = N_P·N_Q. A candidate x has depth -s_Q(x); the
    result is the largest, at least 0 (paper §3.2, steps 2-3 and 7). Every test
    is made on the images projected along N_Q into Q's plane, in 2-D coordinates
    of that plane: projection is affine, so an edge parameter is the same on an
    edge and on its image. Returns (depth, point).

    Branch-free: the outcomes are data-dependent coin flips, and mispredicted
    branches cost more than the arithmetic. An invalid candidate gets depth 0,
    which never beats the floor of 0. One branch is kept: no point of P is deeper
    than P's deepest vertex, so once a candidate is that deep (within `margin`) the
    edge crossings, the costliest candidates, are not searched (in a batch of lanes,
    unless some lane needs them).

    Candidates of different kinds within `margin` (tol·L) of each other are a tie, won
    by P's vertex, then Q's vertex moved onto P, then an edge crossing: an edge of P
    parallel to Q's plane has every point as deep as its end vertex, and which of them
    rounding makes deepest differs when the same scene is scaled or moved.
    """
    pts_p = [p0, p1, p2]
    pts_q = [q0, q1, q2]
    t1, t2 = plane_frame(q0, q1, n_q)
    img_p = [to_frame(sub(p0, q0), t1, t2), to_frame(sub(p1, q0), t1, t2), to_frame(sub(p2, q0), t1, t2)]
    zero = fill(s_p.x, 0.0)
    img_q = [make2(zero, zero), to_frame(sub(q1, q0), t1, t2), to_frame(sub(q2, q0), t1, t2)]
    edge_q = [sub2(img_q[1], img_q[0]), sub2(img_q[2], img_q[1]), sub2(img_q[0], img_q[2])]
    # g[i][j] = cross2(edge j of Q, image of p_i - q_j): positive when p_i's image is
    # strictly on the inner side of Q's edge line j (Q is counter-clockwise here).
    g = [[cross2(edge_q[j], sub2(img_p[i], img_q[j])) for j in ti.static(range(3))] for i in ti.static(range(3))]

    # P's vertices projecting strictly inside Q (Eq. 4).
    depth_v = zero
    point_v = make3(zero, zero, zero)
    for i in ti.static(range(3)):
        inside = (g[i][0] > 0.0) & (g[i][1] > 0.0) & (g[i][2] > 0.0)
        depth_v, point_v = deeper(depth_v, point_v, ti.select(inside, negate(at(s_p, i)), 0.0), pts_p[i])

    # Points x of P's plane reached from Q's vertices along N_Q (Eq. 5):
    # x = q_j + t·N_Q with N_P·(x - p0) = 0, so t = -s_q[j]/cos_pq and the depth
    # is -t. x is inside P exactly when q_j is inside P's image.
    eq5_defined = absolute(cos_pq) > tol
    inv_cos = 1.0 / ti.select(eq5_defined, cos_pq, 1.0)
    depth_q = zero
    point_q = make3(zero, zero, zero)
    for j in ti.static(range(3)):
        d = at(s_q, j) * inv_cos
        valid = eq5_defined & strictly_inside_2d(img_p[0], img_p[1], img_p[2], img_q[j])
        depth_q, point_q = deeper(depth_q, point_q, ti.select(valid, d, 0.0), sub(pts_q[j], scale(n_q, d)))

    # Points of P's edges whose image crosses an edge of Q (ends included). Along
    # P's edge i -> i+1 the line function of Q's edge j is linear, so the crossing
    # is at u = g[i][j] / (g[i][j] - g[i+1][j]); it lies on Q's edge segment when the
    # other two line functions are >= 0 there. Images closer than tol to parallel
    # are skipped. The best crossing per edge is kept as a fraction (x/den, depth
    # times den) so that only one division per edge is needed.
    depth, point = clearly_deeper(depth_v, point_v, depth_q, point_q, margin)
    search_edges = negate(min3(s_p)) > depth + margin
    if any_lane(search_edges):
        depth_e = zero
        point_e = make3(zero, zero, zero)
        for i in ti.static(range(3)):
            k = ti.static((i + 1) % 3)
            e_p_sq = norm_sqr2(sub2(img_p[k], img_p[i]))
            ds = at(s_p, k) - at(s_p, i)
            best_x = zero
            best_den = fill(zero, 1.0)
            best_num = zero
            for j in ti.static(range(3)):
                j1 = ti.static((j + 1) % 3)
                j2 = ti.static((j + 2) % 3)
                den = g[i][j] - g[k][j]
                flip = ti.select(den < 0.0, -1.0, 1.0)
                den *= flip
                num = g[i][j] * flip
                crosses = ((den * den > tol * tol * e_p_sq * norm_sqr2(edge_q[j]))
                           & (num >= 0.0) & (num <= den)
                           & (g[i][j1] * den + num * (g[k][j1] - g[i][j1]) >= 0.0)
                           & (g[i][j2] * den + num * (g[k][j2] - g[i][j2]) >= 0.0))
                x = negate(at(s_p, i) * den + num * ds)
                better = crosses & (x * best_den > best_x * den)
                best_x = ti.select(better, x, best_x)
                best_den = ti.select(better, den, best_den)
                best_num = ti.select(better, num, best_num)
            u = best_num / best_den
            depth_i = ti.select(best_x > 0.0, negate(at(s_p, i) + u * ds), 0.0)
            depth_e, point_e = deeper(depth_e, point_e, depth_i,
                                      add(pts_p[i], scale(sub(pts_p[k], pts_p[i]), u)))
        depth_c, point_c = clearly_deeper(depth, point, depth_e, point_e, margin)
        depth = ti.select(search_edges, depth_c, depth)
        point = keep3(search_edges, point_c, point)
    return depth, point


@ti.func
def raw_planes(a0, a1, a2, b0, b1, b2):
    """The triangles' unnormalised normals na_raw, nb_raw and each one's vertex distances
    to the other's plane in units of the other's |n_raw|: s_a (A's to B's plane), s_b.
    Unless both s_a and s_b straddle zero (`straddles`), the pair does not intersect."""
    nb_raw = cross(sub(b1, b0), sub(b2, b0))
    na_raw = cross(sub(a1, a0), sub(a2, a0))
    s_a = make3(dot(nb_raw, sub(a0, b0)), dot(nb_raw, sub(a1, b0)), dot(nb_raw, sub(a2, b0)))
    s_b = make3(dot(na_raw, sub(b0, a0)), dot(na_raw, sub(b1, a0)), dot(na_raw, sub(b2, a0)))
    return na_raw, nb_raw, s_a, s_b


@ti.func
def collide_pair_lanes(a0, a1, a2, b0, b1, b2):
    """The unified DCD test of triangles A = (a0, a1, a2) and B = (b0, b1, b2), points
    with scalar components (vec3) or components of lanes (see `lanes`).

    Returns (hit, depth, normal, side, point): hit — Möller's test found the
    triangles intersecting; depth — the constraint C of Eq. 6 (0 when there is
    none); normal — unit direction the moved triangle is pushed along (-∇C), zero
    when there is no constraint; side — 0 if A moves, 1 if B moves, -1 if there is
    no constraint; point — the deepest candidate point of the moved triangle.
    """
    tol = ti.static(runtime.tolerance())
    # Möller's test on raw (unnormalised) normals and distances: snapping near-zero
    # distances can only remove a straddle, never create one, so most pairs leave
    # after two cross products and six dot products, before any tolerance work, and
    # only intersecting pairs pay for normalising.
    na_raw, nb_raw, s_a, s_b = raw_planes(a0, a1, a2, b0, b1, b2)
    zero = fill(s_a.x, 0.0)
    hit = zero > 0.0
    depth = zero
    normal = make3(zero, zero, zero)
    side = ti.select(hit, 0, -1)
    point = make3(zero, zero, zero)
    straddling = straddles(s_a) & straddles(s_b)
    if any_lane(straddling):
        edge_a = longest_edge_sq(a0, a1, a2)
        edge_b = longest_edge_sq(b0, b1, b2)
        len_sq = ti.max(edge_a, edge_b)
        na_sq = norm_sqr(na_raw)
        nb_sq = norm_sqr(nb_raw)
        # The snap threshold tol·L on a unit-normal distance is tol²·L²·|n_raw|²
        # on the squared raw one.
        snap_a = snap_to_zero(s_a, tol * tol * len_sq * nb_sq)
        snap_b = snap_to_zero(s_b, tol * tol * len_sq * na_sq)
        crossing = (straddling & has_area(na_raw, edge_a, tol) & has_area(nb_raw, edge_b, tol)
                    & straddles(snap_a) & straddles(snap_b)
                    & intervals_overlap(a0, a1, a2, na_raw, snap_a, b0, b1, b2, nb_raw, snap_b))
        if any_lane(crossing):
            inv_a = 1.0 / ti.sqrt(na_sq)
            inv_b = 1.0 / ti.sqrt(nb_sq)
            n_a = scale(na_raw, inv_a)
            n_b = scale(nb_raw, inv_b)
            # Parallel planes never intersect; tested on the unit normals, as the raw
            # ones' |na_raw × nb_raw|² (~L⁸) leaves f32's range for millimetre triangles.
            hit = crossing & (norm_sqr(cross(n_a, n_b)) > tol * tol)
            if any_lane(hit):
                dist_a = scale(snap_a, inv_b)
                dist_b = scale(snap_b, inv_a)
                cos_ab = dot(n_a, n_b)
                margin = tol * ti.sqrt(len_sq)
                depth_a, point_a = deepest_candidate(a0, a1, a2, dist_a, b0, b1, b2, n_b, dist_b, cos_ab, tol, margin)
                depth_b, point_b = deepest_candidate(b0, b1, b2, dist_b, a0, a1, a2, n_a, dist_a, cos_ab, tol, margin)
                side_ab = moved_side(depth_a, depth_b, add(add(a0, a1), a2), add(add(b0, b1), b2), n_a, n_b, margin)
                side = ti.select(hit, side_ab, -1)
                moves_a = side == 0
                moves_b = side == 1
                depth = ti.select(moves_a, depth_a, ti.select(moves_b, depth_b, zero))
                normal = keep3(moves_a, n_b, keep3(moves_b, n_a, normal))
                point = keep3(moves_a, point_a, keep3(moves_b, point_b, point))
    return hit, depth, normal, side, point


@ti.func
def collide_triangle_pair(a0: vec3, a1: vec3, a2: vec3, b0: vec3, b1: vec3, b2: vec3):
    """The unified DCD test of one pair of triangles A = (a0, a1, a2) and B = (b0, b1, b2):
    `collide_pair_lanes` on vec3 points. Returns (hit, depth, normal, side, point) as there."""
    return collide_pair_lanes(a0, a1, a2, b0, b1, b2)


@ti.func
def touches(s) -> bool:
    """Whether snapped signed distances s put a triangle against a plane without crossing
    it: some exactly 0, none of one of the two signs."""
    return (min3(s) == 0.0 or max3(s) == 0.0) and not straddles(s)


@ti.func
def touching_planes(a0: vec3, a1: vec3, a2: vec3, b0: vec3, b1: vec3, b2: vec3):
    """The planes of a pair the unified test calls touching, not intersecting (supplement
    Fig. 8), when one triangle crosses the other's plane while the other only touches its
    plane. Returns (which, n_a, n_b, floor): which = 0 if A crosses B's plane and B touches
    A's, 1 for the reverse, -1 otherwise (or a triangle without area); n_a, n_b the unit
    normals; floor = tol·L, the distance treated as zero."""
    tol = ti.static(runtime.tolerance())
    size = ti.sqrt(ti.max(longest_edge_sq(a0, a1, a2), longest_edge_sq(b0, b1, b2)))
    floor = tol * size
    which = -1
    n_a = vec3(0.0)
    n_b = vec3(0.0)
    cross_a = (a1 - a0).cross(a2 - a0)
    cross_b = (b1 - b0).cross(b2 - b0)
    # Snapping only removes a straddle, so a pair whose raw distances straddle neither
    # plane (most candidates) is not touching: leave before normalising anything.
    may_cross = (straddles(vec3(cross_b.dot(a0 - b0), cross_b.dot(a1 - b0), cross_b.dot(a2 - b0)))
                 or straddles(vec3(cross_a.dot(b0 - a0), cross_a.dot(b1 - a0), cross_a.dot(b2 - a0))))
    if may_cross and cross_a.norm() > floor * size and cross_b.norm() > floor * size:
        n_a, n_b = cross_a.normalized(), cross_b.normalized()
        s_a = snap_to_zero(vec3(n_b.dot(a0 - b0), n_b.dot(a1 - b0), n_b.dot(a2 - b0)), floor * floor)
        s_b = snap_to_zero(vec3(n_a.dot(b0 - a0), n_a.dot(b1 - a0), n_a.dot(b2 - a0)), floor * floor)
        if straddles(s_a) and touches(s_b):
            which = 0
        elif straddles(s_b) and touches(s_a):
            which = 1
    return which, n_a, n_b, floor


@ti.func
def pressed_through(a0: vec3, a1: vec3, a2: vec3, b0: vec3, b1: vec3, b2: vec3):
    """Whether one triangle of a pair lies wholly behind or on the other's plane, behind it
    by more than tol·L somewhere, the two facing each other (N_A·N_B ≤ -PRESSED_MIN_FACING): a
    flat patch of a surface pushed through a parallel face. Neither straddles the other's
    plane, so the unified test sees nothing (Möller rejects the pair); a soft body resting
    on a face gets there by sagging. Returns (a_behind, b_behind, n_a, n_b, floor): whether A
    is the triangle behind B's plane, whether B is behind A's (both when the planes
    coincide), the unit normals and the distance treated as zero, tol·L."""
    tol = ti.static(runtime.tolerance())
    size = ti.sqrt(ti.max(longest_edge_sq(a0, a1, a2), longest_edge_sq(b0, b1, b2)))
    floor = tol * size
    a_behind = False
    b_behind = False
    n_a = vec3(0.0)
    n_b = vec3(0.0)
    cross_a = (a1 - a0).cross(a2 - a0)
    cross_b = (b1 - b0).cross(b2 - b0)
    len_a, len_b = cross_a.norm(), cross_b.norm()
    # Facing first, on the raw normals: most candidate pairs leave here.
    if (cross_a.dot(cross_b) <= -PRESSED_MIN_FACING * len_a * len_b
            and len_a > floor * size and len_b > floor * size):
        n_a, n_b = cross_a / len_a, cross_b / len_b
        s_a = snap_to_zero(vec3(n_b.dot(a0 - b0), n_b.dot(a1 - b0), n_b.dot(a2 - b0)), floor * floor)
        s_b = snap_to_zero(vec3(n_a.dot(b0 - a0), n_a.dot(b1 - a0), n_a.dot(b2 - a0)), floor * floor)
        a_behind = (max3(s_a) <= 0.0) & (min3(s_a) < 0.0)
        b_behind = (max3(s_b) <= 0.0) & (min3(s_b) < 0.0)
    return a_behind, b_behind, n_a, n_b, floor


@ti.func
def all_finite(points: ti.template()):
    """Whether no coordinate of the points (a list of vec3 or of points of lanes) is NaN or
    infinite, lane by lane: x·0 is NaN exactly for those (runtime.init turns fast_math off,
    so this is not folded to 0)."""
    zeros = points[0].x * 0.0
    for p in ti.static(points):
        for c in ti.static(range(3)):
            zeros += at(p, c) * 0.0
    return zeros == 0.0


@ti.kernel
def _collide_pairs_kernel(
    a: ti.types.ndarray(dtype=vec3, ndim=2),
    b: ti.types.ndarray(dtype=vec3, ndim=2),
    hit: ti.types.ndarray(ndim=1),
    depth: ti.types.ndarray(ndim=1),
    normal: ti.types.ndarray(dtype=vec3, ndim=1),
    side: ti.types.ndarray(ndim=1),
    point: ti.types.ndarray(dtype=vec3, ndim=1),
):
    """One unified DCD test (Eq. 6 and its gradient) per row of a and b: the one-pair path,
    for GPU arches (where lanes would only lengthen each thread's work)."""
    for i in range(a.shape[0]):
        a0, a1, a2, b0, b1, b2 = a[i, 0], a[i, 1], a[i, 2], b[i, 0], b[i, 1], b[i, 2]
        h = ti.i8(-1)  # marks a row with a non-finite coordinate
        d = 0.0
        n = vec3(0.0)
        s = -1
        p = vec3(0.0)
        if all_finite([a0, a1, a2, b0, b1, b2]):
            hit_i, d, n, s, p = collide_triangle_pair(a0, a1, a2, b0, b1, b2)
            h = ti.cast(hit_i, ti.i8)
        hit[i] = h
        depth[i] = d
        normal[i] = n
        side[i] = ti.cast(s, ti.i8)
        point[i] = p


# Bytes of one coordinate over all the pairs of a SIMD batch of `_collide_packets_kernel`:
# one AVX-512 register (8 f64 or 16 f32 lanes; LLVM splits it in two on AVX2 machines).
# Measured per f64 pair on random pairs: 4 lanes 49 ns, 8 lanes 44 ns.
PACKET_BYTES = 64
# Batches whose rows `_collide_packets_kernel` sorts by whether they need the whole test
# (per f64 pair: windows of 8 batches 46 ns, 16 44 ns, 32 44 ns, 64 45 ns).
WINDOW_BATCHES = 16


@ti.func
def load_lanes(a: ti.template(), b: ti.template(), rows: ti.template()):
    """Triangles A and B of the pairs in `rows` (one per lane) as points of lanes."""
    return [[make3(ti.Vector([m[row, v, 0] for row in rows]), ti.Vector([m[row, v, 1] for row in rows]),
                   ti.Vector([m[row, v, 2] for row in rows]))
             for v in ti.static(range(3))] for m in ti.static((a, b))]


@ti.kernel
def _collide_packets_kernel(
    a: ti.types.ndarray(ndim=3),
    b: ti.types.ndarray(ndim=3),
    hit: ti.types.ndarray(ndim=1),
    depth: ti.types.ndarray(ndim=1),
    normal: ti.types.ndarray(ndim=2),
    side: ti.types.ndarray(ndim=1),
    point: ti.types.ndarray(ndim=2),
):
    """The unified DCD test (Eq. 6 and its gradient) per row of a and b, on a batch of rows
    at a time, one row per lane (PACKET_BYTES). Compiled with Taichi's matrices kept as LLVM
    vectors (see `_launch_packets`); only scalars are loaded and stored, so no vector access
    needs an alignment the arrays may not have.

    A batch pays for the candidate searches of all its lanes when one lane needs them, so
    the rows of a window of WINDOW_BATCHES batches are sorted first. Pass 1, every row: the
    no-contact outputs (hit = -1 for a non-finite coordinate), and the rows whose distances
    straddle both planes go on the window's list. Pass 2, the listed rows, now batched with
    each other (their data still in cache): the whole test, whose outputs replace pass 1's."""
    n = a.shape[0]
    lanes = ti.static(PACKET_BYTES // np.dtype(runtime.real_dtype()).itemsize)
    window = ti.static(lanes * WINDOW_BATCHES)
    for window_index in range((n + window - 1) // window):
        listed = ti.Vector([0] * window, dt=ti.i32)
        listed_count = 0
        for batch in range(WINDOW_BATCHES):
            first = window_index * window + batch * lanes
            rows = [ti.min(first + lane, n - 1) for lane in ti.static(range(lanes))]
            tri = load_lanes(a, b, rows)
            finite = all_finite(tri[0] + tri[1])
            _, _, s_a, s_b = raw_planes(tri[0][0], tri[0][1], tri[0][2], tri[1][0], tri[1][1], tri[1][2])
            finite_ints = lane_ints(finite)
            to_list = lane_ints(finite & straddles(s_a) & straddles(s_b))
            for lane in ti.static(range(lanes)):
                row = first + lane
                if row < n:
                    hit[row] = ti.select(finite_ints[lane] != 0, ti.i8(0), ti.i8(-1))
                    depth[row] = 0.0
                    side[row] = ti.i8(-1)
                    for c in ti.static(range(3)):
                        normal[row, c] = 0.0
                        point[row, c] = 0.0
                    # Always written, kept only when counted: no branch on a coin flip.
                    listed[listed_count] = row
                    listed_count += to_list[lane]
        for batch in range((listed_count + lanes - 1) // lanes):
            first = batch * lanes
            # A last, partial batch repeats its last row: the same outputs, written again.
            rows = [listed[ti.min(first + lane, listed_count - 1)] for lane in ti.static(range(lanes))]
            tri = load_lanes(a, b, rows)
            h, d, nrm, s, pt = collide_pair_lanes(tri[0][0], tri[0][1], tri[0][2], tri[1][0], tri[1][1], tri[1][2])
            hit_ints = lane_ints(h)
            for lane in ti.static(range(lanes)):
                row = rows[lane]
                hit[row] = ti.cast(hit_ints[lane], ti.i8)
                depth[row] = d[lane]
                side[row] = ti.cast(s[lane], ti.i8)
                for c in ti.static(range(3)):
                    normal[row, c] = at(nrm, c)[lane]
                    point[row, c] = at(pt, c)[lane]


def _launch_packets(a, b, hit, depth, normal, side, point) -> None:
    """Run `_collide_packets_kernel` on n rows, compiled with `real_matrix_scalarize` off:
    Taichi then leaves its vectors to LLVM as vector types, and the lanes become SIMD
    instructions (with it on, every kernel is scalar code). Only this kernel is compiled
    so: others load vec3 ndarray elements, which that mode turns into vector loads that
    need an alignment the arrays do not have (they crash). Taichi's offline cache leaves the
    flag out of its key, so the kernel is launched through here only."""
    config = ti.lang.impl.current_cfg()
    scalarize = config.real_matrix_scalarize
    config.real_matrix_scalarize = False
    try:
        _collide_packets_kernel(a, b, hit, depth, normal, side, point)
    finally:
        config.real_matrix_scalarize = scalarize


@dataclass
class PairContacts:
    """Result of `collide_triangle_pairs` for n pairs.

    hit (n,) bool — the triangles intersect (Möller's test); depth (n,) float —
    the constraint C in input units, 0 where there is none; normal (n, 3) — unit
    push direction of the moved triangle, zero where there is no constraint;
    side (n,) int8 — 0 if `a` moves, 1 if `b` moves, -1 if no constraint;
    point (n, 3) — deepest candidate point of the moved triangle.
    """

    hit: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    side: np.ndarray
    point: np.ndarray

    def __len__(self) -> int:
        return len(self.depth)


def _as_triangles(x, name: str, dtype) -> np.ndarray:
    arr = np.asarray(x)
    if arr.ndim != 3 or arr.shape[1:] != (3, 3):
        raise ValueError(f"{name} must have shape (n, 3, 3), got {arr.shape}")
    if not np.issubdtype(arr.dtype, np.number):
        raise ValueError(f"{name} must be numeric, got dtype {arr.dtype}")
    return np.ascontiguousarray(arr, dtype=dtype)


def collide_triangle_pairs(a, b) -> PairContacts:
    """Run the unified triangle-pair DCD test on n pairs (a[i], b[i]).

    a, b: arrays of shape (n, 3, 3), vertex k of triangle i at a[i, k]; vertex
    order gives the outward normal (right-hand rule). Computed in the precision
    chosen at `taichi_dcd.init` (default f64). Raises ValueError for a bad shape
    or for NaN/infinite coordinates, naming the first bad pair. See the module
    docstring for how ties and degenerate triangles are decided.
    """
    runtime.ensure_init()
    dtype = runtime.real_dtype()
    a_arr = _as_triangles(a, "a", dtype)
    b_arr = _as_triangles(b, "b", dtype)
    if len(a_arr) != len(b_arr):
        raise ValueError(f"a and b must hold the same number of triangles, got {len(a_arr)} and {len(b_arr)}")
    n = len(a_arr)
    # The kernel writes every row, so outputs need no initialisation.
    hit = np.empty(n, dtype=np.int8)
    result = PairContacts(
        hit=hit,
        depth=np.empty(n, dtype=dtype),
        normal=np.empty((n, 3), dtype=dtype),
        side=np.empty(n, dtype=np.int8),
        point=np.empty((n, 3), dtype=dtype),
    )
    if n:
        outputs = (hit, result.depth, result.normal, result.side, result.point)
        if runtime.arch() == "cpu":
            _launch_packets(a_arr, b_arr, *outputs)
        else:
            _collide_pairs_kernel(a_arr, b_arr, *outputs)
        bad = np.flatnonzero(hit < 0)
        if len(bad):
            i = int(bad[0])
            which = "a" if not np.isfinite(a_arr[i]).all() else "b"
            raise ValueError(f"pair {i}: triangle {which} has a NaN or infinite coordinate")
    result.hit = hit.view(bool)
    return result
