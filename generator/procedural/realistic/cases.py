"""A case piece of furniture: a carcass split into columns of cells, each cell closed by
a drawer, a door, a pair of doors, a flap, a fixed (false) front, or left open.

Shared by the realistic cabinets, dressers, nightstands, sideboards, desk pedestals and
kitchen islands. The carcass is ``blocks.grid_carcass``; fronts are the shared
``blocks.drawer`` and ``blocks.hinged_panel`` with overlay or inset fronts, flat slabs,
shaker frames or glazed frames (a pane in the glass tone), and their handles.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from generator.articulated import Primitive
from generator.procedural.appearance import RGB, Look
from generator.procedural.assembly import PartSpec
from generator.procedural.blocks import (
    DrawerStyle,
    HandleStyle,
    Opening,
    drawer,
    free_edge_gap,
    grid_carcass,
    hinged_panel,
    inset_front,
    overlay_front,
    sample_drawer_style,
    sample_handle,
)
from generator.procedural.realistic import looks, shapes
from generator.procedural.sampling import ParamSampler
from generator.procedural.solids import EPS, box

#: Cell kinds; the hinged ones name their hinge side as the viewer sees it.
CELL_KINDS = (
    "drawer",
    "door_left",
    "door_right",
    "pair",
    "flap_top",
    "flap_bottom",
    "open",
    "false_front",
)


@dataclass(frozen=True)
class Cell:
    """One compartment of a column: its ``kind`` and its height ``weight`` (relative to
    the column's other cells); ``handles`` per drawer front (1 or 2)."""

    kind: str
    weight: float = 1.0
    handles: int = 1


@dataclass
class Tones:
    """The further tones of one part's look, added as they are needed."""

    colours: list[RGB] = field(default_factory=list)

    def __call__(self, colour: RGB) -> int:
        if colour not in self.colours:
            self.colours.append(colour)
        return 2 + self.colours.index(colour)

    def apply(self, look: Look) -> Look:
        return replace(look, tones=tuple(self.colours))


@dataclass
class FrontStyle:
    """How the fronts of a case look and open.

    ``front``: "overlay" (in front of the carcass, covering its edges) or "inset";
    ``door``: "slab", "shaker" (a proud frame ``rail`` wide, ``frame_depth`` deep) or
    "glass" (the frame around a pane of ``glass``); ``grip_z``: the absolute height
    (m) of side-hinged doors' handles (clipped to each door)."""

    handle: HandleStyle
    drawer_handle: HandleStyle
    drawer_style: DrawerStyle
    body: Look
    front: Look
    material: str = "wood"
    overlay: bool = True
    door: str = "slab"
    tf: float = 0.019
    gap: float = 0.002
    rail: float = 0.06
    frame_depth: float = 0.006
    glass: RGB = (150, 164, 168)
    grip_z: float = 1.0
    drawer_frames: bool = False
    upper: float = 1.8


FURNITURE_HANDLES = ("bar", "square_bar", "knob", "edge_pull", "recessed")


def sample_front_style(
    s: ParamSampler,
    body: Look,
    front: Look,
    *,
    handle_kinds: Sequence[str] = FURNITURE_HANDLES,
    handle_p: Sequence[float] | None = None,
    doors: Sequence[str] = ("slab", "shaker"),
    door_p: Sequence[float] | None = None,
    overlay_p: float = 0.7,
    material: str = "wood",
) -> FrontStyle:
    """Draw the fronts of a case: handle shapes, door style, overlay or inset."""
    kind = s.choice("handle_shape", list(handle_kinds), p=handle_p)
    door = s.choice("door_style", list(doors), p=door_p)
    if door != "slab" and kind == "recessed":
        kind = "bar"
    handle = sample_handle(s, "handle", (kind,), length=(0.09, 0.32))
    drawer_kind = (
        kind
        if s.flag("drawer_same_handle", 0.75)
        else s.choice(
            "drawer_handle_shape", [k for k in handle_kinds if k != "recessed" or door == "slab"]
        )
    )
    drawer_handle = sample_handle(s, "drawer_handle", (drawer_kind,), length=(0.08, 0.3))
    return FrontStyle(
        handle=handle,
        drawer_handle=drawer_handle,
        drawer_style=sample_drawer_style(s, "drawer"),
        body=body,
        front=front,
        material=material,
        overlay=s.flag("overlay", overlay_p),
        door=door,
        tf=s.uniform("front_t", 0.016, 0.022),
        gap=s.uniform("gap", 0.0015, 0.003),
        rail=s.uniform("rail", 0.045, 0.075),
        frame_depth=s.uniform("frame_depth", 0.004, 0.008),
        glass=looks.tint((150, 164, 168), s.child_rng(), 0.15, 0.04),
        drawer_frames=door != "slab" and s.flag("drawer_frames", 0.6),
        upper=s.uniform("door_upper", 1.5, 2.0),
    )


def _front_box(
    op: Opening, style: FrontStyle, gaps: Sequence[float]
) -> tuple[np.ndarray, np.ndarray]:
    if style.overlay:
        return overlay_front(op, style.tf, style.gap, gaps)
    return inset_front(op, style.tf, gaps)


def _door_extras(
    lo: np.ndarray, hi: np.ndarray, style: FrontStyle, tones: Tones, frames: bool = True
) -> list[tuple[Primitive, int]]:
    """Frame (and pane) pieces on the face of a front ``lo``..``hi``."""
    if style.door == "slab" or not frames:
        return []
    y0, y1, z0, z1 = lo[1], hi[1], lo[2], hi[2]
    rail = min(style.rail, 0.22 * (y1 - y0), 0.22 * (z1 - z0))
    out: list[tuple[Primitive, int]] = [
        (p, 0) for p in shapes.frame_on_face(y0, y1, z0, z1, hi[0], rail, style.frame_depth)
    ]
    if style.door == "glass":
        out.append(
            (
                shapes.pane(
                    y0 + rail - EPS, y1 - rail + EPS, z0 + rail - EPS, z1 - rail + EPS, hi[0]
                ),
                tones(style.glass),
            )
        )
    return out


def _hinged(
    lo: np.ndarray,
    hi: np.ndarray,
    hinge: str,
    style: FrontStyle,
    upper: float,
    rng: np.random.Generator,
) -> PartSpec:
    tones = Tones()
    extra = _door_extras(lo, hi, style, tones)
    look = tones.apply(looks.per_part(style.front, rng))
    return hinged_panel(
        lo,
        hi,
        hinge,
        handle=style.handle,
        upper=upper,
        look=look,
        material=style.material,
        grip_height=style.grip_z,
        extra=extra,
    )


def cell_fronts(
    s: ParamSampler,
    name: str,
    cell: Cell,
    op: Opening,
    style: FrontStyle,
    rng: np.random.Generator,
    at_outer: tuple[bool, bool],
) -> tuple[list[PartSpec], list[tuple[Primitive, int]]]:
    """The movable fronts of one cell and any fixed pieces it adds to the base.

    ``at_outer``: whether the cell's left / right edges are outer edges of the carcass
    (a door hinged there may open further than one hinged on a divider)."""
    g = style.gap / 2 if style.overlay else style.gap
    fixed: list[tuple[Primitive, int]] = []
    if cell.kind == "open":
        return [], fixed
    if cell.kind == "false_front":
        lo, hi = _front_box(op, style, (g,) * 4)
        fixed.append((box(lo, hi), 0))
        return [], fixed
    if cell.kind == "drawer":
        lo, hi = _front_box(op, style, (g,) * 4)
        tones = Tones()
        extra = (
            _door_extras(lo, hi, replace(style, door="shaker", rail=0.6 * style.rail), tones)
            if style.drawer_frames and hi[2] - lo[2] > 0.12
            else []
        )
        spec = drawer(
            op,
            lo,
            hi,
            clear=style.gap,
            drawer_style=style.drawer_style,
            handle=style.drawer_handle,
            look=tones.apply(looks.per_part(style.front, rng)),
            material=style.material,
            handle_count=cell.handles,
        )
        for prim, tone in extra:
            spec.add([prim], accent=tone)
        return [spec], fixed
    inner_upper = min(style.upper, 1.75)
    if cell.kind == "pair":
        lo, hi = _front_box(op, style, (g,) * 4)
        half = (hi[1] - lo[1]) / 2
        gm = free_edge_gap(style.gap, style.tf, half)
        ym = (lo[1] + hi[1]) / 2
        left_hi, right_lo = hi.copy(), lo.copy()
        left_hi[1], right_lo[1] = ym - gm / 2, ym + gm / 2
        return [
            _hinged(lo, left_hi, "left", style, style.upper if at_outer[0] else inner_upper, rng),
            _hinged(right_lo, hi, "right", style, style.upper if at_outer[1] else inner_upper, rng),
        ], fixed
    if cell.kind in ("door_left", "door_right"):
        hinge = cell.kind.removeprefix("door_")
        width = op.width
        gf = free_edge_gap(style.gap, style.tf, width) if not style.overlay else g
        gaps = (g, gf, g, g) if hinge == "left" else (gf, g, g, g)
        lo, hi = _front_box(op, style, gaps)
        outer = at_outer[0] if hinge == "left" else at_outer[1]
        return [_hinged(lo, hi, hinge, style, style.upper if outer else inner_upper, rng)], fixed
    if cell.kind in ("flap_top", "flap_bottom"):
        hinge = cell.kind.removeprefix("flap_")
        lo, hi = _front_box(op, style, (g,) * 4)
        upper = s.uniform(f"{name}_flap_upper", 1.2, 1.57)
        return [_hinged(lo, hi, hinge, style, upper, rng)], fixed
    raise ValueError(f"unknown cell kind {cell.kind!r}; kinds: {', '.join(CELL_KINDS)}")


@dataclass
class Carcass:
    """Geometry of a case: ``width`` x ``depth``, from ``z0`` (the sides' bottom) to
    ``top_z``, panels ``t`` thick (back ``back_t``), the bottom ``plinth`` above ``z0``
    with a kick board ``kick_setback`` behind the front, centred at (``cx``, ``cy``)."""

    width: float
    depth: float
    top_z: float
    t: float = 0.018
    back_t: float = 0.006
    z0: float = 0.0
    plinth: float = 0.0
    kick_setback: float = 0.04
    cx: float = 0.0
    cy: float = 0.0


def build_case(
    s: ParamSampler,
    prefix: str,
    carcass: Carcass,
    columns: Sequence[tuple[float, Sequence[Cell]]],
    style: FrontStyle,
    rng: np.random.Generator,
    shelves: bool = True,
) -> tuple[list[tuple[Primitive, int]], list[PartSpec]]:
    """The carcass pieces (with their tones: 0 body) and the movable fronts of a case.

    ``columns``: (width weight, cells top to bottom) left to right. Door cells taller
    than 0.5 m get an inner shelf (``shelves``)."""
    c = carcass
    prims, openings = grid_carcass(
        width=c.width,
        depth=c.depth,
        top_z=c.top_z,
        t=c.t,
        back_t=c.back_t,
        col_fracs=[w for w, _ in columns],
        row_fracs=[[cell.weight for cell in cells] for _, cells in columns],
        z0=c.z0,
        plinth=c.plinth,
        kick_setback=c.kick_setback,
        cx=c.cx,
        cy=c.cy,
    )
    fixed: list[tuple[Primitive, int]] = [(p, 0) for p in prims]
    movable: list[PartSpec] = []
    n = len(columns)
    for ci, ((_, cells), ops) in enumerate(zip(columns, openings, strict=True)):
        for ri, (cell, op) in enumerate(zip(cells, ops, strict=True)):
            specs, extra = cell_fronts(
                s, f"{prefix}_c{ci}r{ri}", cell, op, style, rng, (ci == 0, ci == n - 1)
            )
            movable.extend(specs)
            fixed.extend(extra)
            if shelves and cell.kind not in ("drawer", "false_front") and op.height > 0.5:
                k = int(op.height // 0.35)
                for j in range(1, k + 1):
                    zs = op.z0 + j * op.height / (k + 1)
                    fixed.append(
                        (
                            box(
                                [op.x_back - EPS, op.y0 - EPS, zs - c.t / 2],
                                [op.x_front - 0.03, op.y1 + EPS, zs + c.t / 2],
                            ),
                            0,
                        )
                    )
    return fixed, movable


def top_slab(
    carcass: Carcass, thickness: float, front: float, side: float, back: float
) -> Primitive:
    """A top (or countertop) on the carcass, overhanging by ``front``, ``side``, ``back``."""
    c = carcass
    return box(  # on the carcass's top face: overlay fronts reach up to it, never into it
        [c.cx - c.depth / 2 - back, c.cy - c.width / 2 - side, c.top_z],
        [c.cx + c.depth / 2 + front, c.cy + c.width / 2 + side, c.top_z + thickness],
    )


def base_spec(
    pieces: Sequence[tuple[Primitive, int]], look: Look, tones: Tones, material: str
) -> PartSpec:
    """The base part from (primitive, tone) pieces."""
    spec = PartSpec(semantic="base", material=material, look=tones.apply(look))
    for prim, tone in pieces:
        spec.add([prim], accent=tone)
    return spec


@dataclass
class Pieces:
    """Primitives of one part with their tones, collected as a builder goes; a tone is 0
    (body), 1 (accent) or a colour (a further tone of the part's look)."""

    look: Look
    items: list[tuple[Primitive, int]] = field(default_factory=list)
    tones: Tones = field(default_factory=Tones)

    def add(self, prims: Sequence[Primitive] | Primitive, tone: int | RGB = 0) -> None:
        index = tone if isinstance(tone, int) else self.tones(tuple(tone))
        for p in [prims] if isinstance(prims, Primitive) else prims:
            self.items.append((p, index))

    def extra(self) -> list[tuple[Primitive, int]]:
        """The pieces as ``hinged_panel``'s ``extra``."""
        return list(self.items)

    def final_look(self) -> Look:
        return self.tones.apply(self.look)

    def spec(self, material: str, semantic: str = "base") -> PartSpec:
        spec = PartSpec(semantic=semantic, material=material, look=self.final_look())
        for prim, tone in self.items:
            spec.add([prim], accent=tone)
        return spec
