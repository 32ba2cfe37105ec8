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


def falling_body(kind: str, drag: float, name: str = "body", position=(0.0, 0.0, 0.0)) -> dict:
    body = {"name": name, "kind": kind, "drag": drag, "shape": "icosphere" if kind == "soft" else "box",
            "params": {"radius": 0.2, "subdivisions": 1} if kind == "soft" else {"size": [0.2, 0.2, 0.2]},
            "position": list(position)}
    if kind == "soft":
        body["compliance"] = 1e-8
    return body


FALLERS = [("rigid", DRAG), ("soft", DRAG), ("rigid", 0.0), ("soft", 0.0)]


@pytest.fixture(scope="module")
def falls():
    """One scene (one kernel to compile): a rigid box and a soft ball with drag DRAG and a free
    twin of each, 2 m apart, falling from rest, and a fifth body, a box with drag spinning at
    3 rad/s about y. Returns {(kind, drag): [(t, velocity (3,))]} at 0.25, 0.5 and 1 s, and
    under "spin" the spinning box's angular velocity at 1 s."""
    import taichi_dcd

    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    scene = Scene(scene_from_dict({"sim": {"gravity": [0.0, -G, 0.0]}, "body": [
        *(falling_body(kind, drag, f"{kind}{k}", (2.0 * k, 0.0, 0.0)) for k, (kind, drag) in enumerate(FALLERS)),
        falling_body("rigid", DRAG, "spinner", (10.0, 0.0, 0.0))]}, name="drag"))
    spinner = scene.body_names.index("spinner")
    scene.state.body_w[spinner] = [0.0, 3.0, 0.0]
    out = {key: [] for key in FALLERS}
    for t in (0.25, 0.5, 1.0):
        scene.step(round((t - scene.time) / scene.config.sim.frame_dt))
        for k, key in enumerate(FALLERS):
            out[key].append((t, scene.body_velocities()[k]))
    out["spin"] = scene.body_angular_velocities()[spinner]
    return out


@pytest.mark.parametrize("kind", ["rigid", "soft"])
def test_a_body_falling_with_drag_follows_the_closed_form_speed(falls, kind):
    """From rest, v(t) = (g/drag)(1 − exp(−drag·t)): within 0.5% of g/drag at 0.25, 0.5 and
    1 s (XPBD's substep of 1/1200 s is the only error: ~drag·h/2 = 8e-4 at the end); without
    drag the body falls at g·t, so the check can tell the two apart."""
    for t, v in falls[(kind, DRAG)]:
        expected = G / DRAG * (1.0 - math.exp(-DRAG * t))
        assert abs(v[1] + expected) <= 5e-3 * G / DRAG, (t, v, expected)
        assert np.abs(v[[0, 2]]).max() <= 1e-9
    t, v = falls[(kind, 0.0)][-1]
    assert abs(v[1] + G * t) <= 1e-3 * G


def test_drag_slows_a_rigid_spin_at_the_same_rate(falls):
    """A cube spinning at 3 rad/s: ω(t) = ω0·exp(−drag·t) within 0.5% after 1 s, axis unchanged
    (a cube's inertia is isotropic, so the spin is steady without drag; gravity does not turn it)."""
    w0 = np.array([0.0, 3.0, 0.0])
    np.testing.assert_allclose(falls["spin"], w0 * math.exp(-DRAG * 1.0), rtol=5e-3, atol=1e-9)


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


def spinning_boxes() -> Scene:
    """Two 0.2 m cubes resting on the ground 2 m apart, spinning at 3 rad/s about the vertical,
    without sliding friction (which would stop the spin too): the first with spin friction
    0.02 m (a pair's is the mean of its bodies', so 0.01 m against the ground's 0), the second
    without. One scene, one kernel to compile."""
    scene = Scene(scene_from_dict({"sim": {"gravity": [0.0, -G, 0.0]}, "body": [
        {"name": "ground", "kind": "static", "shape": "ground", "friction": 0.0},
        *({"name": f"box{k}", "kind": "rigid", "shape": "box", "params": {"size": [0.2, 0.2, 0.2]}, "friction": 0.0,
           "spin_friction": mu_s, "position": [2.0 * k, 0.1, 0.0]} for k, mu_s in enumerate([0.02, 0.0]))]},
        name="spin"))
    scene.state.body_w[1] = [0.0, 3.0, 0.0]
    scene.state.body_w[2] = [0.0, 3.0, 0.0]
    return scene


def test_spin_friction_stops_a_spinning_box_at_the_coulomb_rate(f64_scene):
    """Spin friction μ_s (m) is a torque μ_s·F_n about the normal: a cube of side a resting on
    the ground decelerates at μ_s·m·g/I = 6·μ_s·g/a² (14.7 rad/s² for μ_s = 0.01 m, a = 0.2 m),
    so from 3 rad/s it turns at 1.53 rad/s after 0.1 s (within 5%) and is still after 0.3 s,
    without sinking or sliding. Without it (and without sliding friction) it keeps spinning."""
    rate = 6.0 * 0.01 * G / 0.2 ** 2
    scene = spinning_boxes()
    scene.step(10)
    w = scene.body_angular_velocities()[1]
    assert abs(w[1] - (3.0 - rate * 0.1)) <= 0.05 * (3.0 - rate * 0.1), w
    scene.step(20)
    assert np.abs(scene.body_angular_velocities()[1]).max() < 1e-6
    assert np.abs(scene.body_positions()[1] - [0.0, 0.1, 0.0]).max() < 1e-5
    assert abs(scene.body_angular_velocities()[2][1] - 3.0) < 0.01
