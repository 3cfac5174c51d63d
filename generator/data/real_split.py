"""The real dev split: articulated objects rendered as product photos and in rooms.

``write_real_split(out, sources)`` renders every object of ``sources`` (each an id, a
loader returning an :class:`ArticulatedObject` and a provenance record) in two styles
and writes a folder in the layout of the procedural test split
(``generator.data.test_split``): ``out/images/<image id>.png`` + ``.mask.png`` + ``.json``
hints (the category), ``out/gt/<object id>/`` (the object's bundle, as given: for
PartNet-Mobility objects the importer's normalized object, ``scale = None``) and
``out/manifest.json`` (objects, styles, views, the camera of every image, the source
of every object, failures). Image ids are ``<object id>_<style>_<k>``; several images
share one ground-truth bundle, ``manifest["images"][i]["object"]`` names it.

This module only renders given objects; importing PartNet-Mobility folders is
``asset_pipeline.importers.partnet``'s job (``bench/real_split.py`` joins the two, since
``generator`` must not import ``asset_pipeline``).

Styles (both at rest, all joints at ``lower``, as the test split):

``product``
    A seamless studio sweep (floor, cove and wall in one near-white or light-grey
    colour) behind the object, soft light (ambient, a shadow-casting key light from
    above the camera's side, a fill and a rim light) and a soft contact shadow (the
    key light's shadow map plus a blurred darkening of the floor under the object's
    footprint). Camera at the front three-quarter: azimuth 20-50 degrees either side
    of the front (+x), elevation 5-30 degrees, vertical field of view 30-60 degrees,
    the object filling 70-90 % of the half-frame.

``room``
    A floor (wood planks or tiles), a back wall just behind the object and, half of
    the time, a side wall on the far side (a corner), skirting boards, sometimes a
    picture on the wall, 2-5 clutter boxes / cylinders / potted plants of random
    colours beside or behind the object (never in front of it, never hiding it), warm
    indoor light (one or two warm lamps in front and above, a window light casting
    shadows, warm ambient). An object under 0.55 m tall (a microwave) stands on a
    counter with its clutter. Camera: azimuth 15-50 degrees, elevation 5-30 degrees,
    field of view 45-65 degrees, the object filling 45-70 % of the half-frame.

Sizes of the scenery are in metres, converted with the object's ``scale`` (metres per
unit) or, for a normalized object (``scale = None``), with a typical height of its
category (``TYPICAL_HEIGHT_M``). Masks are the part ids of the test split (0 for
everything that is not the object, 1 base, slot + 1 for the other parts in
``ArticulatedObject.parts`` order); cameras follow ``generator.data.render`` (OpenCV
extrinsics world -> camera, world = the object's frame; pinhole intrinsics in pixels).
Images are rendered at ``supersample`` times the size and averaged down (masks: the
most frequent id of each block). Deterministic for a seed: every view draws from a
random stream keyed by (seed, object id, style, view).
"""

from __future__ import annotations

import json
import logging
import math
import os
import time
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from generator.articulated import ArticulatedObject
from generator.atomic_files import atomic_write_bytes
from generator.bundle import save_bundle
from generator.data.render import (
    RenderedView,
    fit_distance,
    look_at,
    part_slots,
    posed_vertices,
    render_shape,
    render_system,
    rest_qpos,
    sapien,
)

log = logging.getLogger(__name__)

SCHEMA = "pact.real_split"
VERSION = 1
STYLES: tuple[str, ...] = ("product", "room")
#: Where ``bench/real_split.py`` writes the split and the benches look for it.
DEFAULT_REAL_SPLIT = Path(os.environ.get("PACT_REAL_SPLIT", "/work/data/real_split"))
#: The two halves of the PartNet-Mobility dev objects: half A may be trained on (the
#: generated training assets' photos, the parser variant's renders), half B never is.
DEV_HALVES = Path(__file__).resolve().parents[2] / "policies" / "partnet_split.json"


def dev_half(half: str) -> list[str]:
    """The object ids of half ``"A"`` or ``"B"`` of the dev objects (``DEV_HALVES``)."""
    d = json.loads(DEV_HALVES.read_text())
    keys = [k for k in d if k.startswith(f"{half}_")]
    if len(keys) != 1:
        raise ValueError(f"{DEV_HALVES}: no half {half!r} (halves: {', '.join(d)})")
    return list(d[keys[0]])


#: Closed height (metres) assumed for an object without a metric scale.
TYPICAL_HEIGHT_M = {
    "cabinet": 0.9,
    "desk": 0.75,
    "microwave": 0.32,
    "oven": 0.9,
    "refrigerator": 1.75,
    "dishwasher": 0.85,
    "washing_machine": 0.85,
}
#: What a rendered pixel shows (``StyledRender.labels``).
LABELS = ("none", "object", "floor", "wall", "clutter", "furniture")


@dataclass(frozen=True)
class StyleConfig:
    """Camera ranges of one style (degrees; ``fill``: share of the half-frame)."""

    azimuth: tuple[float, float]  # off the front (+x), either side
    elevation: tuple[float, float]
    fovy: tuple[float, float]
    fill: tuple[float, float]


STYLE_CONFIGS = {
    "product": StyleConfig((20.0, 50.0), (5.0, 30.0), (30.0, 60.0), (0.70, 0.90)),
    "room": StyleConfig((15.0, 50.0), (5.0, 30.0), (45.0, 65.0), (0.45, 0.70)),
}


@dataclass
class Prop:
    """One piece of scenery. ``shape``: "mesh" (``mesh`` = vertices, normals, uv, each
    (3F, ...), triangles in order, with ``texture``), "box" (``size`` = half extents),
    "cylinder" (``size`` = radius, half height; axis +z) or "sphere" (``size`` = radius)."""

    label: str  # one of LABELS
    shape: str
    pose: np.ndarray  # 4x4, object frame
    colour: np.ndarray = field(default_factory=lambda: np.ones(3))  # sRGB 0..1 (primitives)
    size: np.ndarray = field(default_factory=lambda: np.ones(3))
    mesh: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    texture: np.ndarray | None = None  # (H, W, 3|4) uint8 sRGB
    address: str = "repeat"
    roughness: float = 0.8
    specular: float = 0.3
    emission: float = 0.0  # glow (times the colour / texture): a studio backdrop's brightness


@dataclass
class StyledView:
    """Everything random about one view of one style (object frame, angles in degrees)."""

    style: str
    qpos: np.ndarray
    eye: np.ndarray
    target: np.ndarray
    fovy: float  # radians
    azimuth: float
    elevation: float
    ambient: np.ndarray
    key: tuple[np.ndarray, np.ndarray]  # (direction, rgb); casts shadows
    fills: list[tuple[np.ndarray, np.ndarray]]  # directional, no shadow (at most 2)
    lamps: list[tuple[np.ndarray, np.ndarray]]  # point lights (position, rgb), at most 2
    props: list[Prop]


@dataclass
class StyledRender(RenderedView):
    labels: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.uint8))  # LABELS


# --------------------------------------------------------------------------- textures


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.clip(np.asarray(c, float), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _u8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.round(img * 255.0), 0, 255).astype(np.uint8)


def periodic_noise(
    rng: np.random.Generator, shape: tuple[int, int], cycles: tuple[float, float]
) -> np.ndarray:
    """(H, W) smooth noise, zero mean, unit std, tiling seamlessly; ``cycles`` = the
    feature frequency (cycles per period) along rows and columns."""
    white = rng.standard_normal(shape)
    fr = np.fft.fftfreq(shape[0]) * shape[0] / max(cycles[0], 1e-3)
    fc = np.fft.fftfreq(shape[1]) * shape[1] / max(cycles[1], 1e-3)
    spectrum = np.fft.fft2(white) * np.exp(-(fr[:, None] ** 2 + fc[None, :] ** 2))
    out = np.real(np.fft.ifft2(spectrum))
    return (out - out.mean()) / (out.std() + 1e-12)


WOODS = (
    (0.62, 0.45, 0.28),  # oak
    (0.74, 0.58, 0.40),  # light oak
    (0.40, 0.26, 0.16),  # walnut
    (0.80, 0.69, 0.54),  # ash
    (0.52, 0.32, 0.22),  # cherry
    (0.64, 0.61, 0.56),  # grey-washed
)
TILES = (
    (0.86, 0.82, 0.74),  # beige
    (0.92, 0.92, 0.90),  # white
    (0.62, 0.62, 0.61),  # grey
    (0.70, 0.42, 0.31),  # terracotta
    (0.36, 0.38, 0.41),  # slate
)
PAINTS = (
    (0.93, 0.91, 0.87),  # off-white
    (0.88, 0.82, 0.72),  # beige
    (0.74, 0.81, 0.87),  # pale blue
    (0.72, 0.78, 0.67),  # sage
    (0.80, 0.80, 0.79),  # grey
    (0.93, 0.86, 0.66),  # warm yellow
    (0.86, 0.72, 0.64),  # blush
)


def wood_texture(rng: np.random.Generator, px: int, period_m: float) -> np.ndarray:
    """(px, px, 3) uint8 plank floor tiling seamlessly over ``period_m`` metres."""
    rows = max(2, round(period_m / rng.uniform(0.12, 0.2)))
    base = np.array(WOODS[int(rng.integers(len(WOODS)))])
    img = np.empty((px, px, 3))
    r_of = (np.arange(px) * rows) // px  # plank row of each image row
    cols = np.arange(px)
    grain = periodic_noise(rng, (px, px), (rows * 6.0, 1.5))
    fine = periodic_noise(rng, (px, px), (px / 6.0, px / 12.0))
    for r in range(rows):
        cuts = np.sort(rng.uniform(0, px, int(rng.integers(1, 4)))).astype(int)
        seg = np.searchsorted(cuts, cols, side="right") % len(cuts)
        tints = (
            base * rng.uniform(0.82, 1.12, (len(cuts), 1)) * rng.uniform(0.97, 1.03, (len(cuts), 3))
        )
        sel = r_of == r
        img[sel] = tints[seg][None, :, :]
        for c in cuts:  # butt joints
            img[sel, c % px] *= 0.55
    img *= (1.0 + 0.07 * grain + 0.03 * fine)[..., None]
    edges = np.nonzero(np.diff(np.r_[r_of[-1], r_of]) != 0)[0]
    img[edges] *= 0.5  # gaps between rows
    img = _u8(img)
    return img if rng.random() < 0.5 else np.ascontiguousarray(img.transpose(1, 0, 2))


def tile_texture(rng: np.random.Generator, px: int, period_m: float) -> np.ndarray:
    """(px, px, 3) uint8 tiled floor (grout lines) tiling seamlessly over ``period_m``."""
    n = max(2, round(period_m / rng.uniform(0.3, 0.6)))
    a = np.array(TILES[int(rng.integers(len(TILES)))])
    checker = rng.random() < 0.2
    b = np.array(TILES[int(rng.integers(len(TILES)))]) if checker else a
    idx = (np.arange(px) * n) // px
    tint = rng.uniform(0.95, 1.04, (n, n, 1))
    colours = np.where(((idx[:, None] + idx[None, :]) % 2 == 0)[..., None], a, b)
    img = colours * tint[idx][:, idx]
    img *= (1.0 + 0.04 * periodic_noise(rng, (px, px), (n * 3.0, n * 3.0)))[..., None]
    grout = np.array([0.78, 0.76, 0.72]) if rng.random() < 0.6 else np.array([0.3, 0.3, 0.3])
    w = max(1, px // (n * 40))
    lines = np.zeros(px, bool)
    for b in np.nonzero(np.diff(np.r_[idx[-1], idx]))[0]:  # first pixel of every tile
        lines[b : b + w] = True
    img[lines] = grout
    img[:, lines] = grout
    return _u8(img)


def paint_texture(rng: np.random.Generator, px: int, colour: np.ndarray) -> np.ndarray:
    """(px, px, 3) uint8 painted wall (a faint mottle), tiling seamlessly."""
    noise = periodic_noise(rng, (px, px), (6.0, 6.0))
    return _u8(np.asarray(colour)[None, None] * (1.0 + 0.015 * noise)[..., None])


def _shadow_square(
    pts: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    side: float,
    z: float,
    sigma: float,
    strength: float,
) -> tuple[Any, np.ndarray]:
    """A horizontal square ``side`` wide at height ``z``, centred under the footprint
    ``lo``..``hi`` (x, y), and its shading (256 px): the contact shadow of ``pts``."""
    origin = (lo[:2] + hi[:2]) / 2 - side / 2
    shade = footprint_shadow(pts[:, :2], origin, side, 256, sigma, strength)
    mesh = _plane(
        [origin[0], origin[1], z], [1, 0, 0], [0, 1, 0], (0, side), (0, side), [0, 0, 1], side
    )
    return mesh, shade


def footprint_shadow(
    points_xy: np.ndarray, origin: np.ndarray, side: float, px: int, sigma: float, strength: float
) -> np.ndarray:
    """(px, px) factor in (0, 1]: 1 - ``strength`` x the blurred convex hull of
    ``points_xy`` over the square [origin, origin + side] (row = y, column = x)."""
    from PIL import ImageFilter
    from scipy.spatial import ConvexHull

    uv = (points_xy - origin) / side * px
    try:
        hull = uv[ConvexHull(uv).vertices]
    except Exception:  # noqa: BLE001 - degenerate footprint: its bounding box
        lo, hi = uv.min(0), uv.max(0)
        hull = np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])
    canvas = Image.new("L", (px, px), 0)
    ImageDraw.Draw(canvas).polygon([tuple(map(float, p)) for p in hull], fill=255)
    blurred = canvas.filter(ImageFilter.GaussianBlur(radius=max(0.5, sigma / side * px)))
    return 1.0 - strength * np.asarray(blurred, float) / 255.0


# --------------------------------------------------------------------------- geometry


def _quads(corners: np.ndarray, normals: np.ndarray, uv: np.ndarray):  # noqa: ANN202
    """Triangles of quads: ``corners`` (Q, 4, 3), ``normals`` (Q, 4, 3), ``uv`` (Q, 4, 2)
    -> (6Q, 3) vertices, normals, (6Q, 2) uv, counter-clockwise seen from the normal."""
    out_v, out_n, out_uv = [], [], []
    for c, n, t in zip(corners, normals, uv, strict=True):
        order = [0, 1, 2, 0, 2, 3]
        if np.dot(np.cross(c[1] - c[0], c[2] - c[0]), n.mean(0)) < 0:
            order = [0, 2, 1, 0, 3, 2]
        out_v.append(c[order])
        out_n.append(n[order])
        out_uv.append(t[order])
    return (
        np.concatenate(out_v).astype(np.float32),
        np.concatenate(out_n).astype(np.float32),
        np.concatenate(out_uv).astype(np.float32),
    )


def _plane(origin, u_axis, v_axis, u_range, v_range, normal, uv_scale, uv_offset=(0.0, 0.0)):  # noqa: ANN001, ANN202
    """One quad spanning ``origin + u * u_axis + v * v_axis``; texture coordinates
    ``(u, v) / uv_scale - uv_offset`` (v runs along image rows)."""
    o, ua, va = (np.asarray(x, float) for x in (origin, u_axis, v_axis))
    us, vs = (
        (u_range[0], u_range[1], u_range[1], u_range[0]),
        (v_range[0], v_range[0], v_range[1], v_range[1]),
    )
    corners = np.array([o + u * ua + v * va for u, v in zip(us, vs, strict=True)])
    uv = np.array(
        [
            [u / uv_scale - uv_offset[0], v / uv_scale - uv_offset[1]]
            for u, v in zip(us, vs, strict=True)
        ]
    )
    n = np.repeat(np.asarray(normal, float)[None], 4, 0)
    return _quads(corners[None], n[None], uv[None])


def _sweep(
    wall_x: float, z_floor: float, radius: float, reach: float, height: float, half_width: float
):  # noqa: ANN202
    """Studio sweep: floor (z = ``z_floor``, x from the cove to ``reach``), a quarter-circle
    cove of ``radius``, the wall (x = ``wall_x``) up to ``height``; smooth normals."""
    cx, cz = wall_x + radius, z_floor + radius
    prof = [(reach, z_floor, 0.0, 1.0)]
    for t in np.linspace(0.0, 1.0, 13):
        a = -np.pi / 2 - t * np.pi / 2  # bottom of the cove -> its top at the wall
        prof.append((cx + radius * np.cos(a), cz + radius * np.sin(a), -np.cos(a), -np.sin(a)))
    prof.append((wall_x, z_floor + height, 1.0, 0.0))
    corners, normals = [], []
    for (x0, z0, nx0, nz0), (x1, z1, nx1, nz1) in zip(prof[:-1], prof[1:], strict=True):
        corners.append(
            [
                [x0, -half_width, z0],
                [x0, half_width, z0],
                [x1, half_width, z1],
                [x1, -half_width, z1],
            ]
        )
        n0, n1 = [nx0, 0.0, nz0], [nx1, 0.0, nz1]
        normals.append([n0, n0, n1, n1])
    uv = np.full((len(corners), 4, 2), 0.5)
    return _quads(np.array(corners), np.array(normals), uv)


def _pose(xyz, yaw: float = 0.0) -> np.ndarray:  # noqa: ANN001
    T = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = xyz
    return T


def _units_per_metre(obj: ArticulatedObject, lo: np.ndarray, hi: np.ndarray) -> float:
    if obj.scale:
        return 1.0 / float(obj.scale)
    return float(hi[2] - lo[2]) / TYPICAL_HEIGHT_M.get(obj.category, 0.9)


def _project(points: np.ndarray, eye: np.ndarray, target: np.ndarray, fovy: float):  # noqa: ANN202
    """(N, 2) normalized image coordinates (tan units) and (N,) depths of ``points``."""
    T = look_at(eye, target)
    rel = (points - eye) @ T[:3, :3]
    depth = np.maximum(rel[:, 2], 1e-6)
    return rel[:, :2] / depth[:, None], depth


def _box_corners(centre: np.ndarray, half: np.ndarray, yaw: float) -> np.ndarray:
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return (signs * half) @ _pose((0, 0, 0), yaw)[:3, :3].T + centre


# --------------------------------------------------------------------------- views


def _camera(obj: ArticulatedObject, qpos: np.ndarray, rng: np.random.Generator, cfg: StyleConfig):  # noqa: ANN202
    pts = posed_vertices(obj, qpos)
    lo, hi = pts.min(0), pts.max(0)
    size = float(np.max(hi - lo))
    target = (lo + hi) / 2 + rng.uniform(-1, 1, 3) * 0.02 * size
    az_deg = float(rng.uniform(*cfg.azimuth) * rng.choice([-1.0, 1.0]))
    el_deg = float(rng.uniform(*cfg.elevation))
    az, el = np.deg2rad(az_deg), np.deg2rad(el_deg)
    back = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    fovy = float(np.deg2rad(rng.uniform(*cfg.fovy)))
    tan_half = np.tan(fovy / 2) * rng.uniform(*cfg.fill)
    eye = target + back * fit_distance(pts, target, back, tan_half)
    return pts, lo, hi, size, target, eye, fovy, az_deg, el_deg


def _direction(az_deg: float, el_deg: float) -> np.ndarray:
    """Direction light travels, from a source at azimuth / elevation (degrees)."""
    az, el = np.deg2rad(az_deg), np.deg2rad(el_deg)
    return -np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def _product_scene(rng, pts, lo, hi, size, az_deg):  # noqa: ANN001, ANN202
    grey = rng.uniform(0.90, 1.0)
    colour = np.clip(grey * (1.0 + rng.uniform(-0.015, 0.015, 3)), 0, 1)
    gap = rng.uniform(0.4, 1.2) * size
    wall_x = float(lo[0] - gap)
    radius = float(rng.uniform(0.3, 0.8) * (gap - 0.05 * size))
    z0 = float(lo[2])
    far = 60.0 * size
    flat = _u8(np.broadcast_to(colour, (4, 4, 3)))
    glow = rng.uniform(0.3, 0.5)  # studio backdrops are lit to (nearly) white
    props = [
        Prop(
            "floor",
            "mesh",
            np.eye(4),
            mesh=_sweep(wall_x, z0, radius, far, far, far),
            texture=flat,
            address="edge",
            roughness=0.9,
            specular=0.2,
            emission=glow,
        )
    ]
    # contact shadow: the floor's colour darkened under the footprint, just above the floor
    sigma = rng.uniform(0.04, 0.08) * size
    mesh, shade = _shadow_square(
        pts, lo, hi, 2.0 * size, z0 + 1e-3 * size, sigma, rng.uniform(0.45, 0.65)
    )
    tex = _u8(np.asarray(colour)[None, None] * shade[..., None])
    props.append(
        Prop(
            "floor",
            "mesh",
            np.eye(4),
            mesh=mesh,
            texture=tex,
            address="edge",
            roughness=0.9,
            specular=0.2,
            emission=glow,
        )
    )

    ambient = rng.uniform(0.25, 0.4) * np.ones(3)
    key = (
        _direction(az_deg + rng.uniform(-50, 50), rng.uniform(50, 75)),
        rng.uniform(1.3, 2.0) * np.ones(3),
    )
    fills = [
        (
            _direction(-az_deg * rng.uniform(0.5, 1.5), rng.uniform(10, 35)),
            rng.uniform(0.3, 0.6) * np.ones(3),
        ),
        (
            _direction(az_deg + 180 + rng.uniform(-40, 40), rng.uniform(30, 60)),
            rng.uniform(0.2, 0.5) * np.ones(3),
        ),
    ]
    return props, ambient, key, fills, []


def _room_scene(rng, obj, pts, lo, hi, size, az_deg, eye, target, fovy):  # noqa: ANN001, ANN202
    m = _units_per_metre(obj, lo, hi)
    far = 60.0 * size
    height_m = (hi[2] - lo[2]) / m
    on_counter = height_m < 0.55
    appliance = obj.category in (
        "oven",
        "refrigerator",
        "dishwasher",
        "washing_machine",
        "microwave",
    )
    gap = (
        rng.uniform(0.01, 0.08)
        if appliance
        else rng.uniform(0.03, 0.6 if obj.category == "desk" else 0.12)
    )
    wall_x = float(lo[0] - gap * m)
    z_top = float(lo[2])  # what the object stands on
    props: list[Prop] = []
    counter = None
    if on_counter:
        z_floor = z_top - rng.uniform(0.86, 0.94) * m
        depth = max(hi[0] + rng.uniform(0.04, 0.15) * m, wall_x + 0.6 * m)
        y0 = lo[1] - rng.uniform(0.4, 1.2) * m
        y1 = hi[1] + rng.uniform(0.4, 1.2) * m
        counter = (wall_x, depth, y0, y1)
        ctop = (
            np.array(WOODS[int(rng.integers(len(WOODS)))])
            if rng.random() < 0.5
            else np.array(TILES[int(rng.integers(len(TILES)))])
        )
        half = np.array([(depth - wall_x) / 2, (y1 - y0) / 2, (z_top - z_floor) / 2])
        centre = [(depth + wall_x) / 2, (y0 + y1) / 2, (z_top + z_floor) / 2]
        props.append(Prop("furniture", "box", _pose(centre), ctop, half, roughness=0.6))
        support_colour = ctop
    else:
        z_floor = z_top

    # side wall (a corner) on the far side from the camera, half of the time
    cam_side = 1.0 if az_deg > 0 else -1.0
    side_y = None
    if rng.random() < 0.5:
        gs = rng.uniform(0.15, 1.2) * m
        side_y = float(lo[1] - gs) if cam_side > 0 else float(hi[1] + gs)
    y_lo = side_y if (side_y is not None and cam_side > 0) else -far
    y_hi = side_y if (side_y is not None and cam_side < 0) else far

    # floor: a tiling texture, plus a patch of it darkened under the object
    period_m = 2.4
    px = 512
    tex = wood_texture(rng, px, period_m) if rng.random() < 0.6 else tile_texture(rng, px, period_m)
    P = period_m * m
    props.append(
        Prop(
            "floor",
            "mesh",
            np.eye(4),
            mesh=_plane(
                [0, 0, z_floor],
                [1, 0, 0],
                [0, 1, 0],
                (wall_x, wall_x + far),
                (y_lo, y_hi),
                [0, 0, 1],
                P,
            ),
            texture=tex,
            roughness=0.55,
            specular=0.4,
        )
    )
    sigma = rng.uniform(0.03, 0.06) * size
    strength = rng.uniform(0.35, 0.5)
    if counter is None:
        need = float(np.max(hi[:2] - lo[:2])) + 8 * sigma
        k = max(1, math.ceil(need / P))
        n_px = k * px
        centre = (lo[:2] + hi[:2]) / 2 - k * P / 2
        start = np.round(centre / P * px).astype(int)  # texel-aligned patch
        origin = start * P / px
        rows = (start[1] + np.arange(n_px)) % px
        cols = (start[0] + np.arange(n_px)) % px
        base = tex[rows][:, cols].astype(float) / 255.0
        shade = footprint_shadow(pts[:, :2], origin, k * P, n_px, sigma, strength)
        mesh = _plane(
            [origin[0], origin[1], z_floor + 1e-3 * size],
            [1, 0, 0],
            [0, 1, 0],
            (0, k * P),
            (0, k * P),
            [0, 0, 1],
            k * P,
        )
        props.append(
            Prop(
                "floor",
                "mesh",
                np.eye(4),
                mesh=mesh,
                texture=_u8(base * shade[..., None]),
                address="edge",
                roughness=0.55,
                specular=0.4,
            )
        )
    else:
        side = float(np.max(hi[:2] - lo[:2])) + 8 * sigma
        mesh, shade = _shadow_square(pts, lo, hi, side, z_top + 1e-3 * size, sigma, strength)
        props.append(
            Prop(
                "furniture",
                "mesh",
                np.eye(4),
                mesh=mesh,
                texture=_u8(np.asarray(support_colour)[None, None] * shade[..., None]),
                address="edge",
                roughness=0.6,
            )
        )

    # walls
    paint = np.array(PAINTS[int(rng.integers(len(PAINTS)))]) * rng.uniform(0.95, 1.02)
    wall_tex = paint_texture(rng, 128, paint)
    wall_h = far
    props.append(
        Prop(
            "wall",
            "mesh",
            np.eye(4),
            mesh=_plane(
                [wall_x, 0, z_floor],
                [0, 1, 0],
                [0, 0, -1],
                (y_lo, y_hi),
                (-wall_h, 0),
                [1, 0, 0],
                m,
            ),
            texture=wall_tex,
            roughness=0.95,
            specular=0.1,
        )
    )
    skirting = np.array([0.95, 0.94, 0.92]) if rng.random() < 0.6 else paint * 0.8
    sk_h, sk_d = rng.uniform(0.06, 0.12) * m, 0.015 * m
    span = min(y_hi - y_lo, 2 * far)
    props.append(
        Prop(
            "furniture",
            "box",
            _pose([wall_x + sk_d / 2, (max(y_lo, -far) + min(y_hi, far)) / 2, z_floor + sk_h / 2]),
            skirting,
            np.array([sk_d / 2, span / 2, sk_h / 2]),
            roughness=0.5,
        )
    )
    if side_y is not None:
        normal = [0, cam_side, 0]
        props.append(
            Prop(
                "wall",
                "mesh",
                np.eye(4),
                mesh=_plane(
                    [0, side_y, z_floor],
                    [1, 0, 0],
                    [0, 0, -1],
                    (wall_x, wall_x + far),
                    (-wall_h, 0),
                    normal,
                    m,
                ),
                texture=wall_tex,
                roughness=0.95,
                specular=0.1,
            )
        )
        props.append(
            Prop(
                "furniture",
                "box",
                _pose([wall_x + far / 2, side_y + cam_side * sk_d / 2, z_floor + sk_h / 2]),
                skirting,
                np.array([far / 2, sk_d / 2, sk_h / 2]),
                roughness=0.5,
            )
        )
    if rng.random() < 0.5:  # a picture above the object
        w, h = rng.uniform(0.3, 0.8) * m, rng.uniform(0.25, 0.6) * m
        zc = hi[2] + rng.uniform(0.15, 0.4) * m + h / 2
        yc = (lo[1] + hi[1]) / 2 + rng.uniform(-0.5, 0.5) * m
        frame = np.array([0.1, 0.08, 0.06]) if rng.random() < 0.5 else np.array([0.85, 0.8, 0.7])
        props.append(
            Prop(
                "furniture",
                "box",
                _pose([wall_x + 0.012 * m, yc, zc]),
                frame,
                np.array([0.012 * m, w / 2, h / 2]),
                roughness=0.5,
            )
        )
        art = rng.uniform(0.15, 0.9, 3)
        props.append(
            Prop(
                "furniture",
                "box",
                _pose([wall_x + 0.02 * m, yc, zc]),
                art,
                np.array([0.006 * m, w / 2 - 0.03 * m, h / 2 - 0.03 * m]),
                roughness=0.7,
            )
        )

    # clutter beside or behind the object, never in front of it nor hiding it
    uv_obj, depth_obj = _project(pts, eye, target, fovy)
    o_lo, o_hi = uv_obj.min(0), uv_obj.max(0)
    obj_depth = float(np.median(depth_obj))
    placed: list[tuple[np.ndarray, np.ndarray]] = []  # (xy lo, xy hi)
    scale = 0.5 if counter is not None else 1.0
    for _ in range(int(rng.integers(2, 6))):
        for _attempt in range(25):
            kind = rng.choice(["box", "cylinder", "plant"], p=[0.5, 0.35, 0.15])
            if kind == "box":
                half = rng.uniform([0.05, 0.05, 0.05], [0.25, 0.25, 0.3]) * m * scale
                yaw = rng.uniform(-0.4, 0.4)
                ext = np.abs(_pose((0, 0, 0), yaw)[:2, :2]) @ half[:2]
            else:
                r = rng.uniform(0.05, 0.18) * m * scale
                hh = (
                    rng.uniform(0.06, 0.3) * m * scale
                    if kind == "cylinder"
                    else rng.uniform(0.06, 0.14) * m * scale
                )
                half, yaw = np.array([r, r, hh]), 0.0
                ext = np.array([r, r])
            s = rng.choice([-1.0, 1.0])
            margin = rng.uniform(0.03, 0.5) * m * scale
            y = hi[1] + margin + ext[1] if s > 0 else lo[1] - margin - ext[1]
            x_min, x_max = wall_x + ext[0] + 0.01 * m, hi[0] - ext[0]
            x = rng.uniform(x_min, x_max) if x_max > x_min else x_min
            if counter is not None:
                x_max = counter[1] - ext[0]
                x = rng.uniform(x_min, x_max) if x_max > x_min else x_min
                if not (counter[2] + ext[1] < y < counter[3] - ext[1]):
                    continue
            if side_y is not None and (
                y - ext[1] < side_y < y + ext[1] or (side_y - y) * cam_side > 0
            ):
                continue
            b_lo, b_hi = np.array([x, y]) - ext, np.array([x, y]) + ext
            if any(np.all(b_lo < q_hi) and np.all(q_lo < b_hi) for q_lo, q_hi in placed):
                continue
            top = z_top if counter is not None else z_floor
            plant_h = 2 * half[2] + 1.6 * half[0] if kind == "plant" else 2 * half[2]
            centre = np.array([x, y, top + plant_h / 2])
            uv_c, d_c = _project(
                _box_corners(centre, np.array([ext[0], ext[1], plant_h / 2]), 0.0),
                eye,
                target,
                fovy,
            )
            overlaps = np.all(uv_c.min(0) < o_hi) and np.all(o_lo < uv_c.max(0))
            if overlaps and float(d_c.min()) < obj_depth:
                continue  # would hide part of the object
            placed.append((b_lo, b_hi))
            if kind == "box":
                colour = (
                    rng.uniform(0.1, 0.9, 3)
                    if rng.random() < 0.7
                    else np.array([0.62, 0.47, 0.30]) * rng.uniform(0.9, 1.1)
                )
                props.append(
                    Prop(
                        "clutter",
                        "box",
                        _pose([x, y, top + half[2]], yaw),
                        colour,
                        half,
                        roughness=rng.uniform(0.4, 0.9),
                    )
                )
            elif kind == "cylinder":
                props.append(
                    Prop(
                        "clutter",
                        "cylinder",
                        _pose([x, y, top + half[2]]),
                        rng.uniform(0.1, 0.9, 3),
                        half[[0, 2]],
                        roughness=rng.uniform(0.2, 0.8),
                        specular=0.5,
                    )
                )
            else:
                pot = (
                    np.array([0.66, 0.38, 0.26]) if rng.random() < 0.5 else rng.uniform(0.2, 0.9, 3)
                )
                props.append(
                    Prop(
                        "clutter",
                        "cylinder",
                        _pose([x, y, top + half[2]]),
                        pot,
                        half[[0, 2]],
                        roughness=0.7,
                    )
                )
                leaves = np.array([0.18, 0.42, 0.16]) * rng.uniform(0.7, 1.2)
                props.append(
                    Prop(
                        "clutter",
                        "sphere",
                        _pose([x, y, top + 2 * half[2] + 0.8 * half[0]]),
                        leaves,
                        np.array([1.2 * half[0]]),
                        roughness=0.9,
                    )
                )
            break

    warm = np.array([1.0, 0.82, 0.62]) * rng.uniform(0.95, 1.05, 3)
    ambient = rng.uniform(0.12, 0.25) * np.array([1.0, 0.92, 0.8])
    key = (
        _direction(az_deg + rng.uniform(-60, 60), rng.uniform(35, 65)),
        rng.uniform(0.6, 1.2) * (np.array([1.0, 0.97, 0.92]) if rng.random() < 0.5 else warm),
    )
    fills = [
        (
            _direction(az_deg * rng.uniform(0.5, 1.5), rng.uniform(10, 30)),
            rng.uniform(0.1, 0.3) * warm,
        )
    ]
    lamps = []
    centre = (lo + hi) / 2
    for _ in range(int(rng.integers(1, 3))):
        pos = np.array(
            [
                hi[0] + rng.uniform(0.3, 1.5) * m,
                centre[1] + rng.uniform(-1.0, 1.0) * m,
                hi[2] + rng.uniform(0.6, 1.2) * m,
            ]
        )
        d2 = float(np.sum((pos - centre) ** 2))
        lamps.append((pos, rng.uniform(0.5, 1.1) * d2 * warm))
    return props, ambient, key, fills, lamps


def sample_styled_view(obj: ArticulatedObject, style: str, rng: np.random.Generator) -> StyledView:
    """Draw one view of ``obj`` at rest in ``style`` (camera, lights, scenery)."""
    if style not in STYLE_CONFIGS:
        raise ValueError(f"unknown style {style!r}; styles: {', '.join(STYLES)}")
    qpos = rest_qpos(obj)
    pts, lo, hi, size, target, eye, fovy, az, el = _camera(obj, qpos, rng, STYLE_CONFIGS[style])
    if style == "product":
        props, ambient, key, fills, lamps = _product_scene(rng, pts, lo, hi, size, az)
    else:
        props, ambient, key, fills, lamps = _room_scene(
            rng, obj, pts, lo, hi, size, az, eye, target, fovy
        )
    return StyledView(style, qpos, eye, target, fovy, az, el, ambient, key, fills, lamps, props)


# --------------------------------------------------------------------------- rendering


def _prop_shape(prop: Prop) -> sapien.render.RenderShape:
    colour = np.r_[_srgb_to_linear(prop.colour), 1.0].astype(np.float32)
    material = sapien.render.RenderMaterial(
        base_color=colour.tolist(),
        roughness=float(prop.roughness),
        metallic=0.0,
        specular=float(prop.specular),
    )
    if prop.shape == "mesh":
        v, n, uv = prop.mesh
        img = np.asarray(prop.texture, np.uint8)
        if img.shape[-1] == 3:
            img = np.concatenate([img, np.full(img.shape[:2] + (1,), 255, np.uint8)], axis=-1)
        material.base_color = [1.0, 1.0, 1.0, 1.0]
        texture = sapien.render.RenderTexture2D(
            np.ascontiguousarray(img), "R8G8B8A8Unorm", 1, "linear", prop.address, True
        )
        material.base_color_texture = texture
        if prop.emission > 0:
            material.emission = [prop.emission] * 3 + [1.0]
            material.emission_texture = texture
        tri = np.arange(len(v), dtype=np.uint32).reshape(-1, 3)
        return sapien.render.RenderShapeTriangleMesh(v, tri, n, uv, material)
    if prop.shape == "box":
        return sapien.render.RenderShapeBox(np.asarray(prop.size, np.float32), material)
    if prop.shape == "cylinder":
        shape = sapien.render.RenderShapeCylinder(
            float(prop.size[0]), float(prop.size[1]), material
        )
        shape.set_local_pose(sapien.Pose([0, 0, 0], [0.7071068, 0.0, -0.7071068, 0.0]))  # x -> z
        return shape
    if prop.shape == "sphere":
        return sapien.render.RenderShapeSphere(float(prop.size[0]), material)
    raise ValueError(f"unknown prop shape {prop.shape!r}")


def _block_mode(a: np.ndarray, k: int) -> np.ndarray:
    """Most frequent value of each k x k block (ties: the larger value)."""
    if k == 1:
        return a
    h, w = a.shape[0] // k, a.shape[1] // k
    blocks = a[: h * k, : w * k].reshape(h, k, w, k).transpose(0, 2, 1, 3).reshape(h, w, k * k)
    counts = (blocks[..., :, None] == blocks[..., None, :]).sum(-1) * 256 + blocks
    return np.take_along_axis(blocks, counts.argmax(-1)[..., None], -1)[..., 0]


class StyledRenderer:
    """A SAPIEN scene holding one object; ``render(view)`` builds the view's scenery.

    The light rig is fixed (one shadow-casting directional key light, two directional
    fills, two point lamps; unused ones dark) so that lavapipe compiles the shaders once.
    ``rng`` draws the parts' material roughness / specularity (one draw per object).
    """

    def __init__(
        self,
        obj: ArticulatedObject,
        image_size: int,
        rng: np.random.Generator,
        supersample: int = 2,
    ):
        self.obj = obj
        self.image_size = image_size
        self.ss = int(supersample)
        self.scene = sapien.Scene([render_system()])
        slot_of = {id(p): k for k, p in enumerate(part_slots(obj))}
        self.entities: list[sapien.Entity] = []
        self.mask_of: dict[int, int] = {}
        for part in obj.parts:
            body = sapien.render.RenderBodyComponent()
            body.attach(render_shape(part, rng))
            entity = sapien.Entity()
            entity.set_name(part.name)
            entity.add_component(body)
            self.scene.add_entity(entity)
            self.entities.append(entity)
            self.mask_of[entity.per_scene_id] = slot_of[id(part)] + 1
        side = image_size * self.ss
        self.camera = sapien.render.RenderCameraComponent(side, side)
        cam_entity = sapien.Entity()
        cam_entity.set_name("camera")
        cam_entity.add_component(self.camera)
        self.scene.add_entity(cam_entity)
        self.key = self.scene.add_directional_light(
            [0, 0, -1], [0, 0, 0], shadow=True, shadow_map_size=2048
        )
        self.fills = [self.scene.add_directional_light([0, 0, -1], [0, 0, 0]) for _ in range(2)]
        self.lamps = [self.scene.add_point_light([0, 0, 2], [0, 0, 0]) for _ in range(2)]
        self.props: list[sapien.Entity] = []

    def _set_props(self, props: Sequence[Prop]) -> dict[int, int]:
        for e in self.props:
            self.scene.remove_entity(e)
        self.props = []
        label_of = {sid: LABELS.index("object") for sid in self.mask_of}
        for prop in props:
            body = sapien.render.RenderBodyComponent()
            body.attach(_prop_shape(prop))
            entity = sapien.Entity()
            entity.set_name(prop.label)
            entity.add_component(body)
            entity.set_pose(sapien.Pose(np.asarray(prop.pose, np.float32)))
            self.scene.add_entity(entity)
            self.props.append(entity)
            label_of[entity.per_scene_id] = LABELS.index(prop.label)
        return label_of

    def render(self, view: StyledView) -> StyledRender:
        for part, entity, q in zip(self.obj.parts, self.entities, view.qpos, strict=True):
            T = np.eye(4) if part.joint is None else part.joint.transform(float(q))
            entity.set_pose(sapien.Pose(T.astype(np.float32)))
        label_of = self._set_props(view.props)
        pts = posed_vertices(self.obj, view.qpos)
        centre = (pts.min(0) + pts.max(0)) / 2
        size = float(np.max(pts.max(0) - pts.min(0)))

        def aim(light, direction, colour, position=None) -> None:  # noqa: ANN001
            q = sapien.math.shortest_rotation([1, 0, 0], np.asarray(direction, np.float32))
            pos = centre if position is None else position
            light.set_entity_pose(sapien.Pose(np.asarray(pos, np.float32), q))
            light.set_color(np.asarray(colour, np.float32))

        self.scene.set_ambient_light(np.asarray(view.ambient, np.float32))
        self.key.shadow_half_size = 1.6 * size
        self.key.shadow_near = -4.0 * size
        self.key.shadow_far = 4.0 * size
        aim(self.key, *view.key)
        for k, light in enumerate(self.fills):
            aim(light, *(view.fills[k] if k < len(view.fills) else ([0, 0, -1], [0, 0, 0])))
        for k, lamp in enumerate(self.lamps):
            pos, colour = (
                view.lamps[k] if k < len(view.lamps) else (centre + [0, 0, 2 * size], np.zeros(3))
            )
            lamp.set_entity_pose(sapien.Pose(np.asarray(pos, np.float32)))
            lamp.set_color(np.asarray(colour, np.float32))

        cam2world = look_at(np.asarray(view.eye, float), np.asarray(view.target, float))
        dist = float(np.linalg.norm(view.eye - view.target))
        self.camera.set_near(max(1e-3, 0.02 * dist))
        self.camera.set_far(200.0 * max(size, dist))
        sapien_pose = cam2world.copy()  # SAPIEN cameras: x forward, y left, z up
        sapien_pose[:3, :3] = cam2world[:3, :3] @ np.array(
            [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]
        )
        self.camera.entity.set_pose(sapien.Pose(sapien_pose.astype(np.float32)))
        self.camera.set_fovy(view.fovy, compute_x=True)
        self.scene.update_render()
        self.camera.take_picture()
        colour = np.clip(self.camera.get_picture("Color")[..., :3], 0.0, 1.0)
        seg = self.camera.get_picture("Segmentation")[..., 1].astype(np.int64)
        n = max(max(label_of), max(self.mask_of)) + 1
        mask_lut, label_lut = np.zeros(n, np.uint8), np.zeros(n, np.uint8)
        for sid, v in self.mask_of.items():
            mask_lut[sid] = v
        for sid, v in label_of.items():
            label_lut[sid] = v
        inside = (seg >= 0) & (seg < n)
        ids = np.where(inside, seg, 0)
        mask = np.where(inside, mask_lut[ids], 0).astype(np.uint8)
        labels = np.where(inside, label_lut[ids], 0).astype(np.uint8)
        k = self.ss
        if k > 1:
            s = self.image_size
            colour = colour[: s * k, : s * k].reshape(s, k, s, k, 3).mean((1, 3))
            mask, labels = _block_mode(mask, k), _block_mode(labels, k)
        rgb = np.clip(np.round(colour * 255.0), 0, 255).astype(np.uint8)
        K = np.asarray(self.camera.get_intrinsic_matrix(), np.float64)
        K[:2] /= k
        E = np.eye(4)
        E[:3, :3] = cam2world[:3, :3].T
        E[:3, 3] = -cam2world[:3, :3].T @ cam2world[:3, 3]
        return StyledRender(rgb, mask, K.astype(np.float32), E.astype(np.float32), labels)

    def close(self) -> None:
        for entity in list(self.scene.entities):
            self.scene.remove_entity(entity)
        self.scene = None  # type: ignore[assignment]

    def __enter__(self) -> StyledRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --------------------------------------------------------------------------- the split


@dataclass
class SplitSource:
    """One object of the split: its id, how to load it, and where it came from."""

    id: str
    load: Callable[[], ArticulatedObject]
    source: dict[str, Any] = field(default_factory=dict)


def image_id(object_id: str, style: str, k: int) -> str:
    return f"{object_id}_{style}_{k}"


def view_rng(seed: int, object_id: str, style: str, k: int) -> np.random.Generator:
    """The random stream of view ``k`` of ``style`` of an object (independent of the others)."""
    return np.random.default_rng([seed, zlib.crc32(object_id.encode()), STYLES.index(style) + 1, k])


def object_rng(seed: int, object_id: str) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(object_id.encode())])


def _png(arr: np.ndarray) -> bytes:
    buf = BytesIO()
    Image.fromarray(arr).save(buf, format="PNG")
    return buf.getvalue()


def render_object_views(
    obj: ArticulatedObject,
    object_id: str,
    *,
    styles: Sequence[str] = STYLES,
    views: int = 2,
    image_size: int = 256,
    seed: int = 0,
    supersample: int = 2,
) -> list[tuple[str, str, int, StyledView, StyledRender]]:
    """Every view of one object: (image id, style, k, view, render)."""
    out = []
    with StyledRenderer(obj, image_size, object_rng(seed, object_id), supersample) as renderer:
        for style in styles:
            for k in range(views):
                view = sample_styled_view(obj, style, view_rng(seed, object_id, style, k))
                out.append((image_id(object_id, style, k), style, k, view, renderer.render(view)))
    return out


def read_manifest(path: str | Path) -> dict[str, Any] | None:
    """The manifest of a real split folder (None when ``path`` holds none)."""
    f = Path(path) / "manifest.json"
    if not f.is_file():
        return None
    d = json.loads(f.read_text())
    return d if d.get("schema") == SCHEMA else None


def is_real_split(path: str | Path) -> bool:
    d = read_manifest(path)
    return bool(d and d.get("images"))


def write_real_split(
    out: str | Path,
    sources: Iterable[SplitSource],
    *,
    styles: Sequence[str] = STYLES,
    views: int = 2,
    image_size: int = 256,
    seed: int = 0,
    supersample: int = 2,
) -> dict[str, Any]:
    """Render every source in ``styles`` x ``views`` and write the split; returns the manifest.

    Resumable: an object already in the folder's manifest whose files exist is kept as
    it is; the manifest is rewritten atomically after every object. A folder written
    with other settings is refused (ValueError). A source whose ``load`` raises is
    listed under ``failed`` with the reason (and tried again on the next run).
    """
    for s in styles:
        if s not in STYLES:
            raise ValueError(f"unknown style {s!r}; styles: {', '.join(STYLES)}")
    out = Path(out)
    settings = {
        "seed": int(seed),
        "image_size": int(image_size),
        "styles": list(styles),
        "views": int(views),
        "supersample": int(supersample),
    }
    old = read_manifest(out)
    if old is not None and {k: old.get(k) for k in settings} != settings:
        raise ValueError(
            f"{out} holds a real split written with { ({k: old.get(k) for k in settings}) }, not {settings}"
        )
    done = {o["id"]: o for o in (old or {}).get("objects", [])}
    old_images = {im["id"]: im for im in (old or {}).get("images", [])}
    manifest: dict[str, Any] = {
        "schema": SCHEMA,
        "version": VERSION,
        **settings,
        "labels": "mask: 0 background (scenery included), 1 base, 2.. the other parts in ArticulatedObject.parts order",
        "camera": "extrinsics: world (the object's frame, normalized for imported objects) -> camera, OpenCV axes; intrinsics: pinhole K in pixels",
        "objects": [],
        "images": [],
        "failed": [],
    }

    def flush() -> None:
        atomic_write_bytes(out / "manifest.json", json.dumps(manifest, indent=1).encode())

    for src in sources:
        entry = done.get(src.id)
        if (
            entry is not None
            and all(
                (out / "images" / f"{iid}{ext}").is_file()
                for iid in entry["images"]
                for ext in (".png", ".mask.png", ".json")
            )
            and (out / "gt" / src.id / "object.json").is_file()
        ):
            manifest["objects"].append(entry)
            manifest["images"].extend(old_images[i] for i in entry["images"] if i in old_images)
            continue
        t0 = time.perf_counter()
        try:
            obj = src.load()
        except Exception as e:  # noqa: BLE001 - one bad object never stops the split
            manifest["failed"].append(
                {"id": src.id, "reason": f"{type(e).__name__}: {e}", "source": src.source}
            )
            log.warning("%s: not in the split: %s", src.id, e)
            flush()
            continue
        rendered = render_object_views(
            obj,
            src.id,
            styles=styles,
            views=views,
            image_size=image_size,
            seed=seed,
            supersample=supersample,
        )
        hints = json.dumps({"category": obj.category}).encode()
        images = []
        for iid, style, k, view, rv in rendered:
            atomic_write_bytes(out / "images" / f"{iid}.png", _png(rv.rgb))
            atomic_write_bytes(out / "images" / f"{iid}.mask.png", _png(rv.mask))
            atomic_write_bytes(out / "images" / f"{iid}.json", hints)
            images.append(
                {
                    "id": iid,
                    "object": src.id,
                    "category": obj.category,
                    "style": style,
                    "view": k,
                    "intrinsics": np.round(rv.intrinsics.astype(float), 5).tolist(),
                    "extrinsics": np.round(rv.extrinsics.astype(float), 6).tolist(),
                    "fovy_deg": round(math.degrees(view.fovy), 3),
                    "azimuth_deg": round(view.azimuth, 3),
                    "elevation_deg": round(view.elevation, 3),
                    "eye": np.round(view.eye, 5).tolist(),
                    "target": np.round(view.target, 5).tolist(),
                    "mask_ids": sorted(int(i) for i in np.unique(rv.mask) if i),
                    "object_pixels": int((rv.mask > 0).sum()),
                }
            )
        save_bundle(obj, out / "gt" / src.id)
        manifest["objects"].append(
            {
                "id": src.id,
                "category": obj.category,
                "parts": len(obj.parts),
                "movable": len(obj.movable_parts),
                "images": [im["id"] for im in images],
                "source": src.source,
                "seconds": round(time.perf_counter() - t0, 2),
            }
        )
        manifest["images"].extend(images)
        flush()
        log.info("%s: %d images in %.1f s", src.id, len(images), time.perf_counter() - t0)
    flush()
    return manifest
