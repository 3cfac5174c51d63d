"""Materials of real furniture and appliances: wood species, paints, steel, enamel, glass.

Every look is a :class:`~generator.procedural.appearance.Look` with a metric texture
(``"grain"`` wood, ``"steel"`` brushed metal, ``"mottle"`` paint and enamel) or plain
colours, tinted per object (a species or a paint is never exactly its palette entry)
and per part (boards of one piece differ a little). Further tones carry what a part
shows besides its body and its hardware: a window's glass, a display, a countertop.

Colours are sRGB 0-255.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from generator.procedural.appearance import RGB, Look
from generator.procedural.sampling import ParamSampler

WOOD_SPECIES: dict[str, RGB] = {
    "oak": (186, 140, 92),
    "light_oak": (212, 174, 124),
    "walnut": (108, 72, 46),
    "dark_walnut": (74, 50, 34),
    "cherry": (158, 92, 60),
    "maple": (222, 196, 156),
    "pine": (214, 168, 108),
    "mahogany": (116, 58, 38),
    "white_wash": (206, 196, 178),
    "teak": (150, 102, 62),
    "espresso": (58, 42, 34),
    "honey": (196, 134, 66),
}
FURNITURE_PAINTS: dict[str, RGB] = {
    "white": (240, 239, 234),
    "cream": (234, 226, 206),
    "light_grey": (204, 204, 200),
    "grey": (150, 152, 150),
    "anthracite": (72, 76, 80),
    "black": (34, 34, 36),
    "navy": (46, 60, 90),
    "sage": (150, 166, 140),
    "forest": (52, 78, 62),
    "blue_grey": (112, 132, 146),
    "sand": (208, 192, 166),
    "pale_blue": (176, 196, 210),
    "red": (150, 46, 40),
}
APPLIANCE_FINISHES: dict[str, RGB] = {
    "stainless": (190, 192, 194),
    "light_stainless": (206, 207, 206),
    "black_stainless": (84, 84, 88),
    "white": (242, 242, 240),
    "bisque": (234, 228, 212),
    "black": (30, 30, 32),
    "slate": (104, 104, 100),
    "silver": (172, 174, 178),
}
HARDWARE: dict[str, RGB] = {
    "brushed_nickel": (178, 178, 174),
    "chrome": (214, 214, 216),
    "black": (32, 32, 32),
    "brass": (180, 146, 78),
    "bronze": (88, 68, 52),
    "stainless": (188, 190, 192),
    "white": (236, 236, 234),
    "grey_plastic": (120, 122, 124),
}
COUNTERTOPS: dict[str, RGB] = {
    "white_quartz": (234, 232, 226),
    "black_granite": (40, 40, 42),
    "grey_stone": (126, 126, 124),
    "beige_stone": (198, 184, 160),
    "butcher_block": (178, 128, 78),
    "marble": (224, 224, 220),
    "laminate_grey": (160, 160, 156),
}
#: Window glass of oven, microwave and washer doors (dark, slightly tinted).
GLASS: dict[str, RGB] = {
    "smoke": (30, 30, 34),
    "bronze": (44, 36, 30),
    "blue": (34, 44, 56),
    "green": (40, 52, 50),
    "mesh": (52, 52, 52),
    "teal": (72, 128, 138),
    "pale": (112, 130, 142),
}
BLACK_GLASS: RGB = (22, 22, 25)
DISPLAY: RGB = (12, 14, 16)


def tint(color: RGB, rng: np.random.Generator, brightness: float = 0.08, hue: float = 0.03) -> RGB:
    """``color`` with its brightness scaled by up to +-``brightness`` and each channel by
    up to +-``hue`` (a random tint of a palette entry)."""
    c = np.asarray(color, float) * rng.uniform(1 - brightness, 1 + brightness)
    c = c * rng.uniform(1 - hue, 1 + hue, 3)
    c = np.clip(np.round(c), 0, 255)
    return (int(c[0]), int(c[1]), int(c[2]))


def pick(s: ParamSampler, name: str, palette: dict[str, RGB], keys: tuple[str, ...] = ()) -> str:
    """A palette key (recorded as ``name``), among ``keys`` when given."""
    return s.choice(name, list(keys or palette))


def per_part(look: Look, rng: np.random.Generator, amount: float = 0.03) -> Look:
    """A part's variation of ``look``: a slightly different tint, its own pattern."""
    return replace(
        look,
        color=tint(look.color, rng, amount, amount / 3),
        pattern_seed=int(rng.integers(2**31)),
    )


def with_tones(look: Look, *tones: RGB) -> Look:
    return replace(look, tones=tuple(tones))


def wood(s: ParamSampler, prefix: str, accent: RGB, species: tuple[str, ...] = ()) -> Look:
    """A wood look of a species (tinted), grain along z."""
    key = pick(s, f"{prefix}_species", WOOD_SPECIES, species)
    rng = s.child_rng()
    return Look(tint(WOOD_SPECIES[key], rng), accent, "grain", 2, int(rng.integers(2**31)))


def paint(s: ParamSampler, prefix: str, accent: RGB, colours: tuple[str, ...] = ()) -> Look:
    """A painted (or lacquered, or laminate) look, with a faint mottle."""
    key = pick(s, f"{prefix}_paint", FURNITURE_PAINTS, colours)
    rng = s.child_rng()
    return Look(
        tint(FURNITURE_PAINTS[key], rng, 0.05, 0.02), accent, "mottle", 2, int(rng.integers(2**31))
    )


def appliance(s: ParamSampler, prefix: str, accent: RGB, finish: str) -> Look:
    """The look of an appliance finish: brushed steel for the stainless finishes, enamel
    or paint otherwise."""
    rng = s.child_rng()
    colour = tint(APPLIANCE_FINISHES[finish], rng, 0.04, 0.01)
    texture = "steel" if "stainless" in finish or finish == "slate" else "mottle"
    return Look(colour, accent, texture, 2, int(rng.integers(2**31)))


def flat(colour: RGB, accent: RGB, *tones: RGB) -> Look:
    """An untextured look (glass, plastic, black panels)."""
    return Look(colour, accent, None, 2, 0, tuple(tones))


def hardware(s: ParamSampler, name: str, keys: tuple[str, ...] = ()) -> RGB:
    rng = s.child_rng()
    return tint(HARDWARE[pick(s, name, HARDWARE, keys)], rng, 0.05, 0.01)


def furniture_looks(s: ParamSampler, accent: RGB, painted_p: float = 0.45) -> tuple[Look, Look]:
    """(carcass, fronts) of a piece of furniture: wood, painted, or painted fronts on a
    wooden carcass (and the other way round)."""
    scheme = s.choice(
        "finish_scheme",
        ("wood", "painted", "painted_fronts", "wood_fronts"),
        p=(1 - painted_p, painted_p * 0.7, painted_p * 0.2, painted_p * 0.1),
    )
    if scheme == "wood":
        body = wood(s, "body", accent)
        return body, body
    if scheme == "painted":
        body = paint(s, "body", accent)
        return body, body
    if scheme == "painted_fronts":
        return wood(s, "body", accent), paint(s, "front", accent)
    return paint(s, "body", accent), wood(s, "front", accent)
