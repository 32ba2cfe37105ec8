"""XPBD time stepping of rigid, soft and static bodies with the unified triangle-pair
contacts (DESIGN.md §3). The solver only sequences kernels; each physical step is a
`ti.func` over one body, particle, constraint or contact.

One substep of length h:
1. predict: v += h·(g + F/m), x_prev = x, x += h·v; ω += h·I⁻¹(−ω × Iω), q += h/2·[ω,0]⊗q;
2. contacts: every intersecting triangle pair of different bodies (not both static)
   gives C, the push normal N and the deepest point of the moved triangle
   (Kikuchi & Kanai Eq. 6); the constraint ties that point to the point C·N
   further on, which lies on the other triangle, both kept as barycentric anchors;
3. `iterations` Gauss-Seidel sweeps: soft edges and volumes (XPBD), contact normals
   (C = N·(p_other − p_moved) ≥ 0 with generalised inverse masses), then static friction
   as a positional constraint on the slip the normals left (Müller et al. 2020 §3.5);
4. velocities v = (x − x_prev)/h, ω from q ⊗ q_prev⁻¹;
5. `iterations` sweeps of the velocity pass per active contact: restitution and dynamic
   friction (Müller 2020 §3.6, with accumulated, Coulomb-clamped friction impulses).

Contacts are projected serially (Gauss-Seidel), which is race-free and stays stable
with hundreds of contacts on one body. Velocities are staggered half a substep
(leapfrog): the very first predict of a run adds only h/2·a, so free flight under
constant acceleration reproduces x0 + v0·t + a·t²/2 exactly, not with the O(h)
error of symplectic Euler.

Small scenes run a whole frame (all its substeps) in one kernel with an in-kernel
all-pairs box test; large ones use the uniform-grid `CollisionPipeline` each substep.
"""

import time

import numpy as np
import taichi as ti

from ..core import runtime
from ..collision.broadphase import BOX_SLACK, boxes_overlap
from ..collision.pipeline import CollisionPipeline
from .constraints import edge_length, tet_volume6, xpbd_delta_lambda
from ..collision.contacts import ContactConstraints
from ..core.geometry import barycentric, longest_edge_sq
from ..core.model import RIGID, SOFT, STATIC, Model, State, mat_field, scalar_field, vec_field
from ..collision.narrowphase import collide_triangle_pair, pressed_through, touching_planes
from ..core.rigid import (apply_positional_impulse, apply_velocity_impulse, carried_angular_velocity,
                    generalized_inv_mass, inv_mass_matrix_world, quat_matrix, quat_rotate, rotate_by,
                    world_times)
from .tunnelling import TUNNEL_FRACTION

vec3 = ti.math.vec3
mat3 = ti.math.mat3
vec4 = ti.math.vec4
ivec2 = ti.types.vector(2, ti.i32)
ivec3 = ti.types.vector(3, ti.i32)

# Above this many triangle pairs between body boxes (summed over body pairs, upper
# bound) a substep uses the uniform grid instead of the in-kernel all-pairs test.
BRUTE_FORCE_MAX_PAIRS = 200_000
# Contacts are checked for duplicates while the buffer holds at most this many rows (each
# check walks the moved body's rows, so one body with thousands of contacts is quadratic;
# large scenes' contacts rarely share points exactly).
DEDUP_MAX_ROWS = 4096
# The grid path bins moving boxes inflated by this fraction of a grid cell and reuses the
# candidate pairs until a vertex has moved that far (the contacts are exact either way).
# On the pile (benchmarks/large_scenes.py, first second) 0.1 took 50 s per simulated
# second, 0.25 60 s, 0.5 74 s (more candidates for the narrow phase), 0 (rebin every
# substep) 177 s.
GRID_SKIN = 0.1
# Depth a contact did not make during its own substep (older penetration, or a depth
# measured along a poor normal at a degenerate feature) is undone at most this fast (m/s,
# times √length_scale: motions of a scene scaled by L are √L as fast): pushing it out in
# one substep turns it into a launch velocity of depth/h.
DEPENETRATION_SPEED = 0.2
# In a contact between bodies stacked on the ground, the lower body holds still when the
# upper one is at least this many times heavier (XPBDSolver.takes_part).
SHOCK_MASS_RATIO = 10.0
# A soft triangle's box is inflated by this fraction of its body's thickness: a patch
# sagged wholly behind a flat face has a box that no longer meets the face's (flat) box,
# and would drop out of the broad phase before pressed_through could see it. The contacts
# keep a sag to about one substep's motion, far below this; 5% (5 cm on the soft ball)
# doubled the soft ball's stepping time in candidate pairs.
SOFT_BOX_MARGIN = 0.01
# Contact rows a triangle pair can need: its deepest point and up to three more vertices
# of the moved triangle, and with a soft body up to three of the other's.
VERTEX_ROWS_PER_PAIR = 4
VERTEX_ROWS_PER_PAIR_SOFT = 7
# Resting edge rows (add_resting_contacts) go along convex edges of rigid and static bodies whose
# faces' normals differ by more than this.
SHARP_EDGE_DEGREES = 30.0
# A contact row between rigid or static bodies, deeper than one substep's allowance, whose
# point is nearer the plane of a convex neighbour of the other triangle than this fraction of
# its depth leaves through that neighbour instead (XPBDSolver.nearest_exit). Rows within the
# allowance keep their face: re-aimed too, a spike leaning on a block's edge, its points there
# always nearly on the side plane, jittered at 1-3 mm/s (at 0.5 and at 0.01 alike). Edges whose
# faces' normals differ by less than CONVEX_EDGE_DEGREES are not edges of the shape (a flat
# face split in two).
NEAREST_EXIT_FRACTION = 0.01
# A contact row against a static body no deeper than this fraction of its moved triangle's
# longest edge only touches (add_pair_contact): well above f64's rounding, well below a
# substep's sink under gravity; below f32's rounding, where it changes nothing.
TOUCHING_DEPTH = 1e-8
# A resting row against a static body whose point lies on the other body's surface is not made
# when its approach this substep is below this fraction of its depth (add_pair_contact).
SURFACE_APPROACH_FRACTION = 0.01
# Two rows between the same moving bodies push about opposite ways when their pushes on one
# body are within this angle of opposite (keep_rows: neither is carried).
OPPOSED_DEGREES = 30.0
# Inner Gauss-Seidel sweeps (normals alone, then as many with friction) of each island's rows
# per outer sweep, on its bodies linearised at the start of the outer sweep
# (XPBDSolver.solve_blocks): BLOCK_SWEEPS for a lone rigid body against static ones,
# COUPLED_SWEEPS for bodies touching each other, whose island leaves a phase once no row moves
# its anchor by more than COUPLED_TOL of its lever (a stack's Gauss-Seidel converges slowly:
# with opposing rows still carried (keep_rows), a stack of five boxes crept at 1.5e-5 m/s at 64
# sweeps and rested at 128).
BLOCK_SWEEPS = 16
COUPLED_SWEEPS = 128
COUPLED_TOL = 1e-12
CONVEX_EDGE_DEGREES = 1.0
# Resting rows the grid path makes room for per soft vertex (add_resting_contacts): a vertex
# against a face, an edge (two faces) or a corner (three); edge rows share the room.
RESTING_ROWS_PER_SOFT_VERTEX = 3
# A body's or particle's coordinate beyond this many metres counts as an explosion.
DEFAULT_BOUND = 1e6
# _frames_all_pairs's status when the next frame needs more substeps than it was given (not begun),
# and when a frame's contacts overflowed the buffer (undone).
NEEDS_CHOICE = 1
OVERFLOW = 2


class SimulationError(RuntimeError):
    """The simulation produced NaN or left the bounds; message names frame and body."""


@ti.func
def deepest_vertex_behind(p0: vec3, p1: vec3, p2: vec3, q0: vec3, q1: vec3, q2: vec3, n_q: vec3, floor: float,
                          reach: float, tol: float):
    """(depth, vertex) of P's deepest vertex behind Q's plane by more than `floor` and at
    most `reach`, that projects into Q (edges included); depth 0 if none."""
    depth = 0.0
    point = vec3(0.0)
    for p in ti.static([p0, p1, p2]):
        d = n_q.dot(q0 - p)
        if d > floor and d <= reach and d > depth:
            if barycentric(p + d * n_q, q0, q1, q2).min() >= -tol:
                depth, point = d, p
    return depth, point


@ti.func
def friction_in_cone(lam_t: vec3, cap: float) -> vec3:
    """An accumulated friction multiplier or impulse shortened to |λ_t| ≤ cap = μ·λ_n (the
    Coulomb cone). Clamped rather than all-or-nothing: several contacts of one face share the
    load unevenly, and dropping a contact's whole correction when its own share is exceeded
    makes a box stick-slip down a gentle slope."""
    length = lam_t.norm()
    return ti.select(length > cap, lam_t * (cap / ti.select(length > 0.0, length, 1.0)), lam_t)


def convex_edges(model: Model, vertex_x: np.ndarray):
    """Convex edges between two rigid or static triangles of one body: a list of
    (t0, k0, t1, k1, cos) with t0 < t1, edge k0 of t0 (vertex k0 to k0+1) the same as edge
    k1 of t1, cos the dot product of the faces' unit normals. vertex_x (V, 3): any pose
    (rigid motion keeps it)."""
    tri = model.tri_indices_np
    if model.n_tris == 0:
        return []
    p = vertex_x[tri]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    normals = normals / np.where(lengths > 0.0, lengths, 1.0)[:, None]
    rigid = model.body_kind_np[model.tri_body_np] != SOFT
    owner = {}
    for t in np.flatnonzero(rigid):
        for k in range(3):
            a, b = int(tri[t, k]), int(tri[t, (k + 1) % 3])
            owner.setdefault((min(a, b), max(a, b)), []).append((t, k))
    edges = []
    for faces in owner.values():
        if len(faces) != 2:
            continue
        (t0, k0), (t1, k1) = sorted(faces)
        apart = [v for v in range(3) if tri[t1, v] not in tri[t0]]
        if len(apart) != 1 or lengths[t0] == 0.0 or lengths[t1] == 0.0:
            continue
        if normals[t0].dot(p[t1, apart[0]] - p[t0, 0]) < 0.0:
            edges.append((int(t0), k0, int(t1), k1, float(normals[t0].dot(normals[t1]))))
    return edges


def sharp_edge_bits(model: Model, vertex_x: np.ndarray) -> np.ndarray:
    """(T,) int32: bit k set when edge k (vertex k to k+1) of a rigid or static triangle is a
    convex edge whose two faces' normals differ by more than SHARP_EDGE_DEGREES, set on one
    of its two faces only (the lower index). vertex_x (V, 3): any pose."""
    bits = np.zeros(max(model.n_tris, 1), np.int32)
    cos_sharp = np.cos(np.radians(SHARP_EDGE_DEGREES))
    for t0, k0, _, _, cos in convex_edges(model, vertex_x):
        if cos < cos_sharp:
            bits[t0] |= 1 << k0
    return bits


def convex_neighbours(model: Model, vertex_x: np.ndarray) -> np.ndarray:
    """(max(T, 1), 3) int32: the triangle across edge k of each rigid or static triangle when
    that edge is convex by more than CONVEX_EDGE_DEGREES, else -1. vertex_x (V, 3): any pose."""
    nbr = np.full((max(model.n_tris, 1), 3), -1, np.int32)
    cos_edge = np.cos(np.radians(CONVEX_EDGE_DEGREES))
    for t0, k0, t1, k1, cos in convex_edges(model, vertex_x):
        if cos < cos_edge:
            nbr[t0, k0], nbr[t1, k1] = t1, t0
    return nbr


@ti.data_oriented
class XPBDSolver:
    """Advances a State of a Model by frames of `substeps` XPBD substeps.

    gravity: m/s² (3,). broad_phase: "auto" (all-pairs in one kernel per frame for
    small scenes, the uniform grid per substep for large ones), "brute" or "grid".
    contact_capacity: initial size of the contact buffer; it grows when a frame
    overflows it (the frame is then rerun from its start, so no contact is lost).
    length_scale: the scene's size relative to metre-sized bodies (SimConfig.length_scale);
    the depenetration speed scales with its square root.
    """

    def __init__(self, model: Model, state: State, gravity=(0.0, -9.8, 0.0), broad_phase: str = "auto",
                 contact_capacity: int | None = None, bound: float = DEFAULT_BOUND, length_scale: float = 1.0):
        runtime.ensure_init()
        self.model = model
        self.state = state
        self.gravity = np.asarray(gravity, dtype=np.float64).reshape(3)
        self.bound = float(bound)
        self.depenetration_speed = DEPENETRATION_SPEED * float(np.sqrt(length_scale))
        m = model
        kind = m.body_kind_np
        tri_counts = np.array([b.tri_count for b in m.bodies])
        moving = kind != STATIC
        pairs_upper = sum(int(tri_counts[a] * tri_counts[b]) for a in range(m.n_bodies)
                          for b in range(a + 1, m.n_bodies) if moving[a] or moving[b])
        if broad_phase not in ("auto", "brute", "grid"):
            raise ValueError(f"unknown broad_phase {broad_phase!r}: auto, brute or grid")
        self.use_grid = broad_phase == "grid" or (broad_phase == "auto" and pairs_upper > BRUTE_FORCE_MAX_PAIRS)
        self.contacts = ContactConstraints(contact_capacity or max(1024, 4 * m.n_tris))
        # Spin friction is compiled in only where some body has it.
        self.has_spin_friction = bool((m.body_spin_friction.to_numpy()[: m.n_bodies] > 0.0).any())
        self.contact_growths = 0
        rest_x = state.vertex_x.to_numpy()[: m.n_vertices]
        sharp_bits = sharp_edge_bits(m, rest_x) if m.has_soft else None
        nbr = convex_neighbours(m, rest_x)
        with runtime.field_block():  # one SNode tree for the solver's fields
            self.tri_lo = vec_field(m.n_tris)
            self.tri_hi = vec_field(m.n_tris)
            self.body_lo = vec_field(m.n_bodies)
            self.body_hi = vec_field(m.n_bodies)
            self.edge_lambda = scalar_field(m.n_edges) if m.has_soft else None
            self.volume_lambda = scalar_field(m.n_bodies)
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
        if self.use_grid:
            tri_static = kind[m.tri_body_np] == STATIC
            self.pipeline = CollisionPipeline(m.tri_indices_np, m.tri_body_np, tri_static,
                                              pair_capacity=max(1024, 4 * m.n_tris),
                                              contact_capacity=max(1024, m.n_tris), skin=GRID_SKIN,
                                              margin=float(box_margin.max(initial=0.0)), keep_touching=True,
                                              keep_pressed=m.has_soft, tri_hidden=m.tri_hidden_np)
            self.vertex_nd = ti.ndarray(ti.types.vector(3, runtime.real_type()), shape=max(m.n_vertices, 1))
        self.thinnest = min(min(b.thickness for b in m.bodies), 1e30)
        self.soft_vertex_count = int(sum(b.vertex_count for b in m.bodies if b.kind == "soft"))
        self.last_contact_count = 0
        # Set to a dict to have the grid path add up the wall seconds of its phases
        # ("predict", "broad", "narrow", "projection"); costs a sync per phase.
        self.phase_seconds: dict | None = None

    # ------------------------------------------------------------------ anchors
    @ti.func
    def anchor_world(self, t: ti.i32, bary: vec3, prev: ti.template()) -> vec3:
        """World position of the point with barycentric weights `bary` on triangle t,
        now or (prev=True) at the start of the substep."""
        b = self.model.tri_body[t]
        idx = self.model.tri_indices[t]
        p = vec3(0.0)
        if self.model.body_kind[b] == SOFT:
            for k in ti.static(range(3)):
                if ti.static(prev):
                    p += bary[k] * self.state.vertex_x_prev[idx[k]]
                else:
                    p += bary[k] * self.state.vertex_x[idx[k]]
        else:
            r = bary[0] * self.model.vertex_local[idx[0]] + bary[1] * self.model.vertex_local[idx[1]] + bary[2] * self.model.vertex_local[idx[2]]
            if ti.static(prev):
                p = self.state.body_x_prev[b] + quat_rotate(self.state.body_q_prev[b], r)
            else:
                p = self.state.body_x[b] + quat_rotate(self.state.body_q[b], r)
        return p

    @ti.func
    def anchor_velocity(self, t: ti.i32, bary: vec3, p: vec3) -> vec3:
        """Velocity of the anchored point p of triangle t (m/s)."""
        b = self.model.tri_body[t]
        idx = self.model.tri_indices[t]
        v = vec3(0.0)
        kind = self.model.body_kind[b]
        if kind == SOFT:
            if ti.static(self.model.has_soft):
                for k in ti.static(range(3)):
                    v += bary[k] * self.state.vertex_v[idx[k]]
        elif kind == RIGID:
            v = self.state.body_v[b] + self.state.body_w[b].cross(p - self.state.body_x[b])
        return v

    @ti.func
    def anchor_inv_mass(self, t: ti.i32, bary: vec3, p: vec3, n: vec3) -> float:
        """Generalised inverse mass of triangle t's anchored point p along unit n:
        Σ b_k² w_k for a soft triangle, 1/m + (r×n)ᵀI_w⁻¹(r×n) for a rigid body, 0 if static."""
        b = self.model.tri_body[t]
        idx = self.model.tri_indices[t]
        w = 0.0
        kind = self.model.body_kind[b]
        if kind == SOFT:
            for k in ti.static(range(3)):
                w += bary[k] * bary[k] * self.model.vertex_inv_mass[idx[k]]
        elif kind == RIGID:
            w = generalized_inv_mass(self.model.body_inv_mass[b], self.state.body_q[b],
                                     self.model.body_inv_inertia[b], p - self.state.body_x[b], n)
        return w

    @ti.func
    def anchor_move(self, t: ti.i32, bary: vec3, p: vec3, impulse: vec3):
        """Apply a positional impulse (kg·m) at triangle t's anchored point p."""
        b = self.model.tri_body[t]
        idx = self.model.tri_indices[t]
        kind = self.model.body_kind[b]
        if kind == SOFT:
            for k in ti.static(range(3)):
                self.state.vertex_x[idx[k]] += self.model.vertex_inv_mass[idx[k]] * bary[k] * impulse
        elif kind == RIGID:
            # The lever from the substep's starting centre: with the body's end velocity
            # (x − x_prev)/h, that is what keeps angular momentum about any point exact.
            self.state.body_x[b], self.body_theta[b], self.state.body_q[b] = apply_positional_impulse(
                self.state.body_x[b], self.body_theta[b], self.state.body_q_prev[b], self.model.body_inv_mass[b],
                self.model.body_inv_inertia[b], p - self.state.body_x_prev[b], impulse)

    @ti.func
    def anchor_kick(self, t: ti.i32, bary: vec3, p: vec3, impulse: vec3):
        """Apply a velocity impulse (kg·m/s) at triangle t's anchored point p."""
        b = self.model.tri_body[t]
        idx = self.model.tri_indices[t]
        kind = self.model.body_kind[b]
        if kind == SOFT:
            if ti.static(self.model.has_soft):
                for k in ti.static(range(3)):
                    self.state.vertex_v[idx[k]] += self.model.vertex_inv_mass[idx[k]] * bary[k] * impulse
        elif kind == RIGID:
            self.state.body_v[b], self.state.body_w[b] = apply_velocity_impulse(
                self.state.body_v[b], self.state.body_w[b], self.state.body_q[b], self.model.body_inv_mass[b],
                self.model.body_inv_inertia[b], p - self.state.body_x[b], impulse)

    # ---------------------------------------------------------------- predict
    @ti.func
    def predict_body(self, b: ti.i32, h: float, gravity: vec3, kick: float):
        """Explicit prediction of a rigid body's pose (Müller 2020, Alg. 2, lines 4-8);
        kick scales the velocity update (1, or 1/2 on a run's first substep)."""
        if self.model.body_kind[b] == RIGID:
            self.state.body_v[b] += kick * h * (gravity + self.model.body_force[b] * self.model.body_inv_mass[b])
            self.state.body_x_prev[b] = self.state.body_x[b]
            self.state.body_x[b] += h * self.state.body_v[b]
            # ω is already the end-of-substep velocity that keeps L (update_body_velocity).
            self.body_theta[b] = h * self.state.body_w[b]
            self.state.body_q_prev[b] = self.state.body_q[b]
            self.state.body_q[b] = rotate_by(self.state.body_q[b], self.body_theta[b])

    @ti.func
    def predict_particle(self, i: ti.i32, h: float, gravity: vec3, kick: float):
        """Explicit prediction of a soft particle; the body's force is shared equally."""
        w = self.model.vertex_inv_mass[i]
        if w > 0.0:
            b = self.model.vertex_body[i]
            n = self.model.body_vertex_range[b][1] - self.model.body_vertex_range[b][0]
            self.state.vertex_v[i] += kick * h * (gravity + self.model.body_force[b] * (w / n))
            self.state.vertex_x_prev[i] = self.state.vertex_x[i]
            self.state.vertex_x[i] += h * self.state.vertex_v[i]

    @ti.func
    def place_vertex(self, i: ti.i32):
        """World position of a rigid body's vertex from the body's pose."""
        b = self.model.vertex_body[i]
        if self.model.body_kind[b] == RIGID:
            self.state.vertex_x[i] = self.state.body_x[b] + quat_rotate(self.state.body_q[b], self.model.vertex_local[i])

    # --------------------------------------------------------------- contacts
    @ti.func
    def triangle_box(self, t: ti.i32):
        """Box of triangle t padded like the grid's (see broadphase.BOX_SLACK)."""
        idx = self.model.tri_indices[t]
        p0, p1, p2 = self.state.vertex_x[idx[0]], self.state.vertex_x[idx[1]], self.state.vertex_x[idx[2]]
        lo = ti.min(p0, p1, p2)
        hi = ti.max(p0, p1, p2)
        pad = (ti.static(BOX_SLACK * runtime.tolerance()) * (hi - lo).max()
               + self.body_box_margin[self.model.tri_body[t]])
        self.tri_lo[t] = lo - pad
        self.tri_hi[t] = hi + pad

    @ti.func
    def involves_soft(self, t_a: ti.i32, t_b: ti.i32) -> bool:
        return (self.model.body_kind[self.model.tri_body[t_a]] == SOFT
                or self.model.body_kind[self.model.tri_body[t_b]] == SOFT)

    @ti.func
    def write_contact(self, k: ti.i32, t_moved: ti.i32, t_other: ti.i32, depth: float, normal: vec3,
                      point: vec3, max_push: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                      c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                      c_lambda_n: ti.template(), c_lambda_t: ti.template(), c_vn0: ti.template()):
        """Row k: the moved triangle's deepest point and the point C·N further on, on the
        other triangle, as barycentric anchors (Eq. 6 with −∇C = N). Its correction budget
        (m) is the depth the substep's own motion made plus `max_push` of older depth, and
        no more than C itself unless the point is a vertex over the other triangle. With a
        soft body the row holds the depth it may leave instead: the older depth less
        `max_push` (ContactConstraints)."""
        im, io = self.model.tri_indices[t_moved], self.model.tri_indices[t_other]
        bary_m = barycentric(point, self.state.vertex_x[im[0]], self.state.vertex_x[im[1]], self.state.vertex_x[im[2]])
        target = point + depth * normal
        bary_o = barycentric(target, self.state.vertex_x[io[0]], self.state.vertex_x[io[1]], self.state.vertex_x[io[2]])
        approach = self.start_row(k, t_moved, t_other, bary_m, bary_o, normal, point, target, max_push, c_tri,
                                  c_bary_moved, c_bary_other, c_normal, c_budget, c_lambda_n, c_lambda_t, c_vn0)
        if self.involves_soft(t_moved, t_other):
            c_budget[k] = ti.max(depth - approach - max_push, 0.0)
        # A vertex of the moved triangle over the other's face is a plain vertex-face contact,
        # and may correct more than its detected depth when its neighbours turn the body. Any
        # other deepest point (an edge crossing, a feature on a boundary) may carry a depth
        # measured along a poor normal: it corrects at most that depth.
        tol = ti.static(runtime.tolerance())
        at_vertex = bary_m.max() >= 1.0 - tol
        if not (at_vertex and bary_o.min() >= -tol) and not self.involves_soft(t_moved, t_other):
            c_budget[k] = ti.min(depth, c_budget[k])

    @ti.func
    def start_row(self, k: ti.i32, t_moved: ti.i32, t_other: ti.i32, bary_m: vec3, bary_o: vec3, normal: vec3,
                  p_moved: vec3, p_other: vec3, max_push: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                  c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                  c_lambda_n: ti.template(), c_lambda_t: ti.template(), c_vn0: ti.template()) -> float:
        """Row k ties anchor bary_m on t_moved (now at p_moved) to anchor bary_o on t_other (now at
        p_other) along the normal N: links it into the moved body's row chain, clears its
        multipliers, keeps the anchors' normal velocity before projection, and gives it the
        budget (m) max(approach, 0) + max_push. Returns the approach: how much
        N·(p_other − p_moved) grew during this substep."""
        body_m = self.model.tri_body[t_moved]
        c_tri[k] = ivec3(t_moved, t_other, self.body_last_row[body_m])
        self.body_last_row[body_m] = k
        c_bary_moved[k] = bary_m
        c_bary_other[k] = bary_o
        c_normal[k] = normal
        approach = self.closing(t_moved, t_other, bary_m, bary_o, normal, p_moved, p_other)
        c_budget[k] = ti.max(approach, 0.0) + max_push
        c_lambda_n[k] = 0.0
        c_lambda_t[k] = vec3(0.0)
        c_vn0[k] = (self.anchor_velocity(t_moved, bary_m, p_moved)
                    - self.anchor_velocity(t_other, bary_o, p_other)).dot(normal)
        return approach

    @ti.func
    def candidate_pairs(self, c_tri: ti.template()) -> ti.i32:
        """Serial all-pairs broad phase: triangle pairs of different bodies (not both static),
        neither a hidden static face, whose padded boxes overlap, written to c_tri; returns
        their number (more than the capacity on overflow)."""
        n_b = ti.static(self.model.n_bodies)
        for t in range(ti.static(self.model.n_tris)):
            self.triangle_box(t)
        for b in range(n_b):
            lo = vec3(ti.math.inf)
            hi = vec3(-ti.math.inf)
            for t in range(self.model.body_tri_range[b][0], self.model.body_tri_range[b][1]):
                lo = ti.min(lo, self.tri_lo[t])
                hi = ti.max(hi, self.tri_hi[t])
            self.body_lo[b] = lo
            self.body_hi[b] = hi
        n = 0
        capacity = c_tri.shape[0]
        for ba in range(n_b):
            for bb in range(ba + 1, n_b):
                if ((self.model.body_kind[ba] != STATIC or self.model.body_kind[bb] != STATIC)
                        and boxes_overlap(self.body_lo[ba], self.body_hi[ba], self.body_lo[bb], self.body_hi[bb])):
                    for ta in range(self.model.body_tri_range[ba][0], self.model.body_tri_range[ba][1]):
                        if (self.model.tri_hidden[ta] == 0
                                and boxes_overlap(self.tri_lo[ta], self.tri_hi[ta], self.body_lo[bb], self.body_hi[bb])):
                            for tb in range(self.model.body_tri_range[bb][0], self.model.body_tri_range[bb][1]):
                                if (self.model.tri_hidden[tb] == 0
                                        and boxes_overlap(self.tri_lo[ta], self.tri_hi[ta], self.tri_lo[tb], self.tri_hi[tb])):
                                    if n < capacity:
                                        c_tri[n] = ivec3(ta, tb, -1)
                                    n += 1
        return n

    @ti.func
    def collide_candidates(self, n_candidates: ti.i32, max_push: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                           c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                           c_lambda_n: ti.template(), c_lambda_t: ti.template(), c_vn0: ti.template()) -> ti.i32:
        """The unified narrow phase on the candidate pairs in c_tri, compacted in place into
        contact rows (serial: row n <= candidate k is written after k is read); returns the count."""
        self.forget_rows()
        n = 0
        for k in range(n_candidates):
            ab = ivec2(c_tri[k][0], c_tri[k][1])
            ia, ib = self.model.tri_indices[ab[0]], self.model.tri_indices[ab[1]]
            hit, depth, normal, side, point = collide_triangle_pair(
                self.state.vertex_x[ia[0]], self.state.vertex_x[ia[1]], self.state.vertex_x[ia[2]],
                self.state.vertex_x[ib[0]], self.state.vertex_x[ib[1]], self.state.vertex_x[ib[2]])
            n = self.add_pair_contact(n, ab, side, depth, normal, point, max_push, c_tri, c_bary_moved,
                                      c_bary_other, c_normal, c_budget, c_lambda_n, c_lambda_t, c_vn0)
        return n

    @ti.func
    def add_pair_contact(self, n: ti.i32, ab: ivec2, side: ti.i32, depth: float, normal: vec3, point: vec3,
                         max_push: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                         c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                         c_lambda_n: ti.template(), c_lambda_t: ti.template(), c_vn0: ti.template()) -> ti.i32:
        """Row n from the narrow phase's result for the pair ab (side, depth, normal, point as
        collide_triangle_pair returns them), or where that has no constraint from the
        touching test; nothing if the row would repeat an earlier one. Returns the row count."""
        t_m, t_o = ab[0], ab[1]
        if side == 1:
            t_m, t_o = ab[1], ab[0]
        if side < 0:
            found, t_m, t_o, depth, normal, point = self.touching_pair_contact(ab[0], ab[1])
            side = ti.select(found, 0, -1)
        rows = n
        on_surface = False
        keep = side >= 0
        touching = False
        if side >= 0:
            if not self.involves_soft(t_m, t_o):
                both_moving = (self.model.body_kind[self.model.tri_body[t_m]] != STATIC
                               and self.model.body_kind[self.model.tri_body[t_o]] != STATIC)
                # A row within the allowance is resting contact: its own face is the exit.
                if depth > max_push:
                    # A grazing row between two moving bodies: a depth this substep's motion
                    # cannot have made, to a target outside the moved body. A box resting on a
                    # free box turned 7° from it sinks ~1e-5 m a substep, and its side faces then
                    # cross the lower box's side faces in strips that high near its top corners;
                    # Eq. 6 measured those pairs from a corner of one box, outside the other,
                    # pushed onto the other's side plane (0.03-0.24 m sideways), with the point on
                    # the lower box's top plane, and the sideways pushes kept the upper box
                    # jittering at 0.01-0.1 m/s. A wedge's rows at a crack's rim look alike but
                    # reach a rim inside the wedge: they keep their depth (held at depth 0 without
                    # the target test, the wedge ended 1 mm inside the crack block; dropped, 8 mm).
                    # Rows against static bodies are left to the static blocks: held, the pile
                    # crept and `wedges` x1e3 parted from x1 at its first contact.
                    # (Nested: Taichi evaluates both sides of `and`.)
                    may_hold = False
                    if both_moving:
                        may_hold = (depth > max_push + self.approach(t_m, t_o, point, depth, normal)
                                    and not self.target_inside(t_m, point + depth * normal))
                    t_o, depth, normal, on_surface = self.nearest_exit(t_o, point, depth, normal, may_hold)
                else:
                    # A resting row against a static body whose point lies on the other body's
                    # surface (on a convex neighbour's plane: nearest_exit) and has not moved
                    # along the row's normal this substep (approach below SURFACE_APPROACH_FRACTION
                    # of the depth) is no penetration: the depth is measured across the surface,
                    # not along the way the point came. A box set on a block of its own footprint
                    # sinks ~7 µm a substep into the block's top; where its bottom edges meet the
                    # block's vertical edges, pairs of its side faces with the block's side faces
                    # around the corner measured those 7 µm sideways, and pushed the box 0.1 mm
                    # sideways and tilted it. (Dropped whenever the approach made less than half the depth,
                    # rows of the pile's loaded bodies went too, and it ended 1 mm deep; between
                    # moving bodies, where held rows do this, a stack of five boxes crept at
                    # 3e-4 m/s instead of 3e-5.)
                    if not both_moving:
                        t_exit, d_exit, n_exit, on_other = self.nearest_exit(t_o, point, depth, normal, True)
                        if on_other:
                            keep = self.approach(t_m, t_o, point, depth, normal) >= SURFACE_APPROACH_FRACTION * depth
                depth, normal = self.edge_edge_normal(t_m, t_o, point, depth, normal)
                # A row against a static body this shallow only touches. Like a duplicate it
                # gives way to a vertex of its triangle behind the other's face by at most as
                # much (below): at coincident edges (the same box's vertical edges on the
                # block's) the rows at points along the edges came in pairs pushing opposite
                # ways, whose multipliers grew to 7 times the box's weight per substep and let
                # go at once 45 ms later (a 0.1 mm jump); at the vertices they stay below a
                # third of it.
                if not both_moving:
                    touching = depth <= TOUCHING_DEPTH * self.longest_edge(t_m)
        if keep:
            # (Not `or`: Taichi would walk the row chain for a touching row too.)
            duplicate = touching
            if not touching:
                duplicate = self.is_duplicate(n, t_m, t_o, normal, point, c_tri, c_bary_moved, c_normal)
            if duplicate:
                # The deepest point is a vertex another pair already made a row of (or the row
                # only touches). Another candidate vertex of this triangle takes the row
                # instead: without a row here, add_vertex_contacts would never visit this
                # triangle, and a vertex all of whose triangles lost their rows so would sink
                # unopposed (seen: one vertex of a soft cube's bottom face, held 8 µm deep).
                depth, point = self.next_vertex_over_face(n, t_m, t_o, normal, depth, c_tri, c_bary_moved,
                                                          c_normal)
                duplicate = depth <= 0.0
            if not duplicate:
                self.write_contact(n, t_m, t_o, depth, normal, point, max_push, c_tri, c_bary_moved, c_bary_other,
                                   c_normal, c_budget, c_lambda_n, c_lambda_t, c_vn0)
                if on_surface:
                    # Its depth is 0 by construction: whatever it corrects, the solve made, so it
                    # has no budget to spend. With the usual one, rows of other pairs pushed a
                    # pile's wedge into its neighbour once the held rows had spent it (probed:
                    # 7.6-8.2e-4 m deep, nothing left to correct), and the two sank 0.9 mm into
                    # each other by 7 s.
                    c_budget[n] = ti.math.inf
                rows += 1
        return rows

    @ti.func
    def nearest_exit(self, t_other: ti.i32, point: vec3, depth: float, normal: vec3, may_hold: bool):
        """The face a contact's point leaves the other body through: t_other's plane, where
        the narrow phase measured `depth` along `normal`, or the plane of a convex neighbour
        of t_other (tri_convex_nbr) behind which the point lies by less than
        NEAREST_EXIT_FRACTION of that. Eq. 6 sees one pair: a wedge resting on a block's
        edge sinks ~1e-5 m a substep into the top face, its end faces then cross the block's
        side face, and the pair's depth is how far the wedge's base reaches in past the side
        (0.24 m), not the 1e-5 m it is below the top; pushed along the side's normal every
        substep, the wedge crept off the edge. A point on a convex neighbour's plane (within
        rounding) is on the other body's surface, not in it; where the caller found the row
        a grazing one (`may_hold`: add_pair_contact), it becomes a row along that
        neighbour's normal at depth 0, holding the point there. Returns (triangle, depth,
        unit normal, whether the point is held on the surface)."""
        tol = ti.static(runtime.tolerance())
        t_best, d_best, n_best = t_other, depth, normal
        on_surface = False
        t_surface, n_surface = t_other, normal
        nbr = self.tri_convex_nbr[t_other]
        for k in ti.static(range(3)):
            t = nbr[k]
            if t >= 0:
                idx = self.model.tri_indices[t]
                q0, q1, q2 = self.state.vertex_x[idx[0]], self.state.vertex_x[idx[1]], self.state.vertex_x[idx[2]]
                raw = (q1 - q0).cross(q2 - q0)
                length = raw.norm()
                if length > 0.0:
                    n_t = raw / length
                    d = n_t.dot(q0 - point)
                    # A point on the neighbour's plane up to rounding (coplanar faces: the
                    # end faces of the parallel wedges) is not nearer it: which sign rounding
                    # gives differs when the scene is scaled or moved.
                    floor = tol * ti.sqrt(longest_edge_sq(q0, q1, q2))
                    if d > floor and d < NEAREST_EXIT_FRACTION * depth and d < d_best:
                        t_best, d_best, n_best = t, d, n_t
                    elif ti.abs(d) <= floor and not on_surface and may_hold:
                        on_surface = True
                        t_surface, n_surface = t, n_t
        if on_surface:
            t_best, d_best, n_best = t_surface, 0.0, n_surface
        return t_best, d_best, n_best, on_surface

    @ti.func
    def longest_edge(self, t: ti.i32) -> float:
        """Length of triangle t's longest edge (m)."""
        idx = self.model.tri_indices[t]
        return ti.sqrt(longest_edge_sq(self.state.vertex_x[idx[0]], self.state.vertex_x[idx[1]],
                                       self.state.vertex_x[idx[2]]))

    @ti.func
    def target_inside(self, t_moved: ti.i32, target: vec3) -> bool:
        """Whether `target` lies behind t_moved's plane by more than rounding."""
        tol = ti.static(runtime.tolerance())
        im = self.model.tri_indices[t_moved]
        m0, m1, m2 = self.state.vertex_x[im[0]], self.state.vertex_x[im[1]], self.state.vertex_x[im[2]]
        raw = (m1 - m0).cross(m2 - m0)
        length = raw.norm()
        return length > 0.0 and raw.dot(m0 - target) > tol * ti.sqrt(longest_edge_sq(m0, m1, m2)) * length

    @ti.func
    def approach(self, t_moved: ti.i32, t_other: ti.i32, point: vec3, depth: float, normal: vec3) -> float:
        """How much a row from `point` on t_moved to point + depth·normal on t_other closed
        along the normal during this substep (m; start_row's approach)."""
        im, io = self.model.tri_indices[t_moved], self.model.tri_indices[t_other]
        target = point + depth * normal
        bary_m = barycentric(point, self.state.vertex_x[im[0]], self.state.vertex_x[im[1]], self.state.vertex_x[im[2]])
        bary_o = barycentric(target, self.state.vertex_x[io[0]], self.state.vertex_x[io[1]],
                             self.state.vertex_x[io[2]])
        return self.closing(t_moved, t_other, bary_m, bary_o, normal, point, target)

    @ti.func
    def closing(self, t_moved: ti.i32, t_other: ti.i32, bary_m: vec3, bary_o: vec3, normal: vec3, p_moved: vec3,
                p_other: vec3) -> float:
        """How much N·(p_other − p_moved) grew during this substep (m), for anchors bary_m on
        t_moved (now at p_moved) and bary_o on t_other (now at p_other)."""
        return normal.dot((p_other - self.anchor_world(t_other, bary_o, True))
                          - (p_moved - self.anchor_world(t_moved, bary_m, True)))

    @ti.func
    def convex_edge_at(self, t: ti.i32, x: vec3) -> vec3:
        """The direction of the convex edge of triangle t (tri_convex_nbr) that x lies on
        (within √eps in barycentric weight, not at a vertex); zero if none."""
        idx = self.model.tri_indices[t]
        q = [self.state.vertex_x[idx[0]], self.state.vertex_x[idx[1]], self.state.vertex_x[idx[2]]]
        bary = barycentric(x, q[0], q[1], q[2])
        tol = ti.static(ti.sqrt(runtime.machine_eps()))
        nbr = self.tri_convex_nbr[t]
        edge = vec3(0.0)
        for j in ti.static(range(3)):
            k = ti.static((j + 1) % 3)  # the edge opposite vertex j runs from vertex k to k+1
            k1 = ti.static((j + 2) % 3)
            if ti.abs(bary[j]) <= tol and bary[k] > tol and bary[k1] > tol and nbr[k] >= 0:
                edge = q[k1] - q[k]
        return edge

    @ti.func
    def edge_edge_normal(self, t_moved: ti.i32, t_other: ti.i32, point: vec3, depth: float, normal: vec3):
        """A contact whose point is an edge crossing, on a convex edge of the moved
        triangle, and whose target point + depth·normal is on a convex edge of the other, is
        two edges of the shapes meeting: it is pushed along e_m × e_o (oriented as `normal`),
        by the distance between the edge lines along it, depth·(N_ee·N). Eq. 6 gives one
        face's normal instead: a wedge leaning on a block's top edge got rows along the block's
        side and top normals from its end face, pushing it away from the block every substep,
        and it slid down at 5.7 mm/s. Returns (depth, unit normal)."""
        e_m = self.convex_edge_at(t_moved, point)
        e_o = self.convex_edge_at(t_other, point + depth * normal)
        n_ee = e_m.cross(e_o)
        length = n_ee.norm()
        d_out, n_out = depth, normal
        if length > 1e-3 * e_m.norm() * e_o.norm():  # false when either is no edge (zero)
            n_ee = n_ee / length
            cos = n_ee.dot(normal)
            if cos < 0.0:
                n_ee, cos = -n_ee, -cos
            if cos > 0.0:
                d_out, n_out = depth * cos, n_ee
        return d_out, n_out

    @ti.func
    def next_vertex_over_face(self, n: ti.i32, t_moved: ti.i32, t_other: ti.i32, normal: vec3, max_depth: float,
                              c_tri: ti.template(), c_bary_moved: ti.template(), c_normal: ti.template()):
        """The deepest vertex of t_moved behind t_other's plane (unit normal `normal`) by
        0 < d ≤ max_depth·(1 + tol), projecting onto t_other (edges included) and not yet a
        row of rows [0, n). Returns (d, vertex); d = 0 if there is none."""
        tol = ti.static(runtime.tolerance())
        im, io = self.model.tri_indices[t_moved], self.model.tri_indices[t_other]
        o0, o1, o2 = self.state.vertex_x[io[0]], self.state.vertex_x[io[1]], self.state.vertex_x[io[2]]
        best = 0.0
        vertex = vec3(0.0)
        for k in ti.static(range(3)):
            v = self.state.vertex_x[im[k]]
            d = normal.dot(o0 - v)
            if d > best and d <= max_depth * (1.0 + tol):
                if barycentric(v + d * normal, o0, o1, o2).min() >= -tol and not self.is_duplicate(
                        n, t_moved, t_other, normal, v, c_tri, c_bary_moved, c_normal):
                    best, vertex = d, v
        return best, vertex

    @ti.func
    def touching_pair_contact(self, t_a: ti.i32, t_b: ti.i32):
        """A contact the narrow phase reports as touching: one triangle crosses the other's
        plane while the other only touches its plane (a vertex or an edge in it,
        supplement Fig. 8). Alone, such a pair has no depth; between bodies it can hide a
        real one: a box set down exactly on a block of the same footprint has its side
        faces in the block's side planes, so every pair it forms with the block touches,
        and the box would sink through unopposed. Returns (found, moved triangle, other
        triangle, depth, normal, point): the crossing triangle's deepest vertex behind the
        touching one, by more than tol·L and at most half the touching body's thickness,
        projecting into it (edges included); add_vertex_contacts adds its other vertices.
        With a soft body, failing that, a pair pressed through each other (a soft patch
        sagged wholly behind a face, narrowphase.pressed_through) gives the same contact
        for the triangle behind the other's plane."""
        ia, ib = self.model.tri_indices[t_a], self.model.tri_indices[t_b]
        a0, a1, a2 = self.state.vertex_x[ia[0]], self.state.vertex_x[ia[1]], self.state.vertex_x[ia[2]]
        b0, b1, b2 = self.state.vertex_x[ib[0]], self.state.vertex_x[ib[1]], self.state.vertex_x[ib[2]]
        tol = ti.static(runtime.tolerance())
        t_m, t_o = t_a, t_b
        depth = 0.0
        normal = vec3(0.0)
        point = vec3(0.0)
        static_a = self.model.body_kind[self.model.tri_body[t_a]] == STATIC
        static_b = self.model.body_kind[self.model.tri_body[t_b]] == STATIC
        which, n_a, n_b, floor = touching_planes(a0, a1, a2, b0, b1, b2)
        # The crossing triangle moves: a static one would push the other body from its
        # own side, a second copy of the same contact.
        which = ti.select((which == 0 and static_a) or (which == 1 and static_b), -1, which)
        if which < 0 and self.involves_soft(t_a, t_b):
            # A soft patch sagged through a face: the triangle behind the other's plane moves.
            a_behind, b_behind, n_a, n_b, floor = pressed_through(a0, a1, a2, b0, b1, b2)
            which = ti.select(a_behind and not static_a, 0, ti.select(b_behind and not static_b, 1, -1))
        if which == 0:
            depth, point = deepest_vertex_behind(a0, a1, a2, b0, b1, b2, n_b, floor,
                                                 0.5 * self.body_thickness[self.model.tri_body[t_b]], tol)
            normal = n_b
        elif which == 1:
            depth, point = deepest_vertex_behind(b0, b1, b2, a0, a1, a2, n_a, floor,
                                                 0.5 * self.body_thickness[self.model.tri_body[t_a]], tol)
            normal = n_a
            t_m, t_o = t_b, t_a
        found = depth > 0.0
        return found, t_m, t_o, depth, normal, point

    @ti.func
    def vertex_over_face(self, total: ti.i32, t_moved: ti.i32, t_other: ti.i32, v: vec3, normal: vec3, q0: vec3,
                         q1: vec3, q2: vec3, min_depth: float, max_depth: float, max_push: float,
                         c_tri: ti.template(), c_bary_moved: ti.template(), c_bary_other: ti.template(),
                         c_normal: ti.template(), c_budget: ti.template(), c_lambda_n: ti.template(),
                         c_lambda_t: ti.template(), c_vn0: ti.template()) -> ti.i32:
        """Vertex v of t_moved as a contact against the face (q0, q1, q2) of t_other, plane
        normal `normal`: when it lies behind the plane by min_depth < d ≤ max_depth (negative:
        in front), projects onto the face (edges included) and is not already a row. Writes
        row `total` if it fits; returns the rows needed so far."""
        tol = ti.static(runtime.tolerance())
        rows = total
        d = normal.dot(q0 - v)
        if d > min_depth and d <= max_depth:
            w = barycentric(v + d * normal, q0, q1, q2)
            if w.min() >= -tol and not self.is_duplicate(ti.min(rows, c_tri.shape[0]), t_moved, t_other, normal, v,
                                                         c_tri, c_bary_moved, c_normal):
                if rows < c_tri.shape[0]:
                    self.write_contact(rows, t_moved, t_other, d, normal, v, max_push, c_tri, c_bary_moved,
                                       c_bary_other, c_normal, c_budget, c_lambda_n, c_lambda_t, c_vn0)
                rows += 1
        return rows

    @ti.func
    def add_vertex_contacts(self, n: ti.i32, max_push: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                            c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                            c_lambda_n: ti.template(), c_lambda_t: ti.template(), c_vn0: ti.template()) -> ti.i32:
        """After the n contacts of the narrow phase: every other vertex of a moved triangle that
        is one of its candidate points too (behind the other triangle's plane along N, no
        deeper than the contact's C, projecting inside the other triangle) becomes a contact
        with its own depth. Eq. 6 keeps only the deepest candidate; a face resting on a face
        then hangs on one corner per triangle pair and tilts into the support by about one
        substep of gravity. Rows go after row n-1 while they fit; returns the rows needed."""
        total = n
        tol = ti.static(runtime.tolerance())
        for j in range(n):
            tri = c_tri[j]
            normal = c_normal[j]
            p_m = self.anchor_world(tri[0], c_bary_moved[j], False)
            p_o = self.anchor_world(tri[1], c_bary_other[j], False)
            depth_main = normal.dot(p_o - p_m)
            im, io = self.model.tri_indices[tri[0]], self.model.tri_indices[tri[1]]
            o0, o1, o2 = self.state.vertex_x[io[0]], self.state.vertex_x[io[1]], self.state.vertex_x[io[2]]
            for k in ti.static(range(3)):
                total = self.vertex_over_face(total, tri[0], tri[1], self.state.vertex_x[im[k]], normal, o0, o1, o2,
                                              0.0, depth_main * (1.0 + tol), max_push, c_tri, c_bary_moved, c_bary_other,
                                              c_normal, c_budget, c_lambda_n, c_lambda_t, c_vn0)
            # A soft triangle moved along a sharp feature's face normal can slide off the
            # feature sideways while the feature's vertex stays inside it: the membrane
            # wraps a spike's apex. The other triangle's vertices behind the soft one's
            # plane (over its face, within half its body's thickness) push it out too.
            b_m = self.model.tri_body[tri[0]]
            if self.model.body_kind[b_m] == SOFT:
                m0, m1, m2 = self.state.vertex_x[im[0]], self.state.vertex_x[im[1]], self.state.vertex_x[im[2]]
                cross_m = (m1 - m0).cross(m2 - m0)
                if cross_m.norm() > 0.0:
                    n_m = cross_m.normalized()
                    for k in ti.static(range(3)):
                        total = self.vertex_over_face(total, tri[1], tri[0], self.state.vertex_x[io[k]], n_m, m0, m1,
                                                      m2, 0.0, 0.5 * self.body_thickness[b_m], max_push, c_tri,
                                                      c_bary_moved, c_bary_other, c_normal, c_budget, c_lambda_n,
                                                      c_lambda_t, c_vn0)
        return total

    @ti.func
    def add_resting_contacts(self, total: ti.i32, max_push: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                             c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                             c_lambda_n: ti.template(), c_lambda_t: ti.template(), c_vn0: ti.template()) -> ti.i32:
        """Rows for soft vertices resting on a face of a rigid or static body: in front of
        the face's plane by at most SOFT_BOX_MARGIN of the soft body's thickness, projecting
        onto the face, and not already a row. (Not behind it: beside a convex edge a vertex
        outside the body is behind the other face's plane.) The unified test only sees pairs
        that cross; a membrane held against a face by its volume constraint sits at depth 0
        after its correction, gets no row in the next substep, is pressed in again, and
        chatters (a ball draped on a spike: 8 mm/s). With a row the inequality C ≥ 0 holds
        it in every sweep; a row in front of the face does nothing until it is crossed.
        Sharp convex edges of rigid and static bodies get rows against the soft triangles
        over them likewise (edge_under_soft_triangle). Rows go after row total-1 while they
        fit; returns the rows needed."""
        rows = total
        if ti.static(self.model.has_soft):
            for i in range(ti.static(self.model.n_vertices)):
                b_s = self.model.vertex_body[i]
                if self.model.body_kind[b_s] == SOFT:
                    v = self.state.vertex_x[i]
                    skin = ti.static(SOFT_BOX_MARGIN) * self.body_thickness[b_s]
                    t_m = self.vertex_tri[i]
                    for b in range(ti.static(self.model.n_bodies)):
                        if self.model.body_kind[b] != SOFT:
                            for t in range(self.model.body_tri_range[b][0], self.model.body_tri_range[b][1]):
                                if self.model.tri_hidden[t] == 0:
                                    io = self.model.tri_indices[t]
                                    q0, q1, q2 = (self.state.vertex_x[io[0]], self.state.vertex_x[io[1]],
                                                  self.state.vertex_x[io[2]])
                                    if (v >= ti.min(q0, q1, q2) - skin).all() and (v <= ti.max(q0, q1, q2) + skin).all():
                                        cross = (q1 - q0).cross(q2 - q0)
                                        if cross.norm() > 0.0:
                                            rows = self.vertex_over_face(rows, t_m, t, v, cross.normalized(), q0, q1,
                                                                         q2, -skin, 0.0, max_push, c_tri,
                                                                         c_bary_moved, c_bary_other, c_normal,
                                                                         c_budget, c_lambda_n, c_lambda_t, c_vn0)
            # The same for the sharp edges of rigid and static bodies under soft triangles: a
            # membrane draped over an edge is cut by it between its vertices.
            for t_s in range(ti.static(self.model.n_tris)):
                b_s = self.model.tri_body[t_s]
                if self.model.body_kind[b_s] == SOFT:
                    skin = ti.static(SOFT_BOX_MARGIN) * self.body_thickness[b_s]
                    im = self.model.tri_indices[t_s]
                    p0, p1, p2 = self.state.vertex_x[im[0]], self.state.vertex_x[im[1]], self.state.vertex_x[im[2]]
                    lo, hi = ti.min(p0, p1, p2) - skin, ti.max(p0, p1, p2) + skin
                    cross = (p1 - p0).cross(p2 - p0)
                    if cross.norm() > 0.0:
                        n_s = cross.normalized()
                        for b in range(ti.static(self.model.n_bodies)):
                            if self.model.body_kind[b] != SOFT:
                                for t in range(self.model.body_tri_range[b][0], self.model.body_tri_range[b][1]):
                                    if self.tri_sharp_edges[t] != 0 and self.model.tri_hidden[t] == 0:
                                        rows = self.edge_under_soft_triangle(rows, t_s, t, p0, p1, p2, n_s, lo, hi,
                                                                             skin, max_push, c_tri, c_bary_moved,
                                                                             c_bary_other, c_normal, c_budget,
                                                                             c_lambda_n, c_lambda_t, c_vn0)
        return rows

    @ti.func
    def edge_under_soft_triangle(self, total: ti.i32, t_s: ti.i32, t: ti.i32, p0: vec3, p1: vec3, p2: vec3,
                                 n_s: vec3, lo: vec3, hi: vec3, skin: float, max_push: float,
                                 c_tri: ti.template(), c_bary_moved: ti.template(), c_bary_other: ti.template(),
                                 c_normal: ti.template(), c_budget: ti.template(), c_lambda_n: ti.template(),
                                 c_lambda_t: ti.template(), c_vn0: ti.template()) -> ti.i32:
        """Rows for the sharp edges of triangle t under soft triangle t_s = (p0, p1, p2), unit
        normal n_s: the part of the edge whose projection along n_s falls in t_s (clipped
        against t_s's three edge lines), at its end nearest to t_s's back, when that end is
        within `skin` of t_s's plane in front or behind. The row moves t at that point along
        n_s (C = n_s·(p_soft − q) ≥ 0: the edge stays outside the soft body), which pushes
        only t_s when t is static."""
        rows = total
        io = self.model.tri_indices[t]
        bits = self.tri_sharp_edges[t]
        pts = [p0, p1, p2]
        for k in ti.static(range(3)):
            if (bits >> k) & 1:
                qa, qb = self.state.vertex_x[io[k]], self.state.vertex_x[io[(k + 1) % 3]]
                if (ti.max(qa, qb) >= lo).all() and (ti.min(qa, qb) <= hi).all():
                    t0, t1 = 0.0, 1.0
                    e = qb - qa
                    for i in ti.static(range(3)):
                        inward = n_s.cross(pts[(i + 1) % 3] - pts[i])
                        g0 = inward.dot(qa - pts[i])
                        dg = inward.dot(e)
                        # Keep t with g0 + t·dg ≥ 0.
                        if dg > 0.0:
                            t0 = ti.max(t0, -g0 / dg)
                        elif dg < 0.0:
                            t1 = ti.min(t1, -g0 / dg)
                        elif g0 < 0.0:
                            t1 = -1.0
                    if t0 <= t1:
                        d0 = n_s.dot(qa + t0 * e - p0)
                        d1 = n_s.dot(qa + t1 * e - p0)
                        d = ti.min(d0, d1)
                        q = qa + ti.select(d0 <= d1, t0, t1) * e
                        if ti.abs(d) <= skin and not self.is_duplicate(ti.min(rows, c_tri.shape[0]), t, t_s, n_s, q,
                                                                      c_tri, c_bary_moved, c_normal):
                            if rows < c_tri.shape[0]:
                                self.write_contact(rows, t, t_s, -d, n_s, q, max_push, c_tri, c_bary_moved,
                                                   c_bary_other, c_normal, c_budget, c_lambda_n, c_lambda_t, c_vn0)
                            rows += 1
        return rows

    @ti.func
    def is_duplicate(self, n: ti.i32, t_moved: ti.i32, t_other: ti.i32, normal: vec3, point: vec3,
                     c_tri: ti.template(), c_bary_moved: ti.template(), c_normal: ti.template()) -> bool:
        """Whether rows [0, n) already hold this constraint: same two bodies, same normal and
        the same moved point (within √eps of the moved triangle's size). A vertex or edge shared by
        several triangles is reported by each triangle pair; projecting every copy would weigh
        that point several times and make the Gauss-Seidel result depend on the mesh's
        triangulation (a box dropped flat would spin). Checked only for n <= DEDUP_MAX_ROWS."""
        body_m, body_o = self.model.tri_body[t_moved], self.model.tri_body[t_other]
        size = self.longest_edge(t_moved)
        # Copies of one point computed from different triangles differ by rounding, which
        # no threshold at rounding level separates reliably (the same scene scaled by 1e-3
        # rounds differently): √eps of the triangle's size merges them, and nothing else.
        tol = ti.static(ti.sqrt(runtime.machine_eps()))
        found = False
        if n <= DEDUP_MAX_ROWS:
            # Only rows of the same moved body can match: walk its chain of rows.
            j = self.body_last_row[body_m]
            while j >= 0 and not found:
                tri = c_tri[j]
                if self.model.tri_body[tri[1]] == body_o and c_normal[j].dot(normal) >= 1.0 - tol:
                    p = self.anchor_world(tri[0], c_bary_moved[j], False)
                    found = (p - point).norm() <= tol * size
                j = tri[2]
        return found

    @ti.func
    def keep_rows(self, n: ti.i32, slip_max: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                  c_bary_other: ti.template(), c_normal: ti.template(), c_lambda_n: ti.template()):
        """Remember the rigid and static rows of [0, n) that pushed in this substep (λ_n > 0)
        and whose two anchors lie within slip_max (m) of each other across the normal, for
        carried_rows in the next substep. A row carried before may be carried again: a
        support the detection finds only every few substeps is then held in between; once its
        anchors slide apart (the bodies slip or roll past it) it is let go. So is a row
        between two moving bodies that another row of theirs at the same place pushed back
        against (opposed_row): where a box's bottom edge crosses the lower box's top edge,
        two rows along the boxes' side normals (7° apart, about opposite ways) were carried
        for good, each undoing the other, and kept the boxes' block (solve_blocks) from ever
        converging."""
        count = 0
        for k in range(n):
            tri = c_tri[k]
            if c_lambda_n[k] > 0.0 and not self.involves_soft(tri[0], tri[1]) and count < self.carry_capacity:
                normal = c_normal[k]
                gap = (self.anchor_world(tri[1], c_bary_other[k], False)
                       - self.anchor_world(tri[0], c_bary_moved[k], False))
                keep = (gap - gap.dot(normal) * normal).norm() <= slip_max
                if keep:
                    keep = not self.opposed_row(k, slip_max, c_tri, c_bary_moved, c_normal, c_lambda_n)
                if keep:
                    self.carry_tri[count] = ivec2(tri[0], tri[1])
                    self.carry_bary_moved[count] = c_bary_moved[k]
                    self.carry_bary_other[count] = c_bary_other[k]
                    self.carry_normal[count] = normal
                    count += 1
        self.carry_count[0] = count

    @ti.func
    def opposed_row(self, k: ti.i32, reach: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                    c_normal: ti.template(), c_lambda_n: ti.template()) -> bool:
        """Whether another row of this substep between the same two moving bodies pushed
        (λ_n > 0) about the opposite way (the pushes' directions on one body at more than
        OPPOSED_DEGREES from opposite) with its moved anchor within `reach` (m) of row k's."""
        tri = c_tri[k]
        body_m, body_o = self.model.tri_body[tri[0]], self.model.tri_body[tri[1]]
        found = False
        if self.model.body_kind[body_m] != STATIC and self.model.body_kind[body_o] != STATIC:
            point = self.anchor_world(tri[0], c_bary_moved[k], False)
            cos_opposed = ti.static(np.cos(np.radians(OPPOSED_DEGREES)))
            for side in ti.static(range(2)):
                body, other = (body_m, body_o) if side == 0 else (body_o, body_m)
                j = self.body_last_row[body]
                while j >= 0 and not found:
                    tri_j = c_tri[j]
                    if j != k and self.model.tri_body[tri_j[1]] == other and c_lambda_n[j] > 0.0:
                        # Row j moves `body` along its normal; row k moves body_m along its own.
                        push_j = ti.select(body == body_m, 1.0, -1.0) * c_normal[j]
                        if push_j.dot(c_normal[k]) <= -cos_opposed:
                            p = self.anchor_world(tri_j[0], c_bary_moved[j], False)
                            found = (p - point).norm() <= reach
                    j = tri_j[2]
        return found

    @ti.func
    def has_pair_row(self, t_a: ti.i32, t_b: ti.i32, c_tri: ti.template()) -> bool:
        """Whether a row of this substep already ties triangles t_a and t_b (either moved)."""
        found = False
        for r in ti.static(range(2)):
            t_m, t_o = (t_a, t_b) if r == 0 else (t_b, t_a)
            j = self.body_last_row[self.model.tri_body[t_m]]
            while j >= 0 and not found:
                tri = c_tri[j]
                found = tri[0] == t_m and tri[1] == t_o
                j = tri[2]
        return found

    @ti.func
    def carried_rows(self, total: ti.i32, max_push: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                     c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                     c_lambda_n: ti.template(), c_lambda_t: ti.template(), c_vn0: ti.template()) -> ti.i32:
        """The rows keep_rows remembered from the last substep whose triangle pair has no row
        now, on the same anchors and normal. A body between two supports (a spike lying
        along a groove, on both rims) is pushed off one, into the other, within one
        projection; without the other's row, which detection made before the push, it ends
        the substep inside that one and the next substep pushes it back, a cycle that never
        comes to rest. Such a row holds C = N·(p_other − p_moved) ≥ 0 and does nothing
        unless it is crossed. Rows go after row total-1 while they fit; returns the row count."""
        rows = total
        for j in range(self.carry_count[0]):
            pair = self.carry_tri[j]
            if rows < c_tri.shape[0] and not self.has_pair_row(pair[0], pair[1], c_tri):
                bm, bo, normal = self.carry_bary_moved[j], self.carry_bary_other[j], self.carry_normal[j]
                p_m = self.anchor_world(pair[0], bm, False)
                p_o = self.anchor_world(pair[1], bo, False)
                self.start_row(rows, pair[0], pair[1], bm, bo, normal, p_m, p_o, max_push, c_tri, c_bary_moved,
                               c_bary_other, c_normal, c_budget, c_lambda_n, c_lambda_t, c_vn0)
                rows += 1
        return rows

    @ti.func
    def forget_rows(self):
        """Start a substep's contact rows: no body has a row yet."""
        for b in range(ti.static(self.model.n_bodies)):
            self.body_last_row[b] = -1

    @ti.func
    def compute_levels(self, n_contacts: ti.i32, c_tri: ti.template()):
        """Each body's level in the contact graph: 0 for static bodies, 1 + the lowest level
        of the bodies it touches otherwise, n_bodies for bodies that rest on nothing static
        (shortest paths by repeated relaxation, serial)."""
        n_b = ti.static(self.model.n_bodies)
        for b in range(n_b):
            self.body_level[b] = ti.select(self.model.body_kind[b] == STATIC, 0, n_b)
        changed = True
        rounds = 0
        while changed and rounds < n_b:
            changed = False
            for k in range(n_contacts):
                tri = c_tri[k]
                bm, bo = self.model.tri_body[tri[0]], self.model.tri_body[tri[1]]
                if self.body_level[bo] + 1 < self.body_level[bm]:
                    self.body_level[bm] = self.body_level[bo] + 1
                    changed = True
                if self.body_level[bm] + 1 < self.body_level[bo]:
                    self.body_level[bo] = self.body_level[bm] + 1
                    changed = True
            rounds += 1

    @ti.func
    def takes_part(self, t_self: ti.i32, t_other: ti.i32) -> float:
        """1.0, or 0.0 if triangle t_self's body holds still in its contacts with t_other's:
        shock propagation, for a body nearer the static ground (lower level) under one
        SHOCK_MASS_RATIO times heavier or more. Gauss-Seidel would need about mass-ratio
        sweeps to carry the heavy body's weight down through the light one; meanwhile the
        heavy body drives the light one under the ground it rests on. The light body then
        carries its own weight only: it is not pushed into motion by the heavy one."""
        b_self, b_other = self.model.tri_body[t_self], self.model.tri_body[t_other]
        held = (self.body_level[b_self] < self.body_level[b_other]
                and self.body_mass[b_self] * SHOCK_MASS_RATIO <= self.body_mass[b_other])
        return ti.select(held, 0.0, 1.0)

    @ti.func
    def solve_contact_normal(self, k: ti.i32, c_tri: ti.template(), c_bary_moved: ti.template(),
                             c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                             c_lambda_n: ti.template()):
        """Project contact k: C = N·(p_other − p_moved) ≥ 0 with Δλ = C/(w_moved + w_other),
        w the generalised inverse masses along N (Müller 2020, Eq. 2-9 with α = 0), within
        what is left of the contact's correction budget (m)."""
        tri = c_tri[k]
        bm, bo = c_bary_moved[k], c_bary_other[k]
        n = c_normal[k]
        p_m = self.anchor_world(tri[0], bm, False)
        p_o = self.anchor_world(tri[1], bo, False)
        # Both anchors take the impulse at one point: the pair's torques then cancel
        # exactly and angular momentum is kept (the anchors drift apart sideways).
        p_c = 0.5 * (p_m + p_o)
        gap = n.dot(p_o - p_m)
        soft = self.involves_soft(tri[0], tri[1])
        c = ti.select(soft, gap - c_budget[k], ti.min(gap, c_budget[k]))
        if c > 0.0:
            f_m, f_o = self.takes_part(tri[0], tri[1]), self.takes_part(tri[1], tri[0])
            w = f_m * self.anchor_inv_mass(tri[0], bm, p_m, n) + f_o * self.anchor_inv_mass(tri[1], bo, p_o, n)
            if w > 0.0:
                dl = c / w
                self.anchor_move(tri[0], bm, p_c, f_m * dl * n)
                self.anchor_move(tri[1], bo, p_c, -f_o * dl * n)
                c_lambda_n[k] += dl
                if not soft:
                    c_budget[k] -= c

    @ti.func
    def pair_friction(self, t_a: ti.i32, t_b: ti.i32) -> float:
        """μ of a contact between triangles t_a and t_b: the mean of their bodies' coefficients."""
        return 0.5 * (self.model.body_friction[self.model.tri_body[t_a]]
                      + self.model.body_friction[self.model.tri_body[t_b]])

    @ti.func
    def solve_contact_friction(self, k: ti.i32, c_tri: ti.template(), c_bary_moved: ti.template(),
                               c_bary_other: ti.template(), c_normal: ti.template(), c_lambda_n: ti.template(),
                               c_lambda_t: ti.template()):
        """Static friction of an active contact: cancel the anchors' relative tangential
        displacement over the substep, as far as the accumulated vector λ_t stays within
        |λ_t| ≤ μ·λ_n (Müller 2020, Eq. 26-27, clamped; μ is the mean of the two bodies'
        friction coefficients)."""
        if c_lambda_n[k] > 0.0:
            tri = c_tri[k]
            bm, bo = c_bary_moved[k], c_bary_other[k]
            n = c_normal[k]
            p_m = self.anchor_world(tri[0], bm, False)
            p_o = self.anchor_world(tri[1], bo, False)
            p_c = 0.5 * (p_m + p_o)
            slip = (p_m - self.anchor_world(tri[0], bm, True)) - (p_o - self.anchor_world(tri[1], bo, True))
            slip -= slip.dot(n) * n
            length = slip.norm()
            if length > 0.0:
                t = slip / length
                f_m, f_o = self.takes_part(tri[0], tri[1]), self.takes_part(tri[1], tri[0])
                w = f_m * self.anchor_inv_mass(tri[0], bm, p_m, t) + f_o * self.anchor_inv_mass(tri[1], bo, p_o, t)
                if w > 0.0:
                    old_t = c_lambda_t[k]
                    new_t = friction_in_cone(old_t + (length / w) * t,
                                             self.pair_friction(tri[0], tri[1]) * c_lambda_n[k])
                    d = new_t - old_t
                    self.anchor_move(tri[0], bm, p_c, -f_m * d)
                    self.anchor_move(tri[1], bo, p_c, f_o * d)
                    c_lambda_t[k] = new_t

    @ti.func
    def solve_contact_velocity(self, k: ti.i32, h: float, g_norm: float, c_tri: ti.template(),
                               c_bary_moved: ti.template(), c_bary_other: ti.template(),
                               c_normal: ti.template(), c_lambda_n: ti.template(), c_lambda_t: ti.template(),
                               c_vn0: ti.template(), c_impulse_t: ti.template()):
        """One velocity-pass sweep over an active contact (Müller 2020 §3.6, iterated as
        sequential impulses): the normal relative velocity is driven to max(−e·v_n⁰, 0)
        (e = 0 below 2|g|h, so resting stays resting), and the accumulated dynamic-friction
        impulse cancels the tangential velocity within what static friction left of Coulomb's
        bound: |J_t| ≤ (μ·λ_n − λ_t)/h."""
        if c_lambda_n[k] > 0.0:
            tri = c_tri[k]
            bm, bo = c_bary_moved[k], c_bary_other[k]
            n = c_normal[k]
            p_m = self.anchor_world(tri[0], bm, False)
            p_o = self.anchor_world(tri[1], bo, False)
            p_c = 0.5 * (p_m + p_o)
            body_m, body_o = self.model.tri_body[tri[0]], self.model.tri_body[tri[1]]
            e = 0.5 * (self.model.body_restitution[body_m] + self.model.body_restitution[body_o])
            vn0 = c_vn0[k]
            if ti.abs(vn0) <= 2.0 * g_norm * h:
                e = 0.0
            v = self.anchor_velocity(tri[0], bm, p_m) - self.anchor_velocity(tri[1], bo, p_o)
            f_m, f_o = self.takes_part(tri[0], tri[1]), self.takes_part(tri[1], tri[0])
            w_n = f_m * self.anchor_inv_mass(tri[0], bm, p_m, n) + f_o * self.anchor_inv_mass(tri[1], bo, p_o, n)
            if w_n > 0.0:
                impulse = ((ti.max(-e * vn0, 0.0) - v.dot(n)) / w_n) * n
                self.anchor_kick(tri[0], bm, p_c, f_m * impulse)
                self.anchor_kick(tri[1], bo, p_c, -f_o * impulse)
            v = self.anchor_velocity(tri[0], bm, p_m) - self.anchor_velocity(tri[1], bo, p_o)
            vt = v - v.dot(n) * n
            vt_len = vt.norm()
            if vt_len > 0.0:
                t = vt / vt_len
                w_t = f_m * self.anchor_inv_mass(tri[0], bm, p_m, t) + f_o * self.anchor_inv_mass(tri[1], bo, p_o, t)
                if w_t > 0.0:
                    mu = self.pair_friction(tri[0], tri[1])
                    # The position pass already spent λ_t/h of the Coulomb bound μ·λ_n/h.
                    bound = ti.max(mu * c_lambda_n[k] - c_lambda_t[k].norm(), 0.0) / h
                    old = c_impulse_t[k]
                    new = friction_in_cone(old - (vt_len / w_t) * t, bound)
                    c_impulse_t[k] = new
                    self.anchor_kick(tri[0], bm, p_c, f_m * (new - old))
                    self.anchor_kick(tri[1], bo, p_c, f_o * (old - new))

    @ti.func
    def solve_velocities(self, n_contacts: ti.i32, iterations: ti.i32, h: float, g_norm: float,
                         c_tri: ti.template(), c_bary_moved: ti.template(), c_bary_other: ti.template(),
                         c_normal: ti.template(), c_lambda_n: ti.template(), c_lambda_t: ti.template(),
                         c_vn0: ti.template(), c_impulse_t: ti.template()):
        """`iterations` alternating sweeps of the velocity pass (serial)."""
        for k in range(n_contacts):
            c_impulse_t[k] = vec3(0.0)
        for it in range(iterations):
            for j in range(n_contacts):
                k = ti.select(it % 2 == 0, j, n_contacts - 1 - j)
                self.solve_contact_velocity(k, h, g_norm, c_tri, c_bary_moved, c_bary_other, c_normal,
                                            c_lambda_n, c_lambda_t, c_vn0, c_impulse_t)
        if ti.static(self.has_spin_friction):
            for k in range(n_contacts):
                self.solve_contact_spin(k, h, c_tri, c_normal, c_lambda_n)

    @ti.func
    def spin_response(self, b: ti.i32, n: vec3) -> vec3:
        """I_w⁻¹·n of body b at its current pose (1/(kg·m²)): its change of ω per unit angular
        impulse about n; zero unless b is rigid."""
        out = vec3(0.0)
        if self.model.body_kind[b] == RIGID:
            out = world_times(self.state.body_q[b], self.model.body_inv_inertia[b], n)
        return out

    @ti.func
    def solve_contact_spin(self, k: ti.i32, h: float, c_tri: ti.template(), c_normal: ti.template(),
                           c_lambda_n: ti.template()):
        """Spin (torsional) friction of an active contact between rigid or static bodies: an
        angular impulse L·N cancels the bodies' relative spin s = (ω_m − ω_o)·N, L = −s/(N·I_m⁻¹N
        + N·I_o⁻¹N), within Coulomb's bound |L| ≤ μ_s·λ_n/h (μ_s in m: the torque per newton
        of normal force). A point contact has no torque about its normal, so a body held at
        two points turns freely about the line through them: a spike hanging between a
        groove's wall and a wedge swung about it for seconds."""
        tri = c_tri[k]
        body_m, body_o = self.model.tri_body[tri[0]], self.model.tri_body[tri[1]]
        mu_s = 0.5 * (self.model.body_spin_friction[body_m] + self.model.body_spin_friction[body_o])
        if c_lambda_n[k] > 0.0 and mu_s > 0.0 and not self.involves_soft(tri[0], tri[1]):
            n = c_normal[k]
            f_m, f_o = self.takes_part(tri[0], tri[1]), self.takes_part(tri[1], tri[0])
            dw_m, dw_o = f_m * self.spin_response(body_m, n), f_o * self.spin_response(body_o, n)
            w = n.dot(dw_m + dw_o)
            if w > 0.0:
                # A static body's ω is zero: only rigid bodies move (update_body_velocity).
                spin = (self.state.body_w[body_m] - self.state.body_w[body_o]).dot(n)
                bound = mu_s * c_lambda_n[k] / h
                impulse = ti.min(ti.max(-spin / w, -bound), bound)
                self.state.body_w[body_m] += impulse * dw_m
                self.state.body_w[body_o] -= impulse * dw_o

    # ------------------------------------------------------------- soft bodies
    @ti.func
    def solve_edge(self, e: ti.i32, h: float):
        """XPBD edge-length constraint C = |x_i − x_j| − L with the body's compliance."""
        ij = self.model.edge_indices[e]
        c, grad = edge_length(self.state.vertex_x[ij[0]], self.state.vertex_x[ij[1]], self.model.edge_rest[e])
        wi, wj = self.model.vertex_inv_mass[ij[0]], self.model.vertex_inv_mass[ij[1]]
        alpha = self.model.body_compliance[self.model.vertex_body[ij[0]]] / (h * h)
        dl = xpbd_delta_lambda(c, wi + wj, self.edge_lambda[e], alpha)
        self.edge_lambda[e] += dl
        self.state.vertex_x[ij[0]] += wi * dl * grad
        self.state.vertex_x[ij[1]] -= wj * dl * grad

    @ti.func
    def solve_volume(self, b: ti.i32):
        """Volume constraint of a closed soft body, C = V − V₀ with V = Σ (x0×x1)·x2 / 6 over
        its triangles and ∇_i V = Σ over i's triangles of (x_j × x_k)/6 (hard: α = 0)."""
        if self.model.body_kind[b] == SOFT:
            v_lo, v_hi = self.model.body_vertex_range[b][0], self.model.body_vertex_range[b][1]
            for i in range(v_lo, v_hi):
                self.vertex_grad[i] = vec3(0.0)
            vol6 = 0.0
            for t in range(self.model.body_tri_range[b][0], self.model.body_tri_range[b][1]):
                idx = self.model.tri_indices[t]
                x0, x1, x2 = self.state.vertex_x[idx[0]], self.state.vertex_x[idx[1]], self.state.vertex_x[idx[2]]
                vol6 += tet_volume6(x0, x1, x2)
                self.vertex_grad[idx[0]] += x1.cross(x2) / 6.0
                self.vertex_grad[idx[1]] += x2.cross(x0) / 6.0
                self.vertex_grad[idx[2]] += x0.cross(x1) / 6.0
            wsum = 0.0
            for i in range(v_lo, v_hi):
                wsum += self.model.vertex_inv_mass[i] * self.vertex_grad[i].norm_sqr()
            dl = xpbd_delta_lambda(vol6 / 6.0 - self.model.body_rest_volume[b], wsum, 0.0, 0.0)
            for i in range(v_lo, v_hi):
                self.state.vertex_x[i] += self.model.vertex_inv_mass[i] * dl * self.vertex_grad[i]

    # ------------------------------------------------------------- velocities
    @ti.func
    def update_body_velocity(self, b: ti.i32, h: float):
        """v = (x − x_prev)/h and ω = θ/h, the substep's rotation vector over h (Müller 2020,
        Alg. 2, lines 12-15), carried to the end pose with its angular momentum kept."""
        if self.model.body_kind[b] == RIGID:
            self.state.body_v[b] = (self.state.body_x[b] - self.state.body_x_prev[b]) / h
            self.state.body_w[b] = carried_angular_velocity(self.state.body_q_prev[b], self.state.body_q[b],
                                                            self.model.body_inertia[b],
                                                            self.model.body_inv_inertia[b], self.body_theta[b] / h)

    @ti.func
    def update_particle_velocity(self, i: ti.i32, h: float):
        if self.model.vertex_inv_mass[i] > 0.0:
            self.state.vertex_v[i] = (self.state.vertex_x[i] - self.state.vertex_x_prev[i]) / h

    @ti.func
    def damp_soft_body(self, b: ti.i32, h: float):
        """Soft-body damping (Müller et al. 2007, §3.5): each particle loses the fraction
        1 − exp(−damping·h) of its velocity relative to the body's rigid motion
        v_cm + ω × r_i, ω = I⁻¹L; momentum and angular momentum are kept."""
        rate = self.model.body_damping[b]
        if self.model.body_kind[b] == SOFT and rate > 0.0:
            lo, hi = self.model.body_vertex_range[b][0], self.model.body_vertex_range[b][1]
            mass = 0.0
            x_cm = vec3(0.0)
            v_cm = vec3(0.0)
            for i in range(lo, hi):
                m = 1.0 / self.model.vertex_inv_mass[i]
                mass += m
                x_cm += m * self.state.vertex_x[i]
                v_cm += m * self.state.vertex_v[i]
            x_cm /= mass
            v_cm /= mass
            spin = vec3(0.0)
            inertia = ti.Matrix.zero(float, 3, 3)
            for i in range(lo, hi):
                m = 1.0 / self.model.vertex_inv_mass[i]
                r = self.state.vertex_x[i] - x_cm
                spin += m * r.cross(self.state.vertex_v[i])
                inertia += m * (r.dot(r) * ti.Matrix.identity(float, 3) - r.outer_product(r))
            omega = vec3(0.0)
            if ti.abs(inertia.determinant()) > 0.0:
                omega = inertia.inverse() @ spin
            k = 1.0 - ti.exp(-rate * h)
            for i in range(lo, hi):
                r = self.state.vertex_x[i] - x_cm
                self.state.vertex_v[i] += k * (v_cm + omega.cross(r) - self.state.vertex_v[i])

    @ti.func
    def apply_drag(self, b: ti.i32, h: float):
        """Linear velocity damping (drag): every point of body b loses the fraction 1 − exp(−drag·h)
        of its velocity over the substep (dv/dt = −drag·v). For a rigid body that is v and ω
        alike (the force −drag·m·v at the centre of mass and the torque −drag·I·ω)."""
        rate = self.model.body_drag[b]
        if rate > 0.0:
            keep = ti.exp(-rate * h)
            if self.model.body_kind[b] == RIGID:
                self.state.body_v[b] *= keep
                self.state.body_w[b] *= keep
            elif self.model.body_kind[b] == SOFT:
                lo, hi = self.model.body_vertex_range[b][0], self.model.body_vertex_range[b][1]
                for i in range(lo, hi):
                    self.state.vertex_v[i] *= keep

    @ti.func
    def state_is_sane(self, bound: float) -> ti.i32:
        """-1 - (index of the first body) whose state is NaN or beyond `bound`, else 0."""
        bad = 0
        for b in range(ti.static(self.model.n_bodies)):
            ok = ti.abs(self.state.body_x[b]).max() <= bound and ti.abs(self.state.body_v[b]).max() <= bound
            if bad == 0 and not ok:
                bad = -1 - b
        if ti.static(self.model.has_soft):
            for i in range(ti.static(self.model.n_vertices)):
                ok = ti.abs(self.state.vertex_x[i]).max() <= bound and ti.abs(self.state.vertex_v[i]).max() <= bound
                if bad == 0 and not ok:
                    bad = -1 - self.model.vertex_body[i]
        return bad

    # ---------------------------------------------------------------- kernels
    @ti.func
    def save_state(self):
        """Copy the state and the carried rows to the frame's snapshot."""
        self.saved_carry[4][0] = self.carry_count[0]
        for k in range(self.carry_count[0]):
            self.saved_carry[0][k] = self.carry_tri[k]
            self.saved_carry[1][k] = self.carry_bary_moved[k]
            self.saved_carry[2][k] = self.carry_bary_other[k]
            self.saved_carry[3][k] = self.carry_normal[k]
        for b in range(ti.static(self.model.n_bodies)):
            self.saved_body[0][b] = self.state.body_x[b]
            self.saved_body[1][b] = self.state.body_q[b]
            self.saved_body[2][b] = self.state.body_v[b]
            self.saved_body[3][b] = self.state.body_w[b]
        if ti.static(self.model.has_soft):
            for i in range(ti.static(self.model.n_vertices)):
                self.saved_vertex[0][i] = self.state.vertex_x[i]
                self.saved_vertex[1][i] = self.state.vertex_v[i]

    @ti.func
    def summarize_bodies(self):
        """body_summary (serial): per body its linear velocity (m/s; a soft body's particle mean, 0 for a
        static one), the fastest motion about it (|ω| in rad/s for a rigid body, the largest
        particle speed about the mean in m/s for a soft one) and its vertices' box (m)."""
        for b in range(ti.static(self.model.n_bodies)):
            r = self.model.body_vertex_range[b]
            lo = vec3(ti.math.inf)
            hi = vec3(-ti.math.inf)
            for i in range(r[0], r[1]):
                lo = ti.min(lo, self.state.vertex_x[i])
                hi = ti.max(hi, self.state.vertex_x[i])
            v = vec3(0.0)
            spin = 0.0
            if self.model.body_kind[b] == RIGID:
                v = self.state.body_v[b]
                spin = self.state.body_w[b].norm()
            if ti.static(self.model.has_soft):
                if self.model.body_kind[b] == SOFT:
                    for i in range(r[0], r[1]):
                        v += self.state.vertex_v[i]
                    v /= ti.max(r[1] - r[0], 1)
                    for i in range(r[0], r[1]):
                        spin = ti.max(spin, (self.state.vertex_v[i] - v).norm())
            self.body_summary[b] = ti.Vector([v[0], v[1], v[2], spin, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]])

    @ti.kernel
    def _summarize_bodies(self):
        ti.loop_config(serialize=True)  # on the launching thread: a parallel task costs ~30 µs to start
        for _ in range(1):
            self.summarize_bodies()

    @ti.func
    def summary_motion(self, b: ti.i32):
        """(velocity (m/s), bound on its points' speed about it (m/s): |ω|·reach for a rigid
        body, the fastest particle for a soft one) of body b from body_summary; zero if static."""
        s = self.body_summary[b]
        kind = self.model.body_kind[b]
        v = vec3(0.0)
        spin = 0.0
        if kind != STATIC:
            v = vec3(s[0], s[1], s[2])
            spin = s[3] * ti.select(kind == RIGID, self.body_reach[b], 1.0)
        return v, spin

    @ti.func
    def substeps_suffice(self, substeps: ti.i32, frame_dt: float, g_norm: float, max_impact: float,
                         thinnest: float) -> ti.i32:
        """1 if a frame of `substeps` needs no more of them by the rules of
        Scene._substeps_for_next_frame (tunnelling.py), applied to the same per-body summary:
        the two fastest bodies move at most TUNNEL_FRACTION of the thinnest body's thickness
        per substep, and no two bodies that can meet within the frame close in by more than
        `max_impact` per substep. 0 otherwise (the caller then chooses in numpy). Serial."""
        self.summarize_bodies()
        ok = 1
        n_b = ti.static(self.model.n_bodies)
        if ti.static(n_b >= 2):
            first = 0.0
            second = 0.0
            for b in range(n_b):
                if self.model.body_kind[b] != STATIC:
                    v, spin = self.summary_motion(b)
                    speed = v.norm() + spin + g_norm * frame_dt
                    if speed > first:
                        second = first
                        first = speed
                    elif speed > second:
                        second = speed
            motion = (first + second) * frame_dt
            if motion > 0.0 and thinnest > 0.0 and ti.ceil(motion / (TUNNEL_FRACTION * thinnest)) > substeps:
                ok = 0
            if max_impact > 0.0:
                for a in range(n_b):
                    for b in range(n_b):
                        if a != b and (self.model.body_kind[a] != STATIC or self.model.body_kind[b] != STATIC):
                            v_a, spin_a = self.summary_motion(a)
                            v_b, spin_b = self.summary_motion(b)
                            pair_motion = ((v_a - v_b).norm() + spin_a + spin_b + g_norm * frame_dt) * frame_dt
                            s_a, s_b = self.body_summary[a], self.body_summary[b]
                            gap = ti.max(vec3(s_a[4], s_a[5], s_a[6]) - vec3(s_b[7], s_b[8], s_b[9]),
                                         vec3(s_b[4], s_b[5], s_b[6]) - vec3(s_a[7], s_a[8], s_a[9])).max()
                            if gap <= pair_motion and ti.ceil(pair_motion / max_impact) > substeps:
                                ok = 0
        return ok

    def body_summary_numpy(self) -> np.ndarray:
        """(B, 10) float64: per body velocity (3), motion about it (1: |ω| rigid, particle speed
        soft), vertex box low (3) and high (3), at the current state."""
        self._summarize_bodies()
        return self.body_summary.to_numpy()[: self.model.n_bodies].astype(np.float64)

    @ti.func
    def restore_state(self):
        """Return to the frame's snapshot (serial)."""
        self.carry_count[0] = self.saved_carry[4][0]
        for k in range(self.carry_count[0]):
            self.carry_tri[k] = self.saved_carry[0][k]
            self.carry_bary_moved[k] = self.saved_carry[1][k]
            self.carry_bary_other[k] = self.saved_carry[2][k]
            self.carry_normal[k] = self.saved_carry[3][k]
        for b in range(ti.static(self.model.n_bodies)):
            self.state.body_x[b] = self.saved_body[0][b]
            self.state.body_q[b] = self.saved_body[1][b]
            self.state.body_v[b] = self.saved_body[2][b]
            self.state.body_w[b] = self.saved_body[3][b]
        if ti.static(self.model.has_soft):
            for i in range(ti.static(self.model.n_vertices)):
                self.state.vertex_x[i] = self.saved_vertex[0][i]
                self.state.vertex_v[i] = self.saved_vertex[1][i]
        for i in range(ti.static(self.model.n_vertices)):
            self.place_vertex(i)

    @ti.func
    def project(self, n_contacts: ti.i32, iterations: ti.i32, h: float, c_tri: ti.template(),
                c_bary_moved: ti.template(), c_bary_other: ti.template(), c_normal: ti.template(),
                c_budget: ti.template(), c_lambda_n: ti.template(), c_lambda_t: ti.template(),
                b_lever: ti.template(), b_slip: ti.template(), b_gap: ti.template(), b_k: ti.template(),
                b_rows: ti.template()):
        """Gauss-Seidel sweeps over contacts and soft constraints (serial: call inside a serial
        loop); each sweep ends with the rows of rigid bodies (against static bodies and between
        each other) solved in blocks, one per island of touching bodies (solve_blocks)."""
        self.compute_levels(n_contacts, c_tri)
        # The blocks' turns act through the inverse inertia at the substep's start
        # (apply_positional_impulse), the same for every sweep.
        for b in range(ti.static(self.model.n_bodies)):
            if self.model.body_kind[b] == RIGID:
                rot = quat_matrix(self.state.body_q_prev[b])
                self.block_inv_inertia[b] = rot @ self.model.body_inv_inertia[b] @ rot.transpose()
        if ti.static(self.model.has_soft):
            for e in range(ti.static(self.model.n_edges)):
                self.edge_lambda[e] = 0.0
        for it in range(iterations):
            if ti.static(self.model.has_soft):
                for e in range(ti.static(self.model.n_edges)):
                    self.solve_edge(e, h)
                for b in range(ti.static(self.model.n_bodies)):
                    self.solve_volume(b)
            # Normals first, then friction on the slip they leave; the sweeps alternate
            # direction so that no contact is always last.
            for j in range(n_contacts):
                k = ti.select(it % 2 == 0, j, n_contacts - 1 - j)
                if self.block_body(k, c_tri) < 0 and not self.pair_block(k, c_tri):
                    self.solve_contact_normal(k, c_tri, c_bary_moved, c_bary_other, c_normal, c_budget, c_lambda_n)
            for j in range(n_contacts):
                k = ti.select(it % 2 == 0, j, n_contacts - 1 - j)
                if self.block_body(k, c_tri) < 0 and not self.pair_block(k, c_tri):
                    self.solve_contact_friction(k, c_tri, c_bary_moved, c_bary_other, c_normal, c_lambda_n,
                                                c_lambda_t)
            self.solve_blocks(n_contacts, it, c_tri, c_bary_moved, c_bary_other, c_normal, c_budget,
                                     c_lambda_n, c_lambda_t, b_lever, b_slip, b_gap, b_k, b_rows)

    @ti.func
    def block_body(self, k: ti.i32, c_tri: ti.template()) -> ti.i32:
        """The rigid body of row k when its other side is static (the row is solved in that
        body's block), else -1."""
        tri = c_tri[k]
        b_m, b_o = self.model.tri_body[tri[0]], self.model.tri_body[tri[1]]
        kind_m, kind_o = self.model.body_kind[b_m], self.model.body_kind[b_o]
        body = -1
        if kind_m == RIGID and kind_o == STATIC:
            body = b_m
        elif kind_m == STATIC and kind_o == RIGID:
            body = b_o
        return body

    @ti.func
    def pair_block(self, k: ti.i32, c_tri: ti.template()) -> bool:
        """Whether row k is between two rigid bodies (solved in the coupled block)."""
        tri = c_tri[k]
        b_m, b_o = self.model.tri_body[tri[0]], self.model.tri_body[tri[1]]
        return self.model.body_kind[b_m] == RIGID and self.model.body_kind[b_o] == RIGID

    @ti.func
    def solve_blocks(self, n_contacts: ti.i32, it: ti.i32, c_tri: ti.template(), c_bary_moved: ti.template(),
                     c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                     c_lambda_n: ti.template(), c_lambda_t: ti.template(), b_lever: ti.template(),
                     b_slip: ti.template(), b_gap: ti.template(), b_k: ti.template(), b_rows: ti.template()):
        """The rows of rigid bodies, against static bodies and between each other, solved
        together on the bodies' motions linearised at the sweep's start (a move Δx and a turn
        Δθ: an anchor at lever r moves by Δx + Δθ × r), then each body moved once. Bodies that
        touch each other form an island (union-find over the rows between them); each island
        sweeps its own rows: BLOCK_SWEEPS Gauss-Seidel sweeps of the normals alone, then
        BLOCK_SWEEPS of normals and friction for a lone body (COUPLED_SWEEPS for an island of
        several), leaving a phase early once no row moves its anchor by more than tol·|r|
        (sweep_block). Rows projected one at a time on the real pose converge slowly where a
        body rests on several points: each push turns the body about its centre, which sinks
        the other points and slides them sideways for friction to undo (a spike lying on its
        face on the ground kept 1e-7 m of depth at 8 sweeps, 5e-9 at 12). Normals first: a
        substep's sink under gravity is undone by a lift that slides no point, so friction is
        left only real slip to cancel; with friction from the first sweep, the slides of the
        unconverged pushes were held as opposing friction at the points, near the cone, and a
        box at rest on a block alternated between two poses 1e-7 m apart. The linear sweeps
        cost a few multiplications a row: converging there is cheap, re-measuring the pose is
        not. Between moving bodies the same holds: projected one at a time, a stack of five
        boxes crept sideways at 3-6e-5 m/s for good (friction between the boxes unconverged
        at 8 sweeps); in one island it rests."""
        n_b = ti.static(self.model.n_bodies)
        for b in range(n_b):
            self.block_dx[b] = vec3(0.0)
            self.block_dtheta[b] = vec3(0.0)
            self.block_len[b] = 0
            self.block_island[b] = b
            self.block_coupled[b] = 0
        count = 0
        for k in range(n_contacts):
            b = self.block_body(k, c_tri)
            pair = self.pair_block(k, c_tri)
            if b >= 0 or pair:
                tri = c_tri[k]
                bm, bo = c_bary_moved[k], c_bary_other[k]
                n = c_normal[k]
                p_m = self.anchor_world(tri[0], bm, False)
                p_o = self.anchor_world(tri[1], bo, False)
                b_gap[k] = n.dot(p_o - p_m)
                slip = (p_m - self.anchor_world(tri[0], bm, True)) - (p_o - self.anchor_world(tri[1], bo, True))
                b_slip[k] = slip - slip.dot(n) * n
                p_c = 0.5 * (p_m + p_o)
                if b >= 0:
                    r = p_c - self.state.body_x_prev[b]
                    b_lever[k] = r
                    b_k[k] = inv_mass_matrix_world(self.model.body_inv_mass[b], self.block_inv_inertia[b], r)
                else:
                    body_m, body_o = self.model.tri_body[tri[0]], self.model.tri_body[tri[1]]
                    self.join_islands(body_m, body_o)
                    r_m = p_c - self.state.body_x_prev[body_m]
                    r_o = p_c - self.state.body_x_prev[body_o]
                    b_lever[k] = r_m
                    f_m, f_o = self.takes_part(tri[0], tri[1]), self.takes_part(tri[1], tri[0])
                    b_k[k] = (f_m * inv_mass_matrix_world(self.model.body_inv_mass[body_m],
                                                          self.block_inv_inertia[body_m], r_m)
                              + f_o * inv_mass_matrix_world(self.model.body_inv_mass[body_o],
                                                            self.block_inv_inertia[body_o], r_o))
                count += 1
        if count > 0:
            # Each island's rows together, in row order (a counting sort by island root): a
            # block moves no body of another island, so each island sweeps its own rows, and
            # leaves a phase once no row of its moves its anchor by more than tol·|r|. A body
            # still landing does not keep the resting ones sweeping.
            for b in range(n_b):
                self.block_island[b] = self.island_root(b)
            for k in range(n_contacts):
                root = self.row_island(k, c_tri)
                if root >= 0:
                    self.block_len[root] += 1
            first = 0
            for b in range(n_b):
                self.block_first[b] = first
                first += self.block_len[b]
                self.block_len[b] = 0
            for k in range(n_contacts):
                root = self.row_island(k, c_tri)
                if root >= 0:
                    b_rows[self.block_first[root] + self.block_len[root]] = k
                    self.block_len[root] += 1
            for b in range(n_b):
                if self.block_len[b] > 0:
                    self.sweep_block(b, it, c_tri, c_normal, c_budget, c_lambda_n, c_lambda_t, b_lever, b_slip,
                                     b_gap, b_k, b_rows)
            for b in range(n_b):
                if self.model.body_kind[b] == RIGID:
                    dx, dtheta = self.block_dx[b], self.block_dtheta[b]
                    if dx.norm_sqr() + dtheta.norm_sqr() > 0.0:
                        self.state.body_x[b] += dx
                        self.body_theta[b] += dtheta
                        self.state.body_q[b] = rotate_by(self.state.body_q_prev[b], self.body_theta[b])

    @ti.func
    def island_root(self, b: ti.i32) -> ti.i32:
        """The root of body b's island (union-find with path halving; serial)."""
        root = b
        while self.block_island[root] != root:
            self.block_island[root] = self.block_island[self.block_island[root]]
            root = self.block_island[root]
        return root

    @ti.func
    def join_islands(self, b_a: ti.i32, b_b: ti.i32):
        """Put rigid bodies b_a and b_b in one island, rooted at the lower index (serial)."""
        root_a, root_b = self.island_root(b_a), self.island_root(b_b)
        if root_a != root_b:
            low, high = ti.min(root_a, root_b), ti.max(root_a, root_b)
            self.block_island[high] = low
            self.block_coupled[low] = 1

    @ti.func
    def row_island(self, k: ti.i32, c_tri: ti.template()) -> ti.i32:
        """The island root of row k if it is a block row (its rigid body's against a static
        body, or between two rigid bodies), else -1; valid once block_island holds roots."""
        b = self.block_body(k, c_tri)
        if self.pair_block(k, c_tri):
            b = self.model.tri_body[c_tri[k][0]]
        return ti.select(b >= 0, self.block_island[ti.max(b, 0)], -1)

    @ti.func
    def sweep_block(self, b: ti.i32, it: ti.i32, c_tri: ti.template(), c_normal: ti.template(),
                    c_budget: ti.template(), c_lambda_n: ti.template(), c_lambda_t: ti.template(),
                    b_lever: ti.template(), b_slip: ti.template(), b_gap: ti.template(), b_k: ti.template(),
                    b_rows: ti.template()):
        """The block of the island rooted at body b: up to BLOCK_SWEEPS sweeps of its rows'
        normals (COUPLED_SWEEPS for an island of several bodies), then as many with friction,
        alternating direction; a phase ends once no row moves its anchor by more than tol·|r|
        (COUPLED_TOL·|r| in an island of several bodies)."""
        tol = ti.static(runtime.tolerance())
        coupled = self.block_coupled[b] == 1
        sweeps = ti.select(coupled, COUPLED_SWEEPS, BLOCK_SWEEPS)
        tol_r = ti.select(coupled, ti.max(tol, COUPLED_TOL), tol)
        first, count = self.block_first[b], self.block_len[b]
        inner = 0
        while inner < 2 * sweeps:
            friction = inner >= sweeps
            converged = True
            for j in range(count):
                k = b_rows[first + ti.select((it + inner) % 2 == 0, j, count - 1 - j)]
                body = self.block_body(k, c_tri)
                moved = 0.0
                if body >= 0:
                    moved = self.solve_block_row(k, body, friction, c_tri, c_normal, c_budget, c_lambda_n,
                                                 c_lambda_t, b_lever, b_slip, b_gap, b_k)
                else:
                    moved = self.solve_pair_row(k, friction, c_tri, c_normal, c_budget, c_lambda_n, c_lambda_t,
                                                b_lever, b_slip, b_gap, b_k)
                if moved > tol_r * b_lever[k].norm():
                    converged = False
            inner += 1
            if converged:
                inner = ti.select(friction, 2 * sweeps, ti.max(inner, sweeps))

    @ti.func
    def project_block_row(self, k: ti.i32, friction: bool, d: vec3, c_tri: ti.template(), c_normal: ti.template(),
                          c_budget: ti.template(), c_lambda_n: ti.template(), c_lambda_t: ti.template(),
                          b_slip: ti.template(), b_gap: ti.template(), b_k: ti.template()) -> vec3:
        """The positional impulse P (kg·m, on the moved side) that row k adds in one block
        sweep, its moved anchor displaced by d (m) relative to the other since the
        linearisation: gap g = g0 − N·d, tangential slip s = s0 + d_t, K (3×3 inverse mass at
        the anchor, both bodies') from b_k. The normal pushes c = min(g, budget) when c > 0 or
        while it holds λ_n > 0; friction then cancels the slip left, |λ_t| ≤ μ·λ_n (Müller
        2020, Eq. 26-27). Updates λ_n, λ_t and the budget; P = 0 for a row that does nothing."""
        impulse = vec3(0.0)
        n = c_normal[k]
        slip = b_slip[k] + d - d.dot(n) * n
        k_mat = b_k[k]
        c = ti.max(ti.min(b_gap[k] - n.dot(d), c_budget[k]), 0.0)
        lam_n = c_lambda_n[k]
        w = n.dot(k_mat @ n)
        if (c > 0.0 or lam_n > 0.0) and w > 0.0:
            push = c / w
            moved = k_mat @ (push * n)
            slip_left = slip + (moved - moved.dot(n) * n)
            lam_n += push
            old_t = c_lambda_t[k]
            new_t = old_t
            length = slip_left.norm()
            if friction and length > 0.0:
                t = slip_left / length
                new_t = friction_in_cone(old_t + (length / t.dot(k_mat @ t)) * t,
                                         self.pair_friction(c_tri[k][0], c_tri[k][1]) * lam_n)
            impulse = push * n - (new_t - old_t)
            c_lambda_n[k] = lam_n
            c_lambda_t[k] = new_t
            c_budget[k] -= n.dot(k_mat @ impulse)
        return impulse

    @ti.func
    def solve_pair_row(self, k: ti.i32, friction: bool, c_tri: ti.template(), c_normal: ti.template(),
                       c_budget: ti.template(), c_lambda_n: ti.template(), c_lambda_t: ti.template(),
                       b_lever: ti.template(), b_slip: ti.template(), b_gap: ti.template(),
                       b_k: ti.template()) -> float:
        """Row k between two rigid bodies projected on both bodies' linearised motions, as
        solve_block_row does against a static body: d = (Δx_m + Δθ_m × r_m) − (Δx_o + Δθ_o × r_o),
        gap g = g0 − N·d, slip s = s0 + d_t, K = f_m·K_m + f_o·K_o (f: takes_part). Returns how
        far the row moved its anchors apart (m)."""
        tri = c_tri[k]
        body_m, body_o = self.model.tri_body[tri[0]], self.model.tri_body[tri[1]]
        r_m = b_lever[k]
        r_o = r_m + self.state.body_x_prev[body_m] - self.state.body_x_prev[body_o]
        d = (self.block_dx[body_m] + self.block_dtheta[body_m].cross(r_m)
             - self.block_dx[body_o] - self.block_dtheta[body_o].cross(r_o))
        impulse = self.project_block_row(k, friction, d, c_tri, c_normal, c_budget, c_lambda_n, c_lambda_t,
                                         b_slip, b_gap, b_k)
        moved_by = (b_k[k] @ impulse).norm()
        if moved_by > 0.0:
            f_m, f_o = self.takes_part(tri[0], tri[1]), self.takes_part(tri[1], tri[0])
            self.block_dx[body_m] += f_m * self.model.body_inv_mass[body_m] * impulse
            self.block_dtheta[body_m] += f_m * (self.block_inv_inertia[body_m] @ r_m.cross(impulse))
            self.block_dx[body_o] -= f_o * self.model.body_inv_mass[body_o] * impulse
            self.block_dtheta[body_o] -= f_o * (self.block_inv_inertia[body_o] @ r_o.cross(impulse))
        return moved_by

    @ti.func
    def solve_block_row(self, k: ti.i32, b: ti.i32, friction: bool, c_tri: ti.template(), c_normal: ti.template(),
                        c_budget: ti.template(), c_lambda_n: ti.template(), c_lambda_t: ti.template(),
                        b_lever: ti.template(), b_slip: ti.template(), b_gap: ti.template(),
                        b_k: ti.template()) -> float:
        """Row k (rigid body b against a static body) projected on b's linearised motion, as
        solve_contact_normal and solve_contact_friction do on the real pose. With d the moved
        anchor's displacement relative to the other since the linearisation, the gap is
        g = g0 − N·d and the tangential slip s = s0 + d_t; an impulse P on the moved side adds
        K·P to d (K the 3×3 inverse mass at the anchor, rigid.inv_mass_matrix_world), P from
        project_block_row. Returns how far the row moved its anchor (m)."""
        tri = c_tri[k]
        sign = ti.select(self.model.tri_body[tri[0]] == b, 1.0, -1.0)
        r = b_lever[k]
        d = sign * (self.block_dx[b] + self.block_dtheta[b].cross(r))
        impulse = self.project_block_row(k, friction, d, c_tri, c_normal, c_budget, c_lambda_n, c_lambda_t,
                                         b_slip, b_gap, b_k)
        moved_by = (b_k[k] @ impulse).norm()
        if moved_by > 0.0:
            body_impulse = sign * impulse
            self.block_dx[b] += self.model.body_inv_mass[b] * body_impulse
            self.block_dtheta[b] += self.block_inv_inertia[b] @ r.cross(body_impulse)
        return moved_by

    @ti.func
    def predict(self, h: float, gravity: vec3, kick: float):
        """Predict every rigid body and soft particle (Müller 2020, Alg. 2, lines 3-8)."""
        for b in range(ti.static(self.model.n_bodies)):
            self.predict_body(b, h, gravity, kick)
        if ti.static(self.model.has_soft):
            for i in range(ti.static(self.model.n_vertices)):
                self.predict_particle(i, h, gravity, kick)

    @ti.func
    def update_velocities(self, h: float):
        """Velocities from the substep's motion (Müller 2020, Alg. 2, lines 12-16), then the soft
        bodies' damping."""
        for b in range(ti.static(self.model.n_bodies)):
            self.update_body_velocity(b, h)
        if ti.static(self.model.has_soft):
            for i in range(ti.static(self.model.n_vertices)):
                self.update_particle_velocity(i, h)
            for b in range(ti.static(self.model.n_bodies)):
                self.damp_soft_body(b, h)
        for b in range(ti.static(self.model.n_bodies)):
            self.apply_drag(b, h)

    @ti.func
    def substep_all_pairs(self, iterations: ti.i32, h: float, gravity: vec3, g_norm: float, kick: float,
                          depenetration: float, c_tri: ti.template(), c_bary_moved: ti.template(),
                          c_bary_other: ti.template(), c_normal: ti.template(), c_budget: ti.template(),
                          c_lambda_n: ti.template(), c_lambda_t: ti.template(), c_vn0: ti.template(),
                          c_impulse_t: ti.template(), b_lever: ti.template(), b_slip: ti.template(),
                          b_gap: ti.template(), b_k: ti.template(), b_rows: ti.template()):
        """One substep with the all-pairs broad phase (Müller 2020, Alg. 2: predict, contacts,
        projection, velocities, velocity pass; serial). Returns (rows wanted: candidate pairs or
        contact rows, whichever more, above the buffer's capacity if it overflowed; contact rows
        solved)."""
        capacity = c_tri.shape[0]
        self.predict(h, gravity, kick)
        for i in range(ti.static(self.model.n_vertices)):
            self.place_vertex(i)
        n = self.candidate_pairs(c_tri)
        wanted = n
        n = self.collide_candidates(ti.min(n, capacity), depenetration * h, c_tri, c_bary_moved, c_bary_other,
                                    c_normal, c_budget, c_lambda_n, c_lambda_t, c_vn0)
        needed = self.add_vertex_contacts(n, depenetration * h, c_tri, c_bary_moved, c_bary_other, c_normal,
                                          c_budget, c_lambda_n, c_lambda_t, c_vn0)
        needed = self.add_resting_contacts(needed, depenetration * h, c_tri, c_bary_moved, c_bary_other, c_normal,
                                           c_budget, c_lambda_n, c_lambda_t, c_vn0)
        wanted = ti.max(wanted, needed)
        n = ti.min(needed, capacity)
        n = self.carried_rows(n, depenetration * h, c_tri, c_bary_moved, c_bary_other, c_normal, c_budget,
                              c_lambda_n, c_lambda_t, c_vn0)
        self.project(n, iterations, h, c_tri, c_bary_moved, c_bary_other, c_normal, c_budget, c_lambda_n,
                     c_lambda_t, b_lever, b_slip, b_gap, b_k, b_rows)
        self.update_velocities(h)
        self.solve_velocities(n, iterations, h, g_norm, c_tri, c_bary_moved, c_bary_other, c_normal, c_lambda_n,
                              c_lambda_t, c_vn0, c_impulse_t)
        self.keep_rows(n, depenetration * h, c_tri, c_bary_moved, c_bary_other, c_normal, c_lambda_n)
        return wanted, n

    @ti.kernel
    def _frames_all_pairs(self, frames: ti.i32, substeps: ti.i32, iterations: ti.i32, h: float, gravity: vec3,
                          first_kick: float, bound: float, depenetration: float, check: ti.i32, max_impact: float,
                          thinnest: float, c_tri: ti.types.ndarray(dtype=ivec3, ndim=1),
                          c_bary_moved: ti.types.ndarray(dtype=vec3, ndim=1),
                          c_bary_other: ti.types.ndarray(dtype=vec3, ndim=1),
                          c_normal: ti.types.ndarray(dtype=vec3, ndim=1), c_budget: ti.types.ndarray(ndim=1),
                          c_lambda_n: ti.types.ndarray(ndim=1), c_lambda_t: ti.types.ndarray(dtype=vec3, ndim=1),
                          c_vn0: ti.types.ndarray(ndim=1),
                          c_impulse_t: ti.types.ndarray(dtype=vec3, ndim=1),
                          b_lever: ti.types.ndarray(dtype=vec3, ndim=1), b_slip: ti.types.ndarray(dtype=vec3, ndim=1),
                          b_gap: ti.types.ndarray(ndim=1),
                          b_k: ti.types.ndarray(dtype=mat3, ndim=1),
                          b_rows: ti.types.ndarray(dtype=ti.i32, ndim=1)) -> ti.types.vector(4, ti.i32):
        """Up to `frames` frames of substeps, serially in one launch (Müller 2020, Alg. 2 per
        substep). Each frame starts from a snapshot of the state. With `check`, each frame
        first runs `substeps_suffice`; if they do not, the launch stops before that frame
        (NEEDS_CHOICE). A frame whose candidates overflow the contact buffer is undone and the
        launch stops (OVERFLOW). Returns (frames done, most candidate pairs in the last frame
        begun, contacts of the last substep, status: 0, NEEDS_CHOICE, OVERFLOW or -1 - first
        bad body, the bad frame counted as done)."""
        done = 0
        most = 0
        n = 0
        status = 0
        g_norm = gravity.norm()
        capacity = c_tri.shape[0]
        ti.loop_config(serialize=True)
        for _ in range(1):
            while done < frames and status == 0:
                if check != 0 and self.substeps_suffice(substeps, h * substeps, g_norm, max_impact, thinnest) == 0:
                    status = NEEDS_CHOICE
                    break
                self.save_state()
                most = 0
                for sub in range(substeps):
                    kick = ti.select(done == 0 and sub == 0, first_kick, 1.0)
                    wanted, n = self.substep_all_pairs(iterations, h, gravity, g_norm, kick, depenetration, c_tri,
                                                       c_bary_moved, c_bary_other, c_normal, c_budget, c_lambda_n,
                                                       c_lambda_t, c_vn0, c_impulse_t, b_lever, b_slip, b_gap,
                                                       b_k, b_rows)
                    most = ti.max(most, wanted)
                if most > capacity:
                    self.restore_state()
                    status = OVERFLOW
                else:
                    for i in range(ti.static(self.model.n_vertices)):
                        self.place_vertex(i)
                    status = self.state_is_sane(bound)
                    done += 1
        return ti.Vector([done, most, n, status])

    @ti.kernel
    def _begin_substep(self, h: float, gravity: vec3, kick: float,
                       vertex_nd: ti.types.ndarray(dtype=vec3, ndim=1)):
        """Predict every body and particle in parallel and place the vertices for the grid."""
        self.predict(h, gravity, kick)
        for i in range(ti.static(self.model.n_vertices)):
            self.place_vertex(i)
            vertex_nd[i] = self.state.vertex_x[i]

    @ti.kernel
    def _end_substep(self, iterations: ti.i32, h: float, g_norm: float, bound: float, depenetration: float,
                     n_pairs: ti.i32,
                     p_pair: ti.types.ndarray(dtype=ivec2, ndim=1), p_depth: ti.types.ndarray(ndim=1),
                     p_normal: ti.types.ndarray(dtype=vec3, ndim=1), p_side: ti.types.ndarray(ndim=1),
                     p_point: ti.types.ndarray(dtype=vec3, ndim=1),
                     c_tri: ti.types.ndarray(dtype=ivec3, ndim=1),
                     c_bary_moved: ti.types.ndarray(dtype=vec3, ndim=1),
                     c_bary_other: ti.types.ndarray(dtype=vec3, ndim=1),
                     c_normal: ti.types.ndarray(dtype=vec3, ndim=1), c_budget: ti.types.ndarray(ndim=1),
                     c_lambda_n: ti.types.ndarray(ndim=1), c_lambda_t: ti.types.ndarray(dtype=vec3, ndim=1),
                     c_vn0: ti.types.ndarray(ndim=1),
                     c_impulse_t: ti.types.ndarray(dtype=vec3, ndim=1),
                     b_lever: ti.types.ndarray(dtype=vec3, ndim=1), b_slip: ti.types.ndarray(dtype=vec3, ndim=1),
                     b_gap: ti.types.ndarray(ndim=1),
                     b_k: ti.types.ndarray(dtype=mat3, ndim=1),
                     b_rows: ti.types.ndarray(dtype=ti.i32, ndim=1)) -> ti.types.vector(2, ti.i32):
        """The grid's contacts into constraints, projection and velocities of one substep.
        Returns (contacts, state check)."""
        n = 0
        ti.loop_config(serialize=True)
        for _ in range(1):
            # The same rows as the all-pairs path: the pipeline keeps touching pairs too.
            self.forget_rows()
            for k in range(n_pairs):
                n = self.add_pair_contact(n, p_pair[k], ti.cast(p_side[k], ti.i32), p_depth[k], p_normal[k],
                                          p_point[k], depenetration * h, c_tri, c_bary_moved, c_bary_other,
                                          c_normal, c_budget, c_lambda_n, c_lambda_t, c_vn0)
            # The buffer holds VERTEX_ROWS_PER_PAIR(_SOFT) rows per pair (_step_grid): every vertex contact fits.
            n = self.add_vertex_contacts(n, depenetration * h, c_tri, c_bary_moved, c_bary_other, c_normal,
                                         c_budget, c_lambda_n, c_lambda_t, c_vn0)
            # RESTING_ROWS_PER_SOFT_VERTEX more per soft vertex; resting rows past the buffer are dropped.
            n = ti.min(self.add_resting_contacts(n, depenetration * h, c_tri, c_bary_moved, c_bary_other, c_normal,
                                                 c_budget, c_lambda_n, c_lambda_t, c_vn0), c_tri.shape[0])
            n = self.carried_rows(n, depenetration * h, c_tri, c_bary_moved, c_bary_other, c_normal, c_budget,
                                  c_lambda_n, c_lambda_t, c_vn0)
            self.project(n, iterations, h, c_tri, c_bary_moved, c_bary_other, c_normal, c_budget, c_lambda_n,
                         c_lambda_t, b_lever, b_slip, b_gap, b_k, b_rows)
        self.update_velocities(h)
        status = 0
        ti.loop_config(serialize=True)
        for _ in range(1):
            self.solve_velocities(n, iterations, h, g_norm, c_tri, c_bary_moved, c_bary_other, c_normal,
                                  c_lambda_n, c_lambda_t, c_vn0, c_impulse_t)
            self.keep_rows(n, depenetration * h, c_tri, c_bary_moved, c_bary_other, c_normal, c_lambda_n)
            for i in range(ti.static(self.model.n_vertices)):
                self.place_vertex(i)
            status = self.state_is_sane(bound)
        return ti.Vector([n, status])

    # ----------------------------------------------------------------- python
    def step_frame(self, frame_dt: float, substeps: int, iterations: int,
                   max_impact_motion: float | None = None) -> int | None:
        """Advance the state by frame_dt seconds in `substeps` substeps of `iterations`
        Gauss-Seidel sweeps. Returns the contact count of the last substep. Raises
        SimulationError (naming the body) on NaN or a body beyond the bound.

        With max_impact_motion (m), the frame first checks that `substeps` are enough by the
        rules of Scene._substeps_for_next_frame and returns None, the state untouched, if
        they are not (or if it cannot check: the grid path); the caller then chooses the
        substeps and steps again. On the all-pairs path the check runs inside the frame's
        one launch, so that an ordinary frame costs no reading back of the state."""
        done, count = self.step_frames(1, frame_dt, substeps, iterations, max_impact_motion)
        return count if done else None

    def step_frames(self, frames: int, frame_dt: float, substeps: int, iterations: int,
                    max_impact_motion: float | None = None) -> tuple[int, int]:
        """Up to `frames` frames as `step_frame`, all in one launch on the all-pairs path;
        with max_impact_motion, stops before the first frame whose substeps do not suffice
        (on the grid path: before any). Returns (frames done, contact count of the last
        substep). Raises SimulationError as step_frame, after counting the bad frame."""
        if substeps < 1 or iterations < 1 or not frame_dt > 0:
            raise ValueError("frame_dt, substeps and iterations must be positive")
        h = frame_dt / substeps
        done = 0
        count = self.last_contact_count
        status = 0
        if self.use_grid:
            if max_impact_motion is not None:
                return 0, count
            for done in range(1, frames + 1):
                first_kick = 0.5 if self.state.substeps_done == 0 else 1.0
                count, status = self._step_grid(h, substeps, iterations, first_kick)
                self._frames_advanced(1, frame_dt, substeps, count)
                if status != 0:
                    break
        else:
            check = 0 if max_impact_motion is None else 1
            gravity = ti.Vector(list(self.gravity))
            while done < frames:
                first_kick = 0.5 if self.state.substeps_done == 0 else 1.0
                ran, most, count, status = (int(v) for v in self._frames_all_pairs(
                    frames - done, substeps, iterations, h, gravity, first_kick, self.bound,
                    self.depenetration_speed, check, max_impact_motion or 0.0, self.thinnest,
                    *self.contacts.arrays()))
                done += ran
                self._frames_advanced(ran, frame_dt, substeps, count)
                if status != OVERFLOW:
                    break
                self.contacts.grow(most)
                self.contact_growths += 1
        if status < 0:
            body = self.model.bodies[-1 - status].name
            raise SimulationError(f"body {body!r} has a NaN or exploded (|x| or |v| above {self.bound:g}) "
                                  f"by t = {self.state.time:.4g} s")
        return done, count

    def _frames_advanced(self, frames: int, frame_dt: float, substeps: int, count: int) -> None:
        for _ in range(frames):  # time as a sum of frames, as if stepped one by one
            self.state.frames_done += 1
            self.state.substeps_done += substeps
            self.state.time += frame_dt
            self.last_contact_count = count

    def _step_grid(self, h: float, substeps: int, iterations: int, first_kick: float) -> tuple[int, int]:
        gravity = ti.Vector(list(self.gravity))
        g_norm = float(np.linalg.norm(self.gravity))
        n = status = 0
        timing = self.phase_seconds
        for sub in range(substeps):
            start = time.perf_counter()
            self._begin_substep(h, gravity, first_kick if sub == 0 else 1.0, self.vertex_nd)
            if timing is not None:
                ti.sync()
                timing["predict"] = timing.get("predict", 0.0) + time.perf_counter() - start
            self.pipeline.run(self.vertex_nd, timing)
            start = time.perf_counter()
            pc = self.pipeline.contacts
            rows = VERTEX_ROWS_PER_PAIR_SOFT if self.model.has_soft else VERTEX_ROWS_PER_PAIR
            wanted = rows * pc.count + RESTING_ROWS_PER_SOFT_VERTEX * self.soft_vertex_count
            if wanted > self.contacts.capacity:
                self.contacts.grow(wanted)
                self.contact_growths += 1
            n, status = (int(v) for v in self._end_substep(
                iterations, h, g_norm, self.bound, self.depenetration_speed, pc.count, pc.pair, pc.depth, pc.normal, pc.side, pc.point,
                *self.contacts.arrays()))
            if timing is not None:
                timing["projection"] = timing.get("projection", 0.0) + time.perf_counter() - start
            if status != 0:
                break
        return n, status
