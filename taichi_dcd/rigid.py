"""Rigid-body kinematics for XPBD as pure Taichi functions (Müller et al., "Detailed
Rigid Body Simulation with Extended Position Based Dynamics", SCA 2020).

A pose is a centre-of-mass position x and a unit quaternion q = (w, x, y, z)
stored as a vec4 with w first; R(q) maps body-frame vectors to world space.
Inertia tensors are 3×3 in the body frame; world-frame products I_w⁻¹·v = R I_b⁻¹ Rᵀ v
are evaluated by rotating v into the body frame and back.
"""

import taichi as ti

vec3 = ti.math.vec3
vec4 = ti.math.vec4
mat3 = ti.math.mat3


@ti.func
def quat_mul(a: vec4, b: vec4) -> vec4:
    """Hamilton product a ⊗ b."""
    return vec4(
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    )


@ti.func
def quat_conj(q: vec4) -> vec4:
    return vec4(q[0], -q[1], -q[2], -q[3])


@ti.func
def quat_rotate(q: vec4, v: vec3) -> vec3:
    """R(q)·v for a unit quaternion q: v + 2w(u×v) + 2u×(u×v), u = (x, y, z)."""
    u = vec3(q[1], q[2], q[3])
    t = 2.0 * u.cross(v)
    return v + q[0] * t + u.cross(t)


@ti.func
def integrate_rotation(q: vec4, omega: vec3, h: float) -> vec4:
    """q + h/2·[ω, 0] ⊗ q, normalised (Müller 2020, Alg. 2)."""
    dq = quat_mul(vec4(0.0, omega[0], omega[1], omega[2]), q)
    return (q + 0.5 * h * dq).normalized()


@ti.func
def angular_velocity(q: vec4, q_prev: vec4, h: float) -> vec3:
    """ω = 2·vec(q ⊗ q_prev⁻¹)/h, taking the shorter way round (Müller 2020, Alg. 2)."""
    dq = quat_mul(q, quat_conj(q_prev))
    omega = 2.0 * vec3(dq[1], dq[2], dq[3]) / h
    return ti.select(dq[0] >= 0.0, omega, -omega)


@ti.func
def inv_inertia_times(q: vec4, inv_inertia_body: mat3, v: vec3) -> vec3:
    """I_w⁻¹·v = R I_b⁻¹ Rᵀ v, by rotating v into the body frame and back."""
    return quat_rotate(q, inv_inertia_body @ quat_rotate(quat_conj(q), v))


@ti.func
def gyroscopic_step(q: vec4, inertia_body: mat3, inv_inertia_body: mat3, omega: vec3, h: float) -> vec3:
    """ω + h·I_w⁻¹(−ω × I_w ω), evaluated in the body frame (Müller 2020, Alg. 2, line 7)."""
    w_b = quat_rotate(quat_conj(q), omega)
    return omega + h * quat_rotate(q, inv_inertia_body @ (-w_b.cross(inertia_body @ w_b)))


@ti.func
def generalized_inv_mass(inv_mass: float, q: vec4, inv_inertia_body: mat3, r: vec3, n: vec3) -> float:
    """w = 1/m + (r × n)ᵀ I_w⁻¹ (r × n): inverse mass of a body felt by a unit
    impulse along n at offset r from its centre of mass (Müller 2020, Eq. 2-3)."""
    rn = quat_rotate(quat_conj(q), r.cross(n))
    return inv_mass + rn.dot(inv_inertia_body @ rn)


@ti.func
def apply_positional_impulse(x: vec3, q: vec4, inv_mass: float, inv_inertia_body: mat3, r: vec3, p: vec3):
    """Pose after a positional impulse p at offset r: x + p/m and
    q + ½[I_w⁻¹(r × p), 0] ⊗ q, normalised (Müller 2020, Eq. 6-9). Returns (x, q)."""
    dw = inv_inertia_times(q, inv_inertia_body, r.cross(p))
    dq = quat_mul(vec4(0.0, dw[0], dw[1], dw[2]), q)
    return x + inv_mass * p, (q + 0.5 * dq).normalized()


@ti.func
def apply_velocity_impulse(v: vec3, omega: vec3, q: vec4, inv_mass: float, inv_inertia_body: mat3, r: vec3,
                           p: vec3):
    """Velocities after an impulse p at offset r: v + p/m, ω + I_w⁻¹(r × p). Returns (v, ω)."""
    return v + inv_mass * p, omega + inv_inertia_times(q, inv_inertia_body, r.cross(p))
