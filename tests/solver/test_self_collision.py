"""A soft body touching itself (`self_collision`): the turns of a soft coil that land on each
other, judged by the independent self-intersection measure (measure/self_intersection.py)."""


from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene

SMALL_COIL = {"coil_radius": 0.3, "tube_radius": 0.06, "pitch": 0.14, "turns": 2.0, "segments_per_turn": 16}


def coil_scene(self_collision: bool) -> Scene:
    """A soft coil of two turns (592 triangles, 2 cm between its turns) dropped from 0.3 m."""
    return Scene(scene_from_dict({"sim": {"substeps": 12, "iterations": 16}, "body": [
        {"name": "ground", "kind": "static", "shape": "ground"},
        {"name": "coil", "kind": "soft", "shape": "coil", "params": SMALL_COIL, "position": [0.0, 0.3, 0.0],
         "compliance": 1e-5, "damping": 20.0, "self_collision": self_collision}]}, name="coil"))


def test_a_landing_coil_keeps_its_turns_apart_only_with_self_collision(f64_scene):
    """Without self_collision the upper turn falls through the lower one: pairs of its own
    triangles cross by more than 1 cm. With it, no pair in any frame crosses by more than 1 mm
    (the issue's limit), and the coil stays above the ground."""
    deepest = {}
    for on in (False, True):
        scene = coil_scene(on)
        worst = 0.0
        for _ in range(60):
            scene.step(1)
            worst = max(worst, scene.self_penetration()["coil"][1])
        deepest[on] = worst
        assert scene.penetration().depth <= 1e-4
        del scene  # its fields go back to the pool: the second scene compiles nothing
    assert deepest[False] > 1e-2
    assert deepest[True] <= 1e-3
