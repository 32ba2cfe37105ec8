"""Per-query contact buffer: the intersecting triangle pairs and their constraints.

This is what the solver consumes. Rows [0, count) are valid; the buffer has a
fixed capacity, and whoever fills it grows it and runs again on overflow.
"""

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import taichi as ti

from ..core import runtime

ivec2 = ti.types.vector(2, ti.i32)
ivec3 = ti.types.vector(3, ti.i32)


@dataclass
class ContactArrays:
    """Contacts as numpy arrays, one row per intersecting triangle pair.

    pair (n, 2) int — global triangle indices (a, b), the body of a before that of b;
    depth (n,) — the constraint C (scene units), 0 where there is none; normal (n, 3)
    — unit push direction of the moved triangle; side (n,) int8 — 0 if a moves, 1 if
    b moves, -1 if no constraint; point (n, 3) — deepest candidate point of the moved
    triangle.
    """

    pair: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    side: np.ndarray
    point: np.ndarray

    def __len__(self) -> int:
        return len(self.depth)


class GrowableBuffer:
    """Taichi ndarrays of `capacity` rows, allocated by the subclass's `_allocate`."""

    def __init__(self, capacity: int = 1024):
        if capacity < 1:
            raise ValueError(f"contact capacity must be at least 1, got {capacity}")
        runtime.ensure_init()
        self._resize(capacity)

    def _resize(self, capacity: int) -> None:
        self.capacity = capacity
        self._allocate(capacity)

    def grow(self, needed: int) -> None:
        """Reallocate for at least `needed` rows (contents are lost: run the query or frame again)."""
        self._resize(max(needed, 2 * self.capacity))


class Contacts(GrowableBuffer):
    """Fixed-capacity contact buffer (Taichi ndarrays) with a counter."""

    def __init__(self, capacity: int = 1024):
        super().__init__(capacity)
        self.count = 0

    def _allocate(self, capacity: int) -> None:
        real = runtime.real_type()
        vec3 = ti.types.vector(3, real)
        self.pair = ti.ndarray(ivec2, shape=capacity)
        self.depth = ti.ndarray(real, shape=capacity)
        self.normal = ti.ndarray(vec3, shape=capacity)
        self.side = ti.ndarray(ti.i8, shape=capacity)
        self.point = ti.ndarray(vec3, shape=capacity)
        self.counter = ti.ndarray(ti.i32, shape=1)

    def to_numpy(self) -> ContactArrays:
        n = self.count
        return ContactArrays(
            pair=self.pair.to_numpy()[:n],
            depth=self.depth.to_numpy()[:n],
            normal=self.normal.to_numpy()[:n],
            side=self.side.to_numpy()[:n],
            point=self.point.to_numpy()[:n],
        )


class PairResults(NamedTuple):
    """The narrow phase's results for candidate pairs inside a kernel, from a Contacts buffer's
    arrays: pair[k] (ivec2), side[k] (int8), depth[k], normal[k], point[k] as in ContactArrays.
    Build it in the kernel as `ti.static(PairResults(...))` (see contact.rows.ContactRows)."""

    pair: Any
    side: Any
    depth: Any
    normal: Any
    point: Any


@ti.func
def write_contact(rows: ti.template(), slot: ti.i32, ab, depth, normal, side, point):
    """Write one row of a contact buffer's arrays, rows = ti.static((pair, depth, normal, side,
    point)), at `slot`; past the capacity nothing is written (the caller grows the buffer and
    runs again)."""
    if slot < rows[1].shape[0]:
        rows[0][slot] = ab
        rows[1][slot] = depth
        rows[2][slot] = normal
        rows[3][slot] = ti.cast(side, ti.i8)
        rows[4][slot] = point


@ti.func
def append_contact(rows: ti.template(), counter: ti.template(), counter_slot: ti.template(), ab, depth, normal, side,
                   point):
    """Append one row to a contact buffer's arrays (as write_contact) at the slot
    counter[counter_slot] hands out (atomically); past the capacity the row is counted but not
    written."""
    write_contact(rows, ti.atomic_add(counter[counter_slot], 1), ab, depth, normal, side, point)
