"""A grid table's buckets (collision/broadphase.py): kept in (triangle, cell) order, and scanned
for a triangle's partners, each pair reported once, by the cell holding the lower corner of the
two boxes' intersection."""

import taichi as ti

from ..core.geometry import near_in_mesh, vec3
from .grid_cells import LEVELS, boxes_overlap, bucket_of, cell_of, level_inv_h

ivec2 = ti.types.vector(2, ti.i32)
ivec3 = ti.types.vector(3, ti.i32)
# A triangle (vertex 0, 1, 2, body, group); an entry (triangle, body, cell x, y, z).
ivec5 = ti.types.vector(5, ti.i32)


@ti.func
def entry_before(a: ivec5, b: ivec5) -> bool:
    """Whether entry a comes before entry b in a bucket: by triangle, then cell (x, y, z)."""
    before = False
    decided = False
    for i in ti.static((0, 2, 3, 4)):
        if not decided and a[i] != b[i]:
            before = a[i] < b[i]
            decided = True
    return before


@ti.func
def sort_bucket(entry_key: ti.template(), entry_box: ti.template(), first: ti.i32, end: ti.i32):
    """Insertion sort of the entries [first, end) (a bucket holds a few) by entry_before."""
    for i in range(first + 1, end):
        key = entry_key[i]
        lo, hi = entry_box[i, 0], entry_box[i, 1]
        j = i
        shifting = True
        while shifting:
            shifting = False
            if j > first:
                if entry_before(key, entry_key[j - 1]):
                    entry_key[j] = entry_key[j - 1]
                    entry_box[j, 0] = entry_box[j - 1, 0]
                    entry_box[j, 1] = entry_box[j - 1, 1]
                    j -= 1
                    shifting = True
        entry_key[j] = key
        entry_box[j, 0] = lo
        entry_box[j, 1] = hi


@ti.func
def owns_pair(lo_t: vec3, lo_u: vec3, c: ivec3, inv_h: float) -> bool:
    """Whether c, a cell two overlapping boxes (lower corners lo_t, lo_u) both cover, holds the
    lower corner of their intersection: the one cell of theirs that reports the pair."""
    return all(ti.max(cell_of(lo_t, inv_h), cell_of(lo_u, inv_h)) == c)


@ti.func
def report_pair(t: ti.i32, body_t: ti.i32, u: ti.i32, body_u: ti.i32, out: ti.template(), q: ti.i32,
                found: ti.i32):
    """Append (t, u), body order first, the `found`-th pair of query q. out: (pairs, pair_query,
    group_count, serial), made with ti.static; in parallel (not serial) each pair also notes
    (q, found), from which _find_pairs puts it in the queries' order."""
    pairs, pair_query, group_count = ti.static(out[0], out[1], out[2])
    k = ti.atomic_add(group_count[0, LEVELS + 2], 1)
    if k < pairs.shape[0]:
        pairs[k] = ivec2(t, u) if body_t < body_u else ivec2(u, t)
        if ti.static(not out[3]):
            pair_query[k] = ivec2(q, found)


@ti.func
def pairable(bodies: ti.template(), t: ti.i32, body_t: ti.i32, u: ti.i32, body_u: ti.i32) -> bool:
    """Whether triangles t and u may pair: different bodies, or one body with self-collision
    and not near neighbours (geometry.near_in_mesh). bodies: (tri, body_self, nbr_range, nbr)."""
    tri, body_self = ti.static(bodies[0], bodies[1])
    ok = body_u != body_t
    if not ok and body_self[body_t] != 0:
        ok = not near_in_mesh(ivec3(tri[t][0], tri[t][1], tri[t][2]), ivec3(tri[u][0], tri[u][1], tri[u][2]),
                              bodies[2], bodies[3])
    return ok


@ti.func
def scan_entries(t: ti.i32, body_t: ti.i32, lo_t: vec3, hi_t: vec3, level: ti.i32, c: ivec3, inv_h: float,
                 first: ti.i32, end: ti.i32, entries: ti.template(), out: ti.template(), q: ti.i32, found: ti.i32,
                 bodies: ti.template()) -> ti.i32:
    """Report t against the entries [first, end) of a bucket that are binned in cell c at
    `level`, may pair with t (pairable) and have an overlapping box, as query q's pairs from
    its `found`-th on (report_pair's out); returns the query's pairs found so far. entries:
    (tri_level, entry_key, entry_box), the levels and one table's entries; bodies: (tri,
    body_self, nbr_range, nbr); all tuples made with ti.static."""
    tri_level, entry_key, entry_box = ti.static(entries[0], entries[1], entries[2])
    n = found
    for f in range(first, end):
        key = entry_key[f]
        if (key[2] == c[0] and key[3] == c[1] and key[4] == c[2]
                and boxes_overlap(lo_t, hi_t, entry_box[f, 0], entry_box[f, 1])):
            u = key[0]
            # The cell first (a pair meets in every cell both boxes cover, and is reported in
            # one), then the neighbour test; nested, as Taichi's `and` evaluates both sides.
            if tri_level[u] == level and owns_pair(lo_t, entry_box[f, 0], c, inv_h):
                if pairable(bodies, t, body_t, u, key[1]):
                    report_pair(t, body_t, u, key[1], out, q, n)
                    n += 1
    return n


@ti.func
def query_coarser(t: ti.i32, body_t: ti.i32, table: ti.template(), top_level: ti.i32, inv_h0: float,
                  tri_level: ti.template(), tri_box: ti.template(), group_count: ti.template(),
                  bucket_end: ti.template(), entry_key: ti.template(), entry_box: ti.template(),
                  out: ti.template(), q: ti.i32, found: ti.i32, bodies: ti.template()) -> ti.i32:
    """Report t's partners binned in one table (MOVING or STATIC) at levels above t's own,
    looked up in the (at most 2 per axis) cells t's box covers at each such level, as query
    q's pairs from its `found`-th on (scan_entries); returns the query's pairs found so far."""
    mask = bucket_end.shape[0] - 2
    lo_t, hi_t = tri_box[t, 0], tri_box[t, 1]
    n = found
    for level in range(tri_level[t] + 1, top_level + 1):
        if group_count[table, level] > 0:
            inv_h = level_inv_h(inv_h0, level)
            c0, c1 = cell_of(lo_t, inv_h), cell_of(hi_t, inv_h)
            # Nested loops: an inner ti.ndrange divides its flat index on every iteration.
            for x in range(c0[0], c1[0] + 1):
                for y in range(c0[1], c1[1] + 1):
                    for z in range(c0[2], c1[2] + 1):
                        c = ivec3(x, y, z)
                        b = bucket_of(level, c, mask)
                        n = scan_entries(t, body_t, lo_t, hi_t, level, c, inv_h, bucket_end[b], bucket_end[b + 1],
                                         ti.static((tri_level, entry_key, entry_box)), out, q, n, bodies)
    return n
