"""Articulation-aware collision boxes: the hard cases, exactness, coverage, cache, time-out."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from partnet_fixtures import (
    BAR_CENTRE,
    BAR_RADIUS,
    bar_handle_door,
    many_pieces_drawer,
    open_shell_cabinet,
    write_partnet,
)

from asset_pipeline.assets.build import build_asset, prepare_object
from asset_pipeline.geometry.sweeps import HullSet, swept_hulls
from asset_pipeline.geometry.voxel_collision import (
    Grid,
    PointIndex,
    VoxelCollisionParams,
    _Volume,
    articulated_boxes,
    coverage,
    merge_boxes,
    merge_exact,
    surface_points,
)
from asset_pipeline.importers.partnet import PartnetOptions, convert_object
from asset_pipeline.validate import validate_asset
from generator.articulated import ArticulatedObject
from generator.bundle import save_bundle

#: Coarse enough for a fast test, fine enough for the exact refinement to matter.
PARAMS = VoxelCollisionParams(resolution=96, min_pitch=0.006, max_pitch=0.012)


def _metric(tmp_path: Path, links, height: float) -> ArticulatedObject:
    obj = convert_object(write_partnet(tmp_path / "src", links), PartnetOptions(height=height))
    return prepare_object(obj)


def _inside(points: np.ndarray, boxes: list[np.ndarray], depth: float) -> np.ndarray:
    """(N,) True where a point lies deeper than ``depth`` inside one of ``boxes``."""
    hit = np.zeros(len(points), bool)
    for lo, hi in boxes:
        hit |= np.all((points > lo + depth) & (points < hi - depth), axis=1)
    return hit


def _swept_surface(obj: ArticulatedObject, name: str, steps: int = 60) -> np.ndarray:
    """The part's surface samples at ``steps`` joint values over its range."""
    part = obj.part(name)
    pts = surface_points(part.mesh, 0.005)
    out = []
    for q in np.linspace(part.joint.lower, part.joint.upper, steps):
        T = part.joint.transform(float(q))
        out.append(pts @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(out)


def test_surface_points_cover_every_triangle_and_slivers_stay_cheap():
    from scipy.spatial import cKDTree

    slab = trimesh.creation.box([1.0, 0.5, 0.02])
    pts = surface_points(slab, 0.01)
    probe, _ = trimesh.sample.sample_surface(slab, 5000, seed=0)
    assert cKDTree(pts).query(probe)[0].max() <= 0.01
    sliver = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 0.001, 0]], [[0, 1, 2]])
    assert len(surface_points(sliver, 0.01)) < 250  # a 1 m x 1 mm triangle: ~ one row


def test_hull_set_separating_axes_by_hand():
    """A unit cube turned 45 degrees about z: its corner reaches x = 0.707."""
    hulls = HullSet()
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    hulls.add(corners @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T)
    lo = np.array([[0.70, -0.01, -0.1], [0.72, -0.01, -0.1], [0.5, 0.4, -0.1]])
    hi = lo + [0.05, 0.02, 0.2]
    # box 0 touches the corner, box 1 is 13 mm beyond it, box 2 sits off the rotated face
    assert hulls.intersects(lo, hi).tolist() == [True, False, False]
    assert hulls.intersects(lo[1:2], hi[1:2], margin=0.02).tolist() == [True]


def test_open_shell_cabinet_keeps_its_slot_free_and_its_walls_covered(tmp_path):
    """(a) Single-sided walls 1 mm from a drawer: the base's boxes never enter the space
    the drawer slides through, yet cover the walls, shelf and divider."""
    obj = _metric(tmp_path, open_shell_cabinet(), 0.8)
    boxes, pitch, _ = articulated_boxes(obj, PARAMS, tmp_path / "cache")
    assert pitch > 0.002  # far coarser than the 1 mm play: the exact cut does the work
    sweep = _swept_surface(obj, "drawer_0")
    assert not _inside(sweep, boxes["base"], 1e-4).any()
    cov = coverage(obj, boxes)
    assert cov["base"]["uncovered"] < 0.01, cov["base"]
    assert cov["drawer_0"]["uncovered"] == 0.0, cov["drawer_0"]
    assert 1 <= len(boxes["base"]) <= PARAMS.max_pieces


def test_open_shell_cabinet_validates_and_the_drawer_slides_in_sapien(tmp_path):
    obj = convert_object(
        write_partnet(tmp_path / "src", open_shell_cabinet()), PartnetOptions(height=0.8)
    )
    d = save_bundle(obj, tmp_path / "shell")
    from asset_pipeline.assets.build import BuildOptions

    build_asset(d, options=BuildOptions(voxel=PARAMS, cache_dir=tmp_path / "cache"))
    report = validate_asset(d, preview=False)
    assert report.status in ("ok", "repaired"), report.reasons
    (drive,) = report.check("drive_reach", "joint_drawer_0")
    assert drive.passed and drive.value["open_s"] is not None
    (sweep,) = report.check("sweep_penetration", "joint_drawer_0")
    assert sweep.passed and sweep.value <= 0.005


def test_a_door_swing_stays_free_and_its_bar_handle_is_covered(tmp_path):
    """(b) The base never enters the door's swing; the door's boxes cover its bar handle."""
    obj = _metric(tmp_path, bar_handle_door("bar"), 0.8)
    boxes, _, _ = articulated_boxes(obj, PARAMS, tmp_path / "cache")
    assert not _inside(_swept_surface(obj, "door_0"), boxes["base"], 1e-4).any()
    door = obj.part("door_0")
    handle_tip = door.handle.position  # the grasp point on the bar (object frame)
    near = min(
        np.linalg.norm(np.maximum(np.maximum(lo - handle_tip, handle_tip - hi), 0))
        for lo, hi in boxes["door_0"]
    )
    assert near < 0.005  # the bar itself collides: the gripper can close on it
    cov = coverage(obj, boxes)
    assert cov["door_0"]["uncovered"] == 0.0
    # and no box bridges the bar and the door's face: the fingers fit behind the bar
    # (the fixture's frame is kept: height 0.8 m is its own; the bar is 35 mm off the face)
    face, bar_back = BAR_CENTRE[0] - 0.035, BAR_CENTRE[0] - BAR_RADIUS
    behind = np.array([[0.5 * (face + bar_back), BAR_CENTRE[1], BAR_CENTRE[2]]])
    assert not _inside(behind, boxes["door_0"], 0.0).any()
    assert cov["door_0"]["overfill"] < 0.05 and cov["base"]["overfill"] < 0.05, cov


def test_merging_to_a_budget_takes_the_pair_that_adds_the_least_empty_space():
    """A door panel of two strips (A: x 0-4, z 0-10; B: x 4-10, z 0-9, one row short)
    and a knob (x 6-8, z 5) standing 2 cells off B, all one cell thick. At slack 0
    nothing merges; held to 2 boxes, A + B (6 empty cells) merge before B + knob
    (162 - 58 = 104 empty cells)."""
    occ = np.zeros((12, 4, 12), bool)
    occ[0:4, 0, 0:10] = True
    occ[4:10, 0, 0:9] = True
    occ[6:8, 1:3, 5] = True
    runs = np.array([[0, 4, 0, 1, 0, 10], [4, 10, 0, 1, 0, 9], [6, 8, 1, 3, 5, 6]])
    filled, blocked = _Volume(occ), _Volume(np.zeros_like(occ))
    assert len(merge_boxes(runs, filled, blocked, slack=0.0, max_boxes=3)) == 3
    out = merge_boxes(runs, filled, blocked, slack=0.0, max_boxes=2)
    assert sorted(map(tuple, out.tolist())) == [(0, 10, 0, 1, 0, 10), (6, 8, 1, 3, 5, 6)]
    # a slack of 0.7 lets the knob stretch the panel 3 cells thick (202 of 300 cells
    # empty); a one-cell depth limit (202 > 1 x the 100-cell face) keeps it apart
    loose = merge_boxes(runs, filled, blocked, slack=0.7, max_boxes=99)
    assert loose.tolist() == [[0, 10, 0, 3, 0, 10]]
    out = merge_boxes(runs, filled, blocked, slack=0.7, max_boxes=99, depth=1.0)
    assert sorted(map(tuple, out.tolist())) == [(0, 10, 0, 1, 0, 10), (6, 8, 1, 3, 5, 6)]


def test_exact_merging_to_a_budget_skips_pairs_that_would_enter_a_sweep():
    """Three 10 cm boxes in a row along x with 8 mm gaps; a swept hull sits in the first
    gap. Held to 2 boxes, the cheapest pair (either gap: same added volume) is tried
    first; the one across the hull is refused, so the 2nd and 3rd merge."""
    lo = np.array([[0.0, 0, 0], [0.108, 0, 0], [0.216, 0, 0]])
    boxes = [np.stack([a, a + [0.1, 0.1, 0.1]]) for a in lo]
    pts = np.concatenate([surface_points(trimesh.creation.box(bounds=b), 0.01) for b in boxes])
    grid = Grid(origin=np.array([-0.05, -0.05, -0.05]), pitch=0.01, shape=(45, 20, 20))
    hull = HullSet()
    hull.add_box(np.array([0.1015, 0.02, 0.02]), np.array([0.1065, 0.08, 0.08]))
    out = merge_exact(
        boxes, PointIndex(grid, pts), hull, 0.0005, slack=0.0, max_boxes=2,
        min_thickness=0.002, pitch=0.01,
    )  # fmt: skip
    got = sorted(np.round(np.concatenate([b[0], b[1]]), 3).tolist() for b in out)
    assert got == [[0.0, 0, 0, 0.1, 0.1, 0.1], [0.108, 0, 0, 0.316, 0.1, 0.1]]


def test_a_part_of_dozens_of_loose_pieces(tmp_path):
    """(c) A drawer made of 30+ disconnected pieces: few boxes, all of it covered."""
    obj = _metric(tmp_path, many_pieces_drawer(), 0.8)
    drawer = obj.part("drawer_0")
    assert drawer.mesh.body_count >= 30
    boxes, _, _ = articulated_boxes(obj, PARAMS, tmp_path / "cache")
    assert len(boxes["drawer_0"]) <= PARAMS.max_pieces
    cov = coverage(obj, boxes, spacing=0.01)  # 1 cm: samples still on every 2-cm stud
    assert cov["drawer_0"]["uncovered"] == 0.0 and cov["base"]["uncovered"] < 0.01


def test_deterministic_cached_and_keyed_by_parameters(tmp_path):
    obj = _metric(tmp_path, open_shell_cabinet(), 0.8)
    first, _, cached = articulated_boxes(obj, PARAMS, tmp_path / "cache")
    again, _, hit = articulated_boxes(obj, PARAMS, tmp_path / "cache")
    fresh, _, _ = articulated_boxes(obj, PARAMS, tmp_path / "other")
    assert (cached, hit) == (False, True)
    for name in first:
        np.testing.assert_array_equal(np.array(first[name]), np.array(again[name]))
        np.testing.assert_array_equal(np.array(first[name]), np.array(fresh[name]))
    coarser = VoxelCollisionParams(resolution=48, min_pitch=0.012, max_pitch=0.02)
    _, pitch, hit = articulated_boxes(obj, coarser, tmp_path / "cache")
    assert not hit and pitch > 0.012


def test_past_the_time_out_a_coarser_pitch_still_keeps_the_sweeps_free(tmp_path):
    obj = _metric(tmp_path, open_shell_cabinet(), 0.8)
    hurried = VoxelCollisionParams(resolution=96, min_pitch=0.006, max_pitch=0.012, timeout=0.0)
    boxes, pitch, _ = articulated_boxes(obj, hurried, tmp_path / "cache")
    _, normal, _ = articulated_boxes(obj, PARAMS, tmp_path / "cache")
    assert pitch == pytest.approx(8 * normal)  # the last, unhurried attempt
    assert boxes["base"] and boxes["drawer_0"]
    assert not _inside(_swept_surface(obj, "drawer_0"), boxes["base"], 1e-4).any()


def test_swept_hulls_of_a_revolute_box_contain_its_arc():
    """Every corner of a door panel at any angle lies in the hulls of its sweep, to within
    the sag allowed between an arc and its chord (the refinement's margin covers it)."""
    from asset_pipeline.geometry.sweeps import DEFAULT_SAG
    from generator.articulated import Joint

    joint = Joint("revolute", [0.3, -0.3, 0.0], [0, 0, 1], 0.0, 1.5)
    panel = np.array([[0.28, -0.3, 0.0], [0.30, 0.3, 0.6]])
    hulls = HullSet()
    swept_hulls(joint, [panel], hulls)
    corners = np.array([[x, y, z] for x in panel[:, 0] for y in panel[:, 1] for z in panel[:, 2]])
    for q in np.linspace(0, 1.5, 37):
        T = joint.transform(float(q))
        p = corners @ T[:3, :3].T + T[:3, 3]
        assert hulls.intersects(p, p, margin=DEFAULT_SAG).all()
    assert VoxelCollisionParams().margin >= DEFAULT_SAG
