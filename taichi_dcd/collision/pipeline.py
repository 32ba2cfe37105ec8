"""The collision pipeline: broad phase, then the unified narrow phase into a contact buffer.

`CollisionPipeline` allocates once and is run on the current particle positions;
`find_contacts` is the one-call numpy front end for whole meshes.
"""

import time
from dataclasses import dataclass

import numpy as np
import taichi as ti

from ..core import runtime
from .broadphase import UniformGrid, ivec2, ivec5
from .contacts import Contacts, append_contact, write_contact
from ..core.geometry import vec3
from ..core.launch import Launcher
from ..core.scan import block_sums, exclusive_scan
from .narrowphase import collide_triangle_pair, pressed_through, touching_planes
from .two_sided import faced_pair, moved_together


@ti.func
def test_candidate(k: ti.i32, particle_x: ti.template(), tri: ti.template(), pairs: ti.template(),
                   tri_sheet_gap: ti.template(), tri_self_gap: ti.template(), particle_x_prev: ti.template(),
                   keep_touching: ti.template(), keep_pressed: ti.template(), two_sided: ti.template(),
                   self_gaps: ti.template()):
    """The unified DCD test (Eq. 6 and its gradient) on candidate pair k: whether it is kept
    (see _collide_candidates), then the pair and its row (depth, normal, side, point)."""
    ab = pairs[k]
    ia, ib = tri[ab[0]], tri[ab[1]]  # vertex indices first
    a0, a1, a2 = particle_x[ia[0]], particle_x[ia[1]], particle_x[ia[2]]
    b0, b1, b2 = particle_x[ib[0]], particle_x[ib[1]], particle_x[ib[2]]
    if ti.static(two_sided):
        cloth_a, cloth_b = tri_sheet_gap[ab[0]] > 0.0, tri_sheet_gap[ab[1]] > 0.0
        if cloth_a or cloth_b:
            a0, a1, a2, b0, b1, b2 = faced_pair(
                a0, a1, a2, b0, b1, b2,
                particle_x_prev[ia[0]], particle_x_prev[ia[1]], particle_x_prev[ia[2]],
                particle_x_prev[ib[0]], particle_x_prev[ib[1]], particle_x_prev[ib[2]], cloth_a, cloth_b,
                0.5 * (tri_sheet_gap[ab[0]] + tri_sheet_gap[ab[1]]))
    if ti.static(self_gaps):
        if ia[3] == ib[3] and tri_self_gap[ab[0]] > 0.0:
            a0, a1, a2, b0, b1, b2 = moved_together(a0, a1, a2, b0, b1, b2, tri_self_gap[ab[0]])
    hit, depth, normal, side, point = collide_triangle_pair(a0, a1, a2, b0, b1, b2)
    keep = hit
    if ti.static(keep_touching):
        if not hit:
            which, _, _, _ = touching_planes(a0, a1, a2, b0, b1, b2)
            keep = which >= 0
    if ti.static(keep_pressed):
        if not keep:
            a_behind, b_behind, _, _, _ = pressed_through(a0, a1, a2, b0, b1, b2)
            keep = a_behind or b_behind
    return keep, ab, depth, normal, side, point


@ti.kernel
def _collide_candidates(
    particle_x: ti.types.ndarray(dtype=vec3, ndim=1),
    tri: ti.types.ndarray(dtype=ivec5, ndim=1),
    pairs: ti.types.ndarray(dtype=ivec2, ndim=1),
    n_pairs: ti.i32,
    contact_pair: ti.types.ndarray(dtype=ivec2, ndim=1),
    contact_depth: ti.types.ndarray(ndim=1),
    contact_normal: ti.types.ndarray(dtype=vec3, ndim=1),
    contact_side: ti.types.ndarray(ndim=1),
    contact_point: ti.types.ndarray(dtype=vec3, ndim=1),
    contact_count: ti.types.ndarray(dtype=ti.i32, ndim=1),
    tri_sheet_gap: ti.types.ndarray(ndim=1),
    tri_self_gap: ti.types.ndarray(ndim=1),
    particle_x_prev: ti.types.ndarray(dtype=vec3, ndim=1),
    pair_slot: ti.types.ndarray(dtype=ti.i32, ndim=1),
    block_sum: ti.types.ndarray(dtype=ti.i32, ndim=1),
    serial: ti.template(),
    keep_touching: ti.template(),
    keep_pressed: ti.template(),
    two_sided: ti.template(),
    self_gaps: ti.template(),
) -> ti.i32:
    """Unified DCD test (Eq. 6 and its gradient) on each candidate pair; appends the
    intersecting ones (and with keep_touching those it calls touching, with keep_pressed
    those pressed through each other, with side -1) in the pairs' order, and returns how many
    there are (more than the capacity on overflow). With two_sided, a triangle with a gap in tri_sheet_gap
    (m, 0 for one-sided ones) faces the other one of its pair first, and two such triangles are
    moved together by the mean of their gaps (two_sided.faced_pair; particle_x_prev: the
    positions at the substep's start). With self_gaps, two triangles of one body with a gap in
    tri_self_gap (m) are moved together by it (a closed soft body's walls keep it).
    In parallel (not `serial`) each pair's verdict goes to pair_slot (n_pairs + 1 entries),
    is scanned into the rows' slots, and the kept pairs are tested again and written there."""
    rows = ti.static((contact_pair, contact_depth, contact_normal, contact_side, contact_point))
    test_args = ti.static((particle_x, tri, pairs, tri_sheet_gap, tri_self_gap, particle_x_prev, keep_touching,
                           keep_pressed, two_sided, self_gaps))
    contact_count[0] = 0
    if ti.static(serial):
        ti.loop_config(serialize=True)
        for k in range(n_pairs):
            keep, ab, depth, normal, side, point = test_candidate(k, *test_args)
            if keep:
                append_contact(rows, contact_count, 0, ab, depth, normal, side, point)
    else:
        for k in range(n_pairs):
            # Only the verdict is kept (distinct names: Taichi types each on first assignment).
            keep, _ab, _depth, _normal, _side, _point = test_candidate(k, *test_args)
            pair_slot[k] = 1 if keep else 0
        contact_count[0] = exclusive_scan(pair_slot, 0, n_pairs, block_sum, False)
        pair_slot[n_pairs] = contact_count[0]
        for k in range(n_pairs):
            if pair_slot[k + 1] > pair_slot[k]:
                _keep, ab, depth, normal, side, point = test_candidate(k, *test_args)
                write_contact(rows, pair_slot[k], ab, depth, normal, side, point)
    return contact_count[0]


class CollisionPipeline:
    """Broad phase + narrow phase over the triangles of several bodies.

    tri_indices (m, 3), tri_body (m,), tri_static (m,) bool, tri_hidden (m,) bool: as for `UniformGrid`.
    cell_size, margin: the grid's base cell size and box inflation (scene units); skin:
    as for `UniformGrid` (candidate pairs reused while the vertices stay within skin cells
    of where they were binned; the contacts are exact either way). keep_touching: the
    contacts also hold the pairs the narrow phase calls touching (one triangle crossing
    the other's plane, the other only touching this one's; side -1, depth 0), from which
    the solver makes its touching contacts. keep_pressed: likewise the pairs facing each
    other with one triangle wholly behind the other's plane (narrowphase.pressed_through),
    from which the solver makes contacts for soft patches sagged through a face.
    body_self (n_bodies,) bool: bodies whose own triangles collide (as for `UniformGrid`).
    tri_sheet_gap (m,) float: for two-sided (cloth) triangles the gap (m, > 0) two of them
    keep, 0 for the others; each is turned to face the other triangle of its pair
    (collision.two_sided), and `run` then needs the positions at the substep's start too.
    tri_self_gap (m,) float: the gap (m) two triangles of the same body keep from each other
    (a closed soft body's walls), 0 for none; such a pair is tested moved together by it.
    The contacts come out in the candidate pairs' order, on any number of threads and on a GPU
    (a solver needs that: their order is its sweeps' order).
    Buffers start at the given capacities and grow whenever a query overflows them.
    """

    def __init__(self, tri_indices, tri_body, tri_static=None, cell_size: float | None = None,
                 margin: float = 0.0, pair_capacity: int = 1024, contact_capacity: int = 1024,
                 skin: float = 0.0, keep_touching: bool = False, keep_pressed: bool = False, tri_hidden=None,
                 body_self=None, tri_sheet_gap=None, tri_self_gap=None):
        self.self_gaps = tri_self_gap is not None and bool(np.any(np.asarray(tri_self_gap) > 0.0))
        self.tri_self_gap = ti.ndarray(runtime.real_type(), shape=max(len(tri_indices), 1) if self.self_gaps else 1)
        if self.self_gaps:
            self.tri_self_gap.from_numpy(np.asarray(tri_self_gap, runtime.real_dtype()))
        self.two_sided = tri_sheet_gap is not None and bool(np.any(np.asarray(tri_sheet_gap) > 0.0))
        self.tri_sheet_gap = ti.ndarray(runtime.real_type(), shape=max(len(tri_indices), 1) if self.two_sided else 1)
        if self.two_sided:
            self.tri_sheet_gap.from_numpy(np.asarray(tri_sheet_gap, runtime.real_dtype()))
        self.keep_touching = bool(keep_touching)
        self.keep_pressed = bool(keep_pressed)
        self.grid = UniformGrid(tri_indices, tri_body, tri_static, cell_size=cell_size, margin=margin,
                                pair_capacity=pair_capacity, skin=skin, tri_hidden=tri_hidden, body_self=body_self)
        self.contacts = Contacts(contact_capacity)
        # Each candidate's verdict, then its row's slot (a narrow phase shared among threads;
        # grown at the first).
        self.pair_slot = ti.ndarray(ti.i32, shape=1)
        self.block_sum = block_sums()
        self._launch = Launcher()

    def run(self, particle_x, phase_seconds: dict | None = None, particle_x_prev=None) -> int:
        """All intersecting triangle pairs at particle_x (ti.ndarray of vec3, (n_particles,))
        into `self.contacts`; returns their number. `phase_seconds`, if given, gains the
        wall seconds of the "broad" and "narrow" phases. particle_x_prev: the positions at
        the substep's start, needed with two-sided triangles."""
        if self.two_sided and particle_x_prev is None:
            raise ValueError("a pipeline with two-sided triangles needs particle_x_prev")
        start = time.perf_counter()
        n_pairs = self.grid.find_pairs(particle_x)
        if phase_seconds is not None:
            ti.sync()
            middle = time.perf_counter()
            phase_seconds["broad"] = phase_seconds.get("broad", 0.0) + middle - start
        c = self.contacts
        serial = runtime.serial_loops(n_pairs)
        if not serial and self.pair_slot.shape[0] < n_pairs + 1:
            self.pair_slot = ti.ndarray(ti.i32, shape=self.grid.pair_capacity + 1)
        while True:
            n = self._launch(_collide_candidates, particle_x, self.grid.tri, self.grid.pairs, n_pairs,
                             c.pair, c.depth, c.normal, c.side, c.point, c.counter, self.tri_sheet_gap,
                             self.tri_self_gap, particle_x if particle_x_prev is None else particle_x_prev,
                             self.pair_slot, self.block_sum, serial, self.keep_touching,
                             self.keep_pressed, self.two_sided, self.self_gaps)
            if n <= c.capacity:
                break
            c.grow(n)
        c.count = n
        if phase_seconds is not None:
            ti.sync()
            phase_seconds["narrow"] = phase_seconds.get("narrow", 0.0) + time.perf_counter() - middle
        return n


@dataclass
class MeshContacts:
    """Every intersecting triangle pair of different bodies, sorted by (body_a, tri_a, body_b, tri_b).

    body_a < body_b; tri_a, tri_b index the faces of those bodies. hit is True on every
    row; depth, normal, side and point are as in `collide_triangle_pairs` with a = the
    face of body_a (side 0: body_a's triangle moves, along normal).
    """

    body_a: np.ndarray
    tri_a: np.ndarray
    body_b: np.ndarray
    tri_b: np.ndarray
    hit: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    side: np.ndarray
    point: np.ndarray

    def __len__(self) -> int:
        return len(self.depth)


def check_mesh(k: int, mesh) -> tuple[np.ndarray, np.ndarray]:
    try:
        vertices, faces = mesh
    except (TypeError, ValueError):
        raise ValueError(f"mesh {k} must be a (vertices, faces) pair") from None
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or not np.issubdtype(v.dtype, np.number):
        raise ValueError(f"mesh {k}: vertices must be a numeric (n, 3) array, got shape {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"mesh {k}: faces must be an integer (m, 3) array, got shape {f.shape}, dtype {f.dtype}")
    bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
    if len(bad):
        raise ValueError(f"mesh {k}: vertex {bad[0]} has a NaN or infinite coordinate")
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError(f"mesh {k}: face indices must lie in [0, {len(v)}), got {f.min()}..{f.max()}")
    return v, f


def find_contacts(meshes, cell_size: float | None = None) -> MeshContacts:
    """Every intersecting triangle pair between different meshes.

    meshes: a list of (vertices (n_i, 3) float, faces (m_i, 3) int) numpy pairs, one per
    body, in world space; faces give outward normals by the right-hand rule.
    cell_size: base grid cell size (scene units; default: the median triangle size).
    Runs in the precision chosen at `taichi_dcd.init`. Raises ValueError on bad input.
    """
    runtime.ensure_init()
    checked = [check_mesh(k, mesh) for k, mesh in enumerate(meshes)]
    dtype = runtime.real_dtype()
    vert_offset = np.cumsum([0] + [len(v) for v, _ in checked])
    tri_offset = np.cumsum([0] + [len(f) for _, f in checked])
    x = np.concatenate([v for v, _ in checked]).astype(dtype) if checked else np.zeros((0, 3), dtype)
    tri_indices = (np.concatenate([f + o for (_, f), o in zip(checked, vert_offset)]).astype(np.int32)
                   if checked else np.zeros((0, 3), np.int32))
    tri_body = np.repeat(np.arange(len(checked), dtype=np.int32), np.diff(tri_offset))

    pipeline = CollisionPipeline(tri_indices, tri_body, cell_size=cell_size,
                                 pair_capacity=max(1024, 4 * len(tri_indices)))
    particle_x = ti.ndarray(ti.types.vector(3, runtime.real_type()), shape=max(len(x), 1))
    if len(x):
        particle_x.from_numpy(x)
    pipeline.run(particle_x)
    c = pipeline.contacts.to_numpy()
    tri_a, tri_b = c.pair[:, 0].astype(np.int64), c.pair[:, 1].astype(np.int64)
    body_a, body_b = tri_body[tri_a].astype(np.int64), tri_body[tri_b].astype(np.int64)
    local_a, local_b = tri_a - tri_offset[body_a], tri_b - tri_offset[body_b]
    order = np.lexsort((local_b, body_b, local_a, body_a))
    return MeshContacts(
        body_a=body_a[order], tri_a=local_a[order], body_b=body_b[order], tri_b=local_b[order],
        hit=np.ones(len(order), dtype=bool), depth=c.depth[order], normal=c.normal[order],
        side=c.side[order], point=c.point[order])
