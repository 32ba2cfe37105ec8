"""Writing contact rows: a row ties an anchor of the moved triangle to one on the other along a
normal (Eq. 6 of Kikuchi & Kanai with −∇C = N), with its correction budget; each body's rows
form a chain (ContactRows.tri[k][2]) so that duplicates and pair rows are found without a search."""

from typing import Any, NamedTuple

import taichi as ti

from ..collision.contacts import GrowableBuffer
from ..core import runtime
from ..core.geometry import barycentric
from ..core.model import RIGID
from .anchors import anchor_velocity, anchor_world, closing, involves_soft, longest_edge
from .cloth import pair_gap

vec3 = ti.math.vec3
ivec3 = ti.types.vector(3, ti.i32)

# Contacts are checked for duplicates while the buffer holds at most this many rows (each
# check walks the moved body's rows, so one body with thousands of contacts is quadratic;
# large scenes' contacts rarely share points exactly).
DEDUP_MAX_ROWS = 4096

# Between two rigid bodies a row whose moved point lies within this barycentric weight of a
# vertex of its triangle, its target over the other triangle's face within the same weight,
# counts as that vertex over the face (write_contact: its budget is not capped at its depth).
# Where boxes of one footprint stand on each other, their side faces cross at the corners 4 µm
# (1e-5 of the edge) from the vertex: capped there and not on the corners whose pair met the
# vertex itself, the rows spent their budget on one side as the box tilted: each box of a
# ten-box stack landed deeper than the one below (up to 0.34 mm), and a three-box stack rested
# 6.4 µm into itself (now 3e-10 m). At 1e-3 the landing boxes bounced 50-170 µm up.
NEAR_VERTEX_WEIGHT = 1e-4


class ContactRows(NamedTuple):
    """A substep's contact rows inside a kernel: the row arrays of ContactConstraints (in its
    `arrays()` order) under one name, so that each `ti.func` takes `rows` instead of a dozen
    arrays (rows.tri[k], rows.normal[k], rows.block_k[k], ...). Build it in the kernel as
    `rows = ti.static(ContactRows(*arrays))`: a tuple passes through Taichi as it is."""

    tri: Any
    bary_moved: Any
    bary_other: Any
    normal: Any
    budget: Any
    hold: Any
    lambda_n: Any
    lambda_t: Any
    vn0: Any
    impulse_t: Any
    block_lever: Any
    block_slip: Any
    block_gap: Any
    block_k: Any
    block_rows: Any
    block_mu: Any
    block_reach: Any


class ContactConstraints(GrowableBuffer):
    """The solver's contact constraints of one substep (Taichi ndarrays, fixed capacity).

    Row k ties a point of the moved triangle `tri[k][0]` (barycentric weights
    `bary_moved[k]`) to a point of the other triangle `tri[k][1]` (`bary_other[k]`);
    `tri[k][2]` is the row before it with a moved triangle of the same body (-1: none);
    the moved point is pushed along the unit `normal[k]` until it reaches the other
    point's plane. `budget[k]` is how much more of C (m) it may correct this substep (see
    solver.solver.DEPENETRATION_SPEED); on a row with a soft body it is instead the depth (m) the
    row may leave (a soft body's own constraints move the anchors back and forth between
    sweeps, so a spent budget would stop the row halfway); `hold[k]` the C (m) the row holds,
    pushing only while C is above it (0 but on a row carried between two rigid bodies:
    contact.carried.carried_rows), `lambda_n[k]` the
    normal multiplier accumulated this substep (kg·m), `lambda_t[k]` the static-friction one
    (vec3 in the tangent plane, kg·m: corrections that point different ways partly cancel), `vn0[k]`
    the relative normal velocity before the solve (m/s, for restitution),
    `impulse_t[k]` the dynamic-friction impulse accumulated by the velocity pass (kg·m/s);
    `block_*` the linearisation of a rigid body's row (solver.islands.solve_blocks):
    its lever from the (moved) body's centre (m), tangential slip (m), gap (m) and 3×3 inverse
    mass (the two bodies' summed for a row between rigid bodies), and for the sweeps, which
    project each row many times, its friction coefficient μ (`block_mu`) and the length of
    its lever (`block_reach`, m: a sweep has converged once no row moves its anchor by more
    than a tolerance times that);
    `block_rows` the indices of those rows.
    """

    def _allocate(self, capacity: int) -> None:
        real = runtime.real_type()
        vec3 = ti.types.vector(3, real)
        self.tri = ti.ndarray(ivec3, shape=capacity)
        self.bary_moved = ti.ndarray(vec3, shape=capacity)
        self.bary_other = ti.ndarray(vec3, shape=capacity)
        self.normal = ti.ndarray(vec3, shape=capacity)
        self.budget = ti.ndarray(real, shape=capacity)
        self.hold = ti.ndarray(real, shape=capacity)
        self.lambda_n = ti.ndarray(real, shape=capacity)
        self.lambda_t = ti.ndarray(vec3, shape=capacity)
        self.vn0 = ti.ndarray(real, shape=capacity)
        self.impulse_t = ti.ndarray(vec3, shape=capacity)
        self.block_lever = ti.ndarray(vec3, shape=capacity)
        self.block_slip = ti.ndarray(vec3, shape=capacity)
        self.block_gap = ti.ndarray(real, shape=capacity)
        self.block_k = ti.ndarray(ti.types.matrix(3, 3, real), shape=capacity)
        self.block_rows = ti.ndarray(ti.i32, shape=capacity)
        self.block_mu = ti.ndarray(real, shape=capacity)
        self.block_reach = ti.ndarray(real, shape=capacity)

    def arrays(self) -> tuple:
        """The ndarrays in the order the solver's kernels take them (ContactRows' fields)."""
        return tuple(getattr(self, name) for name in ContactRows._fields)


@ti.func
def forget_rows(sim: ti.template()):
    """Start a substep's contact rows: no body has a row yet."""
    for b in range(sim.model.body_count[0]):
        sim.body_last_row[b] = -1


@ti.func
def start_row(sim: ti.template(), rows: ti.template(), k: ti.i32, t_moved: ti.i32, t_other: ti.i32, bary_m: vec3,
              bary_o: vec3, normal: vec3, p_moved: vec3, p_other: vec3, max_push: float) -> float:
    """Row k ties anchor bary_m on t_moved (now at p_moved) to anchor bary_o on t_other (now at
    p_other) along the normal N: links it into the moved body's row chain, clears its
    multipliers, keeps the anchors' normal velocity before projection, and gives it the
    budget (m) max(approach, 0) + max_push. Returns the approach: how much
    N·(p_other − p_moved) grew during this substep."""
    body_m = sim.model.tri_body[t_moved]
    rows.tri[k] = ivec3(t_moved, t_other, sim.body_last_row[body_m])
    sim.body_last_row[body_m] = k
    rows.bary_moved[k] = bary_m
    rows.bary_other[k] = bary_o
    rows.normal[k] = normal
    approach = closing(sim, t_moved, t_other, bary_m, bary_o, normal, p_moved, p_other)
    rows.budget[k] = ti.max(approach, 0.0) + max_push
    rows.hold[k] = 0.0
    rows.lambda_n[k] = 0.0
    rows.lambda_t[k] = vec3(0.0)
    rows.vn0[k] = (anchor_velocity(sim, t_moved, bary_m, p_moved)
                - anchor_velocity(sim, t_other, bary_o, p_other)).dot(normal)
    return approach


@ti.func
def write_contact(sim: ti.template(), rows: ti.template(), k: ti.i32, t_moved: ti.i32, t_other: ti.i32, depth: float,
                  normal: vec3, point: vec3, max_push: float):
    """Row k: the moved triangle's deepest point and the point C·N further on, on the
    other triangle, as barycentric anchors (Eq. 6 with −∇C = N). Its correction budget
    (m) is the depth the substep's own motion made plus `max_push` of older depth, and
    no more than C itself unless the point is a vertex over the other triangle. With a
    soft body the row holds the depth it may leave instead: the older depth less
    `max_push` (ContactConstraints)."""
    im, io = sim.model.tri_indices[t_moved], sim.model.tri_indices[t_other]
    bary_m = barycentric(point, sim.state.vertex_x[im[0]], sim.state.vertex_x[im[1]], sim.state.vertex_x[im[2]])
    target = point + depth * normal
    bary_o = barycentric(target, sim.state.vertex_x[io[0]], sim.state.vertex_x[io[1]], sim.state.vertex_x[io[2]])
    approach = start_row(sim, rows, k, t_moved, t_other, bary_m, bary_o, normal, point, target, max_push)
    if involves_soft(sim, t_moved, t_other):
        # Two cloth triangles, or two of one closed soft body, were tested moved together by
        # their gap: the real anchors are the gap further apart than the depth says, and the
        # row keeps them so.
        rows.budget[k] = ti.max(depth - approach - max_push, 0.0) - pair_gap(sim, t_moved, t_other)
    # A vertex of the moved triangle over the other's face is a plain vertex-face contact,
    # and may correct more than its detected depth when its neighbours turn the body. Any
    # other deepest point (an edge crossing, a feature on a boundary) may carry a depth
    # measured along a poor normal: it corrects at most that depth. Between two rigid bodies
    # a point NEAR_VERTEX_WEIGHT from a vertex is that vertex.
    if not involves_soft(sim, t_moved, t_other):
        weight = 0.0
        if ti.static(sim.rules.near_vertex):
            weight = ti.select(both_rigid(sim, t_moved, t_other), NEAR_VERTEX_WEIGHT, 0.0)
        if not at_vertex_over_face(bary_m, bary_o, weight):
            rows.budget[k] = ti.min(depth, rows.budget[k])


@ti.func
def at_vertex_over_face(bary_moved: vec3, bary_other: vec3, weight: float) -> bool:
    """Whether a row's anchors (barycentric on the moved and on the other triangle) are a vertex
    of the moved triangle over the other's face, up to rounding or `weight` if more: a plain
    vertex-face contact, whose depth is measured along a normal that is right for it."""
    tol = ti.max(ti.static(runtime.tolerance()), weight)
    return bary_moved.max() >= 1.0 - tol and bary_other.min() >= -tol


@ti.func
def both_rigid(sim: ti.template(), t_a: ti.i32, t_b: ti.i32) -> bool:
    """Whether triangles t_a and t_b both belong to rigid bodies."""
    return (sim.model.body_kind[sim.model.tri_body[t_a]] == RIGID
            and sim.model.body_kind[sim.model.tri_body[t_b]] == RIGID)


@ti.func
def is_duplicate(sim: ti.template(), rows: ti.template(), n: ti.i32, t_moved: ti.i32, t_other: ti.i32, normal: vec3,
                 point: vec3) -> bool:
    """Whether rows [0, n) already hold this constraint: same two bodies, same normal and
    the same moved point (within √eps of the moved triangle's size). A vertex or edge shared by
    several triangles is reported by each triangle pair; projecting every copy would weigh
    that point several times and make the Gauss-Seidel result depend on the mesh's
    triangulation (a box dropped flat would spin). Checked only for n <= DEDUP_MAX_ROWS."""
    body_m, body_o = sim.model.tri_body[t_moved], sim.model.tri_body[t_other]
    size = longest_edge(sim, t_moved)
    # Copies of one point computed from different triangles differ by rounding, which
    # no threshold at rounding level separates reliably (the same scene scaled by 1e-3
    # rounds differently): √eps of the triangle's size merges them, and nothing else.
    tol = ti.static(ti.sqrt(runtime.machine_eps()))
    found = False
    if ti.static(sim.rules.duplicates) and n <= DEDUP_MAX_ROWS:
        # Only rows of the same moved body can match: walk its chain of rows.
        j = sim.body_last_row[body_m]
        while j >= 0 and not found:
            tri = rows.tri[j]
            if sim.model.tri_body[tri[1]] == body_o and rows.normal[j].dot(normal) >= 1.0 - tol:
                p = anchor_world(sim, tri[0], rows.bary_moved[j], False)
                found = (p - point).norm() <= tol * size
            j = tri[2]
    return found


@ti.func
def has_pair_row(sim: ti.template(), rows: ti.template(), t_a: ti.i32, t_b: ti.i32) -> bool:
    """Whether a row of this substep already ties triangles t_a and t_b (either moved)."""
    found = False
    for r in ti.static(range(2)):
        t_m, t_o = (t_a, t_b) if r == 0 else (t_b, t_a)
        j = sim.body_last_row[sim.model.tri_body[t_m]]
        while j >= 0 and not found:
            tri = rows.tri[j]
            found = tri[0] == t_m and tri[1] == t_o
            j = tri[2]
    return found
