"""ModelBuilder: numpy meshes in, a Model and its initial State out. The only place
that allocates the simulation's fields.

Each body is a closed, consistently outward-oriented triangle mesh given in world
space. A rigid body's frame is its centre of mass with the world's axes at build
time, so its quaternion starts at identity and its inertia tensor is the mesh's
about the centre of mass in world axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from ..core import runtime
from ..contact.hidden_faces import hidden_static_faces
from ..core.model import KIND_NAMES, RIGID, SOFT, STATIC, BodyInfo, Model, State, mat_field, scalar_field, vec_field
from ..solver.tunnelling import mesh_thickness

DEFAULT_SOFT_COMPLIANCE = 1e-7  # m/N: edge compliance of a soft body


@dataclass
class BodySpec:
    """One body before building. vertices (n, 3) m in world space, faces (m, 3) int;
    kind "rigid" | "soft" | "static"; density kg/m³; velocity m/s; force N (constant,
    at the centre of mass); friction (Coulomb μ, static and dynamic); restitution in [0, 1];
    compliance m/N (soft bodies' edges); damping 1/s, the rate at which a soft body's
    particles lose their velocity relative to the body's rigid motion (0: none); drag 1/s,
    the rate at which every point of a moving body loses its velocity (velocity damping,
    standing in for the dissipation that point contacts lack; 0: none); spin_friction m, the
    largest torque about a contact's normal per newton of its normal force (a contact patch's
    radius times μ; point contacts have none; 0: none)."""

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
    source: str | None = None  # the mesh file, named in error messages


def checked_mesh(name: str, vertices, faces, source: str | None = None) -> tuple[trimesh.Trimesh, list[str]]:
    """The body's mesh, checked and, where the repair is safe and standard, repaired.

    Returns (mesh, warnings): duplicate vertices are merged silently; duplicate faces are
    dropped, inconsistent winding is made consistent and an inward mesh is turned outward,
    each with a one-line warning saying what changed. Raises a one-line ValueError naming the
    body (and `source`, its file) for: non-numeric or non-finite coordinates, face indices out
    of range, an empty mesh, zero-area faces, a mesh that is not closed, or winding that
    cannot be made consistent."""
    label = f"body {name!r}" + (f" ({source})" if source else "")
    try:
        v = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{label}: vertices must be a numeric (n, 3) array") from None
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise ValueError(f"{label}: the mesh is empty or its vertices are not an (n, 3) array (shape {v.shape})")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"{label}: the mesh has no triangles or its faces are not an integer (m, 3) array "
                         f"(shape {f.shape})")
    bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
    if len(bad):
        raise ValueError(f"{label}: vertex {bad[0]} has a NaN or infinite coordinate")
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"{label}: face indices must lie in [0, {len(v)}), got {f.min()}..{f.max()}")
    warnings = []
    mesh = trimesh.Trimesh(v, f, process=True, validate=False)
    unique = trimesh.grouping.unique_rows(np.sort(mesh.faces, axis=1))[0]
    if len(unique) < len(mesh.faces):
        dropped = len(mesh.faces) - len(unique)
        mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[np.sort(unique)], process=False)
        warnings.append(f"{label}: dropped {dropped} duplicate face{'s' if dropped > 1 else ''}")
    area = mesh.area_faces
    zero = np.flatnonzero(area <= 1e-300)
    if len(zero):
        raise ValueError(f"{label}: face {zero[0]} has zero area ({len(zero)} such face{'s' if len(zero) > 1 else ''})")
    if not mesh.is_watertight:
        edges = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)
        raise ValueError(f"{label}: mesh is not closed ({len(edges)} boundary edges)")
    if not mesh.is_winding_consistent:
        mesh = trimesh.Trimesh(mesh.vertices, consistent_winding(mesh), process=False)
        if not mesh.is_winding_consistent:
            raise ValueError(f"{label}: mesh winding is inconsistent and could not be repaired")
        warnings.append(f"{label}: made the faces' winding consistent")
    if not mesh.volume > 0.0:
        mesh.invert()
        warnings.append(f"{label}: the mesh was oriented inward; turned it outward")
    return mesh, warnings


def consistent_winding(mesh: trimesh.Trimesh) -> np.ndarray:
    """The faces (m, 3) reordered so that every edge shared by two faces runs in opposite
    directions in them (breadth-first from face 0 of each connected piece, flipping a
    neighbour that disagrees). A non-orientable mesh stays inconsistent."""
    faces = np.asarray(mesh.faces).copy()
    pairs, edges = np.asarray(mesh.face_adjacency), np.asarray(mesh.face_adjacency_edges)
    neighbours = [[] for _ in range(len(faces))]
    for (f, g), edge in zip(pairs, edges):
        neighbours[f].append((g, edge))
        neighbours[g].append((f, edge))

    def runs_forward(face, a, b) -> bool:
        i = list(face).index(a)
        return face[(i + 1) % 3] == b

    done = np.zeros(len(faces), bool)
    for seed in range(len(faces)):
        if done[seed]:
            continue
        done[seed] = True
        queue = [seed]
        while queue:
            f = queue.pop()
            for g, (a, b) in neighbours[f]:
                if not done[g]:
                    if runs_forward(faces[f], a, b) == runs_forward(faces[g], a, b):
                        faces[g] = faces[g][::-1]
                    done[g] = True
                    queue.append(g)
    return faces


class ModelBuilder:
    """Collects bodies as numpy data; `finalize()` allocates the Model and State once."""

    def __init__(self):
        self.specs: list[BodySpec] = []
        self.meshes: list[trimesh.Trimesh] = []
        self.warnings: list[str] = []  # one line per repair made to a mesh

    def add_body(self, spec: BodySpec) -> int:
        """Check and add a body; returns its index. Raises ValueError naming the body."""
        if spec.kind not in KIND_NAMES:
            raise ValueError(f"body {spec.name!r}: unknown kind {spec.kind!r} (rigid, soft or static)")
        if any(s.name == spec.name for s in self.specs):
            raise ValueError(f"body {spec.name!r}: duplicate body name")
        if spec.kind != "static" and not spec.density > 0.0:
            raise ValueError(f"body {spec.name!r}: density must be positive, got {spec.density}")
        if spec.kind == "soft" and not spec.compliance >= 0.0:
            raise ValueError(f"body {spec.name!r}: compliance must be >= 0, got {spec.compliance}")
        if spec.kind == "soft" and not spec.damping >= 0.0:
            raise ValueError(f"body {spec.name!r}: damping must be >= 0, got {spec.damping}")
        if not spec.drag >= 0.0:
            raise ValueError(f"body {spec.name!r}: drag must be >= 0, got {spec.drag}")
        if not spec.spin_friction >= 0.0:
            raise ValueError(f"body {spec.name!r}: spin_friction must be >= 0, got {spec.spin_friction}")
        mesh, warnings = checked_mesh(spec.name, spec.vertices, spec.faces, spec.source)
        self.meshes.append(mesh)
        self.warnings += warnings
        self.specs.append(spec)
        return len(self.specs) - 1

    def finalize(self) -> tuple[Model, State]:
        """Allocate the Model and its initial State (Taichi must be initialised)."""
        import taichi as ti

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
        edges, edge_rest = [], []
        vertex_range = np.zeros((n_b, 2), np.int32)
        tri_range = np.zeros((n_b, 2), np.int32)
        rest_volume = np.zeros(n_b)
        bodies = []
        v_off = t_off = 0
        for k, (spec, mesh) in enumerate(zip(self.specs, self.meshes)):
            v = np.asarray(mesh.vertices, np.float64)
            f = np.asarray(mesh.faces, np.int64)
            volume = float(mesh.volume)
            mass = spec.density * volume
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
            else:  # soft: equal particle masses, centre = vertex mean
                com[k] = v.mean(axis=0)
                vertex_inv_mass.append(np.full(len(v), len(v) / mass))
                e = np.asarray(mesh.edges_unique, np.int64)
                edges.append(e + v_off)
                edge_rest.append(np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1))
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
                                   thickness=mesh_thickness(v, f),
                                   reach=float(np.linalg.norm(v - com[k], axis=1).max())))
            v_off += len(v)
            t_off += len(f)

        has_soft = bool((kind == SOFT).any())
        n_v, n_t = v_off, t_off
        tri_hidden = np.concatenate(hidden_static_faces(
            [(w, b.faces) for w, b in zip(vertex_world, bodies)], [k == STATIC for k in kind])).astype(np.int32)
        n_e = int(sum(len(e) for e in edges))
        i32 = ti.i32
        real = runtime.real_dtype()

        # One SNode tree for the whole Model and State (runtime.field_block).
        with runtime.field_block():
            m = Model(
                bodies=bodies, n_bodies=n_b, n_vertices=n_v, n_tris=n_t, n_edges=n_e, has_soft=has_soft,
                body_kind=_from(scalar_field(n_b, i32), kind),
                body_inv_mass=_from(scalar_field(n_b), inv_mass.astype(real)),
                body_inertia=_from(mat_field(n_b), inertia.astype(real)),
                body_inv_inertia=_from(mat_field(n_b), inv_inertia.astype(real)),
                body_force=_from(vec_field(n_b), np.array([s.force for s in self.specs], real)),
                body_friction=_from(scalar_field(n_b), np.array([s.friction for s in self.specs], real)),
                body_restitution=_from(scalar_field(n_b), np.array([s.restitution for s in self.specs], real)),
                body_vertex_range=_from(vec_field(n_b, 2, i32), vertex_range),
                body_tri_range=_from(vec_field(n_b, 2, i32), tri_range),
                body_compliance=_from(scalar_field(n_b), np.array([s.compliance for s in self.specs], real)),
                body_damping=_from(scalar_field(n_b), np.array([s.damping for s in self.specs], real)),
                body_drag=_from(scalar_field(n_b), np.array([s.drag for s in self.specs], real)),
                body_spin_friction=_from(scalar_field(n_b), np.array([s.spin_friction for s in self.specs], real)),
                body_rest_volume=_from(scalar_field(n_b), rest_volume.astype(real)),
                vertex_body=_from(scalar_field(n_v, i32), np.concatenate(vertex_body)),
                vertex_local=_from(vec_field(n_v), np.concatenate(vertex_local).astype(real)),
                vertex_inv_mass=_from(scalar_field(n_v), np.concatenate(vertex_inv_mass).astype(real)),
                tri_indices=_from(vec_field(n_t, 3, i32), np.concatenate(tris).astype(np.int32)),
                tri_body=_from(scalar_field(n_t, i32), np.concatenate(tri_body)),
                tri_hidden=_from(scalar_field(n_t, i32), tri_hidden),
                tri_indices_np=np.concatenate(tris).astype(np.int32),
                tri_body_np=np.concatenate(tri_body),
                tri_hidden_np=tri_hidden.astype(bool),
                body_kind_np=kind.copy(),
            )
            if has_soft:
                m.edge_indices = _from(vec_field(n_e, 2, i32), np.concatenate(edges).astype(np.int32))
                m.edge_rest = _from(scalar_field(n_e), np.concatenate(edge_rest).astype(real))

            velocity = np.array([s.velocity for s in self.specs], real)
            vertex_v = np.concatenate([np.tile(velocity[k], (b.vertex_count, 1)) for k, b in enumerate(bodies)])
            quat = np.tile(np.array([1.0, 0.0, 0.0, 0.0], real), (n_b, 1))
            x_world = np.concatenate(vertex_world).astype(real)
            s = State(
                body_x=_from(vec_field(n_b), com.astype(real)),
                body_q=_from(vec_field(n_b, 4), quat),
                body_v=_from(vec_field(n_b), np.where((kind == STATIC)[:, None], 0.0, velocity).astype(real)),
                body_w=_from(vec_field(n_b), np.zeros((n_b, 3), real)),
                body_x_prev=_from(vec_field(n_b), com.astype(real)),
                body_q_prev=_from(vec_field(n_b, 4), quat),
                vertex_x=_from(vec_field(n_v), x_world),
                vertex_x_prev=_from(vec_field(n_v if has_soft else 0), x_world if has_soft else x_world[:0]),
                vertex_v=_from(vec_field(n_v if has_soft else 0), vertex_v.astype(real) if has_soft else x_world[:0]),
            )
        return m, s


def _from(fld, data: np.ndarray):
    """Fill a field (max(len(data), 1) rows) from `data`, an empty array as one zero row."""
    data = np.asarray(data)
    if len(data) == 0:
        data = np.zeros((1,) + data.shape[1:], dtype=data.dtype)
    runtime.fill(fld, data)
    return fld
