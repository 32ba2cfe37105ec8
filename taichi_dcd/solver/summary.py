"""The per-body motion summary the next frame's substep choice is made from, in a kernel."""

import taichi as ti

from ..core.model import RIGID, SOFT, STATIC
from ..solver.tunnelling import TUNNEL_FRACTION

vec3 = ti.math.vec3


@ti.func
def summarize_bodies(sim: ti.template()):
    """body_summary (serial): per body its linear velocity (m/s; a soft body's particle mean, 0 for a
    static one), the fastest motion about it (|ω| in rad/s for a rigid body, the largest
    particle speed about the mean in m/s for a soft one) and its vertices' box (m)."""
    for b in range(sim.model.body_count[0]):
        r = sim.model.body_vertex_range[b]
        lo = vec3(ti.math.inf)
        hi = vec3(-ti.math.inf)
        for i in range(r[0], r[1]):
            lo = ti.min(lo, sim.state.vertex_x[i])
            hi = ti.max(hi, sim.state.vertex_x[i])
        v = vec3(0.0)
        spin = 0.0
        if sim.model.body_kind[b] == RIGID:
            v = sim.state.body_v[b]
            spin = sim.state.body_w[b].norm()
        if ti.static(sim.model.has_soft):
            if sim.model.body_kind[b] == SOFT:
                for i in range(r[0], r[1]):
                    v += sim.state.vertex_v[i]
                v /= ti.max(r[1] - r[0], 1)
                for i in range(r[0], r[1]):
                    spin = ti.max(spin, (sim.state.vertex_v[i] - v).norm())
        sim.body_summary[b] = ti.Vector([v[0], v[1], v[2], spin, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]])


@ti.func
def summary_motion(sim: ti.template(), b: ti.i32):
    """(velocity (m/s), bound on its points' speed about it (m/s): |ω|·reach for a rigid
    body, the fastest particle for a soft one) of body b from body_summary; zero if static."""
    s = sim.body_summary[b]
    kind = sim.model.body_kind[b]
    v = vec3(0.0)
    spin = 0.0
    if kind != STATIC:
        v = vec3(s[0], s[1], s[2])
        spin = s[3] * ti.select(kind == RIGID, sim.body_reach[b], 1.0)
    return v, spin


@ti.func
def substeps_needed(sim: ti.template(), substeps: ti.i32, frame_dt: float, g_norm: float, max_impact: float,
                    thinnest: float, cap: ti.i32) -> ti.i32:
    """The substeps the next frame needs, at least `substeps`, from body_summary
    (summarize_bodies first) by the rules and arithmetic of Scene._substeps_for_next_frame,
    so that a frame kernel that checks or chooses them runs the frame its caller would: the two
    fastest bodies move at most TUNNEL_FRACTION of the thinnest body's thickness per substep
    (-1 when that takes more than `cap`: the caller says which body is too fast), and no two
    bodies that can meet within the frame close in by more than `max_impact` per substep (at
    most `cap`). Counts are compared as floats: an exploding body's would overflow an int.
    Serial."""
    n_b = sim.model.body_count[0]
    first = 0.0
    second = 0.0
    for b in range(n_b):
        if sim.model.body_kind[b] != STATIC:
            v, spin = summary_motion(sim, b)
            speed = v.norm() + spin + g_norm * frame_dt
            if speed > first:
                second = first
                first = speed
            elif speed > second:
                second = speed
    motion = (first + second) * frame_dt
    needed = ti.cast(substeps, float)
    if motion > 0.0 and motion < ti.math.inf and thinnest > 0.0:  # NaN: the explosion check's to report
        needed = ti.max(needed, ti.ceil(motion / (TUNNEL_FRACTION * thinnest)))
    impact = 0.0
    if max_impact > 0.0:
        for a in range(n_b):
            for b in range(n_b):
                if a != b and (sim.model.body_kind[a] != STATIC or sim.model.body_kind[b] != STATIC):
                    v_a, spin_a = summary_motion(sim, a)
                    v_b, spin_b = summary_motion(sim, b)
                    pair_motion = ((v_a - v_b).norm() + spin_a + spin_b + g_norm * frame_dt) * frame_dt
                    if not pair_motion < ti.math.inf:
                        pair_motion = 0.0
                    s_a, s_b = sim.body_summary[a], sim.body_summary[b]
                    gap = ti.max(vec3(s_a[4], s_a[5], s_a[6]) - vec3(s_b[7], s_b[8], s_b[9]),
                                 vec3(s_b[4], s_b[5], s_b[6]) - vec3(s_a[7], s_a[8], s_a[9])).max()
                    if gap <= pair_motion:
                        impact = ti.max(impact, ti.ceil(pair_motion / max_impact))
    chosen = -1
    if needed <= cap:
        chosen = ti.cast(ti.max(needed, ti.min(impact, ti.cast(cap, float))), ti.i32)
    return chosen
