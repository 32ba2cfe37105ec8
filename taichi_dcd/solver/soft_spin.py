"""A soft body's angular momentum through the projection: what its own constraints gave it is
taken back from its velocities.

The sweeps move an edge's ends along the edge's current direction g. With the velocities
v = (x − x_prev)/h, a move of Δλ·g on the two ends changes the body's angular momentum by
Δλ·(x_prev,i − x_prev,j) × g / h, which is zero only if the edge has not turned since the
substep's start. An edge that carries a load and turns within the substep (the sweeps move
it back and forth against a contact) makes a torque from nothing: a cloth hanging from a
spike's apex, its weight on the edges about one row, was spun about the vertical at
0.008 rad/s against its drag for good, and a free soft ball's angular momentum drifted by
2e-3 in 40 frames. Moving the ends along their direction at the substep's start (SHAKE)
keeps it too, but changes the solve: the soft ball on the spike then ended in a two-frame
cycle (docs/experiments.md)."""

import taichi as ti

from ..contact.anchors import anchor_world
from ..core.model import SOFT
from .contact_solve import takes_part

vec3 = ti.math.vec3


@ti.func
def measure_internal_spin(sim: ti.template(), rows: ti.template(), n: ti.i32, h: float):
    """After the projection, before the velocities (vertex_v still the predicted ones): per soft
    body b, the angular momentum (kg·m²/s) its projection gave it beyond its contact rows',
        soft_spin_error[b] = (Σ_i m_i r_i × (x_i − x_prev,i − h v_i) − Σ_rows r_a × J) / h,
    r the lever from the body's first particle at the substep's start, r_a that of a row's
    anchor at the start, J the row's positional impulse on b (kg·m: λ_n N − λ_t on the moved
    side, its negative on the other, times takes_part). Rows between two triangles of one body
    count as its own: a contact acts at one point, and a pair's anchors at two make a couple."""
    for b in range(sim.model.body_count[0]):
        sim.soft_spin_error[b] = vec3(0.0)
    for i in range(sim.model.vertex_count[0]):
        b = sim.model.vertex_body[i]
        w = sim.model.vertex_inv_mass[i]
        if sim.model.body_kind[b] == SOFT and w > 0.0:
            x_prev = sim.state.vertex_x_prev[i]
            r = x_prev - sim.state.vertex_x_prev[sim.model.body_vertex_range[b][0]]
            sim.soft_spin_error[b] += r.cross(sim.state.vertex_x[i] - x_prev - h * sim.state.vertex_v[i]) / w
    for k in range(n):
        tri = rows.tri[k]
        b_m, b_o = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
        if b_m != b_o:
            impulse = rows.lambda_n[k] * rows.normal[k] - rows.lambda_t[k]
            if sim.model.body_kind[b_m] == SOFT:
                r = (anchor_world(sim, tri[0], rows.bary_moved[k], True)
                     - sim.state.vertex_x_prev[sim.model.body_vertex_range[b_m][0]])
                sim.soft_spin_error[b_m] -= takes_part(sim, tri[0], tri[1]) * r.cross(impulse)
            if sim.model.body_kind[b_o] == SOFT:
                r = (anchor_world(sim, tri[1], rows.bary_other[k], True)
                     - sim.state.vertex_x_prev[sim.model.body_vertex_range[b_o][0]])
                sim.soft_spin_error[b_o] += takes_part(sim, tri[1], tri[0]) * r.cross(impulse)
    for b in range(sim.model.body_count[0]):
        sim.soft_spin_error[b] /= h


@ti.func
def centre_and_inertia(sim: ti.template(), b: ti.i32):
    """Soft body b's mass (kg), centre of mass (m) and inertia tensor about it (kg·m²) at its
    particles' current positions."""
    lo, hi = sim.model.body_vertex_range[b][0], sim.model.body_vertex_range[b][1]
    mass = 0.0
    x_cm = vec3(0.0)
    for i in range(lo, hi):
        m = 1.0 / sim.model.vertex_inv_mass[i]
        mass += m
        x_cm += m * sim.state.vertex_x[i]
    x_cm /= mass
    inertia = ti.Matrix.zero(float, 3, 3)
    for i in range(lo, hi):
        m = 1.0 / sim.model.vertex_inv_mass[i]
        r = sim.state.vertex_x[i] - x_cm
        inertia += m * (r.dot(r) * ti.Matrix.identity(float, 3) - r.outer_product(r))
    return mass, x_cm, inertia


@ti.func
def remove_internal_spin(sim: ti.template(), b: ti.i32, x_cm: vec3, inertia: ti.template()):
    """Take soft_spin_error[b] back from soft body b's new velocities as a rigid turn,
    v_i −= (I⁻¹ L_err) × (x_i − x_cm): it changes no distance's rate and no momentum. x_cm and
    inertia: the body's at its particles' current positions (centre_and_inertia)."""
    error = sim.soft_spin_error[b]
    if error.norm_sqr() > 0.0:
        if ti.abs(inertia.determinant()) > 0.0:
            turn = inertia.inverse() @ error
            for i in range(sim.model.body_vertex_range[b][0], sim.model.body_vertex_range[b][1]):
                sim.state.vertex_v[i] -= turn.cross(sim.state.vertex_x[i] - x_cm)
