"""The in-kernel all-pairs broad phase of small scenes: every triangle pair of different bodies
(not both static or asleep, neither a hidden face), and of one soft body with self_collision
(not near neighbours: core.geometry.near_in_mesh), whose padded boxes overlap, serially."""

import taichi as ti

from ..collision.broadphase import BOX_SLACK
from ..collision.grid_cells import boxes_overlap
from ..core import runtime
from ..core.geometry import near_in_mesh
from ..contact.sleeping import is_moving

vec3 = ti.math.vec3
ivec3 = ti.types.vector(3, ti.i32)


@ti.func
def triangle_box(sim: ti.template(), t: ti.i32):
    """Box of triangle t padded like the grid's (see broadphase.BOX_SLACK)."""
    idx = sim.model.tri_indices[t]
    p0, p1, p2 = sim.state.vertex_x[idx[0]], sim.state.vertex_x[idx[1]], sim.state.vertex_x[idx[2]]
    lo = ti.min(p0, p1, p2)
    hi = ti.max(p0, p1, p2)
    pad = (ti.static(BOX_SLACK * runtime.tolerance()) * (hi - lo).max()
           + sim.body_box_margin[sim.model.tri_body[t]])
    sim.tri_lo[t] = lo - pad
    sim.tri_hi[t] = hi + pad


@ti.func
def candidate_pairs(sim: ti.template(), rows: ti.template()) -> ti.i32:
    """Serial all-pairs broad phase: triangle pairs of different bodies (not both static or
    asleep: solver.sleep), neither a hidden static face, whose padded boxes overlap, written to
    rows.tri; returns their number (more than the capacity on overflow)."""
    n_b = sim.model.body_count[0]
    for t in range(sim.model.tri_count[0]):
        triangle_box(sim, t)
    for b in range(n_b):
        lo = vec3(ti.math.inf)
        hi = vec3(-ti.math.inf)
        for t in range(sim.model.body_tri_range[b][0], sim.model.body_tri_range[b][1]):
            lo = ti.min(lo, sim.tri_lo[t])
            hi = ti.max(hi, sim.tri_hi[t])
        sim.body_lo[b] = lo
        sim.body_hi[b] = hi
    n = 0
    capacity = rows.tri.shape[0]
    for ba in range(n_b):
        for bb in range(ba + 1, n_b):
            if ((is_moving(sim, ba) or is_moving(sim, bb))
                    and boxes_overlap(sim.body_lo[ba], sim.body_hi[ba], sim.body_lo[bb], sim.body_hi[bb])):
                for ta in range(sim.model.body_tri_range[ba][0], sim.model.body_tri_range[ba][1]):
                    if (sim.model.tri_hidden[ta] == 0
                            and boxes_overlap(sim.tri_lo[ta], sim.tri_hi[ta], sim.body_lo[bb], sim.body_hi[bb])):
                        for tb in range(sim.model.body_tri_range[bb][0], sim.model.body_tri_range[bb][1]):
                            if (sim.model.tri_hidden[tb] == 0
                                    and boxes_overlap(sim.tri_lo[ta], sim.tri_hi[ta], sim.tri_lo[tb],
                                                      sim.tri_hi[tb])):
                                if n < capacity:
                                    rows.tri[n] = ivec3(ta, tb, -1)
                                n += 1
    if ti.static(sim.model.has_soft):
        n = self_pairs(sim, rows, n)
    return n


@ti.func
def self_pairs(sim: ti.template(), rows: ti.template(), total: ti.i32) -> ti.i32:
    """After candidate `total`-1: the pairs of each soft body with self_collision, triangles that
    are not near neighbours (near_in_mesh) and whose padded boxes overlap; returns the count
    (more than the capacity on overflow)."""
    n = total
    capacity = rows.tri.shape[0]
    for b in range(sim.model.body_count[0]):
        if sim.model.body_self_collision[b] != 0 and is_moving(sim, b):
            first, end = sim.model.body_tri_range[b][0], sim.model.body_tri_range[b][1]
            for ta in range(first, end):
                for tb in range(ta + 1, end):
                    # Nested: Taichi's `and` evaluates both sides, and the neighbour test costs.
                    if boxes_overlap(sim.tri_lo[ta], sim.tri_hi[ta], sim.tri_lo[tb], sim.tri_hi[tb]):
                        if not near_in_mesh(sim.model.tri_indices[ta], sim.model.tri_indices[tb],
                                            sim.vertex_nbr_range, sim.vertex_nbr):
                            if n < capacity:
                                rows.tri[n] = ivec3(ta, tb, -1)
                            n += 1
    return n
