"""Soft-body XPBD constraints as pure Taichi functions (Macklin et al., "XPBD",
MIG 2016; Müller et al., "Position Based Dynamics", 2007).

Every function returns the multiplier increment Δλ of one projection,
    Δλ = (−C − α̃·λ) / (Σ_i w_i |∇_i C|² + α̃),   α̃ = α / h²   (XPBD Eq. 18),
where α is the constraint's compliance (inverse stiffness), λ the multiplier
accumulated over this substep's iterations and w_i the particles' inverse
masses; the caller moves particle i by w_i ∇_i C Δλ.
"""

import taichi as ti

vec3 = ti.math.vec3


@ti.func
def xpbd_delta_lambda(c: float, weighted_grad_sq: float, lam: float, alpha_tilde: float) -> float:
    """Δλ = (−C − α̃λ)/(Σ w|∇C|² + α̃); 0 when nothing can move."""
    den = weighted_grad_sq + alpha_tilde
    return ti.select(den > 0.0, (-c - alpha_tilde * lam) / ti.select(den > 0.0, den, 1.0), 0.0)


@ti.func
def edge_length(x_i: vec3, x_j: vec3, rest: float):
    """C = |x_i − x_j| − L, ∇_i C = −∇_j C = (x_i − x_j)/|x_i − x_j|. Returns (C, ∇_i C);
    the gradient is zero for coincident particles (no defined direction)."""
    d = x_i - x_j
    length = d.norm()
    grad = vec3(0.0)
    if length > 0.0:
        grad = d / length
    return length - rest, grad


@ti.func
def tet_volume6(x0: vec3, x1: vec3, x2: vec3) -> float:
    """Six times the signed volume of the tetrahedron (origin, x0, x1, x2): (x0 × x1)·x2.
    Summed over a closed outward mesh's triangles it gives 6·V (divergence theorem)."""
    return x0.cross(x1).dot(x2)
