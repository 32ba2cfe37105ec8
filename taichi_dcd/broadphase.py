"""Broad phase: every pair of triangles of different bodies whose boxes overlap, once.

Each triangle gets a world-space axis-aligned box inflated by a contact margin
(and by the narrow phase's zero tolerance, see BOX_SLACK),
and a grid level: the smallest l whose cell size h·2^l (h = the base cell size)
is at least the box's largest extent, so a triangle covers at most two cells per
axis at its own level whatever the spread of triangle sizes (a ground triangle
100× larger than the rest sits 7 levels up instead of covering 10^4 cells).

A hash table keyed by (level, cell) is built per group of triangles — moving
triangles at every query, static triangles once — by counting entries per
bucket, a prefix sum and a scatter. A pair of boxes is then found once:
- by the triangle at the finer level (at equal levels, the smaller index), when
  it looks up the cells its box covers at the other triangle's level;
- only in the cell holding the lower corner of the two boxes' intersection, a
  cell both boxes cover, computed in integers from the boxes' own lower cells.
Static–static pairs are never reported. Pairs come out as global triangle
indices (a, b) with body[a] < body[b], in no particular order.
"""

import numpy as np
import taichi as ti

from . import runtime
from .geometry import vec3

ivec2 = ti.types.vector(2, ti.i32)
ivec3 = ti.types.vector(3, ti.i32)

MOVING = 0
STATIC = 1
LEVELS = 32
# Cell coordinates are clamped to ±2^30 so that they fit an i32; clamping is
# monotonic, so far-away boxes still overlap-test exactly, only less efficiently.
CELL_LIMIT = float(1 << 30)
SCAN_BLOCK = 4096
# The narrow phase treats distances within tolerance()·L of zero as touching (L =
# the pair's longest edge, below twice a box's largest extent), so two triangles
# whose boxes are that far apart can still be a hit: every box is padded by this
# many tolerances of its own largest extent on top of the contact margin.
BOX_SLACK = 2.0
# A moving triangle is binned only if its box meets another body's box; with more
# bodies than this the check costs more than it saves and every triangle is binned.
CULL_MAX_BODIES = 64


@ti.func
def cell_of(p: vec3, inv_h: float) -> ivec3:
    """Integer cell holding point p in a grid of cell size 1/inv_h anchored at the origin."""
    c = ti.floor(p * inv_h)
    return ti.cast(ti.math.clamp(c, -CELL_LIMIT, CELL_LIMIT), ti.i32)


@ti.func
def level_inv_h(inv_h0: float, level: ti.i32) -> float:
    """1 / (h·2^level): exact, since it only scales by powers of two."""
    inv_h = inv_h0
    for _ in range(level):
        inv_h *= 0.5
    return inv_h


@ti.func
def bucket_of(level: ti.i32, c: ivec3, mask: ti.i32) -> ti.i32:
    """Hash bucket of cell c at a level, in [0, mask] (mask = table size - 1, a power of two).

    Only the low 21 bits of each coordinate are mixed, so that no product can overflow
    (Taichi's debug mode traps integer overflow); cells that collide are told apart by
    the cell stored with each entry.
    """
    low = ti.cast(c, ti.i64) & 0x1FFFFF
    key = (low[0] * 73856093 + low[1] * 19349663 + low[2] * 83492791
           + ti.cast(level, ti.i64) * 39916801)
    return ti.cast(key & ti.cast(mask, ti.i64), ti.i32)


@ti.func
def boxes_overlap(lo_a: vec3, hi_a: vec3, lo_b: vec3, hi_b: vec3) -> bool:
    """Closed boxes overlap (touching counts)."""
    return all(lo_a <= hi_b) and all(lo_b <= hi_a)


@ti.kernel
def _triangle_boxes(
    particle_x: ti.types.ndarray(dtype=vec3, ndim=1),
    particle_body: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri_indices: ti.types.ndarray(dtype=ivec3, ndim=1),
    tri_group: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri_body: ti.types.ndarray(dtype=ti.i32, ndim=1),
    body_static: ti.types.ndarray(dtype=ti.i32, ndim=1),
    group: ti.i32,
    margin: float,
    inv_h0: float,
    box_lo: ti.types.ndarray(dtype=vec3, ndim=1),
    box_hi: ti.types.ndarray(dtype=vec3, ndim=1),
    body_lo: ti.types.ndarray(dtype=vec3, ndim=1),
    body_hi: ti.types.ndarray(dtype=vec3, ndim=1),
    tri_level: ti.types.ndarray(dtype=ti.i32, ndim=1),
    level_count: ti.types.ndarray(dtype=ti.i32, ndim=2),
    serial: ti.template(),
) -> ti.i32:
    """Boxes of one group's bodies (from their vertices) and triangles, and each triangle's
    level, or -1 for a moving triangle whose box meets no other body's box (it can have
    no pair, so it is neither binned nor queried); returns the group's number of
    (cell, triangle) entries."""
    n_bodies = body_lo.shape[0]
    slack = ti.static(BOX_SLACK * runtime.tolerance())
    ti.loop_config(serialize=True)
    for level in range(LEVELS):
        level_count[group, level] = 0
    ti.loop_config(serialize=True)
    for k in range(n_bodies):
        if body_static[k] == group:
            body_lo[k] = vec3(ti.math.inf)
            body_hi[k] = vec3(-ti.math.inf)
    ti.loop_config(serialize=serial)
    for v in range(particle_body.shape[0]):
        k = particle_body[v]
        if k >= 0 and body_static[k] == group:
            p = particle_x[v]
            ti.atomic_min(body_lo[k], p)
            ti.atomic_max(body_hi[k], p)
    # A body's pad is at least that of any of its triangles.
    ti.loop_config(serialize=True)
    for k in range(n_bodies):
        if body_static[k] == group:
            pad = margin + slack * (body_hi[k] - body_lo[k]).max()
            body_lo[k] -= pad
            body_hi[k] += pad
    entries = 0
    ti.loop_config(serialize=serial)
    for t in range(tri_indices.shape[0]):
        if tri_group[t] == group:
            i = tri_indices[t]
            p0, p1, p2 = particle_x[i[0]], particle_x[i[1]], particle_x[i[2]]
            lo = ti.min(p0, p1, p2)
            hi = ti.max(p0, p1, p2)
            pad = margin + slack * (hi - lo).max()
            lo -= pad
            hi += pad
            box_lo[t] = lo
            box_hi[t] = hi
            active = group == STATIC or n_bodies > CULL_MAX_BODIES
            if not active:
                b = tri_body[t]
                for k in range(n_bodies):
                    if k != b and boxes_overlap(lo, hi, body_lo[k], body_hi[k]):
                        active = True
            level = -1
            if active:
                extent = (hi - lo).max() * inv_h0
                level = 0
                size = 1.0
                while level < LEVELS - 1 and extent > size:
                    level += 1
                    size *= 2.0
                inv_h = level_inv_h(inv_h0, level)
                span = cell_of(hi, inv_h) - cell_of(lo, inv_h) + 1
                entries += span[0] * span[1] * span[2]
                level_count[group, level] += 1
            tri_level[t] = level
    return entries


@ti.kernel
def _bin_group(
    tri_group: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri_body: ti.types.ndarray(dtype=ti.i32, ndim=1),
    group: ti.i32,
    inv_h0: float,
    box_lo: ti.types.ndarray(dtype=vec3, ndim=1),
    box_hi: ti.types.ndarray(dtype=vec3, ndim=1),
    tri_level: ti.types.ndarray(dtype=ti.i32, ndim=1),
    bucket_start: ti.types.ndarray(dtype=ti.i32, ndim=1),
    bucket_fill: ti.types.ndarray(dtype=ti.i32, ndim=1),
    bucket_bodies: ti.types.ndarray(dtype=ivec2, ndim=1),
    block_sum: ti.types.ndarray(dtype=ti.i32, ndim=1),
    entry_tri: ti.types.ndarray(dtype=ti.i32, ndim=1),
    entry_cell: ti.types.ndarray(dtype=ivec3, ndim=1),
    entry_body: ti.types.ndarray(dtype=ti.i32, ndim=1),
    entry_lo: ti.types.ndarray(dtype=vec3, ndim=1),
    entry_hi: ti.types.ndarray(dtype=vec3, ndim=1),
    serial: ti.template(),
):
    """Hash table of one group: count per bucket (and the range of bodies in it), prefix
    sum (blocked; serial over blocks), scatter. Each entry carries its triangle's body
    and box, so that scanning a bucket reads contiguous memory."""
    n_buckets = bucket_fill.shape[0]
    mask = n_buckets - 1
    ti.loop_config(serialize=serial)
    for b in range(n_buckets):
        bucket_fill[b] = 0
        bucket_bodies[b] = ivec2(2147483647, -1)
    ti.loop_config(serialize=serial)
    for t in range(tri_group.shape[0]):
        if tri_group[t] == group and tri_level[t] >= 0:
            level = tri_level[t]
            body = tri_body[t]
            inv_h = level_inv_h(inv_h0, level)
            c0, c1 = cell_of(box_lo[t], inv_h), cell_of(box_hi[t], inv_h)
            for x, y, z in ti.ndrange((c0[0], c1[0] + 1), (c0[1], c1[1] + 1), (c0[2], c1[2] + 1)):
                b = bucket_of(level, ivec3(x, y, z), mask)
                ti.atomic_add(bucket_fill[b], 1)
                ti.atomic_min(bucket_bodies[b][0], body)
                ti.atomic_max(bucket_bodies[b][1], body)
    # Exclusive scan within blocks in parallel, then over block totals serially.
    ti.loop_config(serialize=serial)
    for k in range(block_sum.shape[0]):
        running = 0
        for b in range(k * SCAN_BLOCK, ti.min((k + 1) * SCAN_BLOCK, n_buckets)):
            bucket_start[b] = running
            running += bucket_fill[b]
        block_sum[k] = running
    ti.loop_config(serialize=True)
    for k in range(block_sum.shape[0]):
        if k == 0:
            bucket_start[n_buckets] = 0
        total = block_sum[k]
        block_sum[k] = bucket_start[n_buckets]
        bucket_start[n_buckets] += total
    ti.loop_config(serialize=serial)
    for b in range(n_buckets):
        bucket_start[b] += block_sum[b // SCAN_BLOCK]
        bucket_fill[b] = bucket_start[b]
    ti.loop_config(serialize=serial)
    for t in range(tri_group.shape[0]):
        if tri_group[t] == group and tri_level[t] >= 0:
            level = tri_level[t]
            inv_h = level_inv_h(inv_h0, level)
            lo, hi = box_lo[t], box_hi[t]
            body = tri_body[t]
            c0, c1 = cell_of(lo, inv_h), cell_of(hi, inv_h)
            for x, y, z in ti.ndrange((c0[0], c1[0] + 1), (c0[1], c1[1] + 1), (c0[2], c1[2] + 1)):
                c = ivec3(x, y, z)
                slot = ti.atomic_add(bucket_fill[bucket_of(level, c, mask)], 1)
                entry_tri[slot] = t
                entry_cell[slot] = c
                entry_body[slot] = body
                entry_lo[slot] = lo
                entry_hi[slot] = hi


@ti.func
def report_pair(t: ti.i32, body_t: ti.i32, lo_t: vec3, u: ti.i32, body_u: ti.i32, lo_u: vec3,
                c: ivec3, inv_h: float, pairs: ti.template(), pair_count: ti.template()):
    """Append (t, u), body order first, if c — a cell both overlapping boxes cover — holds
    the lower corner of the boxes' intersection (so each pair is appended in one cell)."""
    if all(ti.max(cell_of(lo_t, inv_h), cell_of(lo_u, inv_h)) == c):
        k = ti.atomic_add(pair_count[0], 1)
        if k < pairs.shape[0]:
            pairs[k] = ivec2(t, u) if body_t < body_u else ivec2(u, t)


@ti.func
def scan_entries(t: ti.i32, body_t: ti.i32, lo_t: vec3, hi_t: vec3, level: ti.i32, c: ivec3, inv_h: float,
                 first: ti.i32, end: ti.i32, tri_level: ti.template(), entry_tri: ti.template(),
                 entry_cell: ti.template(), entry_body: ti.template(), entry_lo: ti.template(),
                 entry_hi: ti.template(), pairs: ti.template(), pair_count: ti.template()):
    """Report t against the entries [first, end) of a bucket that are binned in cell c at
    `level`, belong to another body and have an overlapping box."""
    for f in range(first, end):
        if (entry_body[f] != body_t and all(entry_cell[f] == c)
                and boxes_overlap(lo_t, hi_t, entry_lo[f], entry_hi[f])):
            u = entry_tri[f]
            if tri_level[u] == level:
                report_pair(t, body_t, lo_t, u, entry_body[f], entry_lo[f], c, inv_h, pairs, pair_count)


@ti.func
def query_coarser(t: ti.i32, top_level: ti.i32, table: ti.template(), inv_h0: float,
                  box_lo: ti.template(), box_hi: ti.template(), tri_level: ti.template(),
                  tri_body: ti.template(), level_count: ti.template(), bucket_start: ti.template(),
                  entry_tri: ti.template(), entry_cell: ti.template(), entry_body: ti.template(),
                  entry_lo: ti.template(), entry_hi: ti.template(), pairs: ti.template(),
                  pair_count: ti.template()):
    """Report t's partners binned in one table at levels above t's own, looked up in the
    (at most 2 per axis) cells t's box covers at each such level."""
    mask = bucket_start.shape[0] - 2
    lo_t, hi_t = box_lo[t], box_hi[t]
    body_t = tri_body[t]
    for level in range(tri_level[t] + 1, top_level + 1):
        if level_count[table, level] > 0:
            inv_h = level_inv_h(inv_h0, level)
            c0, c1 = cell_of(lo_t, inv_h), cell_of(hi_t, inv_h)
            for x, y, z in ti.ndrange((c0[0], c1[0] + 1), (c0[1], c1[1] + 1), (c0[2], c1[2] + 1)):
                c = ivec3(x, y, z)
                b = bucket_of(level, c, mask)
                scan_entries(t, body_t, lo_t, hi_t, level, c, inv_h, bucket_start[b], bucket_start[b + 1],
                             tri_level, entry_tri, entry_cell, entry_body, entry_lo, entry_hi, pairs, pair_count)


@ti.kernel
def _find_pairs(
    tri_group: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri_body: ti.types.ndarray(dtype=ti.i32, ndim=1),
    inv_h0: float,
    box_lo: ti.types.ndarray(dtype=vec3, ndim=1),
    box_hi: ti.types.ndarray(dtype=vec3, ndim=1),
    tri_level: ti.types.ndarray(dtype=ti.i32, ndim=1),
    level_count: ti.types.ndarray(dtype=ti.i32, ndim=2),
    moving_entries: ti.i32,
    moving_start: ti.types.ndarray(dtype=ti.i32, ndim=1),
    moving_bodies: ti.types.ndarray(dtype=ivec2, ndim=1),
    moving_tri: ti.types.ndarray(dtype=ti.i32, ndim=1),
    moving_cell: ti.types.ndarray(dtype=ivec3, ndim=1),
    moving_body: ti.types.ndarray(dtype=ti.i32, ndim=1),
    moving_lo: ti.types.ndarray(dtype=vec3, ndim=1),
    moving_hi: ti.types.ndarray(dtype=vec3, ndim=1),
    static_start: ti.types.ndarray(dtype=ti.i32, ndim=1),
    static_tri: ti.types.ndarray(dtype=ti.i32, ndim=1),
    static_cell: ti.types.ndarray(dtype=ivec3, ndim=1),
    static_body: ti.types.ndarray(dtype=ti.i32, ndim=1),
    static_lo: ti.types.ndarray(dtype=vec3, ndim=1),
    static_hi: ti.types.ndarray(dtype=vec3, ndim=1),
    pairs: ti.types.ndarray(dtype=ivec2, ndim=1),
    pair_count: ti.types.ndarray(dtype=ti.i32, ndim=1),
    serial: ti.template(),
) -> ti.i32:
    """Candidate pairs (box overlap, different bodies, not both static); returns their number,
    which exceeds pairs.shape[0] when the buffer overflowed (then only the first ones are stored)."""
    pair_count[0] = 0
    top_moving = -1
    top_static = -1
    bottom = LEVELS
    ti.loop_config(serialize=True)
    for level in range(LEVELS):
        if level_count[MOVING, level] > 0:
            top_moving = level
            bottom = ti.min(bottom, level)
        if level_count[STATIC, level] > 0:
            top_static = level
            bottom = ti.min(bottom, level)
    # With every triangle at one level there are no unequal-level pairs to look up.
    n_coarser_queries = tri_group.shape[0] if ti.max(top_moving, top_static) > bottom else 0
    # Equal levels: each moving entry against the later entries of its bucket and
    # the static entries of its cell, so each pair meets once, in one shared cell.
    moving_mask = moving_start.shape[0] - 2
    static_mask = static_start.shape[0] - 2
    ti.loop_config(serialize=serial)
    for e in range(moving_entries):
        t = moving_tri[e]
        c = moving_cell[e]
        body_t = moving_body[e]
        lo_t, hi_t = moving_lo[e], moving_hi[e]
        level = tri_level[t]
        inv_h = level_inv_h(inv_h0, level)
        b = bucket_of(level, c, moving_mask)
        # A bucket holding one body's triangles only has no pair to offer.
        end = moving_start[b + 1] if moving_bodies[b][0] != moving_bodies[b][1] else 0
        scan_entries(t, body_t, lo_t, hi_t, level, c, inv_h, e + 1, end, tri_level,
                     moving_tri, moving_cell, moving_body, moving_lo, moving_hi, pairs, pair_count)
        if level <= top_static:
            b = bucket_of(level, c, static_mask)
            scan_entries(t, body_t, lo_t, hi_t, level, c, inv_h, static_start[b], static_start[b + 1], tri_level,
                         static_tri, static_cell, static_body, static_lo, static_hi, pairs, pair_count)
    # Unequal levels: the finer triangle looks up the coarser one (static triangles
    # only look up moving ones).
    ti.loop_config(serialize=serial)
    for t in range(n_coarser_queries):
        if tri_level[t] < 0:
            pass
        elif tri_group[t] == MOVING:
            query_coarser(t, top_moving, MOVING, inv_h0, box_lo, box_hi, tri_level, tri_body, level_count,
                          moving_start, moving_tri, moving_cell, moving_body, moving_lo, moving_hi,
                          pairs, pair_count)
            query_coarser(t, top_static, STATIC, inv_h0, box_lo, box_hi, tri_level, tri_body, level_count,
                          static_start, static_tri, static_cell, static_body, static_lo, static_hi,
                          pairs, pair_count)
        else:
            query_coarser(t, top_moving, MOVING, inv_h0, box_lo, box_hi, tri_level, tri_body, level_count,
                          moving_start, moving_tri, moving_cell, moving_body, moving_lo, moving_hi,
                          pairs, pair_count)
    return pair_count[0]


def _next_pow2(n: int) -> int:
    return 1 << max(0, int(n - 1).bit_length())


# Base cell size over the median triangle box extent. Smaller cells bin each
# triangle into more cells, larger ones crowd more triangles into each; on
# tessellated surfaces (benchmarks/broadphase.py) 1.5 is near the best of both.
CELL_OVER_MEDIAN = 1.5


def default_cell_size(box_extent: np.ndarray) -> float:
    """Base cell size from triangle box extents (n,): CELL_OVER_MEDIAN × their median, so
    that a few huge or tiny triangles do not set the grid for the rest; 1 if every box
    is a point."""
    positive = box_extent[box_extent > 0]
    return CELL_OVER_MEDIAN * float(np.median(positive)) if len(positive) else 1.0


class _HashTable:
    """The hash-grid buffers of one group, grown (never shrunk) to fit its entries."""

    def __init__(self):
        self.bucket_start = self.bucket_fill = self.bucket_bodies = self.block_sum = None
        self.entry_tri = self.entry_cell = self.entry_body = self.entry_lo = self.entry_hi = None
        self.entry_capacity = -1
        self.entries = 0

    def reserve(self, entries: int) -> None:
        self.entries = entries
        if entries <= self.entry_capacity:
            return
        capacity = max(2 * self.entry_capacity, entries, 1)
        n_buckets = _next_pow2(capacity)
        self.bucket_start = ti.ndarray(ti.i32, shape=n_buckets + 1)
        self.bucket_start.fill(0)
        self.bucket_fill = ti.ndarray(ti.i32, shape=n_buckets)
        self.bucket_bodies = ti.ndarray(ivec2, shape=n_buckets)
        self.bucket_bodies.fill(0)
        self.block_sum = ti.ndarray(ti.i32, shape=(n_buckets + SCAN_BLOCK - 1) // SCAN_BLOCK)
        self.entry_tri = ti.ndarray(ti.i32, shape=capacity)
        self.entry_cell = ti.ndarray(ivec3, shape=capacity)
        self.entry_body = ti.ndarray(ti.i32, shape=capacity)
        real3 = ti.types.vector(3, runtime.real_type())
        self.entry_lo = ti.ndarray(real3, shape=capacity)
        self.entry_hi = ti.ndarray(real3, shape=capacity)
        self.entry_capacity = capacity

    def entry_arrays(self) -> tuple:
        return self.entry_tri, self.entry_cell, self.entry_body, self.entry_lo, self.entry_hi


class UniformGrid:
    """Uniform-grid broad phase over the triangles of several bodies.

    tri_indices (m, 3) int: vertex indices into the particle array, global over all
    bodies; tri_body (m,) int: the body of each triangle; tri_static (m,) bool:
    triangles of static bodies (binned once, by `bin_static`). cell_size: the base
    cell size in scene units (default: `default_cell_size` of the boxes at the first query);
    margin: every box is inflated by this much (scene units). pair_capacity: the
    initial size of the pair buffer, grown on overflow.
    """

    def __init__(self, tri_indices, tri_body, tri_static=None, cell_size: float | None = None,
                 margin: float = 0.0, pair_capacity: int = 1024):
        runtime.ensure_init()
        tri_indices = np.ascontiguousarray(tri_indices, dtype=np.int32).reshape(-1, 3)
        m = len(tri_indices)
        tri_body = np.ascontiguousarray(tri_body, dtype=np.int32)
        if tri_static is None:
            tri_static = np.zeros(m, dtype=bool)
        tri_static = np.asarray(tri_static, dtype=bool)
        if cell_size is not None and not (np.isfinite(cell_size) and cell_size > 0):
            raise ValueError(f"cell_size must be a positive finite length, got {cell_size}")
        if not (np.isfinite(margin) and margin >= 0):
            raise ValueError(f"margin must be a non-negative finite length, got {margin}")
        if pair_capacity < 1:
            raise ValueError(f"pair_capacity must be at least 1, got {pair_capacity}")
        self.n_tris = m
        self.cell_size = None if cell_size is None else float(cell_size)
        self.margin = float(margin)
        self.has_static = bool(np.any(tri_static))
        self.has_moving = bool(not np.all(tri_static))
        size = max(m, 1)
        self.tri_indices = ti.ndarray(ivec3, shape=size)
        self.tri_body = ti.ndarray(ti.i32, shape=size)
        self.tri_group = ti.ndarray(ti.i32, shape=size)
        if m:
            self.tri_indices.from_numpy(tri_indices)
            self.tri_body.from_numpy(tri_body)
            self.tri_group.from_numpy(np.where(tri_static, STATIC, MOVING).astype(np.int32))
        real = runtime.real_type()
        self.box_lo = ti.ndarray(ti.types.vector(3, real), shape=size)
        self.box_hi = ti.ndarray(ti.types.vector(3, real), shape=size)
        self.tri_level = ti.ndarray(ti.i32, shape=size)
        n_bodies = int(tri_body.max()) + 1 if m else 1
        body_static = np.zeros(n_bodies, dtype=np.int32)
        body_static[tri_body[tri_static]] = STATIC
        if m and np.any(body_static[tri_body[~tri_static]] == STATIC):
            raise ValueError("a body has both static and moving triangles")
        n_particles = int(tri_indices.max()) + 1 if m else 1
        particle_body = np.full(n_particles, -1, dtype=np.int32)
        particle_body[tri_indices] = tri_body[:, None]
        if m and np.any(particle_body[tri_indices] != tri_body[:, None]):
            raise ValueError("a vertex is shared by triangles of different bodies; give each body its own vertices")
        self.particle_body = ti.ndarray(ti.i32, shape=n_particles)
        self.particle_body.from_numpy(particle_body)
        self.body_static = ti.ndarray(ti.i32, shape=n_bodies)
        self.body_static.from_numpy(body_static)
        self.body_lo = ti.ndarray(ti.types.vector(3, real), shape=n_bodies)
        self.body_hi = ti.ndarray(ti.types.vector(3, real), shape=n_bodies)
        self.level_count = ti.ndarray(ti.i32, shape=(2, LEVELS))
        self.level_count.fill(0)
        self.tables = (_HashTable(), _HashTable())
        for table in self.tables:
            table.reserve(0)
        self.pairs = ti.ndarray(ivec2, shape=pair_capacity)
        self.pair_count = ti.ndarray(ti.i32, shape=1)
        self.n_pairs = 0
        self._static_binned = False

    @property
    def pair_capacity(self) -> int:
        return self.pairs.shape[0]

    def _choose_cell_size(self, particle_x) -> None:
        if self.cell_size is not None:
            return
        x = particle_x.to_numpy()
        tris = x[self.tri_indices.to_numpy()[: self.n_tris]]
        extent = (tris.max(axis=1) - tris.min(axis=1)).max(axis=1) + 2 * self.margin
        self.cell_size = default_cell_size(extent)

    def _bin(self, particle_x, group: int) -> None:
        inv_h0 = 1.0 / self.cell_size
        serial = runtime.serial_loops(self.n_tris)
        entries = _triangle_boxes(particle_x, self.particle_body, self.tri_indices, self.tri_group, self.tri_body,
                                  self.body_static,
                                  group, self.margin, inv_h0, self.box_lo, self.box_hi, self.body_lo,
                                  self.body_hi, self.tri_level, self.level_count, serial)
        table = self.tables[group]
        table.reserve(entries)
        _bin_group(self.tri_group, self.tri_body, group, inv_h0, self.box_lo, self.box_hi, self.tri_level,
                   table.bucket_start, table.bucket_fill, table.bucket_bodies, table.block_sum,
                   *table.entry_arrays(),
                   runtime.serial_loops(entries))

    def bin_static(self, particle_x) -> None:
        """Bin the static triangles at their current positions (once; again only if they moved)."""
        self._choose_cell_size(particle_x)
        if self.has_static:
            self._bin(particle_x, STATIC)
        self._static_binned = True

    def find_pairs(self, particle_x) -> int:
        """Rebin the moving triangles at particle_x (ti.ndarray of vec3, (n_particles,)) and
        collect all candidate pairs into `pairs[:n]`; returns n. Grows the pair buffer and
        runs again when it overflows, so no pair is ever dropped."""
        if not self._static_binned:
            self.bin_static(particle_x)
        if self.n_tris == 0:
            self.n_pairs = 0
            return 0
        if self.has_moving:
            self._bin(particle_x, MOVING)
        moving, static = self.tables
        while True:
            n = _find_pairs(self.tri_group, self.tri_body, 1.0 / self.cell_size, self.box_lo, self.box_hi,
                            self.tri_level, self.level_count, moving.entries,
                            moving.bucket_start, moving.bucket_bodies, *moving.entry_arrays(),
                            static.bucket_start, *static.entry_arrays(),
                            self.pairs, self.pair_count, runtime.serial_loops(moving.entries))
            if n <= self.pair_capacity:
                break
            self.pairs = ti.ndarray(ivec2, shape=max(n, 2 * self.pair_capacity))
        self.n_pairs = n
        return n

    def pairs_numpy(self) -> np.ndarray:
        """The candidate pairs of the last query, (n, 2) global triangle indices, body[a] < body[b]."""
        return self.pairs.to_numpy()[: self.n_pairs]
