"""Property-based checks of the narrow phase on hostile inputs (hypothesis).

Whatever the pair: no NaN or infinity in the output, depth >= 0, a unit normal
exactly when there is a constraint, and `side` consistent with depth and hit.
"""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import taichi_dcd
from taichi_dcd.core import runtime

finite = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False, allow_infinity=False)


@st.composite
def hostile_batches(draw):
    """Batches of pairs mixing the hard cases: a scale from 1e-12 to 1e12, an offset,
    coordinates drawn from a tiny pool (repeats, shared vertices and edges, coplanarity),
    B nearly parallel to A, and slivers (a vertex nudged off a line)."""
    # Hypothesis's own floats favour 0 and ±1 (almost no pair would intersect): the base
    # pairs come from a drawn seed, the hostile transformations from hypothesis.
    pairs = np.random.default_rng(draw(st.integers(0, 2**32 - 1))).uniform(-1.0, 1.0, (32, 2, 3, 3))
    kind = draw(st.sampled_from(["plain", "pool", "parallel", "sliver"]))
    if kind == "pool":
        pool = np.array(draw(st.lists(finite, min_size=2, max_size=4)))
        idx = draw(arrays(np.int64, pairs.shape, elements=st.integers(0, len(pool) - 1)))
        pairs = pool[idx]
    elif kind == "parallel":
        tilt = draw(st.sampled_from([0.0, 1e-15, 1e-12, 1e-9, 1e-6]))
        shift = draw(st.sampled_from([0.0, 1e-12, 1e-9]))
        pairs[:, 1] = pairs[:, 0] * (1.0 + tilt) + shift
        pairs[:, 1, :, 1] += draw(st.sampled_from([0.0, 1e-13, -1e-13]))
    elif kind == "sliver":
        t = draw(st.floats(0.0, 1.0))
        nudge = draw(st.sampled_from([0.0, 1e-16, 1e-12, 1e-8]))
        pairs[:, 0, 2] = pairs[:, 0, 0] + t * (pairs[:, 0, 1] - pairs[:, 0, 0]) + nudge
    scale = draw(st.sampled_from([1e-12, 1e-6, 1e-3, 1.0, 1e3, 1e6, 1e12]))
    offset = draw(st.sampled_from([0.0, 1.0, 1e3])) * scale
    return pairs * scale + offset


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(batch=hostile_batches())
def test_output_is_always_well_formed(f64, batch):
    r = taichi_dcd.collide_triangle_pairs(batch[:, 0], batch[:, 1])
    assert np.all(np.isfinite(r.depth)) and np.all(np.isfinite(r.normal)) and np.all(np.isfinite(r.point))
    assert np.all(r.depth >= 0.0)
    constrained = r.side >= 0
    assert np.all(r.hit[constrained]), "a constraint without a hit"
    assert np.all(r.depth[constrained] > 0.0) and np.all(r.depth[~constrained] == 0.0)
    np.testing.assert_allclose(np.linalg.norm(r.normal[constrained], axis=1), 1.0, atol=1e-9)
    assert np.all(r.normal[~constrained] == 0.0)
    assert set(np.unique(r.side)) <= {-1, 0, 1}
    # Swapping the arguments swaps the side and keeps the depth, exactly for depths well
    # above the rounding noise (~TOL_ULPS·eps·L). Nearer to it, rounding differs with the
    # argument order (hypothesis found 0.2% on depths 5x the tolerance), but only within
    # the noise.
    s = taichi_dcd.collide_triangle_pairs(batch[:, 1], batch[:, 0])
    edges = np.linalg.norm(batch - np.roll(batch, 1, axis=2), axis=-1).max(axis=(1, 2))
    noise = 1e3 * runtime.tolerance() * edges
    clear = r.depth > noise
    np.testing.assert_array_equal(s.side[clear], 1 - r.side[clear])
    np.testing.assert_allclose(s.depth[clear], r.depth[clear], rtol=1e-9)
    assert np.all(np.abs(s.depth - r.depth)[~clear] <= noise[~clear])
