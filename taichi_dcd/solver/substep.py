"""One substep, the same sequence for both broad phases: the rows of the contact rules, the
Gauss-Seidel projection, velocities, the velocity pass and the rows carried to the next substep;
and the frame's snapshot that an overflowing frame returns to."""

import taichi as ti

from ..collision.all_pairs import candidate_pairs
from ..contact.carried import carried_rows, keep_rows
from ..contact.gap_rows import add_gap_rows
from ..contact.pair_rows import add_pair_contact, collide_candidates
from ..contact.rows import forget_rows
from ..contact.sleeping import is_moving, wake_near
from ..contact.soft_rows import add_resting_contacts
from ..contact.vertex_rows import add_vertex_contacts
from ..core.model import RIGID, STATIC
from ..core.rigid import quat_matrix
from .contact_solve import (
    compute_levels,
    solve_contact_friction,
    solve_contact_normal,
    solve_velocities,
)
from .integrate import place_vertex, predict, update_velocities
from .block_rows import block_body, pair_block
from .islands import solve_blocks
from .sleep import update_sleep
from .soft import solve_edge, solve_volume
from .soft_spin import measure_internal_spin

vec3 = ti.math.vec3


@ti.func
def project(sim: ti.template(), rows: ti.template(), n_contacts: ti.i32, iterations: ti.i32, h: float):
    """Gauss-Seidel sweeps over contacts and soft constraints (serial: call inside a serial
    loop); each sweep ends with the rows of rigid bodies (against static bodies and between
    each other) solved in blocks, one per island of touching bodies (solve_blocks)."""
    project_begin(sim, rows, n_contacts)
    for it in range(iterations):
        sweep_rows(sim, rows, n_contacts, it, h)
        solve_blocks(sim, rows, n_contacts, it)


@ti.func
def project_begin(sim: ti.template(), rows: ti.template(), n_contacts: ti.i32):
    """What the projection's sweeps share (serial): each body's level in the contact graph,
    the rigid bodies' world inverse inertia at the substep's start, the edges' λ zeroed."""
    compute_levels(sim, rows, n_contacts)
    # The blocks' turns act through the inverse inertia at the substep's start
    # (apply_positional_impulse), the same for every sweep.
    for b in range(sim.model.body_count[0]):
        if sim.model.body_kind[b] == RIGID:
            rot = quat_matrix(sim.state.body_q_prev[b])
            sim.block_inv_inertia[b] = rot @ sim.model.body_inv_inertia[b] @ rot.transpose()
    if ti.static(sim.model.has_soft):
        for e in range(sim.model.edge_count[0]):
            sim.edge_lambda[e] = 0.0


@ti.func
def sweep_rows(sim: ti.template(), rows: ti.template(), n_contacts: ti.i32, it: ti.i32, h: float):
    """Sweep `it` over the soft constraints and the rows that are not in blocks (serial)."""
    if ti.static(sim.model.has_soft):
        for e in range(sim.model.edge_count[0]):
            solve_edge(sim, e, h)
        for b in range(sim.model.body_count[0]):
            solve_volume(sim, b)
    # Normals first, then friction on the slip they leave; the sweeps alternate
    # direction so that no contact is always last. Rows against a static body go after
    # the rows between moving bodies in each sweep: where the two disagree (a cloth's vertex
    # on a box's corner, pressed in by a sheet above it), the row solved last wins, and its
    # place in the list changed with whether the narrow phase found it or it was carried
    # (a 77 µm two-substep cycle); the static body's row now always wins. (Two passes in one
    # loop: one call site of solve_contact_normal for Taichi's frontend to inline.)
    for j in range(2 * n_contacts):
        i = j % n_contacts
        k = ti.select(it % 2 == 0, i, n_contacts - 1 - i)
        if block_body(sim, rows, k) < 0 and not pair_block(sim, rows, k):
            if touches_static(sim, rows, k) == (j >= n_contacts):
                solve_contact_normal(sim, rows, k)
    for j in range(n_contacts):
        k = ti.select(it % 2 == 0, j, n_contacts - 1 - j)
        if block_body(sim, rows, k) < 0 and not pair_block(sim, rows, k):
            solve_contact_friction(sim, rows, k)


@ti.func
def touches_static(sim: ti.template(), rows: ti.template(), k: ti.i32) -> bool:
    """Whether row k ties a triangle of a static body."""
    tri = rows.tri[k]
    return (sim.model.body_kind[sim.model.tri_body[tri[0]]] == STATIC
            or sim.model.body_kind[sim.model.tri_body[tri[1]]] == STATIC)


@ti.func
def rows_after_pairs(sim: ti.template(), rows: ti.template(), n: ti.i32, max_push: float, all_pairs: ti.template()):
    """After the n rows of the triangle pairs: vertex rows, soft resting rows, gap rows (with
    the all-pairs broad phase, whose triangle boxes they read) and carried rows (each rule its
    own function in contact/). Returns (rows needed before the carried rows, above the buffer's
    capacity if it overflowed; rows to solve, within it)."""
    needed = n
    if ti.static(sim.rules.vertex_rows or sim.rules.soft_feature_rows):
        needed = add_vertex_contacts(sim, rows, n, max_push)
    if ti.static(sim.rules.resting_rows or sim.rules.sharp_edge_rows):
        needed = add_resting_contacts(sim, rows, needed, max_push)
    if ti.static(sim.rules.gap_rows and all_pairs):
        needed = add_gap_rows(sim, rows, needed, max_push)
    n_rows = ti.min(needed, rows.tri.shape[0])
    if ti.static(sim.rules.carried_rows):
        n_rows = carried_rows(sim, rows, n_rows, max_push)
    return needed, n_rows


@ti.func
def solve_rows(sim: ti.template(), rows: ti.template(), n: ti.i32, iterations: ti.i32, h: float, g_norm: float,
               max_push: float):
    """The rest of a substep on its n rows (Müller 2020, Alg. 2, lines 9-17): projection,
    velocities, the velocity pass, and the rows to carry to the next substep (serial)."""
    project(sim, rows, n, iterations, h)
    finish_rows(sim, rows, n, iterations, h, g_norm, max_push)


@ti.func
def finish_rows(sim: ti.template(), rows: ti.template(), n: ti.i32, iterations: ti.i32, h: float, g_norm: float,
                max_push: float):
    """After the projection (serial): velocities, the velocity pass, the rows to carry to the
    next substep, and sleep."""
    if ti.static(sim.model.has_soft):
        measure_internal_spin(sim, rows, n, h)
    update_velocities(sim, h)
    solve_velocities(sim, rows, n, iterations, h, g_norm)
    if ti.static(sim.rules.carried_rows):
        keep_rows(sim, rows, n, max_push)
    update_sleep(sim, h)


@ti.func
def substep_all_pairs(sim: ti.template(), rows: ti.template(), iterations: ti.i32, h: float, gravity: vec3,
                      g_norm: float, kick: float, depenetration: float):
    """One substep with the all-pairs broad phase (Müller 2020, Alg. 2: predict, contacts,
    projection, velocities, velocity pass; serial). Returns (rows wanted: candidate pairs or
    contact rows, whichever more, above the buffer's capacity if it overflowed; contact rows
    solved)."""
    capacity = rows.tri.shape[0]
    wake_near(sim)
    predict(sim, h, gravity, kick)
    for i in range(sim.model.vertex_count[0]):
        place_vertex(sim, i)
    n = candidate_pairs(sim, rows)
    wanted = n
    n = collide_candidates(sim, rows, ti.min(n, capacity), depenetration * h)
    needed, n = rows_after_pairs(sim, rows, n, depenetration * h, True)
    solve_rows(sim, rows, n, iterations, h, g_norm, depenetration * h)
    return ti.max(wanted, needed), n


@ti.func
def rows_at_state(sim: ti.template(), rows: ti.template(), max_push: float):
    """The contact rows of the current state, as a substep's first half writes them after its
    prediction (the all-pairs broad phase, the narrow phase, every rule), without solving them.
    Returns (rows needed, rows written)."""
    for i in range(sim.model.vertex_count[0]):
        place_vertex(sim, i)
    n = candidate_pairs(sim, rows)
    wanted = n
    n = collide_candidates(sim, rows, ti.min(n, rows.tri.shape[0]), max_push)
    needed, n = rows_after_pairs(sim, rows, n, max_push, True)
    return ti.max(wanted, needed), n


@ti.func
def substep_from_pairs(sim: ti.template(), rows: ti.template(), pairs: ti.template(), n_pairs: ti.i32,
                       iterations: ti.i32, h: float, g_norm: float, depenetration: float) -> ti.i32:
    """The same substep after the grid's narrow phase (its n_pairs results in `pairs`, a
    collision.contacts.Contacts' arrays: pair, side, depth, normal, point); predict ran in its own
    kernel. Returns the rows solved (serial)."""
    n = rows_from_pairs(sim, rows, pairs, n_pairs, depenetration * h)
    solve_rows(sim, rows, n, iterations, h, g_norm, depenetration * h)
    return n


@ti.func
def rows_from_pairs(sim: ti.template(), rows: ti.template(), pairs: ti.template(), n_pairs: ti.i32,
                    max_push: float) -> ti.i32:
    """A substep's rows from the grid's narrow-phase results, then every rule's rows after them
    (serial). Returns the rows to solve."""
    forget_rows(sim)
    n = 0
    for k in range(n_pairs):
        pair = pairs.pair[k]
        if is_moving(sim, sim.model.tri_body[pair[0]]) or is_moving(sim, sim.model.tri_body[pair[1]]):
            n = add_pair_contact(sim, rows, n, pair, ti.cast(pairs.side[k], ti.i32), pairs.depth[k],
                                 pairs.normal[k], pairs.point[k], max_push)
    _, n = rows_after_pairs(sim, rows, n, max_push, False)
    return n


@ti.func
def save_state(sim: ti.template()):
    """Copy the state and the carried rows to the frame's snapshot."""
    sim.saved_carry[4][0] = sim.carry_count[0]
    for k in range(sim.carry_count[0]):
        sim.saved_carry[0][k] = sim.carry_tri[k]
        sim.saved_carry[1][k] = sim.carry_bary_moved[k]
        sim.saved_carry[2][k] = sim.carry_bary_other[k]
        sim.saved_carry[3][k] = sim.carry_normal[k]
    for b in range(sim.model.body_count[0]):
        sim.saved_body[0][b] = sim.state.body_x[b]
        sim.saved_body[1][b] = sim.state.body_q[b]
        sim.saved_body[2][b] = sim.state.body_v[b]
        sim.saved_body[3][b] = sim.state.body_w[b]
        sim.saved_body[4][b] = sim.body_asleep[b]
        sim.saved_body[5][b] = sim.body_calm[b]
        sim.saved_body[6][b] = sim.body_calm_x[b]
        sim.saved_body[7][b] = sim.body_calm_q[b]
    if ti.static(sim.model.has_soft):
        for i in range(sim.model.vertex_count[0]):
            sim.saved_vertex[0][i] = sim.state.vertex_x[i]
            sim.saved_vertex[1][i] = sim.state.vertex_v[i]


@ti.func
def restore_state(sim: ti.template()):
    """Return to the frame's snapshot (serial)."""
    sim.carry_count[0] = sim.saved_carry[4][0]
    for k in range(sim.carry_count[0]):
        sim.carry_tri[k] = sim.saved_carry[0][k]
        sim.carry_bary_moved[k] = sim.saved_carry[1][k]
        sim.carry_bary_other[k] = sim.saved_carry[2][k]
        sim.carry_normal[k] = sim.saved_carry[3][k]
    for b in range(sim.model.body_count[0]):
        sim.state.body_x[b] = sim.saved_body[0][b]
        sim.state.body_q[b] = sim.saved_body[1][b]
        sim.state.body_v[b] = sim.saved_body[2][b]
        sim.state.body_w[b] = sim.saved_body[3][b]
        sim.body_asleep[b] = sim.saved_body[4][b]
        sim.body_calm[b] = sim.saved_body[5][b]
        sim.body_calm_x[b] = sim.saved_body[6][b]
        sim.body_calm_q[b] = sim.saved_body[7][b]
    if ti.static(sim.model.has_soft):
        for i in range(sim.model.vertex_count[0]):
            sim.state.vertex_x[i] = sim.saved_vertex[0][i]
            sim.state.vertex_v[i] = sim.saved_vertex[1][i]
    for i in range(sim.model.vertex_count[0]):
        place_vertex(sim, i)


@ti.func
def state_is_sane(sim: ti.template(), centre: vec3, bound: float, top_speed: float) -> ti.i32:
    """-1 - (index of the first body) whose state is NaN, faster than `top_speed` (m/s) or
    farther than `bound` (m) from `centre` along an axis, else 0."""
    bad = 0
    for b in range(sim.model.body_count[0]):
        ok = ti.abs(sim.state.body_x[b] - centre).max() <= bound and sim.state.body_v[b].norm() <= top_speed
        if bad == 0 and not ok:
            bad = -1 - b
    if ti.static(sim.model.has_soft):
        for i in range(sim.model.vertex_count[0]):
            ok = ti.abs(sim.state.vertex_x[i] - centre).max() <= bound and sim.state.vertex_v[i].norm() <= top_speed
            if bad == 0 and not ok:
                bad = -1 - sim.model.vertex_body[i]
    return bad
