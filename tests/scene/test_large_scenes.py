"""The large scenes and the stacks are what they claim, without simulating them: the pile has
at least 100 falling spikes and wedges over a bed of cracks and holes and at least 50k
triangles, the high-resolution spike-in-crack at least 20k triangles in every body; both
are listed and left out of `run all`. benchmarks/large_scenes.py runs them to rest (and
benchmarks/stacks.py the stacks)."""

import numpy as np

from taichi_dcd.scene.builtin import builtin_names, builtin_scene
from taichi_dcd.cli import main
from taichi_dcd.scene.scene import body_mesh


def meshes(name):
    config = builtin_scene(name)
    return config, [body_mesh(b, config.base_dir) for b in config.bodies]


def test_pile_drops_a_hundred_spikes_and_wedges_on_cracks_and_holes():
    config, ms = meshes("pile")
    rigid = [b for b in config.bodies if b.kind == "rigid"]
    assert len(rigid) >= 100 and {b.shape for b in rigid} == {"spike", "wedge"}
    static = {b.shape for b in config.bodies if b.kind == "static"}
    assert {"crack_block", "hole_block", "ground"} <= static
    assert sum(len(m.faces) for m in ms) >= 50_000
    # Nothing starts overlapping: the falling bodies' boxes are apart and above the bed.
    boxes = np.array([m.bounds for m, b in zip(ms, config.bodies) if b.kind == "rigid"])
    bed_top = max(m.bounds[1][1] for m, b in zip(ms, config.bodies) if b.kind == "static")
    assert boxes[:, 0, 1].min() > bed_top
    lo, hi = boxes[:, 0], boxes[:, 1]
    apart = (lo[:, None] > hi[None]).any(axis=2) | (lo[None] > hi[:, None]).any(axis=2)
    np.fill_diagonal(apart, True)
    assert apart.all()
    assert builtin_scene("pile").bodies[20].rotation == config.bodies[20].rotation  # seeded


def test_hires_spike_in_crack_has_twenty_thousand_triangles_per_body():
    config, ms = meshes("spike-in-crack-hires")
    _, coarse = meshes("spike-in-crack")
    assert all(len(m.faces) >= 20_000 for m in ms)
    for fine, rough in zip(ms, coarse):  # the same solids
        assert fine.volume == rough.volume or abs(fine.volume - rough.volume) <= 1e-9 * rough.volume
        np.testing.assert_allclose(fine.bounds, rough.bounds, atol=1e-12)


def test_large_scenes_are_listed_but_not_in_all(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "pile" in out and "spike-in-crack-hires" in out
    assert not {"pile", "spike-in-crack-hires"} & set(builtin_names())


def test_stack_and_pyramid_set_boxes_a_hair_apart_on_the_ground():
    """`stack`: ten 0.4 x 0.2 x 0.4 m boxes, each 1e-5 m above the one below (the lowest 1e-5 m
    above the ground), none overlapping. `pyramid`: rows of 5-4-3-2-1 such boxes, the boxes of a
    row touching side to side, each row centred on the one below and 1e-5 m above it. Both are
    listed and left out of `run all`; benchmarks/stacks.py runs them."""
    from taichi_dcd.measure.penetration import scene_penetration

    for name, rows in (("stack", [1] * 10), ("pyramid", [5, 4, 3, 2, 1])):
        config, ms = meshes(name)
        assert config.bodies[0].kind == "static" and all(b.kind == "rigid" for b in config.bodies[1:])
        boxes = ms[1:]
        assert len(boxes) == sum(rows)
        assert np.allclose([m.extents for m in boxes], [0.4, 0.2, 0.4])
        start = 0
        for level, count in enumerate(rows):
            row = sorted(boxes[start:start + count], key=lambda m: m.bounds[0][0])
            start += count
            for m in row:
                assert abs(m.bounds[0][1] - (1e-5 + level * (0.2 + 1e-5))) < 1e-12
            for left, right in zip(row, row[1:]):
                assert abs(right.bounds[0][0] - left.bounds[1][0]) < 1e-12  # side faces touching
            assert abs(np.mean([m.centroid[0] for m in row])) < 1e-12
        bodies = [(b.name, b.kind, m) for b, m in zip(config.bodies, ms)]
        assert scene_penetration(bodies).depth < 1e-12  # touching side faces: rounding only
        assert name not in builtin_names()


def test_pile_of_a_thousand_drops_boxes_and_wedges_apart_onto_the_ground():
    """`pile-1000`: 1,000 turned boxes and wedges in five layers over a ground, none touching
    another or the ground at the start; listed and left out of `run all`
    (benchmarks/pile_1000.py runs it)."""
    config, ms = meshes("pile-1000")
    assert config.bodies[0].kind == "static" and config.bodies[0].shape == "ground"
    parts = [(b, m) for b, m in zip(config.bodies[1:], ms[1:])]
    assert len(parts) == 1000 and all(b.kind == "rigid" for b, _ in parts)
    assert {b.shape for b, _ in parts} == {"box", "wedge"}
    boxes = np.array([m.bounds for _, m in parts])
    assert boxes[:, 0, 1].min() > ms[0].bounds[1][1]
    lo, hi = boxes[:, 0], boxes[:, 1]
    apart = (lo[:, None] > hi[None]).any(axis=2) | (lo[None] > hi[:, None]).any(axis=2)
    np.fill_diagonal(apart, True)
    assert apart.all()
    assert "pile-1000" not in builtin_names()
