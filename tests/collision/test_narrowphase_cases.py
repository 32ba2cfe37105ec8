"""Hand-worked triangle pairs: the supplement's listing example and its perpendicular cases.

Supplement §1 set-up: the red triangle R has normal (0, 1, 0) and lies in the plane
y = 0; the blue triangle B has normal (0, 0, 1) and lies in the plane z = 0. Each
case is passed as collide(a=R, b=B). Projecting B along N_R onto R's plane gives a
segment on the line z = 0 (the "projected line segment" of the captions); it
either fits inside R or does not. In every case B's deepest candidate is shallower
than R's, so B moves (side 1) along N_R = (0, 1, 0), by the depth of B below y = 0.

Notation in the docstrings: d_B = depth of B's deepest candidate below R's plane
(-y), d_R = depth of R's deepest candidate behind B's plane (-z). "R at z=0" is the
x-range R covers on the line z = 0, "B at y=0" the x-range B covers on y = 0.
Eq. 5's candidates never occur here: N_R·N_B = 0.
"""

import numpy as np
import pytest

import taichi_dcd

UP = (0.0, 1.0, 0.0)


def collide_one(a, b):
    r = taichi_dcd.collide_triangle_pairs(np.array([a], float), np.array([b], float))
    return bool(r.hit[0]), float(r.depth[0]), r.normal[0], int(r.side[0]), r.point[0]


def assert_blue_moves(a, b, depth, points):
    hit, got_depth, normal, side, point = collide_one(a, b)
    assert hit
    assert side == 1, "the blue triangle (b) must be the one moved"
    assert got_depth == pytest.approx(depth, abs=1e-12)
    np.testing.assert_allclose(normal, UP, atol=1e-15)
    assert any(np.allclose(point, p, atol=1e-12) for p in points), f"point {point} not one of {points}"


def test_listing_example(f64):
    """Supplement §4's example pair: triangle 1 lies in y = 0.299691 with normal +y;
    triangle 2's lower edge is at y = 0.26, so it is 0.299691 - 0.26 = 0.039691 below
    triangle 1's plane and is the one moved, along (0, 1, 0)."""
    t1 = [[0.375003, 0.299691, 0.299992], [-0.224997, 0.299691, -0.300008], [-0.224998, 0.299691, 0.299994]]
    t2 = [[-0.0749846, 0.26, 0.0999057], [0.125025, 0.26, 0.0999057], [-0.1750912, 0.36939, 0.0999057]]
    hit, depth, normal, side, point = collide_one(t1, t2)
    assert hit
    assert depth == pytest.approx(0.039691, abs=1e-6)
    np.testing.assert_allclose(normal, UP, atol=1e-6)
    assert side == 1
    assert point[1] == pytest.approx(0.26, abs=1e-12)


R_WIDE = [(-1, 0, 1), (1, 0, 1), (0, 0, -1)]  # R at z=0: (-0.5, 0.5); far vertex 1 behind B's plane
B_TIP = [(0, -0.1, 0), (0.3, 0.8, 0), (-0.3, 0.8, 0)]  # tip 0.1 below y=0; B at y=0: (-1/30, 1/30)
B_EDGE = [(-0.3, -0.1, 0), (0.3, -0.1, 0), (0, 0.8, 0)]  # edge 0.1 below y=0; B at y=0: (-0.2667, 0.2667)


def test_fig1_point_triangle_fits(f64):
    """B's tip (0, -0.1, 0) pierces R's face; B's segment x in [-0.3, 0.3] fits in R's (-0.5, 0.5).
    d_B: the tip projects to (0, 0, 0), inside R -> 0.1; B's edge images cross no edge of R.
    d_R: R's vertex (0, 0, -1) projects along z to (0, 0, 0), inside B -> 1.
    min is d_B = 0.1: B moves by 0.1, point = the tip."""
    assert_blue_moves(R_WIDE, B_TIP, 0.1, [(0, -0.1, 0)])


def test_fig2_point_triangle_does_not_fit(f64):
    """R small: R at z=0 is (-1/15, 1/15), B's segment [-0.3, 0.3] sticks out of it.
    d_B: tip -> (0, 0, 0) inside R -> 0.1; B's slanted edges cross R's edges at x = ±1/15
    where y = -0.1 + 0.9·(1/15)/0.3 = 0.1 above R (depth -0.1) -> d_B = 0.1.
    d_R: R's vertex (0, 0, -0.2) projects inside B -> 0.2. B moves by 0.1 at the tip."""
    r_small = [(-0.1, 0, 0.1), (0.1, 0, 0.1), (0, 0, -0.2)]
    assert_blue_moves(r_small, B_TIP, 0.1, [(0, -0.1, 0)])


def test_fig3_edge_triangle_fits(f64):
    """B's lower edge y = -0.1, x in [-0.3, 0.3], lies under R's face; it fits in R's (-0.5, 0.5).
    d_B: both edge vertices project inside R -> 0.1.
    d_R: R's vertex (0, 0, -1) projects inside B (B at y=0 is ±0.2667) -> 1.
    B moves by 0.1; either end of its lower edge is the deepest point."""
    assert_blue_moves(R_WIDE, B_EDGE, 0.1, [(-0.3, -0.1, 0), (0.3, -0.1, 0)])


def test_fig4_edge_triangle_does_not_fit(f64):
    """R at z=0 is (-0.075, 0.075): B's lower edge sticks out on both sides, so its vertices
    are not candidates. d_B: the edge's image crosses R's edges at x = ±0.075 -> points
    (±0.075, -0.1, 0), depth 0.1 (B's slanted edges cross there at y = 0.575, above R).
    d_R: R's vertex (0, 0, -0.3) projects inside B -> 0.3. B moves by 0.1."""
    r_narrow = [(-0.1, 0, 0.1), (0.1, 0, 0.1), (0, 0, -0.3)]
    assert_blue_moves(r_narrow, B_EDGE, 0.1, [(-0.075, -0.1, 0), (0.075, -0.1, 0)])


R_TIP = [(-0.5, 0, 0.5), (0.5, 0, 0.5), (0, 0, -0.2)]  # R at z=0: (-1/7, 1/7); tip 0.2 behind B


def test_fig5_point_point_fits(f64):
    """Both tips pierce the other triangle. B = tip (0, -0.1, 0), top at y = 0.5, x in
    [-0.1, 0.1]: fits in R's (-1/7, 1/7). d_B: the tip projects inside R -> 0.1, and B's
    image crosses no edge of R. d_R: R's tip (0, 0, -0.2) projects to (0, 0, 0), inside B
    (B at y=0 is ±1/60) -> 0.2. B moves by 0.1 at its tip."""
    b_narrow = [(0, -0.1, 0), (0.1, 0.5, 0), (-0.1, 0.5, 0)]
    assert_blue_moves(R_TIP, b_narrow, 0.1, [(0, -0.1, 0)])


def test_fig6_point_point_does_not_fit(f64):
    """As Fig. 5 with B wide, x in [-0.5, 0.5], outside R's (-1/7, 1/7). d_B: tip -> 0.1; B's
    slanted edges cross R's edges at x = ±1/7 where y = -0.1 + 0.6·(1/7)/0.5 > 0 (depth < 0).
    d_R: R's tip projects inside B (B at y=0 is ±1/12) -> 0.2. B moves by 0.1 at its tip."""
    b_wide = [(0, -0.1, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0)]
    assert_blue_moves(R_TIP, b_wide, 0.1, [(0, -0.1, 0)])


def test_fig7_edge_edge(f64):
    """R's edge z = -0.1, x in [-0.5, 0.5], lies behind B's plane; B's edge y = -0.05, x in
    [-0.3, 0.3], lies under R's plane. d_B: B's edge vertices project inside R (R at z=0 is
    ±0.4167) -> 0.05. d_R: R's edge vertices project outside B (B at y=0 is ±0.2824), but
    its image crosses B's slanted edges at x = ±0.2824 -> points (±0.2824, 0, -0.1), depth
    0.1. min is d_B = 0.05: B moves by 0.05 at either end of its edge."""
    r_edge = [(0.5, 0, -0.1), (-0.5, 0, -0.1), (0, 0, 0.5)]
    b_edge = [(-0.3, -0.05, 0), (0.3, -0.05, 0), (0, 0.8, 0)]
    assert_blue_moves(r_edge, b_edge, 0.05, [(-0.3, -0.05, 0), (0.3, -0.05, 0)])


def test_fig8_projection_onto_an_edge_is_touching(f64):
    """R's edge from (-0.5, 0, 0) to (0.5, 0, 0) lies in B's plane z = 0, and B projected along
    N_R lands on that edge's line. R's distances to B's plane are 0, 0, -0.6: no vertex on the
    positive side, so Möller's test (threshold 0) reports touching: no hit, no constraint."""
    r_on_line = [(-0.5, 0, 0), (0.5, 0, 0), (0, 0, -0.6)]
    hit, depth, normal, side, _ = collide_one(r_on_line, B_EDGE)
    assert not hit
    assert depth == 0.0 and side == -1
    np.testing.assert_array_equal(normal, [0, 0, 0])


R_EDGE_ALONG_Z = [(0, 0, -0.5), (0, 0, 0.5), (0.6, 0, 0.1)]  # edge x = 0 crosses B's plane; R at z=0: (0, 0.5)


def test_fig9_point_edge_fits(f64):
    """B's tip (0.02, -0.1, 0) pierces R just beside R's edge x = 0; B's segment x in
    [0.01, 0.1] fits in R's (0, 0.5). d_B: tip -> inside R -> 0.1; no crossings.
    d_R: R's vertices project outside B (B at y=0 is (0.0183, 0.0333)); R's edge from
    (0.6, 0, 0.1) to (0, 0, -0.5) has its image cross B's left edge at x = 0.0183, where
    z = 0.1 - 0.6·(0.6 - 0.0183)/0.6 = -0.4817 -> d_R = 0.4817. B moves by 0.1 at its tip."""
    b_narrow = [(0.02, -0.1, 0), (0.1, 0.5, 0), (0.01, 0.5, 0)]
    assert_blue_moves(R_EDGE_ALONG_Z, b_narrow, 0.1, [(0.02, -0.1, 0)])


def test_fig10_point_edge_does_not_fit(f64):
    """As Fig. 9 with B wide, x in [-0.2, 0.3], so R's edge x = 0 passes through B (B at y=0 is
    (-0.0167, 0.0667)). d_B: tip -> 0.1; B's left edge image crosses R's edge x = 0 at
    y = -0.1 + 0.6·(0.02/0.22) = -0.0455 -> 0.0455 < 0.1. d_R: R's vertex (0, 0, -0.5)
    projects to (0, 0, 0), inside B -> 0.5. B moves by 0.1 at its tip."""
    b_wide = [(0.02, -0.1, 0), (0.3, 0.5, 0), (-0.2, 0.5, 0)]
    assert_blue_moves(R_EDGE_ALONG_Z, b_wide, 0.1, [(0.02, -0.1, 0)])


def test_symmetric_tie_is_resolved_the_same_way_in_either_order(f64):
    """Fig. 7 with B's edge at y = -0.1: d_B = 0.1 (B's edge vertices project inside R) and
    d_R = 0.1 (R's edge image crosses B's edges at x = ±0.2667, z = -0.1): a tie, which the
    published listing drops (strict inequalities). Ours moves the triangle whose vertex sum
    is lexicographically smaller: R's (0, 0, 0.3) < B's (0, 0.6, 0), so R moves along
    N_B = (0, 0, 1) by 0.1, whichever argument it is."""
    r_edge = [(0.5, 0, -0.1), (-0.5, 0, -0.1), (0, 0, 0.5)]
    b_edge = [(-0.3, -0.1, 0), (0.3, -0.1, 0), (0, 0.8, 0)]
    for a, b, r_side in [(r_edge, b_edge, 0), (b_edge, r_edge, 1)]:
        hit, depth, normal, side, point = collide_one(a, b)
        assert hit and side == r_side
        assert depth == pytest.approx(0.1, abs=1e-12)
        np.testing.assert_allclose(normal, (0, 0, 1), atol=1e-15)
        assert point[2] == pytest.approx(-0.1, abs=1e-12) and abs(point[0]) == pytest.approx(0.8 / 3, abs=1e-12)
