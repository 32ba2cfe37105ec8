"""Penetration measured from meshes alone, independently of the solver (docs/method.md, 'Measuring penetration').

For closed bodies A and B the overlap is the solid I = A ∩ B (manifold3d, in double
precision). Its boundary is made of A's surface inside B and B's surface inside A, so
A's deepest point inside B, measured as its distance to B's surface, lies on I's
boundary, and so does B's deepest point inside A. The pair's depth is the largest
distance, to the other body's surface, of a point of I's boundary: I's vertices and a
barycentric grid on its faces, the deepest grid points refined on finer local grids.
Depths at vertices are exact; elsewhere the search can only underestimate, by at most
the final local spacing where the deepest point is found. The scene's
depth is the largest over pairs of bodies that are not both static.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

# The overlap's sampling grid: its box diagonal / EDGE_SAMPLES apart (at most this many per edge).
EDGE_SAMPLES = 16
# Deepest grid points refined locally (pair_penetration).
REFINE_POINTS = 8


@dataclass
class Penetration:
    """depth: largest distance (m) of a surface point of one body inside the other to the
    other's surface; volume: overlap volume (m³); pair: the two body names (or None)."""

    depth: float = 0.0
    volume: float = 0.0
    pair: tuple[str, str] | None = None
    pairs: int = 0        # pairs of bodies measured (not both static)
    pairs_apart: int = 0  # of them, pairs whose boxes are apart: no overlap, nothing computed


def _manifold(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray):
    import manifold3d

    mesh = manifold3d.Mesh64(vert_properties=np.ascontiguousarray(vertices - origin, np.float64),
                             tri_verts=np.ascontiguousarray(faces, np.uint64))
    return manifold3d.Manifold(mesh).as_original()


def boxes_apart(a: trimesh.Trimesh, b: trimesh.Trimesh) -> bool:
    """Whether the meshes' axis-aligned boxes are apart (then the meshes cannot overlap)."""
    return bool(np.any(np.maximum(a.bounds[0], b.bounds[0]) > np.minimum(a.bounds[1], b.bounds[1])))


def overlap(a: trimesh.Trimesh, b: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """The solid A ∩ B as (vertices (n, 3), faces (m, 3), volume m³, side (m,) int8: 0 for a
    face on A's surface, 1 on B's, -1 where the boolean does not say); empty when they do not
    overlap. Coordinates are shifted to the boxes' common centre for the boolean, so that
    large offsets do not cost precision."""
    if boxes_apart(a, b):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), 0.0, np.zeros(0, np.int8)
    origin = 0.5 * (np.maximum(a.bounds[0], b.bounds[0]) + np.minimum(a.bounds[1], b.bounds[1]))
    solid_a = _manifold(np.asarray(a.vertices), np.asarray(a.faces), origin)
    solid_b = _manifold(np.asarray(b.vertices), np.asarray(b.faces), origin)
    solid = solid_a ^ solid_b
    out = solid.to_mesh64()
    v = np.asarray(out.vert_properties, np.float64)[:, :3] + origin
    f = np.asarray(out.tri_verts, np.int64).reshape(-1, 3)
    volume = max(float(solid.volume()), 0.0)
    # The boolean keeps, for each run of output triangles, the id of the input it came from.
    side = np.full(len(f), -1, np.int8)
    starts, ids = np.asarray(out.run_index, np.int64) // 3, np.asarray(out.run_original_id, np.int64)
    for k, run_id in enumerate(ids):
        if run_id in (solid_a.original_id(), solid_b.original_id()):
            side[starts[k]:starts[k + 1]] = 0 if run_id == solid_a.original_id() else 1
    return v, f, volume, side


def surface_samples(vertices: np.ndarray, faces: np.ndarray,
                    per_edge: int = EDGE_SAMPLES) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points on a triangle mesh: its vertices and, on each face, a barycentric grid (which
    includes points along its edges) with spacing about (the mesh's box diagonal) / per_edge.
    Returns (points (k, 3), face (k,) int, -1 for the vertices, barycentric step (k,))."""
    if len(faces) == 0:
        return np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0)
    tri = vertices[faces]
    spacing = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0))) / per_edge
    size = np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2), axis=1)
    steps = np.clip(np.ceil(size / spacing), 1, per_edge).astype(int) if spacing > 0 else np.ones(len(tri), int)
    points, face, step = [vertices], [np.full(len(vertices), -1)], [np.zeros(len(vertices))]
    for n in np.unique(steps):
        if n == 1:
            continue  # the vertices already are the grid
        ids = np.flatnonzero(steps == n)
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        uv = np.stack([i[keep] / n, j[keep] / n], axis=1)
        points.append(_on_faces(tri[ids], uv).reshape(-1, 3))
        face.append(np.repeat(ids, len(uv)))
        step.append(np.full(len(ids) * len(uv), 1.0 / n))
    return np.concatenate(points), np.concatenate(face), np.concatenate(step)


def _on_faces(tri: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Points (f, k, 3) at barycentric (u, v) (k, 2) on each triangle (f, 3, 3)."""
    u, v = uv[None, :, 0:1], uv[None, :, 1:2]
    return tri[:, None, 0] + u * (tri[:, None, 1] - tri[:, None, 0]) + v * (tri[:, None, 2] - tri[:, None, 0])


def _barycentric_uv(tri: np.ndarray, p: np.ndarray) -> np.ndarray | None:
    """(u, v) of point p on triangle tri (3, 3), p = t0 + u (t1 − t0) + v (t2 − t0); None
    for a degenerate triangle."""
    e1, e2, d = tri[1] - tri[0], tri[2] - tri[0], p - tri[0]
    m = np.array([[e1 @ e1, e1 @ e2], [e1 @ e2, e2 @ e2]])
    det = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    if not det > 1e-24 * (m[0, 0] * m[1, 1]) or not det > 0:
        return None  # a sliver face of the overlap: nothing to refine on
    return np.array([m[1, 1] * (d @ e1) - m[0, 1] * (d @ e2), m[0, 0] * (d @ e2) - m[0, 1] * (d @ e1)]) / det


def closest_points_on_triangles(tris: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The point of each triangle (n, 3, 3) closest to each point (n, 3), by the Voronoi
    regions of its vertices, edges and face (Ericson, Real-Time Collision Detection §5.1.5).
    Every test is a sign test on dot products, so the answer does not depend on the scene's
    size: trimesh.triangles.closest_point compares them with an absolute 1e-12 and is off
    by up to 75% for millimetre triangles. A zero-area triangle gets its nearest edge point."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    dot = lambda u, v: np.einsum("ij,ij->i", u, v)  # noqa: E731
    ab, ac, ap, bp, cp = b - a, c - a, points - a, points - b, points - c
    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        on_ab = a + (d1 / (d1 - d3))[:, None] * ab
        on_ac = a + (d2 / (d2 - d6))[:, None] * ac
        on_bc = b + ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None] * (c - b)
        total = va + vb + vc
        inside = a + (vb / total)[:, None] * ab + (vc / total)[:, None] * ac
    regions = [
        (d1 <= 0) & (d2 <= 0), (d3 >= 0) & (d4 <= d3), (vc <= 0) & (d1 >= 0) & (d3 <= 0),
        (d6 >= 0) & (d5 <= d6), (vb <= 0) & (d2 >= 0) & (d6 <= 0),
        (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), total > 0,
    ]
    out = np.select([r[:, None] for r in regions], [a, b, on_ab, c, on_ac, on_bc, inside], default=np.nan)
    bad = ~np.isfinite(out).all(axis=1)
    if bad.any():  # a zero-area triangle: the nearest point of its three edges
        out[bad] = _closest_on_edges(tris[bad], points[bad])
    return out


def _closest_on_edges(tris: np.ndarray, points: np.ndarray) -> np.ndarray:
    best, best_d = tris[:, 0].copy(), np.full(len(points), np.inf)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        p0, e = tris[:, i], tris[:, j] - tris[:, i]
        ee = np.einsum("ij,ij->i", e, e)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.clip(np.einsum("ij,ij->i", points - p0, e) / ee, 0.0, 1.0)
        t[~(ee > 0)] = 0.0
        q = p0 + t[:, None] * e
        d = np.linalg.norm(points - q, axis=1)
        closer = d < best_d
        best[closer], best_d[closer] = q[closer], d[closer]
    return best


def distance_to_surface(points: np.ndarray, mesh: trimesh.Trimesh, chunk: int = 4_000_000) -> np.ndarray:
    """Unsigned distance (m) of each point (n, 3) to the mesh's surface, exactly: each
    triangle t lies within the sphere (c_t, r_t) around its centroid, so |p − c_t| + r_t
    bounds p's distance from above and |p − c_t| − r_t from below; only the triangles whose
    lower bound does not exceed the smallest upper bound (or the distance to the triangle
    with the nearest centre) are measured."""
    if len(points) == 0:
        return np.zeros(0)
    tris = np.asarray(mesh.triangles)
    centre = tris.mean(axis=1)
    radius = np.linalg.norm(tris - centre[:, None, :], axis=2).max(axis=1)
    near = _may_be_nearest(points, centre, radius)
    tris, centre, radius = tris[near], centre[near], radius[near]
    best = np.full(len(points), np.inf)
    step = max(1, chunk // max(len(tris), 1))
    for start in range(0, len(points), step):
        p = points[start:start + step]
        to_centre = np.linalg.norm(p[:, None, :] - centre[None], axis=2)
        upper = (to_centre + radius[None]).min(axis=1)
        # The distance to the triangle with the nearest centre is an upper bound too, and for
        # a point on or near the surface (the overlap's are) a far tighter one: ~5 candidates
        # a point instead of ~35 on the soft ball. The nearest triangle stays a candidate, so
        # the distance is the same to the bit; the slack keeps rounding from dropping it.
        first = np.argmin(to_centre, axis=1)
        upper = np.minimum(upper, np.linalg.norm(closest_points_on_triangles(tris[first], p) - p, axis=1))
        rows, cols = np.nonzero(to_centre - radius[None] <= upper[:, None] * (1.0 + 1e-9) + 1e-300)
        closest = closest_points_on_triangles(tris[cols], p[rows])
        d = np.linalg.norm(closest - p[rows], axis=1)
        out = np.full(len(p), np.inf)
        np.minimum.at(out, rows, d)
        best[start:start + step] = out
    return best


def _may_be_nearest(points: np.ndarray, centre: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Indices of the triangles (centres (t, 3), bounding radii (t,)) that can be nearest to a
    point in the box around `points`: every point is within U = min_t (farthest box corner
    from c_t + r_t) of the surface, so a triangle whose sphere lies farther than U from the
    box is no point's nearest nor one of its candidates in distance_to_surface, whose result
    is therefore the same to the bit with or without the others. The overlap's points lie in
    a small box, so this leaves the triangles around it."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    far = np.linalg.norm(np.maximum(np.abs(centre - lo), np.abs(centre - hi)), axis=1)
    bound = float((far + radius).min())
    gap = np.linalg.norm(np.maximum(np.maximum(lo - centre, centre - hi), 0.0), axis=1)
    # A relative slack keeps rounding from dropping a triangle that is a candidate.
    return np.flatnonzero(gap - radius <= bound * (1.0 + 1e-9) + 1e-300)


def pair_penetration(a: trimesh.Trimesh, b: trimesh.Trimesh, refine: int = REFINE_POINTS) -> tuple[float, float]:
    """(depth m, overlap volume m³) of two closed meshes, as in the module docstring. The
    grid's `refine` deepest face points are then refined twice on an 8× finer local grid,
    so that a deepest point between grid points (a ridge crossing) is found to ~1/64 of
    the grid spacing."""
    v, f, volume, side = overlap(a, b)
    if len(f) == 0:
        return 0.0, 0.0

    def depth_at(points, sides):
        # A point of I's boundary is on one surface (distance ~0 to it) and `depth` from the
        # other: a point of a face of I on A's surface is measured against B's alone, and the
        # reverse; I's vertices (on the curve where the surfaces cross, or on either) and faces
        # the boolean does not attribute, against both.
        depth = np.zeros(len(points))
        for on, others in ((0, (b,)), (1, (a,)), (-1, (a, b))):
            at = sides == on
            if at.any():
                depth[at] = np.max([distance_to_surface(points[at], m) for m in others], axis=0)
        return depth

    points, face, step = surface_samples(v, f)
    point_side = np.where(face >= 0, side[np.maximum(face, 0)], -1)
    depth = depth_at(points, point_side)
    best = float(depth.max())
    tri = v[f]
    # Each of the deepest face points is refined on its own local grid, twice; the grids of
    # one level are measured in one batch (a point's distance does not depend on the batch).
    refining = []  # (triangle (3, 3), centre (u, v), spacing, side)
    for k in np.argsort(depth)[::-1][:refine]:
        if face[k] >= 0 and (centre := _barycentric_uv(tri[face[k]], points[k])) is not None:
            refining.append((tri[face[k]], centre, step[k], point_side[k]))
    for _ in range(2):
        grids = []
        for t, centre, h, on in refining:
            offsets = np.linspace(-h, h, 9)
            uv = (centre[None] + np.stack(np.meshgrid(offsets, offsets, indexing="ij"), -1).reshape(-1, 2))
            uv = uv[(uv[:, 0] >= 0) & (uv[:, 1] >= 0) & (uv.sum(axis=1) <= 1)]
            if len(uv):
                grids.append((t, uv, h, on))
        if not grids:
            break
        d_all = depth_at(np.concatenate([_on_faces(t[None], uv)[0] for t, uv, _, _ in grids]),
                         np.concatenate([np.full(len(uv), on, np.int8) for _, uv, _, on in grids]))
        best = max(best, float(d_all.max()))
        ends = np.cumsum([len(uv) for _, uv, _, _ in grids])
        refining = [(t, uv[int(np.argmax(d))], h / 8, on)
                    for (t, uv, h, on), d in zip(grids, np.split(d_all, ends[:-1]))]
    return best, volume


# Rows of bodies whose boxes are compared with all others at once (box_pairs): bounds the
# comparison's memory to BOX_BLOCK × n × 3 values.
BOX_BLOCK = 256


def box_pairs(bodies: list[tuple[str, str, trimesh.Trimesh]]) -> tuple[np.ndarray, int]:
    """The pairs (i, j), i < j, of bodies (name, kind, world mesh) not both static whose boxes
    meet (not boxes_apart), in order, as a (p, 2) array; and how many such pairs of bodies
    not both static there are in all. The same test as boxes_apart, on every pair at once:
    a scene of 1,000 bodies has 500,000 pairs, and one call per pair took a minute a frame."""
    n = len(bodies)
    if n < 2:
        return np.zeros((0, 2), np.int64), 0
    bounds = np.array([mesh.bounds for _, _, mesh in bodies], np.float64)  # (n, 2, 3)
    lo, hi = bounds[:, 0], bounds[:, 1]
    static = np.array([kind == "static" for _, kind, _ in bodies])
    found, total = [], 0
    for start in range(0, n, BOX_BLOCK):
        rows = np.arange(start, min(start + BOX_BLOCK, n))
        meet = ~np.any(np.maximum(lo[rows, None], lo[None]) > np.minimum(hi[rows, None], hi[None]), axis=2)
        wanted = (np.arange(n)[None] > rows[:, None]) & ~(static[rows, None] & static[None])
        total += int(wanted.sum())
        i, j = np.nonzero(meet & wanted)
        found.append(np.stack([rows[i], j], axis=1))
    return np.concatenate(found), total


def body_pairs(bodies: list[tuple[str, str, trimesh.Trimesh]], meeting: np.ndarray | None = None):
    """(name_a, name_b, depth m, overlap volume m³) for the pairs of bodies (name, kind, world
    mesh) that are not both static and whose boxes meet (box_pairs, or `meeting` if given: the
    others have neither depth nor volume), in order (pair_penetration; with a cloth,
    cloth.cloth_pair_depth and no volume: a sheet has none)."""
    for i, j in (box_pairs(bodies)[0] if meeting is None else meeting).tolist():
        (name_a, kind_a, a), (name_b, kind_b, b) = bodies[i], bodies[j]
        if "cloth" in (kind_a, kind_b):
            from .cloth import cloth_pair_depth  # (it builds on this module)

            depth, volume = cloth_pair_depth(a, kind_a, b, kind_b), 0.0
        else:
            depth, volume = pair_penetration(a, b)
        yield name_a, name_b, depth, volume


def scene_penetration(bodies: list[tuple[str, str, trimesh.Trimesh]]) -> Penetration:
    """The deepest pair and the total overlap volume over pairs of bodies (name, kind,
    world mesh) that are not both static, and how many pairs were measured and found apart."""
    result = Penetration()
    meeting, result.pairs = box_pairs(bodies)
    result.pairs_apart = result.pairs - len(meeting)
    for name_a, name_b, depth, volume in body_pairs(bodies, meeting):
        result.volume += volume
        if depth > result.depth or (result.pair is None and volume > 0):
            result.depth, result.pair = depth, (name_a, name_b)
    return result


# Erleben's tests pass (issue 5) when a run settles within its 5 s without NaN and the
# independent measure finds at most these (for scenes in metres; scaled scenes scale them).
PASS_FINAL_DEPTH = 1e-4     # m
PASS_FINAL_OVERLAP = 1e-9   # m³
PASS_MAX_DEPTH = 5e-3       # m, over the whole run (PyBullet and MuJoCo reach 15–23 mm)
# A soft body with self_collision: none of its own triangles cross at the end, none deeper
# than this in any frame (measure.self_intersection; metrics.json "self_intersection").
PASS_MAX_SELF_DEPTH = 1e-3  # m


def verdict(metrics: dict, length_scale: float = 1.0) -> str | None:
    """None if a run's metrics (metrics.json as a dict) pass the contact test, else the first
    criterion it fails, in words. `length_scale` scales the limits for a scaled scene
    (depths by it, volumes by its cube)."""
    if not metrics.get("complete"):
        return f"failed: {metrics.get('error') or 'incomplete'}"
    if not metrics.get("settled"):
        return "not settled"
    if metrics["final_penetration_depth"] > PASS_FINAL_DEPTH * length_scale:
        return f"final depth {metrics['final_penetration_depth']:.1e} m"
    if metrics["final_overlap_volume"] > PASS_FINAL_OVERLAP * length_scale ** 3:
        return f"final overlap {metrics['final_overlap_volume']:.1e} m³"
    if metrics["max_penetration_depth"] > PASS_MAX_DEPTH * length_scale:
        return f"max depth {metrics['max_penetration_depth']:.1e} m"
    for name, measured in metrics.get("self_intersection", {}).items():
        if measured["self_collision"] and measured["final_pairs"] > 0:
            return f"{name}: {measured['final_pairs']} pairs of its triangles cross at the end"
        if measured["self_collision"] and measured["max_depth"] > PASS_MAX_SELF_DEPTH * length_scale:
            return f"{name}: crossed itself by {measured['max_depth']:.1e} m"
    return None
