"""The z-buffer rasteriser: occlusion, silhouette area against the projected box, and
byte-identical output for the same state."""

import io

import numpy as np
import pytest

from taichi_dcd.scene import shapes
from taichi_dcd.output.render import BACKGROUND, Camera, Rasterizer, project_points, write_png

RED, BLUE = (200, 0, 0), (0, 0, 200)


def soup(meshes_and_colors):
    vertices, faces, rgb, offset = [], [], [], 0
    for mesh, color in meshes_and_colors:
        vertices.append(np.asarray(mesh.vertices))
        faces.append(np.asarray(mesh.faces) + offset)
        rgb.append(np.tile(color, (len(mesh.faces), 1)))
        offset += len(mesh.vertices)
    return np.concatenate(vertices), np.concatenate(faces), np.concatenate(rgb)


def box_at(size, centre):
    mesh = shapes.box(size)
    mesh.apply_translation(centre)
    return mesh


@pytest.mark.parametrize("front_first", [True, False])
def test_the_nearer_box_covers_the_farther_one(f64, front_first):
    front, back = (box_at((1, 1, 1), (0.3, 0.2, 1.0)), RED), (box_at((2, 2, 1), (0, 0, -1.0)), BLUE)
    v, f, rgb = soup([front, back] if front_first else [back, front])
    camera = Camera(eye=(0.5, 0.8, 8.0), target=(0.0, 0.0, 0.0))
    image = Rasterizer(320, 240).render(v, f, rgb, camera)
    x, y, _ = project_points(np.array([[0.3, 0.2, 1.5]]), camera, 320, 240)[0]  # the front box's front face
    pixel = image[int(y), int(x)]
    assert pixel[0] > 0 and pixel[2] == 0, f"front box hidden: {pixel}"
    x, y, _ = project_points(np.array([[-0.9, -0.9, -0.5]]), camera, 320, 240)[0]  # only the back box
    assert image[int(y), int(x)][2] > 0 and image[int(y), int(x)][0] == 0


def polygon_area(points):
    """Area of the convex hull of 2-D points (monotone chain + shoelace)."""
    pts = sorted(map(tuple, points))

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    hull = half(pts)[:-1] + half(pts[::-1])[:-1]
    x, y = np.array(hull).T
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


@pytest.mark.parametrize("eye", [(4.0, 3.0, 5.0), (-3.0, 1.5, 4.0), (0.5, 6.0, 0.7)])
def test_box_silhouette_covers_its_projected_area(f64, eye):
    box = box_at((1.2, 0.8, 1.0), (0.1, 0.0, -0.2))
    v, f, rgb = soup([(box, RED)])
    camera = Camera(eye=eye, target=(0.0, 0.0, 0.0))
    image = Rasterizer(800, 600).render(v, f, rgb, camera)
    covered = int(np.any(image != np.array(BACKGROUND, np.uint8), axis=2).sum())
    predicted = polygon_area(project_points(np.asarray(box.vertices), camera, 800, 600)[:, :2])
    assert predicted > 5000
    assert covered == pytest.approx(predicted, rel=0.02)


def test_same_state_renders_to_identical_bytes(f64, tmp_path):
    scene = [(box_at((1, 1, 1), (0, 0.5, 0)), RED), (shapes.ground((6.0, 1.0, 6.0)), (150, 150, 150)),
             (box_at((0.5, 2, 0.5), (0.2, 1.0, 0.1)), BLUE)]  # overlapping boxes: depth ties are resolved
    v, f, rgb = soup(scene)
    camera = Camera(eye=(4.0, 3.0, 5.0), target=(0.0, 0.5, 0.0))
    blobs = []
    for k in range(2):
        image = Rasterizer(400, 300).render(v, f, rgb, camera, points=np.array([[0.0, 1.0, 0.0]]))
        write_png(tmp_path / f"{k}.png", image)
        blobs.append((tmp_path / f"{k}.png").read_bytes())
    assert blobs[0] == blobs[1]
    assert len(io.BytesIO(blobs[0]).getvalue()) > 1000


@pytest.mark.parametrize("deflate", ["isal", "zlib"])
def test_written_png_reads_back_as_the_same_pixels(tmp_path, monkeypatch, deflate):
    """write_png's files open in Pillow (the contact sheet, any viewer) as exactly the image
    written, for a random image and a flat one, odd sizes included, with either compressor
    (ISA-L's, or zlib's where isal is missing)."""
    import zlib

    from PIL import Image

    from taichi_dcd.output import render

    if deflate == "zlib":
        monkeypatch.setattr(render, "compress_frame", lambda data: zlib.compress(data, 3))
    else:
        pytest.importorskip("isal")

    rng = np.random.default_rng(3)
    for image in (rng.integers(0, 256, size=(37, 53, 3), dtype=np.uint8),
                  np.full((600, 800, 3), BACKGROUND, np.uint8)):
        path = tmp_path / f"image-{image.shape[0]}.png"
        write_png(path, image)
        with Image.open(path) as read:
            assert read.mode == "RGB" and read.size == (image.shape[1], image.shape[0])
            np.testing.assert_array_equal(np.asarray(read), image)


@pytest.mark.parametrize("eye", [(4.0, 3.0, 5.0), (-3.0, 1.5, -4.0), (0.5, 6.0, 0.7)])
def test_closed_bodies_drawn_one_sided_look_the_same(f64, eye):
    """Leaving out the faces that closed bodies turn away from the eye changes at most a few
    pixels (at a silhouette a front and a back face meet at one depth, and the tie went to
    the lower triangle index), and one rasteriser draws frame after frame (its keys are
    cleared as it colours)."""
    scene = [(box_at((1, 1, 1), (0, 0.5, 0)), RED), (shapes.ground((6.0, 1.0, 6.0)), (150, 150, 150)),
             (box_at((0.5, 2, 0.5), (0.2, 1.0, 0.1)), BLUE)]
    v, f, rgb = soup(scene)
    camera = Camera(eye=eye, target=(0.0, 0.5, 0.0))
    rasterizer = Rasterizer(400, 300)
    two_sided = rasterizer.render(v, f, rgb, camera)
    one_sided = rasterizer.render(v, f, rgb, camera, one_sided=np.ones(len(f), bool))
    assert np.any(one_sided != two_sided, axis=2).sum() <= 5
    shifted = rasterizer.render(v + [0.5, 0.0, 0.0], f, rgb, camera, one_sided=np.ones(len(f), bool))
    fresh = Rasterizer(400, 300).render(v + [0.5, 0.0, 0.0], f, rgb, camera, one_sided=np.ones(len(f), bool))
    np.testing.assert_array_equal(shifted, fresh)
    assert np.any(shifted != one_sided, axis=2).sum() > 1000


def test_open_sheet_seen_from_behind_is_drawn_unless_one_sided(f64):
    """A single triangle facing away from the eye (a cloth's underside) is drawn when two-sided
    and left out when marked one-sided."""
    v = np.array([[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    f = np.array([[0, 1, 2]])  # normal (0, -1, 0)·…: faces down, the eye is above
    assert np.cross(v[1] - v[0], v[2] - v[0])[1] < 0
    camera = Camera(eye=(0.3, 4.0, 3.0), target=(0.0, 0.0, 0.0))
    rasterizer = Rasterizer(200, 150)
    drawn = rasterizer.render(v, f, np.array([RED]), camera, one_sided=np.zeros(1, bool))
    culled = rasterizer.render(v, f, np.array([RED]), camera, one_sided=np.ones(1, bool))
    assert np.any(drawn != np.array(BACKGROUND, np.uint8), axis=2).sum() > 1000
    assert not np.any(culled != np.array(BACKGROUND, np.uint8))
