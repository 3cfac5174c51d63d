"""Box layout: collision boxes and joints that a simulator can move without collisions.

A generated object (PAct, the stage-1 generator) has free-form part meshes: adjacent
parts interpenetrate by a voxel or two, a drawer's mesh reaches into its neighbour's
slide path, the base fills the drawer's cavity and predicted axes are a few degrees off.
Decomposed as they are (CoACD), such parts jam, collide at rest and knock the base
over in SAPIEN. :func:`fit_box_layout` gives every part an exact box geometry for
collision (``Part.primitives``) and joints consistent with it, keeping the generated
meshes as the visuals:

1. Each movable part gets the axis-aligned box of the bulk of its mesh
   (:func:`robust_bounds`), lifted off the floor by ``clearance``, cut off
   ``BACK_WALL`` of the object's depth short of its back and brought flush with the
   object's face when recessed by up to ``FLUSH`` of the depth; a drawer reaches at
   least ``DRAWER_BODY`` of the depth back from its front. Its joint axis snaps
   to the nearest of the frame's axes (furniture and appliances are axis-aligned in the
   object frame: front +x, z up). A part's *outward normal* is the side it opens toward:
   for a prismatic part its axis, for a revolute part the axis across the hinge along
   which its box is thinnest (a door's face), for a lid's strip (``LID_STRIP``) up; signed
   toward the object's outer face the part is clearly nearer to (else +: fronts face
   +x, lids open upward).
2. Two movable parts whose sweeps over their ranges meet (a box holding each part over
   its range: a drawer slid out by its depth, a door's width out of its face) are
   shrunk apart along an axis that is neither one's outward normal (so no part stands
   in another's path), where their boxes overlap least among the axes that leave both
   faces at least ``MIN_FACE_M`` wide (else where the narrower stays widest): split at
   the middle of the overlap with a gap of ``clearance``, or, when one box contains the
   other along that axis, the outer one trimmed to its larger side. A revolute part's free edge sweeps
   ``sqrt(t^2 + w^2) - w`` past its box (thickness t, width w); that is added to the
   gap on its free side. Shrinking a box from its hinge side moves the hinge and can
   grow a thick door's sweep, so the pass over the pairs is repeated until no pair's
   sweeps meet (at most ``SEPARATION_PASSES``).
3. A revolute hinge goes on the box's outer face, on the lateral edge nearest the
   predicted origin (the paper projects origins onto the box surface; this picks the
   edge), its axis signed so a positive angle swings the free edge outward; the range is
   [0, min(upper, pi/2)] (past 90 degrees a door sweeps in front of its neighbours),
   less when its handle would otherwise swing past the hinge plane. A prismatic range
   is [0, min(upper, 0.9 x depth)]: an open drawer stays engaged.
4. The base is the bounding box of all parts minus one cavity per movable part: its
   box grown by ``clearance`` (and a free edge's bulge) sideways and from its inner
   face out through the base's outer face. The solid cells of that grid are merged
   greedily into boxes.
5. Fixed parts are merged into the base, and so is a movable part whose box ends up
   thinner than ``MIN_SIZE_M`` or with a face narrower than ``MIN_FACE_M`` (nothing a
   gripper could open; its cavity is not cut). A face narrower than that along one side
   only, and at least twice as wide along the other (a shallow drawer the generator's
   grid draws a voxel or two tall), is first widened to ``MIN_FACE_M`` about its middle
   (before step 2).
6. A part that opens toward +x, +y or +z and has no modelled handle gets the procedural
   factory's bar handle (``HANDLE_M``): centred on a drawer's face along its longer
   side, on a door parallel to the hinge near the free edge. The bar is part of the
   collision geometry, the visual mesh and ``Part.handle`` (a gripper cannot pull a
   bare face).

Every part is then a union of convex boxes that do not overlap at rest, while sliding
or swinging (the arguments above), or when all parts are open; the validator
(:mod:`asset_pipeline.validate`) checks exactly that in SAPIEN.
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass

import numpy as np
import trimesh

from generator.articulated import ArticulatedObject, Joint, Part
from generator.procedural.blocks import HandleStyle, slab_with_handle
from generator.procedural.solids import box

log = logging.getLogger(__name__)

#: Gap (m) between neighbouring movable parts and between a part and its cavity.
CLEARANCE_M = 0.004
#: Gap in generator units when the object's metric scale is unknown (about 5 mm on a
#: 1.2 m cabinet).
CLEARANCE_UNITS = 0.004
#: Passes over the pairs of movable parts while some pair's sweeps still meet.
SEPARATION_PASSES = 6
#: Base boxes thinner than this (m) are dropped (slivers between neighbouring cavities).
SLIVER_M = 0.002
#: A movable box thinner than this (m) after separation is no part...
MIN_SIZE_M = 0.01
#: ... nor is one whose face (across its outward normal) is narrower than this (m).
MIN_FACE_M = 0.05
#: Quantile trimmed off each side of a part's surface samples when fitting its box.
TRIM = 0.03
#: The base keeps a back wall of this fraction of its depth behind every moving part
#: (a drawer's mesh often spans the whole depth; with the wall the base's mass sits
#: behind the drawers, as in real furniture, and opening moves them away from it).
BACK_WALL = 0.1
#: A front recessed by up to this fraction of the depth is brought flush with the
#: object's face (a handle or a worktop's overhang sets that face on generated objects;
#: a drawer centred in the depth would not visibly move away from the base, a door
#: sunk in a pocket is out of a gripper's reach).
FLUSH = 0.5
#: A drawer's box reaches at least this fraction of the object's depth back from its
#: front: a drawer front alone, a panel the head calls a drawer, would otherwise slide out
#: of its slot within a few centimetres (at its limit, less of it than the validation's
#: ``drawer_engaged`` wants stays inside the base). Real drawers reach most of the way
#: back (0.82 of the depth on the real dev split, median) and the generated drawer's
#: visual gets this body too (``generator.pact.inference.generate.drawer_body``).
DRAWER_BODY = 0.75
#: A bar handle on every part without one (m): length, radius, standoff of the bar's
#: axis from the face, and (doors) its distance from the free edge.
HANDLE_M = (0.12, 0.008, 0.03, 0.035)
HANDLE_COLOR = np.array([60, 60, 60, 255], dtype=np.uint8)
#: Largest opening angle of a revolute part (rad).
MAX_SWING = math.pi / 2
#: Fraction of its depth a drawer may slide out.
MAX_SLIDE = 0.9


#: A lid (``Part.semantic``) drawn thinner in depth than in height and at most this
#: share of the object's height tall is the strip of a top lid that the photo shows
#: along the top of the front: it hinges on the back edge of its top and opens upward.
#: A taller one is drawn as a front panel and hinges as one, at its top edge, where its
#: handle has the lever to lift it. On the 12 lid photos of the parser's procedural val
#: renders (3 objects, converted with their masks alone), when a given lid was still cut
#: to a door's front slab, the strips were 0.01-0.17 of the height and the panels
#: 0.26-0.39, and 10 of them validated against 5 with every lid hinged as its thinnest
#: side says. A given lid is now the top of what was drawn (``generate.lid_panel``), so
#: this rule is for the strips PAct itself draws.
LID_STRIP = 0.2


@dataclass
class _Movable:
    part: Part
    lo: np.ndarray
    hi: np.ndarray
    normal_axis: int  # index of the outward normal's axis
    normal_sign: float  # +1 / -1
    hinge_axis: int | None = None  # revolute: index of the hinge axis
    hinge_side: float = 0.0  # revolute: +1 hinge on the box's high side along lateral_axis

    @property
    def lateral_axis(self) -> int | None:
        if self.hinge_axis is None:
            return None
        return 3 - self.normal_axis - self.hinge_axis


def _nearest_axis(v: np.ndarray) -> int:
    """Index of the frame axis nearest a direction (either sign)."""
    return int(np.argmax(np.abs(v)))


def _unit(i: int, sign: float = 1.0) -> np.ndarray:
    e = np.zeros(3)
    e[i] = sign
    return e


def _swing_bulge(m: _Movable) -> float:
    """How far past its box a revolute part's free edge sweeps (sqrt(t^2 + w^2) - w)."""
    if m.hinge_axis is None:
        return 0.0
    t = float(m.hi[m.normal_axis] - m.lo[m.normal_axis])
    w = float(m.hi[m.lateral_axis] - m.lo[m.lateral_axis])  # type: ignore[index]
    return math.hypot(t, w) - w


def _add_bulge(m: _Movable, lo: np.ndarray, hi: np.ndarray) -> None:
    """Grow ``lo``/``hi`` (in place) on a revolute part's free side by its bulge."""
    if m.hinge_axis is None:
        return
    lat = m.lateral_axis
    assert lat is not None
    if m.hinge_side > 0:
        lo[lat] -= _swing_bulge(m)
    else:
        hi[lat] += _swing_bulge(m)


def robust_bounds(mesh: trimesh.Trimesh, trim: float = TRIM, samples: int = 4096) -> np.ndarray:
    """(2, 3) box of the bulk of a mesh's surface: the ``trim`` and ``1 - trim``
    quantiles of area-uniform surface samples per axis (a generated part's stray
    fragments do not stretch it; a clean box loses about ``trim`` of its extent)."""
    if len(mesh.faces) == 0:
        return np.array(mesh.bounds, float)
    pts, _ = trimesh.sample.sample_surface(mesh, samples, seed=0)
    return np.quantile(pts, [trim, 1.0 - trim], axis=0)


def _outward_sign(i: int, lo: np.ndarray, hi: np.ndarray, outer: np.ndarray) -> float:
    """The side (+1 / -1) of axis ``i`` on which the part is nearer the object's outer
    face by more than a quarter of the object's extent; else +1: by the frame
    convention fronts face +x and lids open upward, +z (a generated drawer often spans
    the whole depth, and a handle or a plinth moves the front face)."""
    to_high, to_low = outer[1, i] - hi[i], lo[i] - outer[0, i]
    if abs(to_high - to_low) <= 0.25 * (outer[1, i] - outer[0, i]):
        return 1.0
    return 1.0 if to_high < to_low else -1.0


def _classify(part: Part, bounds: np.ndarray, outer: np.ndarray) -> _Movable:
    """The part with its box ``bounds`` (2, 3), its outward normal and (revolute) hinge."""
    j = part.joint
    assert j is not None and j.movable
    lo, hi = (np.array(b, float) for b in bounds)
    if j.type == "prismatic":
        i = _nearest_axis(j.axis)
        return _Movable(part, lo, hi, i, _outward_sign(i, lo, hi, outer))
    h = _nearest_axis(j.axis)
    others = [k for k in range(3) if k != h]
    if (
        part.semantic == "lid"
        and h != 2
        and hi[2] - lo[2] <= LID_STRIP * (outer[1, 2] - outer[0, 2])
    ):
        # a lid lies on top and opens upward: a top-loader's lid that the photo shows
        # only as a strip along the front is drawn thinner in depth than in height, and
        # as a front flap hinged at its top edge it would fall open
        n, sign = 2, 1.0
    else:
        n = min(others, key=lambda k: hi[k] - lo[k])  # the face: thinnest across the hinge
        sign = _outward_sign(n, lo, hi, outer)
    lat = 3 - n - h  # the hinge goes on the box edge nearest the predicted origin
    side = 1.0 if abs(j.origin[lat] - hi[lat]) < abs(j.origin[lat] - lo[lat]) else -1.0
    return _Movable(part, lo, hi, n, sign, hinge_axis=h, hinge_side=side)


def _swept(m: _Movable) -> tuple[np.ndarray, np.ndarray]:
    """A box holding the part over its whole range: a prismatic part slides out by at
    most its depth; a revolute part reaches its width out of its face and its free edge
    bulges sideways."""
    lo, hi = m.lo.copy(), m.hi.copy()
    n = m.normal_axis
    across = n if m.hinge_axis is None else m.lateral_axis  # the extent that sweeps out
    reach = hi[across] - lo[across]
    _add_bulge(m, lo, hi)
    if m.normal_sign > 0:
        hi[n] += reach
    else:
        lo[n] -= reach
    return lo, hi


def _split(a: _Movable, b: _Movable, k: int, gap: float) -> tuple[tuple[float, float], ...]:
    """New extents along axis ``k`` of ``a`` and ``b`` that put ``gap`` (plus a free
    edge's bulge) between them: the outer box trimmed to its larger side when one
    contains the other along ``k``, else a cut at the middle of the overlap."""
    first, second = (a, b) if (a.lo[k] + a.hi[k]) <= (b.lo[k] + b.hi[k]) else (b, a)
    g = gap
    for m, side in ((first, 1.0), (second, -1.0)):  # the free edge's bulge on that side
        if m.lateral_axis == k and m.hinge_side != side:
            g += _swing_bulge(m)
    new = {id(m): (float(m.lo[k]), float(m.hi[k])) for m in (a, b)}
    for outer, inner in ((a, b), (b, a)):
        if outer.lo[k] <= inner.lo[k] and inner.hi[k] <= outer.hi[k]:
            if inner.lo[k] - outer.lo[k] >= outer.hi[k] - inner.hi[k]:
                new[id(outer)] = (float(outer.lo[k]), float(inner.lo[k] - g))
            else:
                new[id(outer)] = (float(inner.hi[k] + g), float(outer.hi[k]))
            return new[id(a)], new[id(b)]
    mid = (first.hi[k] + second.lo[k]) / 2  # the middle of the overlap
    new[id(first)] = (float(first.lo[k]), float(min(first.hi[k], mid - g / 2)))
    new[id(second)] = (float(max(second.lo[k], mid + g / 2)), float(second.hi[k]))
    return new[id(a)], new[id(b)]


def _separate(a: _Movable, b: _Movable, gap: float, min_face: float) -> bool:
    """Shrink two boxes whose sweeps meet apart (in place), along an axis that is neither
    one's outward normal: where they overlap least among the axes that leave both faces
    at least ``min_face`` wide, else where the narrower one stays widest. Returns whether
    they had to be shrunk."""
    (alo, ahi), (blo, bhi) = _swept(a), _swept(b)
    if np.any(np.minimum(ahi, bhi) - np.maximum(alo, blo) <= -gap * (1 - 1e-6)):
        return False  # their sweeps stay apart by at least the gap along some axis
    overlap = np.minimum(a.hi, b.hi) - np.maximum(a.lo, b.lo)
    allowed = [k for k in range(3) if k not in (a.normal_axis, b.normal_axis)]
    splits = {k: _split(a, b, k, gap) for k in allowed}
    narrowest = {k: min(hi - lo for lo, hi in splits[k]) for k in allowed}
    feasible = [k for k in allowed if narrowest[k] >= min_face]
    if feasible:
        k = min(feasible, key=lambda k: overlap[k])
    else:
        k = max(allowed, key=lambda k: narrowest[k])
    (a.lo[k], a.hi[k]), (b.lo[k], b.hi[k]) = splits[k]
    return True


def _widen_shallow_front(m: _Movable, min_face: float, outer: np.ndarray) -> None:
    """A face narrower than ``min_face`` along one side but at least twice that wide
    along the other (a shallow drawer, a flap: a part of the photo's mask that the
    generator's grid draws a voxel or two tall) is widened to ``min_face`` about its
    middle along the narrow side, inside the object's outer box (in place). A face
    narrow both ways (knob-sized) is left for the size check to merge."""
    lateral = [k for k in range(3) if k != m.normal_axis]
    size = m.hi - m.lo
    narrow = [k for k in lateral if size[k] < min_face]
    if len(narrow) != 1:
        return
    k = narrow[0]
    wide = lateral[1 - lateral.index(k)]
    if size[wide] < 2 * min_face or size[k] <= 0:
        return
    mid = float(
        np.clip((m.lo[k] + m.hi[k]) / 2, outer[0, k] + min_face / 2, outer[1, k] - min_face / 2)
    )
    m.lo[k], m.hi[k] = mid - min_face / 2, mid + min_face / 2


def _base_boxes(
    outer_lo: np.ndarray,
    outer_hi: np.ndarray,
    cavities: list[tuple[np.ndarray, np.ndarray]],
    sliver: float,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Boxes covering the outer box minus the cavities (greedy merge of grid cells)."""
    cuts = []
    for k in range(3):
        vals = {float(outer_lo[k]), float(outer_hi[k])}
        for lo, hi in cavities:
            vals.update(float(np.clip(v, outer_lo[k], outer_hi[k])) for v in (lo[k], hi[k]))
        cuts.append(np.array(sorted(vals)))
    shape = tuple(len(c) - 1 for c in cuts)
    centers = [(c[:-1] + c[1:]) / 2 for c in cuts]
    cx, cy, cz = np.meshgrid(*centers, indexing="ij")
    pts = np.stack([cx, cy, cz], axis=-1)
    solid = np.ones(shape, bool)
    for lo, hi in cavities:
        solid &= ~np.all((pts > lo) & (pts < hi), axis=-1)
    used = np.zeros(shape, bool)
    boxes = []
    for i, j, k in itertools.product(*(range(s) for s in shape)):
        if not solid[i, j, k] or used[i, j, k]:
            continue
        i1 = i + 1
        while i1 < shape[0] and solid[i1, j, k] and not used[i1, j, k]:
            i1 += 1
        j1 = j + 1
        while j1 < shape[1] and np.all(solid[i:i1, j1, k] & ~used[i:i1, j1, k]):
            j1 += 1
        k1 = k + 1
        while k1 < shape[2] and np.all(solid[i:i1, j:j1, k1] & ~used[i:i1, j:j1, k1]):
            k1 += 1
        used[i:i1, j:j1, k:k1] = True
        lo = np.array([cuts[0][i], cuts[1][j], cuts[2][k]])
        hi = np.array([cuts[0][i1], cuts[1][j1], cuts[2][k1]])
        if np.all(hi - lo >= sliver):
            boxes.append((lo, hi))
    return boxes


def fit_box_layout(obj: ArticulatedObject, clearance: float | None = None) -> ArticulatedObject:
    """A copy of ``obj`` whose parts have box collision geometry and consistent joints
    (the module docstring); ``clearance`` in the object's units (default: 4 mm when
    ``obj.scale`` is known, else ``CLEARANCE_UNITS``)."""
    unit = 1.0 / obj.scale if obj.scale else None  # generator units per metre
    gap = clearance if clearance is not None else (CLEARANCE_M * unit if unit else CLEARANCE_UNITS)
    sliver = SLIVER_M * unit if unit else SLIVER_M
    min_size = MIN_SIZE_M * unit if unit else MIN_SIZE_M
    min_face = MIN_FACE_M * unit if unit else MIN_FACE_M

    base = obj.parts[0]
    fixed = [p for p in obj.parts[1:] if p.joint is None or not p.joint.movable]
    movable_parts = [p for p in obj.parts[1:] if p.joint is not None and p.joint.movable]
    all_bounds = np.array([robust_bounds(p.mesh) for p in obj.parts])
    bounds_of = {p.name: b for p, b in zip(obj.parts, all_bounds, strict=True)}
    outer_lo, outer_hi = all_bounds[:, 0].min(0), all_bounds[:, 1].max(0)
    # the pipeline stands the object on its meshes' lowest point: the base reaches it
    outer_lo[2] = min(float(p.mesh.bounds[0, 2]) for p in obj.parts)
    outer = np.array([outer_lo, outer_hi])
    moving = [_classify(p, bounds_of[p.name], outer) for p in movable_parts]
    for m in moving:  # a moving part does not drag on the floor, the base keeps a back
        m.lo[2] = max(m.lo[2], outer_lo[2] + gap)
        n = m.normal_axis
        depth = outer_hi[n] - outer_lo[n]
        if m.normal_sign > 0:
            m.lo[n] = max(m.lo[n], outer_lo[n] + BACK_WALL * depth)
            if outer_hi[n] - m.hi[n] <= FLUSH * depth:
                m.hi[n] = outer_hi[n]
        else:
            m.hi[n] = min(m.hi[n], outer_hi[n] - BACK_WALL * depth)
            if m.lo[n] - outer_lo[n] <= FLUSH * depth:
                m.lo[n] = outer_lo[n]
        if m.part.joint.type == "prismatic" and m.hi[n] - m.lo[n] < DRAWER_BODY * depth:
            # a drawer front alone (a panel the head calls a drawer): its body reaches back
            if m.normal_sign > 0:
                m.lo[n] = max(m.hi[n] - DRAWER_BODY * depth, outer_lo[n] + BACK_WALL * depth)
            else:
                m.hi[n] = min(m.lo[n] + DRAWER_BODY * depth, outer_hi[n] - BACK_WALL * depth)
    for m in moving:
        _widen_shallow_front(m, min_face, outer)
    # a thick door trimmed on its hinge side sweeps further: a pair apart before may meet
    for _ in range(SEPARATION_PASSES):
        shrunk = [_separate(a, b, gap, min_face) for a, b in itertools.combinations(moving, 2)]
        if not any(shrunk):
            break

    kept: list[_Movable] = []
    dropped: list[Part] = list(fixed)
    for m in moving:
        size = m.hi - m.lo
        if np.any(size < min_size) or np.any(
            np.delete(size, m.normal_axis) < min_face * (1 - 1e-9)
        ):
            log.info("box layout: part %s is too small %s; merged into the base", m.part.name, size)
            dropped.append(m.part)
        else:
            kept.append(m)

    cavities = []
    for m in kept:
        lo, hi = m.lo - gap, m.hi + gap
        _add_bulge(m, lo, hi)  # room for a door's free edge
        n, s = m.normal_axis, m.normal_sign
        if s > 0:
            lo[n], hi[n] = m.lo[n] - gap, outer_hi[n] + 1.0
        else:
            lo[n], hi[n] = outer_lo[n] - 1.0, m.hi[n] + gap
        cavities.append((lo, hi))
    base_prims = [box(lo, hi) for lo, hi in _base_boxes(outer_lo, outer_hi, cavities, sliver)]

    base_mesh = base.mesh
    if dropped:
        base_mesh = trimesh.util.concatenate([base.mesh, *(p.mesh for p in dropped)])
    parts = [
        Part(base.name, base.semantic, base_mesh, None, base_prims, base.handle, base.material)
    ]
    for m in kept:
        parts.append(_rigged(m, unit or 1.0))
    return ArticulatedObject(
        parts,
        category=obj.category,
        scale=obj.scale,
        provenance={**obj.provenance, "collision": "box layout (generator.box_layout)"},
    )


def _rigged(m: _Movable, unit: float) -> Part:
    """The part with its box (and a bar handle) as collision geometry and its joint
    placed on the box; ``unit``: generator units per metre."""
    p, j = m.part, m.part.joint
    assert j is not None
    size = m.hi - m.lo
    n, s = m.normal_axis, m.normal_sign
    handle_style = _handle_style(m, unit)
    if m.hinge_axis is None:
        axis = _unit(n, s)
        upper = min(max(j.upper, 0.0), MAX_SLIDE * float(size[n]))
        upper = max(upper, 0.2 * float(size[n]))
        joint = Joint("prismatic", (m.lo + m.hi) / 2, axis, 0.0, upper, j.parent)
    else:
        h, lat = m.hinge_axis, m.lateral_axis
        assert lat is not None
        hinge_side = m.hinge_side
        origin = (m.lo + m.hi) / 2
        origin[n] = m.hi[n] if s > 0 else m.lo[n]
        origin[lat] = m.hi[lat] if hinge_side > 0 else m.lo[lat]
        free_dir = _unit(lat, -hinge_side)  # from the hinge toward the free edge
        axis = _unit(h)
        if np.dot(np.cross(axis, free_dir), _unit(n, s)) < 0:
            axis = -axis
        upper = float(np.clip(j.upper, 0.5, MAX_SWING))
        if handle_style is not None:  # the bar must not swing past the hinge plane
            reach = float(size[lat]) - handle_style.edge_margin - handle_style.radius
            upper = min(upper, math.atan2(reach, handle_style.standoff + handle_style.radius))
        joint = Joint("revolute", origin, axis, 0.0, upper, j.parent)
    prims, mesh, handle = [box(m.lo, m.hi)], p.mesh, p.handle
    if handle_style is not None:
        prims, trims, handle = slab_with_handle(
            m.lo, m.hi, n, handle_style, _grip(m, handle_style), _grip_axis(m)
        )
        prims = prims + trims
        bar = _one_solid([q.to_mesh() for q in trims])
        bar.visual.vertex_colors = np.tile(HANDLE_COLOR, (len(bar.vertices), 1))
        mesh = trimesh.util.concatenate([p.mesh, bar])
    return Part(p.name, p.semantic, mesh, joint, prims, handle, p.material)


def rigged_panel(part: Part, outer: np.ndarray, unit: float = 1.0) -> Part:
    """``part`` remade as a plain panel for its joint: the box of its mesh (in the mesh's
    mean colour) as its geometry, its hinge or slide placed on that box and a bar handle
    where its joint needs one, as :func:`fit_box_layout` rigs a generated part. For a part
    whose motion was given and its own geometry does not fit (a retrieved drawer that is
    a door in the photo: its handle would sit where no gripper pulls). ``outer`` (2, 3):
    the object's bounds; ``unit``: units per metre."""
    lo, hi = part.mesh.bounds
    panel = trimesh.creation.box(hi - lo)
    panel.apply_translation((lo + hi) / 2)
    colours = getattr(part.mesh.visual, "vertex_colors", None)
    colour = (
        np.asarray(colours)[:, :4].mean(axis=0)
        if colours is not None and len(colours)
        else (180, 180, 180, 255)
    )
    panel.visual.vertex_colors = np.tile(np.asarray(colour, np.uint8), (len(panel.vertices), 1))
    bare = Part(part.name, part.semantic, panel, part.joint, [], None, part.material)
    return _rigged(_classify(bare, np.array([lo, hi]), np.asarray(outer, float)), unit)


def _grip_axis(m: _Movable) -> int:
    """The bar's axis: along the hinge for a door, along the longer side of a drawer's face."""
    if m.hinge_axis is not None:
        return m.hinge_axis
    face = [k for k in range(3) if k != m.normal_axis]
    return max(face, key=lambda k: m.hi[k] - m.lo[k])


def _grip(m: _Movable, style: HandleStyle) -> np.ndarray:
    """The bar's centre on the front face: a drawer's face centre; on a door, ``style.
    edge_margin`` in from the free edge, half-way along the hinge."""
    grip = (m.lo + m.hi) / 2
    grip[m.normal_axis] = m.hi[m.normal_axis]
    if m.hinge_axis is not None:
        lat = m.lateral_axis
        assert lat is not None
        if m.hinge_side > 0:  # hinge on the high side, free edge low
            grip[lat] = m.lo[lat] + style.edge_margin
        else:
            grip[lat] = m.hi[lat] - style.edge_margin
    return grip


def _one_solid(pieces: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """The union of overlapping closed solids (a bar on its posts) as one closed mesh, so
    the handle is one piece of the part's visual; their concatenation if the union
    fails."""
    try:
        union = trimesh.boolean.union(pieces, engine="manifold")
        if union.is_watertight and union.volume > 0:
            return union
    except Exception as e:  # noqa: BLE001 - overlapping pieces still render
        log.debug("handle union failed: %s", e)
    return trimesh.util.concatenate(pieces)


def _handle_style(m: _Movable, unit: float) -> HandleStyle | None:
    """A bar handle for a part that opens toward +x/+y/+z and has none modelled (a
    gripper cannot pull a bare face); sizes of ``HANDLE_M`` in metres, the bar at most
    half the face long and the margin at most 0.3 of the door's width."""
    if m.normal_sign < 0 or m.part.handle is not None:
        return None
    length, radius, standoff, margin = (v * unit for v in HANDLE_M)
    along = _grip_axis(m)
    length = min(length, 0.5 * float(m.hi[along] - m.lo[along]))
    if m.hinge_axis is not None:
        lat = m.lateral_axis
        assert lat is not None
        margin = min(margin, 0.3 * float(m.hi[lat] - m.lo[lat]))
    return HandleStyle("bar", length, radius, standoff, 0.0, 0.0, margin)
