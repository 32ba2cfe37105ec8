"""`narrowphase.pressed_through`, the solver's test for a soft patch sagged wholly behind a
facing face (which the unified test cannot see: no triangle straddles the other's plane),
on pairs whose answer follows from the geometry: which triangle lies behind the other's
plane, for facing, tilted, crossing, separated and touching pairs."""

import math

import numpy as np
import pytest
import taichi as ti

from taichi_dcd.collision.narrowphase import PRESSED_MIN_FACING, pressed_through

vec3 = ti.math.vec3

# The top face of a support (normal +y, in y = 0) and, facing it, a patch of a body above it
# (outward normal -y), 0.2 wide, centred over the face.
FACE = np.array([[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0]])
PATCH = np.array([[-0.3, 0.0, 0.1], [-0.1, 0.0, 0.1], [-0.2, 0.0, 0.3]])


@ti.kernel
def _pressed(a: ti.types.ndarray(dtype=vec3, ndim=1), b: ti.types.ndarray(dtype=vec3, ndim=1)) -> ti.math.ivec2:
    a_behind, b_behind, _, _, _ = pressed_through(a[0], a[1], a[2], b[0], b[1], b[2])
    return ti.math.ivec2(ti.cast(a_behind, ti.i32), ti.cast(b_behind, ti.i32))


def pressed(a, b) -> tuple[bool, bool]:
    r = _pressed(np.asarray(a, float), np.asarray(b, float))
    return bool(r[0]), bool(r[1])


def tilted(patch, degrees: float) -> np.ndarray:
    """The patch turned about the z axis through its first vertex."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    r = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return (patch - patch[0]) @ r.T + patch[0]


def test_the_pair_faces_each_other():
    assert np.cross(FACE[1] - FACE[0], FACE[2] - FACE[0])[1] > 0
    assert np.cross(PATCH[1] - PATCH[0], PATCH[2] - PATCH[0])[1] < 0


def test_a_patch_sunk_below_a_facing_face_is_behind_it(f64):
    """1 mm under the face: the patch is behind the face's plane, and the face (y = 0) is behind
    the patch's plane too (inside the body); in either argument order."""
    sunk = PATCH - [0.0, 1e-3, 0.0]
    assert pressed(sunk, FACE) == (True, True)
    assert pressed(FACE, sunk) == (True, True)


def test_a_patch_resting_on_the_face_or_above_it_is_not(f64):
    """In the face's plane (touching, rounding-level offsets included) or 1 mm above it: nothing
    is behind anything."""
    assert pressed(PATCH, FACE) == (False, False)
    assert pressed(PATCH + [0.0, 1e-16, 0.0], FACE) == (False, False)
    assert pressed(PATCH + [0.0, 1e-3, 0.0], FACE) == (False, False)


def test_a_patch_crossing_the_face_is_left_to_the_unified_test(f64):
    """Tilted 10° about its first vertex, which lies 1 mm under the face: the patch's far end
    rises through the face's plane, so the patch straddles it and is not wholly behind it."""
    crossing = tilted(PATCH - [0.0, 1e-3, 0.0], 10.0)
    assert crossing[:, 1].max() > 0.0 > crossing[:, 1].min()
    assert pressed(crossing, FACE)[0] is False


@pytest.mark.parametrize("degrees, facing", [(30.0, True), (44.0, True), (46.0, False), (60.0, False)])
def test_only_a_patch_within_45_degrees_of_parallel_counts(f64, degrees, facing):
    """Sunk and tilted down so that it stays wholly behind the face: it counts while the normals
    are within acos(PRESSED_MIN_FACING) = 45° of opposed (a patch draped over a sharp edge is
    not parallel to the face it is behind)."""
    assert math.degrees(math.acos(PRESSED_MIN_FACING)) == pytest.approx(45.0, abs=0.01)
    patch = tilted(PATCH - [0.0, 1e-3, 0.0], -degrees)
    assert patch[:, 1].max() < 0.0
    assert pressed(patch, FACE)[0] is facing


def test_faces_pointing_the_same_way_are_not_pressed(f64):
    """A copy of the face 1 mm below it (a stacked sheet, not a facing pair)."""
    assert pressed(FACE - [0.0, 1e-3, 0.0], FACE) == (False, False)
