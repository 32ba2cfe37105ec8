"""Contacts between rigid bodies, from grids built once in each body's own frame.

A rigid body's triangles keep their shape, so their boxes, a hash grid of them and an
occupancy table are built once in the body's frame (collision/local_grid.py). A query then
takes the bodies' poses and, for each pair of bodies whose world boxes meet, works in one
body's frame at a time (body Q's triangles against body T's):

1. each cluster of Q (its triangles whose box centres share a cell 2^CLUSTER_LEVEL base
   cells wide) is carried into T's frame, its box made axis-aligned there, and kept if it
   meets a cell that T's triangles cover (T's occupancy table: eight reads) and, where all of
   T's triangles sit in its dense grid, the slab of such a cell (the two planes the cell's
   triangles lie between, local_grid.cell_slabs): only Q's triangles near T's surface go on,
   so the cost follows the contact, not the overlap of the two bodies' boxes;
2. each triangle of a kept cluster is carried into T's frame and looks up T's grid at the
   levels of T's triangles at least as coarse as its own
   (strictly coarser when T's triangles query Q's, so that each pair is looked up from one
   side), reporting a pair in the one cell that holds the lower corner of the two boxes'
   intersection, as the world grid does;
3. the candidate pairs go through the unified narrow phase in world coordinates.

It is exact like the world grid (every intersecting pair, once): boxes are padded by the
narrow phase's zero tolerance (BOX_SLACK) and by the rounding of the change of frame, and
the stored boxes are rounded outwards.
"""

import numpy as np
import taichi as ti

from ..core import runtime
from ..core.geometry import vec3
from ..core.launch import Launcher
from .broadphase import BOX_SLACK, default_cell_size, ivec2
from .contacts import Contacts, append_contact
from .grid_cells import LEVELS, boxes_overlap, cell_of, level_inv_h
from .local_grid import LocalGrid, Occupancy, box_occupied, cell_run, cell_slabs, to_ndarray
from .narrowphase import collide_triangle_pair
from .pipeline import check_mesh

ivec3 = ti.types.vector(3, ti.i32)
ivec4 = ti.types.vector(4, ti.i32)
ivec5 = ti.types.vector(5, ti.i32)
mat3 = ti.math.mat3
# Clusters are the cells of this level of the base grid (one base cell wide): smaller ones
# follow the contact more closely, larger ones are fewer to test. (At level 1, two base cells
# wide, the coax tori of benchmarks/broadphase.py kept 312k of 1M triangles, at level 0 177k.)
CLUSTER_LEVEL = 0
# The change of frame's rounding, in ulps of the largest coordinate involved.
FRAME_ROUND_ULPS = 16.0
# The plane test before the narrow phase: a candidate whose other triangle lies wholly on one
# side of this one's plane by more than PLANE_MARGIN_PADS frame-rounding pads plus
# PLANE_MARGIN_ULPS ulps of the coordinates is dropped; triangles with twice their area below
# PLANE_TEST_MIN_AREA times their extent squared (slivers) are not plane-tested.
PLANE_MARGIN_PADS = 16.0
PLANE_MARGIN_ULPS = 64.0
PLANE_TEST_MIN_AREA = 1e-3
# Steps 2 and 3 share out chunks of this many kept triangles among WORKERS loop iterations,
# each taking the next chunk until none is left (Taichi 1.7 gives a thread no fewer than 512
# of a loop's iterations, so fewer than 1,024 would all go to one thread).
SPREAD_CHUNK = 16
WORKERS = 1024
# counts[]: directions, items (clusters to test), kept triangles, candidate pairs, contacts,
# the most candidates a chunk of kept triangles found, and the next chunk to take in steps 2
# and 3.
N_DIR, N_ITEMS, N_KEPT, N_PAIRS, N_CONTACTS, N_ROOM, N_NEXT_QUERY, N_NEXT_PAIR = 0, 1, 2, 3, 4, 5, 6, 7


@ti.func
def pose_of(poses: ti.template(), k: ti.i32):
    """Body k's rotation (mat3) and translation (vec3) from its rows in `poses`."""
    rot = mat3([[poses[k, 0][i] for i in ti.static(range(3))],
                [poses[k, 1][i] for i in ti.static(range(3))],
                [poses[k, 2][i] for i in ti.static(range(3))]])
    return rot, poses[k, 3]


@ti.func
def next_chunk(counts: ti.template(), which: ti.template(), n_chunks: ti.i32) -> ti.i32:
    """The next of n_chunks chunks for a worker to take, from the counter counts[which], or -1
    when none is left."""
    c = -1
    if counts[which] < n_chunks:
        c = ti.atomic_add(counts[which], 1)
        if c >= n_chunks:
            c = -1
    return c


@ti.func
def rounding_margin(pad: float, size: float) -> float:
    """Far more than the rounding of both frames' coordinates (pad: the change of frame's) and
    of distances among coordinates up to `size` (scene units)."""
    return ti.static(PLANE_MARGIN_PADS) * pad + ti.static(PLANE_MARGIN_ULPS * runtime.machine_eps()) * size


@ti.func
def outside_slab(lo: float, hi: float, slab) -> bool:
    """Whether the interval [lo, hi] along a cell's slab normal misses its slab (lo, hi)."""
    return lo > slab[1] or hi < slab[0]


@ti.func
def box_meets_slabs(body_t: ti.i32, lo: vec3, hi: vec3, margin: float, grid: ti.template(),
                    slab_normal: ti.template(), slab_range: ti.template(), inv_h0: float) -> bool:
    """Whether the box [lo, hi] (body T's frame) meets the slab of a cell of T's dense grid
    that it covers (by more than `margin`), when all of T's triangles sit in that grid; True
    otherwise. A box that meets no covered cell's slab holds nothing that can touch T."""
    dense_origin = ti.static(grid[0])
    level = dense_origin[body_t][3]
    meets = level >= LEVELS
    if not meets:
        inv_h = level_inv_h(inv_h0, level)
        c0, c1 = cell_of(lo, inv_h), cell_of(hi, inv_h)
        centre = 0.5 * (lo + hi)
        half = 0.5 * (hi - lo)
        for x in range(c0[0], c1[0] + 1):
            for y in range(c0[1], c1[1] + 1):
                for z in range(c0[2], c1[2] + 1):
                    if not meets:
                        run = cell_run(body_t, level, ivec3(x, y, z), grid)
                        if run[1] > run[0]:
                            n_c = ti.cast(slab_normal[run[0]], float)
                            d_c = ti.cast(slab_range[run[0]], float)
                            mid = n_c.dot(centre)
                            reach = ti.abs(n_c).dot(half) + margin
                            meets = not outside_slab(mid - reach, mid + reach, d_c)
    return meets


@ti.func
def query_cells(ia: ivec5, a: ti.i32, info: ivec5, rot: mat3, shift: vec3, round_pad: float, levels: ti.i32,
                vert_local: ti.template(), tri: ti.template(), grid: ti.template(), cell_items: ti.template(),
                entry_box: ti.template(), slab_normal: ti.template(), slab_range: ti.template(),
                pairs: ti.template(), region: ti.i32, room: ti.i32, n_found: ti.i32,
                inv_h0: float) -> ti.i32:
    """Step 2 for triangle a of body Q = info[0] (vertex indices ia): its box in T's frame
    (rot, shift; padded by round_pad and BOX_SLACK), and T's triangles in the cells it
    covers at the levels in the bit mask `levels`, each pair appended once to its chunk's
    region of `pairs` (room slots from region; n_found already there; returns the new count,
    which may pass room: the caller then grows the regions), but those whose
    T triangle lies wholly on one side of a's plane by more than rounding can move it (no
    straddle: Möller's test, the narrow phase's first, would turn them away). A cell whose
    slab (local_grid.cell_slabs) a lies wholly outside, by its pad and more than rounding, is
    passed over whole: a plane then parts a from each of its triangles."""
    body_t = info[1]
    p0 = rot @ vert_local[ia[0]] + shift
    p1 = rot @ vert_local[ia[1]] + shift
    p2 = rot @ vert_local[ia[2]] + shift
    lo, hi = ti.min(p0, p1, p2), ti.max(p0, p1, p2)
    extent = (hi - lo).max()
    pad = round_pad + ti.static(BOX_SLACK * runtime.tolerance()) * extent
    lo -= pad
    hi += pad
    # a's unit normal in T's frame, for the plane test; none for a sliver, whose normal
    # rounding turns too far.
    normal = (p1 - p0).cross(p2 - p0)
    area2 = normal.norm()
    plane_test = area2 > ti.static(PLANE_TEST_MIN_AREA) * extent * extent
    if plane_test:
        normal /= area2
    plane_margin = rounding_margin(round_pad, extent + ti.abs(p0).max())
    for level in range(LEVELS):
        if (levels >> level) & 1:
            inv_h = level_inv_h(inv_h0, level)
            c0, c1 = cell_of(lo, inv_h), cell_of(hi, inv_h)
            for x in range(c0[0], c1[0] + 1):
                for y in range(c0[1], c1[1] + 1):
                    for z in range(c0[2], c1[2] + 1):
                        run = cell_run(body_t, level, ivec3(x, y, z), grid)
                        if run[1] > run[0]:
                            n_c = ti.cast(slab_normal[run[0]], float)
                            d_c = ti.cast(slab_range[run[0]], float)
                            s0 = n_c.dot(p0)
                            s1 = n_c.dot(p1)
                            s2 = n_c.dot(p2)
                            reach = pad + plane_margin
                            if outside_slab(ti.min(s0, s1, s2) - reach, ti.max(s0, s1, s2) + reach, d_c):
                                run[1] = run[0]
                        for f in range(run[0], run[1]):
                            lo_b = ti.cast(entry_box[f, 0], float)
                            if boxes_overlap(lo, hi, lo_b, ti.cast(entry_box[f, 1], float)):
                                # Reported only in the cell holding the intersection's lower corner.
                                corner = ti.max(c0, cell_of(lo_b, inv_h))
                                if corner[0] == x and corner[1] == y and corner[2] == z:
                                    b = cell_items[f]
                                    keep = True
                                    if plane_test:
                                        ib = tri[b]
                                        s0 = normal.dot(vert_local[ib[0]] - p0)
                                        s1 = normal.dot(vert_local[ib[1]] - p0)
                                        s2 = normal.dot(vert_local[ib[2]] - p0)
                                        keep = (ti.min(s0, s1, s2) <= plane_margin
                                                and ti.max(s0, s1, s2) >= -plane_margin)
                                    if keep:
                                        if n_found < room:
                                            pairs[region + n_found] = (ivec2(a, b) if info[0] < body_t
                                                                       else ivec2(b, a))
                                        n_found += 1
    return n_found


@ti.kernel
def _rigid_query(
    poses: ti.types.ndarray(dtype=vec3, ndim=2),
    body_box: ti.types.ndarray(dtype=vec3, ndim=2),
    body_reach: ti.types.ndarray(ndim=1),
    body_static: ti.types.ndarray(dtype=ti.i32, ndim=1),
    body_clusters: ti.types.ndarray(dtype=ti.i32, ndim=1),
    vert_local: ti.types.ndarray(dtype=vec3, ndim=1),
    tri: ti.types.ndarray(dtype=ivec5, ndim=1),
    cluster_tris: ti.types.ndarray(dtype=ti.i32, ndim=1),
    cluster_start: ti.types.ndarray(dtype=ti.i32, ndim=1),
    cluster_box: ti.types.ndarray(dtype=vec3, ndim=2),
    cluster_level: ti.types.ndarray(dtype=ti.i32, ndim=1),
    dense_origin: ti.types.ndarray(dtype=ivec4, ndim=1),
    dense_dims: ti.types.ndarray(dtype=ivec4, ndim=1),
    dense_start: ti.types.ndarray(dtype=ti.i32, ndim=1),
    cell_key: ti.types.ndarray(dtype=ivec4, ndim=1),
    cell_range: ti.types.ndarray(dtype=ivec2, ndim=1),
    cell_items: ti.types.ndarray(dtype=ti.i32, ndim=1),
    entry_box: ti.types.ndarray(dtype=ti.types.vector(3, ti.f32), ndim=2),
    slab_normal: ti.types.ndarray(dtype=ti.types.vector(3, ti.f32), ndim=1),
    slab_range: ti.types.ndarray(dtype=ti.types.vector(2, ti.f32), ndim=1),
    fine_levels: ti.types.ndarray(dtype=ti.i32, ndim=1),
    occ_origin: ti.types.ndarray(dtype=vec3, ndim=1),
    occ_inv_cell: ti.types.ndarray(ndim=1),
    occ_dims: ti.types.ndarray(dtype=ivec3, ndim=1),
    occ_offset: ti.types.ndarray(dtype=ti.i32, ndim=1),
    occ_table: ti.types.ndarray(dtype=ti.i32, ndim=1),
    world_box: ti.types.ndarray(dtype=vec3, ndim=2),
    dir_info: ti.types.ndarray(dtype=ivec5, ndim=1),
    dir_rot: ti.types.ndarray(dtype=mat3, ndim=1),
    dir_shift: ti.types.ndarray(dtype=vec3, ndim=1),
    dir_pad: ti.types.ndarray(ndim=1),
    query: ti.types.ndarray(dtype=ivec2, ndim=1),
    pairs: ti.types.ndarray(dtype=ivec2, ndim=1),
    chunk_found: ti.types.ndarray(dtype=ti.i32, ndim=1),
    contact_pair: ti.types.ndarray(dtype=ivec2, ndim=1),
    contact_depth: ti.types.ndarray(ndim=1),
    contact_normal: ti.types.ndarray(dtype=vec3, ndim=1),
    contact_side: ti.types.ndarray(ndim=1),
    contact_point: ti.types.ndarray(dtype=vec3, ndim=1),
    counts: ti.types.ndarray(dtype=ti.i32, ndim=1),
    room: ti.i32,
    inv_h0: float,
    serial: ti.template(),
) -> ti.i32:
    """Candidate pairs of rigid bodies from their own-frame grids (module docstring, steps
    1-2), then the unified DCD test (Eq. 6 and its gradient) on each in world coordinates.
    poses[k] = (rotation rows 0-2, translation) of body k; two static bodies are never
    paired. A direction d (Q, T) holds
    dir_info[d] = (Q, T, Q's triangles look up T's levels >= their own (1) or > (0), Q's
    first item, Q's first cluster) and the change from Q's frame to T's (dir_rot, dir_shift,
    dir_pad: the rounding pad). Returns the contacts, or -1 if a buffer overflowed (counts
    then says how much each needs)."""
    round_pad = ti.static(FRAME_ROUND_ULPS * runtime.machine_eps())
    n_bodies = body_box.shape[0]
    for i in ti.static(range(8)):
        counts[i] = 0
    for k in range(n_bodies):
        rot, shift = pose_of(poses, k)
        centre = rot @ (0.5 * (body_box[k, 0] + body_box[k, 1])) + shift
        half = ti.abs(rot) @ (0.5 * (body_box[k, 1] - body_box[k, 0]))
        world_box[k, 0] = centre - half
        world_box[k, 1] = centre + half
    # Each pair of bodies whose boxes meet, both ways: the lower body's triangles look up
    # equal and coarser levels of the other's, the higher body's strictly coarser ones.
    ti.loop_config(serialize=True)
    for i in range(n_bodies):
        for j in range(i + 1, n_bodies):
            if (body_static[i] == 0 or body_static[j] == 0) and boxes_overlap(
                    world_box[i, 0], world_box[i, 1], world_box[j, 0], world_box[j, 1]):
                for way in ti.static(range(2)):
                    q, t = (i, j) if way == 0 else (j, i)
                    d = counts[N_DIR]
                    counts[N_DIR] += 1
                    if d < dir_info.shape[0]:
                        n_clusters = body_clusters[q + 1] - body_clusters[q]
                        dir_info[d] = ivec5(q, t, 1 - way, counts[N_ITEMS], body_clusters[q])
                        counts[N_ITEMS] += n_clusters
                        rot_q, shift_q = pose_of(poses, q)
                        rot_t, shift_t = pose_of(poses, t)
                        dir_rot[d] = rot_t.transpose() @ rot_q
                        dir_shift[d] = rot_t.transpose() @ (shift_q - shift_t)
                        # World coordinates round with their own size: both translations count.
                        dir_pad[d] = round_pad * (body_reach[q] + body_reach[t] + shift_q.norm() + shift_t.norm())
    n_dir = counts[N_DIR]
    n_items = counts[N_ITEMS] if n_dir <= dir_info.shape[0] else 0
    ti.loop_config(serialize=serial)
    for k in range(n_items):
        # The direction holding item k: the last whose first item is at most k.
        lo_d, hi_d = 0, n_dir - 1
        while lo_d < hi_d:
            mid = (lo_d + hi_d + 1) // 2
            if dir_info[mid][3] <= k:
                lo_d = mid
            else:
                hi_d = mid - 1
        d = lo_d
        info = dir_info[d]
        c = info[4] + k - info[3]
        # Levels of T this cluster's finest triangle would look up: none, nothing to do.
        wanted = fine_levels[info[1]] >> ti.min(cluster_level[c] + 1 - info[2], LEVELS - 1)
        if cluster_level[c] + 1 - info[2] >= LEVELS:
            wanted = 0
        centre = 0.5 * (cluster_box[c, 0] + cluster_box[c, 1])
        half = 0.5 * (cluster_box[c, 1] - cluster_box[c, 0])
        rot = dir_rot[d]
        centre_t = rot @ centre + dir_shift[d]
        half_t = ti.abs(rot) @ half + dir_pad[d]
        keep = wanted != 0 and box_occupied(info[1], centre_t - half_t, centre_t + half_t, occ_origin, occ_inv_cell,
                                            occ_dims, occ_offset, occ_table)
        if keep and fine_levels[info[1]] == (1 << dense_origin[info[1]][3]):
            margin = rounding_margin(dir_pad[d], ti.abs(centre_t).max() + half_t.max())
            keep = box_meets_slabs(info[1], centre_t - half_t, centre_t + half_t, margin,
                                   ti.static((dense_origin, dense_dims, dense_start, cell_key, cell_range)),
                                   slab_normal, slab_range, inv_h0)
        if keep:
            first, end = cluster_start[c], cluster_start[c + 1]
            slot = ti.atomic_add(counts[N_KEPT], end - first)
            if slot + end - first <= query.shape[0]:
                for i in range(end - first):
                    query[slot + i] = ivec2(d, cluster_tris[first + i])
    n_query = counts[N_KEPT] if counts[N_KEPT] <= query.shape[0] else 0
    n_chunks = (n_query + SPREAD_CHUNK - 1) // SPREAD_CHUNK
    n_taken = n_chunks if n_chunks <= chunk_found.shape[0] else 0
    ti.loop_config(serialize=serial)
    for _ in range(WORKERS):
        # Taichi gives each CPU thread one fixed block of a loop's iterations, and the kept
        # triangles are in space order, their work bunched where the bodies meet; a thread
        # also starts late now and then. So each worker takes the next chunk of kept
        # triangles until none is left, and writes its pairs into the chunk's own region of
        # `pairs` (no counter shared per pair, no cache line written by two threads).
        c = next_chunk(counts, N_NEXT_QUERY, n_taken)
        while c >= 0:
            first = c * SPREAD_CHUNK
            n_found = 0
            for s in range(first, ti.min(first + SPREAD_CHUNK, n_query)):
                d, a = query[s][0], query[s][1]
                info = dir_info[d]
                body_t = info[1]
                ia = tri[a]
                first_level = ia[4] + 1 - info[2]
                levels = 0
                if first_level < LEVELS:
                    levels = (fine_levels[body_t] >> first_level) << first_level
                if levels != 0:
                    n_found = query_cells(ia, a, info, dir_rot[d], dir_shift[d], dir_pad[d], levels, vert_local, tri,
                                          ti.static((dense_origin, dense_dims, dense_start, cell_key, cell_range)),
                                          cell_items, entry_box, slab_normal, slab_range, pairs, c * room,
                                          room, n_found, inv_h0)
            chunk_found[c] = n_found
            ti.atomic_add(counts[N_PAIRS], n_found)
            ti.atomic_max(counts[N_ROOM], n_found)
            c = next_chunk(counts, N_NEXT_QUERY, n_taken)
    fits = n_query > 0 and n_chunks <= chunk_found.shape[0] and counts[N_ROOM] <= room
    n_pair_chunks = n_chunks if fits else 0
    ti.loop_config(serialize=serial)
    for _ in range(WORKERS):
        c = next_chunk(counts, N_NEXT_PAIR, n_pair_chunks)
        while c >= 0:
            for i in range(chunk_found[c]):
                ab = pairs[c * room + i]
                ia, ib = tri[ab[0]], tri[ab[1]]
                rot_a, shift_a = pose_of(poses, ia[3])
                rot_b, shift_b = pose_of(poses, ib[3])
                a0 = rot_a @ vert_local[ia[0]] + shift_a
                a1 = rot_a @ vert_local[ia[1]] + shift_a
                a2 = rot_a @ vert_local[ia[2]] + shift_a
                b0 = rot_b @ vert_local[ib[0]] + shift_b
                b1 = rot_b @ vert_local[ib[1]] + shift_b
                b2 = rot_b @ vert_local[ib[2]] + shift_b
                hit, depth, normal, side, point = collide_triangle_pair(a0, a1, a2, b0, b1, b2)
                if hit:
                    append_contact(ti.static((contact_pair, contact_depth, contact_normal, contact_side, contact_point)),
                                   counts, N_CONTACTS, ab, depth, normal, side, point)
            c = next_chunk(counts, N_NEXT_PAIR, n_pair_chunks)
    result = counts[N_CONTACTS]
    if (n_dir > dir_info.shape[0] or counts[N_KEPT] > query.shape[0] or n_chunks > chunk_found.shape[0]
            or counts[N_ROOM] > room):
        result = -1
    return result


class RigidPipeline:
    """Broad phase + narrow phase between rigid bodies whose grids are built once, in their
    own frames.

    meshes: a list of (vertices (n_i, 3) float, faces (m_i, 3) int) numpy pairs, one per
    body, in the body's own frame (scene units; faces give outward normals by the
    right-hand rule). cell_size: the base cell size (default: `default_cell_size` of all
    the triangles' boxes). static (n_bodies,) bool: bodies that never move; two of them are
    never paired. `run(rotation, translation)` finds every intersecting pair of triangles
    of different bodies, not both static, at those poses into `self.contacts` (pairs as
    global triangle indices over the meshes in order, the lower body first), as
    `CollisionPipeline.run` finds them on the posed vertices. Buffers grow on overflow.
    """

    def __init__(self, meshes, cell_size: float | None = None, static=None):
        runtime.ensure_init()
        real = runtime.real_dtype()
        checked = [check_mesh(k, mesh) for k, mesh in enumerate(meshes)]
        vertices = [v.astype(np.float64) for v, _ in checked]
        faces = [f.astype(np.int64) for _, f in checked]
        self.n_bodies = n_bodies = len(meshes)
        vert_offset = np.cumsum([0] + [len(v) for v in vertices])
        self.tri_offset = np.cumsum([0] + [len(f) for f in faces])
        x = np.concatenate(vertices).astype(real) if vertices else np.zeros((0, 3), real)
        tri_indices = (np.concatenate([f + o for f, o in zip(faces, vert_offset)]) if faces
                       else np.zeros((0, 3), np.int64))
        tri_body = np.repeat(np.arange(n_bodies), np.diff(self.tri_offset))
        self.n_tris = m = len(tri_indices)
        corners = x[tri_indices] if m else np.zeros((0, 3, 3), real)
        lo, hi = corners.min(axis=1), corners.max(axis=1)
        extent = (hi - lo).max(axis=1)
        if cell_size is None:
            cell_size = default_cell_size(extent)
        if not (np.isfinite(cell_size) and cell_size > 0):
            raise ValueError(f"cell_size must be a positive finite length, got {cell_size}")
        self.cell_size = float(cell_size)
        pad = (BOX_SLACK * runtime.tolerance() * extent)[:, None]
        lo, hi = lo - pad, hi + pad
        self.grid = LocalGrid(lo, hi, tri_body, n_bodies, self.cell_size)
        self.occupancy = Occupancy(lo, hi, tri_body, n_bodies, self.cell_size)
        self.slab_normal, self.slab_range = cell_slabs(self.grid, x.astype(np.float64), tri_indices, pad[:, 0])

        # Clusters: the triangles whose box centres share a cell at CLUSTER_LEVEL.
        cluster_cell = np.floor(0.5 * (lo + hi) / (self.cell_size * 2.0 ** CLUSTER_LEVEL)).astype(np.int64)
        order = np.lexsort((cluster_cell[:, 2], cluster_cell[:, 1], cluster_cell[:, 0], tri_body))
        ordered = np.column_stack([tri_body[order], cluster_cell[order]])
        new = np.ones(m, bool)
        new[1:] = np.any(ordered[1:] != ordered[:-1], axis=1)
        first = np.flatnonzero(new)
        vec = ti.types.vector(3, runtime.real_type())
        self.vert_local = to_ndarray(vec, x)
        self.tri = to_ndarray(ivec5, np.column_stack([tri_indices, tri_body, self.grid.level]).astype(np.int32))
        self.cluster_tris = to_ndarray(ti.i32, order.astype(np.int32))
        self.cluster_start = to_ndarray(ti.i32, np.append(first, m).astype(np.int32))
        self.cluster_box = to_ndarray(vec, np.stack([np.minimum.reduceat(lo[order], first) if m else lo,
                                                 np.maximum.reduceat(hi[order], first) if m else hi], axis=1))
        self.cluster_level = to_ndarray(ti.i32, np.minimum.reduceat(self.grid.level[order], first) if m else [0])
        cluster_body = tri_body[order][first]
        self.body_clusters = to_ndarray(ti.i32, np.searchsorted(cluster_body, np.arange(n_bodies + 1)).astype(np.int32))
        # Each body's box in its frame and the largest coordinate of its vertices.
        body_lo = np.zeros((n_bodies, 3))
        body_hi = np.zeros((n_bodies, 3))
        reach = np.zeros(n_bodies)
        for k in range(n_bodies):
            mine = tri_body == k
            if mine.any():
                body_lo[k], body_hi[k] = lo[mine].min(axis=0), hi[mine].max(axis=0)
                reach[k] = np.abs(corners[mine]).max()
            else:  # no triangles: a box that meets nothing
                body_lo[k], body_hi[k] = np.inf, -np.inf
        self.body_box = to_ndarray(vec, np.stack([body_lo, body_hi], axis=1))
        self.body_reach = to_ndarray(runtime.real_type(), reach)
        flags = np.zeros(n_bodies, bool) if static is None else np.asarray(static, dtype=bool).ravel()
        if len(flags) != n_bodies:
            raise ValueError(f"static needs one flag per body ({n_bodies}), got {len(flags)}")
        self.body_static = to_ndarray(ti.i32, flags.astype(np.int32))
        self.world_box = ti.ndarray(vec, shape=(max(n_bodies, 1), 2))
        # The poses, written in place by `run`: the kernel reads this array's memory.
        self.poses = np.zeros((max(n_bodies, 1), 4, 3), real)
        self.counts = ti.ndarray(ti.i32, shape=8)
        self._allocate_directions(max(2, min(n_bodies * (n_bodies - 1), 1024)))
        self.query = ti.ndarray(ivec2, shape=max(1024, m // 4))
        # Candidate pairs: `room` slots for each chunk of SPREAD_CHUNK kept triangles.
        self.room = 64
        self._allocate_pairs()
        self.contacts = Contacts(max(1024, m // 64))
        self._launch = Launcher()

    def _allocate_pairs(self) -> None:
        chunks = -(-self.query.shape[0] // SPREAD_CHUNK)
        self.chunk_found = ti.ndarray(ti.i32, shape=chunks)
        self.pairs = ti.ndarray(ivec2, shape=chunks * self.room)

    def _allocate_directions(self, capacity: int) -> None:
        vec = ti.types.vector(3, runtime.real_type())
        self.dir_info = ti.ndarray(ivec5, shape=capacity)
        self.dir_rot = ti.ndarray(mat3, shape=capacity)
        self.dir_shift = ti.ndarray(vec, shape=capacity)
        self.dir_pad = ti.ndarray(runtime.real_type(), shape=capacity)

    def run(self, rotation, translation) -> int:
        """Every intersecting triangle pair of different bodies at the poses rotation
        (n_bodies, 3, 3) and translation (n_bodies, 3) (world = rotation @ local +
        translation, scene units) into `self.contacts`; returns their number."""
        rotation = np.asarray(rotation, dtype=np.float64)
        translation = np.asarray(translation, dtype=np.float64)
        if rotation.shape != (self.n_bodies, 3, 3) or translation.shape != (self.n_bodies, 3):
            raise ValueError(f"poses of {self.n_bodies} bodies need rotation ({self.n_bodies}, 3, 3) and translation "
                             f"({self.n_bodies}, 3), got {rotation.shape} and {translation.shape}")
        bad = np.flatnonzero(~(np.isfinite(rotation).all(axis=(1, 2)) & np.isfinite(translation).all(axis=1)))
        if len(bad):
            raise ValueError(f"body {bad[0]}'s pose has a NaN or infinite entry")
        if self.n_bodies == 0:
            self.contacts.count = 0
            return 0
        self.poses[:, :3, :] = rotation
        self.poses[:, 3, :] = translation
        c = self.contacts
        while True:
            n = self._launch(_rigid_query, self.poses, self.body_box, self.body_reach, self.body_static,
                             self.body_clusters,
                             self.vert_local, self.tri, self.cluster_tris, self.cluster_start, self.cluster_box,
                             self.cluster_level,
                             *self.grid.arrays(), self.grid.cell_items, self.grid.entry_box,
                             self.slab_normal, self.slab_range,
                             self.grid.body_levels, self.occupancy.origin, self.occupancy.inv_cell,
                             self.occupancy.dims, self.occupancy.offset, self.occupancy.table, self.world_box,
                             self.dir_info, self.dir_rot, self.dir_shift, self.dir_pad, self.query, self.pairs,
                             self.chunk_found, c.pair, c.depth, c.normal, c.side, c.point, self.counts, self.room,
                             1.0 / self.cell_size,
                             runtime.serial_loops(self.n_tris))
            if 0 <= n <= c.capacity:
                break
            if n > c.capacity:
                c.grow(n)
                continue
            counts = self.counts.to_numpy()
            if counts[N_DIR] > self.dir_info.shape[0]:
                self._allocate_directions(int(counts[N_DIR]))
            elif counts[N_KEPT] > self.query.shape[0]:
                self.query = ti.ndarray(ivec2, shape=max(int(counts[N_KEPT]), 2 * self.query.shape[0]))
                self._allocate_pairs()
            else:
                self.room = max(int(counts[N_ROOM]), 2 * self.room)
                self._allocate_pairs()
        c.count = n
        return n

    def candidates(self) -> tuple[int, int]:
        """(triangles kept by the clusters' test, candidate pairs) of the last query."""
        counts = self.counts.to_numpy()
        return int(counts[N_KEPT]), int(counts[N_PAIRS])
