"""Carried rows: rows that pushed in one substep are offered again in the next while their
anchors stay together, unless another row of the same two bodies pushes back against them;
rows between cloth triangles also while they lie within their gap or near it."""

import numpy as np
import taichi as ti

from ..core.model import SOFT, STATIC
from .anchors import anchor_world, involves_soft
from .cloth import is_cloth, pair_gap
from .rows import both_rigid, has_pair_row, start_row
from .sleeping import is_moving

ivec2 = ti.types.vector(2, ti.i32)

# Two rows between the same moving bodies push about opposite ways when their pushes on one
# body are within this angle of opposite (keep_rows: neither is carried).
OPPOSED_DEGREES = 30.0

# A row between two cloth triangles (two sheets, or one sheet folded) is carried while its
# anchors are no farther apart across the normal than this many gaps beyond their gap,
# whether or not it pushed (keep_rows).
SLACK_GAPS = 1.0


@ti.func
def keep_rows(sim: ti.template(), rows: ti.template(), n: ti.i32, slip_max: float):
    """Remember the rigid and static rows of [0, n), and those between soft triangles (of one
    body with self_collision, or of two cloths), that pushed in this substep (λ_n > 0)
    and whose two anchors lie within slip_max (m) of each other across the normal, for
    carried_rows in the next substep. A row carried before may be carried again: a
    support the detection finds only every few substeps is then held in between; once its
    anchors slide apart (the bodies slip or roll past it) it is let go. So is a row
    between two moving bodies that another row of theirs at the same place pushed back
    against (opposed_row): where a box's bottom edge crosses the lower box's top edge,
    two rows along the boxes' side normals (7° apart, about opposite ways) were carried
    for good, each undoing the other, and kept the boxes' block (solve_blocks) from ever
    converging. Within a soft body, carrying its rows took soft-coil's deepest crossing of
    itself from 0.78 to 0.53 mm and the pairs crossing at rest from ~200 to ~100. Between two
    cloths, it stopped the upper sheet's vertices over the box's corners in two-cloths-on-box
    from chattering at 0.1-0.3 m/s with a period of two substeps. (Rows between a soft and a
    rigid or static body are not kept: kept, the cloths went 7-18 mm into the spike and box.)
    A row between cloth triangles is kept while it lies within SLACK_GAPS gaps beyond
    their gap, pushed or not: kept only while it pushed, a fold of one sheet lying in
    a fold of the other lost its rows whenever it drifted to the gap's edge, found them again
    40-60 µm late and was pushed back, wall to wall every 13 substeps (two-cloths-on-box
    never settled)."""
    count = 0
    for k in range(n):
        tri = rows.tri[k]
        if (rows.lambda_n[k] > 0.0 or within_slack(sim, rows, k)) \
                and (both_soft(sim, tri[0], tri[1]) or not involves_soft(sim, tri[0], tri[1])) \
                and count < sim.carry_capacity:
            normal = rows.normal[k]
            gap = (anchor_world(sim, tri[1], rows.bary_other[k], False)
                   - anchor_world(sim, tri[0], rows.bary_moved[k], False))
            keep = (gap - gap.dot(normal) * normal).norm() <= slip_max
            if ti.static(sim.rules.opposed_rows):
                if keep:
                    keep = not opposed_row(sim, rows, k, slip_max)
            if keep:
                sim.carry_tri[count] = ivec2(tri[0], tri[1])
                sim.carry_bary_moved[count] = rows.bary_moved[k]
                sim.carry_bary_other[count] = rows.bary_other[k]
                sim.carry_normal[count] = normal
                count += 1
    sim.carry_count[0] = count


@ti.func
def within_slack(sim: ti.template(), rows: ti.template(), k: ti.i32) -> bool:
    """Whether row k ties two cloth triangles, which keep a gap g (contact.cloth.pair_gap),
    and its anchors, N·(p_other − p_moved) apart (−g when they lie exactly at the gap), are
    less than SLACK_GAPS·g beyond it. (A closed soft body's own walls are left out:
    soft-coil, its rows carried so, jerked a vertex at 2-5 mm/s every ~0.16 s and did not
    settle in its 3 s.)"""
    out = False
    if ti.static(sim.model.has_cloth):
        tri = rows.tri[k]
        if is_cloth(sim, tri[0]) and is_cloth(sim, tri[1]):
            g = pair_gap(sim, tri[0], tri[1])
            separation = rows.normal[k].dot(anchor_world(sim, tri[1], rows.bary_other[k], False)
                                            - anchor_world(sim, tri[0], rows.bary_moved[k], False))
            out = separation + g > -ti.static(SLACK_GAPS) * g
    return out


@ti.func
def both_soft(sim: ti.template(), t_a: ti.i32, t_b: ti.i32) -> bool:
    """Whether triangles t_a and t_b both belong to soft bodies."""
    return (sim.model.body_kind[sim.model.tri_body[t_a]] == SOFT
            and sim.model.body_kind[sim.model.tri_body[t_b]] == SOFT)


@ti.func
def opposed_row(sim: ti.template(), rows: ti.template(), k: ti.i32, reach: float) -> bool:
    """Whether another row of this substep between the same two moving bodies pushed
    (λ_n > 0) about the opposite way (the pushes' directions on one body at more than
    OPPOSED_DEGREES from opposite) with its moved anchor within `reach` (m) of row k's."""
    tri = rows.tri[k]
    body_m, body_o = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
    found = False
    if sim.model.body_kind[body_m] != STATIC and sim.model.body_kind[body_o] != STATIC:
        point = anchor_world(sim, tri[0], rows.bary_moved[k], False)
        cos_opposed = ti.static(np.cos(np.radians(OPPOSED_DEGREES)))
        for side in ti.static(range(2)):
            body, other = (body_m, body_o) if side == 0 else (body_o, body_m)
            j = sim.body_last_row[body]
            while j >= 0 and not found:
                tri_j = rows.tri[j]
                if j != k and sim.model.tri_body[tri_j[1]] == other and rows.lambda_n[j] > 0.0:
                    # Row j moves `body` along its normal; row k moves body_m along its own.
                    push_j = ti.select(body == body_m, 1.0, -1.0) * rows.normal[j]
                    if push_j.dot(rows.normal[k]) <= -cos_opposed:
                        p = anchor_world(sim, tri_j[0], rows.bary_moved[j], False)
                        found = (p - point).norm() <= reach
                j = tri_j[2]
    return found


@ti.func
def carried_rows(sim: ti.template(), rows: ti.template(), total: ti.i32, max_push: float) -> ti.i32:
    """The rows keep_rows remembered from the last substep whose triangle pair has no row
    now, on the same anchors and normal. A body between two supports (a spike lying
    along a groove, on both rims) is pushed off one, into the other, within one
    projection; without the other's row, which detection made before the push, it ends
    the substep inside that one and the next substep pushes it back, a cycle that never
    comes to rest. Such a row holds C = N·(p_other − p_moved) ≥ 0 and does nothing
    unless it is crossed. Between two rigid bodies it holds C where the last substep left it
    (C less this substep's approach, if that is smaller; 0 at least): it keeps the support
    from closing in and leaves older depth to the rows detected now. Pushing that depth out
    as well, rows carried from where a box's corner had landed in the box below pushed it
    sideways with up to five times its weight a substep: the top box of a three-box stack
    came to rest 60 µm sideways of its place (8 µm with the hold). A pair of which neither body is moving (static
    or asleep) is not offered. Rows go after row total-1 while they fit; returns the row
    count."""
    n_rows = total
    for j in range(sim.carry_count[0]):
        pair = sim.carry_tri[j]
        moving = is_moving(sim, sim.model.tri_body[pair[0]]) or is_moving(sim, sim.model.tri_body[pair[1]])
        if n_rows < rows.tri.shape[0] and moving and not has_pair_row(sim, rows, pair[0], pair[1]):
            bm, bo, normal = sim.carry_bary_moved[j], sim.carry_bary_other[j], sim.carry_normal[j]
            p_m = anchor_world(sim, pair[0], bm, False)
            p_o = anchor_world(sim, pair[1], bo, False)
            approach = start_row(sim, rows, n_rows, pair[0], pair[1], bm, bo, normal, p_m, p_o, max_push)
            if ti.static(sim.rules.carried_hold):
                if both_rigid(sim, pair[0], pair[1]):
                    rows.hold[n_rows] = ti.max(normal.dot(p_o - p_m) - ti.max(approach, 0.0), 0.0)
            if involves_soft(sim, pair[0], pair[1]):
                # A soft row's budget is the depth it may leave (less the pair's gap).
                rows.budget[n_rows] = 0.0 - pair_gap(sim, pair[0], pair[1])
            n_rows += 1
    return n_rows
