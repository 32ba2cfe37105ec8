"""Cell arithmetic of the broad phase's hierarchical grid: which cell holds a point at a level,
which hash bucket holds a cell, a box's level, and the closed-box overlap test."""

import taichi as ti

from ..core.geometry import vec3

ivec3 = ti.types.vector(3, ti.i32)

LEVELS = 32
# Cell coordinates are clamped to ±2^30 so that they fit an i32; clamping is
# monotonic, so far-away boxes still overlap-test exactly, only less efficiently.
CELL_LIMIT = float(1 << 30)


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
    the cell stored with each entry. (Hashing 4 x 4 x 4 blocks of cells to runs of 64
    buckets, for cache locality, was no faster on the torus benchmark.)
    """
    low = ti.cast(c, ti.i64) & 0x1FFFFF
    key = (low[0] * 73856093 + low[1] * 19349663 + low[2] * 83492791
           + ti.cast(level, ti.i64) * 39916801)
    return ti.cast(key & ti.cast(mask, ti.i64), ti.i32)


@ti.func
def boxes_overlap(lo_a: vec3, hi_a: vec3, lo_b: vec3, hi_b: vec3) -> bool:
    """Closed boxes overlap (touching counts)."""
    return all(lo_a <= hi_b) and all(lo_b <= hi_a)


@ti.func
def level_of(lo: vec3, hi: vec3, inv_h0: float) -> ti.i32:
    """The smallest level whose cells are at least as large as the box's largest extent."""
    extent = (hi - lo).max() * inv_h0
    level = 0
    size = 1.0
    while level < LEVELS - 1 and extent > size:
        level += 1
        size *= 2.0
    return level
