"""generator.mesh_repair.closing (watertight repair / remesh) and asset_pipeline.geometry.metric (the metric step)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from asset_pipeline.geometry.metric import DEFAULT_HEIGHTS, metric_factor, to_metric
from generator.articulated import ArticulatedObject, Handle, Joint, Part, Primitive
from generator.mesh_repair.cleaning import union_solids
from generator.mesh_repair.closing import is_closed_volume, remesh_pitch, slice_closed, watertight


def _stacked_boxes() -> trimesh.Trimesh:
    """Two closed boxes touching along a face (corners coincide): closed, two bodies."""
    a = trimesh.creation.box([0.4, 0.4, 0.1])
    b = trimesh.creation.box([0.4, 0.4, 0.1])
    b.apply_translation([0, 0, 0.1])
    return trimesh.util.concatenate([a, b])


def test_closed_multibody_mesh_is_kept_as_is():
    m = _stacked_boxes()
    m.visual.face_colors = [10, 20, 30, 255]
    out = watertight(m)
    assert out is not m
    np.testing.assert_array_equal(out.faces, m.faces)
    np.testing.assert_array_equal(out.vertices, m.vertices)
    assert out.volume == pytest.approx(2 * 0.4 * 0.4 * 0.1)


def test_inside_out_mesh_is_flipped():
    m = trimesh.creation.box([0.2, 0.3, 0.4])
    m.invert()
    assert m.volume < 0
    out = watertight(m)
    assert is_closed_volume(out) and out.volume == pytest.approx(0.024)


def test_small_hole_is_filled_without_remesh():
    m = trimesh.creation.box([0.3, 0.3, 0.3])
    keep = np.ones(len(m.faces), bool)
    keep[np.where(m.face_normals[:, 2] > 0.99)[0]] = False  # remove the top quad
    m.update_faces(keep)
    assert not m.is_watertight
    out = watertight(m)
    assert is_closed_volume(out)
    assert len(out.vertices) == 8  # same geometry, not a voxel remesh
    assert out.volume == pytest.approx(0.027)


def test_large_hole_triggers_voxel_remesh_with_colours():
    s = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    # colour the lower half red, the upper half blue, then cut a cap off the top
    colors = np.where(s.vertices[:, 2:3] < 0, [255, 0, 0, 255], [0, 0, 255, 255]).astype(np.uint8)
    s.visual.vertex_colors = colors
    keep = s.face_normals[:, 2] < 0.6
    s.update_faces(keep)
    s.remove_unreferenced_vertices()
    assert not s.is_watertight
    out = watertight(s)
    assert is_closed_volume(out)
    pitch = remesh_pitch(s.extents)
    # the remeshed surface stays within about one voxel of the input bounds
    np.testing.assert_allclose(out.bounds, s.bounds, atol=1.01 * pitch)
    vc = out.visual.vertex_colors
    low = out.vertices[:, 2] < -0.1
    high = out.vertices[:, 2] > 0.1
    assert (vc[low, 0] == 255).all() and (vc[high, 2] == 255).all()


def test_slice_closed_caps_a_union_of_differently_coloured_solids():
    """Two unit cubes of different colours side by side (x 0..1 red, 1..2 green), joined
    by union_solids: closed only with the vertices where the colours meet merged. Cut at
    x = 1.75 keeping x < 1.75, the piece is closed, 1.75 cubic units, red then green (the
    cut's vertices nearest the green cube's far corners)."""
    red = trimesh.creation.box((1, 1, 1))
    red.apply_translation((0.5, 0.5, 0.5))
    red.visual.vertex_colors = [255, 0, 0, 255]
    green = trimesh.creation.box((1, 1, 1))
    green.apply_translation((1.5, 0.5, 0.5))
    green.visual.vertex_colors = [0, 255, 0, 255]
    both = union_solids([red, green])
    assert not both.is_watertight and is_closed_volume(both)  # split where colours meet
    cut = slice_closed(both, np.array([-1.0, 0.0, 0.0]), np.array([1.75, 0.0, 0.0]))
    assert cut.is_watertight and is_closed_volume(cut)
    assert cut.volume == pytest.approx(1.75)
    np.testing.assert_allclose(cut.bounds, [[0, 0, 0], [1.75, 1, 1]], atol=1e-9)
    colours = np.asarray(cut.visual.vertex_colors)[:, :3]
    x = cut.vertices[:, 0]
    assert (colours[x < 0.5] == [255, 0, 0]).all() and (colours[x > 1.5] == [0, 255, 0]).all()
    # an open mesh is cut open; a plane past the mesh leaves nothing
    open_box = trimesh.creation.box((1, 1, 1))
    open_box.update_faces(np.arange(len(open_box.faces)) != 0)
    half = slice_closed(open_box, np.array([0.0, 0.0, 1.0]), np.zeros(3))
    assert half is not None and not half.is_watertight
    assert slice_closed(red, np.array([1.0, 0.0, 0.0]), np.array([5.0, 0.0, 0.0])) is None


def test_remesh_pitch_thin_part():
    # a 2 cm thick door of 0.9 m: at least 3 voxels across its thickness
    assert remesh_pitch(np.array([0.02, 0.5, 0.9])) == pytest.approx(0.02 / 3)
    assert remesh_pitch(np.array([0.001, 0.5, 0.9])) == pytest.approx(0.9 / 256)  # floor
    assert remesh_pitch(np.array([0.2, 0.5, 0.9])) == pytest.approx(0.9 / 64)
    assert remesh_pitch(np.array([0.03, 0.5, 0.9])) == pytest.approx(0.01)


def _normalized_object(category: str = "cabinet", scale=None) -> ArticulatedObject:
    """A unit-cube object: base 0.8 x 1.0 x 1.0 box, a drawer and a door, z in [-0.5, 0.5]."""
    base = trimesh.creation.box([0.8, 1.0, 1.0])
    prim = Primitive("box", [0.8, 1.0, 1.0], np.eye(4))
    drawer = trimesh.creation.box([0.1, 0.6, 0.3])
    drawer.apply_translation([0.45, 0.1, -0.2])
    T = np.eye(4)
    T[:3, 3] = [0.45, 0.1, -0.2]
    door = trimesh.creation.box([0.05, 0.5, 0.4])
    door.apply_translation([0.425, 0.0, 0.25])
    cyl = np.eye(4)
    cyl[:3, 3] = [0.46, 0.2, 0.25]
    return ArticulatedObject(
        [
            Part("base", "base", base, primitives=[prim]),
            Part(
                "drawer_0",
                "drawer",
                drawer,
                joint=Joint("prismatic", [0.5, 0.1, -0.2], [1, 0, 0], 0.0, 0.4),
                primitives=[Primitive("box", [0.1, 0.6, 0.3], T)],
                handle=Handle([0.52, 0.1, -0.2]),
            ),
            Part(
                "door_0",
                "door",
                door,
                joint=Joint("revolute", [0.45, -0.25, 0.25], [0, 0, -1], 0.0, 1.2),
                primitives=[Primitive("cylinder", [0.02, 0.1], cyl)],
            ),
        ],
        category=category,
        scale=scale,
    )


def test_to_metric_uses_category_height_and_moves_everything():
    obj = _normalized_object("refrigerator")
    out = to_metric(obj)
    s = DEFAULT_HEIGHTS["refrigerator"]  # unit-tall object -> factor = height
    assert out.scale == 1.0 and out.provenance["metric_scale"] == pytest.approx(s)
    b = out.bounds()
    assert b[0, 2] == pytest.approx(0.0, abs=1e-6)
    assert b[1, 2] - b[0, 2] == pytest.approx(s, rel=1e-6)
    base_b = out.base.mesh.bounds
    np.testing.assert_allclose(base_b.mean(axis=0)[:2], [0, 0], atol=1e-6)
    offset = np.array([0, 0, 0.5 * s])  # z: -0.5 -> 0
    d = out.part("drawer_0")
    assert d.joint.upper == pytest.approx(0.4 * s)  # prismatic range scales
    np.testing.assert_allclose(d.joint.origin, np.array([0.5, 0.1, -0.2]) * s + offset, atol=1e-6)
    np.testing.assert_allclose(
        d.handle.position, np.array([0.52, 0.1, -0.2]) * s + offset, atol=1e-6
    )
    np.testing.assert_allclose(d.primitives[0].size, [0.1 * s, 0.6 * s, 0.3 * s])
    np.testing.assert_allclose(
        d.primitives[0].to_mesh().bounds, d.mesh.bounds, atol=1e-6
    )  # primitive follows the mesh
    door = out.part("door_0")
    assert door.joint.upper == pytest.approx(1.2)  # revolute range does not
    np.testing.assert_allclose(door.joint.axis, [0, 0, -1])
    np.testing.assert_allclose(door.primitives[0].size, [0.02 * s, 0.1 * s])
    # the input is untouched
    assert obj.scale is None and obj.part("drawer_0").joint.upper == 0.4


def test_height_hint_and_known_scale():
    obj = _normalized_object()
    assert metric_factor(obj, height=0.5) == pytest.approx(0.5)
    assert metric_factor(obj) == pytest.approx(DEFAULT_HEIGHTS["cabinet"])
    assert metric_factor(obj, default_heights={"cabinet": 2.0}) == pytest.approx(2.0)
    known = _normalized_object(scale=0.7)
    assert metric_factor(known, height=3.0) == pytest.approx(0.7)  # metric scale wins
    out = to_metric(known)
    assert out.bounds()[1, 2] == pytest.approx(0.7, rel=1e-6)
    with pytest.raises(ValueError, match="height"):
        metric_factor(obj, height=-1.0)
