"""The solver's kernels, each a thin sequence of the `ti.func`s of solver/ and contact/ over
the bundle `sim` (solver.fields): a whole frame's substeps in one launch on the all-pairs
path, the two launches around the grid's collision query per substep on the other, the
rows of the current state, and the per-body summary. `sim` is a template argument: a kernel
is compiled once per bundle, and a bundle serves every scene of its field set (core.pool).
"""

import taichi as ti

from ..collision.contacts import PairResults
from ..contact.rows import ContactRows
from ..contact.sleeping import body_box, wake_touched
from .integrate import place_vertex, predict
from .islands import ISLAND_WORKERS, group_blocks, list_islands, next_island, solve_island
from .substep import (
    finish_rows,
    project_begin,
    restore_state,
    rows_at_state,
    rows_from_pairs,
    save_state,
    state_is_sane,
    substep_all_pairs,
    substep_from_pairs,
)
from .summary import substeps_needed, summarize_bodies

vec3 = ti.math.vec3
mat3 = ti.math.mat3
ivec2 = ti.types.vector(2, ti.i32)
ivec3 = ti.types.vector(3, ti.i32)

# frames_all_pairs's status when the next frame needs more substeps than it was given (not begun),
# and when a frame's contacts overflowed the buffer (undone).
NEEDS_CHOICE = 1
OVERFLOW = 2


@ti.func
def placed_and_checked(sim: ti.template(), centre: vec3, bound: float, top_speed: float) -> ti.i32:
    """The grid path's substep end (serial): every vertex placed at its body's pose, then
    state_is_sane's status."""
    for i in range(sim.model.vertex_count[0]):
        place_vertex(sim, i)
    return state_is_sane(sim, centre, bound, top_speed)


@ti.kernel
def summarize_kernel(sim: ti.template()):
    ti.loop_config(serialize=True)  # on the launching thread: a parallel task costs ~30 µs to start
    for _ in range(1):
        summarize_bodies(sim)

@ti.kernel
def frames_all_pairs(sim: ti.template(), frames: ti.i32, substeps: ti.i32, iterations: ti.i32, h: float, gravity: vec3,
                      first_kick: float, centre: vec3, bound: float, top_speed: float, depenetration: float,
                      check: ti.i32, max_impact: float, thinnest: float, frame_dt: float, choose: ti.i32,
                      cap: ti.i32, c_tri: ti.types.ndarray(dtype=ivec3, ndim=1),
                      c_bary_moved: ti.types.ndarray(dtype=vec3, ndim=1),
                      c_bary_other: ti.types.ndarray(dtype=vec3, ndim=1),
                      c_normal: ti.types.ndarray(dtype=vec3, ndim=1), c_budget: ti.types.ndarray(ndim=1),
                      c_hold: ti.types.ndarray(ndim=1),
                      c_lambda_n: ti.types.ndarray(ndim=1), c_lambda_t: ti.types.ndarray(dtype=vec3, ndim=1),
                      c_vn0: ti.types.ndarray(ndim=1),
                      c_impulse_t: ti.types.ndarray(dtype=vec3, ndim=1),
                      b_lever: ti.types.ndarray(dtype=vec3, ndim=1), b_slip: ti.types.ndarray(dtype=vec3, ndim=1),
                      b_gap: ti.types.ndarray(ndim=1),
                      b_k: ti.types.ndarray(dtype=mat3, ndim=1),
                      b_rows: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      b_mu: ti.types.ndarray(ndim=1), b_reach: ti.types.ndarray(ndim=1)) -> ti.types.vector(7, ti.i32):
    """Up to `frames` frames of substeps, serially in one launch (Müller 2020, Alg. 2 per
    substep). Each frame starts from a snapshot of the state. With `check`, each frame
    first asks `substeps_needed` whether `substeps` suffice; if not, with `choose` it runs
    the substeps chosen there (frame_dt / that many seconds each, at most `cap`), else the
    launch stops before that frame (NEEDS_CHOICE), as it does when even `cap` would not do.
    A frame whose candidates overflow the contact buffer is undone and the launch stops
    (OVERFLOW). Returns (frames done, most candidate pairs in the last frame
    begun, contacts of the last substep, status: 0, NEEDS_CHOICE, OVERFLOW or -1 - first
    bad body, the bad frame counted as done; frames run with more substeps, the most
    substeps of a frame, the substeps they ran beyond `substeps`)."""
    rows = ti.static(ContactRows(c_tri, c_bary_moved, c_bary_other, c_normal, c_budget, c_hold, c_lambda_n,
                                 c_lambda_t, c_vn0, c_impulse_t, b_lever, b_slip, b_gap, b_k, b_rows, b_mu, b_reach))
    done = 0
    most = 0
    n = 0
    status = 0
    more = 0
    most_substeps = 0
    extra = 0
    g_norm = gravity.norm()
    capacity = c_tri.shape[0]
    ti.loop_config(serialize=True)
    for _ in range(1):
        while done < frames and status == 0:
            frame_substeps = substeps
            if check != 0:
                summarize_bodies(sim)
                frame_substeps = substeps_needed(sim, substeps, frame_dt, g_norm, max_impact, thinnest, cap)
                if frame_substeps != substeps and (choose == 0 or frame_substeps < 0):
                    status = NEEDS_CHOICE
                    break
            frame_h = ti.select(frame_substeps == substeps, h, frame_dt / frame_substeps)
            save_state(sim)
            most = 0
            for sub in range(frame_substeps):
                kick = ti.select(done == 0 and sub == 0, first_kick, 1.0)
                wanted, n = substep_all_pairs(sim, rows, iterations, frame_h, gravity, g_norm, kick, depenetration)
                most = ti.max(most, wanted)
            if most > capacity:
                restore_state(sim)
                status = OVERFLOW
            else:
                for i in range(sim.model.vertex_count[0]):
                    place_vertex(sim, i)
                status = state_is_sane(sim, centre, bound, top_speed)
                done += 1
                if frame_substeps != substeps:
                    more += 1
                    extra += frame_substeps - substeps
                    most_substeps = ti.max(most_substeps, frame_substeps)
    return ti.Vector([done, most, n, status, more, most_substeps, extra])

@ti.kernel
def begin_substep(sim: ti.template(), h: float, gravity: vec3, kick: float,
                   vertex_nd: ti.types.ndarray(dtype=vec3, ndim=1), serial: ti.template()):
    """Wake the sleeping bodies a moving one comes near (their boxes in parallel, the pairs
    serially: contact.sleeping.wake_near), predict every body and particle in parallel and place
    the vertices for the grid. serial: the bodies' boxes in one thread (runtime.serial_loops)."""
    # Each body's box on its own where threads are cheap: on a GPU, one thread would read all of
    # the pile's 64k vertices.
    ti.loop_config(serialize=serial)
    for b in range(sim.model.body_count[0]):
        if sim.sleep_time[0] > 0.0:
            body_box(sim, b)
    ti.loop_config(serialize=True)
    for _ in range(1):
        if sim.sleep_time[0] > 0.0:
            wake_touched(sim)
    predict(sim, h, gravity, kick)
    for i in range(sim.model.vertex_count[0]):
        place_vertex(sim, i)
        vertex_nd[i] = sim.state.vertex_x[i]

@ti.kernel
def copy_prev_positions(sim: ti.template(), vertex_prev_nd: ti.types.ndarray(dtype=vec3, ndim=1)):
    """The vertices' positions at the substep's start, for the grid's two-sided (cloth) pairs."""
    for i in range(sim.model.vertex_count[0]):
        vertex_prev_nd[i] = sim.state.vertex_x_prev[i]

@ti.kernel
def end_substep(sim: ti.template(), iterations: ti.i32, h: float, g_norm: float, centre: vec3, bound: float,
                top_speed: float, depenetration: float, n_pairs: ti.i32,
                p_pair: ti.types.ndarray(dtype=ivec2, ndim=1), p_depth: ti.types.ndarray(ndim=1),
                p_normal: ti.types.ndarray(dtype=vec3, ndim=1), p_side: ti.types.ndarray(ndim=1),
                p_point: ti.types.ndarray(dtype=vec3, ndim=1),
                c_tri: ti.types.ndarray(dtype=ivec3, ndim=1),
                c_bary_moved: ti.types.ndarray(dtype=vec3, ndim=1),
                c_bary_other: ti.types.ndarray(dtype=vec3, ndim=1),
                c_normal: ti.types.ndarray(dtype=vec3, ndim=1), c_budget: ti.types.ndarray(ndim=1),
                c_hold: ti.types.ndarray(ndim=1),
                c_lambda_n: ti.types.ndarray(ndim=1), c_lambda_t: ti.types.ndarray(dtype=vec3, ndim=1),
                c_vn0: ti.types.ndarray(ndim=1),
                c_impulse_t: ti.types.ndarray(dtype=vec3, ndim=1),
                b_lever: ti.types.ndarray(dtype=vec3, ndim=1), b_slip: ti.types.ndarray(dtype=vec3, ndim=1),
                b_gap: ti.types.ndarray(ndim=1),
                b_k: ti.types.ndarray(dtype=mat3, ndim=1),
                b_rows: ti.types.ndarray(dtype=ti.i32, ndim=1),
                b_mu: ti.types.ndarray(ndim=1), b_reach: ti.types.ndarray(ndim=1),
                islands: ti.template(), serial: ti.template()) -> ti.types.vector(2, ti.i32):
    """The grid's contacts into rows, projection and velocities of one substep (the same
    sequence as the all-pairs path, solver.substep), the vertices placed and the state checked,
    serially. With `islands` (a scene of rigid and static bodies only, every row a block row)
    the islands are swept side by side: the rows and the islands listed (serial), each island
    through all its sweeps by one worker (parallel), velocities, carried rows and sleep
    (serial), the vertices placed (in parallel unless `serial`: runtime.serial_loops), the state
    checked (serial). An island touches only its own bodies and rows, so the result is the same
    bits on any number of threads. Returns (rows, state check)."""
    rows = ti.static(ContactRows(c_tri, c_bary_moved, c_bary_other, c_normal, c_budget, c_hold, c_lambda_n,
                                 c_lambda_t, c_vn0, c_impulse_t, b_lever, b_slip, b_gap, b_k, b_rows, b_mu, b_reach))
    pairs = ti.static(PairResults(p_pair, p_side, p_depth, p_normal, p_point))
    n = 0
    status = 0
    if ti.static(islands):
        # One launch: these tasks as three launches cost ~0.7 ms a substep more in the pile's
        # landing (docs/experiments.md, 2026-11-28 night).
        ti.loop_config(serialize=True)
        for _ in range(1):
            n_rows = rows_from_pairs(sim, rows, pairs, n_pairs, depenetration * h)
            project_begin(sim, rows, n_rows)
            count = 0
            if group_blocks(sim, rows, n_rows) > 0:
                count = list_islands(sim)
            sim.island_count[0] = count
            sim.island_rows[0] = n_rows
        for _ in range(ISLAND_WORKERS):
            i = next_island(sim, sim.island_count[0])
            while i >= 0:
                solve_island(sim, rows, sim.island_list[i], iterations)
                i = next_island(sim, sim.island_count[0])
        ti.loop_config(serialize=True)
        for _ in range(1):
            finish_rows(sim, rows, sim.island_rows[0], iterations, h, g_norm, depenetration * h)
        # Each vertex on its own where threads are cheap: on a GPU, one thread placing the
        # pile's 64k vertices took half of a free-falling substep.
        ti.loop_config(serialize=serial)
        for i in range(sim.model.vertex_count[0]):
            place_vertex(sim, i)
        ti.loop_config(serialize=True)
        for _ in range(1):
            n = sim.island_rows[0]
            status = state_is_sane(sim, centre, bound, top_speed)
    else:
        ti.loop_config(serialize=True)
        for _ in range(1):
            n = substep_from_pairs(sim, rows, pairs, n_pairs, iterations, h, g_norm, depenetration)
            status = placed_and_checked(sim, centre, bound, top_speed)
    return ti.Vector([n, status])

@ti.kernel
def rows_at_state_kernel(sim: ti.template(), max_push: float, c_tri: ti.types.ndarray(dtype=ivec3, ndim=1),
                   c_bary_moved: ti.types.ndarray(dtype=vec3, ndim=1),
                   c_bary_other: ti.types.ndarray(dtype=vec3, ndim=1),
                   c_normal: ti.types.ndarray(dtype=vec3, ndim=1), c_budget: ti.types.ndarray(ndim=1),
                   c_hold: ti.types.ndarray(ndim=1),
                   c_lambda_n: ti.types.ndarray(ndim=1), c_lambda_t: ti.types.ndarray(dtype=vec3, ndim=1),
                   c_vn0: ti.types.ndarray(ndim=1),
                   c_impulse_t: ti.types.ndarray(dtype=vec3, ndim=1),
                   b_lever: ti.types.ndarray(dtype=vec3, ndim=1), b_slip: ti.types.ndarray(dtype=vec3, ndim=1),
                   b_gap: ti.types.ndarray(ndim=1),
                   b_k: ti.types.ndarray(dtype=mat3, ndim=1),
                   b_rows: ti.types.ndarray(dtype=ti.i32, ndim=1),
                   b_mu: ti.types.ndarray(ndim=1), b_reach: ti.types.ndarray(ndim=1)) -> ti.types.vector(2, ti.i32):
    """The contact rows of the current state, unsolved (solver.substep.rows_at_state)."""
    rows = ti.static(ContactRows(c_tri, c_bary_moved, c_bary_other, c_normal, c_budget, c_hold, c_lambda_n,
                                 c_lambda_t, c_vn0, c_impulse_t, b_lever, b_slip, b_gap, b_k, b_rows, b_mu, b_reach))
    needed = 0
    n = 0
    ti.loop_config(serialize=True)
    for _ in range(1):
        needed, n = rows_at_state(sim, rows, max_push)
    return ti.Vector([needed, n])

