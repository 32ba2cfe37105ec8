"""The batch API's SIMD lanes against the one-pair code path the solver runs, bit for bit.

On CPU `collide_triangle_pairs` computes several pairs at once, one per lane of a vector
(`narrowphase._collide_packets_kernel`, compiled with Taichi's vectors left to LLVM), after
sorting the rows of each window by whether they need more than Möller's first test. The
solver calls `collide_triangle_pair` on one pair inside its kernels. Both are the same
Taichi functions, so every output must agree to the last bit, zeros' signs included, and
however the pairs fall into batches (a last, partial batch included).
"""

import numpy as np
import pytest

import taichi_dcd
from taichi_dcd.core import runtime
from taichi_dcd.collision.narrowphase import PACKET_BYTES, WINDOW_BATCHES, _collide_pairs_kernel

from conftest import random_pairs


def one_pair_each(a, b):
    """The outputs of the one-pair path (a kernel calling collide_triangle_pair per row)."""
    n = len(a)
    dtype = runtime.real_dtype()
    out = (np.empty(n, np.int8), np.empty(n, dtype), np.empty((n, 3), dtype), np.empty(n, np.int8),
           np.empty((n, 3), dtype))
    _collide_pairs_kernel(a.astype(dtype), b.astype(dtype), *out)
    return out


def varied_pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random pairs in four kinds, n each: independent in the unit cube; overlapping (B a
    jittered copy of A, half of them intersecting); touching by construction (a shared
    vertex, a shared edge, or B lying in a plane through A's first vertex); and on a
    quarter grid, where equal depths and coplanar vertices are common (ties)."""
    rng = np.random.default_rng(seed)
    cube = random_pairs(n, seed)
    a = rng.random((n, 3, 3))
    near = (a, a[:, [1, 2, 0]] + rng.normal(scale=0.2, size=(n, 3, 3)))
    a, b = rng.random((n, 3, 3)), rng.random((n, 3, 3))
    third = n // 3
    b[:third, 0] = a[:third, 0]
    b[third:2 * third, :2] = a[third:2 * third, [1, 0]]
    b[2 * third:, :, 2] = a[2 * third:, :1, 2]
    grid = np.round(rng.random((2, n, 3, 3)) * 4) / 4
    return (np.concatenate([cube[0], near[0], a, grid[0]]), np.concatenate([cube[1], near[1], b, grid[1]]))


@pytest.mark.parametrize("precision", ["f64", "f32"])
def test_lanes_give_the_one_pair_results_bit_for_bit(precision, request):
    request.getfixturevalue(precision)
    a, b = varied_pairs(5_000, seed=4242)
    got = taichi_dcd.collide_triangle_pairs(a, b)
    want = one_pair_each(a, b)

    assert 0.2 < got.hit.mean() < 0.5 and (got.side >= 0).sum() > 4_000
    for name, value, expected in zip(("hit", "depth", "normal", "side", "point"),
                                     (got.hit.view(np.int8), got.depth, got.normal, got.side, got.point), want):
        assert value.tobytes() == expected.tobytes(), f"{name} differs from the one-pair path"


def test_every_batch_size_and_offset_gives_the_same_rows(f64):
    """A pair's result does not depend on which lane of which batch it lands in, on which
    other rows of its window need the whole test, nor on the clamped rows that fill the
    last batch."""
    lanes = PACKET_BYTES // 8
    window = lanes * WINDOW_BATCHES
    a, b = varied_pairs(2 * window // 4 + 10, seed=7)
    whole = taichi_dcd.collide_triangle_pairs(a, b)
    for start, stop in [(0, 1), (3, 3 + lanes - 1), (5, 5 + lanes), (11, 11 + lanes + 1), (1, window + 1),
                        (window - 9, 2 * window + 17), (0, len(a))]:
        part = taichi_dcd.collide_triangle_pairs(a[start:stop], b[start:stop])
        assert part.depth.tobytes() == whole.depth[start:stop].tobytes()
        assert part.point.tobytes() == whole.point[start:stop].tobytes()
        np.testing.assert_array_equal(part.side, whole.side[start:stop])


def test_a_bad_pair_in_a_later_batch_is_named(f64):
    """The batch names the first bad pair, and the one-pair path marks the same rows bad."""
    a, b = random_pairs(50, seed=3)
    b[37, 2, 1] = np.nan
    a[44, 0, 0] = np.inf
    with pytest.raises(ValueError, match=r"^pair 37: triangle b has a NaN or infinite coordinate$"):
        taichi_dcd.collide_triangle_pairs(a, b)
    np.testing.assert_array_equal(np.flatnonzero(one_pair_each(a, b)[0] < 0), [37, 44])
