"""One block row projected on its bodies' motions linearised at the sweep's start (the
islands' sweeps, solver.islands): which block a row belongs to, the inverse mass at its anchor,
and the impulse its normal and friction add."""

import taichi as ti

from ..contact.rows import both_rigid
from ..core.model import RIGID, STATIC
from ..core.rigid import inv_mass_matrix_world
from .contact_solve import friction_in_cone, takes_part

vec3 = ti.math.vec3


@ti.func
def block_body(sim: ti.template(), rows: ti.template(), k: ti.i32) -> ti.i32:
    """The rigid body of row k when its other side is static (the row is solved in that
    body's block), else -1."""
    tri = rows.tri[k]
    b_m, b_o = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
    kind_m, kind_o = sim.model.body_kind[b_m], sim.model.body_kind[b_o]
    body = -1
    if kind_m == RIGID and kind_o == STATIC:
        body = b_m
    elif kind_m == STATIC and kind_o == RIGID:
        body = b_o
    return body


@ti.func
def pair_block(sim: ti.template(), rows: ti.template(), k: ti.i32) -> bool:
    """Whether row k is between two rigid bodies (solved in the coupled block)."""
    return both_rigid(sim, rows.tri[k][0], rows.tri[k][1])


@ti.func
def pair_inv_mass(sim: ti.template(), body_m: ti.i32, body_o: ti.i32, r_m: vec3, r_o: vec3, f_m: float,
                  f_o: float):
    """K = f_m·K_m + f_o·K_o: the 3×3 inverse mass at levers r_m, r_o (m) of two rigid bodies
    that move with shares f_m, f_o (rigid.inv_mass_matrix_world)."""
    return (f_m * inv_mass_matrix_world(sim.model.body_inv_mass[body_m], sim.block_inv_inertia[body_m], r_m)
            + f_o * inv_mass_matrix_world(sim.model.body_inv_mass[body_o], sim.block_inv_inertia[body_o], r_o))


@ti.func
def project_block_row(sim: ti.template(), rows: ti.template(), k: ti.i32, friction: bool, d: vec3,
                      leave: bool, k_mat) -> vec3:
    """The positional impulse P (kg·m, on the moved side) that row k adds in one block
    sweep, its moved anchor displaced by d (m) relative to the other since the
    linearisation: gap g = g0 − N·d, tangential slip s = s0 + d_t, K = k_mat (3×3 inverse
    mass at the anchor of the bodies that move: rows.block_k[k] but in islands.support_pass). The
    normal pushes c = min(g, budget) when c > 0 or while it holds λ_n > 0, spending the
    budget; with `leave` (leaves_depth) the budget is the depth the row may leave and
    c = g − budget, spending nothing. Friction then cancels the
    slip left, |λ_t| ≤ μ·λ_n (Müller 2020, Eq. 26-27; μ = rows.block_mu[k]). Updates λ_n, λ_t
    and the budget. Returns (P, K·P): K·P is how far P moves the anchor, which the caller
    needs too (computed once: a row's projection is the islands' inner loop); both 0 for a row
    that does nothing."""
    impulse = vec3(0.0)
    k_impulse = vec3(0.0)
    n = rows.normal[k]
    slip = rows.block_slip[k] + d - d.dot(n) * n
    gap = rows.block_gap[k] - n.dot(d)
    c = ti.max(ti.select(leave, gap - rows.budget[k], ti.min(gap - rows.hold[k], rows.budget[k])), 0.0)
    lam_n = rows.lambda_n[k]
    w = n.dot(k_mat @ n)
    if (c > 0.0 or lam_n > 0.0) and w > 0.0:
        push = c / w
        moved = k_mat @ (push * n)
        slip_left = slip + (moved - moved.dot(n) * n)
        lam_n += push
        old_t = rows.lambda_t[k]
        new_t = old_t
        length = slip_left.norm()
        if friction and length > 0.0:
            t = slip_left / length
            new_t = friction_in_cone(old_t + (length / t.dot(k_mat @ t)) * t,
                                     rows.block_mu[k] * lam_n)
        impulse = push * n - (new_t - old_t)
        rows.lambda_n[k] = lam_n
        rows.lambda_t[k] = new_t
        k_impulse = k_mat @ impulse
        if not leave:
            rows.budget[k] = rows.budget[k] - n.dot(k_impulse)
    return impulse, k_impulse


@ti.func
def solve_pair_row(sim: ti.template(), rows: ti.template(), k: ti.i32, friction: bool, leave: bool) -> float:
    """Row k between two rigid bodies projected on both bodies' linearised motions, as
    solve_block_row does against a static body: d = (Δx_m + Δθ_m × r_m) − (Δx_o + Δθ_o × r_o),
    gap g = g0 − N·d, slip s = s0 + d_t, K = f_m·K_m + f_o·K_o (f: takes_part). Returns how
    far the row moved its anchors apart (m)."""
    tri = rows.tri[k]
    return project_pair_row(sim, rows, k, friction, leave, takes_part(sim, tri[0], tri[1]),
                            takes_part(sim, tri[1], tri[0]), rows.block_k[k])


@ti.func
def project_pair_row(sim: ti.template(), rows: ti.template(), k: ti.i32, friction: bool, leave: bool, f_m: float,
                     f_o: float, k_mat) -> float:
    """solve_pair_row with the two bodies' shares f_m, f_o of the impulse (1 moves, 0 holds
    still) and K = k_mat their summed inverse mass at the anchor."""
    tri = rows.tri[k]
    body_m, body_o = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
    r_m = rows.block_lever[k]
    r_o = r_m + sim.state.body_x_prev[body_m] - sim.state.body_x_prev[body_o]
    d = (sim.block_dx[body_m] + sim.block_dtheta[body_m].cross(r_m)
         - sim.block_dx[body_o] - sim.block_dtheta[body_o].cross(r_o))
    impulse, k_impulse = project_block_row(sim, rows, k, friction, d, leave, k_mat)
    moved_by = k_impulse.norm()
    if moved_by > 0.0:
        sim.block_dx[body_m] = sim.block_dx[body_m] + f_m * sim.model.body_inv_mass[body_m] * impulse
        sim.block_dtheta[body_m] = sim.block_dtheta[body_m] + f_m * (sim.block_inv_inertia[body_m] @ r_m.cross(impulse))
        sim.block_dx[body_o] = sim.block_dx[body_o] - f_o * sim.model.body_inv_mass[body_o] * impulse
        sim.block_dtheta[body_o] = sim.block_dtheta[body_o] - f_o * (sim.block_inv_inertia[body_o] @ r_o.cross(impulse))
    return moved_by


@ti.func
def solve_block_row(sim: ti.template(), rows: ti.template(), k: ti.i32, b: ti.i32, friction: bool,
                    leave: bool) -> float:
    """Row k (rigid body b against a static body) projected on b's linearised motion, as
    solve_contact_normal and solve_contact_friction do on the real pose. With d the moved
    anchor's displacement relative to the other since the linearisation, the gap is
    g = g0 − N·d and the tangential slip s = s0 + d_t; an impulse P on the moved side adds
    K·P to d (K the 3×3 inverse mass at the anchor, rigid.inv_mass_matrix_world), P from
    project_block_row. Returns how far the row moved its anchor (m)."""
    tri = rows.tri[k]
    sign = ti.select(sim.model.tri_body[tri[0]] == b, 1.0, -1.0)
    r = rows.block_lever[k]
    d = sign * (sim.block_dx[b] + sim.block_dtheta[b].cross(r))
    impulse, k_impulse = project_block_row(sim, rows, k, friction, d, leave, rows.block_k[k])
    moved_by = k_impulse.norm()
    if moved_by > 0.0:
        body_impulse = sign * impulse
        sim.block_dx[b] = sim.block_dx[b] + sim.model.body_inv_mass[b] * body_impulse
        sim.block_dtheta[b] = sim.block_dtheta[b] + sim.block_inv_inertia[b] @ r.cross(body_impulse)
    return moved_by
