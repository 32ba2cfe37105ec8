"""Grids built once, in NumPy, over boxes given in their own body's frame.

A rigid body does not change shape, so its triangles' boxes in its own frame, and the
grids that hold them, are built once and reused by every query (collision/rigid_pipeline.py):

- `LocalGrid`, the broad phase's hierarchical grid (collision/broadphase.py) in a body's
  frame: each box sits at the smallest level whose cell (h·2^level) is at least its largest
  extent and is listed in every cell it covers there; the occupied cells, keyed by (tag,
  cell) with tag = body·LEVELS + level, sit in an open-addressing table, each with its run
  of box indices;
- `Occupancy`, a summed-volume table per body of the cells its boxes cover, which answers
  "does this box come near the body at all" in eight reads;
- `cell_slabs`, for each occupied cell of a `LocalGrid`, the slab between two parallel planes
  that holds all its triangles: a triangle wholly outside a cell's slab meets none of them,
  whatever their boxes say.

A box's cells are computed by the same `ti.func`s the query uses (`cell_of`, `bucket_of`),
so that its cells at build time are its cells at query time to the bit.
"""


import numpy as np
import taichi as ti

from ..core import runtime
from .grid_cells import LEVELS, bucket_of, cell_of, level_inv_h

ivec2 = ti.types.vector(2, ti.i32)
ivec3 = ti.types.vector(3, ti.i32)
ivec4 = ti.types.vector(4, ti.i32)


@ti.kernel
def _cells_of(box_lo: ti.types.ndarray(ndim=2), box_hi: ti.types.ndarray(ndim=2),
              level: ti.types.ndarray(dtype=ti.i32, ndim=1), cell_lo: ti.types.ndarray(dtype=ti.i32, ndim=2),
              cell_hi: ti.types.ndarray(dtype=ti.i32, ndim=2), inv_h0: float):
    """The cells holding each box's corners at its level."""
    for k in range(level.shape[0]):
        inv_h = level_inv_h(inv_h0, level[k])
        lo = ti.Vector([box_lo[k, 0], box_lo[k, 1], box_lo[k, 2]])
        hi = ti.Vector([box_hi[k, 0], box_hi[k, 1], box_hi[k, 2]])
        c0, c1 = cell_of(lo, inv_h), cell_of(hi, inv_h)
        for i in ti.static(range(3)):
            cell_lo[k, i] = c0[i]
            cell_hi[k, i] = c1[i]


def box_levels(lo: np.ndarray, hi: np.ndarray, cell_size: float) -> np.ndarray:
    """Level of each box (n, 3): the smallest l with cell_size·2^l at least its largest extent."""
    extent = (hi - lo).max(axis=1)
    level = np.zeros(len(lo), dtype=np.int32)
    size = np.full(len(lo), cell_size)
    for _ in range(LEVELS - 1):
        over = extent > size
        if not over.any():
            break
        level[over] += 1
        size[over] *= 2.0
    return level


# A body's dense grids (cells by index, LocalGrid; covered cells, Occupancy) have at most this
# many cells per triangle, and may have DENSE_MIN_CELLS in all: their cells double until they fit.
DENSE_CELLS_PER_TRI = 8
DENSE_MIN_CELLS = 4096


def dense_cells_over(lo: np.ndarray, hi: np.ndarray, n_boxes: int, cell_size: float,
                     level: int = 0) -> tuple[int, np.ndarray, np.ndarray]:
    """A dense grid over the box [lo, hi] (3,) holding n_boxes boxes: the lowest level from
    `level` up at which its cells (cell_size·2^level, anchored at the origin) number at most
    DENSE_CELLS_PER_TRI per box (or DENSE_MIN_CELLS), with one cell more each way than the box
    needs (the kernels' rounding may differ from NumPy's). Returns (level, first cell (3,) int,
    cells per axis (3,) int)."""
    budget = max(DENSE_MIN_CELLS, DENSE_CELLS_PER_TRI * n_boxes)
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    while True:
        size = cell_size * 2.0 ** level
        first = np.floor(lo / size).astype(np.int64) - 1
        dims = np.floor(hi / size).astype(np.int64) + 2 - first
        if dims.prod() <= budget or level == LEVELS - 1:
            return level, first, dims
        level += 1


class LocalGrid:
    """A hierarchical grid of boxes over all bodies, each body's in its own frame, built once.

    box_lo, box_hi (n, 3): the boxes (scene units); body (n,) int; cell_size: the base cell
    size h. Each box takes the smallest level whose cells are at least its largest extent
    (`box_levels`), raised to its body's dense level, and is listed in every cell it covers
    at that level. A body's dense level is the lowest at which a dense array of cells over
    its box has at most DENSE_CELLS_PER_TRI cells per triangle: its boxes at that level (most
    of them) are found by index, in memory laid out as space is; boxes at higher levels
    (triangles much larger than the rest) sit in a hash table of cells. Holds, as Taichi
    ndarrays:
    - `dense_origin` (n_bodies,) ivec4: the dense grid's first cell and its level;
      `dense_dims` (n_bodies,) ivec4: its cells per axis and the offset of its first cell
      in `dense_start`, where cell i's run of `cell_items` is [dense_start[i], dense_start[i + 1]);
    - `cell_key` (n_slots,) ivec4 (tag, cell x, y, z), tag = body·LEVELS + level, -1 for an
      empty slot, and `cell_range` (n_slots,) ivec2: the hashed cells (linear probing from
      `bucket_of`), each with its run of `cell_items`;
    - `cell_items` (n_entries,) i32: the boxes of each cell, by index;
    - `entry_box` (n_entries, 2) vec3 in f32: each entry's box, rounded outwards (a box only
      grows, so no pair is lost), beside its entry so that a cell's boxes are read in a row;
    - `body_levels` (n_bodies,) i32: a bit mask of the levels each body's boxes occupy;
    and `level` (n,) as a NumPy array, each box's level.
    """

    def __init__(self, box_lo: np.ndarray, box_hi: np.ndarray, body: np.ndarray, n_bodies: int,
                 cell_size: float):
        real = runtime.real_dtype()
        # Stored in f32 rounded outwards; the cells are those of the stored boxes.
        lo32 = np.nextafter(np.asarray(box_lo).astype(np.float32), np.float32(-np.inf))
        hi32 = np.nextafter(np.asarray(box_hi).astype(np.float32), np.float32(np.inf))
        box_lo = np.ascontiguousarray(lo32, dtype=real)
        box_hi = np.ascontiguousarray(hi32, dtype=real)
        body = np.asarray(body, dtype=np.int64)
        n = len(box_lo)
        level = box_levels(box_lo, box_hi, cell_size)
        dense_origin = np.zeros((max(n_bodies, 1), 4), np.int64)
        dense_dims = np.zeros((max(n_bodies, 1), 4), np.int64)
        total = 0
        for k in range(n_bodies):
            mine = body == k
            if not mine.any():
                dense_origin[k, 3] = LEVELS  # no level: every lookup goes to the hash table
                continue
            dense, first, dims = dense_cells_over(box_lo[mine].min(axis=0), box_hi[mine].max(axis=0),
                                                  int(mine.sum()), cell_size, int(level[mine].min()))
            dense_origin[k] = [*first, dense]
            dense_dims[k] = [*dims, total]
            total += int(dims.prod())
            level[mine] = np.maximum(level[mine], dense)
        if total >= 2**31 - 1:
            raise ValueError("the bodies' dense grids need more than 2^31 cells; give a larger cell_size")
        cell_lo = np.zeros((n, 3), np.int32)
        cell_hi = np.zeros((n, 3), np.int32)
        if n:
            _cells_of(box_lo, box_hi, level, cell_lo, cell_hi, 1.0 / cell_size)
        span = (cell_hi.astype(np.int64) - cell_lo + 1)
        count = span.prod(axis=1)
        item = np.repeat(np.arange(n), count)
        # Position of each entry among its box's cells, unravelled over the box's span.
        rank = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
        sy, sz = span[item, 1], span[item, 2]
        offset = np.column_stack([rank // (sy * sz), (rank // sz) % sy, rank % sz])
        cells = cell_lo[item] + offset
        entry_body = body[item]
        in_dense = level[item] == dense_origin[entry_body, 3]

        # Dense entries, ordered by their cell's index.
        rel = cells[in_dense] - dense_origin[entry_body[in_dense], :3]
        dims = dense_dims[entry_body[in_dense]]
        if np.any(rel < 0) or np.any(rel >= dims[:, :3]):
            raise AssertionError("a box's cells fall outside its body's dense grid")
        index = dims[:, 3] + (rel[:, 0] * dims[:, 1] + rel[:, 1]) * dims[:, 2] + rel[:, 2]
        dense_order = np.lexsort((item[in_dense], index))
        dense_items = item[in_dense][dense_order]
        dense_start = np.searchsorted(index[dense_order], np.arange(total + 1)).astype(np.int32)

        # Hashed entries, grouped by cell, after the dense ones in cell_items.
        h_item, h_cells = item[~in_dense], cells[~in_dense]
        tag = entry_body[~in_dense] * LEVELS + level[h_item]
        order = np.lexsort((h_item, h_cells[:, 2], h_cells[:, 1], h_cells[:, 0], tag))
        key = np.column_stack([tag, h_cells]).astype(np.int32)[order]
        new = np.ones(len(key), bool)
        if len(key):
            new[1:] = np.any(key[1:] != key[:-1], axis=1)
        first = np.flatnonzero(new)
        ends = np.append(first[1:], len(key)) if len(first) else first
        ranges = (np.column_stack([first, ends]) + len(dense_items)).astype(np.int32)
        n_slots = 1 << max(1, int(2 * max(len(first), 1) - 1).bit_length())
        self.cell_key = ti.ndarray(ivec4, shape=n_slots)
        self.cell_range = ti.ndarray(ivec2, shape=n_slots)
        if len(first):
            _insert_cells(key[first], ranges, self.cell_key, self.cell_range)
        else:
            self.cell_key.fill(-1)
        all_items = np.concatenate([dense_items, h_item[order]]).astype(np.int32)
        self.cell_items = to_ndarray(ti.i32, all_items)
        self.dense_start = to_ndarray(ti.i32, dense_start)
        self.dense_origin = to_ndarray(ivec4, dense_origin.astype(np.int32))
        self.dense_dims = to_ndarray(ivec4, dense_dims.astype(np.int32))
        self.entry_box = to_ndarray(ti.types.vector(3, ti.f32), np.stack([lo32, hi32], axis=1)[all_items])
        masks = np.zeros(n_bodies, np.int64)
        np.bitwise_or.at(masks, body, np.int64(1) << level.astype(np.int64))
        self.body_levels = to_ndarray(ti.i32, masks.astype(np.uint32).view(np.int32))
        self.level = level
        self.items = all_items
        # Each occupied cell's run [start, end) of cell_items, in cell_items order.
        dense_runs = np.column_stack([dense_start[:-1], dense_start[1:]])
        runs = np.concatenate([dense_runs[dense_runs[:, 1] > dense_runs[:, 0]], ranges.reshape(-1, 2)])
        self.runs = runs[np.argsort(runs[:, 0], kind="stable")].astype(np.int64)

    def arrays(self) -> tuple:
        """The arrays `cell_run` reads, in its order."""
        return (self.dense_origin, self.dense_dims, self.dense_start, self.cell_key, self.cell_range)


@ti.kernel
def _insert_cells(key: ti.types.ndarray(dtype=ti.i32, ndim=2), ranges: ti.types.ndarray(dtype=ti.i32, ndim=2),
                  cell_key: ti.types.ndarray(dtype=ivec4, ndim=1), cell_range: ti.types.ndarray(dtype=ivec2, ndim=1)):
    """Fill the open-addressing cell table: each cell at its bucket or the next free slot."""
    mask = cell_key.shape[0] - 1
    for s in range(cell_key.shape[0]):
        cell_key[s] = ivec4(-1, 0, 0, 0)
    ti.loop_config(serialize=True)
    for k in range(key.shape[0]):
        slot = bucket_of(key[k, 0], ivec3(key[k, 1], key[k, 2], key[k, 3]), mask)
        while cell_key[slot][0] != -1:
            slot = (slot + 1) & mask
        cell_key[slot] = ivec4(key[k, 0], key[k, 1], key[k, 2], key[k, 3])
        cell_range[slot] = ivec2(ranges[k, 0], ranges[k, 1])


@ti.func
def hashed_run(tag: ti.i32, c: ivec3, cell_key: ti.template(), cell_range: ti.template()) -> ivec2:
    """The run [start, end) of `cell_items` of hashed cell c at tag (body·LEVELS + level), or
    an empty run if no box covers it."""
    mask = cell_key.shape[0] - 1
    slot = bucket_of(tag, c, mask)
    run = ivec2(0, 0)
    while cell_key[slot][0] != -1:
        k = cell_key[slot]
        if k[0] == tag and k[1] == c[0] and k[2] == c[1] and k[3] == c[2]:
            run = cell_range[slot]
            break
        slot = (slot + 1) & mask
    return run


@ti.func
def cell_run(body: ti.i32, level: ti.i32, c: ivec3, grid: ti.template()) -> ivec2:
    """The run [start, end) of `cell_items` of cell c at a level of a body's grid (`LocalGrid`;
    grid: its `arrays()`), from the dense array at the body's dense level, else from the hash
    table; an empty run if no box covers the cell."""
    dense_origin, dense_dims, dense_start, cell_key, cell_range = ti.static(grid)
    origin = dense_origin[body]
    run = ivec2(0, 0)
    if level == origin[3]:
        dims = dense_dims[body]
        r = c - ivec3(origin[0], origin[1], origin[2])
        if r[0] >= 0 and r[1] >= 0 and r[2] >= 0 and r[0] < dims[0] and r[1] < dims[1] and r[2] < dims[2]:
            i = dims[3] + (r[0] * dims[1] + r[1]) * dims[2] + r[2]
            run = ivec2(dense_start[i], dense_start[i + 1])
    else:
        run = hashed_run(body * LEVELS + level, c, cell_key, cell_range)
    return run


def cell_slabs(grid: LocalGrid, vertices: np.ndarray, tri_indices: np.ndarray,
               pad: np.ndarray) -> tuple[ti.Ndarray, ti.Ndarray]:
    """Each occupied cell's slab: a unit normal n (the area-weighted mean of its triangles'
    normals) and the interval [lo, hi] of n·x over its triangles' vertices, widened by the
    largest `pad` (n,) of its triangles (the narrow phase's touching tolerance, as the boxes
    are padded) and rounded outwards to f32. Stored at the position of the cell's first entry
    in `cell_items` (the run start `cell_run` returns): `slab_normal` (n_entries,) vec3 f32,
    `slab_range` (n_entries,) vec2 f32. A cell whose normals cancel (a thin plate's two faces)
    gets the interval (-inf, inf): it turns nothing away.

    vertices (v, 3) float64 in the bodies' own frames; tri_indices (t, 3); pad (t,) scene units."""
    n_entries = max(len(grid.items), 1)
    normal_out = np.zeros((n_entries, 3), np.float32)
    range_out = np.zeros((n_entries, 2), np.float32)
    runs = grid.runs
    if len(runs):
        corners = np.asarray(vertices, np.float64)[np.asarray(tri_indices)]
        cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        items = grid.items
        starts = runs[:, 0]
        summed = np.add.reduceat(cross[items], starts, axis=0)
        spread = np.add.reduceat(np.linalg.norm(cross[items], axis=1), starts)
        length = np.linalg.norm(summed, axis=1)
        # Normals that mostly cancel give a slab as thick as the cell: not worth a test.
        flat = length > 0.5 * spread
        unit = np.where(flat[:, None], summed / np.where(length > 0, length, 1.0)[:, None], 0.0).astype(np.float32)
        run_of = np.repeat(np.arange(len(runs)), runs[:, 1] - runs[:, 0])
        n_entry = unit[run_of].astype(np.float64)
        along = np.einsum("ekd,ed->ek", corners[items], n_entry)
        lo = np.minimum.reduceat(along.min(axis=1) - pad[items], starts)
        hi = np.maximum.reduceat(along.max(axis=1) + pad[items], starts)
        lo32 = np.nextafter(lo.astype(np.float32), np.float32(-np.inf))
        hi32 = np.nextafter(hi.astype(np.float32), np.float32(np.inf))
        lo32[~flat], hi32[~flat] = -np.inf, np.inf
        normal_out[starts] = unit
        range_out[starts, 0], range_out[starts, 1] = lo32, hi32
    return (to_ndarray(ti.types.vector(3, ti.f32), normal_out), to_ndarray(ti.types.vector(2, ti.f32), range_out))


def to_ndarray(dtype, values) -> ti.Ndarray:
    """A Taichi ndarray of `dtype` (a primitive or vector type) holding `values` (rows first;
    at least one row, zeros where values is empty)."""
    values = np.asarray(values)
    rows = max(len(values), 1)
    element = values.shape[1:]
    element_dims = getattr(dtype, "ndim", 0) if hasattr(dtype, "dtype") else 0
    arr = ti.ndarray(dtype, shape=(rows,) + element[: len(element) - element_dims])
    padded = np.zeros((rows,) + element, values.dtype if len(values) else np.float64)
    padded[: len(values)] = values
    base = getattr(dtype, "dtype", dtype)
    arr.from_numpy(padded.astype({ti.i32: np.int32, ti.f32: np.float32, ti.f64: np.float64}[base]))
    return arr


class Occupancy:
    """Which cells of each body's frame its boxes cover, as a summed-volume table: whether a
    box meets any cell covered by the body is then eight reads, whatever the box's size.

    box_lo, box_hi (n, 3), body (n,): boxes in their bodies' frames; cell_size: the smallest
    cell (scene units; a body's cells double until they fit, `dense_cells_over`). A box's
    cells are computed by the kernel arithmetic `box_occupied` uses, so that a query box
    meeting a box always meets one of its cells. Holds per body, as Taichi
    ndarrays: `origin` (vec3), `inv_cell` (real), `dims` (ivec3: cells per axis) and `offset`
    (i32) into `table`, the (dims + 1) table flattened x-major, table[i, j, k] = covered cells
    in [0, i) × [0, j) × [0, k).
    """

    def __init__(self, box_lo: np.ndarray, box_hi: np.ndarray, body: np.ndarray, n_bodies: int,
                 cell_size: float):
        real = runtime.real_dtype()
        box_lo = np.ascontiguousarray(box_lo, dtype=real)
        box_hi = np.ascontiguousarray(box_hi, dtype=real)
        body = np.asarray(body, dtype=np.int64)
        rows = max(n_bodies, 1)
        origins = np.zeros((rows, 3))
        inv_cells = np.ones(rows)
        dims_all = np.zeros((rows, 3), np.int64)
        for k in range(n_bodies):
            mine = body == k
            if not mine.any():
                continue
            level, first, dims = dense_cells_over(box_lo[mine].min(axis=0), box_hi[mine].max(axis=0),
                                                  int(mine.sum()), cell_size)
            size = cell_size * 2.0 ** level
            origins[k], inv_cells[k], dims_all[k] = first * size, 1.0 / size, dims
        vec3 = ti.types.vector(3, runtime.real_type())
        self.origin = to_ndarray(vec3, origins.astype(real))
        self.inv_cell = to_ndarray(runtime.real_type(), inv_cells.astype(real))
        cell_lo = np.zeros((len(box_lo), 3), np.int32)
        cell_hi = np.zeros((len(box_lo), 3), np.int32)
        if len(box_lo):
            _occupancy_cells(box_lo, box_hi, body.astype(np.int32), self.origin, self.inv_cell, cell_lo, cell_hi)
        offsets, tables = [], []
        offset = 0
        for k in range(rows):
            mine = body == k
            dims = dims_all[k]
            if not mine.any():
                offsets.append(offset)
                tables.append(np.zeros(1, np.int32))
                offset += 1
                continue
            c0 = np.clip(cell_lo[mine], 0, dims - 1)
            c1 = np.clip(cell_hi[mine], 0, dims - 1) + 1
            # Box ranges [c0, c1) marked through a difference array, summed along each axis.
            diff = np.zeros(tuple(dims + 1), np.int32)
            for corner in range(8):
                pick = [(corner >> axis) & 1 for axis in range(3)]
                idx = tuple(np.where(pick[axis], c1[:, axis], c0[:, axis]) for axis in range(3))
                np.add.at(diff, idx, -1 if sum(pick) % 2 else 1)
            covered = diff.cumsum(0).cumsum(1).cumsum(2)[:-1, :-1, :-1] > 0
            table = np.zeros(tuple(dims + 1), np.int32)
            table[1:, 1:, 1:] = covered.astype(np.int32).cumsum(0).cumsum(1).cumsum(2)
            offsets.append(offset)
            tables.append(table.ravel())
            offset += table.size
        self.dims = to_ndarray(ivec3, dims_all.astype(np.int32))
        self.offset = to_ndarray(ti.i32, np.array(offsets, np.int32))
        self.table = to_ndarray(ti.i32, np.concatenate(tables))


@ti.func
def occupancy_cell(k: ti.i32, p: ti.template(), origin: ti.template(), inv_cell: ti.template()) -> ivec3:
    """The cell of body k's occupancy grid holding point p (clamped below to -1)."""
    return ti.cast(ti.math.clamp(ti.floor((p - origin[k]) * inv_cell[k]), -1.0, 1e9), ti.i32)


@ti.kernel
def _occupancy_cells(box_lo: ti.types.ndarray(ndim=2), box_hi: ti.types.ndarray(ndim=2),
                     body: ti.types.ndarray(dtype=ti.i32, ndim=1), origin: ti.types.ndarray(ndim=1),
                     inv_cell: ti.types.ndarray(ndim=1), cell_lo: ti.types.ndarray(dtype=ti.i32, ndim=2),
                     cell_hi: ti.types.ndarray(dtype=ti.i32, ndim=2)):
    """The occupancy cells holding each box's corners, as `box_occupied` computes them."""
    for i in range(body.shape[0]):
        lo = ti.Vector([box_lo[i, 0], box_lo[i, 1], box_lo[i, 2]])
        hi = ti.Vector([box_hi[i, 0], box_hi[i, 1], box_hi[i, 2]])
        c0 = occupancy_cell(body[i], lo, origin, inv_cell)
        c1 = occupancy_cell(body[i], hi, origin, inv_cell)
        for j in ti.static(range(3)):
            cell_lo[i, j] = c0[j]
            cell_hi[i, j] = c1[j]


@ti.func
def box_occupied(k: ti.i32, lo: ti.template(), hi: ti.template(), origin: ti.template(), inv_cell: ti.template(),
                 dims: ti.template(), offset: ti.template(), table: ti.template()) -> bool:
    """Whether the box [lo, hi] (body k's frame) meets a cell body k's boxes cover
    (`Occupancy`): the summed-volume table over the box's cells, by inclusion-exclusion."""
    n = dims[k]
    a = ti.max(occupancy_cell(k, lo, origin, inv_cell), 0)
    b = occupancy_cell(k, hi, origin, inv_cell)
    b = ti.min(b, n - 1) + 1
    found = False
    if all(a < b):
        sy, sz = n[1] + 1, n[2] + 1
        base = offset[k]
        total = 0
        for corner in ti.static(range(8)):
            i = b[0] if corner & 1 else a[0]
            j = b[1] if corner & 2 else a[1]
            m = b[2] if corner & 4 else a[2]
            sign = ti.static(-1 if ((corner & 1) + ((corner >> 1) & 1) + ((corner >> 2) & 1)) % 2 == 0 else 1)
            total += sign * table[base + (i * sy + j) * sz + m]
        found = total != 0
    return found
