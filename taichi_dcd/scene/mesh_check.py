"""A body's mesh as the user gave it, checked before it becomes a body: refused with a one-line
reason naming the defect, repaired where the repair is safe and standard, or taken with a
warning that says what the defect changes (docs/scene-format.md, 'Bad input')."""

from __future__ import annotations

import numpy as np
import trimesh

from ..measure.self_intersection import crossing_pairs

# What a self-intersecting body's overlap changes, by kind.
SELF_INTERSECTION_EFFECT = {
    "rigid": "its mass and inertia count the overlap twice",
    "soft": "its volume constraint keeps the overlap counted twice",
    "static": "its faces inside its own solid can take contacts",
    "cloth": "it starts tangled: the crossing pairs stay crossed",
}


def checked_mesh(name: str, vertices, faces, source: str | None = None, kind: str = "rigid",
                 crossings: bool = True) -> tuple[trimesh.Trimesh, list[str]]:
    """The body's mesh, checked and, where the repair is safe and standard, repaired.

    Returns (mesh, warnings): duplicate vertices are merged silently; duplicate faces are
    dropped, inconsistent winding is made consistent and an inward mesh is turned outward,
    each with a one-line warning saying what changed; a mesh whose own triangles cross is
    kept with a warning (self_intersection_warning; not looked for without `crossings`).
    Raises a one-line ValueError naming the body (and `source`, its file) for: non-numeric or
    non-finite coordinates, face indices out of range, an empty mesh, zero-area faces, a mesh
    that is not closed or not manifold (the edge named), or winding that cannot be made
    consistent. A cloth's mesh may be open (boundary edges) and is not turned outward: it has
    no inside."""
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
    if kind == "cloth":
        crowded = edge_defect(mesh, v, open_allowed=True)
        if crowded:
            raise ValueError(f"{label}: {crowded}")
    elif not mesh.is_watertight:
        raise ValueError(f"{label}: {edge_defect(mesh, v)}")
    if not mesh.is_winding_consistent:
        mesh = trimesh.Trimesh(mesh.vertices, consistent_winding(mesh), process=False)
        if not mesh.is_winding_consistent:
            raise ValueError(f"{label}: mesh winding is inconsistent and could not be repaired")
        warnings.append(f"{label}: made the faces' winding consistent")
    if kind != "cloth" and not mesh.volume > 0.0:
        mesh.invert()
        warnings.append(f"{label}: the mesh was oriented inward; turned it outward")
    crossing = self_intersection_warning(mesh, kind, source) if crossings else None
    if crossing:
        warnings.append(f"{label}: {crossing}")
    return mesh, warnings


def edge_defect(mesh: trimesh.Trimesh, given_vertices: np.ndarray, open_allowed: bool = False) -> str | None:
    """Why a mesh whose edges are not each shared by exactly two faces is not a solid's
    surface (with open_allowed, not a sheet: only edges shared by more than two faces count;
    None if there is none), naming one such edge by its vertices' indices in `given_vertices`
    (the mesh's vertices as the user gave them, counting from 0) and their coordinates."""
    edges = np.asarray(mesh.edges_sorted)
    groups = trimesh.grouping.group_rows(edges)
    counts = np.array([len(g) for g in groups])
    open_edges = [g for g, c in zip(groups, counts) if c == 1]
    crowded = [g for g, c in zip(groups, counts) if c > 2]

    def named(edge) -> str:
        ends = []
        for k in edges[edge[0]]:
            p = np.asarray(mesh.vertices[k])
            index = int(np.argmin(np.abs(given_vertices - p).max(axis=1)))  # the first, where merged
            ends.append((index, p))
        (i, p), (j, q) = sorted(ends, key=lambda e: e[0])
        return f"the edge between vertices {i} and {j} (at {_point(p)} and {_point(q)} in the scene)"

    if open_allowed:
        if not crowded:
            return None
        open_edges = []
    if open_edges:
        return (f"mesh is not closed ({len(open_edges)} boundary edge{'s' if len(open_edges) > 1 else ''}, "
                f"e.g. {named(open_edges[0])} belongs to one face only)")
    worst = crowded[int(np.argmax([len(g) for g in crowded]))]
    return (f"mesh is not manifold ({len(crowded)} edge{'s' if len(crowded) > 1 else ''} shared by more than "
            f"two faces, e.g. {named(worst)} is shared by {len(worst)} faces, where two parts meet along it): "
            "move the parts apart or join them into one solid")


def _point(p) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in p) + ")"


def self_intersection_warning(mesh: trimesh.Trimesh, kind: str, source: str | None) -> str | None:
    """None for a mesh whose triangles do not cross each other, else one line: how many pairs
    cross, what that changes for a body of `kind`, the volume as given against the solid's,
    and how to fix the file."""
    pairs = crossing_pairs(mesh.vertices, mesh.faces)
    if len(pairs) == 0:
        return None
    given = float(mesh.volume)
    solid = union_of_parts(mesh)
    words = (f"the mesh intersects itself ({len(pairs)} pair{'s' if len(pairs) > 1 else ''} of its triangles "
             f"cross), so {SELF_INTERSECTION_EFFECT[kind]}: its volume is {given:.4g} m³ as given")
    if solid is None:
        return words + "; repair the mesh so that no two of its triangles cross"
    fix = f"taichi-dcd union {source} FIXED.obj" if source else "taichi-dcd union MESH.obj FIXED.obj"
    return words + f", {float(solid.volume):.4g} m³ as one solid; `{fix}` writes that solid"


def face_parts(faces: np.ndarray) -> np.ndarray:
    """(m,) label of each face's connected part (faces sharing a vertex are connected)."""
    f = np.asarray(faces, np.int64)
    label = np.arange(int(f.max()) + 1)
    while True:
        low = label[f].min(axis=1)
        before = label.copy()
        np.minimum.at(label, f.ravel(), np.repeat(low, 3))
        label = label[label]  # pointer jumping: halves the remaining distance to a part's root
        if np.array_equal(label, before):
            return np.unique(label[f[:, 0]], return_inverse=True)[1].ravel()


def union_of_parts(mesh: trimesh.Trimesh) -> trimesh.Trimesh | None:
    """The solid covered by the mesh's connected parts (a boolean union, manifold3d), or None
    when that cannot fix it: a single part whose own triangles cross, or a part that crosses
    itself (no union of whole parts removes a crossing within one part)."""
    import manifold3d

    parts = face_parts(mesh.faces)
    if parts.max() == 0:
        return None
    solids = []
    origin = mesh.bounds.mean(axis=0)
    for k in range(int(parts.max()) + 1):
        faces = np.asarray(mesh.faces)[parts == k]
        used, local = np.unique(faces, return_inverse=True)
        vertices = np.asarray(mesh.vertices)[used]
        local = local.reshape(-1, 3)
        if len(crossing_pairs(vertices, local)):
            return None
        solids.append(manifold3d.Manifold(manifold3d.Mesh64(
            vert_properties=np.ascontiguousarray(vertices - origin, np.float64),
            tri_verts=np.ascontiguousarray(local, np.uint64))))
    union = manifold3d.Manifold.batch_boolean(solids, manifold3d.OpType.Add).to_mesh64()
    vertices = np.asarray(union.vert_properties, np.float64)[:, :3] + origin
    return trimesh.Trimesh(vertices, np.asarray(union.tri_verts, np.int64).reshape(-1, 3), process=False)


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
