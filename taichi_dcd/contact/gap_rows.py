"""Gap rows: between two moving rigid bodies, a vertex of one lying just in front of a face of
the other gets a row whose depth is minus the gap, so that it pushes only once the projection
closes that gap (rule `gap_rows`; the all-pairs broad phase's scenes)."""

import taichi as ti

from ..collision.grid_cells import boxes_overlap
from ..core import runtime
from ..core.geometry import barycentric
from ..core.model import RIGID
from .exits import behind_plane
from .rows import has_pair_row, is_duplicate, start_row
from .sleeping import is_moving

vec3 = ti.math.vec3

# A vertex within this many substep allowances (max_push, m) in front of a face gets a gap row:
# more than a landing body pushes the one it lands on in a substep.
GAP_MARGIN_PUSHES = 2.0
# Only faces turned towards each other (their unit normals' dot below this) tie a vertex of
# one to the other: a box's side faces do not reach over the face below.
FACING_DOT = -0.5
# Only faces that carry weight (their normal within 45° of the vertical, sim.up) get gap rows:
# a landing pushes the body under it up into the ones above. With the side faces too, the
# pyramid's touching neighbours got them, and it rested 29 µm from its places instead of 16 at
# a third more wall time (docs/experiments.md, 2026-12-06).
SUPPORT_DOT = 0.7071


@ti.func
def is_moving_rigid(sim: ti.template(), b: ti.i32) -> bool:
    return sim.model.body_kind[b] == RIGID and is_moving(sim, b)


@ti.func
def add_gap_rows(sim: ti.template(), rows: ti.template(), n: ti.i32, max_push: float) -> ti.i32:
    """After the n rows so far: a row for each vertex p of a triangle of a moving rigid body
    in front of a facing triangle of another that carries weight (SUPPORT_DOT; serial), no row
    tying the two triangles yet,
    at gap d = N·(p − q) ≤ GAP_MARGIN_PUSHES·max_push, q its projection inside the other
    triangle (N the other's unit normal): the point p, target q, normal N, depth −d. In the
    projection its gap g = −d − N·Δ (Δ the anchors' relative motion) pushes only once it turns
    positive (solver.block_rows: c = max(min(g, budget), 0)), so a body pushed up into the one
    above it carries that one along in the same sweep. Prevents: in a stack set 1e-5 m apart,
    only the box whose gap the discrete detection had seen close was stopped in a substep, and
    stopping it pushed it into the next one, still falling: each box landed deeper than the
    one below (up to 0.14 mm in a stack of ten), and the deep side-face crossings pushed the
    boxes sideways (up to 0.1 mm off their places). Returns the rows needed (above the
    buffer's capacity if it overflowed)."""
    capacity = rows.tri.shape[0]
    margin = ti.static(GAP_MARGIN_PUSHES) * max_push
    tol = ti.static(runtime.tolerance())
    n_b = sim.model.body_count[0]
    for ba in range(n_b):
        for bb in range(ba + 1, n_b):
            if is_moving_rigid(sim, ba) and is_moving_rigid(sim, bb):
                if boxes_overlap(sim.body_lo[ba] - margin, sim.body_hi[ba] + margin, sim.body_lo[bb],
                                 sim.body_hi[bb]):
                    for ta in range(sim.model.body_tri_range[ba][0], sim.model.body_tri_range[ba][1]):
                        lo_a, hi_a = sim.tri_lo[ta] - margin, sim.tri_hi[ta] + margin
                        if boxes_overlap(lo_a, hi_a, sim.body_lo[bb], sim.body_hi[bb]):
                            for tb in range(sim.model.body_tri_range[bb][0], sim.model.body_tri_range[bb][1]):
                                if boxes_overlap(lo_a, hi_a, sim.tri_lo[tb], sim.tri_hi[tb]):
                                    if not has_pair_row(sim, rows, ta, tb):
                                        n = gap_rows_of_pair(sim, rows, n, ta, tb, margin, tol, max_push, capacity)
    return n


@ti.func
def gap_rows_of_pair(sim: ti.template(), rows: ti.template(), n: ti.i32, ta: ti.i32, tb: ti.i32, margin: float,
                     tol: float, max_push: float, capacity: ti.i32) -> ti.i32:
    """The gap rows of triangles ta and tb, each one's vertices against the other's face."""
    for way in ti.static(range(2)):
        t_m, t_o = (ta, tb) if way == 0 else (tb, ta)
        im, io = sim.model.tri_indices[t_m], sim.model.tri_indices[t_o]
        o0, o1, o2 = sim.state.vertex_x[io[0]], sim.state.vertex_x[io[1]], sim.state.vertex_x[io[2]]
        # (Each unpacked name distinct: Taichi types a reused name by its first assignment.)
        area_o, n_o, at_o, floor_o = behind_plane(sim, t_o, o0)
        area_m, n_m, at_m, floor_m = behind_plane(sim, t_m, o0)
        if n_m.dot(n_o) < ti.static(FACING_DOT) and ti.abs(n_o.dot(sim.up[0])) >= ti.static(SUPPORT_DOT):
            for k in ti.static(range(3)):
                p = sim.state.vertex_x[im[k]]
                area_p, n_p, behind, floor_p = behind_plane(sim, t_o, p)
                gap = -behind
                if gap >= 0.0 and gap <= margin:
                    q = p - gap * n_o
                    bary_o = barycentric(q, o0, o1, o2)
                    if bary_o.min() >= -tol:
                        if not is_duplicate(sim, rows, n, t_m, t_o, n_o, p):
                            if n < capacity:
                                bary_m = vec3(0.0)
                                bary_m[k] = 1.0
                                start_row(sim, rows, n, t_m, t_o, bary_m, bary_o, n_o, p, q, max_push)
                            n += 1
    return n
