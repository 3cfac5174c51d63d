"""Part appearance: per-part vertex colours or a small procedural texture.

A ``Look`` is a body colour, an accent colour (handles, knobs, burners), optional
further *tones* (a window's glass, a display, a countertop) and an optional texture
kind: ``"wood"`` (grain stripes) or ``"brushed"`` (fine metal streaks), or one of the
metric kinds of ``METRIC_TEXTURES`` (``"grain"``, ``"steel"``, ``"mottle"``), whose
features have real sizes (grain lines per metre) whatever the part's size.

Which colour a primitive takes is its *tone* (``PartSpec.accent``): 0 (or False) the
body colour, 1 (or True) the accent colour, 2, 3, .. ``Look.tones[0], [1], ..``.

Textured parts of the kinds "wood" and "brushed" get a 64x64 PIL image whose left 56
columns hold the pattern and whose right 8 columns hold the accent colour; the metric
kinds get a ``METRIC_TEXTURE_SIZE`` square image whose last 8-column strips hold the
accent colour and then each further tone. UVs come from a planar projection: ``u``
runs across the grain (sum of the two coordinates other than the grain axis), ``v``
along it. Vertices of another tone map into their tone's strip. Untextured parts get
RGBA vertex colours. UVs are quantized to 1/1024 so they round-trip through glTF
exactly.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import trimesh
from PIL import Image

from generator.articulated import Primitive
from generator.procedural.solids import inside_primitive

TEXTURE_SIZE = 64
PATTERN_COLUMNS = 56  # image columns 0..55 hold the pattern, 56..63 the accent colour
_U_PATTERN_MAX = (PATTERN_COLUMNS - 1) / TEXTURE_SIZE
_U_ACCENT = (PATTERN_COLUMNS + 4) / TEXTURE_SIZE
#: Texture kinds whose features have metric sizes (``pattern_image(look, extent)``).
METRIC_TEXTURES = ("grain", "steel", "mottle")
METRIC_TEXTURE_SIZE = 128
TONE_STRIP = 8  # image columns per tone strip of a metric texture

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
    """How a part is coloured. Colours are RGB 0-255; ``texture`` is None, "wood",
    "brushed" or one of ``METRIC_TEXTURES``; ``grain_axis`` (0, 1, 2) is the object axis
    the grain runs along; ``pattern_seed`` seeds the texture noise; ``tones`` are the
    colours of tones 2, 3, .. (the old kinds "wood" and "brushed" take none)."""

    color: RGB
    accent: RGB
    texture: str | None = None
    grain_axis: int = 2
    pattern_seed: int = 0
    tones: tuple[RGB, ...] = ()

    def with_grain(self, axis: int) -> Look:
        return replace(self, grain_axis=axis)

    def palette(self) -> np.ndarray:
        """(2 + len(tones), 3) the colour of every tone: body, accent, further tones."""
        return np.array([self.color, self.accent, *self.tones], dtype=np.uint8).reshape(-1, 3)


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


def _noise_1d(rng: np.random.Generator, n: int, cycles: float) -> np.ndarray:
    """(n,) smooth noise with about ``cycles`` features over its length, unit std."""
    white = rng.standard_normal(n)
    f = np.fft.rfftfreq(n) * n / max(cycles, 1e-3)
    out = np.fft.irfft(np.fft.rfft(white) * np.exp(-(f**2)), n)
    return (out - out.mean()) / (out.std() + 1e-12)


def metric_pattern(
    kind: str, rng: np.random.Generator, shape: tuple[int, int], extent: tuple[float, float]
) -> np.ndarray:
    """(rows, cols) shading factor around 1 of a metric texture over ``extent`` =
    (metres along the grain, metres across it); rows run along the grain.

    "grain": wood glued from boards 8-16 cm wide, each with its own tint and its own
    growth lines (25-70 per metre, sharp dark latewood lines, slowly wandering along the
    grain) and fibre streaks; "steel": brushed streaks along the grain and a faint
    large-scale sheen; "mottle": paint or enamel, a faint low-frequency unevenness.
    """
    rows, cols = shape
    along_m, across_m = max(extent[0], 1e-3), max(extent[1], 1e-3)
    y = (np.arange(rows)[:, None] + 0.5) / rows * along_m  # (rows, 1) metres along
    x = (np.arange(cols)[None, :] + 0.5) / cols * across_m  # (1, cols) metres across
    if kind == "grain":
        shade = np.ones((rows, cols))
        edges = [0.0]
        while edges[-1] < across_m:
            edges.append(edges[-1] + rng.uniform(0.08, 0.16))
        board = np.searchsorted(np.asarray(edges[1:]), x[0], side="right")  # (cols,)
        contrast = rng.uniform(0.06, 0.16)
        for b in range(len(edges)):
            sel = board == b
            if not sel.any():
                continue
            lines = rng.uniform(35.0, 90.0)
            wander = 0.004 * _noise_1d(rng, rows, rng.uniform(1.0, 4.0))[:, None]
            phase = 2 * np.pi * lines * (x[:, sel] + wander + rng.uniform(0, 1))
            late = (0.5 + 0.5 * np.sin(phase)) ** rng.uniform(4.0, 10.0)
            fibre = 0.03 * _noise_1d(rng, int(sel.sum()), max(2.0, sel.sum() / 1.5))[None, :]
            tint = rng.uniform(0.93, 1.07)
            shade[:, sel] = tint * (1.0 - contrast * late + fibre)
        return shade
    if kind == "steel":
        streaks = 0.008 * _noise_1d(rng, cols, cols / 1.2)[None, :]
        sheen = 0.03 * np.sin(2 * np.pi * (x / across_m * rng.uniform(0.3, 0.8) + rng.uniform()))
        sheen = sheen + 0.02 * (y / along_m - 0.5)
        return 1.0 + streaks + sheen
    if kind == "mottle":
        a = _noise_1d(rng, rows, rng.uniform(1.0, 3.0))[:, None]
        b = _noise_1d(rng, cols, rng.uniform(1.0, 3.0))[None, :]
        return 1.0 + 0.012 * (a + b)
    raise ValueError(f"unknown metric texture {kind!r}; kinds: {', '.join(METRIC_TEXTURES)}")


def metric_texture_image(look: Look, extent: tuple[float, float]) -> Image.Image:
    """The ``METRIC_TEXTURE_SIZE`` square RGB texture of ``look`` (a metric kind) over
    ``extent`` (metres along, across the grain): pattern columns, then one
    ``TONE_STRIP``-wide strip per tone 1, 2, .."""
    n = METRIC_TEXTURE_SIZE
    palette = look.palette().astype(float)
    cols = n - TONE_STRIP * (len(palette) - 1)
    rng = np.random.default_rng(look.pattern_seed)
    shade = metric_pattern(look.texture, rng, (n, cols), extent)
    img = np.empty((n, n, 3))
    img[:, :cols] = shade[..., None] * palette[0]
    for k, colour in enumerate(palette[1:]):
        img[:, cols + k * TONE_STRIP : cols + (k + 1) * TONE_STRIP] = colour
    return Image.fromarray(np.clip(np.round(img), 0, 255).astype(np.uint8), mode="RGB")


def vertex_tones(
    vertices: np.ndarray, primitives: Sequence[Primitive], tones: Sequence[bool | int]
) -> np.ndarray:
    """(N,) int tone of every vertex: the largest tone of the primitives it lies on, 0
    (the body) wherever it also lies on a body primitive (tone 0)."""
    tone = np.zeros(len(vertices), dtype=np.int64)
    on_body = np.zeros(len(vertices), dtype=bool)
    for prim, t in zip(primitives, tones, strict=True):
        hit = inside_primitive(vertices, prim, tol=2e-5)
        if int(t):
            tone = np.where(hit, np.maximum(tone, int(t)), tone)
        else:
            on_body |= hit
    return np.where(on_body, 0, tone)


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
    mesh: trimesh.Trimesh,
    primitives: Sequence[Primitive],
    accent: Sequence[bool | int],
    look: Look,
) -> None:
    """Set ``mesh.visual`` in place: vertex colours, or a texture with planar UVs.

    ``accent[i]`` is the tone of ``primitives[i]`` (False / True: body / accent)."""
    if look.tones or look.texture in METRIC_TEXTURES or any(int(a) > 1 for a in accent):
        _paint_toned(mesh, primitives, accent, look)
        return
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


def _paint_toned(
    mesh: trimesh.Trimesh, primitives: Sequence[Primitive], tones: Sequence[bool | int], look: Look
) -> None:
    """``paint`` for looks with further tones or a metric texture."""
    tone = vertex_tones(mesh.vertices, primitives, tones)
    palette = look.palette()
    if int(tone.max(initial=0)) >= len(palette):
        raise ValueError(f"tone {int(tone.max())} used but the look has {len(palette)} colours")
    if look.texture is None:
        colors = np.empty((len(mesh.vertices), 4), dtype=np.uint8)
        colors[:, :3] = palette[tone]
        colors[:, 3] = 255
        mesh.visual = trimesh.visual.ColorVisuals(mesh=mesh, vertex_colors=colors)
        return
    if look.texture not in METRIC_TEXTURES:
        raise ValueError(f"texture {look.texture!r} takes no further tones; use a metric kind")
    n = METRIC_TEXTURE_SIZE
    cols = n - TONE_STRIP * (len(palette) - 1)
    v = mesh.vertices
    across = [a for a in range(3) if a != look.grain_axis]
    s = v[:, across[0]] + v[:, across[1]]
    g = v[:, look.grain_axis]
    s_ext, g_ext = max(float(np.ptp(s)), 1e-9), max(float(np.ptp(g)), 1e-9)
    # pattern texel centres only: linear filtering never reaches the tone strips
    u = (0.5 + (s - s.min()) / s_ext * (cols - 1)) / n
    w = (0.5 + (g - g.min()) / g_ext * (n - 1)) / n
    strip_u = (cols + TONE_STRIP * (tone - 1) + TONE_STRIP / 2) / n
    uv = np.stack([np.where(tone > 0, strip_u, u), np.where(tone > 0, 0.5, w)], axis=1)
    uv = np.round(uv * 1024.0) / 1024.0
    image = metric_texture_image(look, (g_ext, s_ext))
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, image=image)
