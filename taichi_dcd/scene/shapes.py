"""Built-in procedural shapes, usable in scene files as `shape = "..."` with their
parameters in `[body.params]`. Each returns a closed, outward-oriented, watertight
trimesh.Trimesh without T-junctions (y up, metres), but `sheet`, an open square for a cloth.

The Erleben shapes (spike, wedge, crack_block, hole_block, ground) stand on y = 0:
their lowest face lies in that plane (the ground's top face does), centred on x and z.
`box` and `icosphere` are centred on the origin. Every shape takes `subdivisions`:
each face split that many times into four (the same surface, 4^n times the triangles).
"""

import numpy as np
import trimesh


def box(size=(1.0, 1.0, 1.0), subdivisions: int = 0) -> trimesh.Trimesh:
    """An axis-aligned box of extents `size` (x, y, z), each face split `subdivisions`
    times into four."""
    mesh = trimesh.creation.box(extents=[float(s) for s in size])
    for _ in range(int(subdivisions)):
        mesh = mesh.subdivide()
    return mesh


def icosphere(radius: float = 0.5, subdivisions: int = 3) -> trimesh.Trimesh:
    """An icosphere (20·4^subdivisions triangles; 3 gives 1,280)."""
    return trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=float(radius))


def spike(base: float = 1.0, height: float = 3.0) -> trimesh.Trimesh:
    """A square pyramid: base `base` × `base` in the plane y = 0, apex at (0, height, 0)."""
    h = 0.5 * _positive("base", base)
    v = [(-h, 0, -h), (h, 0, -h), (h, 0, h), (-h, 0, h), (0, _positive("height", height), 0)]
    f = [(0, 1, 2), (0, 2, 3), (3, 2, 4), (2, 1, 4), (1, 0, 4), (0, 3, 4)]
    return _mesh(v, f)


def wedge(base: float = 1.0, height: float = 3.0, length: float = 2.0) -> trimesh.Trimesh:
    """A triangular prism along z: cross-section `base` wide at y = 0 with its ridge at
    (0, height), `length` long (z from −length/2 to length/2)."""
    h = 0.5 * _positive("base", base)
    return extrude([(-h, 0.0), (h, 0.0), (0.0, _positive("height", height))], length)


def crack_block(size=(2.0, 1.0, 4.0), width: float = 1.0, depth: float = 0.5) -> trimesh.Trimesh:
    """A block `size` (x, y, z), bottom at y = 0, with a V-groove along z in its top face:
    `width` wide at the top, `depth` deep (1 and 0.5 give a 90° opening), bottom line at
    x = 0, y = size_y − depth."""
    sx, sy, sz = (_positive(f"size[{i}]", s) for i, s in enumerate(size))
    w, d = 0.5 * _positive("width", width), _positive("depth", depth)
    if not (w < 0.5 * sx and d < sy):
        raise ValueError(f"the groove ({width} wide, {depth} deep) must fit inside the block {size}")
    x = 0.5 * sx
    outline = [(-x, 0.0), (x, 0.0), (x, sy), (w, sy), (0.0, sy - d), (-w, sy), (-x, sy)]
    return extrude(outline, sz)


def hole_block(size=(2.0, 1.0, 2.0), hole: float = 1.0, depth: float = 0.5, pit: bool = False) -> trimesh.Trimesh:
    """A block `size` (x, y, z), bottom at y = 0, with a `hole` × `hole` opening centred in
    its top face, `depth` deep: a square pocket with vertical walls and a flat floor, or
    with `pit = true` an inverted square pyramid with its apex at (0, size_y − depth, 0)."""
    sx, sy, sz = (_positive(f"size[{i}]", s) for i, s in enumerate(size))
    a, d = 0.5 * _positive("hole", hole), _positive("depth", depth)
    if not (a < 0.5 * min(sx, sz) and d < sy):
        raise ValueError(f"the hole ({hole} wide, {depth} deep) must fit inside the block {size}")
    X, Z = 0.5 * sx, 0.5 * sz
    # 0-3 bottom corners, 4-7 top outer corners, 8-11 opening corners, each ring clockwise seen from +y
    v = [(-X, 0, -Z), (X, 0, -Z), (X, 0, Z), (-X, 0, Z),
         (-X, sy, -Z), (X, sy, -Z), (X, sy, Z), (-X, sy, Z),
         (-a, sy, -a), (a, sy, -a), (a, sy, a), (-a, sy, a)]
    f = [(0, 1, 2), (0, 2, 3)]                                       # bottom
    for i in range(4):
        j = (i + 1) % 4
        f += [(i, 4 + j, j), (i, 4 + i, 4 + j)]                      # outer walls
        f += [(4 + i, 8 + j, 4 + j), (4 + i, 8 + i, 8 + j)]          # top ring
    if pit:
        v.append((0, sy - d, 0))
        f += [(8 + i, 12, 8 + (i + 1) % 4) for i in range(4)]        # pit faces
    else:
        v += [(-a, sy - d, -a), (a, sy - d, -a), (a, sy - d, a), (-a, sy - d, a)]
        for i in range(4):
            j = (i + 1) % 4
            f += [(8 + i, 12 + j, 8 + j), (8 + i, 12 + i, 12 + j)]   # pocket walls
        f += [(12, 14, 13), (12, 15, 14)]                            # pocket floor
    return _mesh(v, f)


def ground(size=(12.0, 1.0, 12.0)) -> trimesh.Trimesh:
    """A slab `size` (x, y, z) with its top face at y = 0, centred on x and z."""
    sx, sy, sz = (_positive(f"size[{i}]", s) for i, s in enumerate(size))
    mesh = trimesh.creation.box(extents=[sx, sy, sz])
    mesh.apply_translation([0.0, -0.5 * sy, 0.0])
    return mesh


def coil(coil_radius: float = 0.5, tube_radius: float = 0.08, pitch: float = 0.3, turns: float = 3.0,
         sides: int = 8, segments_per_turn: int = 32) -> trimesh.Trimesh:
    """A tube of radius `tube_radius` wound as a helix about the y axis: `coil_radius` from the
    axis, rising `pitch` per turn over `turns` turns, its centreline starting `tube_radius`
    above y = 0. The tube's section is a `sides`-gon, the helix `segments_per_turn` straight
    pieces a turn, and each end a half-sphere (sides // 4 rings and a pole): a flat end's rim
    would be a sharp edge for the turns above to catch on. A pitch below twice the tube
    radius makes the turns cross."""
    R, r, p = _positive("coil_radius", coil_radius), _positive("tube_radius", tube_radius), _positive("pitch", pitch)
    turns = _positive("turns", turns)
    if r >= R:
        raise ValueError(f"tube_radius ({r}) must be smaller than coil_radius ({R})")
    sides, per_turn = int(sides), int(segments_per_turn)
    if sides < 4 or per_turn < 3:
        raise ValueError("a coil needs at least 4 sides and 3 segments per turn")
    theta = np.linspace(0.0, 2.0 * np.pi * turns, max(int(round(turns * per_turn)), 1) + 1)
    centre = np.c_[R * np.cos(theta), r + p * theta / (2.0 * np.pi), R * np.sin(theta)]
    tangent = np.c_[-R * np.sin(theta), np.full(len(theta), p / (2.0 * np.pi)), R * np.cos(theta)]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    inward = np.c_[-np.cos(theta), np.zeros(len(theta)), -np.sin(theta)]   # towards the axis, across the tangent
    binormal = np.cross(tangent, inward)
    # Rings (centre, radius, frame) along the tube, the half-spheres' rings at the ends.
    cap = np.linspace(0.0, 0.5 * np.pi, sides // 4 + 2)[1:-1]
    ring_centre, ring_radius, ring_frame = [], [], []
    for end, sign in ((0, -1.0), (-1, 1.0)):
        part_c = [centre[end] + sign * r * np.sin(a) * tangent[end] for a in cap]
        part_r = [r * np.cos(a) for a in cap]
        if end == 0:
            part_c, part_r = part_c[::-1], part_r[::-1]
            ring_centre += part_c + list(centre)
            ring_radius += part_r + [r] * len(centre)
            ring_frame += [(inward[0], binormal[0])] * len(cap) + list(zip(inward, binormal))
        else:
            ring_centre += part_c
            ring_radius += part_r
            ring_frame += [(inward[-1], binormal[-1])] * len(cap)
    phi = 2.0 * np.pi * np.arange(sides) / sides
    ring = np.array([c + rr * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * w)
                     for c, rr, (u, w) in zip(ring_centre, ring_radius, ring_frame)])
    n_rings = len(ring)
    v = np.vstack([ring.reshape(-1, 3), centre[0] - r * tangent[0], centre[-1] + r * tangent[-1]])
    start, end = len(v) - 2, len(v) - 1
    f = []
    for i in range(n_rings - 1):
        for k in range(sides):
            a, b = i * sides + k, i * sides + (k + 1) % sides
            f += [(a, b, b + sides), (a, b + sides, a + sides)]
    last = (n_rings - 1) * sides
    for k in range(sides):
        f += [(start, (k + 1) % sides, k), (end, last + k, last + (k + 1) % sides)]
    mesh = _mesh(v, f)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def torus(major_radius: float = 0.5, minor_radius: float = 0.15, sections: int = 48,
          tube_sections: int = 12) -> trimesh.Trimesh:
    """A ring about y centred on the origin: a tube of radius `minor_radius` around a circle of
    radius `major_radius` in y = 0, `sections` × `tube_sections` quads of two triangles."""
    major, minor = _positive("major_radius", major_radius), _positive("minor_radius", minor_radius)
    if not minor < major:
        raise ValueError(f"minor_radius must be below major_radius, got {minor} and {major}")
    for name, value in (("sections", sections), ("tube_sections", tube_sections)):
        if isinstance(value, bool) or not isinstance(value, int) or not 3 <= value <= 1000:
            raise ValueError(f"{name} must be a whole number from 3 to 1000, got {value!r}")
    ring = trimesh.creation.torus(major, minor, major_sections=sections, minor_sections=tube_sections)
    ring.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1.0, 0.0, 0.0]))  # z-axis ring -> y
    if ring.volume < 0:
        ring.invert()
    return ring


def sheet(size: float = 1.0, cells: int = 20) -> trimesh.Trimesh:
    """An open square sheet for a cloth: `size` × `size` in the plane y = 0, centred on the
    origin, `cells` × `cells` squares each cut into two triangles, the diagonals alternating
    so that the sheet folds alike along both axes; normals +y."""
    size = _positive("size", size)
    if isinstance(cells, bool) or not isinstance(cells, int) or not 1 <= cells <= 1000:
        raise ValueError(f"cells must be a whole number from 1 to 1000, got {cells!r}")
    t = np.linspace(-0.5 * size, 0.5 * size, cells + 1)
    x, z = np.meshgrid(t, t, indexing="ij")
    vertices = np.column_stack([x.ravel(), np.zeros(x.size), z.ravel()])
    faces = []
    for i in range(cells):
        for j in range(cells):
            a, b = i * (cells + 1) + j, (i + 1) * (cells + 1) + j  # (i, j), (i+1, j)
            c, d = b + 1, a + 1                                     # (i+1, j+1), (i, j+1)
            if (i + j) % 2 == 0:
                faces += [(a, d, c), (a, c, b)]
            else:
                faces += [(a, d, b), (d, c, b)]
    return _mesh(vertices, faces)


def extrude(outline, length: float) -> trimesh.Trimesh:
    """A prism: the simple polygon `outline` ((x, y) pairs, counter-clockwise, no repeated
    point) extruded along z from −length/2 to length/2; caps by ear clipping, sides as quads."""
    p = np.asarray(outline, np.float64)
    n = len(p)
    z = 0.5 * _positive("length", length)
    v = np.vstack([np.c_[p, np.full(n, z)], np.c_[p, np.full(n, -z)]])
    caps = _ear_clip(p)
    f = [tuple(t) for t in caps]                                     # front cap (+z), counter-clockwise
    f += [(n + c, n + b, n + a) for a, b, c in caps]                 # back cap (−z), reversed
    for i in range(n):
        j = (i + 1) % n
        f += [(i, n + i, n + j), (i, n + j, j)]
    return _mesh(v, f)


def _ear_clip(p: np.ndarray) -> list[tuple[int, int, int]]:
    """Counter-clockwise triangles covering the simple counter-clockwise polygon p (n, 2)."""
    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    area2 = sum(cross((0.0, 0.0), p[i], p[(i + 1) % len(p)]) for i in range(len(p)))
    if not area2 > 0:
        raise ValueError("an outline must be a counter-clockwise polygon with positive area")
    left = list(range(len(p)))
    tris = []
    while len(left) > 3:
        for k in range(len(left)):
            a, b, c = left[k - 1], left[k], left[(k + 1) % len(left)]
            if cross(p[a], p[b], p[c]) <= 0:
                continue                                             # reflex corner
            if any(cross(p[a], p[b], p[q]) >= 0 and cross(p[b], p[c], p[q]) >= 0 and cross(p[c], p[a], p[q]) >= 0
                   for q in left if q not in (a, b, c)):
                continue                                             # another corner inside the ear
            tris.append((a, b, c))
            left.pop(k)
            break
        else:
            raise ValueError("the outline is not a simple polygon")
    tris.append(tuple(left))
    return tris


def _positive(name: str, value) -> float:
    value = float(value)
    if not value > 0:
        raise ValueError(f"{name} must be positive, got {value}")
    return value


def _mesh(vertices, faces) -> trimesh.Trimesh:
    return trimesh.Trimesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int64), process=False)


SHAPES = {"box": box, "icosphere": icosphere, "spike": spike, "wedge": wedge, "crack_block": crack_block,
          "hole_block": hole_block, "ground": ground, "coil": coil, "sheet": sheet, "torus": torus}


def make_shape(name: str, params: dict) -> trimesh.Trimesh:
    """The built-in shape `name` with keyword `params`; ValueError for an unknown name or parameter."""
    if name not in SHAPES:
        raise ValueError(f"unknown shape {name!r} (built-in: {', '.join(SHAPES)})")
    params = dict(params)
    refine = 0 if name in ("box", "icosphere", "coil", "sheet", "torus") else params.pop("subdivisions", 0)
    try:
        mesh = SHAPES[name](**params)
    except TypeError as exc:
        raise ValueError(f"shape {name!r}: bad parameters {params} ({exc})") from None
    return subdivided(mesh, refine)


# Above this a shape would hold more than ~20 million triangles.
MAX_SUBDIVISIONS = 10


def subdivided(mesh: trimesh.Trimesh, times) -> trimesh.Trimesh:
    """The mesh with each face split `times` times into four at its edge midpoints: the
    same surface, still closed and without T-junctions (neighbours share the midpoints)."""
    if isinstance(times, bool) or not isinstance(times, int) or not 0 <= times <= MAX_SUBDIVISIONS:
        raise ValueError(f"subdivisions must be a whole number from 0 to {MAX_SUBDIVISIONS}, got {times!r}")
    for _ in range(times):
        mesh = mesh.subdivide()
    return mesh
