"""Projecting contact rows one at a time on the real pose: normals, static friction, the velocity
pass (restitution and dynamic friction), spin friction, and shock propagation by contact level."""

import taichi as ti

from ..contact.anchors import (
    anchor_inv_mass,
    anchor_kick,
    anchor_move,
    anchor_velocity,
    anchor_world,
    involves_soft,
)
from ..core.model import RIGID, STATIC
from ..core.rigid import world_times

vec3 = ti.math.vec3

# In a contact between bodies stacked on the ground, the lower body holds still when the
# upper one is at least this many times heavier (solver.contact_solve.takes_part).
SHOCK_MASS_RATIO = 10.0


@ti.func
def friction_in_cone(lam_t: vec3, cap: float) -> vec3:
    """An accumulated friction multiplier or impulse shortened to |λ_t| ≤ cap = μ·λ_n (the
    Coulomb cone). Clamped rather than all-or-nothing: several contacts of one face share the
    load unevenly, and dropping a contact's whole correction when its own share is exceeded
    makes a box stick-slip down a gentle slope."""
    length = lam_t.norm()
    return ti.select(length > cap, lam_t * (cap / ti.select(length > 0.0, length, 1.0)), lam_t)


@ti.func
def compute_levels(sim: ti.template(), rows: ti.template(), n_contacts: ti.i32):
    """Each body's level in the contact graph: 0 for static bodies, 1 + the lowest level
    of the bodies it touches otherwise, n_bodies for bodies that rest on nothing static
    (shortest paths by repeated relaxation, serial)."""
    n_b = sim.model.body_count[0]
    for b in range(n_b):
        sim.body_level[b] = ti.select(sim.model.body_kind[b] == STATIC, 0, n_b)
    changed = True
    rounds = 0
    while changed and rounds < n_b:
        changed = False
        for k in range(n_contacts):
            tri = rows.tri[k]
            bm, bo = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
            if sim.body_level[bo] + 1 < sim.body_level[bm]:
                sim.body_level[bm] = sim.body_level[bo] + 1
                changed = True
            if sim.body_level[bm] + 1 < sim.body_level[bo]:
                sim.body_level[bo] = sim.body_level[bm] + 1
                changed = True
        rounds += 1


@ti.func
def takes_part(sim: ti.template(), t_self: ti.i32, t_other: ti.i32) -> float:
    """1.0, or 0.0 if triangle t_self's body holds still in its contacts with t_other's:
    shock propagation, for a body nearer the static ground (lower level) under one
    SHOCK_MASS_RATIO times heavier or more. Gauss-Seidel would need about mass-ratio
    sweeps to carry the heavy body's weight down through the light one; meanwhile the
    heavy body drives the light one under the ground it rests on. The light body then
    carries its own weight only: it is not pushed into motion by the heavy one."""
    b_self, b_other = sim.model.tri_body[t_self], sim.model.tri_body[t_other]
    held = (sim.body_level[b_self] < sim.body_level[b_other]
            and sim.body_mass[b_self] * SHOCK_MASS_RATIO <= sim.body_mass[b_other])
    if ti.static(not sim.rules.shock_propagation):
        held = False
    return ti.select(held, 0.0, 1.0)


@ti.func
def pair_friction(sim: ti.template(), t_a: ti.i32, t_b: ti.i32) -> float:
    """μ of a contact between triangles t_a and t_b: the mean of their bodies' coefficients."""
    return 0.5 * (sim.model.body_friction[sim.model.tri_body[t_a]]
                  + sim.model.body_friction[sim.model.tri_body[t_b]])


@ti.func
def solve_contact_normal(sim: ti.template(), rows: ti.template(), k: ti.i32):
    """Project contact k: C = N·(p_other − p_moved) ≥ 0 with Δλ = C/(w_moved + w_other),
    w the generalised inverse masses along N (Müller 2020, Eq. 2-9 with α = 0), within
    what is left of the contact's correction budget (m)."""
    tri = rows.tri[k]
    bm, bo = rows.bary_moved[k], rows.bary_other[k]
    n = rows.normal[k]
    p_m = anchor_world(sim, tri[0], bm, False)
    p_o = anchor_world(sim, tri[1], bo, False)
    # Both anchors take the impulse at one point: the pair's torques then cancel
    # exactly and angular momentum is kept (the anchors drift apart sideways).
    p_c = 0.5 * (p_m + p_o)
    gap = n.dot(p_o - p_m)
    soft = involves_soft(sim, tri[0], tri[1])
    c = ti.select(soft, gap - rows.budget[k], ti.min(gap, rows.budget[k]))
    if c > 0.0:
        f_m, f_o = takes_part(sim, tri[0], tri[1]), takes_part(sim, tri[1], tri[0])
        w = f_m * anchor_inv_mass(sim, tri[0], bm, p_m, n) + f_o * anchor_inv_mass(sim, tri[1], bo, p_o, n)
        if w > 0.0:
            dl = c / w
            anchor_move(sim, tri[0], bm, p_c, f_m * dl * n)
            anchor_move(sim, tri[1], bo, p_c, -f_o * dl * n)
            rows.lambda_n[k] += dl
            if not soft:
                rows.budget[k] -= c


@ti.func
def solve_contact_friction(sim: ti.template(), rows: ti.template(), k: ti.i32):
    """Static friction of an active contact: cancel the anchors' relative tangential
    displacement over the substep, as far as the accumulated vector λ_t stays within
    |λ_t| ≤ μ·λ_n (Müller 2020, Eq. 26-27, clamped; μ is the mean of the two bodies'
    friction coefficients)."""
    if rows.lambda_n[k] > 0.0:
        tri = rows.tri[k]
        bm, bo = rows.bary_moved[k], rows.bary_other[k]
        n = rows.normal[k]
        p_m = anchor_world(sim, tri[0], bm, False)
        p_o = anchor_world(sim, tri[1], bo, False)
        p_c = 0.5 * (p_m + p_o)
        slip = (p_m - anchor_world(sim, tri[0], bm, True)) - (p_o - anchor_world(sim, tri[1], bo, True))
        slip -= slip.dot(n) * n
        length = slip.norm()
        if length > 0.0:
            t = slip / length
            f_m, f_o = takes_part(sim, tri[0], tri[1]), takes_part(sim, tri[1], tri[0])
            w = f_m * anchor_inv_mass(sim, tri[0], bm, p_m, t) + f_o * anchor_inv_mass(sim, tri[1], bo, p_o, t)
            if w > 0.0:
                old_t = rows.lambda_t[k]
                new_t = friction_in_cone(old_t + (length / w) * t,
                                         pair_friction(sim, tri[0], tri[1]) * rows.lambda_n[k])
                d = new_t - old_t
                anchor_move(sim, tri[0], bm, p_c, -f_m * d)
                anchor_move(sim, tri[1], bo, p_c, f_o * d)
                rows.lambda_t[k] = new_t


@ti.func
def solve_contact_velocity(sim: ti.template(), rows: ti.template(), k: ti.i32, h: float, g_norm: float):
    """One velocity-pass sweep over an active contact (Müller 2020 §3.6, iterated as
    sequential impulses): the normal relative velocity is driven to max(−e·v_n⁰, 0)
    (e = 0 below 2|g|h, so resting stays resting), and the accumulated dynamic-friction
    impulse cancels the tangential velocity within what static friction left of Coulomb's
    bound: |J_t| ≤ (μ·λ_n − λ_t)/h."""
    if rows.lambda_n[k] > 0.0:
        tri = rows.tri[k]
        bm, bo = rows.bary_moved[k], rows.bary_other[k]
        n = rows.normal[k]
        p_m = anchor_world(sim, tri[0], bm, False)
        p_o = anchor_world(sim, tri[1], bo, False)
        p_c = 0.5 * (p_m + p_o)
        body_m, body_o = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
        e = 0.5 * (sim.model.body_restitution[body_m] + sim.model.body_restitution[body_o])
        vn0 = rows.vn0[k]
        if ti.abs(vn0) <= 2.0 * g_norm * h:
            e = 0.0
        v = anchor_velocity(sim, tri[0], bm, p_m) - anchor_velocity(sim, tri[1], bo, p_o)
        f_m, f_o = takes_part(sim, tri[0], tri[1]), takes_part(sim, tri[1], tri[0])
        w_n = f_m * anchor_inv_mass(sim, tri[0], bm, p_m, n) + f_o * anchor_inv_mass(sim, tri[1], bo, p_o, n)
        if w_n > 0.0:
            impulse = ((ti.max(-e * vn0, 0.0) - v.dot(n)) / w_n) * n
            anchor_kick(sim, tri[0], bm, p_c, f_m * impulse)
            anchor_kick(sim, tri[1], bo, p_c, -f_o * impulse)
        v = anchor_velocity(sim, tri[0], bm, p_m) - anchor_velocity(sim, tri[1], bo, p_o)
        vt = v - v.dot(n) * n
        vt_len = vt.norm()
        if vt_len > 0.0:
            t = vt / vt_len
            w_t = f_m * anchor_inv_mass(sim, tri[0], bm, p_m, t) + f_o * anchor_inv_mass(sim, tri[1], bo, p_o, t)
            if w_t > 0.0:
                mu = pair_friction(sim, tri[0], tri[1])
                # The position pass already spent λ_t/h of the Coulomb bound μ·λ_n/h.
                bound = ti.max(mu * rows.lambda_n[k] - rows.lambda_t[k].norm(), 0.0) / h
                old = rows.impulse_t[k]
                new = friction_in_cone(old - (vt_len / w_t) * t, bound)
                rows.impulse_t[k] = new
                anchor_kick(sim, tri[0], bm, p_c, f_m * (new - old))
                anchor_kick(sim, tri[1], bo, p_c, f_o * (old - new))


@ti.func
def solve_velocities(sim: ti.template(), rows: ti.template(), n_contacts: ti.i32, iterations: ti.i32, h: float,
                     g_norm: float):
    """`iterations` alternating sweeps of the velocity pass (serial)."""
    for k in range(n_contacts):
        rows.impulse_t[k] = vec3(0.0)
    for it in range(iterations):
        for j in range(n_contacts):
            k = ti.select(it % 2 == 0, j, n_contacts - 1 - j)
            solve_contact_velocity(sim, rows, k, h, g_norm)
    if ti.static(sim.has_spin_friction):
        for k in range(n_contacts):
            solve_contact_spin(sim, rows, k, h)


@ti.func
def spin_response(sim: ti.template(), b: ti.i32, n: vec3) -> vec3:
    """I_w⁻¹·n of body b at its current pose (1/(kg·m²)): its change of ω per unit angular
    impulse about n; zero unless b is rigid."""
    out = vec3(0.0)
    if sim.model.body_kind[b] == RIGID:
        out = world_times(sim.state.body_q[b], sim.model.body_inv_inertia[b], n)
    return out


@ti.func
def solve_contact_spin(sim: ti.template(), rows: ti.template(), k: ti.i32, h: float):
    """Spin (torsional) friction of an active contact between rigid or static bodies: an
    angular impulse L·N cancels the bodies' relative spin s = (ω_m − ω_o)·N, L = −s/(N·I_m⁻¹N
    + N·I_o⁻¹N), within Coulomb's bound |L| ≤ μ_s·λ_n/h (μ_s in m: the torque per newton
    of normal force). A point contact has no torque about its normal, so a body held at
    two points turns freely about the line through them: a spike hanging between a
    groove's wall and a wedge swung about it for seconds."""
    tri = rows.tri[k]
    body_m, body_o = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
    mu_s = 0.5 * (sim.model.body_spin_friction[body_m] + sim.model.body_spin_friction[body_o])
    if rows.lambda_n[k] > 0.0 and mu_s > 0.0 and not involves_soft(sim, tri[0], tri[1]):
        n = rows.normal[k]
        f_m, f_o = takes_part(sim, tri[0], tri[1]), takes_part(sim, tri[1], tri[0])
        dw_m, dw_o = f_m * spin_response(sim, body_m, n), f_o * spin_response(sim, body_o, n)
        w = n.dot(dw_m + dw_o)
        if w > 0.0:
            # A static body's ω is zero: only rigid bodies move (update_body_velocity).
            spin = (sim.state.body_w[body_m] - sim.state.body_w[body_o]).dot(n)
            bound = mu_s * rows.lambda_n[k] / h
            impulse = ti.min(ti.max(-spin / w, -bound), bound)
            sim.state.body_w[body_m] += impulse * dw_m
            sim.state.body_w[body_o] -= impulse * dw_o
