"""Shared building blocks: carcasses with openings, drawers, hinged doors and lids, handles.

Conventions (object frame, metres): +z up, the front faces +x, "left" is -y (the
viewer's left when facing the front). A carcass spans x in [cx - D/2, cx + D/2]
with its front plane at cx + D/2; columns run left to right (ascending y), rows
top to bottom.

Fronts are either *inset* (inside the opening, flush with the front plane, with a
gap to the frame on every side) or *overlay* (in front of the front plane by a gap,
covering the opening and half of any interior divider). Every hinged panel pivots
about the edge of its FRONT face on the hinge side; with that pivot a panel never
passes behind its own back plane nor across its hinge-side edge while it opens,
and its free back corner moves sideways by at most t^2 / (2 L) (t thickness, L
width), which ``free_edge_gap`` adds to the gap on the free side.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from generator.articulated import Handle, Joint, Primitive
from generator.procedural.appearance import Look
from generator.procedural.assembly import PartSpec
from generator.procedural.sampling import ParamSampler
from generator.procedural.solids import EPS, box, cylinder

MAX_GAP = 3e-3  # m, largest clearance between a movable part and its neighbours
MIN_GAP = 1e-3  # m, smallest clearance


# --------------------------------------------------------------------------- carcass


@dataclass(frozen=True)
class Opening:
    """A front opening of a carcass compartment.

    ``y0, y1, z0, z1``: the clear opening in the front plane; ``x_back``: the front face
    of the back panel (the cavity's depth limit); ``x_front``: the carcass front plane.
    ``cover``: (y0, y1, z0, z1) limits an overlay front may reach (outer faces of the
    carcass, or the centre line of an interior divider); ``outer``: which of those four
    sides are outer edges of the carcass.
    """

    y0: float
    y1: float
    z0: float
    z1: float
    x_back: float
    x_front: float
    cover: tuple[float, float, float, float]
    outer: tuple[bool, bool, bool, bool]

    @property
    def width(self) -> float:
        return self.y1 - self.y0

    @property
    def height(self) -> float:
        return self.z1 - self.z0


def grid_carcass(
    *,
    width: float,
    depth: float,
    top_z: float,
    t: float,
    back_t: float,
    col_fracs: Sequence[float],
    row_fracs: Sequence[Sequence[float]],
    z0: float = 0.0,
    plinth: float = 0.0,
    kick_setback: float = 0.04,
    cx: float = 0.0,
    cy: float = 0.0,
) -> tuple[list[Primitive], list[list[Opening]]]:
    """A box carcass divided into a grid of open compartments.

    The carcass spans y in [cy - width/2, cy + width/2], x in [cx - depth/2, cx + depth/2]
    and z in [z0, top_z]; panels are ``t`` thick (back ``back_t``). Side panels reach down
    to ``z0``; the bottom panel sits ``plinth`` above it with a kick board set back by
    ``kick_setback`` below. ``col_fracs`` split the inner width into columns (left to
    right); ``row_fracs[c]`` split column c's inner height into rows (top to bottom).
    Returns the panel boxes and, per column, its openings top to bottom.
    """
    xb, xf = cx - depth / 2, cx + depth / 2
    ylo, yhi = cy - width / 2, cy + width / 2
    bottom_z = z0 + plinth
    prims = [
        box([xb, ylo, z0], [xf, ylo + t, top_z]),
        box([xb, yhi - t, z0], [xf, yhi, top_z]),
        box([xb, ylo, top_z - t], [xf, yhi, top_z]),
        box([xb, ylo, bottom_z], [xf, yhi, bottom_z + t]),
        box([xb, ylo, bottom_z], [xb + back_t, yhi, top_z]),
    ]
    if plinth > 0:
        kx = xf - kick_setback
        prims.append(box([kx - t, ylo, z0], [kx, yhi, bottom_z + EPS]))
    x_in = xb + back_t
    inner_lo, inner_hi = bottom_z + t, top_z - t
    n_cols = len(col_fracs)
    inner_w = (yhi - t) - (ylo + t) - (n_cols - 1) * t
    fr = np.asarray(col_fracs, dtype=float) / np.sum(col_fracs)
    openings: list[list[Opening]] = []
    y = ylo + t
    for c in range(n_cols):
        y_c0, y_c1 = y, y + fr[c] * inner_w
        if c < n_cols - 1:
            prims.append(box([x_in - EPS, y_c1, inner_lo - EPS], [xf, y_c1 + t, inner_hi + EPS]))
        rows = np.asarray(row_fracs[c], dtype=float) / np.sum(row_fracs[c])
        n_rows = len(rows)
        inner_h = inner_hi - inner_lo - (n_rows - 1) * t
        col_ops = []
        z = inner_hi
        for r in range(n_rows):
            z_r1, z_r0 = z, z - rows[r] * inner_h
            if r < n_rows - 1:
                prims.append(box([x_in - EPS, y_c0 - EPS, z_r0 - t], [xf, y_c1 + EPS, z_r0]))
            first_c, last_c, first_r, last_r = c == 0, c == n_cols - 1, r == 0, r == n_rows - 1
            col_ops.append(
                Opening(
                    y0=y_c0,
                    y1=y_c1,
                    z0=z_r0,
                    z1=z_r1,
                    x_back=x_in,
                    x_front=xf,
                    cover=(
                        ylo if first_c else y_c0 - t / 2,
                        yhi if last_c else y_c1 + t / 2,
                        bottom_z if last_r else z_r0 - t / 2,
                        top_z if first_r else z_r1 + t / 2,
                    ),
                    outer=(first_c, last_c, last_r, first_r),
                )
            )
            z = z_r0 - t
        openings.append(col_ops)
        y = y_c1 + t
    return prims, openings


def fill_front(op: Opening, depth: float) -> Primitive:
    """A solid block closing ``op`` over the front ``depth`` metres (control panels)."""
    return box(
        [op.x_front - depth, op.y0 - EPS, op.z0 - EPS], [op.x_front, op.y1 + EPS, op.z1 + EPS]
    )


def feet(xs: Sequence[float], ys: Sequence[float], height: float, radius: float) -> list[Primitive]:
    """Cylindrical feet (axis z) on the floor at every (x, y) of ``xs`` x ``ys``, reaching
    ``EPS`` into the body above."""
    h = height + EPS
    return [cylinder([x, y, h / 2], radius, h, 2) for x in xs for y in ys]


# --------------------------------------------------------------------------- handles


@dataclass(frozen=True)
class HandleStyle:
    """A handle design. ``kind``: "bar", "knob" or "recessed", or one of the shapes of
    realistic objects: "square_bar" (a bar of square section on square posts), "pipe"
    (a round bar on round posts: fridge and oven bars) and "edge_pull" (a flat lip
    standing straight out of the face). Metres: ``length`` of the
    bar (or recess) along its grip axis; ``radius`` of the bar or knob; ``standoff`` of
    the bar centre (or the knob's stem) from the front face; ``width`` of a recess across
    the grip axis; ``depth_frac`` recess depth / panel thickness (10-15 mm deep);
    ``edge_margin`` from a
    door's free edge to the grip line."""

    kind: str
    length: float
    radius: float
    standoff: float
    width: float
    depth_frac: float
    edge_margin: float


def sample_handle(
    s: ParamSampler,
    prefix: str,
    kinds: Sequence[str],
    length: tuple[float, float] = (0.10, 0.30),
    standoff: tuple[float, float] = (0.025, 0.040),
) -> HandleStyle:
    """Draw a ``HandleStyle``; parameters are recorded as ``<prefix>_<name>``."""
    kind = s.choice(f"{prefix}_kind", list(kinds))
    radius_range = (0.012, 0.018) if kind == "knob" else (0.006, 0.010)
    return HandleStyle(
        kind=kind,
        length=s.uniform(f"{prefix}_length", *length),
        radius=s.uniform(f"{prefix}_radius", *radius_range),
        standoff=s.uniform(f"{prefix}_standoff", *standoff),
        width=s.uniform(f"{prefix}_recess_width", 0.022, 0.035),
        depth_frac=s.uniform(f"{prefix}_recess_depth_frac", 0.40, 0.55),
        edge_margin=s.uniform(f"{prefix}_edge_margin", 0.025, 0.05),
    )


def _unit(axis: int) -> np.ndarray:
    e = np.zeros(3)
    e[axis] = 1.0
    return e


def slab_with_handle(
    lo: np.ndarray, hi: np.ndarray, normal: int, style: HandleStyle, grip: np.ndarray, along: int
) -> tuple[list[Primitive], list[Primitive], Handle]:
    """A front panel (box ``lo``..``hi`` whose front face is ``hi[normal]``) with a handle.

    ``grip`` (3,) is the handle's centre on the front face, ``along`` the axis of the
    bar / recess. Returns (panel boxes, handle trims, Handle): a bar is a cylinder on two
    posts, a knob a stem and a disc, a recess a pocket bridged by a flush grip bar
    (:func:`_recessed_pull`). The Handle position is the bar centre, the knob centre
    or the middle of the bridge.
    """
    across = 3 - normal - along
    n = _unit(normal)
    face = hi[normal]
    if style.kind == "recessed":
        return _recessed_pull(lo, hi, normal, style, grip, along)
    panel = [box(lo, hi)]
    if style.kind in _SHAPED_BARS:
        trims, position = _shaped_bar(style, grip, normal, along, face)
        return panel, trims, Handle(position=position, axis=_unit(along), kind="bar")
    if style.kind == "bar":
        centre = grip + n * style.standoff
        trims = [cylinder(centre, style.radius, style.length, along)]
        post = 1.6 * style.radius
        offset = style.length / 2 - max(0.012, 0.12 * style.length)
        for sign in (-1.0, 1.0):
            p_lo, p_hi = grip.copy(), grip.copy()
            p_lo[normal], p_hi[normal] = face - EPS, centre[normal]
            mid = grip[along] + sign * offset
            p_lo[along], p_hi[along] = mid - post / 2, mid + post / 2
            p_lo[across], p_hi[across] = grip[across] - post / 2, grip[across] + post / 2
            trims.append(box(p_lo, p_hi))
        return panel, trims, Handle(position=centre, axis=_unit(along), kind="bar")
    # knob: a stem and a disc, both along the normal
    thick = float(np.clip(1.1 * style.radius, 0.012, 0.018))
    stem_len = style.standoff * 0.6
    knob_centre = grip + n * (stem_len + thick / 2)
    trims = [
        cylinder(grip + n * stem_len / 2, 0.45 * style.radius, stem_len + 2 * EPS, normal),
        cylinder(knob_centre, style.radius, thick, normal),
    ]
    return panel, trims, Handle(position=knob_centre, axis=_unit(along), kind="knob")


_SHAPED_BARS = ("square_bar", "pipe", "edge_pull")


def _shaped_bar(
    style: HandleStyle, grip: np.ndarray, normal: int, along: int, face: float
) -> tuple[list[Primitive], np.ndarray]:
    """The trims of a "square_bar", "pipe" or "edge_pull" handle centred on ``grip`` (on
    the face) and the grasp point."""
    across = 3 - normal - along
    n = _unit(normal)
    if style.kind == "edge_pull":  # a flat lip: thin across, sticking out by the standoff
        lo, hi = grip.copy(), grip.copy()
        lo[normal], hi[normal] = face - EPS, face + style.standoff
        lo[along], hi[along] = grip[along] - style.length / 2, grip[along] + style.length / 2
        half = max(0.003, 0.5 * style.radius)
        lo[across], hi[across] = grip[across] - half, grip[across] + half
        return [box(lo, hi)], grip + n * style.standoff * 0.6
    centre = grip + n * style.standoff
    if style.kind == "square_bar":
        lo, hi = centre - style.radius, centre + style.radius
        lo[along], hi[along] = centre[along] - style.length / 2, centre[along] + style.length / 2
        trims = [box(lo, hi)]
    else:
        trims = [cylinder(centre, style.radius, style.length, along)]
    post = 1.4 * style.radius
    offset = style.length / 2 - max(0.015, 0.06 * style.length)
    for sign in (-1.0, 1.0):
        p = grip.copy()
        p[along] = grip[along] + sign * offset
        stem = style.standoff + EPS
        if style.kind == "pipe":
            trims.append(cylinder(p + n * (stem / 2 - EPS), 0.5 * post, stem, normal))
        else:
            lo, hi = p.copy(), p.copy()
            lo[normal], hi[normal] = face - EPS, centre[normal]
            lo[along], hi[along] = p[along] - post / 2, p[along] + post / 2
            lo[across], hi[across] = p[across] - post / 2, p[across] + post / 2
            trims.append(box(lo, hi))
    return trims, centre


#: Recessed pulls (m): pocket depth range, panel left behind the pocket, bridge width
#: (along the pocket), smallest pocket length and width (across).
RECESS_DEPTH = (0.010, 0.015)
RECESS_BACK = 0.004
RECESS_BRIDGE = 0.012
RECESS_MIN_LENGTH = 0.08
RECESS_MIN_WIDTH = 0.026


def _recessed_pull(
    lo: np.ndarray, hi: np.ndarray, normal: int, style: HandleStyle, grip: np.ndarray, along: int
) -> tuple[list[Primitive], list[Primitive], Handle]:
    """A recessed pull: a pocket cut into the panel, bridged at its middle by a grip bar
    flush with the front face (the bar of a flush ring pull or a sliding-door pull).

    A straight pocket gives a finger nothing to hook: the only surfaces that resist an
    outward pull face inward. The bridge does: two fingers (or a parallel gripper's
    fingertips, 15 x 17.5 mm) enter the pocket on either side of it and pinch or hook
    it. The pocket is ``style.length`` long along ``along`` (at least
    ``RECESS_MIN_LENGTH``, room for a fingertip on each side of the bridge),
    ``style.width`` wide across (at least ``RECESS_MIN_WIDTH``) and 10-15 mm deep
    (``depth_frac`` of the panel thickness, leaving ``RECESS_BACK`` behind it). The
    panel is seven boxes: four around the pocket, the back behind it and the bridge
    (reaching ``EPS`` into its neighbours). The Handle is the middle of the bridge,
    its axis the bridge's (across the pocket), so a gripper closes along the pocket.
    """
    across = 3 - normal - along
    n = _unit(normal)
    face = hi[normal]
    thick = hi[normal] - lo[normal]
    d = float(np.clip(style.depth_frac * thick, *RECESS_DEPTH))
    d = min(d, thick - RECESS_BACK)
    r_lo, r_hi = grip.copy(), grip.copy()
    r_lo[along] -= style.length / 2
    r_hi[along] += style.length / 2
    r_lo[across] -= style.width / 2
    r_hi[across] += style.width / 2
    panel = []
    for axis, side in ((across, 0), (across, 1), (along, 0), (along, 1)):
        b_lo, b_hi = lo.copy(), hi.copy()
        if side == 0:
            b_hi[axis] = r_lo[axis]
        else:
            b_lo[axis] = r_hi[axis]
        panel.append(box(b_lo, b_hi))
    back_hi = hi.copy()
    back_hi[normal] = face - d
    panel.append(box(lo, back_hi))
    g_lo, g_hi = r_lo.copy(), r_hi.copy()
    g_lo[along], g_hi[along] = grip[along] - RECESS_BRIDGE / 2, grip[along] + RECESS_BRIDGE / 2
    g_lo[across] -= EPS
    g_hi[across] += EPS
    g_lo[normal], g_hi[normal] = face - d - EPS, face
    panel.append(box(g_lo, g_hi))
    handle = Handle(position=grip - n * d / 2, axis=_unit(across), kind="recessed")
    return panel, [], handle


def _fit_handle(style: HandleStyle, extent_along: float, extent_across: float) -> HandleStyle:
    """``style`` shrunk to fit a panel of the given extents (m)."""
    length = min(style.length, 0.7 * extent_along)
    width = min(style.width, 0.5 * extent_across)
    if style.kind == "recessed":  # room for a fingertip on either side of the bridge
        length = min(max(length, RECESS_MIN_LENGTH), 0.7 * extent_along)
        width = min(max(width, RECESS_MIN_WIDTH), 0.5 * extent_across)
    return HandleStyle(
        style.kind, length, style.radius, style.standoff, width, style.depth_frac, style.edge_margin
    )


# --------------------------------------------------------------------------- fronts


def inset_front(op: Opening, t: float, gaps: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of a ``t``-thick front inside ``op``, flush with the front plane, leaving
    ``gaps`` = (y0, y1, z0, z1) clearances to the frame."""
    lo = np.array([op.x_front - t, op.y0 + gaps[0], op.z0 + gaps[2]])
    hi = np.array([op.x_front, op.y1 - gaps[1], op.z1 - gaps[3]])
    return lo, hi


def overlay_front(
    op: Opening, t: float, gap_x: float, gaps: Sequence[float]
) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of a ``t``-thick front ``gap_x`` in front of ``op``, reaching the cover
    limits: flush with the outer faces, and ``gaps`` short of interior divider centres."""
    c = op.cover
    y0 = c[0] if op.outer[0] else c[0] + gaps[0]
    y1 = c[1] if op.outer[1] else c[1] - gaps[1]
    z0 = c[2] if op.outer[2] else c[2] + gaps[2]
    z1 = c[3] if op.outer[3] else c[3] - gaps[3]
    lo = np.array([op.x_front + gap_x, y0, z0])
    hi = np.array([op.x_front + gap_x + t, y1, z1])
    return lo, hi


def free_edge_gap(
    gap: float, thickness: float, width: float, cap: float = MAX_GAP, margin: float = 5e-4
) -> float:
    """Clearance (m) on a hinged panel's free side: at least ``gap`` and enough for the
    panel's back corner, which swings out by thickness^2 / (2 width) near the front plane,
    plus ``margin``, up to ``cap`` (the 4-7 cm door of half a fridge's width swings
    2-7 mm)."""
    return float(min(cap, max(gap, thickness**2 / (2 * width) + margin)))


@dataclass(frozen=True)
class DrawerStyle:
    """Drawer box proportions: ``wall_t`` (m) box wall thickness; ``height_frac`` box
    height / opening height; ``back_clear`` (m) box back to the carcass back panel;
    ``range_frac`` travel / drawer depth (0.7..0.9)."""

    wall_t: float
    height_frac: float
    back_clear: float
    range_frac: float


def sample_drawer_style(s: ParamSampler, prefix: str) -> DrawerStyle:
    return DrawerStyle(
        wall_t=s.uniform(f"{prefix}_wall_t", 0.008, 0.012),
        height_frac=s.uniform(f"{prefix}_box_height_frac", 0.6, 0.85),
        back_clear=s.uniform(f"{prefix}_back_clear", 0.005, 0.03),
        range_frac=s.uniform(f"{prefix}_range_frac", 0.7, 0.9),
    )


def drawer(
    op: Opening,
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    clear: float,
    drawer_style: DrawerStyle,
    handle: HandleStyle,
    look: Look,
    material: str,
    handle_count: int = 1,
) -> PartSpec:
    """A drawer: front panel ``lo``..``hi`` (front face at ``hi[0]``) with its handle, and a
    box (four walls and a bottom) reaching into ``op`` with ``clear`` metres of clearance.

    Prismatic joint along +x, travel ``range_frac`` of the drawer depth (front face to
    box back), so the box stays engaged in the carcass when fully open.
    ``handle_count`` 2 puts two handles (not recessed) a quarter of the width in from
    either side (wide dresser drawers); the part's Handle is the left one.
    """
    ds = drawer_style
    xb, xf = lo[0], hi[0]
    yc = (lo[1] + hi[1]) / 2
    style = _fit_handle(handle, hi[1] - lo[1], hi[2] - lo[2])
    if style.kind == "recessed":
        zg = hi[2] - 0.012 - style.width / 2
    else:
        zg = lo[2] + (hi[2] - lo[2]) * (0.5 if hi[2] - lo[2] < 0.25 else 0.75)
    if handle_count == 2 and style.kind != "recessed":
        quarter = (hi[1] - lo[1]) / 4
        style = _fit_handle(handle, quarter * 1.6, hi[2] - lo[2])
        panel, trims, grip = slab_with_handle(
            lo, hi, 0, style, np.array([xf, yc - quarter, zg]), along=1
        )
        trims = (
            trims + slab_with_handle(lo, hi, 0, style, np.array([xf, yc + quarter, zg]), along=1)[1]
        )
    else:
        panel, trims, grip = slab_with_handle(lo, hi, 0, style, np.array([xf, yc, zg]), along=1)
    by0, by1 = max(lo[1], op.y0 + clear), min(hi[1], op.y1 - clear)
    bz0 = max(lo[2], op.z0 + clear)
    bz1 = bz0 + ds.height_frac * (op.z1 - clear - bz0)
    bx0 = op.x_back + ds.back_clear
    w = ds.wall_t
    walls = [
        box([xb - w, by0, bz0], [xb + EPS, by1, bz1]),  # inner front wall behind the panel
        box([bx0, by0, bz0], [bx0 + w, by1, bz1]),  # back wall
        box([bx0, by0, bz0], [xb + EPS, by0 + w, bz1]),  # left wall
        box([bx0, by1 - w, bz0], [xb + EPS, by1, bz1]),  # right wall
        box([bx0, by0, bz0], [xb + EPS, by1, bz0 + w]),  # bottom
    ]
    depth = xf - bx0
    spec = PartSpec(semantic="drawer", material=material, look=look.with_grain(1))
    spec.add(panel)
    spec.add(walls)
    spec.add(trims, accent=True)
    spec.joint = Joint(
        type="prismatic",
        origin=[xf, yc, (lo[2] + hi[2]) / 2],
        axis=[1.0, 0.0, 0.0],
        lower=0.0,
        upper=ds.range_frac * depth,
    )
    spec.handle = grip
    spec.order = ((lo[2] + hi[2]) / 2, yc)
    return spec


def hinged_panel(
    lo: np.ndarray,
    hi: np.ndarray,
    hinge: str,
    *,
    handle: HandleStyle,
    upper: float,
    look: Look,
    material: str,
    semantic: str = "door",
    grip_height: float = 1.0,
    extra: Sequence[tuple[Primitive, bool]] = (),
    body: Sequence[Primitive] | None = None,
) -> PartSpec:
    """A door or lid: panel ``lo``..``hi`` with a handle near its free edge, on a revolute
    joint about the hinge-side edge of its front face.

    ``hinge``: "left" (-y edge), "right" (+y), "top", "bottom" for fronts facing +x;
    "back" (-x edge) for a lid whose outer face is its top (+z). The axis sign is chosen
    so that a positive angle swings the free edge outward (+x, or +z for a lid).
    ``grip_height`` (m, absolute z) is where side-hinged handles are centred when the
    door is tall enough. ``extra``: further (primitive, is_accent) pieces of the part.
    ``body``: primitives replacing the box panel (a round door); ``lo``..``hi`` is then
    its bounding box and the handle must be a bar or a knob.
    """
    normal = 2 if hinge == "back" else 0
    n = _unit(normal)
    face = hi[normal]
    c = (lo + hi) / 2
    origin, free = c.copy(), c.copy()
    origin[normal] = free[normal] = face
    if hinge in ("left", "right"):
        edge_axis, along = 1, 2
    elif hinge in ("top", "bottom"):
        edge_axis, along = 2, 1
    elif hinge == "back":
        edge_axis, along = 0, 1
    else:
        raise ValueError(f"unknown hinge side {hinge!r}")
    at_lo = hinge in ("left", "bottom", "back")
    origin[edge_axis] = lo[edge_axis] if at_lo else hi[edge_axis]
    free[edge_axis] = hi[edge_axis] if at_lo else lo[edge_axis]
    axis = np.cross(free - origin, n)
    axis /= np.linalg.norm(axis)

    style = _fit_handle(handle, hi[along] - lo[along], hi[edge_axis] - lo[edge_axis])
    half_across = {
        "bar": 0.8 * style.radius,
        "knob": style.radius,
        "recessed": style.width / 2,
        "square_bar": style.radius,
        "pipe": style.radius,
        "edge_pull": 0.5 * style.radius,
    }
    margin = max(style.edge_margin, half_across[style.kind] + 0.012)
    margin = min(margin, 0.3 * (hi[edge_axis] - lo[edge_axis]))
    grip = c.copy()
    grip[normal] = face
    grip[edge_axis] = free[edge_axis] + (-margin if at_lo else margin)
    if hinge in ("left", "right"):
        half = style.length / 2 + 0.02
        z_lo, z_hi = lo[2] + half, hi[2] - half
        grip[2] = float(np.clip(grip_height, z_lo, z_hi)) if z_lo <= z_hi else c[2]
    panel, trims, grip_handle = slab_with_handle(lo, hi, normal, style, grip, along)
    if body is not None:
        if style.kind == "recessed":
            raise ValueError("a recessed handle needs a box panel")
        panel = list(body)
    spec = PartSpec(semantic=semantic, material=material, look=look.with_grain(along))
    spec.add(panel)
    spec.add(trims, accent=True)
    for prim, is_accent in extra:
        spec.add([prim], accent=is_accent)
    spec.joint = Joint(type="revolute", origin=origin, axis=axis, lower=0.0, upper=float(upper))
    spec.handle = grip_handle
    spec.order = (float(c[2]), float(c[1]))
    return spec
