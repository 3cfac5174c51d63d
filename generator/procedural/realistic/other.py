"""Things that are none of the seven categories, for the parser's "other" class.

Bookcases and open shelves, plain tables, chairs, stools, benches, boxes and crates,
floor and table lamps, televisions on stands and sofas: furniture-like objects a photo
may show, built from boxes and cylinders with the realistic looks, WITHOUT movable
parts (the base alone).
"""

from __future__ import annotations

from generator.procedural.assembly import PartSpec
from generator.procedural.blocks import grid_carcass
from generator.procedural.realistic import looks, shapes
from generator.procedural.realistic.cases import Pieces
from generator.procedural.sampling import ParamSampler
from generator.procedural.solids import EPS, box, cylinder

OTHER_KINDS = {
    "bookcase": 0.18,
    "rack": 0.07,
    "table": 0.15,
    "chair": 0.13,
    "stool": 0.07,
    "bench": 0.06,
    "crate": 0.1,
    "lamp": 0.08,
    "tv": 0.08,
    "sofa": 0.08,
}
FABRICS: dict[str, looks.RGB] = {
    "grey": (128, 130, 132),
    "charcoal": (62, 64, 68),
    "beige": (196, 182, 160),
    "blue": (64, 86, 120),
    "green": (86, 110, 84),
    "rust": (150, 86, 60),
    "cream": (226, 218, 200),
}


def _wood_or_paint(s: ParamSampler, accent: looks.RGB = (40, 40, 40)) -> looks.Look:
    if s.flag("painted", 0.4):
        return looks.paint(s, "body", accent)
    return looks.wood(s, "body", accent)


def _bookcase(s: ParamSampler) -> Pieces:
    width, height = s.uniform("width", 0.4, 1.2), s.uniform("height", 0.7, 2.0)
    depth = s.uniform("depth", 0.25, 0.4)
    n_cols = 1 if width < 0.7 else s.integer("columns", 1, 2)
    n_rows = max(2, int(height / s.uniform("shelf_pitch", 0.28, 0.4)))
    prims, _ = grid_carcass(
        width=width,
        depth=depth,
        top_z=height,
        t=s.uniform("panel_t", 0.016, 0.025),
        back_t=0.006,
        col_fracs=[1.0] * n_cols,
        row_fracs=[[1.0] * n_rows] * n_cols,
        plinth=s.uniform("plinth_h", 0.0, 0.08),
        kick_setback=0.01,
    )
    out = Pieces(_wood_or_paint(s))
    out.add(prims)
    return out


def _rack(s: ParamSampler) -> Pieces:
    width, height = s.uniform("width", 0.6, 1.2), s.uniform("height", 0.8, 1.9)
    depth = s.uniform("depth", 0.3, 0.5)
    out = Pieces(looks.flat(looks.tint((60, 60, 62), s.child_rng(), 0.5), (40, 40, 40)))
    post = 0.03
    out.add(
        shapes.corner_legs(
            "square", -depth / 2, depth / 2, -width / 2, width / 2, height, post, 0.0
        )
    )
    n = s.integer("shelves", 3, 5)
    for k in range(n):
        z = 0.05 + k * (height - 0.08) / (n - 1)
        out.add(box([-depth / 2, -width / 2, z], [depth / 2, width / 2, z + 0.02]))
    return out


def _table(s: ParamSampler) -> Pieces:
    round_top = s.flag("round", 0.3)
    height = s.uniform("height", 0.42, 0.78)
    out = Pieces(_wood_or_paint(s))
    top_t = s.uniform("top_t", 0.02, 0.045)
    if round_top:
        r = s.uniform("radius", 0.3, 0.6)
        out.add(cylinder([0, 0, height - top_t / 2], r, top_t, 2))
        out.add(
            cylinder(
                [0, 0, (height - top_t) / 2 + EPS],
                s.uniform("stem_r", 0.03, 0.06),
                height - top_t + 2 * EPS,
                2,
            )
        )
        out.add(cylinder([0, 0, 0.015], 0.6 * r, 0.03, 2))
        return out
    width, depth = s.uniform("width", 0.5, 1.8), s.uniform("depth", 0.45, 0.95)
    out.add(box([-depth / 2, -width / 2, height - top_t], [depth / 2, width / 2, height]))
    leg = s.uniform("leg_size", 0.035, 0.07)
    kind = s.choice("leg_kind", ("square", "tapered", "round", "metal", "turned"))
    inset = s.uniform("leg_inset", 0.0, 0.08)
    out.add(
        shapes.corner_legs(
            kind, -depth / 2, depth / 2, -width / 2, width / 2, height - top_t, leg, inset
        )
    )
    if s.flag("apron", 0.5):
        za = height - top_t - s.uniform("apron_h", 0.06, 0.1)
        d = inset + leg / 2
        out.add(
            box(
                [-depth / 2 + d, -width / 2 + d, za],
                [depth / 2 - d, width / 2 - d, height - top_t + EPS],
            )
        )
    return out


def _chair(s: ParamSampler) -> Pieces:
    seat_h, seat_w, seat_d = (
        s.uniform("seat_h", 0.42, 0.48),
        s.uniform("seat_w", 0.4, 0.52),
        s.uniform("seat_d", 0.4, 0.5),
    )
    back_h = s.uniform("back_h", 0.3, 0.5)
    out = Pieces(_wood_or_paint(s))
    seat_t = s.uniform("seat_t", 0.02, 0.06)
    leg = s.uniform("leg_size", 0.025, 0.045)
    x0, x1, y0, y1 = -seat_d / 2, seat_d / 2, -seat_w / 2, seat_w / 2
    out.add(box([x0, y0, seat_h - seat_t], [x1, y1, seat_h]))
    out.add(
        shapes.corner_legs(
            s.choice("leg_kind", ("square", "round", "tapered", "metal")),
            x0,
            x1,
            y0,
            y1,
            seat_h - seat_t,
            leg,
            0.005,
        )
    )
    # back: two posts and a rest (or a panel)
    out.add(box([x0, y0 + 0.005, seat_h - EPS], [x0 + leg, y0 + 0.005 + leg, seat_h + back_h]))
    out.add(box([x0, y1 - 0.005 - leg, seat_h - EPS], [x0 + leg, y1 - 0.005, seat_h + back_h]))
    rest_h = s.uniform("rest_h", 0.08, back_h * 0.9)
    out.add(
        box([x0, y0 + 0.005, seat_h + back_h - rest_h], [x0 + 0.02, y1 - 0.005, seat_h + back_h])
    )
    return out


def _stool(s: ParamSampler) -> Pieces:
    h = s.uniform("height", 0.42, 0.78)
    r = s.uniform("seat_r", 0.16, 0.22)
    out = Pieces(_wood_or_paint(s))
    out.add(cylinder([0, 0, h - 0.02], r, 0.04, 2))
    leg = 0.03
    d = 0.7 * r / 1.414
    for x in (-d, d):
        for y in (-d, d):
            out.add(
                box([x - leg / 2, y - leg / 2, 0.0], [x + leg / 2, y + leg / 2, h - 0.04 + EPS])
            )
    zr = s.uniform("ring_z", 0.15, 0.3)
    out.add(box([-d, -d, zr], [d, -d + leg, zr + 0.02]))
    out.add(box([-d, d - leg, zr], [d, d, zr + 0.02]))
    return out


def _bench(s: ParamSampler) -> Pieces:
    w, d, h = (
        s.uniform("width", 0.8, 1.6),
        s.uniform("depth", 0.3, 0.45),
        s.uniform("height", 0.4, 0.48),
    )
    out = Pieces(_wood_or_paint(s))
    out.add(box([-d / 2, -w / 2, h - 0.04], [d / 2, w / 2, h]))
    t = 0.03
    for y in (-w / 2 + 0.05, w / 2 - 0.05 - t):
        out.add(box([-d / 2 + 0.02, y, 0.0], [d / 2 - 0.02, y + t, h - 0.04 + EPS]))
    if s.flag("shelf", 0.5):
        out.add(box([-d / 2 + 0.02, -w / 2 + 0.05, 0.1], [d / 2 - 0.02, w / 2 - 0.05, 0.12]))
    return out


def _crate(s: ParamSampler) -> Pieces:
    w, d, h = (
        s.uniform("width", 0.3, 0.9),
        s.uniform("depth", 0.25, 0.6),
        s.uniform("height", 0.2, 0.6),
    )
    if s.flag("cardboard", 0.4):
        colour = looks.tint((178, 140, 96), s.child_rng(), 0.1)
        out = Pieces(looks.flat(colour, (200, 190, 170)))
        out.add(box([-d / 2, -w / 2, 0.0], [d / 2, w / 2, h]))
        out.add(box([d / 2 - EPS, -0.03, 0.0], [d / 2 + 0.001, 0.03, h]), 1)  # tape
        return out
    out = Pieces(looks.wood(s, "crate", (40, 40, 40), ("pine", "light_oak", "white_wash", "oak")))
    n = s.integer("slats", 2, 4)
    t = 0.015
    gap = (h - n * 0.0) / n
    for k in range(n):
        z0 = k * gap
        z1 = z0 + 0.7 * gap
        out.add(
            [
                box([d / 2 - t, -w / 2, z0], [d / 2, w / 2, z1]),
                box([-d / 2, -w / 2, z0], [-d / 2 + t, w / 2, z1]),
                box([-d / 2, -w / 2, z0], [d / 2, -w / 2 + t, z1]),
                box([-d / 2, w / 2 - t, z0], [d / 2, w / 2, z1]),
            ]
        )
    for y in (-w / 2, w / 2 - 0.03):
        for x in (-d / 2, d / 2 - 0.03):
            out.add(box([x, y, 0.0], [x + 0.03, y + 0.03, h]))
    out.add(box([-d / 2, -w / 2, 0.0], [d / 2, w / 2, t]))
    return out


def _lamp(s: ParamSampler) -> Pieces:
    floor = s.flag("floor", 0.6)
    h = s.uniform("height", 1.3, 1.8) if floor else s.uniform("table_height", 0.35, 0.6)
    shade_r = s.uniform("shade_r", 0.15, 0.25) if floor else s.uniform("small_shade_r", 0.1, 0.16)
    shade_h = s.uniform("shade_h", 0.18, 0.32) * (1.0 if floor else 0.7)
    metal = looks.tint(
        looks.HARDWARE[
            looks.pick(s, "metal", looks.HARDWARE, ("black", "brass", "chrome", "brushed_nickel"))
        ],
        s.child_rng(),
    )
    paper = ((234, 226, 208), (240, 238, 232), (200, 190, 170), (40, 40, 42))[
        s.integer("shade", 0, 3)
    ]
    shade = looks.tint(paper, s.child_rng(), 0.08)
    out = Pieces(looks.flat(metal, metal))
    base_r = s.uniform("base_r", 0.1, 0.16) if floor else s.uniform("small_base_r", 0.06, 0.1)
    out.add(cylinder([0, 0, 0.015], base_r, 0.03, 2))
    out.add(cylinder([0, 0, (h - shade_h) / 2 + 0.02], 0.012, h - shade_h, 2))
    out.add(cylinder([0, 0, h - shade_h / 2], shade_r, shade_h, 2), shade)
    return out


def _tv(s: ParamSampler) -> Pieces:
    w = s.uniform("width", 0.6, 1.4)
    h = w * 9 / 16
    stand = s.uniform("stand_h", 0.05, 0.1)
    out = Pieces(looks.flat((28, 28, 30), (40, 40, 42)))
    out.add(box([-0.03, -w / 2, stand], [0.03, w / 2, stand + h]))
    out.add(
        box([0.03 - EPS, -w / 2 + 0.01, stand + 0.01], [0.031, w / 2 - 0.01, stand + h - 0.01]),
        (12, 12, 14),
    )
    out.add(box([-0.12, -0.15 * w, 0.0], [0.12, 0.15 * w, 0.015]), 1)
    out.add(box([-0.02, -0.03, 0.0], [0.02, 0.03, stand + 0.05]), 1)
    return out


def _sofa(s: ParamSampler) -> Pieces:
    w, d = s.uniform("width", 1.2, 2.2), s.uniform("depth", 0.8, 1.0)
    seat_h, back_h = s.uniform("seat_h", 0.4, 0.48), s.uniform("back_h", 0.75, 0.9)
    fabric = looks.tint(FABRICS[looks.pick(s, "fabric", FABRICS)], s.child_rng(), 0.08)
    out = Pieces(looks.Look(fabric, (40, 40, 40), "mottle", 2, s.integer("fabric_seed", 0, 2**31)))
    arm = s.uniform("arm_w", 0.1, 0.22)
    leg = 0.05
    out.add(box([-d / 2, -w / 2, leg], [d / 2, w / 2, seat_h]))
    out.add(box([-d / 2, -w / 2, seat_h - EPS], [-d / 2 + 0.2, w / 2, back_h]))
    for y0 in (-w / 2, w / 2 - arm):
        out.add(box([-d / 2, y0, seat_h - EPS], [d / 2, y0 + arm, seat_h + 0.2]))
    out.add(shapes.corner_legs("round", -d / 2, d / 2, -w / 2, w / 2, leg, 0.04, 0.03), 1)
    return out


_BUILDERS = {
    "bookcase": _bookcase,
    "rack": _rack,
    "table": _table,
    "chair": _chair,
    "stool": _stool,
    "bench": _bench,
    "crate": _crate,
    "lamp": _lamp,
    "tv": _tv,
    "sofa": _sofa,
}


def other(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A thing of none of the seven categories: the base alone."""
    kind = s.choice("kind", list(OTHER_KINDS), p=list(OTHER_KINDS.values()))
    pieces = _BUILDERS[kind](s)
    material = "metal" if kind in ("rack", "lamp", "tv") else "wood"
    return pieces.spec(material), []
