"""Box layout of generated objects (generator.box_layout): hand-computed layouts, and a
messy generated-like object that SAPIEN validation accepts only after the layout."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from generator.articulated import ArticulatedObject, Joint, Part
from generator.box_layout import (
    BACK_WALL,
    DRAWER_BODY,
    HANDLE_M,
    MAX_SLIDE,
    MIN_FACE_M,
    _base_boxes,
    fit_box_layout,
    robust_bounds,
)
from generator.bundle import save_bundle

GAP = 0.01


def _box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(hi - lo)
    m.apply_translation((lo + hi) / 2)
    return m


def _u(*v: float) -> np.ndarray:
    return np.asarray(v) / np.linalg.norm(v)


def _bounds(p: Part) -> np.ndarray:
    prim = p.primitives[0]  # the part's box; a bar handle follows
    c, s = prim.transform[:3, 3], prim.size
    return np.array([c - s / 2, c + s / 2])


def _layout(parts: list[Part], gap: float = GAP) -> dict[str, Part]:
    return {p.name: p for p in fit_box_layout(ArticulatedObject(parts), clearance=gap).parts}


def _base(lo=(-0.3, -0.5, -0.5), hi=(0.3, 0.5, 0.5)) -> Part:
    return Part("base", "base", _box(lo, hi))


def test_robust_bounds_ignore_a_stray_fragment():
    body = _box((-0.2, -0.2, -0.2), (0.2, 0.2, 0.2))
    speck = _box((0.45, 0.45, 0.45), (0.46, 0.46, 0.46))
    lo, hi = robust_bounds(trimesh.util.concatenate([body, speck]))
    assert np.all(hi < 0.21) and np.all(lo > -0.21)  # the speck does not stretch it
    assert np.all(hi > 0.17) and np.all(lo < -0.17)  # a box keeps most of its extent


def test_overlapping_drawers_split_sideways_at_the_middle_of_the_overlap():
    """Two front drawers overlapping by 0.1 in y (and fully in x and z): the split is along
    y (x is their slide axis), at the middle of the overlap, with the gap between them."""
    tilt = np.array([0.98, 0.15, 0.1])
    a = Part(
        "drawer_1",
        "drawer",
        _box((0.0, -0.4, -0.2), (0.3, 0.05, 0.2)),
        Joint("prismatic", [0.3, 0, 0], tilt / np.linalg.norm(tilt), 0.0, 0.5),
    )
    b = Part(
        "drawer_2",
        "drawer",
        _box((0.0, -0.05, -0.2), (0.3, 0.4, 0.2)),
        Joint("prismatic", [0.3, 0, 0], [1, 0, 0], 0.0, 0.1),
    )
    out = _layout([_base(), a, b])
    ba, bb = _bounds(out["drawer_1"]), _bounds(out["drawer_2"])
    # robust bounds trim a few mm; the split is at y = 0 (the overlap [-0.05, 0.05])
    assert ba[1, 1] == pytest.approx(-GAP / 2, abs=1e-9)
    assert bb[0, 1] == pytest.approx(GAP / 2, abs=1e-9)
    for name in ("drawer_1", "drawer_2"):
        j = out[name].joint
        np.testing.assert_allclose(j.axis, [1, 0, 0])  # snapped, pointing out of the front
        assert j.lower == 0.0
    depth = ba[1, 0] - ba[0, 0]
    assert out["drawer_1"].joint.upper == pytest.approx(MAX_SLIDE * depth)  # 0.5 > 0.9 depth
    assert out["drawer_2"].joint.upper == pytest.approx(0.1)  # a shorter range is kept


def test_door_hinge_on_the_outer_edge_nearest_the_prediction_and_swinging_outward():
    """A front door (thin in x) with a vertical hinge predicted near its low-y edge: the
    hinge goes on the front face at low y; a positive angle must move the free edge
    (+y side) toward +x, so the axis is -z (z x y = -x); the range is clipped to 90 deg."""
    door = Part(
        "door_1",
        "door",
        _box((0.28, -0.4, -0.4), (0.32, 0.4, 0.4)),
        Joint("revolute", [0.1, -0.35, 0.0], [0.05, 0.0, 1.0], -0.1, 2.5),
    )
    out = _layout([_base(), door])
    j, (lo, hi) = out["door_1"].joint, _bounds(out["door_1"])
    np.testing.assert_allclose(j.axis, [0, 0, -1])
    assert j.origin[0] == pytest.approx(hi[0]) and j.origin[1] == pytest.approx(lo[1])
    # the bar handle: parallel to the hinge, HANDLE_M's margin in from the free edge,
    # standing off the face; the swing stops before the bar crosses the hinge plane
    length, radius, standoff, margin = HANDLE_M
    h = out["door_1"].handle
    assert h.kind == "bar"
    np.testing.assert_allclose(
        h.position, [hi[0] + standoff, hi[1] - margin, (lo[2] + hi[2]) / 2], atol=1e-9
    )
    np.testing.assert_allclose(np.abs(h.axis), [0, 0, 1])
    width = hi[1] - lo[1]
    assert j.lower == 0.0
    assert j.upper == pytest.approx(math.atan2(width - margin - radius, standoff + radius))
    assert 1.3 < j.upper < math.pi / 2
    free_edge = np.array([hi[0], hi[1], 0.0])
    moved = trimesh.transform_points([free_edge], j.transform(0.3))[0]
    assert moved[0] > free_edge[0] + 0.1


def test_base_is_the_outer_box_minus_the_cavities():
    """Volume by hand: outer box 0.6 x 1 x 1 minus the drawer's cavity (its box grown by
    the gap sideways and at the back, cut out through the front face)."""
    drawer = Part(
        "drawer_1",
        "drawer",
        _box((0.0, -0.2, -0.1), (0.3, 0.2, 0.1)),
        Joint("prismatic", [0.3, 0, 0], [1, 0, 0], 0.0, 0.2),
    )
    out = _layout([_base(), drawer])
    lo, hi = _bounds(out["drawer_1"])
    cav = (0.3 - (lo[0] - GAP)) * (hi[1] - lo[1] + 2 * GAP) * (hi[2] - lo[2] + 2 * GAP)
    base = out["base"].primitives
    vol = sum(float(np.prod(p.size)) for p in base)
    assert vol == pytest.approx(0.6 * 1.0 * 1.0 - cav, rel=1e-6)
    for p in base:  # no base box reaches into the drawer's box grown by the gap
        c, s = p.transform[:3, 3], p.size
        overlap = np.minimum(c + s / 2, hi + GAP) - np.maximum(c - s / 2, lo - GAP)
        assert np.any(overlap <= 1e-12)


def test_base_boxes_cover_exactly_what_is_not_cut():
    boxes = _base_boxes(
        np.zeros(3), np.ones(3), [(np.array([0.5, -1, -1]), np.array([2, 2, 2]))], 1e-4
    )
    assert len(boxes) == 1
    np.testing.assert_allclose(boxes[0][1], [0.5, 1, 1])


def test_nested_part_keeps_its_box_and_the_outer_one_is_trimmed_to_its_larger_side():
    outer = Part(
        "drawer_1",
        "drawer",
        _box((0.0, -0.4, -0.4), (0.3, 0.4, 0.4)),
        Joint("prismatic", [0.3, 0, 0], [1, 0, 0], 0.0, 0.2),
    )
    inner = Part(
        "drawer_2",
        "drawer",
        _box((0.0, -0.39, 0.1), (0.3, 0.39, 0.2)),
        Joint("prismatic", [0.3, 0, 0], [1, 0, 0], 0.0, 0.2),
    )
    out = _layout([_base(), outer, inner])
    bo, bi = _bounds(out["drawer_1"]), _bounds(out["drawer_2"])
    # z overlaps least (the inner part's 0.1); below it 0.5 is left, above it 0.2
    assert bo[1, 2] == pytest.approx(bi[0, 2] - GAP)
    assert bi[1, 2] - bi[0, 2] > 0.09


def test_a_thick_door_trimmed_on_its_hinge_side_is_kept_off_its_neighbour():
    """A 15 cm thick door between a drawer on its hinge side, which it overlaps, and one
    just clear of its free edge's sweep: splitting it from the first moves its hinge and
    grows that sweep into the second. The layout passes over the pairs again until no
    sweeps meet: the free edge's reach (hinge + hypot(thickness, width)) stays about a gap off
    the second drawer."""
    door = Part(
        "door_1",
        "door",
        _box((0.05, -0.4, -0.3), (0.2, -0.2, 0.3)),
        Joint("revolute", [0.2, -0.4, 0.0], [0, 0, -1], 0.0, 1.2),
    )
    beside = Part(
        "drawer_2",
        "drawer",
        _box((0.0, -0.1399, -0.2), (0.2, 0.1, 0.2)),
        Joint("prismatic", [0.2, 0, 0], [1, 0, 0], 0.0, 0.15),
    )
    hinge_side = Part(
        "drawer_3",
        "drawer",
        _box((0.0, -0.5, -0.2), (0.2, -0.3, 0.45)),
        Joint("prismatic", [0.2, -0.4, 0.1], [1, 0, 0], 0.0, 0.15),
    )
    out = _layout([_base(), door, beside, hinge_side])
    d, b = _bounds(out["door_1"]), _bounds(out["drawer_2"])
    hinge_y = out["door_1"].joint.origin[1]
    assert hinge_y == pytest.approx(d[0, 1])  # hinged on the trimmed side
    assert d[0, 1] > -0.4 + 0.01  # it was trimmed
    reach = hinge_y + math.hypot(d[1, 0] - d[0, 0], d[1, 1] - d[0, 1])
    assert reach <= b[0, 1] - 0.9 * GAP  # a gap (less what the last pass trims) off it


def test_parts_too_thin_or_too_small_to_open_are_merged_into_the_base():
    """scale = 1: a 4 mm flap (< MIN_SIZE_M) and a 3 x 3 cm knob-sized door (face <
    MIN_FACE_M) are no parts; their meshes join the base's."""
    flap = Part(
        "door_1",
        "door",
        _box((0.3, -0.2, -0.2), (0.304, 0.2, 0.2)),
        Joint("revolute", [0.3, -0.2, 0], [0, 0, 1], 0.0, 1.0),
    )
    knob = Part(
        "door_2",
        "door",
        _box((0.28, 0.3, 0.3), (0.3, 0.33, 0.33)),
        Joint("revolute", [0.3, 0.3, 0.3], [0, 0, 1], 0.0, 1.0),
    )
    keep = Part(
        "drawer_3",
        "drawer",
        _box((0.0, -0.2, -0.45), (0.3, 0.2, -0.3)),
        Joint("prismatic", [0.3, 0, -0.4], [1, 0, 0], 0.0, 0.2),
    )
    out = fit_box_layout(ArticulatedObject([_base(), flap, knob, keep], scale=1.0), clearance=GAP)
    assert [p.name for p in out.parts] == ["base", "drawer_3"]
    assert len(out.parts[0].mesh.vertices) == 24  # the dropped parts' meshes join the base


def test_a_shallow_drawer_is_widened_to_the_smallest_face_not_merged():
    """scale = 1: a drawer 30 cm wide but 3 cm tall (a row of the generator's grid) keeps
    its place, its face widened to MIN_FACE_M about its middle; its cavity is cut."""
    shallow = Part(
        "drawer_1",
        "drawer",
        _box((0.0, -0.15, 0.2), (0.3, 0.15, 0.23)),
        Joint("prismatic", [0.3, 0, 0.215], [1, 0, 0], 0.0, 0.2),
    )
    out = fit_box_layout(ArticulatedObject([_base(), shallow], scale=1.0), clearance=GAP)
    assert [p.name for p in out.parts] == ["base", "drawer_1"]
    b = _bounds(out.parts[1])
    assert b[1, 2] - b[0, 2] == pytest.approx(MIN_FACE_M)
    assert (b[0, 2] + b[1, 2]) / 2 == pytest.approx(0.215)
    assert b[1, 1] - b[0, 1] == pytest.approx(0.3)
    for prim in out.parts[0].primitives:  # no base box in the widened drawer's slot
        c, size = prim.transform[:3, 3], prim.size
        lo, hi = c - size / 2, c + size / 2
        assert np.any(hi <= b[0] + 1e-9) or np.any(lo >= b[1] - 1e-9)


def test_a_drawer_front_alone_gets_a_body_reaching_back():
    """scale = 1: a panel 2 cm deep on the face of a 60 cm deep base, typed a drawer, gets
    a box DRAWER_BODY of the depth deep (a slide of a centimetre or two would leave it
    hanging out of its slot); its slot is cut from the base; a deep drawer keeps its box
    (cut BACK_WALL short of the back)."""
    front = Part(
        "drawer_1",
        "drawer",
        _box((0.28, -0.2, 0.1), (0.3, 0.2, 0.3)),
        Joint("prismatic", [0.3, 0, 0.2], [1, 0, 0], 0.0, 0.015),
    )
    deep = Part(
        "drawer_2",
        "drawer",
        _box((-0.3, -0.2, -0.3), (0.3, 0.2, -0.1)),
        Joint("prismatic", [0.3, 0, -0.2], [1, 0, 0], 0.0, 0.3),
    )
    out = fit_box_layout(ArticulatedObject([_base(), front, deep], scale=1.0), clearance=GAP)
    parts = {p.name: p for p in out.parts}
    b = _bounds(parts["drawer_1"])
    assert b[1, 0] == pytest.approx(0.3)
    assert b[0, 0] == pytest.approx(0.3 - DRAWER_BODY * 0.6)
    assert parts["drawer_1"].joint.upper >= 0.2 * DRAWER_BODY * 0.6 - 1e-9
    d = _bounds(parts["drawer_2"])
    assert d[0, 0] == pytest.approx(-0.3 + BACK_WALL * 0.6)
    for prim in parts["base"].primitives:  # no base box in the drawer's slot
        c, size = prim.transform[:3, 3], prim.size
        lo, hi = c - size / 2, c + size / 2
        assert np.any(hi <= b[0] + 1e-9) or np.any(lo >= b[1] - 1e-9)


@pytest.mark.slow
def test_messy_generated_object_validates_in_sapien_after_the_layout(tmp_path):
    """Parts like a generator's: drawers overlapping each other and the base, a tilted
    slide axis, a door hinge inside its panel and a range past 90 degrees. The layout
    makes it pass every SAPIEN check (rest, sweeps, all open, drives, free base)."""
    from asset_pipeline.assets.build import build_asset
    from asset_pipeline.validate import validate_asset

    base = Part("base", "base", _box((-0.25, -0.45, -0.5), (0.25, 0.45, 0.5)))
    d1 = Part(
        "drawer_1",
        "drawer",
        _box((-0.15, -0.43, 0.15), (0.27, 0.1, 0.45)),
        Joint("prismatic", [0.27, 0, 0.3], _u(0.97, 0.2, 0.1), 0.0, 0.6),
    )
    d2 = Part(
        "drawer_2",
        "drawer",
        _box((-0.1, -0.05, 0.1), (0.26, 0.43, 0.46)),
        Joint("prismatic", [0.27, 0, 0.3], _u(1.0, -0.1, 0.0), 0.0, 0.3),
    )
    door = Part(
        "door_3",
        "door",
        _box((0.22, -0.43, -0.45), (0.28, 0.43, 0.12)),
        Joint("revolute", [0.25, 0.2, 0.0], _u(0.0, 0.1, 1.0), 0.0, 2.4),
    )
    obj = ArticulatedObject([base, d1, d2, door], category="cabinet", scale=1.0)
    obj.validate("messy")  # a valid object model; only its physics is broken
    out = fit_box_layout(obj)
    d = save_bundle(out, tmp_path / "messy")
    build_asset(d, height=1.0)
    report = validate_asset(d, preview=False, repair=False)
    assert report.ok, report.reasons
    movable = {p.name for p in out.parts if p.joint is not None}
    assert movable == {"drawer_1", "drawer_2", "door_3"}


def test_added_bar_handle_is_one_closed_piece_of_the_visual():
    """A part without a modelled handle gets the bar (a cylinder on two posts): in its
    visual mesh that bar is one closed solid beside the panel, not three overlapping
    ones, so the part is two pieces, both watertight."""
    drawer = Part(
        "drawer_1",
        "drawer",
        _box((0.0, -0.2, 0.1), (0.3, 0.2, 0.3)),
        Joint("prismatic", [0.3, 0, 0.2], (1.0, 0.0, 0.0), 0.0, 0.25),
    )
    out = _layout([_base(), drawer])["drawer_1"]
    assert out.handle is not None and out.handle.kind == "bar"
    pieces = out.mesh.split(only_watertight=False)
    assert len(pieces) == 2
    assert all(p.is_watertight and p.volume > 0 for p in pieces)
    bar = min(pieces, key=lambda p: p.volume)
    assert bar.bounds[1][0] > 0.3 + 0.02  # stands out of the drawer's front


@pytest.mark.parametrize(
    "motion", ["drawer", "door_left", "door_right", "flap_bottom", "flap_top", "lid"]
)
def test_the_layout_keeps_a_given_motion(motion):
    """A part whose joint comes from its motion (a user's or the photo parser's word,
    ``articulation.joint_of_motion``) keeps that motion through the layout: the hinge on
    the named edge, opening outward."""
    from generator.motions import motion_of
    from generator.pact.model.articulation import joint_of_motion

    if motion == "lid":  # a top-loader's lid lies on the top
        lo, hi = np.array([-0.25, -0.4, 0.42]), np.array([0.25, 0.4, 0.5])
    else:  # a front panel in the upper half of a cabinet
        lo, hi = np.array([0.22, -0.45, 0.05]), np.array([0.3, 0.45, 0.45])
    pj = joint_of_motion(motion, lo, hi)
    part = Part("p_1", pj.semantic, _box(lo, hi), Joint(pj.type, pj.origin, pj.axis, 0.0, pj.upper))
    laid = _layout([_base(), part])["p_1"]
    assert laid.joint.type == pj.type
    assert (
        motion_of(Part(laid.name, laid.semantic, laid.primitives[0].to_mesh(), laid.joint))
        == motion
    )


def test_a_lid_drawn_as_a_strip_along_the_front_stays_a_lid_and_validates(tmp_path):
    """A top-loader's lid that the photo shows only as a strip along the top of the front
    is drawn deeper in height than in depth. Thinnest across the hinge, its face would be
    the front and it a flap hinged at its top edge, falling open under its own weight
    (and, with friction raised to hold it, too stiff to pull open). As a lid it hinges
    on the back edge of its top face, opens upward, and passes SAPIEN's checks."""
    from asset_pipeline.assets.build import build_asset
    from asset_pipeline.validate import validate_asset
    from generator.motions import motion_of
    from generator.pact.model.articulation import joint_of_motion

    base = Part("base", "base", _box((-0.3, -0.3, 0.0), (0.3, 0.3, 0.85)))
    lo, hi = np.array([0.25, -0.2, 0.76]), np.array([0.31, 0.2, 0.85])  # 6 cm deep, 9 tall
    pj = joint_of_motion("lid", lo, hi)
    lid = Part("lid_1", "lid", _box(lo, hi), Joint(pj.type, pj.origin, pj.axis, 0.0, pj.upper))
    obj = ArticulatedObject([base, lid], category="washing_machine", scale=1.0)
    out = fit_box_layout(obj)
    laid = next(p for p in out.parts if p.name == "lid_1")
    (blo, bhi) = _bounds(laid)
    assert laid.joint.origin[2] == pytest.approx(bhi[2])  # on the top face ...
    assert laid.joint.origin[0] == pytest.approx(blo[0])  # ... at its back edge
    front_top = np.array([bhi[0], 0.0, bhi[2]])
    assert trimesh.transform_points([front_top], laid.joint.transform(0.5))[0][2] > bhi[2] + 0.02
    assert (
        motion_of(Part(laid.name, laid.semantic, laid.primitives[0].to_mesh(), laid.joint)) == "lid"
    )
    d = save_bundle(out, tmp_path / "top_loader")
    build_asset(d, height=0.85)
    report = validate_asset(d, preview=False, repair=False)
    assert report.ok, report.reasons
