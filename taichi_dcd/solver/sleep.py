"""Sleeping: an island of touching rigid bodies that has been at rest for a while stops being
simulated, and wakes when a moving body comes near it.

A rigid body is calm while every point of it stays within sleep_speed·sleep_time of where it
was when its calm began (update_sleep). An island (the rigid bodies joined by rows, as the
projection's blocks join them: solver.islands) falls asleep once each of its bodies has been
calm for sim.sleep_time seconds; its bodies then hold still (v = ω = 0), are not predicted, and
their pairs with static or sleeping bodies get no rows. Before each substep a sleeping body
wakes when a moving one (a rigid body awake, or any soft body) comes near it
(contact.sleeping.wake_near); the bodies it rests on wake in the substeps after, as it comes
near theirs. sleep_time = 0 switches sleeping off.
"""

import taichi as ti

from ..core.model import RIGID
from ..core.rigid import quat_conj, quat_mul


@ti.func
def moved_since(sim: ti.template(), b: ti.i32) -> float:
    """How far (m) rigid body b's farthest point may have moved from the pose where its calm
    began: |x − x_calm| + reach·θ, θ the angle between the two orientations."""
    turn = quat_mul(sim.state.body_q[b], quat_conj(sim.body_calm_q[b]))
    angle = 2.0 * ti.asin(ti.min(ti.math.vec3(turn[1], turn[2], turn[3]).norm(), 1.0))
    return (sim.state.body_x[b] - sim.body_calm_x[b]).norm() + sim.body_reach[b] * angle


@ti.func
def update_sleep(sim: ti.template(), h: float):
    """After a substep of length h (s), the bodies' calm times, and every island whose bodies
    have all been calm for sim.sleep_time put to sleep (serial; block_island holds each rigid
    body's island root from the substep's last sweep). A body is calm while no point of it has
    left the ball of radius sleep_speed·sleep_time about where it was when its calm began (its
    mean speed since is below sleep_speed); judged by the pose, not the substep's velocity,
    which jitters: a box of a stack moving 1 µm in a substep of 1/1200 s has 1.2e-3 m/s."""
    after = sim.sleep_time[0]
    if after > 0.0:
        radius = sim.sleep_speed[0] * after
        n_b = sim.model.body_count[0]
        for b in range(n_b):
            sim.island_calm[b] = ti.math.inf
        for b in range(n_b):
            if sim.model.body_kind[b] == RIGID and sim.body_asleep[b] == 0:
                calm = sim.body_calm[b] + h
                if calm == h or moved_since(sim, b) > radius:  # calm begins (again) here
                    sim.body_calm_x[b] = sim.state.body_x[b]
                    sim.body_calm_q[b] = sim.state.body_q[b]
                    calm = ti.select(calm == h, h, 0.0)
                sim.body_calm[b] = calm
                root = sim.block_island[b]
                sim.island_calm[root] = ti.min(sim.island_calm[root], calm)
        for b in range(n_b):
            if sim.model.body_kind[b] == RIGID and sim.body_asleep[b] == 0:
                if sim.island_calm[sim.block_island[b]] >= after:
                    sim.body_asleep[b] = 1
                    sim.state.body_v[b] = ti.math.vec3(0.0)
                    sim.state.body_w[b] = ti.math.vec3(0.0)
