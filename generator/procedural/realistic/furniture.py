"""Realistic furniture: the cabinets and desks (PartNet's StorageFurniture and Table) of
real homes, offices and kitchens, with real proportions.

cabinet kinds
    ``kitchen_base`` (0.86-0.91 m with its countertop, toe-kick, a drawer over doors,
    a drawer stack or a sink base), ``wall`` (0.3-0.9 m tall, 0.3-0.36 m deep: doors,
    lift-up or drop-down flaps, glazed doors), ``tall`` (pantries, wardrobes,
    armoires, 1.6-2.15 m), ``dresser`` (3-9 drawers, one or two columns, often two
    handles per wide drawer), ``nightstand`` (1-3 drawers, an open shelf or a door),
    ``sideboard`` (doors, drawers and flaps in 2-4 columns), ``chest`` (a lid hinged at
    the back, sometimes a drawer below) and ``metal`` (filing cabinets and lockers).
desk kinds
    ``pedestal`` (a top on one or two drawer pedestals, legs or an end panel at the
    free end, sometimes a centre drawer), ``writing`` (a table with 1-3 apron drawers),
    ``end_table`` (a small table with a drawer and often a lower shelf), ``island``
    (a kitchen island or work table: drawers and doors under a wide top) and
    ``coffee`` (a low table with drawers).

Every builder returns (base, movable part specs) for ``assembly.assemble``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from generator.articulated import Primitive
from generator.procedural.assembly import PartSpec
from generator.procedural.blocks import (
    Opening,
    drawer,
    grid_carcass,
    hinged_panel,
    inset_front,
    sample_handle,
)
from generator.procedural.realistic import looks, shapes
from generator.procedural.realistic.cases import (
    Carcass,
    Cell,
    FrontStyle,
    Tones,
    base_spec,
    build_case,
    cell_fronts,
    sample_front_style,
    top_slab,
)
from generator.procedural.sampling import ParamSampler
from generator.procedural.solids import EPS, box

CABINET_KINDS = {
    "kitchen_base": 0.18,
    "wall": 0.22,
    "tall": 0.10,
    "dresser": 0.14,
    "nightstand": 0.11,
    "sideboard": 0.10,
    "chest": 0.09,
    "metal": 0.06,
}
DESK_KINDS = {"pedestal": 0.30, "writing": 0.20, "end_table": 0.28, "island": 0.12, "coffee": 0.10}
LEG_KINDS = ("square", "tapered", "turned", "round", "metal")


def _hardware(s: ParamSampler) -> looks.RGB:
    return looks.hardware(
        s, "hardware", ("brushed_nickel", "chrome", "black", "brass", "bronze", "stainless")
    )


def _drawer_stack(n: int, grading: float, handles: int = 1) -> list[Cell]:
    """``n`` drawers top to bottom, each ``grading`` taller than the one above."""
    return [Cell("drawer", 1.0 + grading * i, handles) for i in range(n)]


def _door_cell(s: ParamSampler, name: str, width: float) -> Cell:
    """A door cell: a pair when wide, else one door hinged on a random side."""
    if width > 0.62 or (width > 0.45 and s.flag(f"{name}_pair", 0.35)):
        return Cell("pair")
    return Cell(s.choice(f"{name}_hinge", ("door_left", "door_right")))


def _support(
    s: ParamSampler, kinds: tuple[str, ...], p: tuple[float, ...]
) -> tuple[str, float, float, float]:
    """(support kind, z0, plinth, kick setback): "toe_kick", "plinth", "legs", "feet" or
    "flush"."""
    kind = s.choice("support", list(kinds), p=p)
    if kind == "toe_kick":
        return kind, 0.0, s.uniform("plinth_h", 0.09, 0.11), s.uniform("kick_setback", 0.05, 0.08)
    if kind == "plinth":
        return kind, 0.0, s.uniform("plinth_h", 0.05, 0.10), s.uniform("kick_setback", 0.0, 0.02)
    if kind == "legs":
        return kind, s.uniform("leg_h", 0.08, 0.25), 0.0, 0.04
    if kind == "feet":
        return kind, s.uniform("foot_h", 0.03, 0.07), 0.0, 0.04
    return kind, 0.0, 0.0, 0.04


def _legs_under(s: ParamSampler, kind: str, carcass: Carcass, z0: float) -> list[Primitive]:
    """Legs or feet under a carcass standing ``z0`` above the floor."""
    c = carcass
    x0, x1 = c.cx - c.depth / 2, c.cx + c.depth / 2
    y0, y1 = c.cy - c.width / 2, c.cy + c.width / 2
    if kind == "legs":
        leg = s.choice("leg_kind", LEG_KINDS, p=(0.3, 0.3, 0.1, 0.15, 0.15))
        size = s.uniform("leg_size", 0.03, 0.05)
        inset = s.uniform("leg_inset", 0.0, 0.03)
        return shapes.corner_legs(leg, x0, x1, y0, y1, z0, size, inset)
    if kind == "feet":
        size = s.uniform("foot_size", 0.04, 0.07)
        return shapes.corner_legs("round", x0, x1, y0, y1, z0, size, 0.01)
    return []


def _finish(s: ParamSampler, painted_p: float = 0.45) -> tuple[looks.Look, looks.Look]:
    accent = _hardware(s)
    return looks.furniture_looks(s, accent, painted_p)


def _case_object(
    s: ParamSampler,
    *,
    width: float,
    depth: float,
    height: float,
    columns: list[tuple[float, list[Cell]]],
    style: FrontStyle,
    support: tuple[str, float, float, float],
    top: tuple[float, float, float, float] | None,
    top_colour: looks.RGB | None = None,
    upper: tuple[float, list[tuple[float, list[Cell]]]] | None = None,
) -> tuple[PartSpec, list[PartSpec]]:
    """A case standing on the floor: carcass up to ``height`` minus the top's thickness,
    the top (thickness, front, side and back overhangs; ``top_colour`` for a countertop),
    legs or feet. ``upper`` = (height share, columns): a second carcass of other columns
    stacked on the first (small drawers side by side over wide ones)."""
    kind, z0, plinth, setback = support
    top_t = top[0] if top else 0.0
    t = s.uniform("panel_t", 0.015, 0.022)
    back_t = s.uniform("back_t", 0.004, 0.008)
    top_z = height - top_t
    split_z = top_z
    if upper is not None:
        split_z = top_z - upper[0] * (top_z - z0 - plinth)
    carcass = Carcass(width, depth, split_z, t, back_t, z0, plinth, setback)
    rng = s.child_rng()
    pieces, movable = build_case(s, "case", carcass, columns, style, rng)
    if upper is not None:
        above = Carcass(width, depth, top_z, t, back_t, split_z)
        more, more_movable = build_case(s, "upper", above, upper[1], style, rng)
        pieces += more
        movable += more_movable
    full = Carcass(width, depth, top_z, t, back_t, z0, plinth, setback)
    tones = Tones()
    if top is not None:
        tone = tones(top_colour) if top_colour is not None else 0
        pieces.append((top_slab(full, *top), tone))
    pieces.extend((p, 0) for p in _legs_under(s, kind, full, z0))
    return base_spec(pieces, style.body, tones, style.material), movable


# --------------------------------------------------------------------------- cabinets


def kitchen_base(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A kitchen base cabinet (or a run of 2-3) under a countertop, on a toe-kick."""
    n_units = s.choice("units", (1, 2, 3), p=(0.55, 0.3, 0.15))
    widths = [s.choice(f"unit{k}_w", (0.3, 0.4, 0.45, 0.5, 0.6, 0.8, 0.9)) for k in range(n_units)]
    width = float(sum(widths))
    height = s.uniform("height", 0.86, 0.91)
    depth = s.uniform("depth", 0.54, 0.60)
    body, front = _finish(s, painted_p=0.6)
    style = sample_front_style(s, body, front, doors=("slab", "shaker"), overlay_p=0.85)
    style.grip_z = height - 0.12
    columns = []
    for k, w in enumerate(widths):
        layout = s.choice(
            f"unit{k}_layout",
            ("drawer_door", "drawers", "doors", "sink"),
            p=(0.45, 0.25, 0.18, 0.12),
        )
        if layout == "drawers":
            n = s.integer(f"unit{k}_n", 2, 4)
            cells = _drawer_stack(n, s.uniform(f"unit{k}_grading", 0.2, 0.8))
        else:
            door = _door_cell(s, f"unit{k}", w)
            if door.kind != "pair" and n_units > 1 and k in (0, n_units - 1):
                # the end units' doors hinge on the run's ends, away from their neighbours
                door = Cell("door_left" if k == 0 else "door_right")
            if layout == "doors":
                cells = [door]
            else:
                first = Cell("false_front" if layout == "sink" else "drawer", 0.2)
                cells = [first, Cell(door.kind, 0.8)]
        columns.append((w, cells))
    top = (s.uniform("top_t", 0.028, 0.04), s.uniform("top_front", 0.02, 0.04), 0.0, 0.0)
    colour = looks.tint(
        looks.COUNTERTOPS[looks.pick(s, "countertop", looks.COUNTERTOPS)], s.child_rng(), 0.05
    )
    return _case_object(
        s,
        width=width,
        depth=depth,
        height=height,
        columns=columns,
        style=style,
        support=_support(s, ("toe_kick",), (1.0,)),
        top=top,
        top_colour=colour,
    )


def wall(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A wall (upper) cabinet, or a small shallow cabinet: doors, lift-up flaps (one, or a
    row of two or three on a wide unit), drop-down flaps, glazed doors."""
    width = s.uniform("width", 0.3, 1.3)
    height = s.uniform("height", 0.3, 0.92)
    depth = s.uniform("depth", 0.28, 0.37)
    body, front = _finish(s, painted_p=0.55)
    style = sample_front_style(
        s, body, front, doors=("slab", "shaker", "glass"), door_p=(0.45, 0.35, 0.2)
    )
    style.grip_z = s.choice("grip_at", (0.1, height - 0.1))
    short_wide = height < 0.5 and width > 1.1 * height
    layout = s.choice(
        "layout",
        ("door", "flap_top", "flap_bottom", "two_rows"),
        p=(0.4, 0.6 if short_wide else 0.4, 0.05, 0.15 if height > 0.6 else 0.0),
    )
    if layout == "door":
        cells = [_door_cell(s, "cell", width)]
    elif layout == "two_rows":
        cells = [Cell("flap_top", 0.35), _door_cell(s, "cell", width)]
        cells[1] = Cell(cells[1].kind, 0.65)
    else:
        cells = [Cell(layout)]
    columns = [(1.0, cells)]
    if width > 0.8 and layout == "door" and s.flag("split_columns", 0.5):
        columns = [(1.0, [Cell("door_left")]), (1.0, [Cell("door_right")])]
    if width > 0.75 and layout == "flap_top" and s.flag("flap_row", 0.5):
        columns = [(1.0, [Cell("flap_top")]) for _ in range(2 if width < 1.1 else 3)]
    return _case_object(
        s,
        width=width,
        depth=depth,
        height=height,
        columns=columns,
        style=style,
        support=("flush", 0.0, 0.0, 0.04),
        top=None,
    )


def tall(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A pantry, wardrobe or armoire: tall doors, sometimes drawers below or an upper
    pair of doors."""
    width = s.uniform("width", 0.45, 1.25)
    height = s.uniform("height", 1.6, 2.15)
    depth = s.uniform("depth", 0.4, 0.62)
    body, front = _finish(s, painted_p=0.5)
    style = sample_front_style(
        s, body, front, doors=("slab", "shaker", "glass"), door_p=(0.55, 0.35, 0.1)
    )
    style.grip_z = s.uniform("grip_z", 0.95, 1.15)
    layout = s.choice("layout", ("doors", "doors_drawers", "upper_lower"), p=(0.45, 0.35, 0.2))
    door = _door_cell(s, "door", width)
    if layout == "doors":
        cells = [Cell(door.kind)]
    elif layout == "doors_drawers":
        n = s.integer("n_drawers", 1, 3)
        cells = [Cell(door.kind, 3.0)] + _drawer_stack(n, 0.0, 2 if width > 0.8 else 1)
    else:  # an upper compartment (a lift-up flap or doors) over tall doors
        upper = "flap_top" if s.flag("lift_up", 0.3) else door.kind
        cells = [Cell(upper, 0.45 if upper == "flap_top" else 1.2), Cell(door.kind, 1.0)]
    columns = [(1.0, cells)]
    if width > 0.9 and s.flag("two_columns", 0.4):
        columns = [(1.0, [Cell("door_left")]), (1.0, cells[1:] or [Cell("door_right")])]
        if cells[1:]:
            columns[1] = (1.0, [Cell("door_right", 1.0)] + [Cell("drawer", 0.25)])
    kinds = ("plinth", "legs", "feet", "flush")
    top = None
    if s.flag("crown", 0.4):
        top = (s.uniform("top_t", 0.03, 0.06), 0.02, 0.02, 0.0)
    return _case_object(
        s,
        width=width,
        depth=depth,
        height=height,
        columns=columns,
        style=style,
        support=_support(s, kinds, (0.45, 0.15, 0.15, 0.25)),
        top=top,
    )


def dresser(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A chest of drawers: 3-6 wide drawers, small drawers over wide ones, two columns,
    or a tall narrow chest."""
    layout = s.choice(
        "layout", ("wide", "small_over_wide", "two_columns", "tall_chest"), p=(0.35, 0.3, 0.2, 0.15)
    )
    if layout == "tall_chest":
        width, height = s.uniform("width", 0.5, 0.9), s.uniform("height", 1.05, 1.4)
    elif layout == "two_columns":
        width, height = s.uniform("width", 1.1, 1.7), s.uniform("height", 0.72, 1.0)
    else:
        width, height = s.uniform("width", 0.65, 1.3), s.uniform("height", 0.7, 1.15)
    depth = s.uniform("depth", 0.4, 0.55)
    body, front = _finish(s, painted_p=0.45)
    style = sample_front_style(
        s,
        body,
        front,
        handle_kinds=("bar", "square_bar", "knob", "edge_pull", "recessed"),
        handle_p=(0.3, 0.15, 0.35, 0.1, 0.1),
        doors=("slab", "shaker"),
        door_p=(0.7, 0.3),
    )
    double = 2 if width > 0.75 and s.flag("two_handles", 0.5) else 1
    grading = s.uniform("grading", 0.0, 0.35)
    upper = None
    if layout in ("wide", "tall_chest"):
        n = s.integer("n_drawers", 3, 6 if layout == "tall_chest" else 5)
        columns = [(1.0, _drawer_stack(n, grading, double))]
    elif layout == "small_over_wide":
        n = s.integer("n_drawers", 2, 4)
        small = s.integer("n_small", 2, 3)
        columns = [(1.0, _drawer_stack(n, grading, double))]
        upper = (1.0 / (n + 1), [(1.0, [Cell("drawer")]) for _ in range(small)])
    else:
        n = s.integer("n_drawers", 3, 4)
        columns = [(1.0, _drawer_stack(n, grading)), (1.0, _drawer_stack(n, grading))]
        if s.flag("middle_doors", 0.35):
            hinge = s.choice("mid_hinge", ("door_left", "door_right"))
            columns.insert(1, (0.8, [Cell(hinge)]))
    support = _support(s, ("plinth", "legs", "feet", "flush"), (0.35, 0.3, 0.15, 0.2))
    top = (
        s.uniform("top_t", 0.018, 0.035),
        s.uniform("top_front", 0.0, 0.03),
        s.uniform("top_side", 0.0, 0.025),
        0.0,
    )
    return _case_object(
        s,
        width=width,
        depth=depth,
        height=height,
        columns=columns,
        style=style,
        support=support,
        top=top,
        upper=upper,
    )


def nightstand(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A bedside table: drawers, a drawer over an open shelf, or a drawer over a door."""
    width = s.uniform("width", 0.38, 0.62)
    height = s.uniform("height", 0.45, 0.72)
    depth = s.uniform("depth", 0.33, 0.48)
    body, front = _finish(s, painted_p=0.45)
    style = sample_front_style(
        s,
        body,
        front,
        handle_p=(0.3, 0.1, 0.4, 0.1, 0.1),
        doors=("slab", "shaker"),
        door_p=(0.7, 0.3),
    )
    style.grip_z = height - 0.1
    layout = s.choice(
        "layout", ("drawers", "drawer_open", "drawer_door", "open_drawer"), p=(0.4, 0.3, 0.2, 0.1)
    )
    if layout == "drawers":
        cells = _drawer_stack(s.integer("n_drawers", 1, 3), s.uniform("grading", 0.0, 0.3))
    elif layout == "drawer_open":
        cells = [Cell("drawer", 1.0), Cell("open", s.uniform("open_frac", 1.0, 2.0))]
    elif layout == "drawer_door":
        cells = [Cell("drawer", 1.0), Cell(_door_cell(s, "door", width).kind, 2.0)]
    else:
        cells = [Cell("open", 1.0), Cell("drawer", 1.0)]
    support = _support(s, ("legs", "plinth", "feet", "flush"), (0.45, 0.25, 0.1, 0.2))
    top = (s.uniform("top_t", 0.018, 0.03), s.uniform("top_front", 0.0, 0.03), 0.01, 0.0)
    return _case_object(
        s,
        width=width,
        depth=depth,
        height=height,
        columns=[(1.0, cells)],
        style=style,
        support=support,
        top=top,
    )


def sideboard(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A sideboard, credenza or TV console: 2-4 columns of doors and drawers, drop-down
    flaps on low consoles."""
    width = s.uniform("width", 1.0, 1.9)
    low = s.flag("low", 0.35)
    height = s.uniform("height", 0.4, 0.6) if low else s.uniform("height_tall", 0.72, 0.92)
    depth = s.uniform("depth", 0.38, 0.5)
    body, front = _finish(s, painted_p=0.45)
    style = sample_front_style(s, body, front, door_p=(0.75, 0.25))
    style.grip_z = height - 0.12
    n_cols = s.integer("columns", 2, 4 if width > 1.4 else 3)
    columns = []
    for c in range(n_cols):
        kind = s.choice(
            f"col{c}",
            ("door", "drawers", "drawer_door", "flap", "open"),
            p=(0.35, 0.2, 0.2, 0.2 if low else 0.05, 0.05),
        )
        w = width / n_cols
        if kind == "door":
            side = "door_left" if c < n_cols / 2 else "door_right"
            if c * 2 + 1 == n_cols:
                side = s.choice(f"col{c}_hinge", ("door_left", "door_right"))
            cells = [Cell(side)] if w < 0.62 else [Cell("pair")]
        elif kind == "drawers":
            cells = _drawer_stack(s.integer(f"col{c}_n", 2, 4), 0.2)
        elif kind == "drawer_door":
            side = "door_left" if c < n_cols / 2 else "door_right"
            cells = [Cell("drawer", 0.25), Cell(side if w < 0.62 else "pair", 0.75)]
        elif kind == "flap":
            cells = [Cell("flap_bottom")]
        else:
            cells = [Cell("open", 1.0), Cell("open", 1.0)]
        columns.append((1.0, cells))
    support = _support(s, ("legs", "plinth", "flush"), (0.5, 0.3, 0.2))
    top = (s.uniform("top_t", 0.018, 0.035), s.uniform("top_front", 0.0, 0.02), 0.01, 0.0)
    return _case_object(
        s,
        width=width,
        depth=depth,
        height=height,
        columns=columns,
        style=style,
        support=support,
        top=top,
    )


def chest(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A blanket chest or toy box: an open box under a lid hinged at the back, sometimes a
    drawer in a plinth below."""
    width = s.uniform("width", 0.6, 1.2)
    depth = s.uniform("depth", 0.38, 0.52)
    height = s.uniform("height", 0.4, 0.62)
    t = s.uniform("panel_t", 0.015, 0.022)
    body, front = _finish(s, painted_p=0.4)
    style = sample_front_style(
        s, body, front, door_p=(0.6, 0.4), handle_p=(0.3, 0.1, 0.3, 0.3, 0.0)
    )
    has_drawer = s.flag("drawer", 0.3)
    lid_t = s.uniform("lid_t", 0.018, 0.03)
    ov = s.uniform("lid_overhang", 0.0, 0.025)
    box_z = height - lid_t - 0.002
    z_floor = s.uniform("foot_h", 0.0, 0.06)
    z_floor = z_floor if z_floor > 0.02 else 0.0
    xb, xf, yl, yr = -depth / 2, depth / 2, -width / 2, width / 2
    rng = s.child_rng()
    pieces: list = []
    movable = []
    z_box0 = z_floor
    if has_drawer:
        dh = s.uniform("drawer_h", 0.12, 0.18)
        prims, ops = grid_carcass(
            width=width,
            depth=depth,
            top_z=z_floor + dh + 2 * t,
            t=t,
            back_t=t,
            col_fracs=[1.0],
            row_fracs=[[1.0]],
            z0=z_floor,
        )
        pieces += prims
        op = ops[0][0]
        lo, hi = inset_front(op, style.tf, (style.gap,) * 4)
        movable.append(
            drawer(
                op,
                lo,
                hi,
                clear=style.gap,
                drawer_style=style.drawer_style,
                handle=style.drawer_handle,
                look=looks.per_part(style.front, rng),
                material="wood",
                handle_count=2 if width > 0.8 else 1,
            )
        )
        z_box0 = z_floor + dh + 2 * t - EPS
    pieces += [
        box([xb, yl, z_box0], [xf, yl + t, box_z]),
        box([xb, yr - t, z_box0], [xf, yr, box_z]),
        box([xb, yl, z_box0], [xb + t, yr, box_z]),
        box([xf - t, yl, z_box0], [xf, yr, box_z]),
        box([xb, yl, z_box0], [xf, yr, z_box0 + t]),
    ]
    if z_floor > 0:
        pieces += shapes.corner_legs("square", xb, xf, yl, yr, z_floor, 0.06, 0.0)
    lo = np.array([xb - ov, yl - ov, box_z + 0.002])
    hi = np.array([xf + ov, yr + ov, box_z + 0.002 + lid_t])
    lid_handle = sample_handle(s, "lid_handle", ("edge_pull", "bar"), length=(0.1, 0.2))
    lid = hinged_panel(
        lo,
        hi,
        "back",
        handle=lid_handle,
        upper=s.uniform("lid_upper", 1.2, 1.65),
        look=looks.per_part(style.front, rng),
        material="wood",
        semantic="lid",
    )
    movable.append(lid)
    base = base_spec([(p, 0) for p in pieces], style.body, Tones(), "wood")
    return base, movable


def metal(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A steel filing cabinet (2-4 drawers) or a locker (one or two tall doors)."""
    kind = s.choice("metal_kind", ("filing", "locker", "lateral"), p=(0.5, 0.3, 0.2))
    colour = s.choice(
        "metal_colour", ("white", "light_grey", "grey", "anthracite", "black", "sand")
    )
    rng = s.child_rng()
    body = looks.Look(
        looks.tint(looks.FURNITURE_PAINTS[colour], rng, 0.04),
        (60, 60, 62),
        "mottle",
        2,
        int(rng.integers(2**31)),
    )
    style = sample_front_style(
        s,
        body,
        body,
        handle_kinds=("bar", "recessed", "edge_pull", "square_bar"),
        doors=("slab",),
        overlay_p=0.2,
        material="metal",
    )
    if kind == "filing":
        width, depth = s.uniform("width", 0.38, 0.5), s.uniform("depth", 0.5, 0.65)
        n = s.integer("n_drawers", 2, 4)
        height = 0.1 + 0.32 * n * s.uniform("drawer_scale", 0.85, 1.05)
        columns = [(1.0, _drawer_stack(n, 0.0))]
    elif kind == "lateral":
        width, depth = s.uniform("width", 0.75, 1.05), s.uniform("depth", 0.45, 0.5)
        n = s.integer("n_drawers", 2, 4)
        height = 0.1 + 0.34 * n
        columns = [(1.0, _drawer_stack(n, 0.0))]
    else:
        width, depth = s.uniform("width", 0.3, 0.9), s.uniform("depth", 0.45, 0.55)
        height = s.uniform("height", 1.7, 1.95)
        columns = [(1.0, [Cell(_door_cell(s, "door", width).kind)])]
        if width > 0.6:
            columns = [(1.0, [Cell("door_left")]), (1.0, [Cell("door_right")])]
        style.grip_z = 1.05
    return _case_object(
        s,
        width=width,
        depth=depth,
        height=height,
        columns=columns,
        style=style,
        support=_support(s, ("plinth", "flush"), (0.5, 0.5)),
        top=None,
    )


CABINET_BUILDERS = {
    "kitchen_base": kitchen_base,
    "wall": wall,
    "tall": tall,
    "dresser": dresser,
    "nightstand": nightstand,
    "sideboard": sideboard,
    "chest": chest,
    "metal": metal,
}


def cabinet(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    kind = s.choice("kind", list(CABINET_KINDS), p=list(CABINET_KINDS.values()))
    return CABINET_BUILDERS[kind](s)


# --------------------------------------------------------------------------- desks


def _table_top(
    s: ParamSampler, width: float, depth: float, height: float, thick: tuple[float, float]
) -> tuple[float, object]:
    top_t = s.uniform("top_t", *thick)
    return top_t, box([-depth / 2, -width / 2, height - top_t], [depth / 2, width / 2, height])


def _apron_table(
    s: ParamSampler,
    *,
    width: float,
    depth: float,
    height: float,
    n_drawers: int,
    shelf_p: float,
) -> tuple[PartSpec, list[PartSpec]]:
    """A table on four legs with an apron holding ``n_drawers`` drawers side by side at
    the front, and (with probability ``shelf_p``) a lower shelf."""
    body, front = _finish(s, painted_p=0.35)
    style = sample_front_style(
        s,
        body,
        front,
        handle_kinds=("knob", "bar", "square_bar", "edge_pull", "recessed"),
        handle_p=(0.45, 0.25, 0.1, 0.1, 0.1),
        doors=("slab",),
        overlay_p=0.0,
    )
    top_t, top = _table_top(s, width, depth, height, (0.018, 0.04))
    ov = s.uniform("overhang", 0.0, 0.05)
    leg_kind = s.choice("leg_kind", LEG_KINDS, p=(0.3, 0.3, 0.15, 0.1, 0.15))
    leg = s.uniform("leg_size", 0.035, 0.06)
    under = height - top_t
    x0, x1 = -depth / 2 + ov, depth / 2 - ov
    y0, y1 = -width / 2 + ov, width / 2 - ov
    apron_h = s.uniform("apron_h", 0.1, 0.18)
    apron_t = s.uniform("apron_t", 0.015, 0.022)
    pieces = [top]
    pieces += shapes.corner_legs(leg_kind, x0, x1, y0, y1, under, leg, 0.0)
    # side and back aprons between the legs
    za = under - apron_h
    pieces += [
        box([x0 + leg / 2, y0 + leg / 4, za], [x1 - leg / 2, y0 + leg / 4 + apron_t, under + EPS]),
        box([x0 + leg / 2, y1 - leg / 4 - apron_t, za], [x1 - leg / 2, y1 - leg / 4, under + EPS]),
        box([x0 + leg / 4, y0 + leg / 2, za], [x0 + leg / 4 + apron_t, y1 - leg / 2, under + EPS]),
    ]
    # the drawer housing: a carcass between the front legs
    housing_w = (y1 - y0) - 2 * leg
    prims, ops = grid_carcass(
        width=housing_w,
        depth=(x1 - leg / 4 - apron_t) - (x0 + leg / 4 + apron_t),
        top_z=under + EPS,
        t=apron_t,
        back_t=apron_t,
        col_fracs=[1.0] * n_drawers,
        row_fracs=[[1.0]] * n_drawers,
        z0=za,
        cx=((x1 - leg / 4) + (x0 + leg / 4 + apron_t)) / 2 - apron_t / 2,
    )
    pieces += prims
    if s.flag("shelf", shelf_p):
        zs = s.uniform("shelf_z", 0.08, 0.25) * height
        pieces.append(box([x0 + EPS, y0 + EPS, zs], [x1 - EPS, y1 - EPS, zs + 0.018]))
    elif s.flag("stretchers", 0.3):
        zs = s.uniform("stretcher_z", 0.08, 0.2)
        pieces += [
            box([x0 + leg / 4, y0 + leg / 4, zs], [x0 + leg * 0.75, y1 - leg / 4, zs + 0.025]),
            box([x1 - leg * 0.75, y0 + leg / 4, zs], [x1 - leg / 4, y1 - leg / 4, zs + 0.025]),
        ]
    rng = s.child_rng()
    movable = []
    for op in (col[0] for col in ops):
        movable += _apron_drawer(s, op, style, rng)
    return base_spec([(p, 0) for p in pieces], style.body, Tones(), "wood"), movable


def _apron_drawer(
    s: ParamSampler, op: Opening, style: FrontStyle, rng: np.random.Generator
) -> list[PartSpec]:
    """The drawer of an apron or centre housing, inset: its front stays inside the housing,
    clear of the fronts beside it."""
    specs, _ = cell_fronts(
        s, "apron", Cell("drawer"), op, replace(style, overlay=False), rng, (False, False)
    )
    return specs


def writing(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    width = s.uniform("width", 0.85, 1.6)
    return _apron_table(
        s,
        width=width,
        depth=s.uniform("depth", 0.5, 0.75),
        height=s.uniform("height", 0.72, 0.78),
        n_drawers=s.integer("n_drawers", 1, 3 if width > 1.1 else 2),
        shelf_p=0.1,
    )


def end_table(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    width = s.uniform("width", 0.4, 0.75)
    return _apron_table(
        s,
        width=width,
        depth=s.uniform("depth", 0.35, 0.6),
        height=s.uniform("height", 0.5, 0.76),
        n_drawers=2 if width > 0.6 and s.flag("two_drawers", 0.3) else 1,
        shelf_p=0.6,
    )


def coffee(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    width = s.uniform("width", 0.8, 1.3)
    return _apron_table(
        s,
        width=width,
        depth=s.uniform("depth", 0.45, 0.7),
        height=s.uniform("height", 0.38, 0.5),
        n_drawers=s.integer("n_drawers", 1, 2),
        shelf_p=0.5,
    )


def pedestal(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """An office or writing desk: a top on one or two pedestals of drawers (or a door and
    a drawer, or a drawer over open shelves), legs or an end panel under the free end,
    sometimes a centre drawer."""
    width = s.uniform("width", 1.0, 1.8)
    depth = s.uniform("depth", 0.55, 0.8)
    height = s.uniform("height", 0.72, 0.77)
    body, front = _finish(s, painted_p=0.35)
    style = sample_front_style(s, body, front, doors=("slab", "shaker"), door_p=(0.8, 0.2))
    top_t, top = _table_top(s, width, depth, height, (0.022, 0.04))
    under = height - top_t
    ov_f, ov_s = s.uniform("overhang_front", 0.01, 0.05), s.uniform("overhang_side", 0.0, 0.04)
    x_front, x_back = depth / 2 - ov_f, -depth / 2 + s.uniform("overhang_back", 0.0, 0.03)
    body_d, cx = x_front - x_back, (x_front + x_back) / 2
    two = width > 1.3 and s.flag("two_pedestals", 0.45)
    sides = ("left", "right") if two else (s.choice("pedestal_side", ("left", "right")),)
    plinth = s.uniform("plinth_h", 0.0, 0.08)
    plinth = plinth if plinth > 0.03 else 0.0
    rng = s.child_rng()
    pieces: list = [(top, 0)]
    movable: list[PartSpec] = []
    ped_w = s.uniform("pedestal_w", 0.36, 0.48)
    for side in sides:
        cy = (width / 2 - ov_s - ped_w / 2) * (1 if side == "right" else -1)
        layout = s.choice(
            f"{side}_layout",
            ("drawers", "drawer_door", "file", "drawer_open", "shelves"),
            p=(0.45, 0.2, 0.1, 0.15, 0.1),
        )
        if layout == "drawer_open":  # a drawer over an open cubby
            cells = [Cell("drawer", 1.0), Cell("open", s.uniform(f"{side}_open_frac", 1.5, 2.5))]
        elif layout == "shelves":  # a shallow drawer over open shelves
            cells = [Cell("drawer", 0.6), Cell("open", 1.0), Cell("open", 1.0)]
        elif layout == "drawers":
            cells = _drawer_stack(
                s.integer(f"{side}_n", 2, 4), s.uniform(f"{side}_grading", 0.0, 0.5)
            )
        elif layout == "drawer_door":
            hinge = "door_left" if side == "left" else "door_right"
            if s.flag(f"{side}_hinge_in", 0.3):
                hinge = "door_right" if side == "left" else "door_left"
            cells = [Cell("drawer", 1.0), Cell(hinge, 2.5)]
        else:
            cells = [Cell("drawer", 1.0), Cell("drawer", 2.2)]
        carcass = Carcass(
            width=ped_w,
            depth=body_d,
            top_z=under,
            t=s.uniform(f"{side}_t", 0.015, 0.022),
            back_t=0.008,
            plinth=plinth,
            kick_setback=0.02,
            cx=cx,
            cy=cy,
        )
        p, m = build_case(s, f"ped_{side}", carcass, [(1.0, cells)], style, rng)
        pieces += p
        movable += m
    y_inner_l = -width / 2 + ov_s + (ped_w if "left" in sides else 0.0)
    y_inner_r = width / 2 - ov_s - (ped_w if "right" in sides else 0.0)
    if two and s.flag("centre_drawer", 0.5):
        prims, ops = grid_carcass(
            width=y_inner_r - y_inner_l + 2 * EPS,
            depth=body_d,
            top_z=under + EPS,
            t=0.016,
            back_t=0.008,
            col_fracs=[1.0],
            row_fracs=[[1.0]],
            z0=under - s.uniform("centre_h", 0.1, 0.14),
            cx=cx,
            cy=(y_inner_l + y_inner_r) / 2,
        )
        pieces += [(p, 0) for p in prims]
        movable += _apron_drawer(s, ops[0][0], style, rng)
    if not two:
        free = "right" if sides[0] == "left" else "left"
        y_end = width / 2 - ov_s if free == "right" else -width / 2 + ov_s
        if s.flag("end_panel", 0.45):
            t = 0.025
            y0 = y_end - t if free == "right" else y_end
            pieces.append((box([x_back, y0, 0.0], [x_front, y0 + t, under + EPS]), 0))
        else:
            leg = s.uniform("leg_size", 0.04, 0.06)
            kind = s.choice("leg_kind", ("square", "round", "metal", "tapered"))
            y = y_end - leg / 2 if free == "right" else y_end + leg / 2
            for x in (x_back + leg / 2, x_front - leg / 2):
                pieces += [(p, 0) for p in shapes.leg(kind, x, y, under, leg)]
        if s.flag("modesty_panel", 0.5):
            ya, yb = sorted((y_inner_l, y_inner_r))
            zp = under - s.uniform("modesty_h", 0.2, 0.4)
            pieces.append((box([x_back, ya - EPS, zp], [x_back + 0.018, yb + EPS, under + EPS]), 0))
    return base_spec(pieces, style.body, Tones(), "wood"), movable


def island(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A kitchen island or work table: drawers and doors under a wide overhanging top."""
    width = s.uniform("width", 0.9, 1.8)
    depth = s.uniform("depth", 0.5, 0.8)
    height = s.uniform("height", 0.82, 0.94)
    body, front = _finish(s, painted_p=0.5)
    style = sample_front_style(s, body, front, doors=("slab", "shaker"), overlay_p=0.7)
    style.grip_z = height - 0.15
    n_cols = s.integer("columns", 2, 3)
    columns = []
    for c in range(n_cols):
        kind = s.choice(
            f"col{c}", ("drawers", "drawer_door", "door", "open"), p=(0.35, 0.35, 0.2, 0.1)
        )
        side = "door_left" if c < n_cols / 2 else "door_right"
        if kind == "drawers":
            cells = _drawer_stack(s.integer(f"col{c}_n", 2, 4), 0.3)
        elif kind == "drawer_door":
            cells = [Cell("drawer", 0.25), Cell(side, 0.75)]
        elif kind == "door":
            cells = [Cell(side)]
        else:
            cells = [Cell("open"), Cell("open")]
        columns.append((1.0, cells))
    colour = None
    if s.flag("stone_top", 0.4):
        colour = looks.tint(
            looks.COUNTERTOPS[looks.pick(s, "countertop", looks.COUNTERTOPS)], s.child_rng(), 0.05
        )
    top = (
        s.uniform("top_t", 0.03, 0.05),
        s.uniform("top_front", 0.02, 0.25),
        s.uniform("top_side", 0.0, 0.1),
        s.uniform("top_back", 0.0, 0.05),
    )
    return _case_object(
        s,
        width=width - 2 * top[2],
        depth=depth - top[1] - top[3],
        height=height,
        columns=columns,
        style=style,
        support=_support(s, ("toe_kick", "legs", "plinth"), (0.4, 0.35, 0.25)),
        top=top,
        top_colour=colour,
    )


DESK_BUILDERS = {
    "pedestal": pedestal,
    "writing": writing,
    "end_table": end_table,
    "island": island,
    "coffee": coffee,
}


def desk(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    kind = s.choice("kind", list(DESK_KINDS), p=list(DESK_KINDS.values()))
    base, movable = DESK_BUILDERS[kind](s)
    base.look = base.look.with_grain(1)  # the top's grain runs along its length
    return base, movable
