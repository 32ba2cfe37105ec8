"""The built-in scenes: Erleben's six contact tests (Erleben 2018, "Methodology for
assessing mesh-based contact point methods"), their variants, a soft drop, two large
scenes, two of many boxes resting on each other, a pile of 1,000 bodies, a soft coil that touches itself and two cloths. Each is a scene file shipped in
`scene/files/<name>.toml`, the one source of the scene: `taichi-dcd run spikes` reads the
same file a user could copy and edit. Its first line, `# <name>: <description>`, is what
`taichi-dcd list` prints.

Frame dt 0.01 s, gravity (0, −9.8, 0), density 1000 kg/m³, friction 0.5; the static body
stands on a static ground slab; runs stop once every vertex has been slower than 1e-3 m/s
for 0.2 s, or after 5 s.
"""

from __future__ import annotations

import os
from pathlib import Path

from .config import SceneConfig, SceneError, read_scene_file

FILES = Path(__file__).parent / "files"

# `taichi-dcd run all`, in this order: Erleben's six (in his order) among their variants.
ALL = ["spikes", "spike-and-wedge", "wedges", "wedges-crossed", "spike-in-hole", "spike-in-pit", "spike-in-crack",
       "wedge-in-crack", "soft-ball-on-spike"]
ERLEBEN_SIX = ["spikes", "spike-and-wedge", "wedges", "spike-in-hole", "spike-in-crack", "wedge-in-crack"]
# Listed and run by name, left out of `all` (minutes each).
LARGE = ["pile", "spike-in-crack-hires"]
# Many boxes resting on each other (stack, pyramid): listed and run by name, left out of `all`.
STACKS = ["stack", "pyramid"]
# A pile of 1,000 bodies: hours on two cores; listed and run by name, left out of `all`.
PILES = ["pile-1000"]
# Soft bodies touching themselves (self_collision): listed and run by name, left out of `all`.
SELF_TOUCHING = ["soft-coil", "soft-torus-on-spike"]
# Cloth (an open sheet) draped over a sharp feature: listed and run by name, left out of `all`.
CLOTH = ["cloth-on-spike", "cloth-on-wedge", "two-cloths-on-box"]
# Every built-in scene, `all` first.
KNOWN = [*ALL, *LARGE, *STACKS, *PILES, *SELF_TOUCHING, *CLOTH]


def scene_path(name: str) -> Path:
    """The shipped file of built-in scene `name`; KeyError for an unknown name."""
    if name not in KNOWN:
        raise KeyError(name)
    return FILES / f"{name}.toml"


def builtin_names() -> list[str]:
    """The scenes `taichi-dcd run all` runs (not the large ones)."""
    return list(ALL)


def describe(name: str) -> str:
    """The one-line description from the first line of the scene's file."""
    first = scene_path(name).read_text(encoding="utf-8").split("\n", 1)[0]
    return first.split(":", 1)[1].strip()


def builtin_scene(name: str) -> SceneConfig:
    """The SceneConfig of a built-in scene; KeyError for an unknown name."""
    return read_scene_file(scene_path(name))


def scene_config(name: str) -> SceneConfig:
    """A built-in scene's config by name, or a scene file's by path. Raises SceneError."""
    if name in KNOWN:
        return builtin_scene(name)
    if not name.endswith(".toml") and "/" not in name and not os.path.exists(name):
        raise SceneError(f"unknown scene {name!r}: not a built-in scene (see `taichi-dcd list`) nor a file")
    return read_scene_file(name)
