"""Velocity damping (`drag`, 1/s: dv/dt = g − drag·v for every point of a rigid or soft body) and
spin friction (`spin_friction`, m: a torque about a contact's normal up to μ_s times its normal
force), checked against closed-form answers."""

import math

import numpy as np
import pytest

from taichi_dcd.scene.config import SceneError, scene_from_dict
from taichi_dcd.scene.scene import Scene

DRAG = 2.0   # 1/s: terminal speed g/DRAG = 4.9 m/s, reached to 2% in 2 s
G = 9.8


def falling(kind: str, drag: float, spin=(0.0, 0.0, 0.0), gravity=-G) -> Scene:
    body = {"name": "body", "kind": kind, "drag": drag, "shape": "icosphere" if kind == "soft" else "box",
            "params": {"radius": 0.2, "subdivisions": 1} if kind == "soft" else {"size": [0.2, 0.2, 0.2]}}
    if kind == "soft":
        body["compliance"] = 1e-8
    return Scene(scene_from_dict({"sim": {"gravity": [0.0, gravity, 0.0]}, "body": [body]}, name="drag"))


@pytest.mark.parametrize("kind", ["rigid", "soft"])
def test_a_body_falling_with_drag_follows_the_closed_form_speed(f64_scene, kind):
    """From rest, v(t) = (g/drag)(1 − exp(−drag·t)): within 0.5% of g/drag at 0.25, 0.5 and
    1 s (XPBD's substep of 1/1200 s is the only error: ~drag·h/2 = 8e-4 at the end); without
    drag the body falls at g·t, so the check can tell the two apart."""
    scene = falling(kind, DRAG)
    for t in (0.25, 0.5, 1.0):
        scene.step(round((t - scene.time) / scene.config.sim.frame_dt))
        v = scene.body_velocities()[0]
        expected = G / DRAG * (1.0 - math.exp(-DRAG * t))
        assert abs(v[1] + expected) <= 5e-3 * G / DRAG, (t, v, expected)
        assert np.abs(v[[0, 2]]).max() <= 1e-9
    free = falling(kind, 0.0)
    free.step(100)
    assert abs(free.body_velocities()[0][1] + G * 1.0) <= 1e-3 * G


def test_drag_slows_a_rigid_spin_at_the_same_rate(f64_scene):
    """No gravity, a cube spinning at 3 rad/s: ω(t) = ω0·exp(−drag·t) within 0.5% after 1 s,
    axis unchanged (a cube's inertia is isotropic, so the spin is steady without drag)."""
    scene = falling("rigid", DRAG, gravity=0.0)
    w0 = np.array([0.0, 3.0, 0.0])
    scene.state.body_w[0] = list(w0)
    scene.step(100)
    w = scene.body_angular_velocities()[0]
    np.testing.assert_allclose(w, w0 * math.exp(-DRAG * 1.0), rtol=5e-3, atol=1e-9)


def test_negative_drag_is_a_scene_error():
    with pytest.raises(SceneError, match="drag"):
        scene_from_dict({"body": [{"name": "b", "kind": "rigid", "shape": "box", "drag": -1.0}]}, name="bad")


def test_a_scaled_scene_falls_through_the_same_motion_with_drag(f64_scene):
    """`scale_scene` by L = 100 (times ×√L): the drag rate must go ×L^-1/2 for the motion to
    be the same motion; the velocity after the same number of frames is √L times the
    unscaled one (1e-9 relative). Left unscaled, drag would act 10× too long per frame."""
    from taichi_dcd.scene.config import scale_scene

    config = scene_from_dict({"sim": {"gravity": [0.0, -G, 0.0]}, "body": [
        {"name": "body", "kind": "rigid", "drag": DRAG, "shape": "box", "params": {"size": [0.2, 0.2, 0.2]}}]},
        name="drag")
    base, scaled = Scene(config), Scene(scale_scene(config, 100.0))
    base.step(50)
    scaled.step(50)
    np.testing.assert_allclose(scaled.body_velocities()[0], 10.0 * base.body_velocities()[0], rtol=1e-9)


def spinning_box(spin_friction: float) -> Scene:
    """A 0.2 m cube resting on the ground, both without sliding friction (which would stop the
    spin too) and with spin friction μ_s (a pair's is the mean of its bodies'), spinning at
    3 rad/s about the vertical."""
    scene = Scene(scene_from_dict({"sim": {"gravity": [0.0, -G, 0.0]}, "body": [
        {"name": "ground", "kind": "static", "shape": "ground", "friction": 0.0, "spin_friction": spin_friction},
        {"name": "box", "kind": "rigid", "shape": "box", "params": {"size": [0.2, 0.2, 0.2]}, "friction": 0.0,
         "spin_friction": spin_friction, "position": [0.0, 0.1, 0.0], "velocity": [0.0, 0.0, 0.0]}]},
        name="spin"))
    scene.state.body_w[1] = [0.0, 3.0, 0.0]
    return scene


def test_spin_friction_stops_a_spinning_box_at_the_coulomb_rate(f64_scene):
    """Spin friction μ_s (m) is a torque μ_s·F_n about the normal: a cube of side a resting on
    the ground decelerates at μ_s·m·g/I = 6·μ_s·g/a² (14.7 rad/s² for μ_s = 0.01 m, a = 0.2 m),
    so from 3 rad/s it turns at 1.53 rad/s after 0.1 s (within 5%) and is still after 0.3 s,
    without sinking or sliding. Without it (and without sliding friction) it keeps spinning."""
    rate = 6.0 * 0.01 * G / 0.2 ** 2
    scene = spinning_box(0.01)
    scene.step(10)
    w = scene.body_angular_velocities()[1]
    assert abs(w[1] - (3.0 - rate * 0.1)) <= 0.05 * (3.0 - rate * 0.1), w
    scene.step(20)
    assert np.abs(scene.body_angular_velocities()[1]).max() < 1e-6
    assert np.abs(scene.body_positions()[1] - [0.0, 0.1, 0.0]).max() < 1e-5
    free = spinning_box(0.0)
    free.step(30)
    assert abs(free.body_angular_velocities()[1][1] - 3.0) < 0.01
