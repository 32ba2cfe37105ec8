"""The built-in pile run to rest (slow suite: ~20-30 minutes on this project's 2-core machines),
judged as issue 34 asks: settled within its 5 s, its final depth within Erleben's verdict and
no measured frame deeper than its limit. benchmarks/large_scenes.py prints the same figures
with the wall time."""

import numpy as np
import pytest

from taichi_dcd.measure.penetration import PASS_FINAL_DEPTH, PASS_MAX_DEPTH
from taichi_dcd.output.run import SettleClock
from taichi_dcd.scene.builtin import builtin_scene
from taichi_dcd.scene.scene import Scene

MEASURE_EVERY = 50  # frames between penetration measures on the way (each takes seconds)


@pytest.mark.slow
def test_pile_settles_within_five_seconds_and_ends_shallow(f64_scene):
    """`pile` (100 spikes and wedges dropped on a bed of cracks and holes) settles within its
    5 s (every vertex slower than 1 mm/s for 0.2 s), ends at most 1e-4 m deep and no measured
    frame (every 50th) is deeper than 5 mm. Seen 2026-12-02 (third session, with the support
    pass): settled at 3.57 s, 2.5e-5 m at the end, 0.58 mm the deepest sample; before the rule
    moving_exit it settled at 3.82 s with a body 1.15 mm deep at the end."""
    config = builtin_scene("pile")
    sim = config.sim
    scene = Scene(config)
    clock = SettleClock(sim)
    x_prev = scene.vertices()
    deepest, settled = 0.0, False
    for frame in range(sim.frames):
        scene.step(1)
        x = scene.vertices()
        settled = clock.update(scene.time, float(np.max(np.linalg.norm(x - x_prev, axis=1))) / sim.frame_dt)
        x_prev = x
        if (frame + 1) % MEASURE_EVERY == 0:
            deepest = max(deepest, scene.penetration(x).depth)
        if settled:
            break
    final = scene.penetration()
    assert settled, f"not settled by {scene.time:.2f} s"
    assert final.depth <= PASS_FINAL_DEPTH
    assert max(deepest, final.depth) <= PASS_MAX_DEPTH
