"""Model (what does not change during a run) and State (what does), as Taichi fields.

Both are filled by `ModelBuilder.finalize` into a field set of `core.pool` (`model_fields`
lays it out), which has at least as many rows as the scene needs: kernels loop over the
scene's counts (`body_count` ...), read at run time, never over a field's rows. The solver
reads the Model and advances the State in place. Units: metres, kilograms, seconds.

Every body's vertices live in one global array `vertex_x` (world space), which is
what the collision pipeline tests. A rigid or static body's vertices are derived
from its pose (`body_x`, `body_q`) and body-frame offsets `vertex_local`; a soft
body's vertices are its particles.
"""

from dataclasses import dataclass, field

import numpy as np
import taichi as ti

from . import runtime

STATIC = 0
RIGID = 1
SOFT = 2
# A cloth is a soft body (its vertices are particles) with an open surface: no volume, bending
# pairs among its edges, and faces that are two-sided in contact (contact.cloth).
KIND_NAMES = {"static": STATIC, "rigid": RIGID, "soft": SOFT, "cloth": SOFT}
DEFORMABLE_KINDS = ("soft", "cloth")


@ti.func
def body_vertex_box(model: ti.template(), state: ti.template(), b: ti.i32):
    """(lo, hi): the box of body b's vertices in world space now (m)."""
    lo = ti.math.vec3(ti.math.inf)
    hi = ti.math.vec3(-ti.math.inf)
    for i in range(model.body_vertex_range[b][0], model.body_vertex_range[b][1]):
        lo = ti.min(lo, state.vertex_x[i])
        hi = ti.max(hi, state.vertex_x[i])
    return lo, hi


@dataclass
class BodyInfo:
    """Per-body facts kept on the Python side (names, index ranges, mesh faces)."""

    name: str
    kind: str
    vertex_start: int
    vertex_count: int
    tri_start: int
    tri_count: int
    faces: np.ndarray  # (tri_count, 3) local vertex indices
    mass: float
    rest_volume: float
    thickness: float = float("inf")  # m, the thinnest wall (tunnelling.mesh_thickness)
    reach: float = 0.0               # m, largest distance of a vertex from the centre of mass
    self_collision: bool = False     # a soft body whose own triangles collide
    self_gap: float = 0.0            # m, the gap a closed soft body's own walls keep (contact.cloth.pair_gap)

    @property
    def deformable(self) -> bool:
        """Whether its vertices are particles of their own (kind soft or cloth)."""
        return self.kind in DEFORMABLE_KINDS


@dataclass
class Model:
    """Static data. Sizes: B bodies, V vertices, T triangles, E soft edges (0 without soft bodies).

    body_kind (B,) i32 STATIC/RIGID/SOFT; body_inv_mass (B,); body_inertia, body_inv_inertia
    (B,) mat3 in the body frame (kg·m², about the centre of mass); body_force (B,) vec3 N at the
    centre of mass; body_friction, body_restitution (B,); body_vertex_range, body_tri_range (B,)
    ivec2 [start, end); body_compliance (B,) m/N of a soft body's edges, body_damping (B,) 1/s the
    decay rate of its particles' velocities relative to its rigid motion; body_drag (B,) 1/s the
    decay rate of every point's velocity (velocity damping); body_spin_friction (B,) m, the
    largest torque about a contact normal per newton of normal force; body_rest_volume (B,) m³.
    body_count, vertex_count, tri_count, edge_count (1,) i32: B, V, T, E for the kernels.
    vertex_body (V,) i32; vertex_local (V,) vec3 body-frame offset from the centre of mass;
    vertex_inv_mass (V,) 1/kg (soft particles, else 0). tri_indices (T,) ivec3 global vertex
    indices; tri_body (T,) i32; tri_hidden (T,) i32 1 for a static face hidden against another
    static body's (contact/hidden_faces.py: never in contact). With soft bodies only:
    body_self_collision (B,) i32 1 where a soft body's own triangles collide; body_cloth (B,) i32
    1 for a cloth (no volume, two-sided faces); edge_indices (E,) ivec2; edge_rest (E,) m;
    edge_compliance (E,) m/N (a cloth's bending pairs are edges too, with their own compliance);
    the edges in the order the sweeps solve them (scene.builder.wavefront_order).
    """

    bodies: list[BodyInfo]
    n_bodies: int
    n_vertices: int
    n_tris: int
    n_edges: int
    has_soft: bool
    body_count: ti.Field
    vertex_count: ti.Field
    tri_count: ti.Field
    edge_count: ti.Field
    body_kind: ti.Field
    body_inv_mass: ti.Field
    body_inertia: ti.Field
    body_inv_inertia: ti.Field
    body_force: ti.Field
    body_friction: ti.Field
    body_restitution: ti.Field
    body_vertex_range: ti.Field
    body_tri_range: ti.Field
    body_compliance: ti.Field
    body_damping: ti.Field
    body_drag: ti.Field
    body_spin_friction: ti.Field
    body_rest_volume: ti.Field
    vertex_body: ti.Field
    vertex_local: ti.Field
    vertex_inv_mass: ti.Field
    tri_indices: ti.Field
    tri_body: ti.Field
    tri_hidden: ti.Field
    body_self_collision: ti.Field | None = None
    body_cloth: ti.Field | None = None
    edge_indices: ti.Field | None = None
    edge_rest: ti.Field | None = None
    edge_compliance: ti.Field | None = None
    has_cloth: bool = False
    has_self_gap: bool = False  # a closed soft body keeps a gap between its own walls
    tri_indices_np: np.ndarray = field(default=None, repr=False)
    tri_body_np: np.ndarray = field(default=None, repr=False)
    tri_hidden_np: np.ndarray = field(default=None, repr=False)
    body_kind_np: np.ndarray = field(default=None, repr=False)  # a copy of body_kind, read every frame
    field_set: object = field(default=None, repr=False)  # the pool's set holding these fields

    def body_index(self, name: str) -> int:
        for k, b in enumerate(self.bodies):
            if b.name == name:
                return k
        raise KeyError(f"no body named {name!r}")


@dataclass
class State:
    """Time-varying data. body_x (B,) vec3 centre of mass (m); body_q (B,) vec4 unit
    quaternion (w, x, y, z); body_v (B,) m/s; body_w (B,) rad/s, world frame; *_prev the
    same at the start of the substep. vertex_x (V,) world positions; vertex_x_prev and
    vertex_v (V,) for soft particles. time in seconds; frames_done and substeps_done count
    what the solver has run."""

    body_x: ti.Field
    body_q: ti.Field
    body_v: ti.Field
    body_w: ti.Field
    body_x_prev: ti.Field
    body_q_prev: ti.Field
    vertex_x: ti.Field
    vertex_x_prev: ti.Field
    vertex_v: ti.Field
    time: float = 0.0
    frames_done: int = 0
    substeps_done: int = 0


MODEL_FIELD_NAMES = ("body_count", "vertex_count", "tri_count", "edge_count", "body_kind", "body_inv_mass",
                     "body_inertia", "body_inv_inertia", "body_force", "body_friction", "body_restitution",
                     "body_vertex_range", "body_tri_range", "body_compliance", "body_damping", "body_drag",
                     "body_spin_friction", "body_rest_volume", "vertex_body", "vertex_local", "vertex_inv_mass",
                     "tri_indices", "tri_body", "tri_hidden", "body_self_collision", "body_cloth", "edge_indices",
                     "edge_rest", "edge_compliance")
STATE_FIELD_NAMES = ("body_x", "body_q", "body_v", "body_w", "body_x_prev", "body_q_prev", "vertex_x",
                     "vertex_x_prev", "vertex_v")


def model_fields(rows: dict[str, int], has_soft: bool) -> dict:
    """The fields of a Model and State (MODEL_FIELD_NAMES, STATE_FIELD_NAMES → field) with
    rows["bodies"], ["vertices"], ["tris"], ["edges"] rows, in one SNode tree. Without soft
    bodies the edge fields are None and the particles' own fields have one row."""
    b, v, t, e = rows["bodies"], rows["vertices"], rows["tris"], rows["edges"]
    i32 = ti.i32
    particles = v if has_soft else 1
    with runtime.field_block():
        return dict(
            body_count=scalar_field(1, i32), vertex_count=scalar_field(1, i32),
            tri_count=scalar_field(1, i32), edge_count=scalar_field(1, i32),
            body_kind=scalar_field(b, i32), body_inv_mass=scalar_field(b), body_inertia=mat_field(b),
            body_inv_inertia=mat_field(b), body_force=vec_field(b), body_friction=scalar_field(b),
            body_restitution=scalar_field(b), body_vertex_range=vec_field(b, 2, i32),
            body_tri_range=vec_field(b, 2, i32), body_compliance=scalar_field(b), body_damping=scalar_field(b),
            body_drag=scalar_field(b), body_spin_friction=scalar_field(b), body_rest_volume=scalar_field(b),
            vertex_body=scalar_field(v, i32), vertex_local=vec_field(v), vertex_inv_mass=scalar_field(v),
            tri_indices=vec_field(t, 3, i32), tri_body=scalar_field(t, i32), tri_hidden=scalar_field(t, i32),
            body_self_collision=scalar_field(b, i32) if has_soft else None,
            body_cloth=scalar_field(b, i32) if has_soft else None,
            edge_indices=vec_field(e, 2, i32) if has_soft else None,
            edge_rest=scalar_field(e) if has_soft else None,
            edge_compliance=scalar_field(e) if has_soft else None,
            body_x=vec_field(b), body_q=vec_field(b, 4), body_v=vec_field(b), body_w=vec_field(b),
            body_x_prev=vec_field(b), body_q_prev=vec_field(b, 4), vertex_x=vec_field(v),
            vertex_x_prev=vec_field(particles), vertex_v=vec_field(particles),
        )


def _allocate(make, n: int) -> ti.Field:
    """make(shape) → a field of max(n, 1) rows; inside runtime.field_block it joins the
    block's SNode tree (allocated when the block closes)."""
    rows = max(n, 1)
    fld = make(None) if runtime.in_field_block() else make(rows)
    if runtime.in_field_block():
        runtime.place(fld, rows)
    return fld


def vec_field(n: int, dim: int = 3, dtype=None) -> ti.Field:
    """A field of `dim`-vectors of the kernels' float type (or dtype), at least one row."""
    return _allocate(lambda shape: ti.Vector.field(dim, dtype or runtime.real_type(), shape=shape), n)


def scalar_field(n: int, dtype=None) -> ti.Field:
    return _allocate(lambda shape: ti.field(dtype or runtime.real_type(), shape=shape), n)


def mat_field(n: int) -> ti.Field:
    return _allocate(lambda shape: ti.Matrix.field(3, 3, runtime.real_type(), shape=shape), n)
