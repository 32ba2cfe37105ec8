"""A runnable scene: settings, Model, State and solver together, stepped frame by frame.

`load_scene(path)` reads a TOML scene file (docs/scene-format.md); `Scene.from_config` builds
one from a `SceneConfig`. Positions in metres, velocities in m/s, time in seconds.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import trimesh

from ..core import runtime
from .builder import BodySpec, ModelBuilder
from .config import SceneConfig, SceneError, read_scene_file
from ..core.model import RIGID, SOFT, STATIC
from ..measure.penetration import body_pairs, scene_penetration
from ..measure.cloth import poke_depths
from ..measure.self_intersection import self_penetration
from .shapes import make_shape
from ..solver.tunnelling import MAX_SUBSTEP_FACTOR, TUNNEL_FRACTION, substeps_for_impacts, substeps_for_motion


def rotation_matrix(degrees) -> np.ndarray:
    """R = Rz·Ry·Rx for angles (x, y, z) in degrees."""
    ax, ay, az = (math.radians(float(a)) for a in degrees)
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def body_mesh(body, base_dir: Path) -> trimesh.Trimesh:
    """The body's mesh in world space: scaled, rotated about its own origin, then moved."""
    if body.mesh is not None:
        path = (base_dir / body.mesh)
        if not path.is_file():
            raise SceneError(f"body {body.name!r}: mesh file {path} does not exist")
        try:
            mesh = trimesh.load(path, force="mesh", process=False)
        except IndexError as exc:
            raise SceneError(f"body {body.name!r}: mesh file {path}: a face refers to a vertex that does not "
                             f"exist ({exc})") from None
        except Exception as exc:  # trimesh raises many types for unparsable files
            raise SceneError(f"body {body.name!r}: cannot read mesh file {path} ({exc})") from None
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise SceneError(f"body {body.name!r}: mesh file {path} holds no triangles (empty or not a mesh)")
    else:
        try:
            mesh = make_shape(body.shape, body.params)
        except ValueError as exc:
            raise SceneError(f"body {body.name!r}: {exc}") from None
    v = np.asarray(mesh.vertices, np.float64) * body.scale
    with np.errstate(invalid="ignore"):
        v = v @ rotation_matrix(body.rotation).T + np.asarray(body.position)
    return trimesh.Trimesh(v, np.asarray(mesh.faces), process=False)


class Scene:
    """A scene being simulated. `step(frames)` advances it; the accessors return numpy copies.

    broad_phase: "auto", "brute" or "grid" (solver.solver.XPBDSolver). rules: the contact rules
    compiled in (contact.rules.ContactRules; all by default), for tests and studies.
    sweep_stats: the solver counts its block solves' sweeps (XPBDSolver.sweep_stats)."""

    def __init__(self, config: SceneConfig, broad_phase: str = "auto", rules=None, sweep_stats: bool = False):
        from ..solver.solver import XPBDSolver

        self.config = config
        builder = ModelBuilder()
        for body in config.bodies:
            try:
                mesh = body_mesh(body, config.base_dir)
                builder.add_body(BodySpec(
                    name=body.name, vertices=mesh.vertices, faces=mesh.faces, kind=body.kind,
                    density=body.density, velocity=body.velocity, force=body.force, friction=body.friction,
                    restitution=body.restitution, compliance=body.compliance, damping=body.damping,
                    drag=body.drag, spin_friction=body.spin_friction, self_collision=body.self_collision,
                    bending=body.bending,
                    source=str(config.base_dir / body.mesh) if body.mesh else None))
            except ValueError as exc:  # SceneError included
                raise SceneError(f"{config.source}: {exc}") from None
        self.warnings = builder.warnings  # one line per mesh repair
        self.model, self.state = builder.finalize()
        self.warnings += precision_warnings(self.model, self.vertices(), config.sim)
        self._reach = np.array([b.reach for b in self.model.bodies])
        self.solver = XPBDSolver(self.model, self.state, gravity=config.sim.gravity, broad_phase=broad_phase,
                                 length_scale=config.sim.length_scale, rules=rules,
                                 sleep_speed=config.sim.sleep_speed, sleep_time=config.sim.sleep_time,
                                 sweep_stats=sweep_stats)
        # Bodies placed into each other: the independent measure's pairs deeper than rounding.
        self.start_overlaps = [
            {"bodies": [a, b], "depth": depth, "volume": volume}
            for a, b, depth, volume in body_pairs(self._world_bodies(self.vertices()))
            if depth > START_OVERLAP_DEPTH * config.sim.length_scale]
        self.warnings += start_overlap_warnings(self.start_overlaps, self.solver.depenetration_speed)
        self.fast_frames = 0                  # frames run with more substeps than configured
        self.most_substeps = config.sim.substeps
        self.fast_notice: str | None = None   # why, the first time it happened

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def time(self) -> float:
        return self.state.time

    @property
    def frame(self) -> int:
        """Frames run so far (a frame that raised SimulationError included)."""
        return self.state.frames_done

    @property
    def body_names(self) -> list[str]:
        return [b.name for b in self.model.bodies]

    def step(self, frames: int = 1) -> int:
        """Advance `frames` frames of the scene's frame_dt, substeps and iterations; returns the
        contact count of the last frame. A frame in which bodies move too fast for discrete
        detection runs more substeps (solver/tunnelling.py; `fast_frames`, `most_substeps` and
        `fast_notice` say so). Raises solver.solver.SimulationError on NaN or explosion, or when a
        body is too fast even for MAX_SUBSTEP_FACTOR times the substeps."""
        sim = self.config.sim
        count = self.solver.last_contact_count
        # The all-pairs path runs frames in one launch and checks on the device whether the
        # configured substeps do (solver.summary.substeps_needed); once this scene has said
        # why frames need more (fast_notice), it also chooses them there in f64
        # (substeps_needed, by the same rules and arithmetic), saving a launch and a read of
        # the state a frame. Any other frame for which they do not is chosen here and stepped
        # on its own. (In f32 the device's frame_dt / n would differ from NumPy's in its last bit.)
        check = sim.max_impact_motion if len(self.model.bodies) >= 2 else None
        choose = self.fast_notice is not None and runtime.precision() == "f64"
        done = 0
        while done < frames:
            ran, count = self.solver.step_frames(frames - done, sim.frame_dt, sim.substeps, sim.iterations,
                                                 max_impact_motion=check, choose_substeps=choose)
            more, most = self.solver.more_substeps
            self.fast_frames += more
            self.most_substeps = max(self.most_substeps, most)
            if ran == 0:
                with np.errstate(over="ignore", invalid="ignore"):  # an exploded body's inf speed is an error there
                    substeps = self._substeps_for_next_frame()
                ran, count = self.solver.step_frames(1, sim.frame_dt, substeps, sim.iterations)
            done += ran
        return count

    def _substeps_for_next_frame(self) -> int:
        """The scene's substeps, or more where discrete detection needs them: when the two
        fastest bodies could together move more than TUNNEL_FRACTION of the thinnest body's
        thickness in one substep (else a contact can be missed), and when two bodies that
        can meet within the frame close in faster than sim.max_impact_motion per substep
        (else the landing goes that deep). A body's motion over the frame is bounded by
        (|v| + |ω|·reach + |g|·dt)·dt."""
        from ..solver.solver import SimulationError

        sim = self.config.sim
        bodies = self.model.bodies
        if len(bodies) < 2:
            return sim.substeps
        # One read of the state: per body velocity, motion about it, vertex box.
        summary = self.solver.body_summary_numpy()
        velocity, box_lo, box_hi = summary[:, 0:3], summary[:, 4:7], summary[:, 7:10]
        # A rigid body's points move |ω|·reach about its centre; a soft body's particles are
        # summarised by their fastest speed about its mean velocity.
        spin = summary[:, 3] * np.where(self.model.body_kind_np == RIGID, self._reach, 1.0)
        speed = np.linalg.norm(velocity, axis=1) + spin
        moving = self.model.body_kind_np != STATIC
        speed = np.where(moving, speed + np.linalg.norm(sim.gravity) * sim.frame_dt, 0.0)
        fastest = np.argsort(-speed)[:2]
        motion = float(speed[fastest].sum()) * sim.frame_dt
        thin = min(range(len(bodies)), key=lambda k: bodies[k].thickness)
        needed = substeps_for_motion(motion, bodies[thin].thickness, sim.substeps)
        cap = MAX_SUBSTEP_FACTOR * sim.substeps
        fast = bodies[fastest[0]].name
        if needed > cap:
            raise SimulationError(
                f"body {fast!r} moves {motion:.3g} m per frame ({speed[fastest[0]]:.3g} m/s), more than "
                f"{TUNNEL_FRACTION:g} × the thinnest body ({bodies[thin].name!r}, {bodies[thin].thickness:.3g} m) "
                f"in each of {cap} substeps: contacts would be missed; it needs "
                f"--substeps {needed} (or a smaller frame_dt or a slower start) by t = {self.time:.4g} s")
        g_norm = float(np.linalg.norm(sim.gravity))
        for_impact, a, b = substeps_for_impacts(box_lo, box_hi, velocity, spin, moving, sim.frame_dt, g_norm,
                                                sim.max_impact_motion, sim.substeps)
        for_impact = min(for_impact, cap)  # deeper landings past this are the metrics' to report
        if max(needed, for_impact) == sim.substeps:
            return sim.substeps
        self.fast_frames += 1
        self.most_substeps = max(self.most_substeps, needed, for_impact)
        if self.fast_notice is None:
            if needed >= for_impact:
                self.fast_notice = (
                    f"body {fast!r} moves {motion / sim.substeps:.3g} m per substep, more than "
                    f"{TUNNEL_FRACTION:g} × the thinnest body ({bodies[thin].name!r}, {bodies[thin].thickness:.3g} m): "
                    f"frames like this run up to {needed} substeps so that no contact is missed")
            else:
                self.fast_notice = (
                    f"bodies {bodies[a].name!r} and {bodies[b].name!r} may close in by more than the impact "
                    f"depth {sim.max_impact_motion:.3g} m: frames like this run up to {for_impact} substeps")
        return max(needed, for_impact)

    def sleeping_bodies(self) -> list[str]:
        """Names of the bodies asleep now (sim.sleep: islands at rest are not simulated until touched)."""
        return [b.name for b, asleep in zip(self.model.bodies, self.solver.asleep_numpy()) if asleep]

    def body_vertices(self, name: str) -> np.ndarray:
        """World-space vertices (n, 3) of a body, in the order of `body_faces(name)`."""
        b = self.model.bodies[self.model.body_index(name)]
        return self.state.vertex_x.to_numpy()[b.vertex_start:b.vertex_start + b.vertex_count].astype(np.float64)

    def body_faces(self, name: str) -> np.ndarray:
        return self.model.bodies[self.model.body_index(name)].faces.copy()

    def body_positions(self) -> np.ndarray:
        """(B, 3): centre of mass of rigid bodies, vertex mean of soft and static ones."""
        x = self.state.body_x.to_numpy()[: self.model.n_bodies].astype(np.float64)
        for k, b in enumerate(self.model.bodies):
            if b.deformable:
                x[k] = self.body_vertices(b.name).mean(axis=0)
        return x

    def body_rotations(self) -> np.ndarray:
        """(B, 4) unit quaternions (w, x, y, z) from the build-time orientation (identity for soft)."""
        return self.state.body_q.to_numpy()[: self.model.n_bodies].astype(np.float64)

    def body_velocities(self) -> np.ndarray:
        """(B, 3) linear velocities (m/s); a soft body's is its particles' mean. Velocities
        are XPBD's (x − x_prev)/h of the last substep."""
        v = self.state.body_v.to_numpy()[: self.model.n_bodies].astype(np.float64)
        kind = self.model.body_kind_np
        if self.model.has_soft:
            vv = self.state.vertex_v.to_numpy()
            for k, b in enumerate(self.model.bodies):
                if kind[k] == SOFT:
                    v[k] = vv[b.vertex_start:b.vertex_start + b.vertex_count].mean(axis=0)
        v[kind == STATIC] = 0.0
        return v

    def body_angular_velocities(self) -> np.ndarray:
        """(B, 3) angular velocities (rad/s, world frame) of rigid bodies; 0 for others."""
        w = self.state.body_w.to_numpy()[: self.model.n_bodies].astype(np.float64)
        w[self.model.body_kind_np != RIGID] = 0.0
        return w

    def kinetic_energy(self) -> float:
        """Total kinetic energy (J) of rigid bodies (translation + rotation) and soft particles."""
        m = self.model
        kind = m.body_kind_np
        inv_mass = m.body_inv_mass.to_numpy()[: m.n_bodies]
        inertia = m.body_inertia.to_numpy()[: m.n_bodies]
        v, w, q = self.state.body_v.to_numpy(), self.state.body_w.to_numpy(), self.body_rotations()
        energy = 0.0
        with np.errstate(over="ignore", invalid="ignore"):  # an exploding run's energy is inf, not a warning
            for k in np.flatnonzero(kind == 1):
                r = quat_to_matrix(q[k])
                energy += 0.5 * v[k] @ v[k] / inv_mass[k] + 0.5 * w[k] @ (r @ inertia[k] @ r.T) @ w[k]
            if m.has_soft:
                inv = m.vertex_inv_mass.to_numpy()[: m.n_vertices]
                vv = self.state.vertex_v.to_numpy()[: m.n_vertices]
                soft = inv > 0
                energy += 0.5 * float(np.sum((vv[soft] ** 2).sum(axis=1) / inv[soft]))
        return float(energy)

    def potential_energy(self) -> float:
        """Gravitational potential energy (J) of rigid and soft bodies, −Σ m g·x, zero at the
        origin (rigid bodies by their centre of mass, soft bodies particle by particle)."""
        m = self.model
        g = np.asarray(self.config.sim.gravity, np.float64)
        kind = m.body_kind_np
        inv_mass = m.body_inv_mass.to_numpy()[: m.n_bodies].astype(np.float64)
        x = self.state.body_x.to_numpy()[: m.n_bodies].astype(np.float64)
        rigid = kind == 1
        with np.errstate(over="ignore", invalid="ignore"):
            energy = -float(np.sum((x[rigid] @ g) / inv_mass[rigid]))
            if m.has_soft:
                inv = m.vertex_inv_mass.to_numpy()[: m.n_vertices].astype(np.float64)
                soft = inv > 0
                energy -= float(np.sum((self.vertices()[soft] @ g) / inv[soft]))
        return energy

    def body_mesh(self, name: str) -> trimesh.Trimesh:
        """The body's current world-space mesh."""
        return trimesh.Trimesh(self.body_vertices(name), self.body_faces(name), process=False)

    def vertices(self) -> np.ndarray:
        """World-space vertices (V, 3) of all bodies, body after body (see `body_vertex_slices`)."""
        return self.state.vertex_x.to_numpy()[: self.model.n_vertices].astype(np.float64)

    def moving_vertex_mask(self) -> np.ndarray:
        """(V,) True for the vertices of rigid and soft bodies."""
        mask = np.zeros(self.model.n_vertices, bool)
        for b in self.model.bodies:
            mask[b.vertex_start:b.vertex_start + b.vertex_count] = b.kind != "static"
        return mask

    def penetration(self, vertices: np.ndarray | None = None):
        """Penetration measured from the current meshes alone (metrics.scene_penetration);
        `vertices` (V, 3) if the caller already read them."""
        x = self.vertices() if vertices is None else vertices
        return scene_penetration(self._world_bodies(x))

    def self_penetration(self, vertices: np.ndarray | None = None) -> dict[str, tuple[int, float]]:
        """Each soft body's name → (pairs of its own triangles that cross, the deepest of them
        in m), measured from its mesh alone (measure.self_intersection.self_penetration)."""
        x = self.vertices() if vertices is None else vertices
        return {b.name: self_penetration(x[b.vertex_start:b.vertex_start + b.vertex_count], b.faces,
                                         poke_depths if b.kind == "cloth" else None)
                for b in self.model.bodies if b.deformable}

    def _world_bodies(self, x: np.ndarray) -> list[tuple[str, str, trimesh.Trimesh]]:
        """(name, kind, mesh at the vertices x (V, 3)) of every body."""
        return [(b.name, b.kind, trimesh.Trimesh(x[b.vertex_start:b.vertex_start + b.vertex_count], b.faces,
                                                 process=False))
                for b in self.model.bodies]

    def contact_points(self) -> np.ndarray:
        """(n, 3) world positions of the last substep's contacts (the moved triangles' points)."""
        return self.solver.rows_numpy(self.solver.last_contact_count)["point"]


# A scene whose coordinates f32 cannot resolve finely enough
# for the settle test or the contact test's depth gets a warning (F32_NOISE of either).
F32_NOISE = 0.1


def precision_warnings(model, vertices: np.ndarray, sim) -> list[str]:
    """Warnings for an f32 run whose position quantum eps·|x| (x: the moving bodies'
    coordinates) makes velocities (x − x_prev)/h noisier than F32_NOISE of the settle speed,
    or positions coarser than F32_NOISE of the contact test's final depth (1e-4 m ×
    length_scale). On Erleben's scenes (|x| ≤ 3.5 m, h = 1 ms) the noise is ~4e-4 m/s, and
    spike-in-crack never settles in f32."""
    from ..measure.penetration import PASS_FINAL_DEPTH

    if runtime.precision() != "f32" or not model.bodies:
        return []
    moving = np.concatenate([vertices[b.vertex_start:b.vertex_start + b.vertex_count]
                             for b in model.bodies if b.kind != "static"] or [np.zeros((1, 3))])
    quantum = float(np.finfo(np.float32).eps) * float(np.abs(moving).max())
    h = sim.frame_dt / sim.substeps
    noise = quantum / h
    if noise > F32_NOISE * sim.settle_speed or quantum > F32_NOISE * PASS_FINAL_DEPTH * sim.length_scale:
        return [f"f32 resolves positions here only to {quantum:.1e} m (coordinates up to "
                f"{np.abs(moving).max():.3g} m), so velocities carry {noise:.1e} m/s of rounding noise "
                f"against a settle speed of {sim.settle_speed:.0e} m/s: this scene may never settle or "
                "may keep a visible depth; use --precision f64"]
    return []


# Bodies that start deeper than this (m, times length_scale) in each other get a warning.
START_OVERLAP_DEPTH = 1e-6
START_OVERLAP_LINES = 5  # pairs named one by one; the rest are counted


def start_overlap_warnings(overlaps: list[dict], depenetration_speed: float) -> list[str]:
    """One line per pair of bodies that overlap at the start (Scene.start_overlaps), saying
    what the solver will do with it (docs/scene-format.md, 'Bad input')."""
    lines = [f"bodies {o['bodies'][0]!r} and {o['bodies'][1]!r} overlap at the start, {o['depth']:.2e} m deep "
             f"({o['volume']:.2e} m³): the solver undoes such depth gradually (at most {depenetration_speed:.2g} m/s "
             "per contact, without launching the bodies) and may never part them where the overlap is bounded "
             "by faces lying in each other's planes (two aligned boxes pushed into each other); move them "
             "apart in the scene file"
             for o in overlaps[:START_OVERLAP_LINES]]
    if len(overlaps) > START_OVERLAP_LINES:
        lines.append(f"{len(overlaps) - START_OVERLAP_LINES} more pairs of bodies overlap at the start")
    return lines


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def load_scene(path, broad_phase: str = "auto") -> Scene:
    """Read a TOML scene file and build it (Taichi is initialised with the defaults if
    nobody called `taichi_dcd.init`). Raises SceneError with a one-line message."""
    return Scene(read_scene_file(path), broad_phase=broad_phase)
