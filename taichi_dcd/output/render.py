"""Offscreen frames: a z-buffer rasteriser in Taichi kernels, flat shading, PNG (write_png).

The camera and lighting are set up in NumPy (a few hundred triangles at most); the
kernels do the per-pixel work. Each pixel keeps the smallest 64-bit key
(depth quantised to 31 bits, then the triangle's index) by atomic min, so the image
does not depend on the order in which threads run: the same state renders to the same
bytes.
"""


import math
import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import taichi as ti

from ..core import runtime

BACKGROUND = (235, 238, 242)
CONTACT_COLOR = (220, 30, 30)
# One colour per body, in body order (static bodies get greys, see body_colors).
PALETTE = [(66, 133, 204), (230, 145, 56), (92, 170, 96), (170, 92, 170), (204, 170, 60), (80, 170, 180)]
STATIC_GREYS = [(150, 150, 155), (190, 185, 175), (120, 125, 130)]
AMBIENT = 0.35
DEPTH_LEVELS = (1 << 31) - 1
NO_HIT = (1 << 63) - 1


@dataclass
class Camera:
    """A pinhole camera: eye and target (m), up vector, vertical field of view (degrees)."""

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray = None
    fov_deg: float = 35.0

    def __post_init__(self):
        self.eye = np.asarray(self.eye, np.float64)
        self.target = np.asarray(self.target, np.float64)
        self.up = np.array([0.0, 1.0, 0.0]) if self.up is None else np.asarray(self.up, np.float64)

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up, forward) unit vectors."""
        forward = self.target - self.eye
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        right /= np.linalg.norm(right)
        return right, np.cross(right, forward), forward


def framing_camera(lo, hi, direction=(1.0, 0.75, 1.4), fov_deg: float = 35.0, aspect: float = 4 / 3) -> Camera:
    """A three-quarter-view camera looking at the box [lo, hi] (m) from `direction`, far
    enough that the box's bounding sphere fills the view."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-9)
    half = math.radians(fov_deg) / 2
    half = min(half, math.atan(math.tan(half) * aspect))
    d = np.asarray(direction, np.float64)
    return Camera(centre + d / np.linalg.norm(d) * radius / math.sin(half) * 1.05, centre, fov_deg=fov_deg)


def body_colors(kinds: list[str]) -> list[tuple[int, int, int]]:
    """A colour per body: moving bodies from PALETTE, static ones grey."""
    colors, moving, static = [], 0, 0
    for kind in kinds:
        if kind == "static":
            colors.append(STATIC_GREYS[static % len(STATIC_GREYS)])
            static += 1
        else:
            colors.append(PALETTE[moving % len(PALETTE)])
            moving += 1
    return colors


@ti.func
def raster_triangle(key: ti.template(), a, b, c, t: ti.i32):
    """Triangle t (screen x, y in pixels, depth 1 − near/z) writes min(depth, t) keys into
    the pixels whose centres it covers (edge functions, either winding)."""
    height, width = key.shape
    area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
    if ti.abs(area) > 1e-12:
        x0 = ti.max(ti.cast(ti.floor(ti.min(a.x, b.x, c.x)), ti.i32), 0)
        x1 = ti.min(ti.cast(ti.ceil(ti.max(a.x, b.x, c.x)), ti.i32), width - 1)
        y0 = ti.max(ti.cast(ti.floor(ti.min(a.y, b.y, c.y)), ti.i32), 0)
        y1 = ti.min(ti.cast(ti.ceil(ti.max(a.y, b.y, c.y)), ti.i32), height - 1)
        sign = ti.select(area > 0.0, 1.0, -1.0)
        for y in range(y0, y1 + 1):
            # The row's span inside the three edge lines, widened by a pixel on each side: the
            # exact test below still decides each pixel, it just skips those sure to be out.
            py = y + 0.5
            lo, hi = ti.cast(x0, float), ti.cast(x1, float) + 1.0
            for e in ti.static(range(3)):
                p, q = ti.static((b, c), (c, a), (a, b))[e]
                slope = sign * (p.y - q.y)  # the edge function is slope·px + offset (times sign)
                offset = sign * (p.x * (q.y - py) - (p.y - py) * q.x)
                if slope > 0.0:
                    lo = ti.max(lo, -offset / slope)
                elif slope < 0.0:
                    hi = ti.min(hi, -offset / slope)
                elif offset < 0.0:
                    hi = lo - 4.0
            start = ti.max(x0, ti.cast(ti.floor(lo - 0.5), ti.i32) - 1)
            end = ti.min(x1, ti.cast(ti.ceil(hi - 0.5), ti.i32) + 1)
            for x in range(start, end + 1):
                px = x + 0.5
                w0 = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) / area
                w1 = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) / area
                w2 = 1.0 - w0 - w1
                if w0 >= 0.0 and w1 >= 0.0 and w2 >= 0.0:
                    z = ti.math.clamp(w0 * a.z + w1 * b.z + w2 * c.z, 0.0, 1.0)
                    q = ti.cast(z * DEPTH_LEVELS, ti.i64)  # z in [0, 1] -> 31 bits
                    k = (q << 32) | ti.cast(t, ti.i64)
                    if k < key[y, x]:  # a plain read first: the atomic only where this triangle is nearer
                        ti.atomic_min(key[y, x], k)


@ti.data_oriented
class Rasterizer:
    """Renders triangle soups into a width × height RGB image (uint8, row 0 at the top)."""

    def __init__(self, width: int = 800, height: int = 600):
        if width < 1 or height < 1:
            raise ValueError(f"image size must be positive, got {width} x {height}")
        self.width, self.height = int(width), int(height)
        self.key = ti.field(ti.i64, shape=(self.height, self.width))
        self.background = ti.Vector(list(BACKGROUND), ti.i32)
        self._clear()

    @ti.kernel
    def _clear(self):
        for i, j in self.key:
            self.key[i, j] = ti.i64(NO_HIT)

    @ti.kernel
    def _draw(self, n: ti.i32, screen: ti.types.ndarray(dtype=ti.math.vec3, ndim=1),
              tri_rgb: ti.types.ndarray(dtype=ti.types.vector(3, ti.u8), ndim=1),
              image: ti.types.ndarray(dtype=ti.types.vector(3, ti.u8), ndim=2),
              background: ti.types.vector(3, ti.i32)):
        """Rasterise n triangles, then colour each pixel by its key and clear the key for the
        next frame (the keys start cleared, _clear): two loops, the first finished before the
        second starts, in one launch."""
        for t in range(n):
            raster_triangle(self.key, screen[3 * t], screen[3 * t + 1], screen[3 * t + 2], t)
        for i, j in self.key:
            k = self.key[i, j]
            if k == ti.i64(NO_HIT):
                image[i, j] = ti.cast(background, ti.u8)
            else:
                image[i, j] = tri_rgb[ti.cast(k & ti.i64(0xFFFFFFFF), ti.i32)]
                self.key[i, j] = ti.i64(NO_HIT)

    def render(self, vertices: np.ndarray, faces: np.ndarray, face_rgb: np.ndarray, camera: Camera,
               points: np.ndarray | None = None, point_rgb=CONTACT_COLOR, point_size: int = 5,
               one_sided: np.ndarray | None = None) -> np.ndarray:
        """Image (height, width, 3) uint8 of the triangles vertices[faces] ((n, 3) m, (m, 3)
        int) with base colours face_rgb (m, 3) flat-shaded, seen by `camera`; `points`
        (k, 3) m are drawn on top as squares of point_size pixels. Faces marked in
        one_sided (m,) bool belong to closed, outward-oriented surfaces that keep their shape:
        they are left out when they face away from the camera (never seen: a front face of
        the same body lies nearer)."""
        tris, rgb = project_and_shade(np.asarray(vertices, np.float64), np.asarray(faces, np.int64),
                                      np.asarray(face_rgb, np.float64), camera, self.width, self.height,
                                      one_sided)
        # NumPy arrays go to the kernel as they are (on the CPU it reads and writes them in
        # place): copying them into Taichi's arrays and back took three launches more.
        screen = np.ascontiguousarray(tris.reshape(-1, 3), runtime.real_dtype())
        if not len(screen):
            screen = np.zeros((3, 3), runtime.real_dtype())
            rgb = np.zeros((1, 3), np.uint8)
        out = np.empty((self.height, self.width, 3), np.uint8)
        self._draw(len(tris), screen, np.ascontiguousarray(rgb), out, self.background)
        if points is not None and len(points):
            draw_points(out, project_points(np.asarray(points, np.float64), camera, self.width, self.height),
                        point_rgb, point_size)
        return out


NEAR = 1e-3  # m: the near plane, as a fraction of the eye-target distance


def project_points(points: np.ndarray, camera: Camera, width: int, height: int) -> np.ndarray:
    """(n, 3) world points to (n, 3) pixel x, pixel y, view depth (m)."""
    right, up, forward = camera.basis()
    rel = points - camera.eye
    x, y, z = rel @ right, rel @ up, rel @ forward
    f = 0.5 * height / math.tan(math.radians(camera.fov_deg) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        sx = 0.5 * width + f * x / z
        sy = 0.5 * height - f * y / z
    return np.stack([sx, sy, z], axis=1)


def project_and_shade(vertices, faces, face_rgb, camera: Camera, width: int, height: int, one_sided=None):
    """Triangles clipped at the near plane and projected to (k, 3, 3) screen x, y and
    depth 1 − near/z in [0, 1), with their flat-shaded colours (k, 3) uint8; faces marked in
    one_sided (m,) bool are left out where they face away from the eye."""
    if len(faces) == 0:
        return np.zeros((0, 3, 3)), np.zeros((0, 3), np.uint8)
    tri = vertices[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1)
    keep = length > 0
    if one_sided is not None:
        keep &= ~(np.asarray(one_sided, bool) & (np.einsum("ij,ij->i", normal, tri[:, 0] - camera.eye) >= 0.0))
    tri, normal, base = tri[keep], normal[keep] / length[keep, None], face_rgb[keep]
    right, up, forward = camera.basis()
    light = -forward + 0.6 * up - 0.4 * right
    light /= np.linalg.norm(light)
    shade = AMBIENT + (1 - AMBIENT) * np.clip(normal @ light, 0.0, 1.0)
    rgb = np.clip(np.round(base * shade[:, None]), 0, 255).astype(np.uint8)
    # Clip against the near plane (a triangle partly behind the eye becomes one or two).
    dist = float(np.linalg.norm(camera.target - camera.eye))
    near = NEAR * dist
    depth = (tri - camera.eye) @ forward
    out_tris, out_rgb = [], []
    inside = depth > near
    full = inside.all(axis=1)
    out_tris.append(tri[full])
    out_rgb.append(rgb[full])
    for k in np.flatnonzero(~full & inside.any(axis=1)):
        poly = _clip_polygon(tri[k], depth[k], near)
        for i in range(1, len(poly) - 1):
            out_tris.append(np.array([[poly[0], poly[i], poly[i + 1]]]))
            out_rgb.append(rgb[k:k + 1])
    tris = np.concatenate(out_tris)
    rgb = np.concatenate(out_rgb)
    screen = project_points(tris.reshape(-1, 3), camera, width, height).reshape(-1, 3, 3)
    # 1 − near/z is affine in screen space (1/z is), so the kernels may interpolate it linearly.
    screen[:, :, 2] = 1.0 - near / screen[:, :, 2]
    return screen, rgb


def _clip_polygon(tri: np.ndarray, depth: np.ndarray, near: float) -> list[np.ndarray]:
    """The part of triangle `tri` with view depth > near, as a polygon (Sutherland-Hodgman)."""
    poly = []
    for i in range(3):
        j = (i + 1) % 3
        if depth[i] > near:
            poly.append(tri[i])
        if (depth[i] > near) != (depth[j] > near):
            s = (near - depth[i]) / (depth[j] - depth[i])
            poly.append(tri[i] + s * (tri[j] - tri[i]))
    return poly


def draw_points(image: np.ndarray, screen: np.ndarray, rgb, size: int) -> None:
    """Squares of `size` pixels at the screen positions in front of the camera."""
    h, w = image.shape[:2]
    r = size // 2
    for x, y, z in screen:
        if not (z > 0 and np.isfinite(x) and np.isfinite(y)):
            continue
        cx, cy = int(math.floor(x)), int(math.floor(y))
        image[max(cy - r, 0):max(min(cy + r + 1, h), 0), max(cx - r, 0):max(min(cx + r + 1, w), 0)] = rgb


def _deflate():
    """The frames' compressor (bytes -> a zlib stream): ISA-L's (the isal package) at its level
    1, ~0.45 ms for an 800 × 600 frame against zlib's ~3.5 ms at level 3 for files ~10% larger
    (~15 KB); zlib's at level 3 where isal cannot be imported (both decode with any PNG reader)."""
    try:
        from isal import isal_zlib
    except ImportError:
        return lambda data: zlib.compress(data, 3)
    return lambda data: isal_zlib.compress(data, 1)


compress_frame = _deflate()


def write_png(path, image: np.ndarray) -> None:
    """An RGB image (height, width, 3) uint8 as an 8-bit PNG. Written here rather than by
    Pillow, whose per-row choice of filter took half of its ~11 ms a frame: a flat-shaded
    render compresses as small unfiltered (filter type 0 on every row)."""
    image = np.ascontiguousarray(image, np.uint8)
    height, width = image.shape[:2]
    rows = np.zeros((height, 1 + 3 * width), np.uint8)  # each row: filter byte 0, then RGB
    rows[:, 1:] = image.reshape(height, 3 * width)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)  # 8-bit RGB, no interlace
    with open(path, "wb") as fh:
        fh.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                 + chunk(b"IDAT", compress_frame(rows.tobytes())) + chunk(b"IEND", b""))


def last_frame(folder) -> Path | None:
    """The last frame_NNNNN.png in a run's frames folder; None without any."""
    folder = Path(folder)
    frames = sorted(folder.glob("frame_*.png")) if folder.is_dir() else []
    return frames[-1] if frames else None


def write_contact_sheet(entries, path, columns: int = 3, tile=(400, 300)) -> None:
    """A grid of each entry's last frame ((label, frames folder) pairs), labelled, as PNG;
    entries without frames are left out."""
    from PIL import Image, ImageDraw

    tiles = []
    for label, folder in entries:
        frame = last_frame(folder)
        if frame is not None:
            image = Image.open(frame).convert("RGB").resize(tile, Image.LANCZOS)
            ImageDraw.Draw(image).text((8, 6), label, fill=(20, 20, 20))
            tiles.append(image)
    if not tiles:
        return
    rows = (len(tiles) + columns - 1) // columns
    sheet = Image.new("RGB", (columns * tile[0], rows * tile[1]), BACKGROUND)
    for k, image in enumerate(tiles):
        sheet.paste(image, ((k % columns) * tile[0], (k // columns) * tile[1]))
    path = Path(path)
    sheet.save(path.with_name(path.name + ".tmp"), format="PNG")
    os.replace(path.with_name(path.name + ".tmp"), path)
