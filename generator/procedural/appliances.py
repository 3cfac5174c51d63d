"""Appliance families: microwave, oven, dishwasher, refrigerator, washing machine.

Appliance bodies are metal carcasses whose doors are *overlay* fronts: they sit a
1-3 mm gap in front of the body's front plane and are hinged at the edge of their
front face, so they never swing into the body.

microwave
    Body on four feet with a cavity and a control column (knobs); one side-hinged
    door over the cavity, hinged on the outer edge. Split: ``width`` (m),
    ``aspect`` (height / width).
oven
    Freestanding range: cavity, control strip with knobs, burners on top, optional
    storage drawer below; bottom-hinged door. Split: ``width``, ``height`` (m).
dishwasher
    Tub on a recessed kick plinth; bottom-hinged door. Split: ``width``, ``height``.
refrigerator
    One door, top or bottom freezer (two stacked doors hinged on the same side), or
    side-by-side (two doors hinged on the outer edges). Split: ``width``, ``height``.
washing_machine
    Front loader (square drum opening, round porthole door on a side hinge) or top
    loader (top opening, lid hinged at the back in front of the control console).
    Split: ``width``, ``height``.
"""

from __future__ import annotations

import numpy as np

from generator.articulated import Primitive
from generator.procedural.appearance import ACCENT_COLORS, APPLIANCE_COLORS, Look, jitter
from generator.procedural.assembly import PartSpec
from generator.procedural.blocks import (
    HandleStyle,
    Opening,
    drawer,
    feet,
    fill_front,
    free_edge_gap,
    grid_carcass,
    hinged_panel,
    overlay_front,
    sample_drawer_style,
    sample_handle,
)
from generator.procedural.sampling import ParamSampler, SplitChoice, SplitRange
from generator.procedural.solids import EPS, box, cylinder

SPLITS: dict[str, dict[str, SplitRange | SplitChoice]] = {
    "microwave": {
        "width": SplitRange(0.44, 0.62, 0.52, 0.54),
        "aspect": SplitRange(0.50, 0.70, 0.59, 0.62),
    },
    "oven": {
        "width": SplitRange(0.50, 0.90, 0.66, 0.72),
        "height": SplitRange(0.82, 0.95, 0.87, 0.89),
    },
    "dishwasher": {
        "width": SplitRange(0.44, 0.62, 0.52, 0.55),
        "height": SplitRange(0.80, 0.88, 0.835, 0.85),
    },
    "refrigerator": {
        "width": SplitRange(0.55, 0.95, 0.70, 0.76),
        "height": SplitRange(1.40, 1.95, 1.62, 1.70),
    },
    "washing_machine": {
        "width": SplitRange(0.55, 0.65, 0.595, 0.61),
        "height": SplitRange(0.82, 0.92, 0.86, 0.875),
    },
}

_STAINLESS = {(200, 202, 204), (168, 172, 176)}
_DARK_DOOR = (32, 32, 36)


def _looks(s: ParamSampler) -> tuple[Look, Look]:
    """(body look, door look) of an appliance; stainless bodies may get a brushed texture."""
    color = s.choice("body_color", APPLIANCE_COLORS)
    accent = s.choice("accent_color", ACCENT_COLORS)
    brushed = color in _STAINLESS and s.flag("brushed_texture", 0.5)
    body = Look(
        color, accent, "brushed" if brushed else None, 2, s.integer("pattern_seed", 0, 2**31)
    )
    door = Look(_DARK_DOOR, accent) if s.flag("dark_door", 0.3) else body
    return body, door


def _per_part(look: Look, rng: np.random.Generator) -> Look:
    return Look(
        jitter(look.color, rng, 3),
        look.accent,
        look.texture,
        look.grain_axis,
        int(rng.integers(2**31)),
    )


def _knobs(op: Opening, n: int, radius: float, protrude: float) -> list[Primitive]:
    """``n`` knobs (cylinders along x) spread across the control opening ``op``'s width (or
    height, if taller than wide), sticking ``protrude`` m out of the front plane."""
    c = np.array([op.x_front + protrude / 2 - EPS / 2, (op.y0 + op.y1) / 2, (op.z0 + op.z1) / 2])
    out = []
    axis = 1 if op.width >= op.height else 2
    lo, hi = (op.y0, op.y1) if axis == 1 else (op.z0, op.z1)
    for k in range(n):
        p = c.copy()
        p[axis] = lo + (hi - lo) * (k + 1) / (n + 1)
        out.append(cylinder(p, radius, protrude + EPS, 0))
    return out


def _body(
    s: ParamSampler,
    width: float,
    depth: float,
    top_z: float,
    col_fracs: list[float],
    row_fracs: list[list[float]],
    z0: float = 0.0,
    plinth: float = 0.0,
    kick_setback: float = 0.04,
) -> tuple[list[Primitive], list[list[Opening]], float]:
    """A metal carcass (see ``grid_carcass``); returns (panels, openings, panel thickness)."""
    t = s.uniform("panel_t", 0.012, 0.025)
    prims, ops = grid_carcass(
        width=width,
        depth=depth,
        top_z=top_z,
        t=t,
        back_t=t,
        col_fracs=col_fracs,
        row_fracs=row_fracs,
        z0=z0,
        plinth=plinth,
        kick_setback=kick_setback,
    )
    return prims, ops, t


# --------------------------------------------------------------------------- microwave


def microwave(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A countertop microwave: cavity + control column, one side-hinged door."""
    sp = SPLITS["microwave"]
    width = s.split_param("width", sp["width"])
    aspect = s.split_param("aspect", sp["aspect"])
    depth = min(s.uniform("depth", 0.32, 0.45), 0.9 * width)
    foot_h = s.uniform("foot_h", 0.008, 0.015)
    height = foot_h + aspect * width
    control_w = s.uniform("control_w", 0.09, 0.14)
    control_side = s.choice("control_side", ("left", "right"))
    hinge = "left" if control_side == "right" else "right"
    gap = s.uniform("gap", 0.001, 0.003)
    td = s.uniform("door_t", 0.018, 0.025)
    body_look, door_look = _looks(s)
    cavity_w = width - control_w
    fracs = [control_w, cavity_w] if control_side == "left" else [cavity_w, control_w]
    prims, ops, _ = _body(
        s, width, depth, height, col_fracs=fracs, row_fracs=[[1.0], [1.0]], z0=foot_h
    )
    control, cavity = (ops[0][0], ops[1][0]) if control_side == "left" else (ops[1][0], ops[0][0])
    base = PartSpec(semantic="base", material="metal", look=body_look)
    base.add(prims)
    base.add([fill_front(control, 0.02)])
    n_knobs = s.integer("n_knobs", 1, 2)
    knob_r = min(0.3 * control.width, s.uniform("knob_r", 0.014, 0.022))
    base.add(_knobs(control, n_knobs, knob_r, s.uniform("knob_protrude", 0.01, 0.02)), accent=True)
    foot_r = s.uniform("foot_r", 0.008, 0.014)
    base.add(
        feet(
            [-depth / 2 + 0.04, depth / 2 - 0.04],
            [-width / 2 + 0.05, width / 2 - 0.05],
            foot_h,
            foot_r,
        )
    )
    handle = sample_handle(s, "handle", ("bar", "recessed"), length=(0.12, 0.22))
    lo, hi = overlay_front(cavity, td, gap, (gap / 2,) * 4)
    door = hinged_panel(
        lo,
        hi,
        hinge,
        handle=handle,
        upper=s.uniform("door_upper", 1.4, 2.0),
        look=door_look,
        material="plastic",
        grip_height=float((lo[2] + hi[2]) / 2),
    )
    return base, [door]


# --------------------------------------------------------------------------- oven


def oven(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A freestanding oven: bottom-hinged door, optional storage drawer below."""
    sp = SPLITS["oven"]
    width = s.split_param("width", sp["width"])
    height = s.split_param("height", sp["height"])
    depth = s.uniform("depth", 0.55, 0.68)
    plinth = s.uniform("plinth_h", 0.0, 0.06)
    plinth = plinth if plinth > 0.02 else 0.0
    has_drawer = s.flag("has_drawer", 0.5)
    control_h = s.uniform("control_h", 0.08, 0.13)
    drawer_h = s.uniform("drawer_h", 0.12, 0.17)
    gap = s.uniform("gap", 0.001, 0.003)
    td = s.uniform("door_t", 0.02, 0.025)
    body_look, door_look = _looks(s)
    rows = [control_h, height - control_h - (drawer_h if has_drawer else 0.0)]
    if has_drawer:
        rows.append(drawer_h)
    prims, ops, _ = _body(s, width, depth, height, col_fracs=[1.0], row_fracs=[rows], plinth=plinth)
    col = ops[0]
    base = PartSpec(semantic="base", material="metal", look=body_look)
    base.add(prims)
    base.add([fill_front(col[0], 0.03)])
    knob_r = min(0.3 * col[0].height, s.uniform("knob_r", 0.015, 0.022))
    base.add(
        _knobs(
            col[0], s.integer("n_knobs", 2, 5), knob_r, s.uniform("knob_protrude", 0.015, 0.025)
        ),
        accent=True,
    )
    burner_r = min(s.uniform("burner_r", 0.05, 0.09), min(width, depth) / 4 - 0.01)
    for x in (-depth / 4, depth / 4):
        for y in (-width / 4, width / 4):
            base.add(
                [cylinder([x, y, height + 0.004 - EPS / 2], burner_r, 0.008 + EPS, 2)], accent=True
            )
    rng = s.child_rng()
    handle = sample_handle(s, "door_handle", ("bar",), length=(0.35, 0.7), standoff=(0.035, 0.05))
    lo, hi = overlay_front(col[1], td, gap, (gap / 2,) * 4)
    movable = [
        hinged_panel(
            lo,
            hi,
            "bottom",
            handle=handle,
            upper=s.uniform("door_upper", 1.4, 1.57),
            look=_per_part(door_look, rng),
            material="glass",
        )
    ]
    if has_drawer:
        dh = sample_handle(s, "drawer_handle", ("bar", "recessed"), length=(0.25, 0.5))
        lo, hi = overlay_front(
            col[2], s.uniform("drawer_front_t", 0.015, 0.022), gap, (gap / 2,) * 4
        )
        movable.append(
            drawer(
                col[2],
                lo,
                hi,
                clear=gap,
                drawer_style=sample_drawer_style(s, "drawer"),
                handle=dh,
                look=_per_part(body_look, rng),
                material="metal",
            )
        )
    return base, movable


# --------------------------------------------------------------------------- dishwasher


def dishwasher(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A dishwasher: tub on a kick plinth, one bottom-hinged door."""
    sp = SPLITS["dishwasher"]
    width = s.split_param("width", sp["width"])
    height = s.split_param("height", sp["height"])
    depth = s.uniform("depth", 0.55, 0.62)
    plinth = s.uniform("plinth_h", 0.08, 0.12)
    gap = s.uniform("gap", 0.001, 0.003)
    td = s.uniform("door_t", 0.02, 0.025)
    body_look, door_look = _looks(s)
    prims, ops, t = _body(
        s,
        width,
        depth,
        height,
        col_fracs=[1.0],
        row_fracs=[[1.0]],
        plinth=plinth,
        kick_setback=s.uniform("kick_setback", 0.04, 0.07),
    )
    op = ops[0][0]
    base = PartSpec(semantic="base", material="metal", look=body_look)
    base.add(prims)
    # two rack rails on the tub walls (visible when the door is open)
    for frac in (0.3, 0.65):
        z = op.z0 + frac * op.height
        for y0, y1 in ((op.y0 - EPS, op.y0 + 0.015), (op.y1 - 0.015, op.y1 + EPS)):
            base.add([box([op.x_back - EPS, y0, z], [op.x_front - 0.03, y1, z + 0.01])])
    handle = sample_handle(
        s, "handle", ("bar", "recessed"), length=(0.25, 0.45), standoff=(0.03, 0.045)
    )
    lo, hi = overlay_front(op, td, gap, (gap / 2,) * 4)
    door = hinged_panel(
        lo,
        hi,
        "bottom",
        handle=handle,
        upper=s.uniform("door_upper", 1.4, 1.57),
        look=door_look,
        material="metal",
    )
    return base, [door]


# --------------------------------------------------------------------------- refrigerator


def refrigerator(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A refrigerator with one door, stacked freezer/fridge doors, or side-by-side doors."""
    sp = SPLITS["refrigerator"]
    width = s.split_param("width", sp["width"])
    height = s.split_param("height", sp["height"])
    depth = s.uniform("depth", 0.60, 0.75)
    layouts = ["single", "top_freezer", "bottom_freezer"] + (
        ["side_by_side"] if width >= 0.75 else []
    )
    layout = s.choice("layout", layouts)
    plinth = s.uniform("plinth_h", 0.04, 0.10)
    gap = s.uniform("gap", 0.001, 0.003)
    td = s.uniform("door_t", 0.03, 0.05)
    freezer = s.uniform("freezer_frac", 0.25, 0.38)
    body_look, door_look = _looks(s)
    narrowest = width
    if layout == "side_by_side":
        col_fracs, row_fracs = [freezer + 0.12, 1.0 - freezer - 0.12], [[1.0], [1.0]]
        narrowest = min(col_fracs) * (width - 0.075)
        # keep the free-edge swing t^2 / (2 L) within 2 mm so the middle gap stays <= 3 mm
        td = min(td, float(np.sqrt(2 * narrowest * 0.002)))
    elif layout == "top_freezer":
        col_fracs, row_fracs = [1.0], [[freezer, 1.0 - freezer]]
    elif layout == "bottom_freezer":
        col_fracs, row_fracs = [1.0], [[1.0 - freezer, freezer]]
    else:
        col_fracs, row_fracs = [1.0], [[1.0]]
    s.params["door_t"] = td
    prims, ops, t = _body(
        s,
        width,
        depth,
        height,
        col_fracs=col_fracs,
        row_fracs=row_fracs,
        plinth=plinth,
        kick_setback=0.04,
    )
    base = PartSpec(semantic="base", material="metal", look=body_look)
    base.add(prims)
    for col in ops:
        for op in col:
            n_shelves = int(op.height // 0.35)
            for k in range(1, n_shelves + 1):
                z = op.z0 + k * op.height / (n_shelves + 1)
                base.add(
                    [
                        box(
                            [op.x_back - EPS, op.y0 - EPS, z - 0.004],
                            [op.x_front - 0.05, op.y1 + EPS, z + 0.004],
                        )
                    ]
                )
    handle = sample_handle(
        s, "handle", ("bar", "recessed"), length=(0.25, 0.6), standoff=(0.035, 0.055)
    )
    upper = s.uniform("door_upper", 1.6, 2.0)
    rng = s.child_rng()
    doors = []
    if layout == "side_by_side":
        left, right = ops[0][0], ops[1][0]
        gm = free_edge_gap(gap, td, narrowest)
        for op, hinge in ((left, "left"), (right, "right")):
            lo, hi = overlay_front(op, td, gap, (gm / 2, gm / 2, gap / 2, gap / 2))
            doors.append(_fridge_door(lo, hi, hinge, handle, upper, _per_part(door_look, rng)))
    else:
        hinge = s.choice("hinge", ("left", "right"))
        for op in ops[0]:
            lo, hi = overlay_front(op, td, gap, (gap / 2,) * 4)
            doors.append(_fridge_door(lo, hi, hinge, handle, upper, _per_part(door_look, rng)))
    return base, doors


def _fridge_door(
    lo: np.ndarray, hi: np.ndarray, hinge: str, handle: HandleStyle, upper: float, look: Look
) -> PartSpec:
    return hinged_panel(
        lo, hi, hinge, handle=handle, upper=upper, look=look, material="metal", grip_height=1.05
    )


# --------------------------------------------------------------------------- washing machine


def washing_machine(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A washing machine: front loader (round side-hinged door) or top loader (back-hinged lid)."""
    sp = SPLITS["washing_machine"]
    width = s.split_param("width", sp["width"])
    height = s.split_param("height", sp["height"])
    depth = s.uniform("depth", 0.50, 0.65)
    loader = s.choice("loader", ("front", "top"))
    gap = s.uniform("gap", 0.001, 0.003)
    body_look, door_look = _looks(s)
    if loader == "front":
        return _front_loader(s, width, height, depth, gap, body_look, door_look)
    return _top_loader(s, width, height, depth, gap, body_look, door_look)


def _front_loader(
    s: ParamSampler,
    width: float,
    height: float,
    depth: float,
    gap: float,
    body_look: Look,
    door_look: Look,
) -> tuple[PartSpec, list[PartSpec]]:
    control_h = s.uniform("control_h", 0.10, 0.14)
    plinth = s.uniform("plinth_h", 0.0, 0.06)
    plinth = plinth if plinth > 0.02 else 0.0
    prims, ops, t = _body(
        s,
        width,
        depth,
        height,
        col_fracs=[1.0],
        row_fracs=[[control_h, height - control_h]],
        plinth=plinth,
    )
    control, main = ops[0]
    base = PartSpec(semantic="base", material="metal", look=body_look)
    base.add(prims)
    base.add([fill_front(control, 0.03)])
    knob_r = min(0.35 * control.height, s.uniform("knob_r", 0.025, 0.035))
    knob_y = (
        main.y0 + 0.25 * main.width if s.flag("knob_left", 0.5) else main.y1 - 0.25 * main.width
    )
    knob_x = control.x_front + 0.01
    base.add(
        [cylinder([knob_x, knob_y, (control.z0 + control.z1) / 2], knob_r, 0.02 + EPS, 0)],
        accent=True,
    )
    # front panel with a square drum opening
    hole = min(main.width, main.height) * s.uniform("hole_frac", 0.55, 0.68)
    zc = (main.z0 + main.z1) / 2
    hy0, hy1, hz0, hz1 = -hole / 2, hole / 2, zc - hole / 2, zc + hole / 2
    xa, xf = main.x_front - t, main.x_front
    for lo, hi in (
        ([xa, main.y0 - EPS, main.z0 - EPS], [xf, hy0, main.z1 + EPS]),
        ([xa, hy1, main.z0 - EPS], [xf, main.y1 + EPS, main.z1 + EPS]),
        ([xa, main.y0 - EPS, main.z0 - EPS], [xf, main.y1 + EPS, hz0]),
        ([xa, main.y0 - EPS, hz1], [xf, main.y1 + EPS, main.z1 + EPS]),
    ):
        base.add([box(lo, hi)])
    # the round porthole door, in front of the body and below the control strip
    r = min(
        hole * s.uniform("door_r_frac", 0.72, 0.80),
        main.cover[3] - t / 2 - zc - 0.01,
        width / 2 - 0.01,
    )
    td = s.uniform("door_t", 0.03, 0.045)
    bulge = s.uniform("bulge_t", 0.01, 0.02)
    x0 = xf + gap
    ring = cylinder([x0 + td / 2, 0.0, zc], r, td, 0)
    glass = cylinder([x0 + td + bulge / 2 - EPS / 2, 0.0, zc], 0.68 * r, bulge + EPS, 0)
    style = sample_handle(s, "handle", ("bar",), length=(0.08, 0.14))
    style = HandleStyle(
        "bar", min(style.length, 0.9 * r), style.radius, style.standoff, 0.0, 0.0, 0.25 * r
    )
    lo, hi = np.array([x0, -r, zc - r]), np.array([x0 + td, r, zc + r])
    door = hinged_panel(
        lo,
        hi,
        s.choice("hinge", ("left", "right")),
        handle=style,
        upper=s.uniform("door_upper", 1.4, 2.0),
        look=door_look,
        material="plastic",
        grip_height=zc,
        body=[ring, glass],
    )
    return base, [door]


def _top_loader(
    s: ParamSampler,
    width: float,
    height: float,
    depth: float,
    gap: float,
    body_look: Look,
    door_look: Look,
) -> tuple[PartSpec, list[PartSpec]]:
    t = s.uniform("panel_t", 0.012, 0.02)
    console_d = s.uniform("console_d", 0.08, 0.12)
    console_h = s.uniform("console_h", 0.08, 0.14)
    xb, xf, yl, yr = -depth / 2, depth / 2, -width / 2, width / 2
    base = PartSpec(semantic="base", material="metal", look=body_look)
    base.add(
        [
            box([xb, yl, 0.0], [xf, yl + t, height]),
            box([xb, yr - t, 0.0], [xf, yr, height]),
            box([xb, yl, 0.0], [xf, yr, t]),
            box([xb, yl, 0.0], [xb + t, yr, height]),
            box([xf - t, yl, 0.0], [xf, yr, height]),
        ]
    )
    x_console = xb + console_d
    hx0, hx1 = x_console + 0.03, xf - 0.05
    hy = width / 2 - 0.06
    zt = height - t
    base.add(
        [
            box([xb, yl, zt], [hx0, yr, height]),
            box([hx1, yl, zt], [xf, yr, height]),
            box([xb, yl, zt], [xf, -hy, height]),
            box([xb, hy, zt], [xf, yr, height]),
            box([xb, yl, height - EPS], [x_console, yr, height + console_h]),
        ]
    )
    knob_r = s.uniform("knob_r", 0.02, min(0.035, console_d / 2 - 0.01))
    knob_y = s.uniform("knob_y", -0.3, 0.3) * width
    base.add(
        [
            cylinder(
                [xb + console_d / 2, knob_y, height + console_h + 0.01 - EPS / 2],
                knob_r,
                0.02 + EPS,
                2,
            )
        ],
        accent=True,
    )
    tl = s.uniform("lid_t", 0.015, 0.025)
    side = s.uniform("lid_side_margin", 0.0, 0.01)
    lo = np.array([x_console + gap, yl + side, height + gap])
    hi = np.array([xf, yr - side, height + gap + tl])
    handle = sample_handle(
        s, "handle", ("recessed", "bar"), length=(0.10, 0.25), standoff=(0.02, 0.03)
    )
    lid = hinged_panel(
        lo,
        hi,
        "back",
        handle=handle,
        upper=s.uniform("lid_upper", 1.3, 1.55),
        look=door_look,
        material="glass",
        semantic="lid",
    )
    return base, [lid]
