"""Soft bodies' own constraints: XPBD edge lengths (a cloth's bending pairs among them) and the
closed body's volume."""

import taichi as ti

from ..core.model import SOFT
from ..solver.constraints import edge_length, tet_volume6, xpbd_delta_lambda

vec3 = ti.math.vec3


@ti.func
def solve_edge(sim: ti.template(), e: ti.i32, h: float):
    """XPBD edge-length constraint C = |x_i − x_j| − L with the edge's compliance α (Macklin
    et al. 2016, Eq. 18: Δλ = (−C − α̃λ)/(w_i + w_j + α̃), α̃ = α/h²)."""
    ij = sim.model.edge_indices[e]
    c, grad = edge_length(sim.state.vertex_x[ij[0]], sim.state.vertex_x[ij[1]], sim.model.edge_rest[e])
    wi, wj = sim.model.vertex_inv_mass[ij[0]], sim.model.vertex_inv_mass[ij[1]]
    alpha = sim.model.edge_compliance[e] / (h * h)
    dl = xpbd_delta_lambda(c, wi + wj, sim.edge_lambda[e], alpha)
    sim.edge_lambda[e] += dl
    sim.state.vertex_x[ij[0]] += wi * dl * grad
    sim.state.vertex_x[ij[1]] -= wj * dl * grad


@ti.func
def solve_volume(sim: ti.template(), b: ti.i32):
    """Volume constraint of a closed soft body, C = V − V₀ with V = Σ (x0×x1)·x2 / 6 over
    its triangles and ∇_i V = Σ over i's triangles of (x_j × x_k)/6 (hard: α = 0). A cloth
    has no volume."""
    if sim.model.body_kind[b] == SOFT and sim.model.body_cloth[b] == 0:
        v_lo, v_hi = sim.model.body_vertex_range[b][0], sim.model.body_vertex_range[b][1]
        for i in range(v_lo, v_hi):
            sim.vertex_grad[i] = vec3(0.0)
        vol6 = 0.0
        for t in range(sim.model.body_tri_range[b][0], sim.model.body_tri_range[b][1]):
            idx = sim.model.tri_indices[t]
            x0, x1, x2 = sim.state.vertex_x[idx[0]], sim.state.vertex_x[idx[1]], sim.state.vertex_x[idx[2]]
            vol6 += tet_volume6(x0, x1, x2)
            sim.vertex_grad[idx[0]] += x1.cross(x2) / 6.0
            sim.vertex_grad[idx[1]] += x2.cross(x0) / 6.0
            sim.vertex_grad[idx[2]] += x0.cross(x1) / 6.0
        wsum = 0.0
        for i in range(v_lo, v_hi):
            wsum += sim.model.vertex_inv_mass[i] * sim.vertex_grad[i].norm_sqr()
        dl = xpbd_delta_lambda(vol6 / 6.0 - sim.model.body_rest_volume[b], wsum, 0.0, 0.0)
        for i in range(v_lo, v_hi):
            sim.state.vertex_x[i] += sim.model.vertex_inv_mass[i] * dl * sim.vertex_grad[i]
