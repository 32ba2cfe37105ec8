"""The built-in scenes: Erleben's six contact tests (Erleben 2018, "Methodology for
assessing mesh-based contact point methods"), their variants and a soft drop.

Each scene is the same table a scene file holds (DESIGN.md §4), so `taichi-dcd run
spikes` and a TOML copy of it behave alike. Frame dt 0.01 s, gravity (0, −9.8, 0),
density 1000 kg/m³, friction 0.5; the static body stands on a static ground slab; runs
stop once every vertex has been slower than 1e-3 m/s for 0.2 s, or after 5 s.
"""

from __future__ import annotations

from .config import SceneConfig, scene_from_dict

GAP = 1e-4          # m: the dropped tip's or ridge's initial clearance
SHIFT = 0.01        # m: 1% of the 1 m base width, so that nothing balances
SLIDE = [1.0, 0.0, 0.0]  # m/s: initial velocity across a hole or crack
SPIKE_HEIGHT = 3.0
APEX_DOWN = [180.0, 0.0, 0.0]       # degrees: Rx(180°) turns a spike or wedge (ridge along z) upside down
RIDGE_DOWN_ACROSS = [180.0, 90.0, 0.0]  # upside down, then the ridge turned to run along x
SOFT_SETTINGS = {"substeps": 12, "iterations": 16}  # the soft scene's (config.DEFAULT_*: the rigid scenes')


def _sim() -> dict:
    return {"frame_dt": 0.01, "frames": 500, "stop_when_settled": True}


def _ground(top_y: float) -> dict:
    return {"name": "ground", "kind": "static", "shape": "ground", "position": [0.0, top_y, 0.0]}


def _dropped(shape: str, tip_y: float, x: float = 0.0, rotation=APEX_DOWN, velocity=None) -> dict:
    """A rigid spike or wedge turned tip/ridge down with its tip at (x, tip_y, 0)."""
    body = {"name": f"dropped_{shape}", "kind": "rigid", "shape": shape, "rotation": list(rotation),
            "position": [x, tip_y + SPIKE_HEIGHT, 0.0]}
    if velocity is not None:
        body["velocity"] = list(velocity)
    return body


def _standing(shape: str, params: dict | None = None) -> dict:
    """A static spike or wedge, tip/ridge up at y = 0, standing on the ground."""
    body = {"name": f"static_{shape}", "kind": "static", "shape": shape, "position": [0.0, -SPIKE_HEIGHT, 0.0]}
    if params:
        body["params"] = params
    return body


def _block(shape: str, params: dict | None = None) -> dict:
    body = {"name": shape, "kind": "static", "shape": shape, "position": [0.0, 0.0, 0.0]}
    if params:
        body["params"] = params
    return body


# Block tops are at y = 1; the groove's bottom line and the pocket's floor at y = 0.5.
BOTTOM_Y = 0.5

SCENES: dict[str, tuple[str, dict]] = {
    "spikes": ("a spike dropped apex down onto a standing spike's apex, 1% off centre", {
        "sim": _sim(), "body": [_ground(-SPIKE_HEIGHT), _standing("spike"), _dropped("spike", GAP, SHIFT)]}),
    "spike-and-wedge": ("a spike dropped apex down onto a standing wedge's ridge, 1% off centre", {
        "sim": _sim(), "body": [_ground(-SPIKE_HEIGHT), _standing("wedge"), _dropped("spike", GAP, SHIFT)]}),
    "wedges": ("a wedge dropped ridge down onto a standing wedge's ridge, ridges parallel, 1% off", {
        "sim": _sim(), "body": [_ground(-SPIKE_HEIGHT), _standing("wedge"), _dropped("wedge", GAP, SHIFT)]}),
    "wedges-crossed": ("a wedge dropped ridge down across a standing wedge's ridge (90°)", {
        "sim": _sim(), "body": [_ground(-SPIKE_HEIGHT), _standing("wedge"),
                                _dropped("wedge", GAP, SHIFT, rotation=RIDGE_DOWN_ACROSS)]}),
    "spike-in-hole": ("a spike sliding at 1 m/s, apex 0.1 mm above a square pocket's floor", {
        "sim": _sim(), "body": [_ground(0.0), _block("hole_block"),
                                _dropped("spike", BOTTOM_Y + GAP, velocity=SLIDE)]}),
    "spike-in-pit": ("a spike sliding at 1 m/s, apex 0.1 mm above an inverted-pyramid pit's bottom", {
        "sim": _sim(), "body": [_ground(0.0), _block("hole_block", {"pit": True}),
                                _dropped("spike", BOTTOM_Y + GAP, velocity=SLIDE)]}),
    "spike-in-crack": ("a spike sliding at 1 m/s across a V-groove, apex 0.1 mm above its bottom", {
        "sim": _sim(), "body": [_ground(0.0), _block("crack_block"),
                                _dropped("spike", BOTTOM_Y + GAP, velocity=SLIDE)]}),
    "wedge-in-crack": ("a wedge sliding at 1 m/s across a V-groove, ridge parallel, 1 mm above its bottom", {
        "sim": _sim(), "body": [_ground(0.0), _block("crack_block"),
                                _dropped("wedge", BOTTOM_Y + 1e-3, velocity=SLIDE)]}),
    "soft-ball-on-spike": ("a soft ball (radius 0.5, 1,280 triangles) dropped from 1 m onto a spike's apex", {
        # The setting the soft scene was tuned at (its damping and compliance), not the
        # rigid scenes' default: the membrane's edge and volume constraints share the
        # sweeps with its contacts (at 12 x 8 the spike ends 0.5 mm inside the ball).
        "sim": {**_sim(), **SOFT_SETTINGS}, "body": [_ground(-SPIKE_HEIGHT), _standing("spike"),
                                {"name": "ball", "kind": "soft", "shape": "icosphere",
                                 "params": {"radius": 0.5, "subdivisions": 3}, "position": [0.0, 1.5, 0.0],
                                 "compliance": 1e-4, "damping": 70.0, "drag": 0.5}]}),
}

# Erleben's six tests, in his order; `taichi-dcd run all` runs these and the variants.
ERLEBEN_SIX = ["spikes", "spike-and-wedge", "wedges", "spike-in-hole", "spike-in-crack", "wedge-in-crack"]

# The pile's bed: a row of crack blocks (z from −4 to 0) beside two rows of hole blocks
# (z from 0 to 4), 8 m wide; its bodies: spikes and wedges PILE_SCALE the Erleben size,
# in PILE_LAYERS layers of PILE_GRID × PILE_GRID, alternating, turned at random.
PILE_GRID = 5
PILE_LAYERS = 4
PILE_SCALE = 0.3
PILE_SUBDIVISIONS = 3   # spikes 384, wedges 512, crack blocks 1,536, hole blocks 1,792 triangles
HIRES_SUBDIVISIONS = 6  # spike 24,576, ground 49,152; the crack block takes one fewer (24,576)


# m: without spin friction a spike held at two points (a groove's wall and a wedge) swung
# about the line through them for 10 s and more (README, "Large scenes").
PILE_SPIN_FRICTION = 2e-3


def _pile() -> dict:
    """At least 100 spikes and wedges dropped onto a bed of cracks and holes, ≥ 50k
    triangles (issue 6). Seeded, so every run builds the same pile. At the library's default
    setting: since the bodies touching each other are solved as islands (solver.solve_blocks)
    it settles at 12 × 8 (it needed 32 sweeps before, and crept at the rest threshold even so)."""
    import numpy as np

    rng = np.random.default_rng(2025)
    refine = {"subdivisions": PILE_SUBDIVISIONS}
    bodies = [{"name": "ground", "kind": "static", "shape": "ground", "params": {"size": [16.0, 1.0, 16.0]}}]
    for i, x in enumerate((-3.0, -1.0, 1.0, 3.0)):
        bodies.append({"name": f"crack_{i}", "kind": "static", "shape": "crack_block", "params": refine,
                       "position": [x, 0.0, -2.0]})
        for j, z in enumerate((1.0, 3.0)):
            bodies.append({"name": f"hole_{i}_{j}", "kind": "static", "shape": "hole_block",
                           "params": dict(refine, pit=bool((i + j) % 2)), "position": [x, 0.0, z]})
    spacing = 8.0 / PILE_GRID
    for layer in range(PILE_LAYERS):
        for i in range(PILE_GRID):
            for j in range(PILE_GRID):
                shape = ("spike", "wedge")[(i + j + layer) % 2]
                x, z = (-4.0 + spacing * (k + 0.5) + rng.uniform(-0.2, 0.2) for k in (i, j))
                tilt = rng.uniform(-15.0, 15.0, 2)
                bodies.append({"name": f"{shape}_{layer}_{i}_{j}", "kind": "rigid", "shape": shape, "params": refine,
                               "scale": PILE_SCALE, "rotation": [180.0 + tilt[0], rng.uniform(0.0, 360.0), tilt[1]],
                               "position": [x, 2.2 + 1.2 * layer, z]})
    for body in bodies:
        body["spin_friction"] = PILE_SPIN_FRICTION
    return {"sim": _sim(), "body": bodies}


def _spike_in_crack_hires() -> dict:
    """spike-in-crack with every body remeshed to ≥ 20k triangles (the same surfaces)."""
    import copy

    table = copy.deepcopy(SCENES["spike-in-crack"][1])
    for body in table["body"]:
        refine = HIRES_SUBDIVISIONS - (body["shape"] == "crack_block")
        body["params"] = dict(body.get("params", {}), subdivisions=refine)
    return table


# Large scenes: built on demand (their tables are generated), listed, and left out of `all`.
LARGE_SCENES = {
    "pile": ("100 spikes and wedges (0.3 scale) dropped onto a bed of cracks and holes, ~65k triangles", _pile),
    "spike-in-crack-hires": ("spike-in-crack with every body remeshed to >= 20k triangles", _spike_in_crack_hires),
}


def builtin_names() -> list[str]:
    """The scenes `taichi-dcd run all` runs (not the large ones)."""
    return list(SCENES)


def describe(name: str) -> str:
    return (SCENES.get(name) or LARGE_SCENES[name])[0]


def builtin_scene(name: str) -> SceneConfig:
    """The SceneConfig of a built-in scene; KeyError for an unknown name."""
    import copy

    table = copy.deepcopy(SCENES[name][1]) if name in SCENES else LARGE_SCENES[name][1]()
    return scene_from_dict(table, name=name, where=f"built-in scene {name!r}")


def scene_config(name: str) -> SceneConfig:
    """A built-in scene's config by name, or a scene file's by path. Raises SceneError."""
    import os

    from .config import SceneError, read_scene_file

    if name in SCENES or name in LARGE_SCENES:
        return builtin_scene(name)
    if not name.endswith(".toml") and "/" not in name and not os.path.exists(name):
        raise SceneError(f"unknown scene {name!r}: not a built-in scene (see `taichi-dcd list`) nor a file")
    return read_scene_file(name)
