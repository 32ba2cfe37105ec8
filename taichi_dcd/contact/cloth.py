"""Cloth and self-touching soft bodies in the contact rules: a triangle pair's vertices with
each cloth triangle turned to face the other (collision.two_sided), for the narrow phase and
the rules that read faces, and the gap two sheets, or a closed soft body's own walls, keep."""

import taichi as ti

from ..collision.two_sided import faced_pair, moved_together
from ..core.model import SOFT

vec3 = ti.math.vec3

# Two cloth triangles (two sheets, or one sheet folded) keep this fraction of their sheets'
# mesh spacing between them: the unified test sees only triangles that cross, and sheets of no
# thickness resting on each other come to lie in one plane, where any wrinkle crosses them.
# The pair is tested with each triangle moved half the gap towards the other, and its row
# holds the gap (write_contact).
CLOTH_GAP_FRACTION = 0.02

# The walls of one closed soft body with self_collision keep this fraction of its mesh's
# spacing between them, for the same reason: without a gap, turns of a coil pressed onto each
# other rest where their facets cross in edge-against-edge strips that no row holds (70-130
# pairs, 0.5 mm deep, at rest).
SELF_GAP_FRACTION = 0.02


@ti.func
def is_cloth(sim: ti.template(), t: ti.i32) -> bool:
    """Whether triangle t belongs to a cloth (always False where no body is one)."""
    out = False
    if ti.static(sim.model.has_cloth):
        b = sim.model.tri_body[t]
        out = sim.model.body_kind[b] == SOFT and sim.model.body_cloth[b] != 0
    return out


@ti.func
def self_gap(sim: ti.template(), t_a: ti.i32, t_b: ti.i32) -> float:
    """The gap (m) two triangles of one closed soft body keep (its self_gap), else 0."""
    gap = 0.0
    if ti.static(sim.model.has_self_gap):
        b = sim.model.tri_body[t_a]
        if sim.model.tri_body[t_b] == b:
            gap = sim.body_self_gap[b]
    return gap


@ti.func
def pair_gap(sim: ti.template(), t_a: ti.i32, t_b: ti.i32) -> float:
    """The gap (m) triangles t_a and t_b keep: CLOTH_GAP_FRACTION of their sheets' mean
    spacing when both are cloth, a closed soft body's self_gap when both are its own, else 0."""
    gap = 0.0
    if ti.static(sim.model.has_cloth):
        if is_cloth(sim, t_a) and is_cloth(sim, t_b):
            gap = ti.static(CLOTH_GAP_FRACTION) * 0.5 * (sim.body_thickness[sim.model.tri_body[t_a]]
                                                         + sim.body_thickness[sim.model.tri_body[t_b]])
    if ti.static(sim.model.has_self_gap):
        gap += self_gap(sim, t_a, t_b)
    return gap


@ti.func
def pair_vertices(sim: ti.template(), t_a: ti.i32, t_b: ti.i32):
    """The current vertices (a0, a1, a2, b0, b1, b2) of triangles t_a and t_b, a cloth
    triangle turned to face the other, two cloth triangles, or two of one closed soft body,
    moved together by their gap (collision.two_sided.faced_pair, moved_together)."""
    ia, ib = sim.model.tri_indices[t_a], sim.model.tri_indices[t_b]
    a0, a1, a2 = sim.state.vertex_x[ia[0]], sim.state.vertex_x[ia[1]], sim.state.vertex_x[ia[2]]
    b0, b1, b2 = sim.state.vertex_x[ib[0]], sim.state.vertex_x[ib[1]], sim.state.vertex_x[ib[2]]
    if ti.static(sim.model.has_cloth):
        cloth_a, cloth_b = is_cloth(sim, t_a), is_cloth(sim, t_b)
        if cloth_a or cloth_b:
            a0, a1, a2, b0, b1, b2 = faced_pair(
                a0, a1, a2, b0, b1, b2,
                sim.state.vertex_x_prev[ia[0]], sim.state.vertex_x_prev[ia[1]], sim.state.vertex_x_prev[ia[2]],
                sim.state.vertex_x_prev[ib[0]], sim.state.vertex_x_prev[ib[1]], sim.state.vertex_x_prev[ib[2]],
                cloth_a, cloth_b, pair_gap(sim, t_a, t_b))
    if ti.static(sim.model.has_self_gap):
        gap = self_gap(sim, t_a, t_b)
        if gap > 0.0:
            a0, a1, a2, b0, b1, b2 = moved_together(a0, a1, a2, b0, b1, b2, gap)
    return a0, a1, a2, b0, b1, b2


@ti.func
def facing_against(sim: ti.template(), t: ti.i32, n: vec3, other_normal: vec3) -> vec3:
    """Unit normal n of triangle t, reversed if t is a cloth triangle facing along
    `other_normal` (the one-sided face it meets): a cloth faces what it touches."""
    out = n
    if ti.static(sim.model.has_cloth):
        if is_cloth(sim, t) and n.dot(other_normal) > 0.0:
            out = -n
    return out
