"""The substep guards of discrete detection (tunnelling.py): wall thickness from ray casts
against analytic boxes, and the impact-depth substep rule against a per-pair loop."""

import math

import numpy as np
import pytest
import trimesh

from taichi_dcd.tunnelling import mesh_thickness, substeps_for_impacts


@pytest.mark.parametrize("size", [(1.0, 1.0, 1.0), (2.0, 0.01, 2.0), (3e-4, 1e-4, 2e-4)])
def test_thickness_of_a_box_is_its_thinnest_side(size):
    box = trimesh.creation.box(extents=size)
    assert mesh_thickness(box.vertices, box.faces) == pytest.approx(min(size), rel=1e-9)


def impacts_by_loops(lo, hi, velocity, spin, moving, dt, g, step, substeps):
    """Every pair of bodies, one at a time: how far can they close in this frame, can
    their grown boxes touch, and how many substeps keep that within `step` per substep?"""
    best = substeps
    for a in range(len(spin)):
        for b in range(len(spin)):
            if a == b or not (moving[a] or moving[b]):
                continue
            va = velocity[a] if moving[a] else np.zeros(3)
            vb = velocity[b] if moving[b] else np.zeros(3)
            closing = math.dist(va, vb) + (spin[a] if moving[a] else 0.0) + (spin[b] if moving[b] else 0.0) + g * dt
            reach = closing * dt
            separated = any(lo[a][k] - hi[b][k] > reach or lo[b][k] - hi[a][k] > reach for k in range(3))
            if not separated:
                best = max(best, math.ceil(reach / step))
    return best


def test_impact_substeps_match_a_loop_over_pairs():
    rng = np.random.default_rng(7)
    for trial in range(300):
        n = int(rng.integers(2, 12))
        lo = rng.uniform(-2.0, 2.0, (n, 3))
        hi = lo + rng.uniform(0.01, 1.0, (n, 3))
        velocity = rng.normal(0.0, 10.0, (n, 3)) * (rng.random((n, 1)) < 0.8)
        spin = rng.uniform(0.0, 5.0, n)
        moving = rng.random(n) < 0.7
        substeps = int(rng.integers(1, 20))
        got, a, b = substeps_for_impacts(lo, hi, velocity, spin, moving, 0.01, 9.8, 2e-3, substeps)
        assert got == impacts_by_loops(lo, hi, velocity, spin, moving, 0.01, 9.8, 2e-3, substeps), trial
        if got > substeps:
            assert moving[a] or moving[b]


def test_a_body_falling_onto_the_ground_takes_substeps_for_its_speed_only_when_near():
    """A 1 m box 5 cm above a static ground, falling at 9.902 m/s: with |g|·dt it closes in
    by up to 0.1 m in the 0.01 s frame, which at 2 mm per substep takes 50 substeps; 1 m
    above the ground it takes the 10. A second box falling beside it at the same speed
    asks for nothing more."""
    ground = ([-5.0, -1.0, -5.0], [5.0, 0.0, 5.0])
    fall = [0.0, -9.902, 0.0]
    near = substeps_for_impacts(np.array([ground[0], [-0.5, 0.05, -0.5]]), np.array([ground[1], [0.5, 1.05, 0.5]]),
                                np.array([[0.0] * 3, fall]), np.zeros(2), np.array([False, True]), 0.01, 9.8, 2e-3, 10)
    assert near == (50, 0, 1)
    far = substeps_for_impacts(np.array([ground[0], [-0.5, 1.0, -0.5]]), np.array([ground[1], [0.5, 2.0, 0.5]]),
                               np.array([[0.0] * 3, fall]), np.zeros(2), np.array([False, True]), 0.01, 9.8, 2e-3, 10)
    assert far == (10, -1, -1)
    side_by_side = substeps_for_impacts(np.array([[-0.5, 1.0, -0.5], [0.51, 1.0, -0.5]]),
                                        np.array([[0.5, 2.0, 0.5], [1.51, 2.0, 0.5]]), np.array([fall, fall]),
                                        np.zeros(2), np.array([True, True]), 0.01, 9.8, 2e-3, 10)
    assert side_by_side == (10, -1, -1)
    # Two static bodies that overlap never ask for substeps.
    assert substeps_for_impacts(np.zeros((2, 3)), np.ones((2, 3)), np.ones((2, 3)), np.ones(2),
                                np.array([False, False]), 0.01, 9.8, 2e-3, 10) == (10, -1, -1)
