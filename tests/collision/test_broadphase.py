"""The grid's candidate pairs equal brute-force box overlap, whatever the triangle soup."""

import numpy as np
import pytest
import taichi as ti

import taichi_dcd

from taichi_dcd.collision.broadphase import BOX_SLACK, UniformGrid
from taichi_dcd.core.runtime import tolerance


def brute_pairs(x, tri_indices, tri_body, tri_static, margin=0.0) -> set:
    """All (a, b) with body[a] < body[b], not both static, whose closed boxes overlap
    (boxes padded by the margin, a length or one per triangle, and the narrow phase's
    tolerance, as the grid's are)."""
    tris = x[tri_indices]
    lo, hi = tris.min(axis=1), tris.max(axis=1)
    pad = np.reshape(margin, (-1, 1)) + BOX_SLACK * tolerance() * (hi - lo).max(axis=1, keepdims=True)
    lo, hi = lo - pad, hi + pad
    overlap = ((lo[:, None, :] <= hi[None, :, :]) & (lo[None, :, :] <= hi[:, None, :])).all(axis=2)
    keep = overlap & (tri_body[:, None] < tri_body[None, :]) & ~(tri_static[:, None] & tri_static[None, :])
    a, b = np.nonzero(keep)
    return set(zip(a.tolist(), b.tolist()))


def grid_pairs(grid: UniformGrid, x: np.ndarray) -> set:
    px = ti.ndarray(ti.types.vector(3, ti.f64), shape=len(x))
    px.from_numpy(x)
    grid.find_pairs(px)
    pairs = grid.pairs_numpy()
    found = [tuple(p) for p in pairs.tolist()]
    assert len(found) == len(set(found)), "a pair was reported twice"
    return set(found)


def soup(rng, n_bodies: int, tris_per_body: int, spread: float, size: float):
    """Bodies of random triangles around random centres: vertices (n, 3), faces (m, 3), body (m,)."""
    xs, faces, body = [], [], []
    for k in range(n_bodies):
        centre = rng.uniform(-spread, spread, 3)
        m = int(rng.integers(1, tris_per_body + 1))
        sizes = size * rng.uniform(0.2, 1.5, (m, 1, 1))
        tri = centre + sizes * rng.uniform(-1, 1, (m, 3, 3))
        faces.append(np.arange(3 * m).reshape(m, 3) + sum(len(v) for v in xs))
        xs.append(tri.reshape(-1, 3))
        body += [k] * m
    return np.concatenate(xs), np.concatenate(faces), np.array(body)


def check(x, faces, body, static=None, **grid_kwargs):
    static = np.zeros(len(faces), bool) if static is None else static
    grid = UniformGrid(faces, body, static, **grid_kwargs)
    expected = brute_pairs(x, faces, body, static, grid_kwargs.get("margin", 0.0))
    got = grid_pairs(grid, x)
    assert got == expected, f"missing {sorted(expected - got)[:5]}, extra {sorted(got - expected)[:5]}"
    return grid, expected


@pytest.mark.parametrize("seed", range(6))
def test_random_soups_match_brute_force(f64, seed):
    rng = np.random.default_rng(seed)
    n_bodies = int(rng.integers(2, 51))
    x, faces, body = soup(rng, n_bodies, tris_per_body=12, spread=1.0, size=0.3)
    _, expected = check(x, faces, body)
    assert len(expected) > 0


def test_ground_triangle_100_times_larger(f64):
    rng = np.random.default_rng(10)
    x, faces, body = soup(rng, 30, tris_per_body=8, spread=1.0, size=0.05)
    ground = np.array([[-100.0, -0.5, -100.0], [0.0, 0.3, 100.0], [100.0, -0.5, -100.0]])
    x = np.concatenate([x, ground])
    faces = np.concatenate([faces, [[len(x) - 3, len(x) - 2, len(x) - 1]]])
    body = np.concatenate([body, [body.max() + 1]])
    grid, expected = check(x, faces, body)
    assert sum(1 for a, b in expected if b == len(faces) - 1) > 10
    # The ground is binned at a coarse level, not into ~10^8 fine cells.
    assert grid.entries(0) < 8 * len(faces)


def test_slivers_and_zero_area_triangles(f64):
    rng = np.random.default_rng(11)
    x, faces, body = soup(rng, 20, tris_per_body=6, spread=0.5, size=0.3)
    tris = x[faces]
    # Every other triangle becomes a needle: its third vertex on its first edge,
    # or a point: all three vertices equal.
    tris[::2, 2] = tris[::2, 0] + 0.5 * (tris[::2, 1] - tris[::2, 0])
    tris[1::7, 1:] = tris[1::7, :1]
    check(tris.reshape(-1, 3), np.arange(3 * len(faces)).reshape(-1, 3), body)


@pytest.mark.parametrize("margin", [0.0, 0.1])
def test_triangles_on_cell_boundaries(f64, margin):
    rng = np.random.default_rng(12)
    h = 0.25
    # Vertices on the lattice of cell corners: many boxes touch exactly at a face,
    # an edge or a corner of a cell.
    tris = h * rng.integers(-4, 5, (300, 3, 3)).astype(float)
    body = rng.integers(0, 12, 300)
    x = tris.reshape(-1, 3)
    check(x, np.arange(len(x)).reshape(-1, 3), body, cell_size=h, margin=margin)


def test_everything_in_one_cell(f64):
    rng = np.random.default_rng(13)
    x, faces, body = soup(rng, 15, tris_per_body=10, spread=0.2, size=0.1)
    grid, expected = check(x + 50.0, faces, body, cell_size=100.0)
    binned = int((grid.tri_level.to_numpy() >= 0).sum())
    assert grid.entries(0) == binned > len(faces) // 2  # one cell each, the same cell
    assert len(expected) > 50


def test_static_bodies_binned_once_while_others_move(f64):
    rng = np.random.default_rng(14)
    x, faces, body = soup(rng, 12, tris_per_body=10, spread=0.6, size=0.3)
    static = np.isin(body, [0, 3, 4])
    grid, _ = check(x, faces, body, static)
    static_entries = grid.entries(1)
    moving_vertices = np.unique(faces[~static])
    for step in range(3):
        x = x.copy()
        x[moving_vertices] += rng.uniform(-0.2, 0.2, (len(moving_vertices), 3))
        expected = brute_pairs(x, faces, body, static)
        assert grid_pairs(grid, x) == expected
    assert grid.entries(1) == static_entries


def test_pair_buffer_overflow_grows_and_gives_the_same_pairs(f64):
    rng = np.random.default_rng(15)
    x, faces, body = soup(rng, 20, tris_per_body=10, spread=0.5, size=0.3)
    grid, expected = check(x, faces, body, pair_capacity=1)
    assert grid.pair_capacity >= len(expected) > 1


def test_f32_grid_matches_brute_force(f32):
    rng = np.random.default_rng(16)
    x, faces, body = soup(rng, 25, tris_per_body=10, spread=1.0, size=0.3)
    x = x.astype(np.float32)
    grid = UniformGrid(faces, body)
    px = ti.ndarray(ti.types.vector(3, ti.f32), shape=len(x))
    px.from_numpy(x)
    grid.find_pairs(px)
    got = set(map(tuple, grid.pairs_numpy().tolist()))
    assert got == brute_pairs(x, faces, body, np.zeros(len(faces), bool))


def test_skin_reuses_pairs_only_while_they_cover_the_exact_ones(f64):
    """With a skin the grid rebins only after some moving vertex moved 0.9 skin along an
    axis; every query's pairs still contain every overlapping pair, and right after a
    rebin they are the pairs of the inflated boxes."""
    rng = np.random.default_rng(17)
    x, faces, body = soup(rng, 12, tris_per_body=10, spread=0.6, size=0.3)
    static = np.isin(body, [0, 5])
    grid = UniformGrid(faces, body, static, cell_size=0.2, skin=0.5)
    skin = 0.5 * 0.2
    moving = np.unique(faces[~static])
    velocity = rng.uniform(-1, 1, (len(moving), 3))
    inflated = np.where(static, 0.0, skin)  # static triangles are never rebinned
    assert grid_pairs(grid, x) == brute_pairs(x, faces, body, static, margin=inflated)
    built = x.copy()
    for step in range(40):
        x = x.copy()
        x[moving] += 0.004 * velocity
        got = grid_pairs(grid, x)
        exact = brute_pairs(x, faces, body, static)
        assert exact <= got, f"step {step}: missing {sorted(exact - got)[:5]}"
        if np.abs(x[moving] - built[moving]).max() > 0.9 * skin:
            built = x.copy()
            assert got == brute_pairs(x, faces, body, static, margin=inflated)
    assert 2 <= grid.rebuilds <= 8 < grid.queries  # reused most of the time


def connected_soup(rng, n_bodies: int, strips: int, spread: float):
    """Bodies that are triangle strips folded at random (neighbours share vertices), so that
    pairs sharing a vertex are common: vertices (n, 3), faces (m, 3), body (m,)."""
    xs, faces, body = [], [], []
    offset = 0
    for k in range(n_bodies):
        n = strips + 2
        path = rng.uniform(-spread, spread, 3) + np.cumsum(rng.normal(0.0, 0.3, (n, 3)), axis=0)
        xs.append(path)
        faces.append(np.stack([np.arange(strips), np.arange(1, strips + 1), np.arange(2, strips + 2)], axis=1) + offset)
        body += [k] * strips
        offset += n
    return np.concatenate(xs), np.concatenate(faces), np.array(body)


@pytest.mark.parametrize("seed", range(4))
def test_self_colliding_bodies_add_their_own_pairs_but_near_neighbours(f64, seed):
    """With body_self, a body's own triangle pairs whose boxes overlap are candidates too,
    except near neighbours (a vertex shared, or two vertices joined by an edge of the mesh),
    both on the moving table's equal levels and across levels (static bodies never collide
    with themselves)."""
    rng = np.random.default_rng(100 + seed)
    x, faces, body = connected_soup(rng, 5, 60, 1.0)
    static = body == 4
    body_self = np.array([True, False, True, True, False])
    grid = UniformGrid(faces, body, static, body_self=body_self)
    expected = brute_pairs(x, faces, body, static)
    edges = {frozenset((int(f[i]), int(f[j]))) for f in faces for i, j in ((0, 1), (1, 2), (2, 0))}
    tris = x[faces]
    lo, hi = tris.min(axis=1), tris.max(axis=1)
    pad = BOX_SLACK * tolerance() * (hi - lo).max(axis=1, keepdims=True)
    lo, hi = lo - pad, hi + pad
    own = near = 0
    for a in range(len(faces)):
        for b in range(a + 1, len(faces)):
            if body[a] == body[b] and body_self[body[a]] and (lo[a] <= hi[b]).all() and (lo[b] <= hi[a]).all():
                if any(va == vb or frozenset((int(va), int(vb))) in edges for va in faces[a] for vb in faces[b]):
                    near += 1
                else:
                    expected.add((a, b))
                    own += 1
    got = {tuple(sorted(p)) for p in grid_pairs(grid, x)}
    assert own > 20 and near > 20
    assert got == expected, f"missing {sorted(expected - got)[:5]}, extra {sorted(got - expected)[:5]}"


def pairs_and_contacts(x, faces, body, static):
    """The candidate pairs and contacts of one query, in the order they come out."""
    from taichi_dcd.collision.pipeline import CollisionPipeline

    pipeline = CollisionPipeline(faces, body, static, keep_touching=True, pair_capacity=8)
    px = ti.ndarray(ti.types.vector(3, ti.f64), shape=len(x))
    px.from_numpy(x)
    pipeline.run(px)
    return pipeline.grid.pairs_numpy(), pipeline.contacts.to_numpy()


@pytest.mark.parametrize("seed", range(3))
def test_pairs_and_contacts_come_out_in_the_serial_order_on_two_threads(monkeypatch, seed):
    """Loops shared among threads (as above 200,000 iterations) append as the threads finish;
    the pairs and contacts must still come out in the one order a single thread gives, since a
    solver sweeps its rows in that order. Bodies of triangles of mixed sizes (several grid
    levels, so both kinds of query), one body static."""
    from taichi_dcd.core import runtime

    rng = np.random.default_rng(100 + seed)
    x, faces, body = soup(rng, n_bodies=12, tris_per_body=150, spread=1.0, size=0.3)
    big = rng.random(len(faces)) < 0.05
    x[faces[big]] *= 3.0  # a few triangles several levels up
    static = body == 0
    taichi_dcd.init(arch="cpu", precision="f64", debug=True, cpu_threads=1)
    pairs, contacts = pairs_and_contacts(x, faces, body, static)
    assert len(pairs) > 1000 and len(contacts) > 100
    assert set(map(tuple, pairs.tolist())) == brute_pairs(x, faces, body, static)
    monkeypatch.setattr(runtime, "PARALLEL_MIN_WORK", 0)
    taichi_dcd.init(arch="cpu", precision="f64", debug=True, cpu_threads=2)
    for _ in range(2):
        shared_pairs, shared = pairs_and_contacts(x, faces, body, static)
        np.testing.assert_array_equal(shared_pairs, pairs)
        np.testing.assert_array_equal(shared.pair, contacts.pair)
        np.testing.assert_array_equal(shared.depth, contacts.depth)
        np.testing.assert_array_equal(shared.normal, contacts.normal)
