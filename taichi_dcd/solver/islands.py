"""Rows of rigid bodies solved in blocks, one per island of touching bodies (union-find over the
rows between them), on the bodies' motions linearised at the sweep's start."""

import numpy as np
import taichi as ti

from ..contact.anchors import anchor_world
from ..contact.rows import at_vertex_over_face
from ..core import runtime
from ..core.model import RIGID
from ..core.rigid import inv_mass_matrix_world, rotate_by
from .block_rows import block_body, pair_block, pair_inv_mass, project_pair_row, solve_block_row, solve_pair_row
from .contact_solve import SHOCK_MASS_RATIO, pair_friction, takes_part

vec3 = ti.math.vec3

# Inner Gauss-Seidel sweeps (normals alone, then as many with friction) of each island's rows
# per outer sweep, on its bodies linearised at the start of the outer sweep
# (solver.islands.solve_blocks): BLOCK_SWEEPS for a lone rigid body against static ones,
# COUPLED_SWEEPS for bodies touching each other, whose island leaves a phase once no row moves
# its anchor by more than COUPLED_TOL of its lever. Gauss-Seidel carries a stack's weight down
# one box per few sweeps: without support_pass a stack of five boxes crept at 1.5e-5 m/s at 64
# sweeps and rested only at 128, every solve of the ten-box stack ran all 128 + 128, and it
# cost 6.2 s per simulated second. With support_pass the sweeps need not carry the weight all
# the way down: at 16 the ten-box stack costs 0.7 s per simulated second, its boxes 0.10 mm
# from their places (0.09 at 128 without the pass); at 8, 0.17 mm, the pyramid's 41 µm (23).
BLOCK_SWEEPS = 16
COUPLED_SWEEPS = 16
COUPLED_TOL = 1e-12
# support_pass projects an island's rows whose normal lies within this angle of the vertical
# (sim.up): it moves the upper body along the normal and solves no friction, so a tilted
# normal's sideways part would slide the body unresisted (at most sin 5° = 9% of the
# correction here). At 45°, a slab leaning 6.5° on a chip, two slabs on it, crept 0.2 mm in
# 0.6 s; with every row between two levels in the pass, rows along the boxes' side normals
# pushed the ten-box stack's top boxes 0.3-0.6 mm sideways of their places.
SUPPORT_DEGREES = 5.0
# kernels.end_substep (with islands) shares the islands out among this many loop iterations,
# each taking the next island until none is left (Taichi 1.7 gives a CPU thread no fewer than
# 512 of a loop's iterations: fewer would all go to one thread).
ISLAND_WORKERS = 1024
# A rigid body touching one at least this many times heavier, in an island of several bodies,
# is loaded: its rows against static bodies hold the depth they may leave (leaves_depth). At
# 2, the built-in pile (spikes and wedges of a few times each other's mass) no longer settled
# by 5 s (a body at 3 mm/s; 3.5 s before); its pairs are below 10.
LOADED_MASS_RATIO = SHOCK_MASS_RATIO
# A row at a vertex in an island of several bodies, one of whose rigid bodies touches a body at
# least this many times heavier (r times), may spend 1 + r times its budget (load_budget_factor).
LOAD_BUDGET_RATIO = 2.0


@ti.func
def leaves_depth(sim: ti.template(), rows: ti.template(), k: ti.i32, coupled: bool) -> bool:
    """Whether block row k, in an island of several bodies (`coupled`) or alone, holds the
    depth it may leave instead of a budget it spends (project_block_row): in an island of
    several bodies, a row against a static body whose rigid body is loaded (mark_loaded: it
    touches a body LOADED_MASS_RATIO times heavier or more), and a row between two rigid
    bodies whose masses differ that much (the shock-propagation threshold). Such a row is pushed against
    by rows that carry a heavier body's weight, and Gauss-Seidel takes about as many sweeps as
    the mass ratio to pass that weight on: a spent budget stops the row halfway, and the light
    body is driven in. Prevents: a light body under a heavy one that also rests on the ground
    (the same contact level, so no shock propagation) went into the ground a little more each
    substep, its rows against the ground having spent their budget pushing back: a 0.1 m chip
    (1/40 of the slab's mass) under a leaning slab and two slabs on it went 3.6 cm into the
    ground in 0.6 s. Rows of bodies of closer mass keep the budget: holding the depth they may
    leave, the rows of a ten-box stack's flush side faces pushed it 0.17 m sideways, the ground
    rows of a stack of five unit boxes let it creep 3 µm a second, and between bodies twice
    the mass apart, rows squeezing a body from two sides threw it out of a pile at 28 m/s."""
    out = False
    if coupled:
        tri = rows.tri[k]
        b = block_body(sim, rows, k)
        if b >= 0:
            out = sim.block_heaviest[b] >= LOADED_MASS_RATIO * sim.body_mass[b]
        else:
            m_a, m_b = sim.body_mass[sim.model.tri_body[tri[0]]], sim.body_mass[sim.model.tri_body[tri[1]]]
            out = ti.max(m_a, m_b) >= LOADED_MASS_RATIO * ti.min(m_a, m_b)
    return out


@ti.func
def mark_loaded(sim: ti.template(), rows: ti.template(), first: ti.i32, count: ti.i32):
    """block_heaviest of the rigid bodies of an island's rows (block_rows[first:][:count]): the
    mass of the heaviest body a row ties each to, its own if none heavier."""
    for j in range(count):
        tri = rows.tri[rows.block_rows[first + j]]
        for side in ti.static(range(2)):
            b = sim.model.tri_body[tri[side]]
            if sim.model.body_kind[b] == RIGID:  # (static bodies are shared by islands side by side)
                sim.block_heaviest[b] = sim.body_mass[b]
    for j in range(count):
        k = rows.block_rows[first + j]
        if block_body(sim, rows, k) < 0:
            tri = rows.tri[k]
            b_a, b_b = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
            sim.block_heaviest[b_a] = ti.max(sim.block_heaviest[b_a], sim.body_mass[b_b])
            sim.block_heaviest[b_b] = ti.max(sim.block_heaviest[b_b], sim.body_mass[b_a])


@ti.func
def load_budget_factor(sim: ti.template(), rows: ti.template(), k: ti.i32) -> float:
    """How many times its correction budget row k of an island of several bodies may spend:
    1 + r for a row at a vertex over the other face, r ≥ LOAD_BUDGET_RATIO the largest ratio
    block_heaviest / own mass of its rigid bodies; else 1. Gauss-Seidel passes a heavier body's
    weight on to a lighter one in rounds: the row between them pushes them apart, the light
    body's rows against the ground push it back up, the heavy body presses it down again, and
    each of these rows pushes in all about 1 + r times what it gains. With the plain budget the
    rows ran out part way every substep and the light body went a little deeper each time: a
    slab leaning on a 0.1 × 0.04 × 0.1 m chip of a sixth of its mass, two more slabs on it,
    was 3.9 mm into the chip after 0.6 s (now 5e-7 m at most); in a pile of 300 boxes and
    wedges (masses up to ten times apart) a wedge went 1.15 cm into the ground by 1.3 s and
    stayed (now nothing deeper than 0.6 mm to 3 s). The budget still bounds what a row pushes
    in all, so rows that cannot all be met (opposite normals between the same two bodies)
    cannot throw the bodies apart, as rows holding the depth they may leave did at twice the
    mass. Rows elsewhere than at a vertex keep their budget, capped at their depth along a
    normal that may be poor: with them at 1 + r too, a spike of the built-in pile still moved
    at 2 cm/s at 5 s (1.8 mm/s without). Rows between bodies of equal mass (stacks) keep
    theirs."""
    tri = rows.tri[k]
    ratio = 1.0
    for side in ti.static(range(2)):
        b = sim.model.tri_body[tri[side]]
        if sim.model.body_kind[b] == RIGID:
            ratio = ti.max(ratio, sim.block_heaviest[b] / sim.body_mass[b])
    at_vertex = at_vertex_over_face(rows.bary_moved[k], rows.bary_other[k], 0.0)
    return ti.select(ratio >= LOAD_BUDGET_RATIO and at_vertex, 1.0 + ratio, 1.0)


@ti.func
def island_root(sim: ti.template(), b: ti.i32) -> ti.i32:
    """The root of body b's island (union-find with path halving; serial)."""
    root = b
    while sim.block_island[root] != root:
        sim.block_island[root] = sim.block_island[sim.block_island[root]]
        root = sim.block_island[root]
    return root


@ti.func
def join_islands(sim: ti.template(), b_a: ti.i32, b_b: ti.i32):
    """Put rigid bodies b_a and b_b in one island, rooted at the lower index (serial)."""
    root_a, root_b = island_root(sim, b_a), island_root(sim, b_b)
    if root_a != root_b:
        low, high = ti.min(root_a, root_b), ti.max(root_a, root_b)
        sim.block_island[high] = low
        sim.block_coupled[low] = 1


@ti.func
def row_island(sim: ti.template(), rows: ti.template(), k: ti.i32) -> ti.i32:
    """The island root of row k if it is a block row (its rigid body's against a static
    body, or between two rigid bodies), else -1; valid once block_island holds roots."""
    b = block_body(sim, rows, k)
    if pair_block(sim, rows, k):
        b = sim.model.tri_body[rows.tri[k][0]]
    return ti.select(b >= 0, sim.block_island[ti.max(b, 0)], -1)


@ti.func
def solve_blocks(sim: ti.template(), rows: ti.template(), n_contacts: ti.i32, it: ti.i32):
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
    at 8 sweeps); in one island it rests. Islands touch no body or row of each other's: the
    grid path solves them side by side (solve_island), to the same bits."""
    if group_blocks(sim, rows, n_contacts) > 0:
        for b in range(sim.model.body_count[0]):
            if sim.block_len[b] > 0:
                sweep_block(sim, rows, b, it)
        move_blocks(sim)


@ti.func
def group_blocks(sim: ti.template(), rows: ti.template(), n_contacts: ti.i32) -> ti.i32:
    """solve_blocks' first part (serial): each block row linearised at the bodies' current
    poses, the islands joined, and each island's rows listed together in row order
    (block_rows[block_first[root]:][:block_len[root]]). Returns the number of block rows."""
    n_b = sim.model.body_count[0]
    for b in range(n_b):
        sim.block_dx[b] = vec3(0.0)
        sim.block_dtheta[b] = vec3(0.0)
        sim.block_len[b] = 0
        sim.block_island[b] = b
        sim.block_coupled[b] = 0
    count = 0
    for k in range(n_contacts):
        if block_body(sim, rows, k) >= 0 or pair_block(sim, rows, k):
            linearise_row(sim, rows, k)
            if pair_block(sim, rows, k):
                join_islands(sim, sim.model.tri_body[rows.tri[k][0]], sim.model.tri_body[rows.tri[k][1]])
            count += 1
    if count > 0:
        # Each island's rows together, in row order (a counting sort by island root): a
        # block moves no body of another island, so each island sweeps its own rows, and
        # leaves a phase once no row of its moves its anchor by more than tol·|r|. A body
        # still landing does not keep the resting ones sweeping.
        for b in range(n_b):
            sim.block_island[b] = island_root(sim, b)
        for k in range(n_contacts):
            root = row_island(sim, rows, k)
            if root >= 0:
                sim.block_len[root] += 1
        starts_from_counts(sim.block_len, sim.block_first, n_b)
        for k in range(n_contacts):
            root = row_island(sim, rows, k)
            if root >= 0:
                rows.block_rows[sim.block_first[root] + sim.block_len[root]] = k
                sim.block_len[root] += 1
    return count


@ti.func
def linearise_row(sim: ti.template(), rows: ti.template(), k: ti.i32):
    """Block row k at the bodies' current poses: its gap and tangential slip, its lever from
    the moved body's centre, and its 3×3 inverse mass (both bodies' for a row between rigid
    bodies)."""
    b = block_body(sim, rows, k)
    tri = rows.tri[k]
    bm, bo = rows.bary_moved[k], rows.bary_other[k]
    n = rows.normal[k]
    p_m = anchor_world(sim, tri[0], bm, False)
    p_o = anchor_world(sim, tri[1], bo, False)
    rows.block_gap[k] = n.dot(p_o - p_m)
    slip = (p_m - anchor_world(sim, tri[0], bm, True)) - (p_o - anchor_world(sim, tri[1], bo, True))
    rows.block_slip[k] = slip - slip.dot(n) * n
    p_c = 0.5 * (p_m + p_o)
    rows.block_mu[k] = pair_friction(sim, tri[0], tri[1])
    if b >= 0:
        r = p_c - sim.state.body_x_prev[b]
        rows.block_lever[k] = r
        rows.block_reach[k] = r.norm()
        rows.block_k[k] = inv_mass_matrix_world(sim.model.body_inv_mass[b], sim.block_inv_inertia[b], r)
    else:
        body_m, body_o = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
        r_m = p_c - sim.state.body_x_prev[body_m]
        r_o = p_c - sim.state.body_x_prev[body_o]
        rows.block_lever[k] = r_m
        rows.block_reach[k] = r_m.norm()
        f_m, f_o = takes_part(sim, tri[0], tri[1]), takes_part(sim, tri[1], tri[0])
        rows.block_k[k] = pair_inv_mass(sim, body_m, body_o, r_m, r_o, f_m, f_o)


@ti.func
def starts_from_counts(counts: ti.template(), starts: ti.template(), n: ti.i32):
    """A counting sort's middle step (serial): starts[i] = counts[0] + ... + counts[i-1], and
    counts zeroed for the placing pass to count again."""
    first = 0
    for i in range(n):
        starts[i] = first
        first += counts[i]
        counts[i] = 0


@ti.func
def move_blocks(sim: ti.template()):
    """Move each rigid body once by its block motion Δx, Δθ."""
    for b in range(sim.model.body_count[0]):
        move_block_of(sim, b)


@ti.func
def move_block_of(sim: ti.template(), b: ti.i32):
    """Move body b (if rigid) by its block motion Δx, Δθ. (Here and in the islands' sweeps a
    field is updated as `a = a + b`, not `a += b`: in a parallel loop Taichi makes the latter
    an atomic add, ~5 times the cost, and an island is only ever swept by one worker.)"""
    if sim.model.body_kind[b] == RIGID:
        dx, dtheta = sim.block_dx[b], sim.block_dtheta[b]
        if dx.norm_sqr() + dtheta.norm_sqr() > 0.0:
            sim.state.body_x[b] = sim.state.body_x[b] + dx
            sim.body_theta[b] = sim.body_theta[b] + dtheta
            sim.state.body_q[b] = rotate_by(sim.state.body_q_prev[b], sim.body_theta[b])


@ti.func
def island_work(sim: ti.template(), root: ti.i32) -> ti.i32:
    """An upper bound on the row projections of the island rooted at `root` in one sweep:
    its rows times twice its inner sweeps (sweep_block)."""
    sweeps = ti.select(sim.block_coupled[root] == 1, COUPLED_SWEEPS, BLOCK_SWEEPS)
    return sim.block_len[root] * 2 * sweeps


@ti.func
def list_islands(sim: ti.template()) -> ti.i32:
    """The roots of the islands with rows in island_list, the most work first (insertion
    sort; equal work by root), and the shared counter island_next at 0 (serial). Returns how
    many: kernels.end_substep shares them out."""
    count = 0
    for b in range(sim.model.body_count[0]):
        if sim.block_len[b] > 0:
            work = island_work(sim, b)
            j = count
            while j > 0 and island_work(sim, sim.island_list[j - 1]) < work:
                sim.island_list[j] = sim.island_list[j - 1]
                j -= 1
            sim.island_list[j] = b
            count += 1
    # Each listed island's rigid bodies together (a counting sort by root).
    n_b = sim.model.body_count[0]
    for b in range(n_b):
        sim.island_body_count[b] = 0
    for b in range(n_b):
        if sim.model.body_kind[b] == RIGID:
            sim.island_body_count[sim.block_island[b]] += 1
    starts_from_counts(sim.island_body_count, sim.island_body_first, n_b)
    for b in range(n_b):
        if sim.model.body_kind[b] == RIGID:
            root = sim.block_island[b]
            sim.island_bodies[sim.island_body_first[root] + sim.island_body_count[root]] = b
            sim.island_body_count[root] += 1
    sim.island_next[0] = 0
    return count


@ti.func
def solve_island(sim: ti.template(), rows: ti.template(), root: ti.i32, iterations: ti.i32):
    """All `iterations` sweeps of the island rooted at `root`, as solve_blocks makes them in a
    scene whose rows are all block rows (no soft body): each sweep after the first linearises
    the island's rows again at its bodies' poses; each ends with its bodies moved. Islands
    share no body or row, so each can go on to its next sweep alone."""
    first_row, n_rows = sim.block_first[root], sim.block_len[root]
    first_body, n_bodies = sim.island_body_first[root], sim.island_body_count[root]
    for it in range(iterations):
        if it > 0:
            for j in range(n_bodies):
                b = sim.island_bodies[first_body + j]
                sim.block_dx[b] = vec3(0.0)
                sim.block_dtheta[b] = vec3(0.0)
            for j in range(n_rows):
                linearise_row(sim, rows, rows.block_rows[first_row + j])
        sweep_block(sim, rows, root, it)
        for j in range(n_bodies):
            move_block_of(sim, sim.island_bodies[first_body + j])


@ti.func
def next_island(sim: ti.template(), count: ti.i32) -> ti.i32:
    """The next of `count` listed islands for a worker to sweep, or -1 when none is left."""
    i = -1
    if sim.island_next[0] < count:
        i = ti.atomic_add(sim.island_next[0], 1)
        if i >= count:
            i = -1
    return i


@ti.func
def sweep_block(sim: ti.template(), rows: ti.template(), b: ti.i32, it: ti.i32):
    """The block of the island rooted at body b: up to BLOCK_SWEEPS sweeps of its rows'
    normals (COUPLED_SWEEPS for an island of several bodies), then as many with friction,
    alternating direction; a phase ends once no row moves its anchor by more than tol·|r|
    (COUPLED_TOL·|r| in an island of several bodies). In the substep's first sweep, each row
    that leaves_depth turns its budget into the depth it may leave, max(g0 − budget, 0), g0 its
    gap then, and each other row has its budget multiplied by load_budget_factor."""
    tol = ti.static(runtime.tolerance())
    coupled = sim.block_coupled[b] == 1
    sweeps = ti.select(coupled, COUPLED_SWEEPS, BLOCK_SWEEPS)
    tol_r = ti.select(coupled, ti.max(tol, COUPLED_TOL), tol)
    first, count = sim.block_first[b], sim.block_len[b]
    if coupled and it == 0:
        mark_loaded(sim, rows, first, count)
        for j in range(count):
            k = rows.block_rows[first + j]
            if leaves_depth(sim, rows, k, coupled):
                rows.budget[k] = ti.max(rows.block_gap[k] - rows.budget[k], 0.0)
            else:
                rows.budget[k] = rows.budget[k] * load_budget_factor(sim, rows, k)
    inner = 0
    normal_sweeps, friction_sweeps = 0, 0
    while inner < 2 * sweeps:
        friction = inner >= sweeps
        converged = True
        if ti.static(sim.count_sweeps):
            normal_sweeps += ti.select(friction, 0, 1)
            friction_sweeps += ti.select(friction, 1, 0)
        for j in range(count):
            k = rows.block_rows[first + ti.select((it + inner) % 2 == 0, j, count - 1 - j)]
            body = block_body(sim, rows, k)
            moved = 0.0
            leave = leaves_depth(sim, rows, k, coupled)
            if body >= 0:
                moved = solve_block_row(sim, rows, k, body, friction, leave)
            else:
                moved = solve_pair_row(sim, rows, k, friction, leave)
            if moved > tol_r * rows.block_reach[k]:
                converged = False
        inner += 1
        if converged:
            inner = ti.select(friction, 2 * sweeps, ti.max(inner, sweeps))
    if ti.static(sim.rules.support_pass):
        if coupled:
            support_pass(sim, rows, first, count, it)
    if ti.static(sim.count_sweeps):
        count_block_sweeps(sim, coupled, count, sweeps, normal_sweeps, friction_sweeps)


@ti.func
def support_pass(sim: ti.template(), rows: ti.template(), first: ti.i32, count: ti.i32, it: ti.i32):
    """Rule `support_pass` (shock propagation as a last pass): the supporting rows of an
    island of several bodies (block_rows[first:][:count]; support_level) projected once more
    after its sweeps, their normals alone, level by level from the ground up: up to
    BLOCK_SWEEPS sweeps of the rows at the lowest level, the bodies below held still
    (support_row), then those at the next level, until a level's sweep moves no anchor by
    more than tol·|r|. Each level then stands on the one below as it was left, so what the
    island's Gauss-Seidel sweeps have not yet carried down to the ground does not leave the
    upper bodies inside the lower ones. Prevents: at COUPLED_SWEEPS = 16 without it, the
    ten-box stack fell asleep 1.9e-5 m and 1.3e-6 m³ into itself and the pyramid 5.6e-7 m and
    7.9e-9 m³ (with it: none, and 2e-9 m and 1.5e-14 m³)."""
    tol = ti.static(runtime.tolerance())
    n_b = sim.model.body_count[0]
    level = 0
    while level < n_b:
        above = n_b
        for j in range(count):
            row_level = support_level(sim, rows, rows.block_rows[first + j])
            if row_level > level:
                above = ti.min(above, row_level)
        level = above
        inner = 0
        while level < n_b and inner < BLOCK_SWEEPS:
            converged = True
            for j in range(count):
                k = rows.block_rows[first + ti.select((it + inner) % 2 == 0, j, count - 1 - j)]
                if support_level(sim, rows, k) == level:
                    if support_row(sim, rows, k) > tol * rows.block_reach[k]:
                        converged = False
            inner = ti.select(converged, BLOCK_SWEEPS, inner + 1)


@ti.func
def support_level(sim: ti.template(), rows: ti.template(), k: ti.i32) -> ti.i32:
    """The level at which support_pass projects row k: the higher of its two bodies' levels
    (contact_solve.compute_levels) when its normal lies within SUPPORT_DEGREES of sim.up;
    -1 for a row that does not carry weight. (A row whose bodies rest on nothing static is
    at level n_bodies, which support_pass leaves alone.)"""
    tri = rows.tri[k]
    level = ti.max(sim.body_level[sim.model.tri_body[tri[0]]], sim.body_level[sim.model.tri_body[tri[1]]])
    upright = ti.abs(rows.normal[k].dot(sim.up[0])) >= ti.static(np.cos(np.radians(SUPPORT_DEGREES)))
    return ti.select(upright, level, -1)


@ti.func
def support_row(sim: ti.template(), rows: ti.template(), k: ti.i32) -> float:
    """Row k's normal projected in support_pass: against a static body as in the sweeps;
    between two rigid bodies with the lower-level one held still (its share 0, K the upper
    body's alone), both moving if they stand at one level. Returns how far it moved its
    anchor (m)."""
    leave = leaves_depth(sim, rows, k, True)
    body = block_body(sim, rows, k)
    moved = 0.0
    if body >= 0:
        moved = solve_block_row(sim, rows, k, body, False, leave)
    else:
        tri = rows.tri[k]
        body_m, body_o = sim.model.tri_body[tri[0]], sim.model.tri_body[tri[1]]
        f_m = ti.select(sim.body_level[body_m] < sim.body_level[body_o], 0.0, 1.0)
        f_o = ti.select(sim.body_level[body_o] < sim.body_level[body_m], 0.0, 1.0)
        r_m = rows.block_lever[k]
        r_o = r_m + sim.state.body_x_prev[body_m] - sim.state.body_x_prev[body_o]
        moved = project_pair_row(sim, rows, k, False, leave, f_m, f_o,
                                 pair_inv_mass(sim, body_m, body_o, r_m, r_o, f_m, f_o))
    return moved


@ti.func
def count_block_sweeps(sim: ti.template(), coupled: bool, rows: ti.i32, sweeps: ti.i32, normal_sweeps: ti.i32,
                       friction_sweeps: ti.i32):
    """Add one block solve of `rows` rows to sweep_stats: [0:6] for a lone body, [6:12] for an
    island of several bodies, each the solves, their normal and friction sweeps, how many of
    the two phases ran all `sweeps` sweeps (the cap), and the rows."""
    counts = ti.Vector([1, normal_sweeps, friction_sweeps, ti.select(normal_sweeps == sweeps, 1, 0),
                        ti.select(friction_sweeps == sweeps, 1, 0), rows])
    for c in ti.static(range(6)):
        if coupled:
            ti.atomic_add(sim.sweep_stats[0][6 + c], counts[c])
        else:
            ti.atomic_add(sim.sweep_stats[0][c], counts[c])
