"""Pure geometry functions against slow, obvious references on seeded random data."""

import numpy as np
import taichi as ti

from taichi_dcd.core.geometry import closest_on_segments


def closest_on_segments_numpy(p0, p1, q0, q1, n=801):
    """Brute force: the nearest pair over an n × n grid of parameters; returns its distance."""
    s = np.linspace(0.0, 1.0, n)
    on_p = p0 + s[:, None] * (p1 - p0)
    on_q = q0 + s[:, None] * (q1 - q0)
    return np.sqrt(((on_p[:, None, :] - on_q[None, :, :]) ** 2).sum(-1).min())


def segment_cases(seed: int) -> np.ndarray:
    """(N, 4, 3) segments p0, p1, q0, q1: random ones, parallel ones, crossing ones and points."""
    rng = np.random.default_rng(seed)
    cases = list(rng.normal(size=(40, 4, 3)))
    for _ in range(10):
        p0, d, q0 = rng.normal(size=(3, 3))
        cases.append(np.array([p0, p0 + d, q0, q0 + rng.uniform(-2.0, 2.0) * d]))  # parallel
        centre = rng.normal(size=3)
        a, b = rng.normal(size=(2, 3))
        cases.append(np.array([centre - a, centre + 0.5 * a, centre - b, centre + 2.0 * b]))  # crossing
    p0, q0, q1 = rng.normal(size=(3, 3))
    cases.append(np.array([p0, p0, q0, q1]))  # a point and a segment
    cases.append(np.array([q0, q1, p0, p0]))
    cases.append(np.array([p0, p0, q0, q0]))  # two points
    return np.array(cases)


def test_closest_points_on_segments_match_brute_force(f64):
    """closest_on_segments: both points lie on their segments, and their distance is the least
    over the segments, to within the brute-force grid's spacing (and never above it)."""
    cases = segment_cases(seed=7)
    n = len(cases)
    ends = ti.Vector.field(3, ti.f64, shape=(n, 4))
    nearest = ti.Vector.field(3, ti.f64, shape=(n, 2))
    ends.from_numpy(cases)

    @ti.kernel
    def closest():
        for i in range(n):
            c_p, c_q = closest_on_segments(ends[i, 0], ends[i, 1], ends[i, 2], ends[i, 3])
            nearest[i, 0] = c_p
            nearest[i, 1] = c_q

    closest()
    got = nearest.to_numpy()
    for (p0, p1, q0, q1), (c_p, c_q) in zip(cases, got):
        for c, a, b in ((c_p, p0, p1), (c_q, q0, q1)):  # on its segment: |c-a| + |c-b| = |a-b|
            assert np.linalg.norm(c - a) + np.linalg.norm(c - b) <= np.linalg.norm(b - a) + 1e-12
        distance = np.linalg.norm(c_p - c_q)
        reference = closest_on_segments_numpy(p0, p1, q0, q1)
        spacing = (np.linalg.norm(p1 - p0) + np.linalg.norm(q1 - q0)) / 800
        assert distance <= reference + 1e-12
        assert distance >= reference - spacing
