"""Image-space drawing for :mod:`quad_wrench_env.envs.render`: the camera's geometry and what is painted
onto PyBullet's image afterwards, with numpy and Pillow (no PyBullet here).

PyBullet's TinyRenderer (``rgb_array`` without a display) draws no debug lines, no text and no
transparency, and fills its huge ground plane slowly; so the renderer hides the plane and
:func:`paint_scene` paints, from each pixel's ray, a ground (1 m tiles fading into the distance, the
vehicle's shadow on it) and a sky where PyBullet drew nothing, and tints the pixels whose rays pass
through a jet by how much air of the jet's Gaussian profile they cross in front of the first opaque
surface (in closed form); both at half resolution, scaled up (they are smooth, and numpy's full-size
temporaries would cost more than the painting). Then :func:`draw_reference` draws a reference path
and point (kept off the vehicle's pixels, so the vehicle stays in front), :func:`draw_arrows` arrows
over the scene and :func:`draw_panel` text panels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cache

import numpy as np
from PIL import Image, ImageDraw, ImageFont
from scipy.special import erf

JET_COLOUR = (40, 125, 235)
"""The jet's tint (RGB)."""
_SKY = np.array(((226.0, 231.0, 238.0), (248.0, 248.0, 248.0)), dtype=np.float32)
"""Top and horizon colours of the sky (RGB)."""
_TILE = np.array((226.0, 222.0, 212.0), dtype=np.float32)
_HAZE = np.array((240.0, 240.0, 240.0), dtype=np.float32)
_OUTLINE = (25, 25, 30)


@dataclass(frozen=True)
class Camera:
    """A pinhole camera at ``eye`` looking at ``target``, z up, no roll; ``fov`` vertical (degrees)."""

    eye: np.ndarray
    target: np.ndarray
    width: int
    height: int
    fov: float = 50.0
    near: float = 0.02
    far: float = 40.0

    @property
    def axes(self) -> np.ndarray:
        """(3, 3) rows: the camera's right, up and forward unit vectors in the world frame."""
        forward = self.target - self.eye
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, (0.0, 0.0, 1.0))
        right = right / np.linalg.norm(right)
        return np.array((right, np.cross(right, forward), forward))

    @property
    def focal(self) -> float:
        """Pixels per unit of ``tan`` of the angle off the optical axis."""
        return 0.5 * self.height / math.tan(math.radians(0.5 * self.fov))

    def view_matrix(self) -> list[float]:
        """The 4x4 view matrix, column-major, as PyBullet takes it."""
        right, up, forward = self.axes
        rows = np.eye(4)
        rows[:3, :3] = (right, up, -forward)
        rows[:3, 3] = -rows[:3, :3] @ self.eye
        return rows.T.ravel().tolist()

    def projection_matrix(self) -> list[float]:
        """The 4x4 perspective projection, column-major, as PyBullet takes it."""
        f, n, r = self.focal, self.near, self.far
        rows = np.zeros((4, 4))
        rows[0, 0], rows[1, 1] = 2.0 * f / self.width, 2.0 * f / self.height
        rows[2, 2], rows[2, 3], rows[3, 2] = (r + n) / (n - r), 2.0 * r * n / (n - r), -1.0
        return rows.T.ravel().tolist()

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (n, 2) of world points (n, 3), and their depth along the optical axis
        (n,) (behind the camera where <= ``near``)."""
        local = (np.asarray(points, dtype=float) - self.eye) @ self.axes.T
        depth = np.maximum(local[:, 2], self.near)
        u = 0.5 * self.width + self.focal * local[:, 0] / depth
        v = 0.5 * self.height - self.focal * local[:, 1] / depth
        return np.column_stack((u, v)), local[:, 2]

    def depth(self, buffer: np.ndarray) -> np.ndarray:
        """Depth (m along the optical axis) from PyBullet's depth buffer in [0, 1]."""
        return self.far * self.near / (self.far - (self.far - self.near) * buffer)

    def tangents(self) -> tuple[np.ndarray, np.ndarray]:
        """(W,) and (H,) float32 tangents of each pixel column's and row's angle off the optical axis:
        the ray of pixel (row, column) is ``x·right + y·up + forward``, a unit step along the axis."""
        return _tangents(self.width, self.height, self.focal)

    def along(self, vector: np.ndarray) -> np.ndarray:
        """(H, W) float32: each pixel's ray dotted with ``vector``."""
        x, y = self.tangents()
        right, up, forward = (self.axes @ np.asarray(vector, dtype=float)).tolist()
        return (x * right)[None, :] + (y * up + forward)[:, None]


@cache
def _tangents(width: int, height: int, focal: float) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Camera.tangents`, computed once per image size."""
    x = (np.arange(width) + 0.5 - 0.5 * width) / focal
    y = (0.5 * height - np.arange(height) - 0.5) / focal
    return x.astype(np.float32), y.astype(np.float32)


@dataclass(frozen=True)
class JetShape:
    """A round jet as drawn: outlet centre, unit axis, outlet radius ``R`` and spread ``c`` of its
    half-width ``b(x) = sqrt(R² + (c·x)²)``, drawn for ``0 <= x <= length``."""

    origin: np.ndarray
    axis: np.ndarray
    radius: float
    spread: float
    length: float


def paint_scene(
    rgb: np.ndarray,
    depth: np.ndarray,
    segments: np.ndarray,
    camera: Camera,
    shadow: tuple,
    jets: list[JetShape],
    vehicle: int,
) -> Image.Image:
    """PyBullet's image ``rgb`` (H, W, 3) with the background painted where PyBullet drew nothing
    (negative ``segments``, its body ids) and everything but the body ``vehicle`` (kept clear to read)
    tinted by the ``jets``; ``depth`` (H, W): PyBullet's depth buffer, ``shadow``: the centre (x, y)
    and radius (m) of the vehicle's shadow on the ground."""
    size = (camera.width, camera.height)
    half = replace(camera, width=camera.width // 2, height=camera.height // 2)
    background, ground = _background(half, shadow)
    empty = segments < 0
    image = Image.composite(
        Image.fromarray(background).resize(size, Image.Resampling.BILINEAR),
        Image.fromarray(rgb),
        Image.fromarray(empty.view(np.uint8) * np.uint8(255)),
    )
    if not jets:
        return image
    rows, columns = half.height, half.width
    scene = np.where(
        empty[: rows * 2 : 2, : columns * 2 : 2],
        ground[:, None],
        half.depth(depth[: rows * 2 : 2, : columns * 2 : 2]),
    )
    clear = np.ones(scene.shape, dtype=np.float32)
    for jet in jets:
        clear *= 1.0 - _jet_opacity(half, scene, jet)
    alpha = Image.fromarray(((1.0 - clear) * 255.0).astype(np.uint8)).resize(size, Image.Resampling.BILINEAR)
    alpha = np.where(segments == vehicle, np.uint8(0), np.asarray(alpha))
    return Image.composite(Image.new("RGB", size, JET_COLOUR), image, Image.fromarray(alpha))


def _background(camera: Camera, shadow: tuple) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) uint8 ground (z = 0) and sky, and (H,) the ground's depth per row (``far`` for the
    sky). The camera has no roll, so where a ray meets the ground depends on its row alone."""
    x, y = camera.tangents()
    (rx, ry, _), (ux, uy, uz), (fx, fy, fz) = camera.axes.tolist()  # Python floats keep float32 float32
    (ex, ey, ez), (cx, cy), radius = camera.eye.tolist(), (float(c) for c in shadow[0]), float(shadow[1])
    rise = y * uz + fz
    ground = rise < -1e-6
    t = np.where(ground, ez / np.where(ground, -rise, np.float32(1.0)), np.float32(camera.far))
    px = (ex + t * (y * ux + fx))[:, None] + (t * rx)[:, None] * x[None, :]
    py = (ey + t * (y * uy + fy))[:, None] + (t * ry)[:, None] * x[None, :]
    tiles = np.mod(np.floor(px) + np.floor(py), 2.0)
    dark = np.clip(1.5 - np.sqrt((px - cx) ** 2 + (py - cy) ** 2) / radius, 0.0, 1.0)
    light = (1.0 - 0.085 * tiles) * (1.0 - 0.35 * dark)
    haze = np.clip((t - 6.0) / 25.0, 0.0, 1.0)[:, None]
    elevation = np.sqrt(np.clip(rise / np.sqrt(1.0 + y * y), 0.0, 1.0))[:, None]
    sky = _SKY[1] * (1.0 - elevation) + _SKY[0] * elevation
    scale = np.where(ground[:, None], _TILE * (1.0 - haze), np.float32(0.0))
    offset = np.where(ground[:, None], _HAZE * haze, sky)
    image = np.empty((camera.height, camera.width, 3), dtype=np.uint8)
    for k in range(3):  # per channel: 2-D arrays broadcast by row are far cheaper than (H, W, 3)
        np.copyto(image[:, :, k], light * scale[:, k, None] + offset[:, k, None], casting="unsafe")
    return image, t


def _jet_opacity(camera: Camera, depth: np.ndarray, jet: JetShape, density: float = 0.4) -> np.ndarray:
    """(H, W) opacity ``1 - exp(-density·∫ g ds / b)`` of the jet along each pixel's ray up to the scene
    (``depth``), with ``g = exp(-(r/b)²)`` the jet's Gaussian profile (r off the axis) over ``0 <= x <=
    length`` (x along the axis): a ray across the axis reads ``1 - exp(-density·√π)``, about 0.5, one
    along the core more. Along a ray ``eye + t·d``, ``r² = α(t - t₀)² + m`` and the integral is in
    closed form (erf), with ``b`` taken where the ray passes closest to the axis."""
    q = camera.eye - jet.origin
    qx = float(q @ jet.axis)
    qr = q - qx * jet.axis
    dx = camera.along(jet.axis)
    x, y = camera.tangents()
    alpha = np.maximum((y * y + 1.0)[:, None] + (x * x)[None, :] - dx * dx, np.float32(1e-9))
    beta = camera.along(qr)
    with np.errstate(divide="ignore", invalid="ignore"):
        ends = ((-qx) / dx, (jet.length - qx) / dx)
    low = np.maximum(np.nan_to_num(np.minimum(*ends), nan=-np.inf), camera.near)
    high = np.minimum(np.nan_to_num(np.maximum(*ends), nan=np.inf), depth)
    high = np.clip(high, low, camera.far)
    t0 = -beta / alpha
    closest = np.maximum(float(qr @ qr) - beta * beta / alpha, 0.0)
    b = np.sqrt(
        jet.radius**2 + (jet.spread * np.clip(qx + dx * np.clip(t0, low, high), 0.0, jet.length)) ** 2
    )
    root = np.sqrt(alpha) / b
    integral = 0.5 * math.sqrt(math.pi) / root * np.exp(-closest / (b * b))
    integral *= erf(root * (high - t0)) - erf(root * (low - t0))
    return (1.0 - np.exp(-density * np.nan_to_num(integral) * np.sqrt(alpha + dx * dx) / b)).astype(
        np.float32
    )


@dataclass(frozen=True)
class Arrow:
    """A force drawn from ``origin`` (m, world) along ``vector`` (m, world: the force times the scale),
    ``width`` times the normal width (a narrower arrow drawn over a wider one leaves both visible)."""

    origin: np.ndarray
    vector: np.ndarray
    colour: tuple[int, int, int]
    width: float = 1.0


def draw_arrows(image: Image.Image, camera: Camera, arrows: list[Arrow]) -> None:
    """Draw each arrow (a shaft with a head, outlined) onto ``image``, over the scene; an arrow that
    points at the camera shows as a dot."""
    draw = ImageDraw.Draw(image)
    scale = image.height / 480.0
    for arrow in arrows:
        (start, end), depth = camera.project(np.array((arrow.origin, arrow.origin + arrow.vector)))
        if min(depth) <= camera.near:
            continue
        along = end - start
        length = float(np.hypot(*along))
        if length < 6.0 * scale:
            r = 4.0 * scale
            draw.ellipse((*(start - r), *(start + r)), fill=arrow.colour, outline=_OUTLINE)
            continue
        unit = along / length
        head = min((8.0 + 8.0 * arrow.width) * scale, 0.5 * length)
        base = end - head * unit
        side = np.array((-unit[1], unit[0])) * 0.5 * head
        shaft = (tuple(start), tuple(base))
        thickness = max(1, round(5.0 * arrow.width * scale))
        draw.line(shaft, fill=_OUTLINE, width=thickness + 3)
        draw.line(shaft, fill=arrow.colour, width=thickness)
        draw.polygon(
            [tuple(end), tuple(base + side), tuple(base - side)], fill=arrow.colour, outline=_OUTLINE
        )


def draw_reference(
    image: Image.Image,
    camera: Camera,
    point: np.ndarray,
    path: np.ndarray | None,
    vehicle: np.ndarray,
    colour: tuple[int, int, int],
    clear: np.ndarray,
) -> None:
    """Draw where the vehicle should be: ``path`` (K, 3, world; may be None) as a thin line, ``point``
    (3,) as a ring with a cross and a thin line from the vehicle's position ``vehicle`` (3,) to it; not
    over the pixels of ``clear`` (H, W bool: the vehicle's). A ``point`` outside the image or behind
    the camera shows as a pointer on the image's edge towards it, labelled with its distance from the
    vehicle."""
    scale = image.height / 480.0
    shade = Image.new("L", image.size, 0)  # how much of ``colour`` each pixel takes
    draw = ImageDraw.Draw(shade)
    if path is not None and len(path) > 1:
        pixels, depth = camera.project(path)
        front = depth > camera.near
        width = max(1, round(3 * scale))
        for run in np.split(np.arange(len(path)), np.flatnonzero(np.diff(front)) + 1):
            if front[run[0]] and len(run) > 1:  # the pieces in front of the camera
                draw.line([tuple(xy) for xy in pixels[run]], fill=170, width=width, joint="curve")
    (centre, start), depth = camera.project(np.array((point, vehicle)))
    margin = 12.0 * scale
    inside = depth[0] > camera.near and bool(
        np.all((centre >= margin) & (centre <= np.array(image.size) - margin))
    )
    if inside and depth[1] > camera.near:
        draw.line((tuple(start), tuple(centre)), fill=230, width=max(1, round(2 * scale)))
    alpha = np.array(shade)
    alpha[clear] = 0
    image.paste(colour, (0, 0, *image.size), Image.fromarray(alpha))
    if not inside:
        _pointer(image, camera, point, float(np.linalg.norm(np.subtract(point, vehicle))), colour, margin)
        return
    draw, r = ImageDraw.Draw(image), 8.0 * scale  # the point itself over everything: never hidden
    draw.ellipse((*(centre - r), *(centre + r)), outline=_OUTLINE, width=max(1, round(5 * scale)))
    ring = (*(centre - r + scale), *(centre + r - scale))
    draw.ellipse(ring, outline=colour, width=max(1, round(3 * scale)))
    draw.ellipse((*(centre - 1.5 * scale), *(centre + 1.5 * scale)), fill=colour)


def _pointer(
    image: Image.Image, camera: Camera, point: np.ndarray, distance: float, colour: tuple, margin: float
) -> None:
    """A triangle on the edge of ``image`` pointing towards ``point`` (outside it or behind the camera:
    the way to turn towards it), with ``reference <distance> m``."""
    right, up, _ = camera.axes @ (np.asarray(point, dtype=float) - camera.eye)
    direction = np.array((right, -up))
    if np.hypot(*direction) < 1e-9:
        direction = np.array((0.0, 1.0))  # straight behind: point down
    direction /= np.hypot(*direction)
    half = 0.5 * np.array(image.size, dtype=float) - margin
    reach = min(h / abs(d) if abs(d) > 1e-9 else math.inf for h, d in zip(half, direction, strict=True))
    tip = 0.5 * np.array(image.size, dtype=float) + reach * direction
    scale = image.height / 480.0
    size = 18.0 * scale
    side = np.array((-direction[1], direction[0])) * 0.6 * size
    base = tip - size * direction
    draw = ImageDraw.Draw(image)
    draw.polygon([tuple(tip), tuple(base + side), tuple(base - side)], fill=colour, outline=_OUTLINE, width=2)
    font = _font(max(10, round(image.height / 34)))
    text = f"reference {distance:.1f} m"
    pad = round(0.3 * font.size)
    box = np.array((font.getlength(text) + 2 * pad, 1.3 * font.size + 2 * pad))
    corner = base - 0.5 * box - 0.6 * box * direction  # beside the triangle, inwards
    corner = np.clip(corner, 2.0, np.array(image.size) - box - 2.0)
    draw.rounded_rectangle((*corner, *(corner + box)), radius=pad, fill=(20, 22, 28))
    draw.text(tuple(corner + pad), text, fill=(245, 245, 245), font=font)


@cache
def _font(size: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    return ImageFont.load_default(size=size)


def draw_panel(
    image: Image.Image, lines: list[str], legend: list[tuple[str, tuple[int, int, int]]], top: bool = True
) -> None:
    """A translucent dark panel in the top left (``top``) or the bottom right corner of ``image`` with
    ``lines`` of text, then ``legend`` entries (a colour swatch and its label)."""
    size = max(10, round(image.height / 34))
    font, pad, step, swatch = _font(size), round(0.5 * size), round(1.3 * size), 2 * size
    rows = [(line, None) for line in lines] + [(label, colour) for label, colour in legend]
    width = (
        round(max(font.getlength(text) + (swatch + pad if colour else 0) for text, colour in rows)) + 2 * pad
    )
    height = step * len(rows) + 2 * pad
    box = (pad, pad) if top else (image.width - width - pad, image.height - height - pad)
    box = (*box, box[0] + width, box[1] + height)
    region = image.crop(box).convert("RGBA")
    shade = Image.new("RGBA", region.size, (0, 0, 0, 0))
    ImageDraw.Draw(shade).rounded_rectangle((0, 0, width - 1, height - 1), radius=pad, fill=(20, 22, 28, 170))
    image.paste(Image.alpha_composite(region, shade).convert("RGB"), box[:2])
    draw = ImageDraw.Draw(image)
    for k, (text, colour) in enumerate(rows):
        x, y = box[0] + pad, box[1] + pad + k * step
        if colour is not None:
            middle = y + 0.55 * size
            draw.line(((x, middle), (x + swatch, middle)), fill=colour, width=max(3, size // 3))
            x += swatch + pad
        draw.text((x, y), text, fill=(245, 245, 245), font=font)
