"""Broad phase: every pair of triangles of different bodies whose boxes overlap, once, and of
one body with self-collision (a soft body's own triangles that are not near neighbours,
core.geometry.near_in_mesh).

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
indices (a, b) with body[a] <= body[b], in no particular order.
"""

import numpy as np
import taichi as ti

from ..core import runtime
from ..core.geometry import vec3, vertex_neighbours
from ..core.launch import Launcher
from ..core.scan import block_sums, exclusive_scan
from .grid_buckets import ivec2, ivec3, ivec5, query_coarser, scan_entries, sort_bucket
from .grid_cells import LEVELS, boxes_overlap, bucket_of, cell_of, level_inv_h, level_of

MOVING = 0
STATIC = 1
HIDDEN = 2  # a triangle's group when it is in neither table
# The narrow phase treats distances within tolerance()·L of zero as touching (L =
# the pair's longest edge, below twice a box's largest extent), so two triangles
# whose boxes are that far apart can still be a hit: every box is padded by this
# many tolerances of its own largest extent on top of the contact margin.
BOX_SLACK = 2.0
# A moving triangle is binned only if its box meets another body's box; with more
# bodies than this the check costs more than it saves and every triangle is binned.
CULL_MAX_BODIES = 64


@ti.kernel
def _bin_group(
    particle_x: ti.types.ndarray(dtype=vec3, ndim=1),
    particle_body: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri: ti.types.ndarray(dtype=ivec5, ndim=1),
    tri_level: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri_box: ti.types.ndarray(dtype=vec3, ndim=2),
    body_group: ti.types.ndarray(dtype=ti.i32, ndim=1),
    body_self: ti.types.ndarray(dtype=ti.i32, ndim=1),
    body_box: ti.types.ndarray(dtype=vec3, ndim=2),
    group_count: ti.types.ndarray(dtype=ti.i32, ndim=2),
    bucket_end: ti.types.ndarray(dtype=ti.i32, ndim=1),
    bucket_bodies: ti.types.ndarray(dtype=ivec2, ndim=1),
    entry_key: ti.types.ndarray(dtype=ivec5, ndim=1),
    entry_box: ti.types.ndarray(dtype=vec3, ndim=2),
    active: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri_slot: ti.types.ndarray(dtype=ti.i32, ndim=1),
    block_sum: ti.types.ndarray(dtype=ti.i32, ndim=1),
    group: ti.i32,
    margin: float,
    inv_h0: float,
    serial: ti.template(),
) -> ti.i32:
    """Hash table of one group's triangles, in one launch (kernel launches cost more than a
    small query's work): boxes of the group's bodies (from their vertices) and triangles,
    each triangle's level (-1 for a moving triangle whose box meets no other body's box, on a
    body without self-collision: it can have no pair), count per bucket with the range of
    bodies in it, the binned triangles listed in index order (`active`, through tri_slot:
    n_tris + 1 entries), prefix sum, scatter. Each entry carries its triangle's body, cell and
    box, so that scanning a bucket reads contiguous memory; a bucket's entries are in
    (triangle, cell) order, as a serial scatter writes them, on any number of threads.
    Returns the number of (cell, triangle) entries; if that exceeds the entry capacity
    nothing is scattered and the caller grows the table and runs again."""
    n_bodies = body_box.shape[0]
    n_buckets = bucket_bodies.shape[0]
    mask = n_buckets - 1
    capacity = entry_key.shape[0]
    slack = ti.static(BOX_SLACK * runtime.tolerance())
    ti.loop_config(serialize=True)
    for level in range(LEVELS + 2):
        group_count[group, level] = 0
    ti.loop_config(serialize=True)
    for k in range(n_bodies):
        if body_group[k] == group:
            body_box[k, 0] = vec3(ti.math.inf)
            body_box[k, 1] = vec3(-ti.math.inf)
    cull = group == MOVING and n_bodies <= CULL_MAX_BODIES
    n_particles = particle_body.shape[0] if cull or group == STATIC else 0
    ti.loop_config(serialize=serial)
    for v in range(n_particles):
        k = particle_body[v]
        if k >= 0 and body_group[k] == group:
            p = particle_x[v]
            ti.atomic_min(body_box[k, 0], p)
            ti.atomic_max(body_box[k, 1], p)
    # A body's pad is at least that of any of its triangles.
    ti.loop_config(serialize=True)
    for k in range(n_bodies):
        if body_group[k] == group:
            pad = margin + slack * (body_box[k, 1] - body_box[k, 0]).max()
            body_box[k, 0] -= pad
            body_box[k, 1] += pad
    ti.loop_config(serialize=serial)
    for b in range(n_buckets + 1):
        bucket_end[b] = 0
    ti.loop_config(serialize=serial)
    for b in range(n_buckets):
        bucket_bodies[b] = ivec2(2147483647, -1)
    entries = 0
    n_tris = tri.shape[0]
    ti.loop_config(serialize=serial)
    for t in range(n_tris):
        info = tri[t]
        binned = 0
        if info[4] == group:
            p0, p1, p2 = particle_x[info[0]], particle_x[info[1]], particle_x[info[2]]
            lo = ti.min(p0, p1, p2)
            hi = ti.max(p0, p1, p2)
            pad = margin + slack * (hi - lo).max()
            lo -= pad
            hi += pad
            body = info[3]
            is_active = not cull or body_self[body] != 0
            if cull:
                for k in range(n_bodies):
                    if k != body and boxes_overlap(lo, hi, body_box[k, 0], body_box[k, 1]):
                        is_active = True
            level = -1
            if is_active:
                level = level_of(lo, hi, inv_h0)
                inv_h = level_inv_h(inv_h0, level)
                c0, c1 = cell_of(lo, inv_h), cell_of(hi, inv_h)
                # Nested loops: an inner ti.ndrange divides its flat index on every iteration.
                for x in range(c0[0], c1[0] + 1):
                    for y in range(c0[1], c1[1] + 1):
                        for z in range(c0[2], c1[2] + 1):
                            b = bucket_of(level, ivec3(x, y, z), mask)
                            ti.atomic_add(bucket_end[b + 1], 1)
                            ti.atomic_min(bucket_bodies[b][0], body)
                            ti.atomic_max(bucket_bodies[b][1], body)
                span = c1 - c0 + 1
                entries += span[0] * span[1] * span[2]
                ti.atomic_add(group_count[group, level], 1)
                binned = 1
                tri_box[t, 0] = lo
                tri_box[t, 1] = hi
            tri_level[t] = level
        tri_slot[t] = binned
    n_binned = exclusive_scan(tri_slot, 0, n_tris, block_sum, serial)
    tri_slot[n_tris] = n_binned
    group_count[group, LEVELS] = n_binned
    ti.loop_config(serialize=serial)
    for t in range(n_tris):
        if tri_slot[t + 1] > tri_slot[t]:
            active[tri_slot[t]] = t
    group_count[group, LEVELS + 1] = entries
    fits = entries <= capacity
    # Bucket b's count is at b + 1. An exclusive scan puts its start there; the scatter then
    # advances it to the bucket's end, so that bucket b's entries are [end[b], end[b + 1]).
    exclusive_scan(bucket_end, 1, n_buckets if fits else 0, block_sum, serial)
    n_scatter = n_binned if fits else 0
    ti.loop_config(serialize=serial)
    for s in range(n_scatter):
        t = active[s]
        level = tri_level[t]
        inv_h = level_inv_h(inv_h0, level)
        lo, hi = tri_box[t, 0], tri_box[t, 1]
        body = tri[t][3]
        c0, c1 = cell_of(lo, inv_h), cell_of(hi, inv_h)
        # Nested loops: an inner ti.ndrange divides its flat index on every iteration.
        for x in range(c0[0], c1[0] + 1):
            for y in range(c0[1], c1[1] + 1):
                for z in range(c0[2], c1[2] + 1):
                    slot = ti.atomic_add(bucket_end[bucket_of(level, ivec3(x, y, z), mask) + 1], 1)
                    entry_key[slot] = ivec5(t, body, x, y, z)
                    entry_box[slot, 0] = lo
                    entry_box[slot, 1] = hi
    if ti.static(not serial):
        # Threads scatter into a bucket in the order they reach it: put it back in order.
        for b in range(n_buckets if fits else 0):
            sort_bucket(entry_key, entry_box, bucket_end[b], bucket_end[b + 1])
    return entries


@ti.kernel
def _find_pairs(
    tri: ti.types.ndarray(dtype=ivec5, ndim=1),
    body_self: ti.types.ndarray(dtype=ti.i32, ndim=1),
    nbr_range: ti.types.ndarray(dtype=ivec2, ndim=1),
    nbr: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri_level: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri_box: ti.types.ndarray(dtype=vec3, ndim=2),
    group_count: ti.types.ndarray(dtype=ti.i32, ndim=2),
    moving_end: ti.types.ndarray(dtype=ti.i32, ndim=1),
    moving_bodies: ti.types.ndarray(dtype=ivec2, ndim=1),
    moving_key: ti.types.ndarray(dtype=ivec5, ndim=1),
    moving_box: ti.types.ndarray(dtype=vec3, ndim=2),
    moving_active: ti.types.ndarray(dtype=ti.i32, ndim=1),
    static_end: ti.types.ndarray(dtype=ti.i32, ndim=1),
    static_key: ti.types.ndarray(dtype=ivec5, ndim=1),
    static_box: ti.types.ndarray(dtype=vec3, ndim=2),
    static_active: ti.types.ndarray(dtype=ti.i32, ndim=1),
    pairs: ti.types.ndarray(dtype=ivec2, ndim=1),
    pairs_found: ti.types.ndarray(dtype=ivec2, ndim=1),
    pair_query: ti.types.ndarray(dtype=ivec2, ndim=1),
    query_count: ti.types.ndarray(dtype=ti.i32, ndim=1),
    block_sum: ti.types.ndarray(dtype=ti.i32, ndim=1),
    inv_h0: float,
    serial: ti.template(),
) -> ti.i32:
    """Candidate pairs (box overlap, different bodies or one with self-collision not near
    neighbours, not both static); returns their number,
    which exceeds pairs.shape[0] when the buffer overflowed (then only the first ones are stored).
    The queries (each moving entry, then each triangle that looks up coarser levels) report
    their pairs in query order, on any number of threads: in parallel they land in
    pairs_found (with pair_query, as large as pairs) as the threads finish, each query's
    count in query_count (one per query), and are then moved to their place in `pairs`."""
    mesh = ti.static((tri, body_self, nbr_range, nbr))
    out = ti.static((pairs if serial else pairs_found, pair_query, group_count, serial))
    group_count[0, LEVELS + 2] = 0
    top_moving = -1
    top_static = -1
    bottom = LEVELS
    ti.loop_config(serialize=True)
    for level in range(LEVELS):
        if group_count[MOVING, level] > 0:
            top_moving = level
            bottom = ti.min(bottom, level)
        if group_count[STATIC, level] > 0:
            top_static = level
            bottom = ti.min(bottom, level)
    n_moving = group_count[MOVING, LEVELS]
    # With every triangle at one level there are no unequal-level pairs to look up.
    n_coarser_queries = n_moving + group_count[STATIC, LEVELS] if ti.max(top_moving, top_static) > bottom else 0
    # Equal levels: each moving entry against the later entries of its bucket and
    # the static entries of its cell, so each pair meets once, in one shared cell.
    moving_mask = moving_bodies.shape[0] - 1
    static_mask = static_end.shape[0] - 2
    n_entries = group_count[MOVING, LEVELS + 1]
    ti.loop_config(serialize=serial)
    for e in range(n_entries):
        key = moving_key[e]
        t = key[0]
        body_t = key[1]
        c = ivec3(key[2], key[3], key[4])
        lo_t, hi_t = moving_box[e, 0], moving_box[e, 1]
        level = tri_level[t]
        inv_h = level_inv_h(inv_h0, level)
        b = bucket_of(level, c, moving_mask)
        # A bucket holding one body's triangles only has no pair to offer (unless the body
        # collides with itself).
        bodies = moving_bodies[b]
        end = moving_end[b + 1] if bodies[0] != bodies[1] or body_self[bodies[0]] != 0 else 0
        found = scan_entries(t, body_t, lo_t, hi_t, level, c, inv_h, e + 1, end,
                             ti.static((tri_level, moving_key, moving_box)), out, e, 0, mesh)
        if level <= top_static:
            b = bucket_of(level, c, static_mask)
            found = scan_entries(t, body_t, lo_t, hi_t, level, c, inv_h, static_end[b], static_end[b + 1],
                                 ti.static((tri_level, static_key, static_box)), out, e, found, mesh)
        if ti.static(not serial):
            query_count[e] = found
    # Unequal levels: the finer triangle looks up the coarser one (static triangles
    # only look up moving ones).
    ti.loop_config(serialize=serial)
    for s in range(n_coarser_queries):
        q = n_entries + s
        found = 0
        if s < n_moving:
            t = moving_active[s]
            body_t = tri[t][3]
            found = query_coarser(t, body_t, MOVING, top_moving, inv_h0, tri_level, tri_box, group_count,
                                  moving_end, moving_key, moving_box, out, q, found, mesh)
            found = query_coarser(t, body_t, STATIC, top_static, inv_h0, tri_level, tri_box, group_count,
                                  static_end, static_key, static_box, out, q, found, mesh)
        else:
            t = static_active[s - n_moving]
            found = query_coarser(t, tri[t][3], MOVING, top_moving, inv_h0, tri_level, tri_box, group_count,
                                  moving_end, moving_key, moving_box, out, q, found, mesh)
        if ti.static(not serial):
            query_count[q] = found
    n_pairs = group_count[0, LEVELS + 2]
    if ti.static(not serial):
        # Each query's pairs to its offset in the queries' order (nothing moved on overflow).
        exclusive_scan(query_count, 0, n_entries + n_coarser_queries, block_sum, False)
        for k in range(n_pairs if n_pairs <= pairs.shape[0] else 0):
            which = pair_query[k]
            pairs[query_count[which[0]] + which[1]] = pairs_found[k]
    return n_pairs


@ti.kernel
def _moving_displacement(
    particle_x: ti.types.ndarray(dtype=vec3, ndim=1),
    particle_built: ti.types.ndarray(dtype=vec3, ndim=1),
    particle_body: ti.types.ndarray(dtype=ti.i32, ndim=1),
    body_group: ti.types.ndarray(dtype=ti.i32, ndim=1),
    serial: ti.template(),
) -> float:
    """Largest coordinate change of a moving body's vertex since the grid was built."""
    most = 0.0
    ti.loop_config(serialize=serial)
    for v in range(particle_x.shape[0]):
        k = particle_body[v]
        if k >= 0 and body_group[k] == MOVING:
            ti.atomic_max(most, ti.abs(particle_x[v] - particle_built[v]).max())
    return most


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

    def __init__(self, n_tris: int):
        self.entries = 0
        self.active = ti.ndarray(ti.i32, shape=max(n_tris, 1))
        self._allocate(0)

    def _allocate(self, capacity: int) -> None:
        n_buckets = _next_pow2(max(capacity, 1))
        self.bucket_end = ti.ndarray(ti.i32, shape=n_buckets + 1)
        self.bucket_end.fill(0)
        self.bucket_bodies = ti.ndarray(ivec2, shape=n_buckets)
        self.entry_key = ti.ndarray(ivec5, shape=max(capacity, 1))
        self.entry_box = ti.ndarray(ti.types.vector(3, runtime.real_type()), shape=(max(capacity, 1), 2))
        self.capacity = capacity

    def grow(self, entries: int) -> None:
        """Room for at least `entries`, with a quarter more for entries that come and go."""
        self._allocate(max(entries + entries // 4, 2 * self.capacity))

    def arrays(self) -> tuple:
        return self.bucket_end, self.bucket_bodies, self.entry_key, self.entry_box, self.active


class UniformGrid:
    """Uniform-grid broad phase over the triangles of several bodies.

    tri_indices (m, 3) int: vertex indices into the particle array, global over all
    bodies; tri_body (m,) int: the body of each triangle; tri_static (m,) bool:
    triangles of static bodies (binned once, by `bin_static`). cell_size: the base
    cell size in scene units (default: `default_cell_size` of the boxes at the first query);
    margin: every box is inflated by this much (scene units). pair_capacity: the
    initial size of the pair buffer, grown on overflow. skin: reuse the pairs while the
    moving vertices stay near where they were binned: moving boxes are binned inflated
    by skin × the base cell size, and a query in which no moving vertex has moved that
    far along any axis since returns the same pairs, a superset of the exact ones
    (0: bin at every query, the exact pairs). tri_hidden (m,) bool: static triangles
    never binned, so in no pair (faces hidden against another static body, contact/hidden_faces.py).
    body_self (n_bodies,) bool: bodies whose own triangles pair too (those not near neighbours:
    core.geometry.near_in_mesh). The pairs come out in one order on any number of threads and
    on a GPU.
    """

    def __init__(self, tri_indices, tri_body, tri_static=None, cell_size: float | None = None,
                 margin: float = 0.0, pair_capacity: int = 1024, skin: float = 0.0, tri_hidden=None,
                 body_self=None):
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
        if not (np.isfinite(skin) and skin >= 0):
            raise ValueError(f"skin must be a non-negative finite fraction of a cell, got {skin}")
        self.n_tris = m
        self.cell_size = None if cell_size is None else float(cell_size)
        self.margin = float(margin)
        self.skin = float(skin)
        self.rebuilds = 0  # queries that binned the moving triangles
        self.queries = 0
        self.has_static = bool(np.any(tri_static))
        self.has_moving = bool(not np.all(tri_static))
        size = max(m, 1)
        n_bodies = int(tri_body.max()) + 1 if m else 1
        body_group = np.full(n_bodies, MOVING, dtype=np.int32)
        body_group[tri_body[tri_static]] = STATIC
        if m and np.any(body_group[tri_body[~tri_static]] == STATIC):
            raise ValueError("a body has both static and moving triangles")
        n_particles = int(tri_indices.max()) + 1 if m else 1
        particle_body = np.full(n_particles, -1, dtype=np.int32)
        particle_body[tri_indices] = tri_body[:, None]
        if m and np.any(particle_body[tri_indices] != tri_body[:, None]):
            raise ValueError("a vertex is shared by triangles of different bodies; give each body its own vertices")
        self.tri_indices_np = tri_indices
        # Vertex indices, body and group of each triangle: one array, one kernel argument.
        self.tri = ti.ndarray(ivec5, shape=size)
        if m:
            group = np.where(tri_static, STATIC, MOVING).astype(np.int32)
            if tri_hidden is not None:
                group[np.asarray(tri_hidden, dtype=bool) & tri_static] = HIDDEN
            self.tri.from_numpy(np.column_stack([tri_indices, tri_body, group]).astype(np.int32))
        real3 = ti.types.vector(3, runtime.real_type())
        self.tri_box = ti.ndarray(real3, shape=(size, 2))
        self.tri_level = ti.ndarray(ti.i32, shape=size)
        self.tri_level.fill(-1)
        self.particle_body = ti.ndarray(ti.i32, shape=n_particles)
        self.particle_body.from_numpy(particle_body)
        self.body_group = ti.ndarray(ti.i32, shape=n_bodies)
        self.body_group.from_numpy(body_group)
        self.body_self = ti.ndarray(ti.i32, shape=n_bodies)
        self.body_self.fill(0)
        if body_self is not None:
            flags = np.asarray(body_self, dtype=bool)
            if len(flags) < n_bodies or np.any(flags[:n_bodies] & (body_group == STATIC)):
                raise ValueError("body_self needs one flag per body, and a static body cannot collide with itself")
            self.body_self.from_numpy(flags[:n_bodies].astype(np.int32))
        # The self-colliding bodies' vertex neighbours (geometry.near_in_mesh).
        self_tris = np.asarray(body_self, dtype=bool)[tri_body] if body_self is not None and m else np.zeros(m, bool)
        nbr_range, nbr = vertex_neighbours(tri_indices, n_particles, self_tris)
        self.nbr_range = ti.ndarray(ivec2, shape=n_particles)
        self.nbr_range.from_numpy(nbr_range)
        self.nbr = ti.ndarray(ti.i32, shape=len(nbr))
        self.nbr.from_numpy(nbr)
        self.body_box = ti.ndarray(real3, shape=(n_bodies, 2))
        # Per group: triangles binned per level [0, LEVELS), binned triangles [LEVELS],
        # entries [LEVELS + 1]; [0, LEVELS + 2] counts the pairs of a query.
        self.group_count = ti.ndarray(ti.i32, shape=(2, LEVELS + 3))
        self.group_count.fill(0)
        self.tables = (_HashTable(m), _HashTable(m))
        # Scratch of the loops that run in parallel and keep their output in one order.
        self.tri_slot = ti.ndarray(ti.i32, shape=size + 1)
        self.block_sum = block_sums()
        self._allocate_pairs(pair_capacity)
        # A query whose loops are shared among threads also needs pairs_found and pair_query
        # (as large as pairs) and query_count (one per query): allocated at the first such query.
        self.pairs_found = self.pair_query = self.query_count = None
        self._none_pairs = ti.ndarray(ivec2, shape=1)  # in their place for a serial query
        self._none_counts = ti.ndarray(ti.i32, shape=1)
        self.n_pairs = 0
        self._static_binned = False
        self._launch = Launcher()
        self.particle_built = ti.ndarray(real3, shape=n_particles) if skin > 0 else None
        self._moving_binned = False

    @property
    def pair_capacity(self) -> int:
        return self.pairs.shape[0]

    def _allocate_pairs(self, capacity: int) -> None:
        self.pairs = ti.ndarray(ivec2, shape=capacity)

    def _order_scratch(self, serial: bool, queries: int) -> tuple:
        """(pairs_found, pair_query, query_count) for _find_pairs: where a parallel query's pairs
        land first, the query and rank of each, and each query's count; placeholders when the
        loops run serially."""
        if serial:
            return self._none_pairs, self._none_pairs, self._none_counts
        if self.pairs_found is None or self.pairs_found.shape[0] != self.pair_capacity:
            self.pairs_found = ti.ndarray(ivec2, shape=self.pair_capacity)
            self.pair_query = ti.ndarray(ivec2, shape=self.pair_capacity)
        if self.query_count is None or self.query_count.shape[0] < queries:
            self.query_count = ti.ndarray(ti.i32, shape=queries)
        return self.pairs_found, self.pair_query, self.query_count

    def entries(self, group: int) -> int:
        """(cell, triangle) entries of the last binning of `group` (MOVING or STATIC)."""
        return self.tables[group].entries

    def _choose_cell_size(self, particle_x) -> None:
        if self.cell_size is not None:
            return
        x = particle_x.to_numpy()
        tris = x[self.tri_indices_np]
        extent = (tris.max(axis=1) - tris.min(axis=1)).max(axis=1) + 2 * self.margin
        self.cell_size = default_cell_size(extent)

    def _skin_length(self) -> float:
        return self.skin * self.cell_size

    def _bin(self, particle_x, group: int) -> None:
        table = self.tables[group]
        pad = self.margin + (self._skin_length() if group == MOVING else 0.0)
        while True:
            entries = self._launch(_bin_group, particle_x, self.particle_body, self.tri, self.tri_level, self.tri_box,
                                   self.body_group, self.body_self, self.body_box, self.group_count,
                                   *table.arrays(), self.tri_slot, self.block_sum,
                                   group, pad, 1.0 / self.cell_size, runtime.serial_loops(self.n_tris))
            if entries <= table.capacity:
                break
            table.grow(entries)
        table.entries = entries

    def bin_static(self, particle_x) -> None:
        """Bin the static triangles at their current positions (once; again only if they moved)."""
        self._choose_cell_size(particle_x)
        if self.has_static:
            self._bin(particle_x, STATIC)
        self._static_binned = True

    def find_pairs(self, particle_x) -> int:
        """Rebin the moving triangles at particle_x (ti.ndarray of vec3, (n_particles,)) and
        collect all candidate pairs into `pairs[:n]`; returns n. Grows the buffers and
        runs again when they overflow, so no pair is ever dropped."""
        if not self._static_binned:
            self.bin_static(particle_x)
        if self.n_tris == 0:
            self.n_pairs = 0
            return 0
        self.queries += 1
        if self.has_moving and self._moving_binned and self.skin > 0:
            moved = self._launch(_moving_displacement, particle_x, self.particle_built, self.particle_body,
                                 self.body_group, runtime.serial_loops(self.particle_body.shape[0]))
            # A box grows by at most the vertices' motion, plus its tolerance pad's share
            # (BOX_SLACK tolerances of twice that) and rounding: a tenth is kept clear.
            if moved <= 0.9 * self._skin_length():
                return self.n_pairs
        if self.has_moving:
            self._bin(particle_x, MOVING)
            self.rebuilds += 1
            if self.skin > 0:
                self.particle_built.copy_from(particle_x)
                self._moving_binned = True
        moving, static = self.tables
        serial = runtime.serial_loops(moving.entries)
        while True:
            # Queries: each moving entry, then each triangle that looks up coarser levels.
            scratch = self._order_scratch(serial, moving.capacity + self.n_tris)
            n = self._launch(_find_pairs, self.tri, self.body_self, self.nbr_range, self.nbr, self.tri_level,
                             self.tri_box, self.group_count, moving.bucket_end, moving.bucket_bodies,
                             moving.entry_key, moving.entry_box, moving.active, static.bucket_end,
                             static.entry_key, static.entry_box, static.active,
                             self.pairs, *scratch, self.block_sum, 1.0 / self.cell_size, serial)
            if n <= self.pair_capacity:
                break
            self._allocate_pairs(max(n, 2 * self.pair_capacity))
        self.n_pairs = n
        return n

    def pairs_numpy(self) -> np.ndarray:
        """The candidate pairs of the last query, (n, 2) global triangle indices, body[a] <= body[b]."""
        return self.pairs.to_numpy()[: self.n_pairs]
