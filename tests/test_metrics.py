"""Generation metrics against hand-computed cases (definitions in generator/metrics.py)."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
import trimesh
from rich.console import Console

from generator.articulated import ArticulatedObject, Joint, Part
from generator.bundle import save_bundle
from generator.metrics import (
    DCDIST_UNMATCHED,
    DGIOU_UNMATCHED,
    METRIC_KEYS,
    aor,
    box_corners,
    chamfer,
    evaluate_dirs,
    evaluate_pair,
    format_table,
    giou,
    iou,
    joint_types_missed,
    match_parts,
    part_boxes,
    part_poses,
)

N_POINTS = 2000  # enough for the tests, keeps each evaluate_pair to a few ms


def box_part(name: str, lo, hi, joint: Joint | None = None) -> Part:
    mesh = trimesh.creation.box(bounds=np.array([lo, hi], dtype=float))
    semantic = "base" if joint is None else name.split("_")[0]
    return Part(name, semantic, mesh, joint)


def prismatic(axis=(1, 0, 0), upper=0.25) -> Joint:
    return Joint("prismatic", [0.5, 0.0, 0.0], axis, 0.0, upper)


def cabinet(half: float = 0.5) -> ArticulatedObject:
    """Base cube [-half, half]^3 with two drawers and a door, all inside the base's bounds.

    With half = 0.5 the normalization is the identity (centre 0, largest extent 1).
    """
    h = half
    door_hinge = Joint("revolute", [h, -0.75 * h, 0.0], [0, 0, -1], 0.0, math.pi / 2)
    return ArticulatedObject(
        parts=[
            box_part("base", [-h, -h, -h], [h, h, h]),
            box_part(
                "drawer_0", [0.5 * h, -0.75 * h, 0.25 * h], [h, 0.75 * h, 0.75 * h], prismatic()
            ),
            box_part("drawer_1", [0.5 * h, -0.75 * h, -0.25 * h], [h, 0.75 * h, 0.0], prismatic()),
            box_part("door_0", [0.875 * h, -0.75 * h, -0.75 * h], [h, 0.0, -0.5 * h], door_hinge),
        ],
        category="cabinet",
        scale=None,
    )


def without(obj: ArticulatedObject, name: str) -> ArticulatedObject:
    return ArticulatedObject([p for p in obj.parts if p.name != name], obj.category, obj.scale)


def scores(pred: ArticulatedObject, gt: ArticulatedObject, **kw) -> dict[str, float]:
    return evaluate_pair(pred, gt, n_points=N_POINTS, **kw)


# --------------------------------------------------------------------------- pure functions


def test_giou_hand_computed() -> None:
    cube = np.array([[0, 0, 0], [1, 1, 1]], dtype=float)
    assert giou(cube, cube) == pytest.approx(1.0)
    # disjoint: IoU 0, union 2, enclosing box [0, 3] x [0, 1]^2 of volume 3 -> -1/3
    assert giou(cube, cube + [2, 0, 0]) == pytest.approx(-1.0 / 3.0)
    # half-overlapping bars: intersection 1, union 3, enclosing 3 -> IoU 1/3, gIoU 1/3
    bar = np.array([[0, 0, 0], [2, 1, 1]], dtype=float)
    assert iou(bar, bar + [1, 0, 0]) == pytest.approx(1.0 / 3.0)
    assert giou(bar, bar + [1, 0, 0]) == pytest.approx(1.0 / 3.0)
    # nested: half of the cube, enclosing box is the cube -> 1/2
    assert giou(cube, np.array([[0, 0, 0], [0.5, 1, 1]])) == pytest.approx(0.5)


def test_giou_of_rotated_boxes_is_exact() -> None:
    unit = np.array([[-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]])
    quarter = trimesh.transformations.rotation_matrix(math.pi / 2, [0, 0, 1])
    assert giou(unit, unit, None, quarter) == pytest.approx(1.0)
    # a unit square and the same square turned 45 degrees overlap in a regular octagon of
    # area 2 (sqrt 2 - 1); their 8 corners lie on a circle of radius r = sqrt(2) / 2 and
    # span a regular octagon of area 2 sqrt(2) r^2 = sqrt 2: |C| = sqrt 2 (height 1)
    eighth = trimesh.transformations.rotation_matrix(math.pi / 4, [0, 0, 1])
    inter = 2.0 * (math.sqrt(2.0) - 1.0)
    union = 2.0 - inter
    hull = math.sqrt(2.0)
    assert iou(unit, unit, None, eighth) == pytest.approx(inter / union)
    assert giou(unit, unit, None, eighth) == pytest.approx(inter / union - (hull - union) / hull)
    # turned boxes are compared in their own shape: identical turned boxes give 1
    assert giou(unit, unit, eighth, eighth) == pytest.approx(1.0)


def test_chamfer_hand_computed() -> None:
    a = np.array([[0.0, 0.0, 0.0]])
    b = np.array([[1.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    # a -> b: 1^2; b -> a: mean(1^2, 3^2) = 5
    assert chamfer(a, b) == pytest.approx(6.0)
    assert chamfer(b, a) == pytest.approx(6.0)
    # L2: a -> b: 1; b -> a: mean(1, 3) = 2
    assert chamfer(a, b, squared=False) == pytest.approx(3.0)
    assert chamfer(b, b) == 0.0


def test_match_parts_follows_a_permutation() -> None:
    boxes = part_boxes(cabinet())[1:]
    order = [2, 0, 1]
    pairs = match_parts(boxes[order], boxes)
    assert pairs == [(i, order[i]) for i in range(3)]
    assert match_parts(boxes[:2], boxes) == [(0, 0), (1, 1)]
    assert match_parts(boxes[:0], boxes) == []


def test_posed_boxes_prismatic_and_revolute() -> None:
    obj = cabinet()
    boxes = part_boxes(obj)
    np.testing.assert_allclose(
        boxes[0], [[-0.5] * 3, [0.5] * 3], atol=1e-7
    )  # identity normalization
    poses = part_poses(obj, 0.5)
    # drawer_0: prismatic +x, range [0, 0.25], half way -> shifted by 0.125 in x
    np.testing.assert_allclose(poses[1][:3, 3], [0.125, 0, 0], atol=1e-9)
    np.testing.assert_allclose(poses[1][:3, :3], np.eye(3), atol=1e-12)
    posed = box_corners(boxes[1], poses[1])
    np.testing.assert_allclose(posed.min(0), [0.375, -0.375, 0.125], atol=1e-6)
    np.testing.assert_allclose(posed.max(0), [0.625, 0.375, 0.375], atol=1e-6)
    # door_0: hinge on the line x = 0.5, y = -0.375, axis -z, opened 90 degrees: the leaf
    # (x in [0.4375, 0.5], y in [-0.375, 0]) swings out to x in [0.5, 0.875], y in [-0.375, -0.3125]
    door = box_corners(boxes[3], part_poses(obj, 1.0)[3])
    np.testing.assert_allclose(door.min(0), [0.5, -0.375, -0.375], atol=1e-6)
    np.testing.assert_allclose(door.max(0), [0.875, -0.3125, -0.25], atol=1e-6)
    # at rest every pose is the identity
    np.testing.assert_allclose(part_poses(obj, 0.0), np.tile(np.eye(4), (4, 1, 1)), atol=1e-12)


# --------------------------------------------------------------------------- evaluate_pair


def test_identical_objects_score_zero() -> None:
    gt = cabinet()
    s = scores(copy.deepcopy(gt), gt)
    assert set(s) == set(METRIC_KEYS)
    for key in METRIC_KEYS[:-1]:
        assert s[key] == pytest.approx(0.0, abs=1e-12), key
    assert math.isfinite(s["AOR"])


def test_similar_copy_scores_zero() -> None:
    """A uniformly scaled and moved copy normalizes to the same object."""
    gt = cabinet()
    pred = cabinet(half=1.5)
    for p in pred.parts:
        p.mesh.apply_translation([0.25, -0.5, 1.5])
        if p.joint is not None:
            p.joint.origin = p.joint.origin + [0.25, -0.5, 1.5]
            if p.joint.type == "prismatic":  # metres scale with the object
                p.joint.upper *= 3.0
    s = scores(pred, gt)
    for key in METRIC_KEYS[:-1]:
        assert s[key] == pytest.approx(0.0, abs=1e-9), key


def test_shifted_part_gives_known_centre_distance_and_giou() -> None:
    # base [-1, 1]^3: largest extent 2, normalization scale 1/2; the drawer stays inside
    def obj(shift) -> ArticulatedObject:
        lo = np.array([0.5, -0.5, 0.0]) + shift
        hi = np.array([1.0, 0.5, 0.5]) + shift
        return ArticulatedObject(
            [box_part("base", [-1, -1, -1], [1, 1, 1]), box_part("drawer_0", lo, hi, prismatic())]
        )

    d = np.array([0.0, 0.25, 0.25])
    s = scores(obj(d), obj(np.zeros(3)))
    assert s["RS-dcDist"] == pytest.approx(np.linalg.norm(d) / 2.0)
    assert s["AS-dcDist"] == pytest.approx(np.linalg.norm(d) / 2.0)  # both slide alike
    # normalized boxes: extents (a, b, c) = (0.25, 0.5, 0.25), offset t = (0, 0.125, 0.125).
    # The hull of a box and its translate is the box swept along t:
    # |C| = abc + ab |t_z| + ac |t_y| + bc |t_x|
    a, b, c = 0.25, 0.5, 0.25
    inter = a * (b - 0.125) * (c - 0.125)
    union = 2 * a * b * c - inter
    hull = a * b * c + a * b * 0.125 + a * c * 0.125
    expected = 1.0 - (inter / union - (hull - union) / hull)
    assert s["RS-dgIoU"] == pytest.approx(expected)
    assert s["RS-dCD"] > 0.0


def test_matching_is_invariant_to_part_order() -> None:
    gt = cabinet()
    pred = cabinet()
    pred.part("drawer_1").mesh.apply_translation([0.0, 0.0, -0.0625])
    shuffled = ArticulatedObject([pred.parts[i] for i in (3, 0, 2, 1)], pred.category, pred.scale)
    a, b = scores(pred, gt), scores(shuffled, gt)
    for key in ("RS-dgIoU", "AS-dgIoU", "RS-dcDist", "AS-dcDist", "AOR"):
        assert b[key] == pytest.approx(a[key], abs=1e-12), key
    assert a["RS-dcDist"] == pytest.approx(0.0625 / 3)  # one of three parts moved by 1/16
    assert b["RS-dCD"] == pytest.approx(a["RS-dCD"], abs=1e-12)  # parts sampled in name order
    assert b["AS-dCD"] == pytest.approx(a["AS-dCD"], abs=1e-12)


def test_missing_and_extra_parts_cost_the_penalty() -> None:
    gt = cabinet()
    missing = scores(without(gt, "door_0"), gt)  # 2 of 3 slots matched exactly
    for rs_as in ("RS", "AS"):
        assert missing[f"{rs_as}-dgIoU"] == pytest.approx(DGIOU_UNMATCHED / 3)
        assert missing[f"{rs_as}-dcDist"] == pytest.approx(DCDIST_UNMATCHED / 3)
    extra_obj = cabinet()
    extra_obj.parts.append(box_part("drawer_2", [0, -0.25, -0.25], [0.25, 0.25, 0.0], prismatic()))
    extra = scores(extra_obj, gt)
    assert extra["RS-dgIoU"] == pytest.approx(DGIOU_UNMATCHED / 4)
    assert extra["RS-dcDist"] == pytest.approx(DCDIST_UNMATCHED / 4)
    assert missing["RS-dCD"] > 0.0 and extra["RS-dCD"] > 0.0
    # dropping a part never beats predicting it badly (door moved to the back, inside the base)
    bad = cabinet()
    bad.part("door_0").mesh.apply_translation([-0.9375, 0.375, 0.75])
    bad_s = scores(bad, gt)
    assert bad_s["RS-dgIoU"] <= missing["RS-dgIoU"]
    assert bad_s["RS-dcDist"] <= missing["RS-dcDist"]


def test_flipped_axes_only_change_articulated_states() -> None:
    gt = cabinet()
    for name in ("drawer_0", "door_0"):
        pred = copy.deepcopy(gt)
        pred.part(name).joint.axis = -pred.part(name).joint.axis
        s = scores(pred, gt)
        for key in ("RS-dgIoU", "RS-dcDist", "RS-dCD"):
            assert s[key] == pytest.approx(0.0, abs=1e-12), (name, key)
        for key in ("AS-dgIoU", "AS-dcDist"):
            assert s[key] > 1e-2, (name, key)
        assert s["AS-dCD"] > 1e-4, name


def test_aor_of_overlapping_siblings() -> None:
    def obj(joint_b: Joint, joint_a: Joint | None = None) -> ArticulatedObject:
        joint_a = joint_a or Joint("fixed")
        return ArticulatedObject(
            [
                box_part("base", [-1, -1, -1], [1, 1, 1]),
                box_part("part_0", [0, 0, 0], [0.5, 0.25, 0.25], joint_a),
                box_part("part_1", [0.25, 0, 0], [0.75, 0.25, 0.25], joint_b),
            ]
        )

    # overlap 0.25 of a 0.75 long union: IoU 1/3 in every state when both move alike
    up = Joint("prismatic", [0, 0, 0], [0, 0, 1], 0.0, 0.5)
    assert aor(obj(up, up), n_states=4) == pytest.approx(1.0 / 3.0)
    spin = Joint("revolute", [0, 0, 0], [0, 0, 1], 0.0, math.pi / 2)
    assert aor(obj(spin, spin), n_states=4) == pytest.approx(1.0 / 3.0)
    # part_1 slides +x by 0 / 0.25 / 0.5 (object units): IoU 1/3, 0 (touching), 0 -> 1/9
    out = Joint("prismatic", [0, 0, 0], [1, 0, 0], 0.0, 0.5)
    assert aor(obj(out), n_states=3) == pytest.approx(1.0 / 9.0)
    # a single movable part has no sibling: AOR is undefined
    assert math.isnan(aor(ArticulatedObject(cabinet().parts[:2])))


def test_joint_types_missed_compares_multisets_of_movable_joint_types() -> None:
    """The cabinet has two prismatic joints and a revolute one: a drawer predicted as a
    door misses one prismatic (the extra revolute counts nothing); a missing door one
    revolute; an extra part nothing; a part made fixed its type."""
    gt = cabinet()
    assert joint_types_missed(gt, gt) == (0, 3)
    as_door = cabinet()
    as_door.part("drawer_1").joint = copy.deepcopy(gt.part("door_0").joint)
    assert joint_types_missed(as_door, gt) == (1, 3)
    assert joint_types_missed(without(gt, "door_0"), gt) == (1, 3)
    extra = cabinet()
    extra.parts.append(box_part("drawer_2", [0.25, -0.3, -0.4], [0.5, 0.3, -0.3], prismatic()))
    assert joint_types_missed(extra, gt) == (0, 3)
    fixed = cabinet()
    fixed.part("drawer_0").joint = Joint("fixed")
    assert joint_types_missed(fixed, gt) == (1, 3)
    assert joint_types_missed(gt, fixed) == (0, 2)


# --------------------------------------------------------------------------- folders


def test_evaluate_dirs_and_table(tmp_path) -> None:
    gt = cabinet()
    moved = cabinet()
    moved.part("drawer_0").mesh.apply_translation([0.0, 0.0, 0.0625])
    for oid in ("a", "b", "c"):
        save_bundle(gt, tmp_path / "gt" / oid)
    save_bundle(gt, tmp_path / "pred" / "a")
    save_bundle(moved, tmp_path / "pred" / "b")
    save_bundle(gt, tmp_path / "pred" / "x")
    res = evaluate_dirs(tmp_path / "pred", tmp_path / "gt", n_points=N_POINTS, n_states=3)
    assert res["missing"] == ["c"]
    assert res["extra"] == ["x"]
    assert res["failed"] == {}
    assert set(res["per_object"]) == {"a", "b"}
    assert res["per_object"]["a"]["RS-dgIoU"] == pytest.approx(0.0, abs=1e-12)
    assert res["per_object"]["b"]["RS-dcDist"] == pytest.approx(0.0625 / 3)
    assert res["per_category"]["cabinet"]["count"] == 2
    # the drawer moved, not re-typed: no joint type missed, 3 movable joints per object
    assert res["mean"]["joint_types_missed"] == 0 and res["mean"]["movable_joints"] == 6
    assert res["mean"]["RS-dcDist"] == pytest.approx(0.0625 / 6)
    json.dumps(res, allow_nan=False)
    console = Console(record=True, width=200)
    console.print(format_table(res))
    text = console.export_text()
    assert "RS-dgIoU" in text and "cabinet" in text and "1 missing" in text
    assert "0 of 6" in text


def test_motions_match_compares_kinds_and_hinge_edges_as_multisets():
    """Two doors hinged left and a drawer against: the same (both exact), the doors hinged
    right (kinds exact, motions not), one door a flap (neither), a part missing (neither)."""
    import trimesh as tm

    from generator.articulated import ArticulatedObject, Part
    from generator.metrics import motions_match
    from generator.motions import joint_for_motion

    def obj(motions):
        parts = [Part("base", "base", tm.creation.box((1, 1, 1)))]
        for k, m in enumerate(motions):
            lo, hi = np.array([0.45, -0.4 + 0.3 * k, -0.4]), np.array([0.5, -0.15 + 0.3 * k, 0.4])
            box = tm.creation.box(hi - lo)
            box.apply_translation((lo + hi) / 2)
            parts.append(Part(f"p_{k}", "door", box, joint_for_motion(m, lo, hi)))
        return ArticulatedObject(parts)

    gt = obj(["door_left", "door_left", "drawer"])
    assert motions_match(obj(["drawer", "door_left", "door_left"]), gt) == (True, True)
    assert motions_match(obj(["door_right", "door_right", "drawer"]), gt) == (True, False)
    assert motions_match(obj(["door_left", "flap_bottom", "drawer"]), gt) == (False, False)
    assert motions_match(obj(["door_left", "drawer"]), gt) == (False, False)
