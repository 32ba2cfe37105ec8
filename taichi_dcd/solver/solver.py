"""XPBD time stepping of rigid, soft and static bodies with the unified triangle-pair
contacts . XPBDSolver only sequences kernels; each physical step is a `ti.func`
over one body, particle, constraint or contact row, in the modules of solver/ and contact/.

One substep of length h:
1. predict: v += h·(g + F/m), x_prev = x, x += h·v; ω += h·I⁻¹(−ω × Iω), q += h/2·[ω,0]⊗q;
2. contacts: every intersecting triangle pair of different bodies (not both static)
   gives C, the push normal N and the deepest point of the moved triangle
   (Kikuchi & Kanai Eq. 6); the constraint ties that point to the point C·N
   further on, which lies on the other triangle, both kept as barycentric anchors;
3. `iterations` Gauss-Seidel sweeps: soft edges and volumes (XPBD), contact normals
   (C = N·(p_other − p_moved) ≥ 0 with generalised inverse masses), then static friction
   as a positional constraint on the slip the normals left (Müller et al. 2020 §3.5);
4. velocities v = (x − x_prev)/h, ω from q ⊗ q_prev⁻¹;
5. `iterations` sweeps of the velocity pass per active contact: restitution and dynamic
   friction (Müller 2020 §3.6, with accumulated, Coulomb-clamped friction impulses).

Contacts are projected serially (Gauss-Seidel), which is race-free and stays stable
with hundreds of contacts on one body; on the grid path the islands of touching rigid
bodies, which share no body, are solved side by side on several threads, to the same bits.
Velocities are staggered half a substep (leapfrog): the very first predict of a run adds
only h/2·a, so free flight under constant acceleration reproduces x0 + v0·t + a·t²/2
exactly, not with the O(h) error of symplectic Euler.

Small scenes run a whole frame (all its substeps) in one kernel with an in-kernel
all-pairs box test; large ones use the uniform-grid `CollisionPipeline` each substep.
"""

import os
import time

import numpy as np
import taichi as ti

from ..collision.pipeline import CollisionPipeline
from ..contact.cloth import CLOTH_GAP_FRACTION
from ..contact.rows import ContactConstraints
from ..contact.rules import ContactRules
from ..contact.soft_rows import RESTING_ROWS_PER_SOFT_VERTEX
from ..contact.vertex_rows import VERTEX_ROWS_PER_PAIR, VERTEX_ROWS_PER_PAIR_SOFT
from ..core import runtime
from ..core.launch import Launcher
from ..core.model import RIGID, STATIC, Model, State
from .fields import solver_fields
from .kernels import (
    OVERFLOW,
    begin_substep,
    copy_prev_positions,
    end_substep,
    frames_all_pairs,
    rows_at_state_kernel,
    summarize_kernel,
)
from .tunnelling import MAX_SUBSTEP_FACTOR


# Above this many triangle pairs between body boxes (summed over body pairs, upper
# bound) a substep uses the uniform grid instead of the in-kernel all-pairs test.
BRUTE_FORCE_MAX_PAIRS = 200_000
# The grid path bins moving boxes inflated by this fraction of a grid cell and reuses the
# candidate pairs until a vertex has moved that far (the contacts are exact either way).
# On the pile (benchmarks/large_scenes.py, first second) 0.1 took 50 s per simulated
# second, 0.25 60 s, 0.5 74 s (more candidates for the narrow phase), 0 (rebin every
# substep) 177 s.
GRID_SKIN = 0.1
# Depth a contact did not make during its own substep (older penetration, or a depth
# measured along a poor normal at a degenerate feature) is undone at most this fast (m/s,
# times √length_scale: motions of a scene scaled by L are √L as fast): pushing it out in
# one substep turns it into a launch velocity of depth/h.
DEPENETRATION_SPEED = 0.2
# A body has exploded when it moves more than this many scene sizes (the diagonal of the
# box around every body at the start) in one frame, and has left the scene when it is this many
# sizes from the start box's centre. Judged by motion, not by absolute coordinates: a scene
# placed at x = 1e9 m is not an explosion.
EXPLOSION_SIZES_PER_FRAME = 100.0
LEFT_SCENE_SIZES = 1e6
# ... but no speed below this (m/s, times √length_scale) counts as an explosion, so that a lone
# small body may fall for as long as a scene runs (a fall from 5 km ends at ~310 m/s).
EXPLOSION_SPEED_FLOOR = 1e4


class SimulationError(RuntimeError):
    """The simulation produced NaN, a body exploded or left the scene; the message names the body."""


def several_threads() -> bool:
    """Whether Taichi runs parallel loops on more than one thread (a GPU does)."""
    settings = runtime.settings()
    if settings["arch"] != "cpu":
        return True
    return (settings["cpu_threads"] or os.cpu_count() or 1) > 1


def sheet_gaps(m: Model) -> np.ndarray:
    """(T,) the gap (m) each cloth triangle keeps from other cloth triangles
    (contact.cloth.CLOTH_GAP_FRACTION of its sheet's spacing), 0 for the others."""
    return np.repeat([CLOTH_GAP_FRACTION * b.thickness if b.kind == "cloth" else 0.0 for b in m.bodies],
                     [b.tri_count for b in m.bodies])


def self_gaps(m: Model) -> np.ndarray:
    """(T,) the gap (m) each triangle keeps from the other triangles of its own body
    (BodyInfo.self_gap: closed soft bodies with self_collision), 0 for the others."""
    return np.repeat([b.self_gap for b in m.bodies], [b.tri_count for b in m.bodies])


class XPBDSolver:
    """Advances a State of a Model by frames of `substeps` XPBD substeps.

    gravity: m/s² (3,). broad_phase: "auto" (all-pairs in one kernel per frame for
    small scenes, the uniform grid per substep for large ones), "brute" or "grid".
    contact_capacity: initial size of the contact buffer; it grows when a frame
    overflows it (the frame is then rerun from its start, so no contact is lost).
    length_scale: the scene's size relative to metre-sized bodies (SimConfig.length_scale);
    the depenetration speed scales with its square root. rules: the contact rules compiled
    in (contact.rules.ContactRules; all by default). bound: how far (m) from the centre of the
    bodies' start box a body may go before it counts as having left the scene (default
    LEFT_SCENE_SIZES scene sizes). sleep_time: s an island of rigid bodies must stay slower than
    sleep_speed (m/s, at every point) to fall asleep (solver.sleep); 0 (default): never.
    sweep_stats: count the block solves' inner sweeps (`sweep_stats()`; a kernel variant of its
    own, for benchmarks and studies).
    """

    def __init__(self, model: Model, state: State, gravity=(0.0, -9.8, 0.0), broad_phase: str = "auto",
                 contact_capacity: int | None = None, bound: float | None = None, length_scale: float = 1.0,
                 rules: ContactRules | None = None, sleep_speed: float = 0.0, sleep_time: float = 0.0,
                 sweep_stats: bool = False):
        runtime.ensure_init()
        self.model = model
        self.state = state
        self.gravity = np.asarray(gravity, dtype=np.float64).reshape(3)
        x0 = state.vertex_x.to_numpy()[: model.n_vertices].astype(np.float64)
        lo, hi = (x0.min(axis=0), x0.max(axis=0)) if len(x0) else (np.zeros(3), np.zeros(3))
        self.scene_centre = 0.5 * (lo + hi)
        self.scene_size = float(np.linalg.norm(hi - lo)) or 1.0
        self.bound = float(bound) if bound is not None else LEFT_SCENE_SIZES * self.scene_size
        self.depenetration_speed = DEPENETRATION_SPEED * float(np.sqrt(length_scale))
        self.speed_floor = EXPLOSION_SPEED_FLOOR * float(np.sqrt(length_scale))
        m = model
        kind = m.body_kind_np
        tri_counts = np.array([b.tri_count for b in m.bodies])
        moving = kind != STATIC
        pairs_upper = sum(int(tri_counts[a] * tri_counts[b]) for a in range(m.n_bodies)
                          for b in range(a + 1, m.n_bodies) if moving[a] or moving[b])
        if broad_phase not in ("auto", "brute", "grid"):
            raise ValueError(f"unknown broad_phase {broad_phase!r}: auto, brute or grid")
        body_self = np.array([b.self_collision for b in m.bodies], bool)
        pairs_upper += sum(int(tri_counts[b]) * (int(tri_counts[b]) - 1) // 2 for b in np.flatnonzero(body_self))
        self.use_grid = broad_phase == "grid" or (broad_phase == "auto" and pairs_upper > BRUTE_FORCE_MAX_PAIRS)
        self.contacts = ContactConstraints(contact_capacity or max(1024, 4 * m.n_tris))
        self.contact_growths = 0
        self.sim = solver_fields(model, state, rules, count_sweeps=sweep_stats)
        if sweep_stats:
            self.reset_sweep_stats()
        self.sim.sleep_speed[0] = float(sleep_speed)
        self.sim.sleep_time[0] = float(sleep_time)
        self.vertex_prev_nd = None
        if self.use_grid:
            tri_static = kind[m.tri_body_np] == STATIC
            self.pipeline = CollisionPipeline(m.tri_indices_np, m.tri_body_np, tri_static,
                                              pair_capacity=max(1024, 4 * m.n_tris),
                                              contact_capacity=max(1024, m.n_tris), skin=GRID_SKIN,
                                              margin=float(self.sim.box_margin_np.max(initial=0.0)),
                                              keep_touching=True, keep_pressed=m.has_soft,
                                              tri_hidden=m.tri_hidden_np, body_self=body_self,
                                              tri_sheet_gap=sheet_gaps(m) if m.has_cloth else None,
                                              tri_self_gap=self_gaps(m) if m.has_self_gap else None)
            self.vertex_nd = ti.ndarray(ti.types.vector(3, runtime.real_type()), shape=max(m.n_vertices, 1))
            # A cloth's triangles face each other as they were at the substep's start.
            self.vertex_prev_nd = (ti.ndarray(ti.types.vector(3, runtime.real_type()), shape=max(m.n_vertices, 1))
                                   if m.has_cloth else None)
        self.thinnest = min(min(b.thickness for b in m.bodies), 1e30)
        self.soft_vertex_count = int(sum(b.vertex_count for b in m.bodies if b.deformable))
        self.last_contact_count = 0
        # The grid path solves the islands of rigid bodies side by side where there can be
        # several, every row is theirs (no soft body) and threads share them (the same bits
        # as one after another).
        self.parallel_islands = (self.use_grid and not m.has_soft and int((kind == RIGID).sum()) >= 2
                                 and several_threads())
        # Loops over every vertex or body outside the solve: one thread on the CPU below
        # runtime.PARALLEL_MIN_WORK, shared on a GPU.
        self.serial_vertex_loops = runtime.serial_loops(m.n_vertices)
        self.launch = Launcher()
        self.centre_vec = ti.Vector(list(self.scene_centre))
        self.gravity_vec = ti.Vector(list(self.gravity))
        # The last step_frames call's frames that ran more substeps than asked, and the most
        # a frame ran (choose_substeps).
        self.more_substeps = (0, 0)
        # Set to a dict to have the grid path add up the wall seconds of its phases
        # ("predict", "broad", "narrow", "projection"); costs a sync per phase.
        self.phase_seconds: dict | None = None

    # ----------------------------------------------------------------- python
    def reset_sweep_stats(self) -> None:
        """Start counting the block solves' sweeps afresh (with sweep_stats on)."""
        self.sim.sweep_stats.fill(0)

    def sweep_stats(self) -> dict:
        """The block solves since the last reset (with sweep_stats on), for lone rigid bodies
        ("lone") and for islands of several ("coupled"): each a dict of `solves`, the mean
        `normal_sweeps` and `friction_sweeps` a solve ran, and the share of the solves whose
        normal or friction phase ran all its sweeps (`normal_at_cap`, `friction_at_cap`;
        islands.BLOCK_SWEEPS and COUPLED_SWEEPS are the caps), and the mean `rows` a solve
        projects in each sweep (a sweep's cost)."""
        if not self.sim.count_sweeps:
            raise RuntimeError("sweep statistics are off: make the solver with sweep_stats=True")
        counts = self.sim.sweep_stats.to_numpy()[0]
        out = {}
        for name, part in (("lone", counts[0:6]), ("coupled", counts[6:12])):
            solves = int(part[0])
            per = max(solves, 1)
            out[name] = {"solves": solves, "normal_sweeps": float(part[1]) / per,
                         "friction_sweeps": float(part[2]) / per, "normal_at_cap": float(part[3]) / per,
                         "friction_at_cap": float(part[4]) / per, "rows": float(part[5]) / per}
        return out

    def contact_rows(self, h: float) -> dict:
        """The contact rows the rules write for the current state, as a substep of length h (s)
        would before solving them (all-pairs broad phase; the carried rows of the last substep
        included). For inspection and tests: it replaces the last substep's rows. Returns numpy
        arrays: moved_tri, other_tri (n,); point, target (n, 3) m, the moved and the other
        triangle's anchor in world space; normal (n, 3), the unit direction the moved point is
        pushed; depth (n,) m, normal·(target − point)."""
        while True:
            needed, n = (int(v) for v in rows_at_state_kernel(self.sim, self.depenetration_speed * h, *self.contacts.arrays()))
            if needed <= self.contacts.capacity:
                break
            self.contacts.grow(needed)
        return self.rows_numpy(n)

    def rows_numpy(self, n: int) -> dict:
        """The first n contact rows now in the buffer, at the current vertices (contact_rows)."""
        c = self.contacts
        tri = c.tri.to_numpy()[:n]
        x = self.state.vertex_x.to_numpy()[: self.model.n_vertices].astype(np.float64)
        corners = x[self.model.tri_indices_np]
        point = np.einsum("nk,nkd->nd", c.bary_moved.to_numpy()[:n].astype(np.float64), corners[tri[:, 0]])
        target = np.einsum("nk,nkd->nd", c.bary_other.to_numpy()[:n].astype(np.float64), corners[tri[:, 1]])
        normal = c.normal.to_numpy()[:n].astype(np.float64)
        return {"moved_tri": tri[:, 0], "other_tri": tri[:, 1], "point": point, "target": target, "normal": normal,
                "depth": np.einsum("nd,nd->n", normal, target - point)}

    def asleep_numpy(self) -> np.ndarray:
        """(B,) bool: which bodies are asleep (solver.sleep)."""
        return self.sim.body_asleep.to_numpy()[: self.model.n_bodies] == 1

    def body_summary_numpy(self) -> np.ndarray:
        """(B, 10) float64: per body velocity (3), motion about it (1: |ω| rigid, particle speed
        soft), vertex box low (3) and high (3), at the current state."""
        summarize_kernel(self.sim)
        return self.sim.body_summary.to_numpy()[: self.model.n_bodies].astype(np.float64)

    def step_frame(self, frame_dt: float, substeps: int, iterations: int,
                   max_impact_motion: float | None = None) -> int | None:
        """Advance the state by frame_dt seconds in `substeps` substeps of `iterations`
        Gauss-Seidel sweeps. Returns the contact count of the last substep. Raises
        SimulationError (naming the body) on NaN, explosion or a body that left the scene.

        With max_impact_motion (m), the frame first checks that `substeps` are enough by the
        rules of Scene._substeps_for_next_frame and returns None, the state untouched, if
        they are not (or if it cannot check: the grid path); the caller then chooses the
        substeps and steps again. On the all-pairs path the check runs inside the frame's
        one launch, so that an ordinary frame costs no reading back of the state."""
        done, count = self.step_frames(1, frame_dt, substeps, iterations, max_impact_motion)
        return count if done else None

    def step_frames(self, frames: int, frame_dt: float, substeps: int, iterations: int,
                    max_impact_motion: float | None = None, choose_substeps: bool = False) -> tuple[int, int]:
        """Up to `frames` frames as `step_frame`, all in one launch on the all-pairs path;
        with max_impact_motion, stops before the first frame whose substeps do not suffice
        (on the grid path: before any), unless `choose_substeps`: then the all-pairs path
        runs such a frame with the substeps Scene._substeps_for_next_frame would choose
        (at most MAX_SUBSTEP_FACTOR times `substeps`; beyond that it stops before it), and
        `more_substeps` says (frames that ran more, the most a frame ran). Returns (frames
        done, contact count of the last substep). Raises SimulationError as step_frame, after
        counting the bad frame."""
        if substeps < 1 or iterations < 1 or not frame_dt > 0:
            raise ValueError("frame_dt, substeps and iterations must be positive")
        h = frame_dt / substeps
        top_speed = max(EXPLOSION_SIZES_PER_FRAME * self.scene_size / frame_dt, self.speed_floor)
        done = 0
        count = self.last_contact_count
        status = 0
        self.more_substeps = (0, 0)
        if self.use_grid:
            if max_impact_motion is not None:
                return 0, count
            for done in range(1, frames + 1):
                first_kick = 0.5 if self.state.substeps_done == 0 else 1.0
                count, status = self._step_grid(h, substeps, iterations, first_kick, top_speed)
                self._frames_advanced(1, frame_dt, substeps, count)
                if status != 0:
                    break
        else:
            check = 0 if max_impact_motion is None else 1
            while done < frames:
                first_kick = 0.5 if self.state.substeps_done == 0 else 1.0
                # Bound (core.launch): Taichi's own argument checks cost ~0.2 ms a launch, as
                # much as a resting body's frame of 12 substeps.
                ran, most, count, status, more, most_substeps, extra = (int(v) for v in self.launch(
                    frames_all_pairs, self.sim, int(frames - done), int(substeps), int(iterations), float(h),
                    self.gravity_vec, float(first_kick), self.centre_vec, float(self.bound), float(top_speed),
                    float(self.depenetration_speed), check, float(max_impact_motion or 0.0), float(self.thinnest),
                    float(frame_dt), int(choose_substeps), int(MAX_SUBSTEP_FACTOR * substeps),
                    *self.contacts.arrays()))
                done += ran
                self._frames_advanced(ran, frame_dt, substeps, count)
                self.state.substeps_done += extra
                self.more_substeps = (self.more_substeps[0] + more, max(self.more_substeps[1], most_substeps))
                if status != OVERFLOW:
                    break
                self.contacts.grow(most)
                self.contact_growths += 1
        if status < 0:
            raise SimulationError(f"{self._failure(-1 - status, top_speed)} by t = {self.state.time:.4g} s")
        return done, count

    def _failure(self, b: int, top_speed: float) -> str:
        """What state_is_sane found wrong with body b, in words."""
        info = self.model.bodies[b]
        if info.kind == "rigid":
            x = self.state.body_x.to_numpy()[b:b + 1].astype(np.float64)
            v = self.state.body_v.to_numpy()[b:b + 1].astype(np.float64)
        else:
            span = slice(info.vertex_start, info.vertex_start + info.vertex_count)
            x = self.state.vertex_x.to_numpy()[span].astype(np.float64)
            v = self.state.vertex_v.to_numpy()[span].astype(np.float64)
        if not (np.isfinite(x).all() and np.isfinite(v).all()):
            return f"body {info.name!r} has a NaN (its state is no longer finite)"
        speed = float(np.linalg.norm(v, axis=1).max())
        if speed > top_speed:
            return (f"body {info.name!r} exploded (it moves at {speed:.2g} m/s, more than "
                    f"{EXPLOSION_SIZES_PER_FRAME:g} scene sizes of {self.scene_size:.3g} m per frame and "
                    f"{self.speed_floor:.2g} m/s)")
        away = float(np.abs(x - self.scene_centre).max())
        return (f"body {info.name!r} left the scene ({away:.3g} m from where the bodies started, more than "
                f"{self.bound:.3g} m)")

    def _frames_advanced(self, frames: int, frame_dt: float, substeps: int, count: int) -> None:
        for _ in range(frames):  # time as a sum of frames, as if stepped one by one
            self.state.frames_done += 1
            self.state.substeps_done += substeps
            self.state.time += frame_dt
            self.last_contact_count = count

    def _step_grid(self, h: float, substeps: int, iterations: int, first_kick: float,
                   top_speed: float) -> tuple[int, int]:
        gravity = ti.Vector(list(self.gravity))
        g_norm = float(np.linalg.norm(self.gravity))
        n = status = 0
        timing = self.phase_seconds
        for sub in range(substeps):
            start = time.perf_counter()
            begin_substep(self.sim, h, gravity, first_kick if sub == 0 else 1.0, self.vertex_nd,
                          self.serial_vertex_loops)
            if timing is not None:
                ti.sync()
                timing["predict"] = timing.get("predict", 0.0) + time.perf_counter() - start
            if self.vertex_prev_nd is not None:
                copy_prev_positions(self.sim, self.vertex_prev_nd)
            self.pipeline.run(self.vertex_nd, timing, self.vertex_prev_nd)
            start = time.perf_counter()
            pc = self.pipeline.contacts
            rows = VERTEX_ROWS_PER_PAIR_SOFT if self.model.has_soft else VERTEX_ROWS_PER_PAIR
            wanted = rows * pc.count + RESTING_ROWS_PER_SOFT_VERTEX * self.soft_vertex_count
            if wanted > self.contacts.capacity:
                self.contacts.grow(wanted)
                self.contact_growths += 1
            n, status = (int(v) for v in self.launch(
                end_substep, self.sim, int(iterations), float(h), float(g_norm), self.centre_vec, float(self.bound),
                float(top_speed), float(self.depenetration_speed), int(pc.count), pc.pair, pc.depth, pc.normal,
                pc.side, pc.point, *self.contacts.arrays(), self.parallel_islands, self.serial_vertex_loops))
            if timing is not None:
                timing["projection"] = timing.get("projection", 0.0) + time.perf_counter() - start
            if status != 0:
                break
        return n, status
