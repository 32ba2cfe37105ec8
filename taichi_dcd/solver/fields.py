"""The solver's own fields, allocated once per scene: the bundle `sim` that every solver and
contact-rule `ti.func` takes (with the Model and State it steps), so that no function threads a
dozen fields through its arguments."""

import numpy as np
import taichi as ti

from ..contact.exits import convex_neighbours, sharp_edge_bits
from ..contact.rules import ContactRules
from ..contact.soft_rows import SOFT_BOX_MARGIN
from ..core import runtime
from ..core.model import SOFT, Model, State, mat_field, scalar_field, vec_field


@ti.data_oriented
class SolverFields:
    """Model, State and the per-scene fields of the solver (sizes fixed by the Model).

    Body fields have n_bodies rows, triangle fields n_tris, vertex fields n_vertices; lengths
    in metres. `rules` says which contact rules are compiled in (all by default);
    `has_spin_friction` compiles the spin-friction pass in only where some body has it.
    """

    def __init__(self, model: Model, state: State, rules: ContactRules | None = None):
        m = model
        self.model = model
        self.state = state
        self.rules = rules or ContactRules()
        kind = m.body_kind_np
        self.has_spin_friction = bool((m.body_spin_friction.to_numpy()[: m.n_bodies] > 0.0).any())
        rest_x = state.vertex_x.to_numpy()[: m.n_vertices]
        sharp_bits = sharp_edge_bits(m, rest_x) if m.has_soft else None
        nbr = convex_neighbours(m, rest_x)
        with runtime.field_block():  # one SNode tree for the solver's fields
            self.tri_lo = vec_field(m.n_tris)
            self.tri_hi = vec_field(m.n_tris)
            self.body_lo = vec_field(m.n_bodies)
            self.body_hi = vec_field(m.n_bodies)
            self.edge_lambda = scalar_field(m.n_edges) if m.has_soft else None
            self.body_level = scalar_field(m.n_bodies, ti.i32)
            # The last contact row whose moved triangle belongs to each body (-1: none); each
            # row links to the one before it (ContactConstraints.tri), for is_duplicate.
            self.body_last_row = scalar_field(m.n_bodies, ti.i32)
            self.body_mass = scalar_field(m.n_bodies)
            # Each rigid body's rotation vector over the current substep (rad): predicted plus
            # every angular correction, added up so that the angular impulses add up exactly.
            self.body_theta = vec_field(m.n_bodies)
            # solve_blocks: each rigid body's move and turn (rad) in the current block
            # solve, and its world inverse inertia at the substep's start (set by project).
            self.block_dx = vec_field(m.n_bodies)
            self.block_dtheta = vec_field(m.n_bodies)
            self.block_inv_inertia = mat_field(m.n_bodies)
            # Each island's rows in b_rows, indexed by its root: [block_first, block_first + block_len).
            self.block_first = scalar_field(m.n_bodies, ti.i32)
            self.block_len = scalar_field(m.n_bodies, ti.i32)
            # Islands of rigid bodies joined by rows between them (union-find: each body's
            # parent, the root its own), and 1 at the root of an island of several bodies.
            self.block_island = scalar_field(m.n_bodies, ti.i32)
            self.block_coupled = scalar_field(m.n_bodies, ti.i32)
            self.body_thickness = scalar_field(m.n_bodies)
            self.body_reach = scalar_field(m.n_bodies)  # farthest vertex from a rigid body's centre (m)
            # Per body for the next frame's substep choice (_summarize_bodies): velocity (3),
            # speed about it (1), vertex box low (3) and high (3) corners.
            self.body_summary = vec_field(m.n_bodies, 10)
            real = runtime.real_dtype()
            runtime.fill(self.body_mass, np.array([min(b.mass, 1e30) for b in m.bodies], real))
            thickness = np.array([min(b.thickness, 1e30) for b in m.bodies])
            runtime.fill(self.body_thickness, thickness.astype(real))
            runtime.fill(self.body_reach, np.array([min(b.reach, 1e30) for b in m.bodies], real))
            box_margin = np.where(kind == SOFT, SOFT_BOX_MARGIN * thickness, 0.0)
            self.body_box_margin = scalar_field(m.n_bodies)
            runtime.fill(self.body_box_margin, box_margin.astype(real))
            self.vertex_grad = vec_field(m.n_vertices) if m.has_soft else None
            # One triangle holding each vertex: the moved triangle of a soft vertex's resting row.
            self.vertex_tri = scalar_field(max(m.n_vertices, 1), ti.i32)
            vertex_tri = np.zeros(max(m.n_vertices, 1), np.int32)
            vertex_tri[m.tri_indices_np[::-1].ravel()] = np.repeat(np.arange(m.n_tris)[::-1], 3)
            runtime.fill(self.vertex_tri, vertex_tri)
            # Bit k of tri_sharp_edges[t]: edge k (vertex k to k+1) of a rigid or static face is
            # a convex edge sharper than SHARP_EDGE_DEGREES that this face owns (resting edge rows).
            self.tri_sharp_edges = scalar_field(max(m.n_tris, 1), ti.i32)
            if m.has_soft:
                runtime.fill(self.tri_sharp_edges, sharp_bits)
            # The triangles across each face's convex edges, -1 elsewhere (nearest_exit).
            self.tri_convex_nbr = vec_field(m.n_tris, 3, ti.i32)
            runtime.fill(self.tri_convex_nbr, nbr)
            # The rows that pushed in the last substep (carry_rows), offered again in the next one.
            self.carry_capacity = max(1024, m.n_tris)
            self.carry_tri = vec_field(self.carry_capacity, 2, ti.i32)
            self.carry_bary_moved = vec_field(self.carry_capacity)
            self.carry_bary_other = vec_field(self.carry_capacity)
            self.carry_normal = vec_field(self.carry_capacity)
            self.carry_count = scalar_field(1, ti.i32)
            # ... and their copy at the start of a frame (save_state), with the state's.
            self.saved_carry = [vec_field(self.carry_capacity, 2, ti.i32), vec_field(self.carry_capacity),
                                vec_field(self.carry_capacity), vec_field(self.carry_capacity),
                                scalar_field(1, ti.i32)]
            # A copy of the state at the start of a frame, restored when the frame overflows the contact buffer.
            self.saved_body = [vec_field(m.n_bodies), vec_field(m.n_bodies, 4), vec_field(m.n_bodies),
                               vec_field(m.n_bodies)]
            self.saved_vertex = [vec_field(m.n_vertices), vec_field(m.n_vertices)] if m.has_soft else None
        self.box_margin_np = box_margin  # (B,) the grid pads soft bodies' boxes by it too
