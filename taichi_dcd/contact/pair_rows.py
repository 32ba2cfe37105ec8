"""The row of one triangle pair: the narrow phase's result turned into a contact row by the rules
of this package (touching pairs, nearest exit, held surface points, edge-edge normals, touching
rows, duplicates), and the serial narrow phase over the all-pairs candidates."""

import taichi as ti

from ..collision.narrowphase import collide_triangle_pair
from ..core.model import SOFT, STATIC
from .cloth import pair_vertices
from .anchors import approach, involves_soft, longest_edge, target_inside
from .exits import edge_edge_normal, nearest_exit
from .rows import forget_rows, is_duplicate, write_contact
from .touching import next_vertex_over_face, touching_pair_contact

vec3 = ti.math.vec3
ivec2 = ti.types.vector(2, ti.i32)

# A contact row against a static body no deeper than this fraction of its moved triangle's
# longest edge only touches (add_pair_contact): well above f64's rounding, well below a
# substep's sink under gravity; below f32's rounding, where it changes nothing.
TOUCHING_DEPTH = 1e-8

# A row between two moving bodies within the substep's allowance may leave through a convex
# neighbour's face (exit_of_moving_row) when less than this fraction of its depth closed in
# during this substep: its depth is older than the motion that made it.
MOVING_EXIT_APPROACH_FRACTION = 0.5

# A resting row against a static body whose point lies on the other body's surface is not made
# when its approach this substep is below this fraction of its depth (add_pair_contact).
SURFACE_APPROACH_FRACTION = 0.01


@ti.func
def collide_candidates(sim: ti.template(), rows: ti.template(), n_candidates: ti.i32, max_push: float) -> ti.i32:
    """The unified narrow phase on the candidate pairs in rows.tri, compacted in place into
    contact rows (serial: row n <= candidate k is written after k is read); returns the count."""
    forget_rows(sim)
    n = 0
    for k in range(n_candidates):
        ab = ivec2(rows.tri[k][0], rows.tri[k][1])
        a0, a1, a2, b0, b1, b2 = pair_vertices(sim, ab[0], ab[1])
        hit, depth, normal, side, point = collide_triangle_pair(a0, a1, a2, b0, b1, b2)
        n = add_pair_contact(sim, rows, n, ab, side, depth, normal, point, max_push)
    return n


@ti.func
def exit_of_deep_row(sim: ti.template(), t_m: ti.i32, t_o: ti.i32, point: vec3, depth: float, normal: vec3,
                     max_push: float, both_moving: bool):
    """Rules `nearest_exit` and `surface_points` for a row deeper than the substep's allowance
    between rigid or static bodies: it leaves through the nearest convex neighbour's face
    (contact.exits.nearest_exit), and a grazing row whose point is on that neighbour's plane is
    held there at depth 0. Grazing: a depth this substep's motion cannot have made, to a target
    outside the moved body (against a static body: no deeper than the allowance behind the
    moved face). Prevents (surface points): a box resting on a free box turned 7° from it sinks
    ~1e-5 m a substep, its side faces cross the lower box's side faces in strips that high near
    its top corners, Eq. 6 measured those pairs from a corner of one box pushed onto the other's
    side plane (0.03-0.24 m sideways), and the sideways pushes kept the upper box jittering at
    0.01-0.1 m/s. Against a static body alike: a box on a block whose side plane it shares (set
    1e-12 m off its footprint, or 0.3 m along one side) had a row from the block's side face,
    its point on the box's bottom edge, 0.7 m deep along the box's end face, and was thrown
    1-4 cm; a box turned by 5e-12 rad put that row's target 3.5e-12 m behind the block's face,
    hence the allowance. A wedge's rows at a crack's rim look alike but reach a rim inside the
    wedge: they keep their depth (held at depth 0 without the target test, the wedge ended 1 mm
    inside the crack block; dropped, 8 mm). Returns (other triangle, depth, normal, held)."""
    on_surface = False
    if ti.static(sim.rules.nearest_exit or sim.rules.surface_points):
        may_hold = False
        if ti.static(sim.rules.surface_points):
            # (Nested: Taichi evaluates both sides of `and`.)
            if depth > max_push + approach(sim, t_m, t_o, point, depth, normal):
                margin = ti.select(both_moving, 0.0, max_push)
                may_hold = not target_inside(sim, t_m, point + depth * normal, margin)
        # Against a static body a point behind another neighbour's plane leaves through it: at a
        # box's bottom edge on a block of its footprint the point lies in the end face's plane and
        # the substep's sink below the bottom, and that sink is its depth. (Between moving bodies
        # the held point comes first: leaving, a stack of five turned boxes crept at 2 mm/s.)
        t_exit, d_exit, n_exit, on_surface = nearest_exit(sim, t_o, point, depth, normal, may_hold,
                                                          not both_moving)
        if ti.static(sim.rules.nearest_exit):
            t_o, depth, normal = t_exit, d_exit, n_exit
        elif on_surface:
            t_o, depth, normal = t_exit, d_exit, n_exit
    return t_o, depth, normal, on_surface


@ti.func
def exit_of_moving_row(sim: ti.template(), t_m: ti.i32, t_o: ti.i32, point: vec3, depth: float, normal: vec3,
                       both_moving: bool):
    """Rule `moving_exit`: a row between two moving rigid bodies within the substep's allowance,
    less than MOVING_EXIT_APPROACH_FRACTION of whose depth closed in during this substep, leaves
    through the other triangle's nearest convex neighbour as a deeper row does
    (contact.exits.nearest_exit: its point nearer that face's plane than NEAREST_EXIT_FRACTION
    of its depth). Where boxes of one footprint stand on each other and the upper one has
    shifted a little, its bottom face crosses the lower box's side face just under the top edge;
    Eq. 6 then measures how far the point lies in past that side (the shift, up to 44 µm), not
    the 1e-7 m it is below the top, and the row pushed the box sideways every substep: the
    ten-box stack's boxes rested up to 0.19 mm off their places and the pyramid 2.2e-9 m³ into
    itself (now 8.8e-5 m and 3.0e-10 m³). A row whose depth this substep made keeps its face:
    re-aimed too, the corner rows of a landing box turned to the lower box's side faces wherever
    its edge lay a hair inside them, and a two-box stack landed 47 µm sideways. (Against a static
    body every row within the allowance keeps its face: re-aimed, a spike leaning on a block's
    edge jittered.) Returns (other triangle, depth, normal)."""
    if ti.static(sim.rules.moving_exit):
        if both_moving:
            if approach(sim, t_m, t_o, point, depth, normal) < MOVING_EXIT_APPROACH_FRACTION * depth:
                t_o, depth, normal, _ = nearest_exit(sim, t_o, point, depth, normal, False, False)
    return t_o, depth, normal


@ti.func
def resting_row_approached(sim: ti.template(), t_m: ti.i32, t_o: ti.i32, point: vec3, depth: float,
                           normal: vec3, both_moving: bool) -> bool:
    """Rule `surface_points` for a row within the substep's allowance: a resting row against a
    static body whose point lies on the other body's surface (on a convex neighbour's plane:
    nearest_exit) and has not moved along the row's normal this substep (approach below
    SURFACE_APPROACH_FRACTION of the depth) is no penetration: its depth is measured across the
    surface, not along the way the point came. Returns whether to keep the row. Prevents: a box
    set on a block of its own footprint sinks ~7 µm a substep into the block's top; where its
    bottom edges meet the block's vertical edges, pairs of its side faces with the block's
    side faces measured those 7 µm sideways, and pushed the box 0.1 mm sideways and tilted it.
    (Dropped whenever the approach made less than half the depth, rows of the pile's loaded
    bodies went too, and it ended 1 mm deep; between moving bodies, where held rows do this, a
    stack of five boxes crept at 3e-4 m/s instead of 3e-5.)"""
    keep = True
    if ti.static(sim.rules.surface_points):
        if not both_moving:
            t_exit, d_exit, n_exit, on_other = nearest_exit(sim, t_o, point, depth, normal, True, False)
            if on_other:
                keep = approach(sim, t_m, t_o, point, depth, normal) >= SURFACE_APPROACH_FRACTION * depth
    return keep


@ti.func
def only_touches(sim: ti.template(), t_m: ti.i32, depth: float, both_moving: bool) -> bool:
    """Rule `touching_rows`: a row against a static body no deeper than TOUCHING_DEPTH of its
    moved triangle's longest edge only touches; like a duplicate it gives way to a vertex of its
    triangle behind the other's face (next_vertex_over_face). Prevents: at coincident edges (a
    box's vertical edges on a block's of the same footprint) the rows at points along the edges
    came in pairs pushing opposite ways, whose multipliers grew to 7 times the box's weight per
    substep and let go at once 45 ms later (a 0.1 mm jump); at the vertices they stay below a
    third of it."""
    touching = False
    if ti.static(sim.rules.touching_rows):
        if not both_moving:
            touching = depth <= TOUCHING_DEPTH * longest_edge(sim, t_m)
    return touching


@ti.func
def add_pair_contact(sim: ti.template(), rows: ti.template(), n: ti.i32, ab: ivec2, side: ti.i32, depth: float,
                     normal: vec3, point: vec3, max_push: float) -> ti.i32:
    """Row n from the narrow phase's result for the pair ab (side, depth, normal, point as
    collide_triangle_pair returns them), or where that has no constraint from the touching
    test; nothing if the row would repeat an earlier one. The rules in the order they apply:
    touching_pairs, edge_edge_normal for a deep edge crossing (which then seeks no exit),
    nearest_exit and surface_points (a row between rigid or static bodies deeper than the
    allowance; within it, its own face is the exit but between two moving bodies:
    moving_exit), edge_edge_normal,
    touching_rows, duplicates, next_vertex. Returns the row count."""
    t_m, t_o = ab[0], ab[1]
    if side == 1:
        t_m, t_o = ab[1], ab[0]
    if ti.static(sim.rules.touching_pairs or sim.rules.pressed_through):
        if side < 0:
            found, t_m, t_o, depth, normal, point = touching_pair_contact(sim, ab[0], ab[1])
            side = ti.select(found, 0, -1)
    n_rows = n
    on_surface = False
    keep = side >= 0
    touching = False
    if side >= 0:
        if not involves_soft(sim, t_m, t_o):
            both_moving = (sim.model.body_kind[sim.model.tri_body[t_m]] != STATIC
                           and sim.model.body_kind[sim.model.tri_body[t_o]] != STATIC)
            crossing = False
            if ti.static(sim.rules.edge_edge_normal):
                # A deep edge crossing whose target lies inside the moved body (not a grazing
                # row: surface_points) and whose edges lie farther apart than the allowance
                # (an interlock: at a graze, the slabs leaning on a chip slid 0.18 mm) pushes
                # along the edges' common normal before any exit is sought: its point is where
                # one edge enters the other body, on a neighbour face's plane, and nearest_exit
                # would re-aim it there at depth ~0. Prevents:
                # two boxes of pile-1000 with edges crossed 1.35 cm deep, no vertex of either
                # inside the other, were held so and sank ~1 mm a second into each other.
                if depth > max_push and target_inside(sim, t_m, point + depth * normal,
                                                      ti.select(both_moving, 0.0, max_push)):
                    depth_ee, normal_ee = edge_edge_normal(sim, t_m, t_o, point, depth, normal, False, max_push)
                    if (normal_ee - normal).norm_sqr() > 0.0 and depth_ee > max_push:
                        crossing = True
                        depth, normal = depth_ee, normal_ee
            if crossing:
                pass
            elif depth > max_push:
                t_o, depth, normal, on_surface = exit_of_deep_row(sim, t_m, t_o, point, depth, normal, max_push,
                                                                  both_moving)
            else:
                keep = resting_row_approached(sim, t_m, t_o, point, depth, normal, both_moving)
                t_o, depth, normal = exit_of_moving_row(sim, t_m, t_o, point, depth, normal, both_moving)
            if ti.static(sim.rules.edge_edge_normal):
                # A row deeper than the allowance that is no deep crossing takes the edge-edge
                # normal only where the two edges pass through each other (exits.edges_interlock).
                # Prevents: a wedge lying on the ground with its ridge on a standing wedge's
                # slanted face at its end cap; a row from the cap's bottom edge to the ridge,
                # 1.1 m deep (two skew edges 1.1 m apart outside both bodies), turned 2.5°
                # toward the standing wedge by their common normal pushed the lying wedge
                # 1.6 cm into it (`wedges` at 12 substeps × 4 sweeps). Asked of the deep
                # crossings too, it refused a spike's edge passing its apex into a wedge
                # beside the ridge, whose rows then left through a neighbour face (the spike
                # landed 2.8 mm deep).
                depth, normal = edge_edge_normal(sim, t_m, t_o, point, depth, normal,
                                                 not crossing and depth > max_push, max_push)
            touching = only_touches(sim, t_m, depth, both_moving)
        elif ti.static(sim.rules.nearest_exit):
            # A soft triangle deeper than the allowance in a rigid or static face leaves through
            # that face's nearest convex neighbour too (held points are for rigid bodies only).
            # Prevents: a cloth triangle lying over a box's top corner measured 5.6 cm deep from
            # a side face, and its row pushed the sheet sideways a budget's worth each substep.
            if depth > max_push and sim.model.body_kind[sim.model.tri_body[t_o]] != SOFT:
                t_o, depth, normal, _ = nearest_exit(sim, t_o, point, depth, normal, False, False)
    if keep:
        # (Not `or`: Taichi would walk the row chain for a touching row too.)
        duplicate = touching
        if not touching:
            duplicate = is_duplicate(sim, rows, n, t_m, t_o, normal, point)
        if duplicate:
            # Rule `next_vertex`: the deepest point is a vertex another pair already made a row
            # of (or the row only touches); another candidate vertex of this triangle takes the
            # row instead. Prevents: without a row here, add_vertex_contacts would never visit
            # this triangle, and a vertex all of whose triangles lost their rows so would sink
            # unopposed (seen: one vertex of a soft cube's bottom face, held 8 µm deep).
            if ti.static(sim.rules.next_vertex):
                depth, point = next_vertex_over_face(sim, rows, n, t_m, t_o, normal, depth)
                duplicate = depth <= 0.0
        if not duplicate:
            write_contact(sim, rows, n, t_m, t_o, depth, normal, point, max_push)
            if on_surface:
                # Its depth is 0 by construction: whatever it corrects, the solve made, so it
                # has no budget to spend. With the usual one, rows of other pairs pushed a
                # pile's wedge into its neighbour once the held rows had spent it (probed:
                # 7.6-8.2e-4 m deep, nothing left to correct), and the two sank 0.9 mm into
                # each other by 7 s.
                rows.budget[n] = ti.math.inf
            n_rows += 1
    return n_rows
