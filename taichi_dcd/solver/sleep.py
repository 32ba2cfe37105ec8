"""Sleeping: an island of touching rigid bodies that has been at rest for a while stops being
simulated, and wakes when a moving body comes near it.

A rigid body is calm while every point of it moves slower than sim.sleep_speed:
|v| + |ω|·reach < sleep_speed. An island (the rigid bodies joined by rows, as the projection's
blocks join them: solver.islands) falls asleep once each of its bodies has been calm for
sim.sleep_time seconds; its bodies then hold still (v = ω = 0), are not predicted, and their
pairs with static or sleeping bodies get no rows. A sleeping body wakes when its box meets the
box of a moving one (a rigid body awake, or any soft body); the bodies it rests on wake in the
substeps after, as the woken body's box meets theirs. sleep_time = 0 switches sleeping off.
"""

import taichi as ti

from ..core.model import RIGID


@ti.func
def update_sleep(sim: ti.template(), h: float):
    """After a substep of length h (s), the bodies' calm times, and every island whose bodies
    have all been calm for sim.sleep_time put to sleep (serial; block_island holds each rigid
    body's island root from the substep's last sweep)."""
    after = sim.sleep_time[0]
    if after > 0.0:
        n_b = sim.model.body_count[0]
        for b in range(n_b):
            sim.island_calm[b] = ti.math.inf
        for b in range(n_b):
            if sim.model.body_kind[b] == RIGID and sim.body_asleep[b] == 0:
                speed = sim.state.body_v[b].norm() + sim.state.body_w[b].norm() * sim.body_reach[b]
                calm = ti.select(speed < sim.sleep_speed[0], sim.body_calm[b] + h, 0.0)
                sim.body_calm[b] = calm
                root = sim.block_island[b]
                sim.island_calm[root] = ti.min(sim.island_calm[root], calm)
        for b in range(n_b):
            if sim.model.body_kind[b] == RIGID and sim.body_asleep[b] == 0:
                if sim.island_calm[sim.block_island[b]] >= after:
                    sim.body_asleep[b] = 1
                    sim.state.body_v[b] = ti.math.vec3(0.0)
                    sim.state.body_w[b] = ti.math.vec3(0.0)
