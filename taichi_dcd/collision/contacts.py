"""Per-query contact buffer: the intersecting triangle pairs and their constraints.

This is what the solver consumes. Rows [0, count) are valid; the buffer has a
fixed capacity, and whoever fills it grows it and runs again on overflow.
"""

from dataclasses import dataclass

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


class _GrowableBuffer:
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


class Contacts(_GrowableBuffer):
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


class ContactConstraints(_GrowableBuffer):
    """The solver's contact constraints of one substep (Taichi ndarrays, fixed capacity).

    Row k ties a point of the moved triangle `tri[k][0]` (barycentric weights
    `bary_moved[k]`) to a point of the other triangle `tri[k][1]` (`bary_other[k]`);
    `tri[k][2]` is the row before it with a moved triangle of the same body (-1: none);
    the moved point is pushed along the unit `normal[k]` until it reaches the other
    point's plane. `budget[k]` is how much more of C (m) it may correct this substep (see
    solver.DEPENETRATION_SPEED); on a row with a soft body it is instead the depth (m) the
    row may leave (a soft body's own constraints move the anchors back and forth between
    sweeps, so a spent budget would stop the row halfway), `lambda_n[k]` the
    normal multiplier accumulated this substep (kg·m), `lambda_t[k]` the static-friction one
    (vec3 in the tangent plane, kg·m: corrections that point different ways partly cancel), `vn0[k]`
    the relative normal velocity before the solve (m/s, for restitution),
    `impulse_t[k]` the dynamic-friction impulse accumulated by the velocity pass (kg·m/s);
    `block_*` the linearisation of a rigid body's row (solver.solve_blocks):
    its lever from the (moved) body's centre (m), tangential slip (m), gap (m) and 3×3 inverse
    mass (the two bodies' summed for a row between rigid bodies);
    `block_rows` the indices of those rows.
    """

    def _allocate(self, capacity: int) -> None:
        real = runtime.real_type()
        vec3 = ti.types.vector(3, real)
        self.tri = ti.ndarray(ivec3, shape=capacity)
        self.bary_moved = ti.ndarray(vec3, shape=capacity)
        self.bary_other = ti.ndarray(vec3, shape=capacity)
        self.normal = ti.ndarray(vec3, shape=capacity)
        self.budget = ti.ndarray(real, shape=capacity)
        self.lambda_n = ti.ndarray(real, shape=capacity)
        self.lambda_t = ti.ndarray(vec3, shape=capacity)
        self.vn0 = ti.ndarray(real, shape=capacity)
        self.impulse_t = ti.ndarray(vec3, shape=capacity)
        self.block_lever = ti.ndarray(vec3, shape=capacity)
        self.block_slip = ti.ndarray(vec3, shape=capacity)
        self.block_gap = ti.ndarray(real, shape=capacity)
        self.block_k = ti.ndarray(ti.types.matrix(3, 3, real), shape=capacity)
        self.block_rows = ti.ndarray(ti.i32, shape=capacity)

    def arrays(self) -> tuple:
        """The ndarrays in the order the solver's kernels take them."""
        return (self.tri, self.bary_moved, self.bary_other, self.normal, self.budget,
                self.lambda_n, self.lambda_t, self.vn0, self.impulse_t,
                self.block_lever, self.block_slip, self.block_gap, self.block_k, self.block_rows)
