"""Details of real furniture and appliances, as boxes and cylinders (object frame, metres).

Front details lie on a face whose outward normal is +x at ``x_face``: frames of shaker
doors, window panes, knobs, keypads, displays, vent slots. Legs and feet stand on the
floor. Every function returns primitives (or (primitive, tone) pairs), never parts.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from generator.articulated import Primitive
from generator.procedural.solids import EPS, box, cylinder

Toned = list[tuple[Primitive, int]]


def frame_on_face(
    y0: float, y1: float, z0: float, z1: float, x_face: float, rail: float, depth: float
) -> list[Primitive]:
    """Four boxes (stiles and rails) ``rail`` wide standing ``depth`` proud of the face
    over the rectangle y0..y1 x z0..z1: a shaker door's or a glass door's frame."""
    rail = min(rail, 0.3 * (y1 - y0), 0.3 * (z1 - z0))
    xa, xb = x_face - EPS, x_face + depth
    return [
        box([xa, y0, z0], [xb, y0 + rail, z1]),
        box([xa, y1 - rail, z0], [xb, y1, z1]),
        box([xa, y0 + rail - EPS, z0], [xb, y1 - rail + EPS, z0 + rail]),
        box([xa, y0 + rail - EPS, z1 - rail], [xb, y1 - rail + EPS, z1]),
    ]


def pane(
    y0: float, y1: float, z0: float, z1: float, x_face: float, proud: float = 0.0015
) -> Primitive:
    """A flat pane (glass, a display) on the face, ``proud`` metres in front of it."""
    return box([x_face - EPS, y0, z0], [x_face + proud, y1, z1])


def knobs(
    x_face: float,
    points: Sequence[tuple[float, float]],
    radius: float,
    protrude: float,
    skirt: bool = True,
) -> list[Primitive]:
    """Control knobs (cylinders along x) centred at the (y, z) ``points``: a knob and,
    with ``skirt``, a thin wider ring behind it."""
    out = []
    for y, z in points:
        out.append(cylinder([x_face + protrude / 2 - EPS / 2, y, z], radius, protrude + EPS, 0))
        if skirt:
            out.append(cylinder([x_face + 0.002 - EPS / 2, y, z], 1.35 * radius, 0.004 + EPS, 0))
    return out


def row(lo: float, hi: float, n: int) -> list[float]:
    """``n`` evenly spread centres between ``lo`` and ``hi``."""
    return [lo + (hi - lo) * (k + 0.5) / n for k in range(n)]


def keypad(
    y0: float, y1: float, z0: float, z1: float, x_face: float, cols: int, rows: int
) -> list[Primitive]:
    """A grid of ``cols`` x ``rows`` small buttons filling y0..y1 x z0..z1."""
    bw, bh = (y1 - y0) / cols, (z1 - z0) / rows
    out = []
    for y in row(y0, y1, cols):
        for z in row(z0, z1, rows):
            out.append(
                box(
                    [x_face - EPS, y - 0.36 * bw, z - 0.32 * bh],
                    [x_face + 0.003, y + 0.36 * bw, z + 0.32 * bh],
                )
            )
    return out


def slots(
    y0: float, y1: float, z0: float, z1: float, x_face: float, n: int, vertical: bool
) -> list[Primitive]:
    """``n`` thin proud slats (a vent grille) across y0..y1 x z0..z1 (none when the
    rectangle is empty)."""
    out: list[Primitive] = []
    if y1 <= y0 or z1 <= z0:
        return out
    if vertical:
        w = (y1 - y0) / n
        for y in row(y0, y1, n):
            out.append(box([x_face - EPS, y - 0.3 * w, z0], [x_face + 0.002, y + 0.3 * w, z1]))
    else:
        h = (z1 - z0) / n
        for z in row(z0, z1, n):
            out.append(box([x_face - EPS, y0, z - 0.3 * h], [x_face + 0.002, y1, z + 0.3 * h]))
    return out


def leg(kind: str, x: float, y: float, height: float, size: float) -> list[Primitive]:
    """One leg from the floor to ``height`` (+ EPS into what it carries) at (x, y).

    ``kind``: "square" (a box ``size`` wide), "round" (a cylinder of diameter ``size``),
    "tapered" (three stacked boxes narrowing toward the floor), "turned" (a square
    block at the top over stacked cylinders) or "metal" (a thin square tube)."""
    h = height + EPS
    if kind == "square":
        return [box([x - size / 2, y - size / 2, 0.0], [x + size / 2, y + size / 2, h])]
    if kind == "metal":
        s = 0.6 * size
        return [box([x - s / 2, y - s / 2, 0.0], [x + s / 2, y + s / 2, h])]
    if kind == "round":
        return [cylinder([x, y, h / 2], size / 2, h, 2)]
    if kind == "tapered":
        out, z = [], 0.0
        for k, frac in enumerate((0.6, 0.78, 1.0)):
            top = h * (k + 1) / 3
            s = size * frac
            out.append(box([x - s / 2, y - s / 2, max(0.0, z - EPS)], [x + s / 2, y + s / 2, top]))
            z = top
        return out
    if kind == "turned":
        block = min(0.3 * h, 0.12)
        out = [box([x - size / 2, y - size / 2, h - block], [x + size / 2, y + size / 2, h])]
        z = 0.0
        span = h - block + EPS
        for frac, r in ((0.12, 0.35), (0.5, 0.42), (0.18, 0.3), (0.2, 0.45)):
            top = min(z + frac * span, h - block + EPS)
            out.append(cylinder([x, y, (z + top) / 2], r * size, top - z + EPS, 2))
            z = top
        return out
    raise ValueError(f"unknown leg kind {kind!r}")


def corner_legs(
    kind: str,
    x0: float,
    x1: float,
    y0: float,
    y1: float,
    height: float,
    size: float,
    inset: float,
) -> list[Primitive]:
    """Four legs ``inset`` metres in from the corners of the rectangle x0..x1 x y0..y1
    (measured to the legs' outer faces)."""
    d = inset + size / 2
    out: list[Primitive] = []
    for x in (x0 + d, x1 - d):
        for y in (y0 + d, y1 - d):
            out.extend(leg(kind, x, y, height, size))
    return out


def cooktop_grates(
    x0: float, x1: float, y0: float, y1: float, z: float, sections: int, bar: float = 0.01
) -> list[Primitive]:
    """Cast-iron grates over a gas hob: ``sections`` frames side by side, each with a
    cross of bars, ``bar`` metres square, standing on the hob at height ``z``."""
    out = []
    w = (y1 - y0) / sections
    h = 0.018
    for k in range(sections):
        a, b = y0 + k * w + 0.004, y0 + (k + 1) * w - 0.004
        out += [
            box([x0, a, z - EPS], [x1, a + bar, z + h]),
            box([x0, b - bar, z - EPS], [x1, b, z + h]),
            box([x0, a, z - EPS], [x0 + bar, b, z + h]),
            box([x1 - bar, a, z - EPS], [x1, b, z + h]),
            box([x0, (a + b) / 2 - bar / 2, z - EPS], [x1, (a + b) / 2 + bar / 2, z + h]),
            box([(x0 + x1) / 2 - bar / 2, a, z - EPS], [(x0 + x1) / 2 + bar / 2, b, z + h]),
        ]
    return out


def burners(
    centres: Sequence[tuple[float, float]], z: float, radius: float, height: float = 0.012
) -> list[Primitive]:
    """Burner caps (flat cylinders) at the (x, y) ``centres`` on a hob at height ``z``."""
    return [cylinder([x, y, z + height / 2 - EPS / 2], radius, height + EPS, 2) for x, y in centres]


def rings(
    centres: Sequence[tuple[float, float]], z: float, radius: Sequence[float]
) -> list[Primitive]:
    """Cooking-zone marks of a glass-ceramic hob: thin discs barely proud of it."""
    return [
        cylinder([x, y, z + 0.0004], r, 0.0008 + EPS, 2)
        for (x, y), r in zip(centres, radius, strict=True)
    ]


def hob_centres(
    x0: float, x1: float, y0: float, y1: float, n: int, rng: np.random.Generator
) -> list[tuple[float, float]]:
    """``n`` (4, 5 or 6) burner positions over the hob rectangle: two rows (and a centre
    burner for 5)."""
    xs = (x0 + 0.28 * (x1 - x0), x0 + 0.72 * (x1 - x0))
    if n == 5:
        ys = (y0 + 0.2 * (y1 - y0), y0 + 0.8 * (y1 - y0))
        return [(x, y) for x in xs for y in ys] + [((x0 + x1) / 2, (y0 + y1) / 2)]
    per_row = n // 2
    ys = row(y0, y1, per_row)
    jitter = rng.uniform(-0.02, 0.02, size=len(ys)) * (x1 - x0)
    return [(x + j, y) for x in xs for y, j in zip(ys, jitter, strict=True)]


def liner(
    x_back: float, x_front: float, y0: float, y1: float, z0: float, z1: float, t: float = 0.002
) -> list[Primitive]:
    """Thin boxes lining the back, sides, floor and ceiling of a cavity (an oven's dark
    enamel, a microwave's light one), from ``x_back`` to ``x_front``."""
    return [
        box([x_back - EPS, y0, z0], [x_back + t, y1, z1]),
        box([x_back, y0 - EPS, z0], [x_front, y0 + t, z1]),
        box([x_back, y1 - t, z0], [x_front, y1 + EPS, z1]),
        box([x_back, y0, z0 - EPS], [x_front, y1, z0 + t]),
        box([x_back, y0, z1 - t], [x_front, y1, z1 + EPS]),
    ]


def wire_rack(
    x0: float, x1: float, y0: float, y1: float, z: float, wires: int, wall: float = 0.0
) -> list[Primitive]:
    """A wire shelf (an oven rack, a dishwasher basket with ``wall`` m high sides): a
    frame and ``wires`` wires front to back, 5 mm thick, at height ``z``."""
    w = 0.005
    out = [
        box([x0, y0, z], [x1, y0 + w, z + w]),
        box([x0, y1 - w, z], [x1, y1, z + w]),
        box([x0, y0, z], [x0 + w, y1, z + w]),
        box([x1 - w, y0, z], [x1, y1, z + w]),
    ]
    for y in row(y0, y1, wires):
        out.append(box([x0, y - w / 2, z], [x1, y + w / 2, z + w]))
    if wall > 0:
        for zz in (z + wall / 2, z + wall):
            out += [
                box([x0, y0, zz - w], [x1, y0 + w, zz]),
                box([x0, y1 - w, zz - w], [x1, y1, zz]),
                box([x1 - w, y0, zz - w], [x1, y1, zz]),
                box([x0, y0, zz - w], [x0 + w, y1, zz]),
            ]
        for y in row(y0, y1, max(2, wires // 2)):
            out.append(box([x1 - w, y - w / 2, z], [x1, y + w / 2, z + wall]))
            out.append(box([x0, y - w / 2, z], [x0 + w, y + w / 2, z + wall]))
    return out
