"""Furniture families: storage cabinets and desks (wood, inset fronts).

cabinet
    A carcass (sides, top, bottom, back, column dividers, row shelves) on a plinth,
    legs or flush with the floor, split into 1-3 columns of cells; each cell holds a
    drawer, a door (hinged on the column's outer side, or either side), a pair of
    doors (wide cells) or a flap (short wide cells, hinged top or bottom). 1 to 8
    movable parts. Split parameters: ``width`` (m), ``height`` (m), ``columns``.
desk
    A top on legs with an apron drawer housing (1-2 drawers), or on one or two
    drawer pedestals (1-4 drawers in all) with legs under the free end. Split
    parameters: ``width`` (m), ``n_drawers``.
"""

from __future__ import annotations

import math

import numpy as np

from generator.procedural.appearance import (
    ACCENT_COLORS,
    PAINT_COLORS,
    WOOD_COLORS,
    Look,
    jitter,
)
from generator.procedural.assembly import PartSpec
from generator.procedural.blocks import (
    HandleStyle,
    Opening,
    drawer,
    free_edge_gap,
    grid_carcass,
    hinged_panel,
    inset_front,
    sample_drawer_style,
    sample_handle,
)
from generator.procedural.sampling import ParamSampler, SplitChoice, SplitRange
from generator.procedural.solids import EPS, box, cylinder

SPLITS: dict[str, dict[str, SplitRange | SplitChoice]] = {
    "cabinet": {
        "width": SplitRange(0.40, 1.60, 0.90, 1.00),
        "height": SplitRange(0.45, 2.00, 1.10, 1.25),
        "columns": SplitChoice(train=(1, 2), test=(3,)),
    },
    "desk": {
        "width": SplitRange(0.90, 1.80, 1.25, 1.35),
        "n_drawers": SplitChoice(train=(1, 2, 4), test=(3,)),
    },
}

MAX_CABINET_PARTS = 8


def _wood_looks(s: ParamSampler) -> tuple[Look, Look]:
    """(carcass look, front look) for a piece of furniture."""
    accent = s.choice("accent_color", ACCENT_COLORS)
    textured = s.flag("wood_texture", 0.6)
    if textured:
        body = Look(
            s.choice("body_color", WOOD_COLORS),
            accent,
            "wood",
            2,
            s.integer("pattern_seed", 0, 2**31),
        )
    else:
        body = Look(s.choice("body_color", PAINT_COLORS + WOOD_COLORS), accent)
    if s.flag("contrast_fronts", 0.3):
        front = Look(s.choice("front_color", PAINT_COLORS), accent)
    else:
        front = body
    return body, front


def _part_look(look: Look, rng: np.random.Generator) -> Look:
    """A per-part variation of ``look`` (slight colour jitter, own grain phase)."""
    return Look(
        jitter(look.color, rng),
        look.accent,
        look.texture,
        look.grain_axis,
        int(rng.integers(2**31)),
    )


# --------------------------------------------------------------------------- cabinet


def _column_cells(
    s: ParamSampler, c: int, inner_h: float, t: float, budget: int
) -> list[tuple[str, float]]:
    """Cells of column ``c`` top to bottom as (kind, height m), kind "drawer" or "door";
    at most ``budget`` drawers + 1 door cell."""
    style = s.choice(
        f"col{c}_style",
        ("drawers", "door", "drawers_over_door", "door_over_drawers"),
        p=(0.35, 0.25, 0.3, 0.1),
    )
    if style == "drawers":
        n_min = max(1, math.ceil((inner_h + t) / (0.45 + t)))
        n_max = min(4, budget, max(1, math.floor((inner_h + t) / (0.10 + t))))
        if n_min <= n_max:
            n = s.integer(f"col{c}_n_drawers", n_min, n_max)
            grad = s.uniform(f"col{c}_grading", 0.0, 0.4)
            w = np.array([1.0 + grad * i for i in range(n)])
            heights = w / w.sum() * (inner_h - (n - 1) * t)
            return [("drawer", float(h)) for h in heights]
        style = "drawers_over_door"
    if style == "door" or budget < 2:
        return [("door", inner_h)]
    k = s.integer(f"col{c}_n_drawers", 1, min(3, budget - 1))
    drawer_h = s.uniform(f"col{c}_drawer_h", 0.12, 0.24)
    while k > 0 and inner_h - k * (drawer_h + t) < 0.30:
        k -= 1
    if k == 0:
        return [("door", inner_h)]
    door = ("door", inner_h - k * (drawer_h + t))
    drawers = [("drawer", drawer_h)] * k
    return drawers + [door] if style == "drawers_over_door" else [door] + drawers


def _door_kind(s: ParamSampler, c: int, r: int, width: float, height: float, spare: int) -> str:
    """How a door cell of ``width`` x ``height`` (m) is closed: "pair" (wide cells, when
    ``spare`` parts remain), "flap" (short wide cells) or a single "door"."""
    if width > 0.65 and spare >= 1:
        return "pair"
    if height < 0.45 and width > 1.2 * height and s.flag(f"col{c}_row{r}_flap", 0.5):
        return "flap"
    return "door"


def cabinet(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A storage cabinet: grid of drawers and doors in a wooden carcass."""
    sp = SPLITS["cabinet"]
    width = s.split_param("width", sp["width"])
    height = s.split_param("height", sp["height"])
    depth = s.uniform("depth", 0.35, 0.65)
    t = s.uniform("panel_t", 0.012, 0.025)
    back_t = s.uniform("back_t", 0.006, t)
    tf = s.uniform("front_t", 0.015, 0.025)
    gap = s.uniform("gap", 0.001, 0.003)
    columns = min(s.split_param("columns", sp["columns"]), max(1, int(width // 0.27)))
    s.params["columns"] = columns
    support = s.choice("support", ("plinth", "legs", "flush"))
    z0, plinth = 0.0, 0.0
    if support == "plinth":
        plinth = s.uniform("plinth_h", 0.06, 0.12)
    elif support == "legs":
        z0 = s.uniform("leg_h", 0.08, 0.18)
    inner_h = height - z0 - plinth - 2 * t
    body_look, front_look = _wood_looks(s)
    handle = sample_handle(s, "handle", ("bar", "knob", "recessed"))
    dstyle = sample_drawer_style(s, "drawer")

    col_fracs = np.array([s.uniform(f"col{c}_frac", 0.8, 1.2) for c in range(columns)])
    col_w = col_fracs / col_fracs.sum() * (width - (columns + 1) * t)
    plan: list[list[tuple[str, float]]] = []
    used = 0
    for c in range(columns):
        budget = MAX_CABINET_PARTS - used - (columns - c - 1)
        cells = _column_cells(s, c, inner_h, t, budget)
        count = len(cells)
        for r, (kind, h) in enumerate(cells):
            if kind == "door":
                kind = _door_kind(s, c, r, float(col_w[c]), h, budget - count)
                count += kind == "pair"
                cells[r] = (kind, h)
        used += count
        plan.append(cells)
    s.params["n_movable"] = used

    prims, openings = grid_carcass(
        width=width,
        depth=depth,
        top_z=height,
        t=t,
        back_t=back_t,
        col_fracs=col_fracs.tolist(),
        row_fracs=[[h for _, h in col] for col in plan],
        z0=z0,
        plinth=plinth,
    )
    base = PartSpec(semantic="base", material="wood", look=body_look)
    base.add(prims)
    if support == "legs":
        r_leg = s.uniform("leg_r", 0.015, 0.025)
        inset = r_leg + s.uniform("leg_inset", 0.01, 0.04)
        for x in (-depth / 2 + inset, depth / 2 - inset):
            for y in (-width / 2 + inset, width / 2 - inset):
                base.add([cylinder([x, y, (z0 + EPS) / 2], r_leg, z0 + EPS, 2)])

    rng = s.child_rng()
    movable: list[PartSpec] = []
    for c, (cells, ops) in enumerate(zip(plan, openings, strict=True)):
        for r, ((kind, _), op) in enumerate(zip(cells, ops, strict=True)):
            if kind == "drawer":
                lo, hi = inset_front(op, tf, (gap,) * 4)
                movable.append(
                    drawer(
                        op,
                        lo,
                        hi,
                        clear=gap,
                        drawer_style=dstyle,
                        handle=handle,
                        look=_part_look(front_look, rng),
                        material="wood",
                    )
                )
                continue
            movable.extend(_door_cell(s, kind, c, r, columns, op, tf, gap, handle, front_look, rng))
            if op.height > 0.6:  # an inner shelf behind the door(s)
                zs = (op.z0 + op.z1) / 2
                base.add(
                    [
                        box(
                            [op.x_back - EPS, op.y0 - EPS, zs - t / 2],
                            [op.x_front - tf - 0.01, op.y1 + EPS, zs + t / 2],
                        )
                    ]
                )
    return base, movable


def _door_cell(
    s: ParamSampler,
    kind: str,
    c: int,
    r: int,
    columns: int,
    op: Opening,
    tf: float,
    gap: float,
    handle: HandleStyle,
    front_look: Look,
    rng: np.random.Generator,
) -> list[PartSpec]:
    """The door(s) of one door cell: a pair, a flap or a single side-hinged door.

    Doors hinged on the carcass's outer edge open up to 2.0 rad; doors hinged on an
    interior divider stop at 1.75 rad so they do not fold onto the neighbouring
    column's handles; flaps stop at 1.57 rad.
    """
    outer_upper = s.uniform(f"col{c}_row{r}_upper", 1.4, 2.0)
    inner_upper = min(outer_upper, 1.75)
    if kind == "pair":
        half = op.width / 2 - gap
        gm = free_edge_gap(gap, tf, half)
        ym = (op.y0 + op.y1) / 2
        out = []
        for hinge, y0, y1 in (
            ("left", op.y0 + gap, ym - gm / 2),
            ("right", ym + gm / 2, op.y1 - gap),
        ):
            at_outer = (hinge == "left" and c == 0) or (hinge == "right" and c == columns - 1)
            lo = np.array([op.x_front - tf, y0, op.z0 + gap])
            hi = np.array([op.x_front, y1, op.z1 - gap])
            out.append(
                hinged_panel(
                    lo,
                    hi,
                    hinge,
                    handle=handle,
                    upper=outer_upper if at_outer else inner_upper,
                    look=_part_look(front_look, rng),
                    material="wood",
                )
            )
        return out
    if kind == "flap":
        hinge = "top" if r == 0 else "bottom"
        gf = free_edge_gap(gap, tf, op.height - 2 * gap)
        gaps = (gap, gap, gf, gap) if hinge == "top" else (gap, gap, gap, gf)
        lo, hi = inset_front(op, tf, gaps)
        return [
            hinged_panel(
                lo,
                hi,
                hinge,
                handle=handle,
                upper=min(outer_upper, 1.57),
                look=_part_look(front_look, rng),
                material="wood",
            )
        ]
    if columns == 1 or 0 < c < columns - 1:
        hinge = s.choice(f"col{c}_row{r}_hinge", ("left", "right"))
    else:
        hinge = "left" if c == 0 else "right"
    at_outer = (hinge == "left" and c == 0) or (hinge == "right" and c == columns - 1)
    gf = free_edge_gap(gap, tf, op.width - 2 * gap)
    gaps = (gap, gf, gap, gap) if hinge == "left" else (gf, gap, gap, gap)
    lo, hi = inset_front(op, tf, gaps)
    return [
        hinged_panel(
            lo,
            hi,
            hinge,
            handle=handle,
            upper=outer_upper if at_outer else inner_upper,
            look=_part_look(front_look, rng),
            material="wood",
        )
    ]


# --------------------------------------------------------------------------- desk

_DESK_LAYOUTS: dict[int, tuple[tuple[str, tuple[int, ...]], ...]] = {
    1: (("apron", (1,)),),
    2: (("apron", (2,)), ("pedestal", (2,))),
    3: (("pedestal", (3,)), ("pedestal", (2, 1))),
    4: (("pedestal", (2, 2)), ("pedestal", (4,))),
}


def desk(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A desk: top on legs with apron drawers, or on drawer pedestals (1-4 drawers)."""
    sp = SPLITS["desk"]
    width = s.split_param("width", sp["width"])
    n_drawers = s.split_param("n_drawers", sp["n_drawers"])
    depth = s.uniform("depth", 0.50, 0.80)
    height = s.uniform("height", 0.70, 0.78)
    top_t = s.uniform("top_t", 0.025, 0.04)
    t = s.uniform("panel_t", 0.012, 0.025)
    back_t = s.uniform("back_t", 0.006, t)
    tf = s.uniform("front_t", 0.015, 0.022)
    gap = s.uniform("gap", 0.001, 0.003)
    ov_f = s.uniform("overhang_front", 0.02, 0.05)
    ov_b = s.uniform("overhang_back", 0.0, 0.04)
    ov_s = s.uniform("overhang_side", 0.0, 0.05)
    leg = s.uniform("leg_size", 0.04, 0.06)
    options = _DESK_LAYOUTS[n_drawers]
    kind, counts = options[s.integer("layout", 0, len(options) - 1)]
    s.params["layout_kind"], s.params["layout_counts"] = kind, list(counts)
    body_look, front_look = _wood_looks(s)
    handle = sample_handle(s, "handle", ("bar", "knob", "recessed"), length=(0.08, 0.22))
    dstyle = sample_drawer_style(s, "drawer")

    under = height - top_t
    x_front, x_back = depth / 2 - ov_f, -depth / 2 + ov_b
    body_d, cx = x_front - x_back, (x_front + x_back) / 2
    base = PartSpec(semantic="base", material="wood", look=body_look)
    base.add([box([-depth / 2, -width / 2, under], [depth / 2, width / 2, height])])

    def leg_pair(y0: float) -> None:
        for x0 in (x_back, x_front - leg):
            base.add([box([x0, y0, 0.0], [x0 + leg, y0 + leg, under + EPS])])

    openings: list[Opening] = []
    if kind == "apron":
        k = counts[0]
        available = width - 2 * ov_s - 2 * leg - 0.04
        housing_w = min(available, k * s.uniform("apron_drawer_w", 0.40, 0.60))
        housing_h = s.uniform("apron_h", 0.12, 0.18)
        prims, ops = grid_carcass(
            width=housing_w,
            depth=body_d,
            top_z=under + EPS,
            t=t,
            back_t=back_t,
            col_fracs=[1.0] * k,
            row_fracs=[[1.0]] * k,
            z0=under - housing_h,
            cx=cx,
        )
        base.add(prims)
        openings = [col[0] for col in ops]
        leg_pair(-width / 2 + ov_s)
        leg_pair(width / 2 - ov_s - leg)
    else:
        sides = (
            ("left", "right")
            if len(counts) == 2
            else (s.choice("pedestal_side", ("left", "right")),)
        )
        plinth = s.uniform("plinth_h", 0.0, 0.06)
        plinth = plinth if plinth > 0.02 else 0.0
        ped_y: dict[str, tuple[float, float]] = {}
        for side, k in zip(sides, counts, strict=True):
            pw = s.uniform(f"pedestal_{side}_w", 0.36, 0.46)
            cy = (width / 2 - ov_s - pw / 2) * (1 if side == "right" else -1)
            ped_y[side] = (cy - pw / 2, cy + pw / 2)
            grad = s.uniform(f"pedestal_{side}_grading", 0.0, 0.5)
            prims, ops = grid_carcass(
                width=pw,
                depth=body_d,
                top_z=under + EPS,
                t=t,
                back_t=back_t,
                col_fracs=[1.0],
                row_fracs=[[1.0 + grad * i for i in range(k)]],
                plinth=plinth,
                cx=cx,
                cy=cy,
            )
            base.add(prims)
            openings.extend(ops[0])
        if len(sides) == 1:
            if sides[0] == "right":
                leg_y0 = -width / 2 + ov_s
                y_a, y_b = leg_y0 + leg - EPS, ped_y["right"][0] + EPS
            else:
                leg_y0 = width / 2 - ov_s - leg
                y_a, y_b = ped_y["left"][1] - EPS, leg_y0 + EPS
            leg_pair(leg_y0)
            if s.flag("modesty_panel", 0.6):
                panel_h = s.uniform("modesty_panel_h", 0.2, 0.35)
                base.add([box([x_back, y_a, under - panel_h], [x_back + t, y_b, under + EPS])])

    rng = s.child_rng()
    movable = []
    for op in openings:
        lo, hi = inset_front(op, tf, (gap,) * 4)
        movable.append(
            drawer(
                op,
                lo,
                hi,
                clear=gap,
                drawer_style=dstyle,
                handle=handle,
                look=_part_look(front_look, rng),
                material="wood",
            )
        )
    return base, movable
