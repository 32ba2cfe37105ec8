"""Which bodies a substep simulates: not the static ones, nor those asleep (solver.sleep), and
waking a sleeping body that a moving one comes near before the substep's prediction. The broad
phases and the carried rows ask this before they make a body's rows."""

import taichi as ti

from ..core.model import STATIC, body_vertex_box

# A sleeping body wakes when a moving body's box comes within this fraction of the larger of the
# two bodies' reaches (wake_near): a substep or more before they touch, so that it is already
# resting on its supports with its rows when the other arrives. Woken only on touching, a box
# under a falling one was pushed into the ground without rows and jumped 5 mm.
WAKE_REACH = 0.25


@ti.func
def is_moving(sim: ti.template(), b: ti.i32) -> bool:
    """Whether body b is simulated this substep: not static and not asleep."""
    return sim.model.body_kind[b] != STATIC and sim.body_asleep[b] == 0


@ti.func
def wake(sim: ti.template(), b: ti.i32):
    """Body b is simulated again from this substep, its calm time restarted."""
    sim.body_asleep[b] = 0
    sim.body_calm[b] = 0.0


@ti.func
def wake_if_touched(sim: ti.template(), b_a: ti.i32, b_b: ti.i32):
    """Of two bodies near each other (wake_near), wake the sleeping one if the other is moving."""
    if sim.body_asleep[b_a] == 1 and is_moving(sim, b_b):
        wake(sim, b_a)
    elif sim.body_asleep[b_b] == 1 and is_moving(sim, b_a):
        wake(sim, b_b)


@ti.func
def body_box(sim: ti.template(), b: ti.i32):
    """Body b's vertex box into body_lo/body_hi (wake_near's first part; each body on its own)."""
    lo, hi = body_vertex_box(sim.model, sim.state, b)
    sim.body_lo[b] = lo
    sim.body_hi[b] = hi


@ti.func
def wake_touched(sim: ti.template()):
    """wake_near's second part, on the boxes of body_box (serial: a body woken by one pair is
    moving for the pairs after it)."""
    n_b = sim.model.body_count[0]
    for b_a in range(n_b):
        for b_b in range(b_a + 1, n_b):
            if sim.body_asleep[b_a] == 1 or sim.body_asleep[b_b] == 1:
                pad = WAKE_REACH * ti.max(sim.body_reach[b_a], sim.body_reach[b_b])
                near = ((sim.body_lo[b_a] - pad <= sim.body_hi[b_b]).all()
                        and (sim.body_lo[b_b] - pad <= sim.body_hi[b_a]).all())
                if near:
                    wake_if_touched(sim, b_a, b_b)


@ti.func
def wake_near(sim: ti.template()):
    """Before a substep's prediction (serial): wake every sleeping body whose vertex box comes
    within WAKE_REACH of the larger reach of a moving body's box. Writes each body's vertex box
    to body_lo/body_hi (the all-pairs broad phase overwrites them with its own)."""
    if sim.sleep_time[0] > 0.0:
        for b in range(sim.model.body_count[0]):
            body_box(sim, b)
        wake_touched(sim)
