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
def quat_exp(theta: vec3) -> vec4:
    """Unit quaternion of the rotation by the rotation vector θ (rad): (cos(|θ|/2), sin(|θ|/2)·θ/|θ|)."""
    angle = theta.norm()
    # sin(a/2)/a, by its series where the division would lose digits (error < a⁴/3840).
    s = 0.5 - angle * angle / 48.0
    if angle > 1e-4:
        s = ti.sin(0.5 * angle) / angle
    return vec4(ti.cos(0.5 * angle), s * theta[0], s * theta[1], s * theta[2])


@ti.func
def rotate_by(q: vec4, theta: vec3) -> vec4:
    """exp(θ) ⊗ q: q turned by the world-frame rotation vector θ (rad)."""
    return quat_mul(quat_exp(theta), q)


@ti.func
def world_times(q: vec4, matrix_body: mat3, v: vec3) -> vec3:
    """M_w·v = R M_b Rᵀ v for a body-frame matrix M_b (an inertia tensor or its inverse),
    by rotating v into the body frame and back."""
    return quat_rotate(q, matrix_body @ quat_rotate(quat_conj(q), v))


@ti.func
def carried_angular_velocity(q_start: vec4, q_end: vec4, inertia_body: mat3, inv_inertia_body: mat3,
                             omega: vec3) -> vec3:
    """I_w(q_end)⁻¹ I_w(q_start) ω: the angular velocity at the end of a substep whose
    rotation ran at ω, with the angular momentum I_w(q_start)·ω of that rotation kept. With
    ω held through the next substep's rotation this is Lie-Euler with L constant: free
    spin keeps L exactly (its gyroscopic turning included), and each impulse r × p adds to
    it exactly (Müller 2020's explicit gyroscopic term instead loses ~h²ω² per substep)."""
    return world_times(q_end, inv_inertia_body, world_times(q_start, inertia_body, omega))


@ti.func
def generalized_inv_mass(inv_mass: float, q: vec4, inv_inertia_body: mat3, r: vec3, n: vec3) -> float:
    """w = 1/m + (r × n)ᵀ I_w⁻¹ (r × n): inverse mass of a body felt by a unit
    impulse along n at offset r from its centre of mass (Müller 2020, Eq. 2-3)."""
    rn = quat_rotate(quat_conj(q), r.cross(n))
    return inv_mass + rn.dot(inv_inertia_body @ rn)


@ti.func
def quat_matrix(q: vec4) -> mat3:
    """R(q) as a 3×3 matrix (its columns are the rotated axes)."""
    rot = mat3(0.0)
    for i in ti.static(range(3)):
        axis = vec3(0.0)
        axis[i] = 1.0
        column = quat_rotate(q, axis)
        for j in ti.static(range(3)):
            rot[j, i] = column[j]
    return rot


@ti.func
def inv_mass_matrix_world(inv_mass: float, inv_inertia_world: mat3, r: vec3) -> mat3:
    """K = I/m − [r]× I_w⁻¹ [r]×: how far a body's point at offset r from its centre of mass
    moves per unit positional impulse there, in every direction (n·K·n is
    `generalized_inv_mass` along n)."""
    skew = mat3([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    return inv_mass * ti.Matrix.identity(float, 3) - skew @ inv_inertia_world @ skew


@ti.func
def apply_positional_impulse(x: vec3, theta: vec3, q_start: vec4, inv_mass: float, inv_inertia_body: mat3,
                             r_start: vec3, p: vec3):
    """Pose after a positional impulse p (kg·m) at offset r_start from the centre of mass
    at the start of the substep: x + p/m and the substep's rotation vector θ + I_w⁻¹(r × p),
    I_w at the start (Müller 2020, Eq. 6-9, with rotation vectors added rather than
    quaternions composed, so that the angular impulses add up exactly). Returns (x, θ, q)."""
    theta_new = theta + world_times(q_start, inv_inertia_body, r_start.cross(p))
    return x + inv_mass * p, theta_new, rotate_by(q_start, theta_new)


@ti.func
def apply_velocity_impulse(v: vec3, omega: vec3, q: vec4, inv_mass: float, inv_inertia_body: mat3, r: vec3,
                           p: vec3):
    """Velocities after an impulse p at offset r: v + p/m, ω + I_w⁻¹(r × p). Returns (v, ω)."""
    return v + inv_mass * p, omega + world_times(q, inv_inertia_body, r.cross(p))
