"""The solver's own fields and the bundle `sim` that every solver and contact-rule `ti.func`
takes (with the fields of the Model and State it steps), so that no function threads a dozen
fields through its arguments. Both are made once per field set of `core.pool` and reused by
every scene that gets the set."""

import numpy as np
import taichi as ti

from ..contact.exits import convex_neighbours, sharp_edge_bits
from ..contact.rules import ContactRules
from ..contact.cloth import CLOTH_GAP_FRACTION
from ..contact.soft_rows import SOFT_BOX_MARGIN
from ..core import pool, runtime
from ..core.geometry import vertex_neighbours
from ..core.upload import upload
from ..core.model import (MODEL_FIELD_NAMES, SOFT, STATE_FIELD_NAMES, Model, State, mat_field, scalar_field,
                          vec_field)


# The solver's fields: name → (count the rows follow, kind), kind "scalar", "int", "vec<k>",
# "ivec<k>" or "mat". "carry" rows hold the rows carried from one substep to the next; "one"
# fields have a single row.
_LAYOUT = {
    "tri_lo": ("tris", "vec3"), "tri_hi": ("tris", "vec3"),
    "body_lo": ("bodies", "vec3"), "body_hi": ("bodies", "vec3"),
    # Each rigid or static body's vertex box in the current substep (soft_rows.solid_boxes).
    "solid_lo": ("bodies", "vec3"), "solid_hi": ("bodies", "vec3"),
    "body_level": ("bodies", "int"),
    # The last contact row whose moved triangle belongs to each body (-1: none); each
    # row links to the one before it (ContactConstraints.tri), for is_duplicate.
    "body_last_row": ("bodies", "int"),
    "body_mass": ("bodies", "scalar"),
    # Each rigid body's rotation vector over the current substep (rad): predicted plus
    # every angular correction, added up so that the angular impulses add up exactly.
    "body_theta": ("bodies", "vec3"),
    # solve_blocks: each rigid body's move and turn (rad) in the current block
    # solve, and its world inverse inertia at the substep's start (set by project).
    "block_dx": ("bodies", "vec3"), "block_dtheta": ("bodies", "vec3"), "block_inv_inertia": ("bodies", "mat"),
    # Each island's rows in b_rows, indexed by its root: [block_first, block_first + block_len).
    "block_first": ("bodies", "int"), "block_len": ("bodies", "int"),
    # Islands of rigid bodies joined by rows between them (union-find: each body's
    # parent, the root its own), and 1 at the root of an island of several bodies.
    "block_island": ("bodies", "int"), "block_coupled": ("bodies", "int"),
    # Per rigid body, the mass (kg) of the heaviest rigid body a row of its island ties it to,
    # its own if none (solver.islands.mark_loaded), for the substep.
    "block_heaviest": ("bodies", "scalar"),
    # The roots of the islands with rows, the most work first, how many, and the next one for a
    # worker to take; the substep's rows (solver.islands.list_islands,
    # solver.kernels.end_substep).
    "island_list": ("bodies", "int"), "island_count": ("one", "int"), "island_next": ("one", "int"),
    "island_rows": ("one", "int"),
    # With sweep statistics on (SolverFields.count_sweeps), the block solves counted since the
    # last reset (solver.islands.count_block_sweeps): for lone bodies, then for islands of
    # several, the solves, their normal and friction sweeps, the phases that ran to the cap, and
    # the rows solved.
    "sweep_stats": ("one", "ivec12"),
    # Each island's rigid bodies, by root: island_bodies[island_body_first[root]:][:island_body_count[root]].
    "island_bodies": ("bodies", "int"), "island_body_first": ("bodies", "int"),
    "island_body_count": ("bodies", "int"),
    # The unit vector against gravity (0 without gravity), set by integrate.predict each
    # substep: solver.islands.support_pass projects the rows whose normal lies near it.
    "up": ("one", "vec3"),
    "body_thickness": ("bodies", "scalar"),
    "body_reach": ("bodies", "scalar"),  # farthest vertex from a rigid body's centre (m)
    # Per body for the next frame's substep choice (_summarize_bodies): velocity (3),
    # speed about it (1), vertex box low (3) and high (3) corners.
    "body_summary": ("bodies", "vec10"),
    "body_box_margin": ("bodies", "scalar"),
    "body_self_gap": ("bodies", "scalar"),  # BodyInfo.self_gap (m)
    # One triangle holding each vertex: the moved triangle of a soft vertex's resting row.
    "vertex_tri": ("vertices", "int"),
    # Bit k of tri_sharp_edges[t]: edge k (vertex k to k+1) of a rigid or static face is
    # a convex edge sharper than SHARP_EDGE_DEGREES that this face owns (resting edge rows).
    "tri_sharp_edges": ("tris", "int"),
    # The triangles across each face's convex edges, -1 elsewhere (nearest_exit).
    "tri_convex_nbr": ("tris", "ivec3"),
    # The rows that pushed in the last substep (carry_rows), offered again in the next one,
    # and their copy at the start of a frame (save_state).
    "carry_tri": ("carry", "ivec2"), "carry_bary_moved": ("carry", "vec3"),
    "carry_bary_other": ("carry", "vec3"), "carry_normal": ("carry", "vec3"), "carry_count": ("one", "int"),
    "saved_carry_tri": ("carry", "ivec2"), "saved_carry_bary_moved": ("carry", "vec3"),
    "saved_carry_bary_other": ("carry", "vec3"), "saved_carry_normal": ("carry", "vec3"),
    "saved_carry_count": ("one", "int"),
    # Sleeping (solver.sleep): 1 for a body asleep; how long (s) each rigid body has been calm and
    # its pose when its calm began; per island root the least of its bodies' calm times; the
    # speed (m/s) and time (s) a body must be calm to sleep (time 0: never).
    "body_asleep": ("bodies", "int"), "body_calm": ("bodies", "scalar"), "island_calm": ("bodies", "scalar"),
    "body_calm_x": ("bodies", "vec3"), "body_calm_q": ("bodies", "vec4"),
    "sleep_speed": ("one", "scalar"), "sleep_time": ("one", "scalar"),
    # A copy of the state at the start of a frame, restored when the frame overflows the contact buffer.
    "saved_body_x": ("bodies", "vec3"), "saved_body_q": ("bodies", "vec4"), "saved_body_v": ("bodies", "vec3"),
    "saved_body_w": ("bodies", "vec3"), "saved_body_asleep": ("bodies", "int"), "saved_body_calm": ("bodies", "scalar"),
    "saved_body_calm_x": ("bodies", "vec3"), "saved_body_calm_q": ("bodies", "vec4"),
}
_SOFT_LAYOUT = {
    "edge_lambda": ("edges", "scalar"),
    # The angular momentum a soft body's projection gave it beyond its contacts' (solver.soft_spin).
    "soft_spin_error": ("bodies", "vec3"),
    "vertex_grad": ("vertices", "vec3"),
    "saved_vertex_x": ("vertices", "vec3"), "saved_vertex_v": ("vertices", "vec3"),
    # The self-colliding bodies' vertex neighbours (core.geometry.near_in_mesh): each vertex's
    # [first, end) in vertex_nbr.
    "vertex_nbr_range": ("vertices", "ivec2"), "vertex_nbr": ("vertex_nbrs", "int"),
}


def _allocate(rows: dict[str, int], has_soft: bool) -> dict:
    """The solver's fields for a field set with these rows, in one SNode tree."""
    out = {}
    with runtime.field_block():
        for name, (count, kind) in (_LAYOUT | (_SOFT_LAYOUT if has_soft else {})).items():
            n = rows[count]
            if kind == "scalar":
                out[name] = scalar_field(n)
            elif kind == "int":
                out[name] = scalar_field(n, ti.i32)
            elif kind == "mat":
                out[name] = mat_field(n)
            elif kind.startswith("ivec"):
                out[name] = vec_field(n, int(kind[4:]), ti.i32)
            else:
                out[name] = vec_field(n, int(kind[3:]))
    return out


class FieldView:
    """Fields by attribute, as the solver's `ti.func`s read them (sim.model.tri_indices ...)."""

    def __init__(self, fields: dict, **facts):
        self.__dict__.update(fields)
        self.__dict__.update(facts)


@ti.data_oriented
class SolverFields:
    """The bundle `sim` every solver and contact-rule `ti.func` takes: `model` and `state` (the
    Model's and State's fields), the solver's own fields, `rules` (which contact rules are
    compiled in), `has_spin_friction` (whether the spin-friction pass is) and `count_sweeps`
    (whether the block solves count their sweeps into sweep_stats). Made by
    `solver_fields`, once per field set and variant, so that kernels compiled for it serve
    every scene that uses the set. Body fields have at least n_bodies rows, triangle fields
    n_tris, vertex fields n_vertices; lengths in metres.
    """

    def __init__(self, model: FieldView, state: FieldView, fields: dict, rules: ContactRules,
                 has_spin_friction: bool, carry_capacity: int, count_sweeps: bool = False):
        self.model = model
        self.state = state
        self.rules = rules
        self.has_spin_friction = has_spin_friction
        self.count_sweeps = count_sweeps
        self.carry_capacity = carry_capacity
        self.__dict__.update(fields)
        self.saved_carry = [fields[f"saved_carry_{k}"] for k in ("tri", "bary_moved", "bary_other", "normal", "count")]
        self.saved_body = [fields[f"saved_body_{k}"] for k in ("x", "q", "v", "w", "asleep", "calm", "calm_x",
                                                                "calm_q")]
        self.saved_vertex = [fields["saved_vertex_x"], fields["saved_vertex_v"]] if model.has_soft else None
        self.box_margin_np = np.zeros(0)


def solver_fields(model: Model, state: State, rules: ContactRules | None = None,
                  count_sweeps: bool = False) -> SolverFields:
    """The solver's bundle for this Model and State, its fields filled for them: one made
    before for the same field set (core.pool) and variant, or a new one. `rules` says which
    contact rules are compiled in (all by default); the spin-friction pass is compiled in
    only where some body has spin friction; `count_sweeps` compiles in the block solves'
    sweep statistics."""
    m = model
    rules = rules or ContactRules()
    field_set = m.field_set
    parts = field_set.parts
    fresh = "solver" not in parts
    if fresh:
        # A vertex's neighbours take an entry per edge end: at most 6 per triangle (an open mesh).
        rows = dict(field_set.capacity, carry=max(1024, field_set.capacity["tris"]), one=1,
                    vertex_nbrs=max(1, 6 * field_set.capacity["tris"]))
        parts["solver"] = _allocate(rows, m.has_soft)
        parts["model"] = FieldView({k: field_set.fields[k] for k in MODEL_FIELD_NAMES}, has_soft=m.has_soft,
                                   has_cloth=m.has_cloth, has_self_gap=m.has_self_gap)
        parts["state"] = FieldView({k: field_set.fields[k] for k in STATE_FIELD_NAMES})
    has_spin_friction = bool((m.body_spin_friction.to_numpy()[: m.n_bodies] > 0.0).any())
    key = ("sim", rules, has_spin_friction) + (("count_sweeps",) if count_sweeps else ())
    if key not in parts:
        parts[key] = SolverFields(parts["model"], parts["state"], parts["solver"], rules, has_spin_friction,
                                  carry_capacity=parts["solver"]["carry_tri"].shape[0], count_sweeps=count_sweeps)
    sim = parts[key]
    _fill(sim, parts["solver"], m, state, fresh)
    return sim


def _fill(sim: SolverFields, fields: dict, m: Model, state: State, fresh: bool) -> None:
    """Every solver field of this scene: its data, or zeros (a fresh set's fields are zero)."""
    kind = m.body_kind_np
    real = runtime.real_dtype()
    rest_x = state.vertex_x.to_numpy()[: m.n_vertices]
    thickness = np.array([min(b.thickness, 1e30) for b in m.bodies])
    # A cloth's boxes also reach as far as the gap its triangles keep from other sheets'.
    margin = np.array([max(SOFT_BOX_MARGIN, CLOTH_GAP_FRACTION if b.kind == "cloth" else 0.0) for b in m.bodies])
    self_gap = np.array([b.self_gap for b in m.bodies])
    # A closed soft body's boxes reach at least as far as the gap between its own walls.
    box_margin = np.where(kind == SOFT, np.maximum(margin * thickness, self_gap), 0.0)
    vertex_tri = np.zeros(max(m.n_vertices, 1), np.int32)
    vertex_tri[m.tri_indices_np[::-1].ravel()] = np.repeat(np.arange(m.n_tris)[::-1], 3)
    data = {
        "body_mass": np.array([min(b.mass, 1e30) for b in m.bodies], real),
        "body_thickness": thickness.astype(real),
        "body_reach": np.array([min(b.reach, 1e30) for b in m.bodies], real),
        "body_box_margin": box_margin.astype(real),
        "body_self_gap": self_gap.astype(real),
        "vertex_tri": vertex_tri,
        "tri_convex_nbr": convex_neighbours(m, rest_x),
    }
    if m.has_soft:
        data["tri_sharp_edges"] = sharp_edge_bits(m, rest_x)
        self_tris = np.array([b.self_collision for b in m.bodies], bool)[m.tri_body_np]
        data["vertex_nbr_range"], data["vertex_nbr"] = vertex_neighbours(m.tri_indices_np, m.n_vertices, self_tris)
    upload([(fields[name], pool.padded(values, fields[name].shape[0])) for name, values in data.items()])
    if not fresh:
        scratch = [fld for name, fld in fields.items() if name not in data]
        for start in range(0, len(scratch), ZERO_BATCH):
            _zero(tuple(scratch[start:start + ZERO_BATCH]))
    sim.box_margin_np = box_margin  # (B,) the grid pads soft bodies' boxes by it too


# Fields zeroed per launch: Taichi warns of long compiles past 32 unrolled iterations.
ZERO_BATCH = 16


@ti.kernel
def _zero(fields: ti.template()):
    """Every element of every field in `fields` (a tuple) to zero, in one launch (a fill per
    field would compile a kernel for each)."""
    for k in ti.static(range(len(fields))):
        for index in ti.grouped(fields[k]):
            fields[k][index] = ti.zero(fields[k][index])  # not *= 0: NaN * 0 is NaN
