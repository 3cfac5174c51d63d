"""Training data of the photo parser: realistic procedural objects rendered like photos.

``write_parser_data(out, n_objects, views, seed)`` renders ``views`` photos of each of
``n_objects`` objects of ``generator.procedural.realistic`` and writes (docs/dataset.md,
"Parser training data")::

    out/manifest.json            schema "pact.parser_data", version 1, seed, image_size,
                                 categories, motions, items (one per image), failed
    out/images/<id>.png          RGB photo, image_size x image_size
    out/images/<id>.mask.png     8-bit mask: 0 not the object, 1 base, 2..K the movable
                                 parts visible in the view, consecutive
    out/images/<id>.json         {"category": ..., "parts": {"2": {"motion": ...}, ..}}

``write_parser_data_from_bundles(out, bundles, views, seed)`` writes the same photos of
objects that exist as bundles (imported PartNet-Mobility objects, for the parser's
``partnet`` variant); both go through ``write_object_views``, the format's one writer.

Objects: object ``i`` has the category of slot ``i % 100`` of block ``i // 100``, a
deterministic shuffle of ``CATEGORY_SHARES`` (per hundred objects), and is
``sample_realistic_object(category, seed * 1_000_000 + i)``; about 5 % of the objects
(``VAL_SHARE``, drawn per object) are "val", the rest "train". Image ids are
``<object id>_<k>``.

Views (``sample_parser_view``): a style ("room" 50 %, "product" 40 %, "plain" 10 %); a
camera within +-60 degrees of the front and 0-35 degrees above the horizon, at the
height of a person's eye (1.75 m) down to a low camera (0.3 m), with a field of view
of a phone or a product lens, the object filling 45-92 % of the half-frame and, in 40 %
of the views, shifted off the centre; 15 % of the views open one or two movable parts
to 25-100 % of their range. The scenery is ``real_split``'s product sweep or room (floor,
walls, skirting, pictures, clutter, a counter under small objects), here with more floor
materials (tinted planks and tiles, carpet, concrete), more walls (stripes, brick,
subway tiles, panelling, stronger paints), tinted studio backdrops and more lighting
(exposure, colour temperature, daylight or lamplight); "plain" views show the object in
front of a random flat or patterned background. The rendered RGB then goes through photo
degradations (``degrade``): colour jitter, vignetting, blur or motion blur, noise,
resampling and JPEG compression. Masks are the renderer's segmentation, block-mode
downsampled (exact, no anti-aliasing); a movable part showing fewer than
``MIN_PART_PIXELS`` pixels counts as hidden and its pixels are given to the base.

Deterministic: every object draws from a stream keyed by (seed, object id), every view
from one keyed by (seed, object id, view index). Resumable: an object whose images are
all in the manifest and on disk is kept; files are written atomically and the manifest
is rewritten (atomically) as objects are added, so an interrupted run resumes; a folder
written with another seed or image size is refused (``ParserDataError``).
"""

from __future__ import annotations

import json
import logging
import math
import time
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageFilter

from generator.articulated import ArticulatedObject
from generator.atomic_files import atomic_write_bytes
from generator.data.backgrounds import random_background
from generator.data.real_split import (
    LABELS,
    PAINTS,
    Prop,
    StyledRenderer,
    StyledView,
    _direction,
    _product_scene,
    _room_scene,
    _u8,
    periodic_noise,
)
from generator.data.render import fit_distance, look_at, posed_vertices, rest_qpos
from generator.motions import MOTIONS, motion_of
from generator.procedural.realistic import (
    REALISTIC_CATEGORIES,
    realistic_object_id,
    sample_realistic_object,
)

log = logging.getLogger(__name__)

SCHEMA = "pact.parser_data"
VERSION = 1
CATEGORIES: tuple[str, ...] = REALISTIC_CATEGORIES
#: Objects per hundred of each category (cabinets and desks, the commonest real
#: categories, 40 %; "other" 4 %).
CATEGORY_SHARES = {
    "cabinet": 20,
    "desk": 20,
    "microwave": 11,
    "oven": 12,
    "dishwasher": 10,
    "refrigerator": 12,
    "washing_machine": 11,
    "other": 4,
}
STYLE_SHARES = {"room": 0.5, "product": 0.4, "plain": 0.1}
VAL_SHARE = 0.05
OPEN_SHARE = 0.15
MIN_PART_PIXELS = 8
SUPERSAMPLE = 2


class ParserDataError(ValueError):
    """A parser data folder that cannot be written or resumed; the message says why."""


# --------------------------------------------------------------------------- objects


@dataclass(frozen=True)
class PlannedObject:
    index: int
    category: str
    seed: int
    split: str  # "train" or "val"

    @property
    def id(self) -> str:
        return realistic_object_id(self.category, self.seed)


def plan_object(seed: int, index: int) -> PlannedObject:
    """Object ``index`` of a dataset of ``seed``: category, object seed, split."""
    block, slot = divmod(index, 100)
    order = [c for c, n in CATEGORY_SHARES.items() for _ in range(n)]
    perm = np.random.default_rng([seed, block, 17]).permutation(len(order))
    category = order[int(perm[slot])]
    val = np.random.default_rng([seed, index, 23]).random() < VAL_SHARE
    return PlannedObject(index, category, int(seed) * 1_000_000 + index, "val" if val else "train")


def _stream(*keys: int | str) -> np.random.Generator:
    return np.random.default_rng(
        [k if isinstance(k, int) else zlib.crc32(k.encode()) for k in keys]
    )


# --------------------------------------------------------------------------- scenery


def _floor_texture(rng: np.random.Generator, px: int, period_m: float) -> np.ndarray:
    """(px, px, 3) uint8: carpet or concrete, tiling over ``period_m`` metres."""
    if rng.random() < 0.5:  # carpet: fine fibres and a faint blotch
        colour = np.array(
            [(0.55, 0.53, 0.5), (0.42, 0.4, 0.38), (0.7, 0.66, 0.58), (0.36, 0.4, 0.46)][
                int(rng.integers(4))
            ]
        ) * rng.uniform(0.85, 1.15)
        fine = periodic_noise(rng, (px, px), (px / 3.0, px / 3.0))
        blot = periodic_noise(rng, (px, px), (3.0, 3.0))
        img = colour[None, None] * (1 + 0.06 * fine + 0.04 * blot)[..., None]
    else:  # concrete / screed
        grey = rng.uniform(0.45, 0.75)
        colour = grey * np.array([1.0, 0.99, 0.96])
        img = (
            colour[None, None]
            * (
                1
                + 0.05 * periodic_noise(rng, (px, px), (6.0, 6.0))
                + 0.03 * periodic_noise(rng, (px, px), (px / 4.0, px / 4.0))
            )[..., None]
        )
    return _u8(img)


def _wall_texture(rng: np.random.Generator, px: int) -> np.ndarray:
    """(px, px, 3) uint8 over one metre: striped wallpaper, brick, subway tiles, panelling
    or a strong paint."""
    kind = ["stripes", "brick", "subway", "panelling", "paint"][int(rng.integers(5))]
    paint = np.array(PAINTS[int(rng.integers(len(PAINTS)))]) * rng.uniform(0.8, 1.02)
    y, x = np.mgrid[0:px, 0:px] / px  # metres over the one-metre tile (rows = down)
    if kind == "stripes":
        other = paint * rng.uniform(0.82, 0.95)
        n = int(rng.integers(6, 16))
        sel = (np.floor(x * n) % 2 == 0)[..., None]
        img = np.where(sel, paint, other)
    elif kind in ("brick", "subway"):
        if kind == "brick":
            rows, cols = 14, 4
            colour = np.array([0.62, 0.34, 0.26]) * rng.uniform(0.8, 1.15)
            mortar = np.array([0.75, 0.72, 0.66])
        else:
            rows, cols = 12, 6
            colour = np.array([0.93, 0.93, 0.91]) * rng.uniform(0.9, 1.02)
            mortar = np.array([0.7, 0.7, 0.68])
        r = np.floor(y * rows)
        shifted = x + 0.5 * (r % 2) / cols
        c = np.floor(shifted * cols)
        tint = 1 + (0.08 if kind == "brick" else 0.02) * rng.standard_normal((rows, cols + 1))
        img = colour[None, None] * tint[r.astype(int) % rows, c.astype(int) % (cols + 1)][..., None]
        line = (np.abs(y * rows - np.round(y * rows)) < 0.06) | (
            np.abs(shifted * cols - np.round(shifted * cols)) < 0.02 * cols / 4
        )
        img[line] = mortar
    elif kind == "panelling":
        colour = paint if rng.random() < 0.6 else np.array([0.6, 0.45, 0.3])
        n = int(rng.integers(5, 10))
        img = np.broadcast_to(colour, (px, px, 3)).copy()
        img[(np.abs(x * n - np.round(x * n)) < 0.03)] *= 0.7
    else:
        strong = np.array(
            [(0.35, 0.45, 0.55), (0.55, 0.3, 0.25), (0.3, 0.42, 0.32), (0.85, 0.7, 0.35)][
                int(rng.integers(4))
            ]
        )
        img = np.broadcast_to(strong * rng.uniform(0.85, 1.1), (px, px, 3)).copy()
    img = img * (1 + 0.012 * periodic_noise(rng, (px, px), (6.0, 6.0)))[..., None]
    return _u8(img)


def _retexture(props: list[Prop], label: str, make: Callable[[int], np.ndarray]) -> None:
    """Replace the repeating texture of every ``label`` mesh prop with ``make(px)`` and
    redo the contact-shadow patch cut from it (a prop addressed "edge" whose texture is
    the old texture times a shade)."""
    tiles = [p for p in props if p.label == label and p.shape == "mesh" and p.address == "repeat"]
    if not tiles:
        return
    old = np.asarray(tiles[0].texture, float)
    px = old.shape[0]
    new = make(px).astype(float)
    for p in tiles:
        p.texture = _u8(new / 255.0)
    for p in props:
        if p.label != label or p.shape != "mesh" or p.address != "edge" or p.texture is None:
            continue
        tex = np.asarray(p.texture, float)
        if tex.shape[0] % px or tex.shape[0] < px:
            continue
        # the patch is a texel-aligned window onto the tiling texture: find it
        v, _, uv = p.mesh
        origin = v.min(0)[:2]
        side = float(np.ptp(v[:, 0]))
        period = side / (tex.shape[0] // px)
        start = np.round(origin / period * px).astype(int)
        n = tex.shape[0]
        rows, cols = (start[1] + np.arange(n)) % px, (start[0] + np.arange(n)) % px
        shade = tex / np.maximum(old[rows][:, cols], 1.0)
        p.texture = _u8(np.clip(new[rows][:, cols] * shade, 0, 255) / 255.0)


def _tint_props(props: list[Prop], label: str, factor: np.ndarray) -> None:
    for p in props:
        if p.label == label and p.texture is not None:
            p.texture = _u8(np.asarray(p.texture, float) * factor / 255.0)
        elif p.label == label:
            p.colour = np.clip(np.asarray(p.colour) * factor, 0, 1)


def _restyle_room(props: list[Prop], rng: np.random.Generator) -> None:
    """More floors and walls than ``real_split``'s room: tinted planks and tiles, carpet,
    concrete; stripes, brick, subway tiles, panelling, strong paints."""
    r = rng.random()
    if r < 0.3:
        _retexture(props, "floor", lambda px: _floor_texture(rng, px, 2.4))
    elif r < 0.6:  # darker, greyer or warmer planks / tiles
        factor = rng.uniform(0.55, 1.1) * rng.uniform(0.9, 1.1, 3)
        _tint_props(props, "floor", factor)
    if rng.random() < 0.45:
        _retexture(props, "wall", lambda px: _wall_texture(rng, 256))


def _restyle_product(props: list[Prop], rng: np.random.Generator) -> None:
    """Studio backdrops other than near-white: light greys, warm and cool tints."""
    r = rng.random()
    if r < 0.25:
        _tint_props(props, "floor", np.full(3, rng.uniform(0.72, 0.92)))
    elif r < 0.4:
        _tint_props(props, "floor", rng.uniform(0.8, 1.0, 3))


def _relight(view: StyledView, rng: np.random.Generator) -> None:
    """Exposure, colour temperature and, in rooms, daylight or lamplight."""
    exposure = rng.uniform(0.75, 1.25)
    temp = rng.uniform(-1.0, 1.0)
    wb = np.array([1 + 0.1 * temp, 1.0, 1 - 0.1 * temp])
    if view.style == "room" and rng.random() < 0.3:  # daylight from a window
        direction, colour = view.key
        view.key = (direction, colour * rng.uniform(1.3, 1.7) * np.array([0.95, 1.0, 1.08]))
        view.lamps = [(p, c * 0.4) for p, c in view.lamps]
    view.ambient = np.asarray(view.ambient) * exposure * wb
    view.key = (view.key[0], np.asarray(view.key[1]) * exposure * wb)
    view.fills = [(d, np.asarray(c) * exposure * wb) for d, c in view.fills]
    view.lamps = [(p, np.asarray(c) * exposure * wb) for p, c in view.lamps]


# --------------------------------------------------------------------------- views


@dataclass
class ParserView:
    """One view: the styled scene (``view.style`` "product", "room" or "plain") and
    what happens to the picture after rendering."""

    view: StyledView
    background: np.ndarray | None  # plain style: (H, W, 3) uint8
    photo: dict[str, Any]  # degradation parameters (``degrade``)


def _open_qpos(obj: ArticulatedObject, rng: np.random.Generator) -> np.ndarray:
    q = rest_qpos(obj)
    movable = [i for i, p in enumerate(obj.parts) if p.joint is not None and p.joint.movable]
    if not movable or rng.random() >= OPEN_SHARE:
        return q
    k = 1 if rng.random() < 0.7 or len(movable) == 1 else 2
    for i in rng.choice(movable, size=k, replace=False):
        j = obj.parts[int(i)].joint
        q[int(i)] = j.lower + rng.uniform(0.25, 1.0) * j.range
    return q


_CAMERA = {  # fovy (deg), fill of the half-frame
    "product": ((28.0, 50.0), (0.62, 0.92)),
    "room": ((42.0, 65.0), (0.45, 0.85)),
    "plain": ((30.0, 60.0), (0.55, 0.92)),
}


def _camera(
    pts: np.ndarray, style: str, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """(eye, target, fovy rad, azimuth deg, elevation deg) of a photo of the posed points
    ``pts`` (metres): azimuth within +-60 degrees (mostly 10-55 off the front), the
    camera at 0.3-1.75 m (elevation kept within 0-35 degrees), off-centre sometimes."""
    lo, hi = pts.min(0), pts.max(0)
    size = float(np.max(hi - lo))
    target = (lo + hi) / 2 + rng.uniform(-1, 1, 3) * 0.02 * size
    if rng.random() < 0.7:
        az = float(rng.uniform(10.0, 55.0) * rng.choice([-1.0, 1.0]))
    else:
        az = float(rng.uniform(-60.0, 60.0))
    fov_range, fill_range = _CAMERA[style]
    fovy = math.radians(rng.uniform(*fov_range))
    tan_half = math.tan(fovy / 2) * rng.uniform(*fill_range)
    eye_h = rng.uniform(0.3, 1.75)
    el = math.radians(15.0)
    for _ in range(2):  # elevation from the eye height at the fitted distance
        back = np.array(
            [
                math.cos(el) * math.cos(math.radians(az)),
                math.cos(el) * math.sin(math.radians(az)),
                math.sin(el),
            ]
        )
        dist = fit_distance(pts, target, back, tan_half)
        rise = eye_h - target[2]
        el = float(np.clip(math.atan2(rise, dist * math.cos(el)), 0.0, math.radians(35.0)))
    back = np.array(
        [
            math.cos(el) * math.cos(math.radians(az)),
            math.cos(el) * math.sin(math.radians(az)),
            math.sin(el),
        ]
    )
    dist = fit_distance(pts, target, back, tan_half)
    eye = target + back * dist
    if rng.random() < 0.4:  # off-centre: shift the frame, the object stays inside it
        fill = tan_half / math.tan(fovy / 2)
        T = look_at(eye, target)
        shift = rng.uniform(-1, 1, 2) * (1 - fill) * 0.9 * dist * math.tan(fovy / 2)
        move = T[:3, 0] * shift[0] + T[:3, 1] * shift[1]
        eye, target = eye + move, target + move
    return eye, target, fovy, az, math.degrees(el)


def sample_parser_view(
    obj: ArticulatedObject, rng: np.random.Generator, image_size: int
) -> ParserView:
    """Draw one photo of ``obj``: style, pose, camera, scenery, light, degradations."""
    style = str(rng.choice(list(STYLE_SHARES), p=list(STYLE_SHARES.values())))
    qpos = _open_qpos(obj, rng)
    pts = posed_vertices(obj, qpos)
    lo, hi = pts.min(0), pts.max(0)
    size = float(np.max(hi - lo))
    eye, target, fovy, az, el = _camera(pts, style, rng)
    background = None
    if style == "room":
        props, ambient, key, fills, lamps = _room_scene(
            rng, obj, pts, lo, hi, size, az, eye, target, fovy
        )
        _restyle_room(props, rng)
    else:
        props, ambient, key, fills, lamps = _product_scene(rng, pts, lo, hi, size, az)
        if style == "product":
            _restyle_product(props, rng)
        else:
            props = []
            background = random_background(rng, image_size)
            key = (_direction(az + rng.uniform(-70, 70), rng.uniform(25, 75)), key[1])
    view = StyledView(style, qpos, eye, target, fovy, az, el, ambient, key, fills, lamps, props)
    _relight(view, rng)
    return ParserView(view, background, sample_degradation(rng))


# --------------------------------------------------------------------------- photos


def sample_degradation(rng: np.random.Generator) -> dict[str, Any]:
    """Parameters of ``degrade``: what a phone or a web photo does to a picture."""
    blur = rng.random()
    return {
        "brightness": float(rng.uniform(0.88, 1.12)),
        "contrast": float(rng.uniform(0.85, 1.15)),
        "saturation": float(rng.uniform(0.75, 1.2)),
        "white_balance": rng.uniform(0.95, 1.05, 3).tolist(),
        "gamma": float(rng.uniform(0.9, 1.1)),
        "vignette": float(rng.uniform(0.1, 0.35)) if rng.random() < 0.3 else 0.0,
        "blur_sigma": float(rng.uniform(0.3, 0.9)) if blur < 0.25 else 0.0,
        "motion_blur": (
            (int(rng.integers(2, 5)), float(rng.uniform(0, 180))) if 0.25 <= blur < 0.37 else None
        ),
        "resample": float(rng.uniform(0.5, 0.8)) if rng.random() < 0.15 else 1.0,
        "noise": float(rng.uniform(1.0, 5.0)) if rng.random() < 0.6 else 0.0,
        "noise_seed": int(rng.integers(2**31)),
        "jpeg": int(rng.integers(35, 93)) if rng.random() < 0.7 else 0,
    }


def _motion_kernel(length: int, angle_deg: float) -> np.ndarray:
    k = 2 * length + 1
    kernel = np.zeros((k, k))
    a = math.radians(angle_deg)
    for t in np.linspace(-length, length, 4 * k):
        kernel[int(round(length + t * math.sin(a))), int(round(length + t * math.cos(a)))] = 1.0
    return kernel / kernel.sum()


def degrade(rgb: np.ndarray, p: dict[str, Any]) -> np.ndarray:
    """(H, W, 3) uint8 ``rgb`` after the degradations ``p`` (``sample_degradation``)."""
    img = rgb.astype(np.float64) / 255.0
    h, w = img.shape[:2]
    img = img * p["brightness"] * np.asarray(p["white_balance"])
    mean = img.mean()
    img = (img - mean) * p["contrast"] + mean
    grey = img.mean(axis=2, keepdims=True)
    img = grey + (img - grey) * p["saturation"]
    img = np.clip(img, 0, 1) ** p["gamma"]
    if p["vignette"]:
        yy, xx = (np.mgrid[0:h, 0:w] + 0.5) / np.array([h, w])[:, None, None] - 0.5
        img = img * (1 - p["vignette"] * (xx**2 + yy**2) * 2)[..., None]
    out = Image.fromarray(_u8(img))
    if p["blur_sigma"]:
        out = out.filter(ImageFilter.GaussianBlur(p["blur_sigma"]))
    if p["motion_blur"]:
        from scipy.ndimage import convolve

        kernel = _motion_kernel(*p["motion_blur"])
        arr = np.asarray(out, float)
        arr = np.stack([convolve(arr[..., c], kernel, mode="nearest") for c in range(3)], -1)
        out = Image.fromarray(np.clip(np.round(arr), 0, 255).astype(np.uint8))
    if p["resample"] < 1.0:
        small = (max(8, round(w * p["resample"])), max(8, round(h * p["resample"])))
        out = out.resize(small, Image.BILINEAR).resize((w, h), Image.BILINEAR)
    arr = np.asarray(out, float)
    if p["noise"]:
        noise = np.random.default_rng(p["noise_seed"]).standard_normal(arr.shape)
        arr = arr + p["noise"] * noise * (0.6 + 0.4 * arr / 255.0)
    out = Image.fromarray(np.clip(np.round(arr), 0, 255).astype(np.uint8))
    if p["jpeg"]:
        buf = BytesIO()
        out.save(buf, format="JPEG", quality=p["jpeg"])
        out = Image.open(BytesIO(buf.getvalue())).convert("RGB")
    return np.asarray(out, np.uint8)


def visible_parts(
    obj: ArticulatedObject, mask: np.ndarray, min_pixels: int = MIN_PART_PIXELS
) -> tuple[np.ndarray, dict[str, dict[str, str]]]:
    """The renderer's mask (1 base, slot + 1 movable parts) renumbered to the visible
    parts: (mask with 2..K consecutive, ``{"2": {"motion": ...}, ..}``). A part with
    fewer than ``min_pixels`` pixels is hidden: its pixels become the base's."""
    movable = [p for p in obj.parts if not p.is_base]  # slot order
    counts = np.bincount(mask.ravel(), minlength=len(movable) + 2)
    lut = np.zeros(max(256, len(counts)), np.uint8)
    lut[1] = 1
    parts: dict[str, dict[str, str]] = {}
    next_id = 2
    for slot, part in enumerate(movable, start=1):
        if counts[slot + 1] >= min_pixels:
            lut[slot + 1] = next_id
            parts[str(next_id)] = {"motion": motion_of(part)}
            next_id += 1
        else:
            lut[slot + 1] = 1
    return lut[mask], parts


def render_parser_views(
    obj: ArticulatedObject, object_id: str, views: int, image_size: int, seed: int
) -> Iterator[tuple[int, ParserView, np.ndarray, np.ndarray, dict[str, Any]]]:
    """Every view of one object, rendered by one renderer: (k, view, rgb, mask, hints)."""
    with StyledRenderer(obj, image_size, _stream(seed, object_id), SUPERSAMPLE) as renderer:
        for k in range(views):
            pv = sample_parser_view(obj, _stream(seed, object_id, k), image_size)
            rv = renderer.render(pv.view)
            rgb = rv.rgb
            if pv.background is not None:
                rgb = np.where((rv.labels == LABELS.index("none"))[..., None], pv.background, rgb)
            rgb = degrade(rgb, pv.photo)
            mask, parts = visible_parts(obj, rv.mask)
            yield k, pv, rgb, mask, {"category": obj.category, "parts": parts}


# --------------------------------------------------------------------------- the folder


def _png(arr: np.ndarray) -> bytes:
    buf = BytesIO()
    Image.fromarray(arr).save(buf, format="PNG")
    return buf.getvalue()


def read_manifest(out: str | Path) -> dict[str, Any] | None:
    f = Path(out) / "manifest.json"
    if not f.is_file():
        return None
    d = json.loads(f.read_text())
    if d.get("schema") != SCHEMA:
        raise ParserDataError(
            f"{out}: manifest.json is not a parser data manifest ({d.get('schema')!r})"
        )
    return d


def write_parser_data(
    out: str | Path,
    n_objects: int,
    views: int = 4,
    seed: int = 0,
    image_size: int = 256,
    progress: Callable[[int, int], None] | None = None,
    flush_seconds: float = 5.0,
) -> dict[str, Any]:
    """Render objects ``0 .. n_objects - 1`` (``plan_object``) with ``views`` photos each
    into ``out``; returns the manifest. Resumable; refuses a folder of another seed or
    image size (ParserDataError). An object that cannot be built or rendered is listed
    under ``failed`` with the reason (and tried again by the next run).
    ``progress(done, total)`` is called after every object."""
    sources = []
    for i in range(n_objects):
        plan = plan_object(seed, i)
        sources.append(
            ObjectSource(
                plan.id,
                plan.category,
                plan.split,
                lambda plan=plan: sample_realistic_object(plan.category, plan.seed),
            )
        )
    return write_object_views(out, sources, views, seed, image_size, progress, flush_seconds)


def write_parser_data_from_bundles(
    out: str | Path,
    bundles: list[str | Path],
    views: int = 16,
    seed: int = 0,
    image_size: int = 256,
    progress: Callable[[int, int], None] | None = None,
    flush_seconds: float = 5.0,
) -> dict[str, Any]:
    """Parser data of built or imported objects (pact.object bundles, e.g. what
    ``pact import`` writes for PartNet-Mobility objects), rendered exactly as the
    procedural objects are. Object ids are the bundle folders' names, every object is
    "train" (measure on other objects), a category outside ``CATEGORIES`` is "other".
    Same format, resumability and refusals as :func:`write_parser_data`."""
    from generator.bundle import load_bundle

    sources = []
    for b in bundles:
        b = Path(b)
        if not (b / "object.json").is_file():
            raise ParserDataError(f"{b}: not an object bundle (no object.json)")
        cat = json.loads((b / "object.json").read_text()).get("category")
        sources.append(
            ObjectSource(
                b.name,
                cat if cat in CATEGORIES else "other",
                "train",
                lambda b=b: load_bundle(b),
            )
        )
    return write_object_views(out, sources, views, seed, image_size, progress, flush_seconds)


@dataclass(frozen=True)
class ObjectSource:
    """One object of a parser data folder: its id, category, split and how to build it."""

    id: str
    category: str
    split: str
    build: Callable[[], ArticulatedObject]


def write_object_views(
    out: str | Path,
    sources: list[ObjectSource],
    views: int,
    seed: int,
    image_size: int,
    progress: Callable[[int, int], None] | None = None,
    flush_seconds: float = 5.0,
) -> dict[str, Any]:
    """Render ``views`` photos of each object of ``sources`` into ``out`` (the writer
    of the format; :func:`write_parser_data` and :func:`write_parser_data_from_bundles`
    choose the objects)."""
    out = Path(out)
    old = read_manifest(out)
    if old is not None and (old.get("seed"), old.get("image_size")) != (seed, image_size):
        raise ParserDataError(
            f"{out}: holds parser data of seed {old.get('seed')} and image size "
            f"{old.get('image_size')}, not seed {seed} and image size {image_size}; "
            "use another folder"
        )
    old_items: dict[str, list[dict[str, Any]]] = {}
    for item in (old or {}).get("items", []):
        old_items.setdefault(item["object"], []).append(item)
    manifest: dict[str, Any] = {
        "schema": SCHEMA,
        "version": VERSION,
        "seed": int(seed),
        "image_size": int(image_size),
        "categories": list(CATEGORIES),
        "motions": list(MOTIONS),
        "items": [],
        "failed": [],
    }
    images = out / "images"

    def flush() -> None:
        atomic_write_bytes(out / "manifest.json", json.dumps(manifest, indent=0).encode())

    last_flush = time.monotonic()
    flush()
    for i, src in enumerate(sources):
        oid = src.id
        ids = [f"{oid}_{k}" for k in range(views)]
        kept = {it["id"]: it for it in old_items.get(oid, [])}
        if all(
            iid in kept
            and all((images / f"{iid}{ext}").is_file() for ext in (".png", ".mask.png", ".json"))
            for iid in ids
        ):
            manifest["items"].extend(kept[iid] for iid in ids)
        else:
            t0 = time.perf_counter()
            try:
                obj = src.build()
                for k, pv, rgb, mask, hints in render_parser_views(
                    obj, oid, views, image_size, seed
                ):
                    iid = ids[k]
                    hints["category"] = src.category
                    atomic_write_bytes(images / f"{iid}.png", _png(rgb))
                    atomic_write_bytes(images / f"{iid}.mask.png", _png(mask))
                    atomic_write_bytes(images / f"{iid}.json", json.dumps(hints).encode())
                    manifest["items"].append(
                        {
                            "id": iid,
                            "object": oid,
                            "category": src.category,
                            "style": pv.view.style,
                            "split": src.split,
                        }
                    )
            except Exception as e:  # noqa: BLE001 - one bad object never stops the data
                manifest["items"] = [it for it in manifest["items"] if it["object"] != oid]
                manifest["failed"].append({"object": oid, "reason": f"{type(e).__name__}: {e}"})
                log.warning("%s: left out: %s", oid, e)
            log.debug("%s: %d views in %.1f s", oid, views, time.perf_counter() - t0)
        if time.monotonic() - last_flush >= flush_seconds:
            flush()
            last_flush = time.monotonic()
        if progress is not None:
            progress(i + 1, len(sources))
    flush()
    return manifest
