"""ModelBuilder: numpy meshes in, a Model and its initial State out. The only place
that fills the simulation's fields (a field set from core.pool).

Each body is a closed, consistently outward-oriented triangle mesh given in world
space. A rigid body's frame is its centre of mass with the world's axes at build
time, so its quaternion starts at identity and its inertia tensor is the mesh's
about the centre of mass in world axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from ..core import pool, runtime
from ..core.upload import upload
from ..contact.cloth import SELF_GAP_FRACTION
from ..contact.hidden_faces import hidden_static_faces
from ..core.model import (DEFORMABLE_KINDS, KIND_NAMES, MODEL_FIELD_NAMES, RIGID, SOFT, STATE_FIELD_NAMES, STATIC,
                          BodyInfo, Model, State, model_fields)
from ..solver.tunnelling import mesh_thickness
from .mesh_check import checked_mesh

DEFAULT_SOFT_COMPLIANCE = 1e-7  # m/N: edge compliance of a soft body


@dataclass
class BodySpec:
    """One body before building. vertices (n, 3) m in world space, faces (m, 3) int;
    kind "rigid" | "soft" | "cloth" | "static"; density kg/m³ (a cloth: kg/m² of sheet);
    velocity m/s; force N (constant, at the centre of mass); friction (Coulomb μ, static and
    dynamic); restitution in [0, 1]; compliance m/N (soft bodies' edges); damping 1/s, the
    rate at which a soft body's particles lose their velocity relative to the body's rigid
    motion (0: none); drag 1/s,
    the rate at which every point of a moving body loses its velocity (velocity damping,
    standing in for the dissipation that point contacts lack; 0: none); spin_friction m, the
    largest torque about a contact's normal per newton of its normal force (a contact patch's
    radius times μ; point contacts have none; 0: none); bending m/N, a cloth's bending
    compliance (the pairs of vertices across each inner edge keep their distance with it)."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    kind: str = "rigid"
    density: float = 1000.0
    velocity: tuple = (0.0, 0.0, 0.0)
    force: tuple = (0.0, 0.0, 0.0)
    friction: float = 0.5
    restitution: float = 0.0
    compliance: float = DEFAULT_SOFT_COMPLIANCE
    damping: float = 0.0
    drag: float = 0.0
    spin_friction: float = 0.0
    self_collision: bool = False  # soft bodies: its own triangles collide (not near neighbours)
    bending: float = 0.0
    source: str | None = None  # the mesh file, named in error messages


def bending_pairs(mesh: trimesh.Trimesh) -> np.ndarray:
    """(k, 2) the two vertices opposite each inner edge of a sheet (the hinge's tips): the
    distance between them shrinks as the two faces fold about the edge, so keeping it is a
    bending constraint (Müller et al. 2007 use the dihedral angle; a distance is cheaper, the
    same near flat, and cannot flip sign)."""
    pairs = np.asarray(mesh.face_adjacency, np.int64)
    if len(pairs) == 0:
        return np.zeros((0, 2), np.int64)
    faces = np.asarray(mesh.faces, np.int64)
    shared = np.sort(np.asarray(mesh.face_adjacency_edges, np.int64), axis=1)

    def tip(f):
        rows = faces[f]
        alone = (rows != shared[:, :1]) & (rows != shared[:, 1:])
        return rows[np.arange(len(rows)), np.argmax(alone, axis=1)]

    return np.column_stack([tip(pairs[:, 0]), tip(pairs[:, 1])])


def wavefront_order(edges: np.ndarray) -> np.ndarray:
    """(E,) a permutation of the (E, 2) edge constraints, solved one after another in that
    list's order, that gives the same Gauss-Seidel sweep bit for bit and lets the processor
    overlap neighbouring solves. Each constraint reads what the last constraint before it on
    either vertex wrote; its wave is one more than that constraint's, and the constraints are
    taken wave by wave (in list order within a wave). No two of one wave share a vertex, and
    every constraint still comes after all those it read from, so each sees the same inputs.
    In the mesh's own order a third of the solves read the vertex the one before just wrote,
    and the serial sweep waited on every square root and division of that chain."""
    wave_of_vertex: dict[int, int] = {}
    wave = np.empty(len(edges), np.int64)
    for k, (i, j) in enumerate(edges.tolist()):
        w = max(wave_of_vertex.get(i, 0), wave_of_vertex.get(j, 0)) + 1
        wave[k] = wave_of_vertex[i] = wave_of_vertex[j] = w
    return np.argsort(wave, kind="stable")


def sheet_spacing(vertices: np.ndarray, faces: np.ndarray) -> float:
    """A cloth's stand-in for thickness (m): its mean edge length. A sheet has no wall to
    cross; what discrete detection cannot miss is a crossing that leaves a triangle pair
    intersecting, so a substep may move it by at most a fraction of its mesh's spacing."""
    tris = vertices[faces]
    return float(np.linalg.norm(tris - np.roll(tris, 1, axis=1), axis=2).mean())


class ModelBuilder:
    """Collects bodies as numpy data; `finalize()` allocates the Model and State once."""

    def __init__(self):
        self.specs: list[BodySpec] = []
        self.meshes: list[trimesh.Trimesh] = []
        self.warnings: list[str] = []  # one line per repair made to a mesh

    def add_body(self, spec: BodySpec) -> int:
        """Check and add a body; returns its index. Raises ValueError naming the body."""
        if spec.kind not in KIND_NAMES:
            raise ValueError(f"body {spec.name!r}: unknown kind {spec.kind!r} (rigid, soft, cloth or static)")
        if any(s.name == spec.name for s in self.specs):
            raise ValueError(f"body {spec.name!r}: duplicate body name")
        if spec.kind != "static" and not spec.density > 0.0:
            raise ValueError(f"body {spec.name!r}: density must be positive, got {spec.density}")
        if spec.kind in DEFORMABLE_KINDS and not spec.compliance >= 0.0:
            raise ValueError(f"body {spec.name!r}: compliance must be >= 0, got {spec.compliance}")
        if spec.kind in DEFORMABLE_KINDS and not spec.damping >= 0.0:
            raise ValueError(f"body {spec.name!r}: damping must be >= 0, got {spec.damping}")
        if spec.kind == "cloth" and not spec.bending >= 0.0:
            raise ValueError(f"body {spec.name!r}: bending must be >= 0, got {spec.bending}")
        if spec.self_collision and spec.kind not in DEFORMABLE_KINDS:
            raise ValueError(f"body {spec.name!r}: self_collision is for soft bodies and cloth only, not {spec.kind}")
        if not spec.drag >= 0.0:
            raise ValueError(f"body {spec.name!r}: drag must be >= 0, got {spec.drag}")
        if not spec.spin_friction >= 0.0:
            raise ValueError(f"body {spec.name!r}: spin_friction must be >= 0, got {spec.spin_friction}")
        mesh, warnings = checked_mesh(spec.name, spec.vertices, spec.faces, spec.source, spec.kind)
        self.meshes.append(mesh)
        self.warnings += warnings
        self.specs.append(spec)
        return len(self.specs) - 1

    def finalize(self) -> tuple[Model, State]:
        """The Model and its initial State, in a field set of the pool (core.pool) held until
        both are collected (Taichi is initialised if it is not)."""
        runtime.ensure_init()
        if not self.specs:
            raise ValueError("a model needs at least one body")
        n_b = len(self.specs)
        kind = np.array([KIND_NAMES[s.kind] for s in self.specs], np.int32)
        inv_mass = np.zeros(n_b)
        inertia = np.zeros((n_b, 3, 3))
        inv_inertia = np.zeros((n_b, 3, 3))
        com = np.zeros((n_b, 3))
        vertex_local, vertex_world, vertex_body, vertex_inv_mass, tris, tri_body = [], [], [], [], [], []
        edges, edge_rest, edge_compliance = [], [], []
        vertex_range = np.zeros((n_b, 2), np.int32)
        tri_range = np.zeros((n_b, 2), np.int32)
        rest_volume = np.zeros(n_b)
        bodies = []
        v_off = t_off = 0
        for k, (spec, mesh) in enumerate(zip(self.specs, self.meshes)):
            v = np.asarray(mesh.vertices, np.float64)
            f = np.asarray(mesh.faces, np.int64)
            cloth = spec.kind == "cloth"
            volume = 0.0 if cloth else float(mesh.volume)
            mass = spec.density * (float(mesh.area) if cloth else volume)
            rest_volume[k] = volume
            if kind[k] == RIGID:
                props = mesh.mass_properties  # unit density: scale mass and inertia by density
                com[k] = props["center_mass"]
                inv_mass[k] = 1.0 / mass
                inertia[k] = spec.density * np.asarray(props["inertia"])
                inv_inertia[k] = np.linalg.inv(inertia[k])
            elif kind[k] == STATIC:
                com[k] = v.mean(axis=0)
                mass = float("inf")
            else:  # soft or cloth: equal particle masses, centre = vertex mean
                com[k] = v.mean(axis=0)
                vertex_inv_mass.append(np.full(len(v), len(v) / mass))
                e = np.asarray(mesh.edges_unique, np.int64)
                compliance = np.full(len(e), spec.compliance)
                if cloth:
                    hinges = bending_pairs(mesh)
                    e = np.concatenate([e, hinges])
                    compliance = np.concatenate([compliance, np.full(len(hinges), spec.bending)])
                edges.append(e + v_off)
                edge_rest.append(np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1))
                edge_compliance.append(compliance)
            if kind[k] != SOFT:
                vertex_inv_mass.append(np.zeros(len(v)))
            vertex_local.append(v - com[k])
            vertex_world.append(v)
            vertex_body.append(np.full(len(v), k, np.int32))
            tris.append(f + v_off)
            tri_body.append(np.full(len(f), k, np.int32))
            vertex_range[k] = (v_off, v_off + len(v))
            tri_range[k] = (t_off, t_off + len(f))
            bodies.append(BodyInfo(spec.name, spec.kind, v_off, len(v), t_off, len(f), f.copy(), mass, volume,
                                   thickness=sheet_spacing(v, f) if cloth else mesh_thickness(v, f),
                                   reach=float(np.linalg.norm(v - com[k], axis=1).max()),
                                   self_collision=bool(spec.self_collision),
                                   self_gap=(SELF_GAP_FRACTION * sheet_spacing(v, f)
                                             if spec.self_collision and kind[k] == SOFT and not cloth else 0.0)))
            v_off += len(v)
            t_off += len(f)

        has_soft = bool((kind == SOFT).any())
        cloth_flags = np.array([s.kind == "cloth" for s in self.specs], np.int32)
        n_v, n_t = v_off, t_off
        tri_hidden = np.concatenate(hidden_static_faces(
            [(w, b.faces) for w, b in zip(vertex_world, bodies)], [k == STATIC for k in kind])).astype(np.int32)
        n_e = int(sum(len(e) for e in edges))
        real = runtime.real_dtype()

        velocity = np.array([s.velocity for s in self.specs], real)
        vertex_v = np.concatenate([np.tile(velocity[k], (b.vertex_count, 1)) for k, b in enumerate(bodies)])
        quat = np.tile(np.array([1.0, 0.0, 0.0, 0.0], real), (n_b, 1))
        x_world = np.concatenate(vertex_world).astype(real)
        data = dict(
            body_count=np.array([n_b], np.int32), vertex_count=np.array([n_v], np.int32),
            tri_count=np.array([n_t], np.int32), edge_count=np.array([n_e], np.int32),
            body_kind=kind,
            body_inv_mass=inv_mass.astype(real),
            body_inertia=inertia.astype(real),
            body_inv_inertia=inv_inertia.astype(real),
            body_force=np.array([s.force for s in self.specs], real),
            body_friction=np.array([s.friction for s in self.specs], real),
            body_restitution=np.array([s.restitution for s in self.specs], real),
            body_vertex_range=vertex_range,
            body_tri_range=tri_range,
            body_compliance=np.array([s.compliance for s in self.specs], real),
            body_damping=np.array([s.damping for s in self.specs], real),
            body_drag=np.array([s.drag for s in self.specs], real),
            body_spin_friction=np.array([s.spin_friction for s in self.specs], real),
            body_rest_volume=rest_volume.astype(real),
            vertex_body=np.concatenate(vertex_body),
            vertex_local=np.concatenate(vertex_local).astype(real),
            vertex_inv_mass=np.concatenate(vertex_inv_mass).astype(real),
            tri_indices=np.concatenate(tris).astype(np.int32),
            tri_body=np.concatenate(tri_body),
            tri_hidden=tri_hidden,
            body_x=com.astype(real),
            body_q=quat,
            body_v=np.where((kind == STATIC)[:, None], 0.0, velocity).astype(real),
            body_w=np.zeros((n_b, 3), real),
            body_x_prev=com.astype(real),
            body_q_prev=quat,
            vertex_x=x_world,
        )
        if has_soft:
            all_edges = np.concatenate(edges)
            order = wavefront_order(all_edges)
            data.update(body_self_collision=np.array([s.self_collision for s in self.specs], np.int32),
                        edge_indices=all_edges[order].astype(np.int32),
                        edge_rest=np.concatenate(edge_rest)[order].astype(real),
                        edge_compliance=np.concatenate(edge_compliance)[order].astype(real),
                        body_cloth=cloth_flags,
                        vertex_x_prev=x_world, vertex_v=vertex_v.astype(real))
        else:  # one zero row each: only soft bodies have particles of their own
            data.update(vertex_x_prev=x_world[:0], vertex_v=x_world[:0])

        counts = {"bodies": n_b, "vertices": n_v, "tris": n_t, "edges": n_e}
        has_self_gap = any(b.self_gap > 0.0 for b in bodies)
        # The set's FieldView holds these flags (solver.fields), so sets differ by them.
        field_set = pool.acquire(("model", has_soft, bool(cloth_flags.any()), has_self_gap), counts,
                                 lambda rows: model_fields(rows, has_soft))
        try:
            upload([(fld, pool.padded(data[name], fld.shape[0]))
                    for name, fld in field_set.fields.items() if fld is not None])
            f = field_set.fields
            m = Model(bodies=bodies, n_bodies=n_b, n_vertices=n_v, n_tris=n_t, n_edges=n_e, has_soft=has_soft,
                      **{name: f[name] for name in MODEL_FIELD_NAMES},
                      tri_indices_np=data["tri_indices"], tri_body_np=data["tri_body"],
                      tri_hidden_np=tri_hidden.astype(bool), body_kind_np=kind.copy(), field_set=field_set,
                      has_cloth=bool(cloth_flags.any()), has_self_gap=has_self_gap)
            s = State(**{name: f[name] for name in STATE_FIELD_NAMES})
        except BaseException:
            pool.give_back(field_set)
            raise
        pool.hold(field_set, m, s)
        return m, s
