"""Integration: prediction of rigid bodies and soft particles (Müller et al. 2020, Alg. 2), the
velocities from the substep's motion, soft-body damping and drag."""

import taichi as ti

from ..core.model import RIGID, SOFT
from ..core.rigid import carried_angular_velocity, quat_rotate, rotate_by
from .soft_spin import centre_and_inertia, remove_internal_spin

vec3 = ti.math.vec3


@ti.func
def predict_body(sim: ti.template(), b: ti.i32, h: float, gravity: vec3, kick: float):
    """Explicit prediction of a rigid body's pose (Müller 2020, Alg. 2, lines 4-8);
    kick scales the velocity update (1, or 1/2 on a run's first substep)."""
    if sim.model.body_kind[b] == RIGID and sim.body_asleep[b] == 1:
        # Asleep (solver.sleep): held where it is, at rest.
        sim.state.body_x_prev[b] = sim.state.body_x[b]
        sim.state.body_q_prev[b] = sim.state.body_q[b]
        sim.body_theta[b] = vec3(0.0)
    elif sim.model.body_kind[b] == RIGID:
        sim.state.body_v[b] += kick * h * (gravity + sim.model.body_force[b] * sim.model.body_inv_mass[b])
        sim.state.body_x_prev[b] = sim.state.body_x[b]
        sim.state.body_x[b] += h * sim.state.body_v[b]
        # ω is already the end-of-substep velocity that keeps L (update_body_velocity).
        sim.body_theta[b] = h * sim.state.body_w[b]
        sim.state.body_q_prev[b] = sim.state.body_q[b]
        sim.state.body_q[b] = rotate_by(sim.state.body_q[b], sim.body_theta[b])


@ti.func
def predict_particle(sim: ti.template(), i: ti.i32, h: float, gravity: vec3, kick: float):
    """Explicit prediction of a soft particle; the body's force is shared equally."""
    w = sim.model.vertex_inv_mass[i]
    if w > 0.0:
        b = sim.model.vertex_body[i]
        n = sim.model.body_vertex_range[b][1] - sim.model.body_vertex_range[b][0]
        sim.state.vertex_v[i] += kick * h * (gravity + sim.model.body_force[b] * (w / n))
        sim.state.vertex_x_prev[i] = sim.state.vertex_x[i]
        sim.state.vertex_x[i] += h * sim.state.vertex_v[i]


@ti.func
def place_vertex(sim: ti.template(), i: ti.i32):
    """World position of a rigid body's vertex from the body's pose."""
    b = sim.model.vertex_body[i]
    if sim.model.body_kind[b] == RIGID:
        sim.state.vertex_x[i] = sim.state.body_x[b] + quat_rotate(sim.state.body_q[b], sim.model.vertex_local[i])


@ti.func
def predict(sim: ti.template(), h: float, gravity: vec3, kick: float):
    """Predict every rigid body and soft particle (Müller 2020, Alg. 2, lines 3-8), and keep
    the unit vector against gravity in sim.up."""
    up = vec3(0.0)
    g_norm = gravity.norm()
    if g_norm > 0.0:
        up = -gravity / g_norm
    sim.up[0] = up
    for b in range(sim.model.body_count[0]):
        predict_body(sim, b, h, gravity, kick)
    if ti.static(sim.model.has_soft):
        for i in range(sim.model.vertex_count[0]):
            predict_particle(sim, i, h, gravity, kick)


@ti.func
def update_body_velocity(sim: ti.template(), b: ti.i32, h: float):
    """v = (x − x_prev)/h and ω = θ/h, the substep's rotation vector over h (Müller 2020,
    Alg. 2, lines 12-15), carried to the end pose with its angular momentum kept."""
    if sim.model.body_kind[b] == RIGID:
        sim.state.body_v[b] = (sim.state.body_x[b] - sim.state.body_x_prev[b]) / h
        sim.state.body_w[b] = carried_angular_velocity(sim.state.body_q_prev[b], sim.state.body_q[b],
                                                        sim.model.body_inertia[b],
                                                        sim.model.body_inv_inertia[b], sim.body_theta[b] / h)


@ti.func
def update_particle_velocity(sim: ti.template(), i: ti.i32, h: float):
    if sim.model.vertex_inv_mass[i] > 0.0:
        sim.state.vertex_v[i] = (sim.state.vertex_x[i] - sim.state.vertex_x_prev[i]) / h


@ti.func
def damp_soft_body(sim: ti.template(), b: ti.i32, h: float, mass: float, x_cm: vec3, inertia: ti.template()):
    """Soft-body damping (Müller et al. 2007, §3.5): each particle loses the fraction
    1 − exp(−damping·h) of its velocity relative to the body's rigid motion
    v_cm + ω × r_i, ω = I⁻¹L; momentum and angular momentum are kept. mass, x_cm and inertia:
    soft body b's (soft_spin.centre_and_inertia)."""
    rate = sim.model.body_damping[b]
    if rate > 0.0:
        lo, hi = sim.model.body_vertex_range[b][0], sim.model.body_vertex_range[b][1]
        v_cm = vec3(0.0)
        spin = vec3(0.0)
        for i in range(lo, hi):
            m = 1.0 / sim.model.vertex_inv_mass[i]
            v_cm += m * sim.state.vertex_v[i]
            spin += m * (sim.state.vertex_x[i] - x_cm).cross(sim.state.vertex_v[i])
        v_cm /= mass
        omega = vec3(0.0)
        if ti.abs(inertia.determinant()) > 0.0:
            omega = inertia.inverse() @ spin
        k = 1.0 - ti.exp(-rate * h)
        for i in range(lo, hi):
            r = sim.state.vertex_x[i] - x_cm
            sim.state.vertex_v[i] += k * (v_cm + omega.cross(r) - sim.state.vertex_v[i])


@ti.func
def apply_drag(sim: ti.template(), b: ti.i32, h: float):
    """Linear velocity damping (drag): every point of body b loses the fraction 1 − exp(−drag·h)
    of its velocity over the substep (dv/dt = −drag·v). For a rigid body that is v and ω
    alike (the force −drag·m·v at the centre of mass and the torque −drag·I·ω)."""
    rate = sim.model.body_drag[b]
    if rate > 0.0:
        keep = ti.exp(-rate * h)
        if sim.model.body_kind[b] == RIGID:
            sim.state.body_v[b] *= keep
            sim.state.body_w[b] *= keep
        elif sim.model.body_kind[b] == SOFT:
            lo, hi = sim.model.body_vertex_range[b][0], sim.model.body_vertex_range[b][1]
            for i in range(lo, hi):
                sim.state.vertex_v[i] *= keep


@ti.func
def update_velocities(sim: ti.template(), h: float):
    """Velocities from the substep's motion (Müller 2020, Alg. 2, lines 12-16), less the spin a
    soft body's own constraints gave it (solver.soft_spin), then the soft bodies' damping."""
    for b in range(sim.model.body_count[0]):
        update_body_velocity(sim, b, h)
    if ti.static(sim.model.has_soft):
        for i in range(sim.model.vertex_count[0]):
            update_particle_velocity(sim, i, h)
        for b in range(sim.model.body_count[0]):
            if sim.model.body_kind[b] == SOFT:
                # Positions are final here: one centre and inertia serves both.
                mass, x_cm, inertia = centre_and_inertia(sim, b)
                remove_internal_spin(sim, b, x_cm, inertia)
                damp_soft_body(sim, b, h, mass, x_cm, inertia)
    for b in range(sim.model.body_count[0]):
        apply_drag(sim, b, h)
