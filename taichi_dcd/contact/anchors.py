"""Anchors: points tied to a triangle by barycentric weights, on a soft body's particles or
a rigid body's pose. Where such a point is, how fast it moves, its generalised inverse mass
along a direction, and how an impulse there moves its body; every contact row is a pair of
anchors. Each function takes `sim`, the solver's fields (solver.fields.SolverFields); a
scene without soft bodies compiles none of their branches (`model.has_soft`)."""

import taichi as ti

from ..core import runtime
from ..core.geometry import barycentric, longest_edge_sq
from ..core.model import RIGID, SOFT
from ..core.rigid import (
    apply_positional_impulse,
    apply_velocity_impulse,
    generalized_inv_mass,
    quat_rotate,
)

vec3 = ti.math.vec3


@ti.func
def anchor_world(sim: ti.template(), t: ti.i32, bary: vec3, prev: ti.template()) -> vec3:
    """World position of the point with barycentric weights `bary` on triangle t,
    now or (prev=True) at the start of the substep."""
    b = sim.model.tri_body[t]
    idx = sim.model.tri_indices[t]
    p = vec3(0.0)
    if sim.model.body_kind[b] == SOFT:
        if ti.static(sim.model.has_soft):
            for k in ti.static(range(3)):
                if ti.static(prev):
                    p += bary[k] * sim.state.vertex_x_prev[idx[k]]
                else:
                    p += bary[k] * sim.state.vertex_x[idx[k]]
    else:
        r = bary[0] * sim.model.vertex_local[idx[0]] + bary[1] * sim.model.vertex_local[idx[1]] + bary[2] * sim.model.vertex_local[idx[2]]
        if ti.static(prev):
            p = sim.state.body_x_prev[b] + quat_rotate(sim.state.body_q_prev[b], r)
        else:
            p = sim.state.body_x[b] + quat_rotate(sim.state.body_q[b], r)
    return p


@ti.func
def anchor_velocity(sim: ti.template(), t: ti.i32, bary: vec3, p: vec3) -> vec3:
    """Velocity of the anchored point p of triangle t (m/s)."""
    b = sim.model.tri_body[t]
    idx = sim.model.tri_indices[t]
    v = vec3(0.0)
    kind = sim.model.body_kind[b]
    if kind == SOFT:
        if ti.static(sim.model.has_soft):
            for k in ti.static(range(3)):
                v += bary[k] * sim.state.vertex_v[idx[k]]
    elif kind == RIGID:
        v = sim.state.body_v[b] + sim.state.body_w[b].cross(p - sim.state.body_x[b])
    return v


@ti.func
def anchor_inv_mass(sim: ti.template(), t: ti.i32, bary: vec3, p: vec3, n: vec3) -> float:
    """Generalised inverse mass of triangle t's anchored point p along unit n:
    Σ b_k² w_k for a soft triangle, 1/m + (r×n)ᵀI_w⁻¹(r×n) for a rigid body, 0 if static."""
    b = sim.model.tri_body[t]
    idx = sim.model.tri_indices[t]
    w = 0.0
    kind = sim.model.body_kind[b]
    if kind == SOFT:
        if ti.static(sim.model.has_soft):
            for k in ti.static(range(3)):
                w += bary[k] * bary[k] * sim.model.vertex_inv_mass[idx[k]]
    elif kind == RIGID:
        w = generalized_inv_mass(sim.model.body_inv_mass[b], sim.state.body_q[b],
                                 sim.model.body_inv_inertia[b], p - sim.state.body_x[b], n)
    return w


@ti.func
def anchor_move(sim: ti.template(), t: ti.i32, bary: vec3, p: vec3, impulse: vec3):
    """Apply a positional impulse (kg·m) at triangle t's anchored point p."""
    b = sim.model.tri_body[t]
    idx = sim.model.tri_indices[t]
    kind = sim.model.body_kind[b]
    if kind == SOFT:
        if ti.static(sim.model.has_soft):
            for k in ti.static(range(3)):
                sim.state.vertex_x[idx[k]] += sim.model.vertex_inv_mass[idx[k]] * bary[k] * impulse
    elif kind == RIGID:
        # The lever from the substep's starting centre: with the body's end velocity
        # (x − x_prev)/h, that is what keeps angular momentum about any point exact.
        sim.state.body_x[b], sim.body_theta[b], sim.state.body_q[b] = apply_positional_impulse(
            sim.state.body_x[b], sim.body_theta[b], sim.state.body_q_prev[b], sim.model.body_inv_mass[b],
            sim.model.body_inv_inertia[b], p - sim.state.body_x_prev[b], impulse)


@ti.func
def anchor_kick(sim: ti.template(), t: ti.i32, bary: vec3, p: vec3, impulse: vec3):
    """Apply a velocity impulse (kg·m/s) at triangle t's anchored point p."""
    b = sim.model.tri_body[t]
    idx = sim.model.tri_indices[t]
    kind = sim.model.body_kind[b]
    if kind == SOFT:
        if ti.static(sim.model.has_soft):
            for k in ti.static(range(3)):
                sim.state.vertex_v[idx[k]] += sim.model.vertex_inv_mass[idx[k]] * bary[k] * impulse
    elif kind == RIGID:
        sim.state.body_v[b], sim.state.body_w[b] = apply_velocity_impulse(
            sim.state.body_v[b], sim.state.body_w[b], sim.state.body_q[b], sim.model.body_inv_mass[b],
            sim.model.body_inv_inertia[b], p - sim.state.body_x[b], impulse)


@ti.func
def closing(sim: ti.template(), t_moved: ti.i32, t_other: ti.i32, bary_m: vec3, bary_o: vec3, normal: vec3,
            p_moved: vec3,
            p_other: vec3) -> float:
    """How much N·(p_other − p_moved) grew during this substep (m), for anchors bary_m on
    t_moved (now at p_moved) and bary_o on t_other (now at p_other)."""
    return normal.dot((p_other - anchor_world(sim, t_other, bary_o, True))
                      - (p_moved - anchor_world(sim, t_moved, bary_m, True)))


@ti.func
def approach(sim: ti.template(), t_moved: ti.i32, t_other: ti.i32, point: vec3, depth: float, normal: vec3) -> float:
    """How much a row from `point` on t_moved to point + depth·normal on t_other closed
    along the normal during this substep (m; start_row's approach)."""
    im, io = sim.model.tri_indices[t_moved], sim.model.tri_indices[t_other]
    target = point + depth * normal
    bary_m = barycentric(point, sim.state.vertex_x[im[0]], sim.state.vertex_x[im[1]], sim.state.vertex_x[im[2]])
    bary_o = barycentric(target, sim.state.vertex_x[io[0]], sim.state.vertex_x[io[1]],
                         sim.state.vertex_x[io[2]])
    return closing(sim, t_moved, t_other, bary_m, bary_o, normal, point, target)


@ti.func
def longest_edge(sim: ti.template(), t: ti.i32) -> float:
    """Length of triangle t's longest edge (m)."""
    idx = sim.model.tri_indices[t]
    return ti.sqrt(longest_edge_sq(sim.state.vertex_x[idx[0]], sim.state.vertex_x[idx[1]],
                                   sim.state.vertex_x[idx[2]]))


@ti.func
def target_inside(sim: ti.template(), t_moved: ti.i32, target: vec3, margin: float) -> bool:
    """Whether `target` lies behind t_moved's plane by more than `margin` (m) and rounding."""
    tol = ti.static(runtime.tolerance())
    im = sim.model.tri_indices[t_moved]
    m0, m1, m2 = sim.state.vertex_x[im[0]], sim.state.vertex_x[im[1]], sim.state.vertex_x[im[2]]
    raw = (m1 - m0).cross(m2 - m0)
    length = raw.norm()
    return length > 0.0 and raw.dot(m0 - target) > ti.max(tol * ti.sqrt(longest_edge_sq(m0, m1, m2)), margin) * length


@ti.func
def involves_soft(sim: ti.template(), t_a: ti.i32, t_b: ti.i32) -> bool:
    soft = False
    if ti.static(sim.model.has_soft):
        soft = (sim.model.body_kind[sim.model.tri_body[t_a]] == SOFT
                or sim.model.body_kind[sim.model.tri_body[t_b]] == SOFT)
    return soft
