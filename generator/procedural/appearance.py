"""Part appearance: per-part vertex colours or a small procedural texture.

A ``Look`` is a body colour, an accent colour (handles, knobs, burners) and an
optional texture kind: ``"wood"`` (grain stripes) or ``"brushed"`` (fine metal
streaks). Textured parts get a 64x64 PIL image whose left 56 columns hold the
pattern and whose right 8 columns hold the accent colour; UVs come from a planar
projection: ``u`` runs across the grain (sum of the two coordinates other than
the grain axis), ``v`` along it. Accent vertices map into the accent strip.
Untextured parts get RGBA vertex colours. UVs are quantized to 1/1024 so they
round-trip through glTF exactly.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh
from PIL import Image

from generator.articulated import Primitive
from generator.procedural.solids import inside_primitive

TEXTURE_SIZE = 64
PATTERN_COLUMNS = 56  # image columns 0..55 hold the pattern, 56..63 the accent colour
_U_PATTERN_MAX = (PATTERN_COLUMNS - 1) / TEXTURE_SIZE
_U_ACCENT = (PATTERN_COLUMNS + 4) / TEXTURE_SIZE

RGB = tuple[int, int, int]

WOOD_COLORS: tuple[RGB, ...] = (
    (196, 154, 108),  # oak
    (222, 190, 140),  # birch
    (150, 100, 60),  # walnut light
    (105, 68, 42),  # walnut
    (178, 120, 80),  # cherry
    (230, 214, 180),  # maple
)
PAINT_COLORS: tuple[RGB, ...] = (
    (240, 240, 235),  # white
    (200, 200, 196),  # light grey
    (90, 94, 98),  # anthracite
    (52, 66, 96),  # navy
    (150, 170, 140),  # sage
    (30, 30, 32),  # black
    (214, 200, 176),  # sand
)
APPLIANCE_COLORS: tuple[RGB, ...] = (
    (245, 245, 243),  # white
    (200, 202, 204),  # stainless
    (168, 172, 176),  # silver
    (40, 40, 42),  # black
    (110, 112, 116),  # graphite
)
ACCENT_COLORS: tuple[RGB, ...] = (
    (190, 192, 195),  # brushed steel
    (35, 35, 35),  # black
    (176, 140, 72),  # brass
    (150, 150, 150),  # aluminium
)


@dataclass(frozen=True)
class Look:
    """How a part is coloured. Colours are RGB 0-255; ``texture`` is None, "wood" or
    "brushed"; ``grain_axis`` (0, 1, 2) is the object axis the grain runs along;
    ``pattern_seed`` seeds the texture noise."""

    color: RGB
    accent: RGB
    texture: str | None = None
    grain_axis: int = 2
    pattern_seed: int = 0

    def with_grain(self, axis: int) -> Look:
        return Look(self.color, self.accent, self.texture, axis, self.pattern_seed)


def jitter(color: RGB, rng: np.random.Generator, amount: int = 6) -> RGB:
    """``color`` with each channel moved by up to ``amount`` (a per-part variation)."""
    c = np.clip(np.asarray(color) + rng.integers(-amount, amount + 1, size=3), 0, 255)
    return (int(c[0]), int(c[1]), int(c[2]))


def pattern_image(look: Look) -> Image.Image:
    """The 64x64 RGB texture of ``look``: pattern columns, then the accent strip."""
    rng = np.random.default_rng(look.pattern_seed)
    rows = np.arange(TEXTURE_SIZE)[:, None] / TEXTURE_SIZE  # (64, 1) along the grain
    cols = np.arange(PATTERN_COLUMNS)[None, :] / PATTERN_COLUMNS  # (1, 56) across it
    if look.texture == "wood":
        freq = rng.uniform(6.0, 12.0)
        wave = 0.03 * np.sin(2 * np.pi * (rows * rng.uniform(1.0, 2.5) + rng.uniform()))
        phase = 2 * np.pi * freq * (cols + wave) + 0.8 * np.sin(2 * np.pi * 3.0 * cols)
        shade = 0.86 + 0.10 * np.sin(phase) + 0.04 * rng.standard_normal((1, PATTERN_COLUMNS))
    else:  # brushed metal: fine streaks along the grain
        shade = 0.92 + 0.05 * rng.standard_normal((1, PATTERN_COLUMNS))
        shade = shade + 0.02 * rng.standard_normal((TEXTURE_SIZE, 1))
    shade = np.broadcast_to(shade, (TEXTURE_SIZE, PATTERN_COLUMNS))
    img = np.empty((TEXTURE_SIZE, TEXTURE_SIZE, 3), dtype=np.float64)
    img[:, :PATTERN_COLUMNS] = shade[..., None] * np.asarray(look.color, dtype=float)
    img[:, PATTERN_COLUMNS:] = np.asarray(look.accent, dtype=float)
    return Image.fromarray(np.clip(img, 0, 255).astype(np.uint8), mode="RGB")


def accent_vertices(
    vertices: np.ndarray, primitives: Sequence[Primitive], accent: Sequence[bool]
) -> np.ndarray:
    """(N,) bool: vertices on an accent primitive and not on any body primitive.

    Vertices where an accent solid meets the body stay body-coloured, so that big
    body faces never blend toward the accent colour.
    """
    on_accent = np.zeros(len(vertices), dtype=bool)
    on_body = np.zeros(len(vertices), dtype=bool)
    for prim, is_accent in zip(primitives, accent, strict=True):
        hit = inside_primitive(vertices, prim, tol=2e-5)
        if is_accent:
            on_accent |= hit
        else:
            on_body |= hit
    return on_accent & ~on_body


def paint(
    mesh: trimesh.Trimesh, primitives: Sequence[Primitive], accent: Sequence[bool], look: Look
) -> None:
    """Set ``mesh.visual`` in place: vertex colours, or a texture with planar UVs."""
    is_accent = accent_vertices(mesh.vertices, primitives, accent)
    if look.texture is None:
        colors = np.empty((len(mesh.vertices), 4), dtype=np.uint8)
        colors[:, :3] = np.where(is_accent[:, None], look.accent, look.color)
        colors[:, 3] = 255
        mesh.visual = trimesh.visual.ColorVisuals(mesh=mesh, vertex_colors=colors)
        return
    v = mesh.vertices
    across = [a for a in range(3) if a != look.grain_axis]
    s = v[:, across[0]] + v[:, across[1]]
    g = v[:, look.grain_axis]
    u = (s - s.min()) / max(float(np.ptp(s)), 1e-9) * _U_PATTERN_MAX
    w = (g - g.min()) / max(float(np.ptp(g)), 1e-9)
    uv = np.stack([np.where(is_accent, _U_ACCENT, u), np.where(is_accent, 0.5, w)], axis=1)
    uv = np.round(uv * 1024.0) / 1024.0
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, image=pattern_image(look))
