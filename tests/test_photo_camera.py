"""The photo's camera (asset_pipeline.photo.camera): model, rasterizer, part matching, fit."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from asset_pipeline.photo.camera import (
    CameraFormatError,
    FitOptions,
    PhotoCamera,
    fit_camera,
    look_at_pose,
    match_parts,
    rasterize,
    read_camera,
    scene_mesh,
    silhouette_iou,
    write_camera,
)
from generator.articulated import ArticulatedObject, Joint, Part


def box(extents, centre) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents)
    m.apply_translation(centre)
    return m


def cabinet() -> ArticulatedObject:
    """A box body with a drawer front on its +x face (not symmetric: the drawer is high)."""
    base = Part("base", "base", box((0.6, 1.0, 0.8), (0.0, 0.0, 0.4)))
    drawer = Part(
        "drawer_0",
        "drawer",
        box((0.05, 0.8, 0.22), (0.325, 0.0, 0.62)),
        Joint("prismatic", origin=(0.3, 0.0, 0.62), axis=(1.0, 0.0, 0.0), lower=0.0, upper=0.4),
    )
    return ArticulatedObject([base, drawer], category="cabinet", scale=1.0)


def camera(az=25.0, el=20.0, dist=3.0, fov=40.0, w=160, h=120, roll=0.0) -> PhotoCamera:
    target = np.array([0.0, 0.0, 0.4])
    a, e = math.radians(az), math.radians(el)
    eye = target + dist * np.array(
        [math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)]
    )
    f = 0.5 * h / math.tan(math.radians(fov) / 2)
    return PhotoCamera(w, h, f, f, w / 2, h / 2, look_at_pose(eye, target, math.radians(roll)))


def render_ids(obj: ArticulatedObject, cam: PhotoCamera) -> np.ndarray:
    scene = scene_mesh(obj)
    r = rasterize(scene.vertices, scene.faces, cam)
    return np.where(r.face >= 0, scene.face_part[np.maximum(r.face, 0)] + 1, 0)


def test_projection_and_frame_change():
    cam = camera()
    # the look-at target projects onto the image centre
    uv, z = cam.project(np.array([[0.0, 0.0, 0.4]]))
    assert np.allclose(uv, [[80.0, 60.0]], atol=1e-9) and z[0] == pytest.approx(3.0)
    # OpenCV axes: world up (+z) is image up (smaller row)
    uv_up, _ = cam.project(np.array([[0.0, 0.0, 0.6]]))
    assert uv_up[0, 1] < 60.0
    # a similarity of the object frame moves the camera along: same pixels
    pts = np.random.default_rng(0).uniform(-0.5, 0.5, (20, 3))
    moved = cam.transformed(2.5, np.array([0.1, -0.2, 0.3]))
    a, _ = cam.project(pts)
    b, _ = moved.project(2.5 * pts + [0.1, -0.2, 0.3])
    assert np.allclose(a, b, atol=1e-9)
    # resampling the image scales the pixels
    half, _ = cam.resized(80, 60).project(pts)
    assert np.allclose(half, a / 2, atol=1e-9)


def test_camera_json_round_trip(tmp_path):
    cam = camera()
    cam.fit = {"silhouette_iou": 0.9, "part_iou": None}
    write_camera(cam, tmp_path, texture={"seconds": 1.0})
    back = read_camera(tmp_path)
    assert back is not None and back.width == 160 and back.height == 120
    assert np.allclose(back.pose, cam.pose) and back.fx == pytest.approx(cam.fx)
    assert back.fit == {"silhouette_iou": 0.9, "part_iou": None}
    assert read_camera(tmp_path / "nowhere") is None
    (tmp_path / "camera.json").write_text('{"schema": "pact.camera", "version": 1}')
    with pytest.raises(CameraFormatError, match="camera.json"):
        read_camera(tmp_path)


def test_rasterizer_silhouette_of_a_box_is_its_projected_hull():
    from scipy.spatial import ConvexHull
    from skimage.draw import polygon

    cam = camera(w=200, h=150)
    mesh = box((0.6, 1.0, 0.8), (0.0, 0.0, 0.4))
    r = rasterize(mesh.vertices, mesh.faces, cam)
    uv, _ = cam.project(mesh.vertices)
    hull = uv[ConvexHull(uv).vertices]
    expected = np.zeros((150, 200), bool)
    # pixel centres inside the hull (skimage's polygon takes centre coordinates)
    rr, cc = polygon(hull[:, 1] - 0.5, hull[:, 0] - 0.5, expected.shape)
    expected[rr, cc] = True
    assert silhouette_iou(r.covered, expected) > 0.99
    # depth: the nearest corner is nearer than the box's centre
    assert r.depth[r.covered].min() < np.linalg.norm(cam.centre - [0, 0, 0.4])
    assert np.isinf(r.depth[~r.covered]).all()


def test_match_parts_recovers_a_permutation():
    rendered = np.zeros((6, 9), int)
    rendered[:, 0:3], rendered[:, 3:6], rendered[:, 6:9] = 1, 2, 3
    mask = np.zeros_like(rendered)
    mask[:, 0:3], mask[:, 3:6], mask[:, 6:9] = 3, 1, 2  # ids permuted
    match, iou = match_parts(rendered, mask)
    assert match == {3: 1, 1: 2, 2: 3}
    assert iou == {1: 1.0, 2: 1.0, 3: 1.0}
    # half of id 2 painted as background: IoU 1/2; an id with no rendered part: 0
    mask[:3, 6:9] = 0
    mask[0, 0] = 4
    _, iou = match_parts(rendered, mask)
    assert iou[2] == pytest.approx(0.5) and iou[4] == 0.0


def test_fit_recovers_a_known_camera_from_a_render():
    obj = cabinet()
    truth = camera(az=25.0, el=20.0, fov=40.0)
    ids = render_ids(obj, truth)
    assert set(np.unique(ids)) == {0, 1, 2}
    fitted = fit_camera(obj, ids > 0, ids, FitOptions())
    R = fitted.pose[:3, :3].T @ truth.pose[:3, :3]
    angle = math.degrees(math.acos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
    assert angle < 3.0
    assert fitted.fx == pytest.approx(truth.fx, rel=0.15)
    distance = np.linalg.norm(truth.centre - [0, 0, 0.4])
    assert np.linalg.norm(fitted.centre - truth.centre) < 0.1 * distance
    assert fitted.fit["silhouette_iou"] > 0.95 and fitted.fit["part_iou"] > 0.9
    assert fitted.fit["part_match"] == {1: "base", 2: "drawer_0"}


def test_fit_without_a_mask_uses_the_silhouette():
    obj = cabinet()
    truth = camera(az=-30.0, el=10.0, fov=50.0)
    sil = render_ids(obj, truth) > 0
    fitted = fit_camera(obj, sil)
    assert fitted.fit["part_iou"] is None and fitted.fit["silhouette_iou"] > 0.95
    with pytest.raises(ValueError, match="empty"):
        fit_camera(obj, np.zeros_like(sil))
