"""Realistic appliances with the proportions and details of real ones.

oven
    ``range`` (freestanding 20-36" cookers, 0.90-0.94 m to the hob: gas grates and
    burners, a glass-ceramic top or coils; controls on a front strip or a backguard;
    a bottom-hinged door with a dark window and a long bar; sometimes a storage drawer
    or a second oven door), ``wall`` (built-in single or double ovens, a control strip
    with a display on top; a double may carry a side-opening microwave above) and
    ``toaster`` (a countertop oven with a glass door and a column of knobs).
microwave
    ``countertop`` (a side-hinged door with a window, the control panel on the right:
    display and keypad or knobs), ``over_range`` (30" wide, a vent grille along the
    top, a bar handle) and ``drawer`` (a built-in microwave drawer).
dishwasher
    Bottom-hinged door on a toe-kick, controls on a strip at the top of the door, on
    its top edge (hidden) or on a fixed panel; bar, pocket or lip handle; sometimes
    under a countertop.
refrigerator
    ``single``, ``top_freezer``, ``bottom_freezer`` (a freezer drawer or door),
    ``french`` (two doors over one or two freezer drawers), ``side_by_side`` (a
    dispenser on the freezer door) and ``mini`` (a small fridge or a glass-door
    beverage cooler); long vertical bars, lips or pockets; a grille at the bottom,
    sometimes on a tall panel that looks like a drawer front.
washing_machine
    ``front`` loaders (a round side-hinged door with a chrome or plastic ring and a
    glass bowl, a detergent drawer, a program knob and a display) and ``top`` loaders
    (a lid hinged at the back, often glazed, a console at the back); ``dryer``s.

Appliance doors are overlay fronts hinged at the edge of their front face (as in
``generator.procedural.appliances``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from generator.procedural.appearance import RGB, Look
from generator.procedural.appliances import _body
from generator.procedural.assembly import PartSpec
from generator.procedural.blocks import (
    HandleStyle,
    Opening,
    drawer,
    fill_front,
    free_edge_gap,
    hinged_panel,
    overlay_front,
    sample_drawer_style,
    sample_handle,
)
from generator.procedural.realistic import looks, shapes
from generator.procedural.realistic.cases import Pieces
from generator.procedural.sampling import ParamSampler
from generator.procedural.solids import EPS, box, cylinder

OVEN_KINDS = {"range": 0.62, "wall": 0.28, "toaster": 0.10}
MICROWAVE_KINDS = {"countertop": 0.62, "over_range": 0.3, "drawer": 0.08}
FRIDGE_KINDS = {
    "single": 0.12,
    "top_freezer": 0.22,
    "bottom_freezer": 0.18,
    "french": 0.2,
    "side_by_side": 0.16,
    "mini": 0.12,
}
WASHER_KINDS = {"front": 0.5, "top": 0.38, "dryer": 0.12}
#: Largest gap (m) between a side-by-side or French-door fridge's doors: their 4-7 cm
#: thick doors swing the free edge's back corner 2-7 mm toward the other door, and
#: FRIDGE_GAP_MARGIN more is left (``free_edge_gap``).
FRIDGE_MAX_GAP = 0.012
#: Clearance (m) beyond that swing: with 0.5 mm (the default) or 2.3 mm the closing door's
#: back corner met the other door's edge at the swing's peak (0.13 rad) and jammed there
#: in SAPIEN's drive check; with 4 mm 39 of 40 realistic fridges validate.
FRIDGE_GAP_MARGIN = 0.004
#: Least gap (m) between a fridge's door and the freezer drawer under it: with the 2-4 mm
#: of the other fronts, a closing drawer's front met the door's bottom edge about 6 cm
#: out and jammed in SAPIEN's drive check (a French-door fridge of 40).
FRIDGE_DRAWER_GAP = 0.008
FINISHES = {
    "stainless": 0.36,
    "light_stainless": 0.08,
    "white": 0.24,
    "black": 0.14,
    "black_stainless": 0.08,
    "bisque": 0.04,
    "slate": 0.03,
    "silver": 0.03,
}


def _finish(s: ParamSampler, weights: dict[str, float] = FINISHES) -> str:
    return s.choice("finish", list(weights), p=list(weights.values()))


def _accent_for(s: ParamSampler, finish: str) -> RGB:
    """Hardware of an appliance: steel bars on steel, matching or steel bars on enamel."""
    if finish in ("black", "black_stainless", "slate"):
        keys = ("black", "stainless", "chrome")
    elif finish == "white" or finish == "bisque":
        keys = ("white", "stainless", "grey_plastic", "chrome")
    else:
        keys = ("stainless", "chrome", "black")
    return looks.hardware(s, "hardware", keys)


def _looks(s: ParamSampler, finish: str) -> tuple[Look, Look]:
    accent = _accent_for(s, finish)
    body = looks.appliance(s, "body", accent, finish)
    return body, body


def _bar(
    s: ParamSampler,
    prefix: str,
    kinds: tuple[str, ...],
    length: tuple[float, float],
    p: tuple[float, ...] | None = None,
    radius: tuple[float, float] = (0.008, 0.013),
    standoff: tuple[float, float] = (0.035, 0.055),
) -> HandleStyle:
    kind = s.choice(f"{prefix}_shape", list(kinds), p=p)
    style = sample_handle(s, prefix, (kind,), length=length, standoff=standoff)
    if kind in ("pipe", "square_bar", "bar"):
        style = replace(style, radius=s.uniform(f"{prefix}_bar_r", *radius))
    if kind == "edge_pull":
        style = replace(style, standoff=s.uniform(f"{prefix}_lip", 0.012, 0.025))
    return style


def _window(
    door: Pieces,
    lo: np.ndarray,
    hi: np.ndarray,
    frac_w: float,
    frac_h: float,
    dz: float,
    glass: RGB,
    border: RGB | None = None,
) -> None:
    """A window pane on a door's face: ``frac_w`` x ``frac_h`` of the face, shifted
    ``dz`` (m) from its centre, with an optional darker border band around it."""
    yc, zc = (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2 + dz
    w, h = frac_w * (hi[1] - lo[1]), frac_h * (hi[2] - lo[2])
    if border is not None:
        b = 0.12 * min(w, h)
        door.add(
            shapes.pane(
                yc - w / 2 - b, yc + w / 2 + b, zc - h / 2 - b, zc + h / 2 + b, hi[0], 0.001
            ),
            border,
        )
    door.add(shapes.pane(yc - w / 2, yc + w / 2, zc - h / 2, zc + h / 2, hi[0], 0.0018), glass)


def _door(
    door: Pieces,
    lo: np.ndarray,
    hi: np.ndarray,
    hinge: str,
    handle: HandleStyle,
    upper: float,
    material: str,
    grip: float | None = None,
    semantic: str = "door",
) -> PartSpec:
    return hinged_panel(
        lo,
        hi,
        hinge,
        handle=handle,
        upper=upper,
        look=door.final_look(),
        material=material,
        semantic=semantic,
        grip_height=float((lo[2] + hi[2]) / 2) if grip is None else grip,
        extra=door.extra(),
    )


def _door_look(s: ParamSampler, body: Look, name: str = "door_face") -> Look:
    """A door's face: the body's finish, or black glass."""
    face = s.choice(name, ("finish", "black_glass"), p=(0.65, 0.35))
    if face == "black_glass":
        return looks.flat(looks.tint(looks.BLACK_GLASS, s.child_rng(), 0.1, 0.02), body.accent)
    return body


def _glass(s: ParamSampler, name: str = "glass") -> RGB:
    key = looks.pick(s, name, looks.GLASS)
    return looks.tint(looks.GLASS[key], s.child_rng(), 0.15, 0.05)


def _feet(base: Pieces, depth: float, width: float, h: float, r: float) -> None:
    base.add(
        [
            cylinder([x, y, (h + EPS) / 2], r, h + EPS, 2)
            for x in (-depth / 2 + 0.04, depth / 2 - 0.04)
            for y in (-width / 2 + 0.04, width / 2 - 0.04)
        ],
        looks.HARDWARE["black"],
    )


def _display(base: Pieces, op: Opening, x_face: float, w: float, h: float, yc: float) -> None:
    zc = (op.z0 + op.z1) / 2
    base.add(shapes.pane(yc - w / 2, yc + w / 2, zc - h / 2, zc + h / 2, x_face), looks.DISPLAY)


def _cavity(base: Pieces, op: Opening, colour: RGB, racks: int, rack_colour: RGB) -> None:
    """Line the cavity behind a door opening (enamel) and put wire racks in it."""
    x1 = op.x_front - 0.012
    base.add(shapes.liner(op.x_back, x1, op.y0, op.y1, op.z0, op.z1), colour)
    for k in range(racks):
        z = op.z0 + (k + 1) * op.height / (racks + 1)
        base.add(
            shapes.wire_rack(op.x_back + 0.01, x1 - 0.01, op.y0 + 0.004, op.y1 - 0.004, z, 8),
            rack_colour,
        )


OVEN_ENAMEL: tuple[RGB, ...] = ((34, 36, 44), (52, 52, 56), (28, 30, 36), (90, 92, 98))


# --------------------------------------------------------------------------- ovens


def _range(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A freestanding range: hob, controls, oven door(s), maybe a drawer."""
    width = s.choice("nominal_w", (0.51, 0.61, 0.76, 0.91), p=(0.08, 0.3, 0.47, 0.15))
    width += s.uniform("width_jitter", -0.01, 0.01)
    hob_z = s.uniform("hob_z", 0.9, 0.94)
    depth = s.uniform("depth", 0.6, 0.7)
    finish = _finish(s)
    body, _ = _looks(s, finish)
    controls = s.choice("controls", ("front", "backguard"), p=(0.5, 0.5))
    bottom = s.choice("bottom", ("drawer", "kick", "second_door"), p=(0.45, 0.35, 0.2))
    plinth = s.uniform("plinth_h", 0.02, 0.06)
    control_h = s.uniform("control_h", 0.09, 0.13) if controls == "front" else 0.0
    drawer_h = {"drawer": (0.12, 0.18), "kick": (0.05, 0.1)}.get(bottom)
    drawer_h = s.uniform("drawer_h", *drawer_h) if drawer_h else 0.0
    avail = hob_z - plinth - 0.04 - control_h - drawer_h
    rows = ([control_h] if control_h else []) + (
        [0.32 * avail, 0.68 * avail] if bottom == "second_door" else [avail]
    )
    if drawer_h:
        rows.append(drawer_h)
    hob_t = s.uniform("hob_t", 0.02, 0.035)
    prims, ops, t = _body(
        s, width, depth, hob_z - hob_t, col_fracs=[1.0], row_fracs=[rows], plinth=plinth
    )
    col = ops[0]
    base = Pieces(body)
    base.add(prims)
    rng = s.child_rng()
    # the hob
    hob = s.choice("hob", ("gas", "glass", "coil"), p=(0.5, 0.38, 0.12))
    hob_colour = (
        looks.tint(looks.BLACK_GLASS, rng, 0.1)
        if hob != "coil" and s.flag("black_hob", 0.6)
        else None
    )
    top = box([-depth / 2, -width / 2, hob_z - hob_t], [depth / 2 + 0.005, width / 2, hob_z])
    base.add(top, hob_colour if hob_colour else 0)
    n_burners = 4 if width < 0.8 else s.choice("n_burners", (5, 6))
    hx0, hx1 = -depth / 2 + 0.08, depth / 2 - 0.06
    hy0, hy1 = -width / 2 + 0.05, width / 2 - 0.05
    centres = shapes.hob_centres(hx0, hx1, hy0, hy1, n_burners, rng)
    if hob == "gas":
        base.add(
            shapes.cooktop_grates(hx0, hx1, hy0, hy1, hob_z, s.integer("grates", 2, 3), 0.012),
            looks.HARDWARE["black"],
        )
        base.add(shapes.burners(centres, hob_z, s.uniform("burner_r", 0.03, 0.045)), (40, 40, 40))
    elif hob == "glass":
        radii = rng.uniform(0.07, 0.11, len(centres))
        base.add(shapes.rings(centres, hob_z, radii), (70, 70, 72))
    else:
        for (x, y), r in zip(centres, rng.uniform(0.07, 0.1, len(centres)), strict=True):
            for k in range(3):
                rr = r * (1 - 0.3 * k)
                base.add(cylinder([x, y, hob_z + 0.004], rr, 0.008, 2), (35, 35, 35))
    # controls: a front strip or a backguard
    knob_r = s.uniform("knob_r", 0.017, 0.025)
    n_knobs = s.integer("n_knobs", 4, 6)
    knob_colour = s.choice("knob_colour", ("accent", "black"), p=(0.6, 0.4))
    knob_tone = 1 if knob_colour == "accent" else looks.HARDWARE["black"]
    if controls == "front":
        op = col[0]
        base.add(fill_front(op, 0.03))
        x_face = op.x_front
        if s.flag("control_glass", 0.4):
            base.add(
                shapes.pane(op.y0, op.y1, op.z0, op.z1, x_face, 0.001),
                looks.tint(looks.BLACK_GLASS, rng),
            )
            x_face += 0.001
        zc = (op.z0 + op.z1) / 2
        ys = shapes.row(op.y0 + 0.04, op.y1 - 0.04, n_knobs + 1)
        mid = len(ys) // 2
        _display(base, op, x_face, min(0.12, 0.6 * (ys[1] - ys[0]) * 2), 0.4 * op.height, ys[mid])
        pts = [(y, zc) for k, y in enumerate(ys) if k != mid]
        base.add(shapes.knobs(x_face, pts, min(knob_r, 0.35 * op.height), 0.025), knob_tone)
        door_rows = col[1:]
    else:
        bg_h = s.uniform("backguard_h", 0.06, 0.22)
        bg_d = s.uniform("backguard_d", 0.05, 0.1)
        x0, x1 = -depth / 2, -depth / 2 + bg_d
        base.add(box([x0, -width / 2, hob_z - EPS], [x1, width / 2, hob_z + bg_h]))
        if bg_h > 0.12:
            zc = hob_z + bg_h / 2
            ys = shapes.row(-width / 2 + 0.05, width / 2 - 0.05, n_knobs + 1)
            mid = len(ys) // 2
            base.add(
                shapes.pane(ys[mid] - 0.06, ys[mid] + 0.06, zc - 0.025, zc + 0.025, x1),
                looks.DISPLAY,
            )
            pts = [(y, zc) for k, y in enumerate(ys) if k != mid]
            base.add(shapes.knobs(x1, pts, knob_r, 0.022), knob_tone)
        door_rows = col  # (a low backguard carries no controls)
    # oven door(s)
    door_face = _door_look(s, body)
    glass = _glass(s)
    handle = _bar(
        s,
        "door_handle",
        ("pipe", "square_bar", "bar"),
        (0.55 * width, 0.85 * width),
        (0.6, 0.25, 0.15),
    )
    td = s.uniform("door_t", 0.03, 0.05)
    gap = s.uniform("gap", 0.002, 0.004)
    movable = []
    n_doors = 2 if bottom == "second_door" else 1
    enamel = looks.tint(OVEN_ENAMEL[s.integer("enamel", 0, len(OVEN_ENAMEL) - 1)], rng, 0.1)
    for k in range(n_doors):
        op = door_rows[k]
        _cavity(base, op, enamel, 2 if op.height > 0.35 else 1, (170, 170, 172))
        lo, hi = overlay_front(op, td, gap, (gap / 2,) * 4)
        door = Pieces(looks.per_part(door_face, rng, 0.01))
        _window(
            door,
            lo,
            hi,
            s.uniform(f"window{k}_w", 0.6, 0.82),
            s.uniform(f"window{k}_h", 0.35, 0.55),
            -0.05 * (hi[2] - lo[2]),
            glass,
            looks.BLACK_GLASS if s.flag(f"window{k}_border", 0.5) else None,
        )
        movable.append(
            _door(door, lo, hi, "bottom", handle, s.uniform(f"door{k}_upper", 1.35, 1.57), "glass")
        )
    if bottom == "drawer":
        op = col[-1]
        lo, hi = overlay_front(op, s.uniform("drawer_front_t", 0.02, 0.03), gap, (gap / 2,) * 4)
        dh = _bar(
            s,
            "drawer_handle",
            ("pipe", "square_bar", "edge_pull", "recessed"),
            (0.4 * width, 0.8 * width),
            (0.45, 0.2, 0.2, 0.15),
        )
        movable.append(
            drawer(
                op,
                lo,
                hi,
                clear=gap,
                drawer_style=sample_drawer_style(s, "drawer"),
                handle=dh,
                look=looks.per_part(door_face, rng, 0.01),
                material="metal",
            )
        )
    elif bottom == "kick":
        op = col[-1]
        base.add(fill_front(op, 0.03))
    # kick / plinth shadow strip
    base.add(
        box(
            [depth / 2 - 0.06, -width / 2 + 0.01, 0.0],
            [depth / 2 - 0.04, width / 2 - 0.01, plinth + EPS],
        ),
        (25, 25, 25),
    )
    return base.spec("metal"), movable


def _wall_oven(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A built-in single or double wall oven (a microwave combination on top sometimes)."""
    width = s.uniform("width", 0.595, 0.77)
    double = s.flag("double", 0.6)
    height = s.uniform("height", 1.15, 1.32) if double else s.uniform("height_single", 0.58, 0.76)
    depth = s.uniform("depth", 0.55, 0.62)
    finish = _finish(s, {"stainless": 0.5, "black": 0.25, "black_stainless": 0.15, "white": 0.1})
    body, _ = _looks(s, finish)
    control_h = s.uniform("control_h", 0.06, 0.12)
    rows = [control_h] + ([0.45, 0.55] if double else [1.0])
    if double:
        rest = height - control_h - 0.04
        rows = [control_h, 0.45 * rest, 0.55 * rest]
    else:
        rows = [control_h, height - control_h - 0.04]
    prims, ops, t = _body(s, width, depth, height, col_fracs=[1.0], row_fracs=[rows])
    col = ops[0]
    base = Pieces(body)
    base.add(prims)
    rng = s.child_rng()
    op = col[0]
    base.add(fill_front(op, 0.025))
    panel = looks.tint(looks.BLACK_GLASS, rng) if s.flag("glass_panel", 0.7) else None
    x_face = op.x_front
    if panel is not None:
        base.add(shapes.pane(op.y0, op.y1, op.z0, op.z1, x_face, 0.001), panel)
        x_face += 0.001
    _display(base, op, x_face, 0.25 * op.width, 0.45 * op.height, 0.0)
    if s.flag("knobs", 0.4):
        r = min(0.3 * op.height, 0.02)
        zc = (op.z0 + op.z1) / 2
        base.add(shapes.knobs(x_face, [(op.y0 + 0.08, zc), (op.y1 - 0.08, zc)], r, 0.02), 1)
    door_face = _door_look(s, body)
    glass = _glass(s)
    handle = _bar(s, "door_handle", ("pipe", "square_bar"), (0.6 * width, 0.9 * width))
    td = s.uniform("door_t", 0.03, 0.05)
    gap = s.uniform("gap", 0.002, 0.004)
    movable = []
    combo = double and s.flag("microwave_combo", 0.3)
    enamel = looks.tint(OVEN_ENAMEL[s.integer("enamel", 0, len(OVEN_ENAMEL) - 1)], rng, 0.1)
    for k, op in enumerate(col[1:]):
        _cavity(
            base,
            op,
            enamel if not (combo and k == 0) else (200, 200, 198),
            0 if combo and k == 0 else 2,
            (170, 170, 172),
        )
        lo, hi = overlay_front(op, td, gap, (gap / 2,) * 4)
        door = Pieces(looks.per_part(door_face, rng, 0.01))
        _window(
            door,
            lo,
            hi,
            s.uniform(f"window{k}_w", 0.62, 0.82),
            s.uniform(f"window{k}_h", 0.4, 0.6),
            -0.04 * (hi[2] - lo[2]),
            glass,
            looks.BLACK_GLASS if s.flag(f"border{k}", 0.4) else None,
        )
        if combo and k == 0:
            side = s.choice("combo_hinge", ("left", "right"))
            movable.append(
                _door(
                    door,
                    lo,
                    hi,
                    side,
                    replace(handle, length=0.7 * (hi[2] - lo[2])),
                    s.uniform("combo_upper", 1.5, 1.9),
                    "glass",
                )
            )
        else:
            movable.append(
                _door(
                    door, lo, hi, "bottom", handle, s.uniform(f"door{k}_upper", 1.35, 1.57), "glass"
                )
            )
    return base.spec("metal"), movable


def _toaster_oven(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A countertop toaster oven: glass door on the left, knobs in a column on the right."""
    width = s.uniform("width", 0.4, 0.55)
    height = s.uniform("height", 0.23, 0.33)
    depth = s.uniform("depth", 0.3, 0.42)
    foot_h = s.uniform("foot_h", 0.01, 0.025)
    finish = _finish(s, {"stainless": 0.45, "black": 0.4, "silver": 0.15})
    body, _ = _looks(s, finish)
    control_w = s.uniform("control_w", 0.09, 0.13)
    prims, ops, t = _body(
        s,
        width,
        depth,
        height,
        col_fracs=[width - control_w, control_w],
        row_fracs=[[1.0], [1.0]],
        z0=foot_h,
    )
    base = Pieces(body)
    base.add(prims)
    _feet(base, depth, width, foot_h, 0.012)
    control = ops[1][0]
    base.add(fill_front(control, 0.02))
    panel_colour = looks.tint(looks.BLACK_GLASS, s.child_rng())
    base.add(
        shapes.pane(control.y0, control.y1, control.z0, control.z1, control.x_front, 0.001),
        panel_colour,
    )
    n = s.integer("n_knobs", 2, 4)
    yc = (control.y0 + control.y1) / 2
    zs = shapes.row(control.z0 + 0.02, control.z1 - 0.02, n)
    base.add(
        shapes.knobs(
            control.x_front + 0.001,
            [(yc, z) for z in zs],
            min(0.018, 0.3 * control.width, 0.35 * (zs[1] - zs[0]) * 2 if n > 1 else 0.018),
            0.02,
        ),
        1,
    )
    op = ops[0][0]
    _cavity(base, op, looks.tint(OVEN_ENAMEL[1], s.child_rng(), 0.1), 1, (170, 170, 172))
    gap = 0.002
    lo, hi = overlay_front(op, s.uniform("door_t", 0.015, 0.025), gap, (gap / 2,) * 4)
    door = Pieces(looks.flat(looks.tint(looks.BLACK_GLASS, s.child_rng()), body.accent))
    _window(door, lo, hi, 0.86, 0.72, -0.03 * (hi[2] - lo[2]), _glass(s))
    handle = _bar(
        s,
        "handle",
        ("pipe", "square_bar"),
        (0.6 * (hi[1] - lo[1]), 0.85 * (hi[1] - lo[1])),
        radius=(0.006, 0.009),
        standoff=(0.025, 0.04),
    )
    return base.spec("metal"), [
        _door(door, lo, hi, "bottom", handle, s.uniform("door_upper", 1.3, 1.57), "glass")
    ]


def oven(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    kind = s.choice("kind", list(OVEN_KINDS), p=list(OVEN_KINDS.values()))
    return {"range": _range, "wall": _wall_oven, "toaster": _toaster_oven}[kind](s)


# --------------------------------------------------------------------------- microwaves


def _control_panel(s: ParamSampler, base: Pieces, op: Opening, rng: np.random.Generator) -> None:
    """A microwave's control column: a (black glass) panel, a display, a keypad or
    knobs, and a door-release button at the bottom."""
    base.add(fill_front(op, 0.015))
    x_face = op.x_front
    if s.flag("panel_glass", 0.6):
        base.add(
            shapes.pane(op.y0, op.y1, op.z0, op.z1, x_face, 0.001),
            looks.tint(looks.BLACK_GLASS, rng),
        )
        x_face += 0.001
    m = 0.15 * op.width
    y0, y1 = op.y0 + m, op.y1 - m
    zt = op.z1 - 0.02
    base.add(shapes.pane(y0, y1, zt - 0.035, zt, x_face), looks.DISPLAY)
    kind = s.choice("panel", ("keypad", "knobs", "keypad_knob"), p=(0.55, 0.25, 0.2))
    button = (205, 205, 205) if s.flag("light_buttons", 0.5) else (60, 60, 62)
    z_lo = op.z0 + 0.055
    if kind in ("keypad", "keypad_knob"):
        z_top = zt - 0.05
        z_bot = z_lo + (0.06 if kind == "keypad_knob" else 0.0)
        if z_top - z_bot > 0.04:
            base.add(
                shapes.keypad(y0, y1, z_bot, z_top, x_face, 3, s.integer("keypad_rows", 3, 6)),
                button,
            )
        if kind == "keypad_knob":
            r = min(0.3 * (y1 - y0), 0.022)
            base.add(shapes.knobs(x_face, [((y0 + y1) / 2, z_lo + 0.03)], r, 0.018), 1)
    else:
        r = min(0.33 * (y1 - y0), 0.022)
        zs = shapes.row(z_lo, zt - 0.05, 2)
        base.add(shapes.knobs(x_face, [((y0 + y1) / 2, z) for z in zs], r, 0.018), 1)
    base.add(box([x_face - EPS, y0, op.z0 + 0.012], [x_face + 0.004, y1, op.z0 + 0.04]), button)


def _microwave_door(
    s: ParamSampler,
    op: Opening,
    body: Look,
    hinge: str,
    rng: np.random.Generator,
    handle_kinds: tuple[str, ...] = ("pipe", "square_bar", "edge_pull", "recessed"),
    handle_p: tuple[float, ...] = (0.3, 0.15, 0.15, 0.4),
) -> PartSpec:
    gap = s.uniform("gap", 0.0015, 0.003)
    td = s.uniform("door_t", 0.02, 0.035)
    lo, hi = overlay_front(op, td, gap, (gap / 2,) * 4)
    door = Pieces(looks.per_part(_door_look(s, body), rng, 0.01))
    glass = looks.tint(
        looks.GLASS["mesh"] if s.flag("mesh_glass", 0.5) else looks.GLASS["smoke"], rng, 0.2
    )
    _window(
        door,
        lo,
        hi,
        s.uniform("window_w", 0.58, 0.76),
        s.uniform("window_h", 0.55, 0.75),
        0.0,
        glass,
        looks.BLACK_GLASS if s.flag("window_border", 0.5) else None,
    )
    h = hi[2] - lo[2]
    handle = _bar(
        s,
        "handle",
        handle_kinds,
        (0.55 * h, 0.9 * h),
        handle_p,
        radius=(0.006, 0.011),
        standoff=(0.025, 0.04),
    )
    if handle.kind == "recessed":
        handle = replace(handle, length=0.35 * h)
    # the window sits toward the hinge, the handle on the free edge
    shift = 0.04 * (hi[1] - lo[1]) * (-1 if hinge == "left" else 1)
    door.items = [
        (
            replace(p, transform=_shifted(p.transform, shift)),
            tone,
        )
        for p, tone in door.items
    ]
    return _door(door, lo, hi, hinge, handle, s.uniform("door_upper", 1.4, 1.9), "glass")


def _shifted(T: np.ndarray, dy: float) -> np.ndarray:
    out = np.array(T, float)
    out[1, 3] += dy
    return out


def _countertop_microwave(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    width = s.uniform("width", 0.44, 0.6)
    height = s.uniform("aspect", 0.52, 0.64) * width
    depth = min(s.uniform("depth", 0.33, 0.46), 0.85 * width)
    foot_h = s.uniform("foot_h", 0.008, 0.018)
    finish = _finish(s, {"stainless": 0.35, "black": 0.3, "white": 0.25, "silver": 0.1})
    body, _ = _looks(s, finish)
    control_w = s.uniform("control_w", 0.09, 0.13)
    prims, ops, t = _body(
        s,
        width,
        depth,
        height,
        col_fracs=[width - control_w, control_w],
        row_fracs=[[1.0], [1.0]],
        z0=foot_h,
    )
    base = Pieces(body)
    base.add(prims)
    _feet(base, depth, width, foot_h, 0.01)
    rng = s.child_rng()
    _control_panel(s, base, ops[1][0], rng)
    _cavity(base, ops[0][0], looks.tint((214, 214, 210), rng, 0.05), 0, (0, 0, 0))
    door = _microwave_door(s, ops[0][0], body, "left", rng)
    return base.spec("metal"), [door]


def _over_range_microwave(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    width = s.uniform("width", 0.74, 0.77)
    height = s.uniform("height", 0.38, 0.44)
    depth = s.uniform("depth", 0.38, 0.43)
    finish = _finish(s, {"stainless": 0.5, "black_stainless": 0.15, "black": 0.15, "white": 0.2})
    body, _ = _looks(s, finish)
    control_w = s.uniform("control_w", 0.11, 0.15)
    vent_h = s.uniform("vent_h", 0.035, 0.06)
    prims, ops, t = _body(
        s,
        width,
        depth,
        height,
        col_fracs=[width - control_w, control_w],
        row_fracs=[[vent_h, height - vent_h], [1.0]],  # the vent strip vent_h metres high
    )
    base = Pieces(body)
    base.add(prims)
    rng = s.child_rng()
    vent = ops[0][0]
    base.add(fill_front(vent, 0.02))
    base.add(
        shapes.slots(
            vent.y0 + 0.02,
            vent.y1 - 0.02,
            vent.z0 + 0.006,
            vent.z1 - 0.006,
            vent.x_front,
            s.integer("vent_slots", 20, 45),
            True,
        ),
        (40, 40, 42),
    )
    _control_panel(s, base, ops[1][0], rng)
    _cavity(base, ops[0][1], looks.tint((214, 214, 210), rng, 0.05), 0, (0, 0, 0))
    door = _microwave_door(
        s, ops[0][1], body, "left", rng, ("pipe", "square_bar", "edge_pull"), (0.55, 0.3, 0.15)
    )
    return base.spec("metal"), [door]


def _drawer_microwave(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    width = s.uniform("width", 0.6, 0.77)
    height = s.uniform("height", 0.38, 0.46)
    depth = s.uniform("depth", 0.55, 0.62)
    finish = _finish(s, {"stainless": 0.6, "black": 0.25, "black_stainless": 0.15})
    body, _ = _looks(s, finish)
    control_h = s.uniform("control_h", 0.05, 0.08)
    prims, ops, t = _body(
        s, width, depth, height, col_fracs=[1.0], row_fracs=[[control_h, 1.0 - control_h]]
    )
    base = Pieces(body)
    base.add(prims)
    op = ops[0][0]
    base.add(fill_front(op, 0.02))
    base.add(
        shapes.pane(op.y0, op.y1, op.z0, op.z1, op.x_front, 0.001),
        looks.tint(looks.BLACK_GLASS, s.child_rng()),
    )
    _display(base, op, op.x_front + 0.001, 0.3 * op.width, 0.5 * op.height, 0.0)
    op = ops[0][1]
    gap = 0.002
    lo, hi = overlay_front(op, s.uniform("front_t", 0.025, 0.04), gap, (gap / 2,) * 4)
    handle = _bar(s, "handle", ("edge_pull", "pipe", "recessed"), (0.5 * width, 0.8 * width))
    front = Pieces(looks.flat(looks.tint(looks.BLACK_GLASS, s.child_rng()), body.accent))
    _window(front, lo, hi, 0.6, 0.5, -0.05 * (hi[2] - lo[2]), _glass(s))
    spec = drawer(
        op,
        lo,
        hi,
        clear=gap,
        drawer_style=sample_drawer_style(s, "drawer"),
        handle=handle,
        look=front.final_look(),
        material="metal",
    )
    for prim, tone in front.items:
        spec.add([prim], accent=tone)
    return base.spec("metal"), [spec]


def microwave(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    kind = s.choice("kind", list(MICROWAVE_KINDS), p=list(MICROWAVE_KINDS.values()))
    return {
        "countertop": _countertop_microwave,
        "over_range": _over_range_microwave,
        "drawer": _drawer_microwave,
    }[kind](s)


# --------------------------------------------------------------------------- dishwasher


def dishwasher(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A dishwasher: bottom-hinged door on a toe-kick; controls on the door's top strip,
    hidden on its top edge, or on a fixed panel; sometimes under a countertop."""
    width = s.choice("nominal_w", (0.45, 0.6), p=(0.25, 0.75)) + s.uniform(
        "width_jitter", -0.01, 0.01
    )
    height = s.uniform("height", 0.81, 0.87)
    depth = s.uniform("depth", 0.55, 0.62)
    finish = _finish(
        s, {"stainless": 0.45, "white": 0.27, "black": 0.14, "black_stainless": 0.1, "bisque": 0.04}
    )
    body, _ = _looks(s, finish)
    controls = s.choice("controls", ("door_strip", "top_edge", "panel"), p=(0.45, 0.35, 0.2))
    plinth = s.uniform("plinth_h", 0.08, 0.12)
    panel_h = s.uniform("panel_h", 0.08, 0.12) if controls == "panel" else 0.0
    counter = s.flag("countertop", 0.3)
    top_t = s.uniform("top_t", 0.03, 0.04) if counter else 0.0
    rows = ([panel_h] if panel_h else []) + [1.0]
    prims, ops, t = _body(
        s,
        width,
        depth,
        height - top_t,
        col_fracs=[1.0],
        row_fracs=[rows] if not panel_h else [[panel_h, height - top_t - plinth - panel_h]],
        plinth=plinth,
        kick_setback=s.uniform("kick_setback", 0.03, 0.07),
    )
    base = Pieces(body)
    base.add(prims)
    rng = s.child_rng()
    if counter:
        colour = looks.tint(
            looks.COUNTERTOPS[looks.pick(s, "countertop_colour", looks.COUNTERTOPS)], rng, 0.05
        )
        base.add(
            box(
                [-depth / 2, -width / 2 - 0.01, height - top_t],
                [depth / 2 + 0.03, width / 2 + 0.01, height],
            ),
            colour,
        )
    col = ops[0]
    if panel_h:
        op = col[0]
        base.add(fill_front(op, 0.02))
        zc = (op.z0 + op.z1) / 2
        base.add(
            shapes.knobs(op.x_front, [(op.y0 + 0.07, zc)], min(0.3 * op.height, 0.022), 0.02), 1
        )
        base.add(
            shapes.keypad(
                op.y0 + 0.15,
                op.y1 - 0.05,
                zc - 0.012,
                zc + 0.012,
                op.x_front,
                s.integer("buttons", 3, 7),
                1,
            ),
            (70, 70, 72),
        )
    op = col[-1]
    tub = looks.tint((196, 198, 200), rng, 0.05)
    base.add(shapes.liner(op.x_back, op.x_front - 0.012, op.y0, op.y1, op.z0, op.z1), tub)
    rack = (120, 124, 130) if s.flag("grey_racks", 0.6) else (235, 235, 232)
    for frac in (0.12, 0.55):
        z = op.z0 + frac * op.height
        base.add(
            shapes.wire_rack(
                op.x_back + 0.02, op.x_front - 0.05, op.y0 + 0.02, op.y1 - 0.02, z, 9, 0.12
            ),
            rack,
        )
    gap = s.uniform("gap", 0.002, 0.004)
    lo, hi = overlay_front(op, s.uniform("door_t", 0.025, 0.045), gap, (gap / 2,) * 4)
    door = Pieces(looks.per_part(body, rng, 0.01))
    if controls == "door_strip":
        sh = s.uniform("strip_h", 0.06, 0.1)
        strip = looks.tint(looks.BLACK_GLASS, rng) if s.flag("strip_glass", 0.5) else None
        if strip is not None:
            door.add(shapes.pane(lo[1], hi[1], hi[2] - sh, hi[2], hi[0], 0.001), strip)
        yc = s.uniform("display_y", -0.25, 0.25) * width
        zc = hi[2] - sh / 2
        door.add(
            shapes.pane(yc - 0.05, yc + 0.05, zc - 0.012, zc + 0.012, hi[0] + 0.001), looks.DISPLAY
        )
        n = s.integer("buttons", 3, 7)
        ys = shapes.row(lo[1] + 0.04, hi[1] - 0.04, n + 2)
        door.add(
            [
                box([hi[0], y - 0.008, zc - 0.006], [hi[0] + 0.003, y + 0.008, zc + 0.006])
                for y in ys
                if abs(y - yc) > 0.07
            ],
            (150, 150, 150),
        )
    handle = _bar(
        s,
        "handle",
        ("pipe", "square_bar", "recessed", "edge_pull"),
        (0.35, min(0.52, 0.85 * width)),
        (0.4, 0.2, 0.25, 0.15),
    )
    if controls == "door_strip" and handle.kind == "recessed":
        handle = replace(handle, kind="pipe")
    spec = _door(door, lo, hi, "bottom", handle, s.uniform("door_upper", 1.35, 1.57), "metal")
    return base.spec("metal"), [spec]


# --------------------------------------------------------------------------- refrigerator


def refrigerator(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    """A refrigerator: single, top or bottom freezer, French door, side by side or mini."""
    kind = s.choice("kind", list(FRIDGE_KINDS), p=list(FRIDGE_KINDS.values()))
    if kind == "mini":
        width, height = s.uniform("width", 0.44, 0.6), s.uniform("height", 0.5, 0.9)
        depth = s.uniform("depth", 0.45, 0.6)
    elif kind in ("french", "side_by_side"):
        width, height = s.uniform("width", 0.76, 0.92), s.uniform("height", 1.7, 1.82)
        depth = s.uniform("depth", 0.65, 0.8)
    else:
        width, height = s.uniform("width", 0.55, 0.84), s.uniform("height", 1.45, 1.85)
        depth = s.uniform("depth", 0.6, 0.75)
    finish = _finish(
        s,
        {
            "stainless": 0.42,
            "white": 0.28,
            "black": 0.1,
            "black_stainless": 0.1,
            "bisque": 0.05,
            "slate": 0.05,
        },
    )
    body, _ = _looks(s, finish)
    plinth = (
        s.uniform("plinth_h", 0.04, 0.1) if kind != "mini" else s.uniform("mini_plinth", 0.01, 0.04)
    )
    # a tall grille panel across the bottom (older and commercial fridges): a fixed front
    # that reads like a drawer's
    grille_panel = kind != "mini" and s.flag("grille_panel", 0.3)
    if grille_panel:
        plinth = s.uniform("grille_panel_h", 0.1, 0.2)
    freezer = s.uniform("freezer_frac", 0.26, 0.34)
    if kind == "side_by_side":
        col_fracs, row_fracs = [s.uniform("freezer_w", 0.4, 0.48), 1.0], [[1.0], [1.0]]
        col_fracs[1] = 1.0 - col_fracs[0]
    elif kind == "top_freezer":
        col_fracs, row_fracs = [1.0], [[freezer, 1.0 - freezer]]
    elif kind == "bottom_freezer":
        col_fracs, row_fracs = [1.0], [[1.0 - freezer, freezer]]
    elif kind == "french":
        two = s.flag("two_drawers", 0.4)
        rows = [1.0 - freezer] + ([freezer * 0.4, freezer * 0.6] if two else [freezer])
        col_fracs, row_fracs = [1.0], [rows]
    else:
        col_fracs, row_fracs = [1.0], [[1.0]]
    prims, ops, t = _body(
        s,
        width,
        depth,
        height,
        col_fracs=col_fracs,
        row_fracs=row_fracs,
        plinth=plinth,
        kick_setback=0.01,
    )
    base = Pieces(body)
    base.add(prims)
    rng = s.child_rng()
    # the grille in the plinth and shelves inside
    if grille_panel:  # a panel over the plinth's width, in the body's finish or dark plastic
        colour = looks.tint((38, 38, 40), rng, 0.2) if s.flag("grille_panel_dark", 0.5) else None
        base.add(
            box(
                [depth / 2 - 0.03, -width / 2 + 0.005, 0.005],
                [depth / 2, width / 2 - 0.005, plinth - 0.004],
            ),
            colour or 0,
        )
    if kind != "mini":
        base.add(
            shapes.slots(
                -width / 2 + 0.03,
                width / 2 - 0.03,
                0.01 if not grille_panel else 0.3 * plinth,
                plinth - 0.01 if not grille_panel else 0.75 * plinth,
                depth / 2 - 0.01 if not grille_panel else depth / 2,
                s.integer("grille_slots", 3, 6),
                False,
            ),
            (35, 35, 35),
        )
    drawer_rows = {
        "french": {(0, r) for r in range(1, len(row_fracs[0]))},
        "bottom_freezer": {(0, 1)},
    }.get(kind, set())
    for c, column in enumerate(ops):
        for r, op in enumerate(column):
            if (c, r) in drawer_rows:
                continue
            n_shelves = int(op.height // 0.35)
            for k in range(1, n_shelves + 1):
                z = op.z0 + k * op.height / (n_shelves + 1)
                base.add(
                    box(
                        [op.x_back - EPS, op.y0 - EPS, z - 0.004],
                        [op.x_front - 0.08, op.y1 + EPS, z + 0.004],
                    ),
                    (215, 225, 230),
                )
    td = s.uniform("door_t", 0.04, 0.07)
    gap = s.uniform("gap", 0.002, 0.004)
    handle = _bar(
        s,
        "handle",
        ("pipe", "square_bar", "edge_pull", "recessed", "bar"),
        (0.3, 0.85),
        (0.35, 0.22, 0.2, 0.13, 0.1),
        radius=(0.009, 0.015),
        standoff=(0.04, 0.06),
    )
    drawer_handle = _bar(
        s,
        "drawer_handle",
        (handle.kind if handle.kind != "bar" else "pipe",),
        (0.45 * width, 0.8 * width),
        radius=(0.009, 0.014),
        standoff=(0.04, 0.06),
    )
    upper = s.uniform("door_upper", 1.6, 2.0)
    glass_door = kind == "mini" and s.flag("glass_door", 0.35)
    hinge = s.choice("hinge", ("left", "right"))
    movable: list[PartSpec] = []

    def door_part(
        op: Opening, side: str, gaps: tuple[float, float, float, float], dispenser: bool = False
    ) -> PartSpec:
        lo, hi = overlay_front(op, td if not glass_door else 0.03, gap, gaps)
        door = Pieces(looks.per_part(body, rng, 0.01))
        if glass_door:
            frame = 0.05
            door.add(
                shapes.pane(lo[1] + frame, hi[1] - frame, lo[2] + frame, hi[2] - frame, hi[0]),
                _glass(s, "cooler_glass"),
            )
        if dispenser:
            yc, zc = (lo[1] + hi[1]) / 2, lo[2] + 0.62 * (hi[2] - lo[2])
            w = min(0.2, 0.6 * (hi[1] - lo[1]))
            door.add(
                shapes.pane(yc - w / 2, yc + w / 2, zc - 0.16, zc + 0.16, hi[0], 0.002),
                (40, 40, 42),
            )
        style = handle
        h = hi[2] - lo[2]
        style = replace(style, length=min(style.length, 0.8 * h))
        grip = lo[2] + (0.35 if h > 0.9 else 0.5) * h if op.z1 < 1.2 else lo[2] + 0.45 * h
        if op.z0 > 0.9 * height - 0.6:  # a top door: handle low on it
            grip = lo[2] + 0.3 * h
        return _door(
            door, lo, hi, side, style, upper, "metal", grip=grip if kind != "mini" else None
        )

    dstyle = sample_drawer_style(s, "drawer")

    below_door = max(gap, FRIDGE_DRAWER_GAP) / 2  # a drawer's gap to the door above it

    def drawer_part(op: Opening, top_gap: float) -> PartSpec:
        lo, hi = overlay_front(op, td, gap, (gap / 2, gap / 2, gap / 2, top_gap))
        return drawer(
            op,
            lo,
            hi,
            clear=gap,
            drawer_style=dstyle,
            handle=drawer_handle,
            look=looks.per_part(body, rng, 0.01),
            material="metal",
        )

    g = (gap / 2,) * 4
    if kind == "side_by_side":
        gm = free_edge_gap(
            gap, td, min(col_fracs) * width, cap=FRIDGE_MAX_GAP, margin=FRIDGE_GAP_MARGIN
        )
        gaps = (gm / 2, gm / 2, gap / 2, gap / 2)
        movable.append(door_part(ops[0][0], "left", gaps, dispenser=s.flag("dispenser", 0.7)))
        movable.append(door_part(ops[1][0], "right", gaps))
    elif kind == "french":
        top = ops[0][0]
        lo, hi = overlay_front(top, td, gap, g)
        ym = (lo[1] + hi[1]) / 2
        gm = free_edge_gap(
            gap, td, (hi[1] - lo[1]) / 2, cap=FRIDGE_MAX_GAP, margin=FRIDGE_GAP_MARGIN
        )
        for side, y0, y1 in (("left", top.y0, ym - gm / 2), ("right", ym + gm / 2, top.y1)):
            half = Opening(
                y0,
                y1,
                top.z0,
                top.z1,
                top.x_back,
                top.x_front,
                (
                    y0 if side == "right" else top.cover[0],
                    y1 if side == "left" else top.cover[1],
                    top.cover[2],
                    top.cover[3],
                ),
                (side == "left", side == "right", top.outer[2], top.outer[3]),
            )
            movable.append(
                door_part(
                    half,
                    side,
                    (0.0, 0.0, below_door, gap / 2),
                    dispenser=side == "left" and s.flag("dispenser", 0.3),
                )
            )
        for r, op in enumerate(ops[0][1:]):
            movable.append(drawer_part(op, below_door if r == 0 else gap / 2))
    elif kind == "bottom_freezer":
        if s.flag("freezer_drawer", 0.7):  # (door_part draws nothing from s)
            movable.append(door_part(ops[0][0], hinge, (*g[:2], below_door, g[3])))
            movable.append(drawer_part(ops[0][1], below_door))
        else:
            movable.append(door_part(ops[0][0], hinge, g))
            movable.append(door_part(ops[0][1], hinge, g))
    else:
        for op in ops[0]:
            movable.append(door_part(op, hinge, g))
    return base.spec("metal"), movable


# --------------------------------------------------------------------------- washing machine


def _front_loader(s: ParamSampler, dryer: bool) -> tuple[PartSpec, list[PartSpec]]:
    width = s.choice("nominal_w", (0.6, 0.686), p=(0.7, 0.3)) + s.uniform(
        "width_jitter", -0.005, 0.005
    )
    height = s.uniform("height", 0.84, 0.87) if width < 0.65 else s.uniform("height_us", 0.93, 0.99)
    depth = s.uniform("depth", 0.5, 0.66)
    finish = _finish(
        s,
        {
            "white": 0.55,
            "silver": 0.12,
            "slate": 0.1,
            "black": 0.1,
            "stainless": 0.08,
            "bisque": 0.05,
        },
    )
    body, _ = _looks(s, finish)
    control_h = s.uniform("control_h", 0.1, 0.16)
    plinth = s.uniform("plinth_h", 0.04, 0.09)
    prims, ops, t = _body(
        s,
        width,
        depth,
        height,
        col_fracs=[1.0],
        row_fracs=[[control_h, 1.0 - control_h]],
        plinth=plinth,
        kick_setback=0.0,
    )
    control, main = ops[0]
    base = Pieces(body)
    base.add(prims)
    rng = s.child_rng()
    base.add(fill_front(main, 0.02))
    panel = looks.tint(looks.BLACK_GLASS, rng) if s.flag("panel_dark", 0.35) else None
    x_face = control.x_front
    movable: list[PartSpec] = []
    has_drawer = not dryer and s.flag("detergent_drawer", 0.75)
    dy1 = control.y0 + s.uniform("drawer_w", 0.17, 0.25) if has_drawer else control.y0
    fill = fill_front(control, 0.02)
    if has_drawer:  # the panel right of the detergent drawer's opening
        fill = box(
            [control.x_front - 0.02, dy1, control.z0 - EPS],
            [control.x_front, control.y1 + EPS, control.z1 + EPS],
        )
    base.add(fill)
    if panel is not None:
        base.add(shapes.pane(dy1, control.y1, control.z0, control.z1, x_face, 0.001), panel)
    zc = (control.z0 + control.z1) / 2
    # right of the drawer: a display, the program knob, a row of buttons
    ya, yb = dy1 + 0.02, control.y1 - 0.02
    knob_r = min(0.38 * control.height, s.uniform("knob_r", 0.028, 0.04))
    knob_y = ya + s.uniform("knob_pos", 0.45, 0.7) * (yb - ya)
    knob_tone = 1 if s.flag("chrome_knob", 0.5) else (225, 225, 225)
    base.add(shapes.knobs(x_face + 0.001, [(knob_y, zc)], knob_r, 0.025), knob_tone)
    d1 = knob_y - knob_r - 0.025
    d0 = max(ya, d1 - 0.13)
    if d1 - d0 > 0.03:
        base.add(shapes.pane(d0, d1, zc - 0.02, zc + 0.02, x_face + 0.001), looks.DISPLAY)
    k0 = knob_y + knob_r + 0.015
    if yb - k0 > 0.03:
        buttons = shapes.keypad(
            k0, yb, zc - 0.015, zc + 0.015, x_face, s.integer("buttons", 2, 5), 1
        )
        base.add(buttons, (170, 170, 172))
    if has_drawer:
        op = Opening(
            control.y0,
            dy1,
            control.z0,
            control.z1,
            control.x_back,
            control.x_front,
            (control.cover[0], dy1, control.z0, control.z1),
            (True, False, False, False),
        )
        gap = 0.002
        lo = np.array([control.x_front + 0.001, control.y0 + gap, control.z0 + gap])
        hi = np.array([control.x_front + 0.02, dy1 - gap, control.z1 - gap])
        dh = _bar(s, "drawer_handle", ("recessed", "edge_pull"), (0.08, 0.12))
        dstyle = sample_drawer_style(s, "drawer")
        dstyle = replace(dstyle, back_clear=max(dstyle.back_clear, depth - 0.42))
        movable.append(
            drawer(
                op,
                lo,
                hi,
                clear=gap,
                drawer_style=dstyle,
                handle=dh,
                look=looks.per_part(body, rng, 0.01),
                material="plastic",
            )
        )
    # the drum opening (a dark gasket) and the round door in front of it
    zc = (main.z0 + main.z1) / 2 + s.uniform("door_dz", -0.02, 0.04)
    r = min(s.uniform("door_r", 0.19, 0.26), main.width / 2 - 0.03, (main.z1 - main.z0) / 2 - 0.015)
    gasket = cylinder([main.x_front + 0.0005, 0.0, zc], 0.8 * r, 0.001 + EPS, 0)
    base.add(gasket, (45, 45, 48))
    ring_colour = s.choice("ring", ("chrome", "white", "black", "grey"), p=(0.35, 0.3, 0.2, 0.15))
    ring = {
        "chrome": (205, 207, 210),
        "white": (238, 238, 236),
        "black": (30, 30, 32),
        "grey": (120, 122, 126),
    }[ring_colour]
    td = s.uniform("door_t", 0.035, 0.06)
    bulge = s.uniform("bulge_t", 0.01, 0.03)
    gap = 0.003
    x0 = main.x_front + 0.0015 + gap
    bowls = ((60, 72, 84), (58, 146, 160), (108, 138, 158), (36, 40, 46))
    glass = bowls[s.integer("bowl", 0, 3)] if not dryer else looks.tint(looks.GLASS["smoke"], rng)
    door = Pieces(looks.flat(looks.tint(ring, rng, 0.03), body.accent))
    door.add(
        cylinder(
            [x0 + td + bulge / 2 - EPS / 2, 0.0, zc],
            s.uniform("glass_frac", 0.62, 0.75) * r,
            bulge + EPS,
            0,
        ),
        looks.tint(glass, rng, 0.1),
    )
    door.add(
        cylinder([x0 + td + 0.001, 0.0, zc], 0.86 * r, 0.002 + EPS, 0),
        (22, 22, 24) if ring_colour != "black" else (90, 90, 92),
    )
    body_prims = [cylinder([x0 + td / 2, 0.0, zc], r, td, 0)]
    style = _bar(
        s,
        "handle",
        ("bar", "square_bar", "edge_pull"),
        (0.07, 0.13),
        radius=(0.008, 0.012),
        standoff=(0.015, 0.025),
    )
    style = replace(style, edge_margin=0.2 * r, length=min(style.length, 0.8 * r))
    lo, hi = np.array([x0, -r, zc - r]), np.array([x0 + td, r, zc + r])
    door_spec = hinged_panel(
        lo,
        hi,
        "left",
        handle=style,
        upper=s.uniform("door_upper", 1.4, 1.9),
        look=door.final_look(),
        material="plastic",
        grip_height=zc,
        extra=door.extra(),
        body=body_prims,
    )
    movable.append(door_spec)
    return base.spec("metal"), movable


def _top_loader(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    width = s.uniform("width", 0.6, 0.7)
    height = s.uniform("height", 0.88, 0.96)
    depth = s.uniform("depth", 0.6, 0.7)
    finish = _finish(s, {"white": 0.65, "silver": 0.1, "slate": 0.1, "black": 0.05, "bisque": 0.1})
    body, _ = _looks(s, finish)
    t = s.uniform("panel_t", 0.012, 0.02)
    console_d = s.uniform("console_d", 0.09, 0.15)
    console_h = s.uniform("console_h", 0.1, 0.2)
    xb, xf, yl, yr = -depth / 2, depth / 2, -width / 2, width / 2
    base = Pieces(body)
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
    hx0, hx1 = x_console + 0.04, xf - 0.06
    hy = width / 2 - 0.07
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
    rng = s.child_rng()
    tub_r = min(hy, (hx1 - hx0) / 2) - 0.01
    base.add(cylinder([(hx0 + hx1) / 2, 0.0, height - 0.2], tub_r, 0.4 - t, 2), (150, 152, 156))
    xf_c = x_console
    zc = height + console_h / 2
    panel = looks.tint(looks.BLACK_GLASS, rng) if s.flag("console_dark", 0.4) else None
    if panel is not None:
        base.add(
            box(
                [xf_c - EPS, yl + 0.02, height + 0.015],
                [xf_c + 0.001, yr - 0.02, height + console_h - 0.015],
            ),
            panel,
        )
    n = s.integer("n_knobs", 1, 3)
    ys = shapes.row(yl + 0.06, yr - 0.06, n + 1)
    mid = len(ys) // 2
    # knobs high on the console, clear of the open lid's thickness below them
    r = min(0.035, 0.3 * console_h, (console_h - 0.053) / 2)
    zk = height + console_h - 0.008 - r
    base.add(
        shapes.knobs(xf_c + 0.001, [(y, zk) for k, y in enumerate(ys) if k != mid], r, 0.025), 1
    )
    base.add(
        shapes.pane(ys[mid] - 0.06, ys[mid] + 0.06, zc - 0.02, zc + 0.02, xf_c + 0.001),
        looks.DISPLAY,
    )
    tl = s.uniform("lid_t", 0.02, 0.035)
    gap = 0.002
    side = s.uniform("lid_side_margin", 0.0, 0.015)
    # clear of the console by the lid's thickness: the lid's back edge swings back by it
    lo = np.array([x_console + tl + 0.003, yl + side, height + gap])
    hi = np.array([xf - s.uniform("lid_front_margin", 0.0, 0.03), yr - side, height + gap + tl])
    lid = Pieces(looks.per_part(body, rng, 0.01))
    if s.flag("glass_lid", 0.5):
        m = 0.06
        lid.add(
            box([lo[0] + m, lo[1] + m, hi[2] - EPS], [hi[0] - m - 0.03, hi[1] - m, hi[2] + 0.0015]),
            _glass(s),
        )
    handle = _bar(
        s,
        "handle",
        ("edge_pull", "recessed", "bar"),
        (0.12, 0.3),
        (0.5, 0.3, 0.2),
        standoff=(0.02, 0.03),
    )
    spec = hinged_panel(
        lo,
        hi,
        "back",
        handle=handle,
        upper=s.uniform("lid_upper", 1.2, 1.55),
        look=lid.final_look(),
        material="metal",
        semantic="lid",
        extra=lid.extra(),
    )
    return base.spec("metal"), [spec]


def washing_machine(s: ParamSampler) -> tuple[PartSpec, list[PartSpec]]:
    kind = s.choice("kind", list(WASHER_KINDS), p=list(WASHER_KINDS.values()))
    if kind == "top":
        return _top_loader(s)
    return _front_loader(s, dryer=kind == "dryer")
