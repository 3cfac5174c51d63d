"""The photo's texture (asset_pipeline.photo.texture): a box seen from a known camera."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh
from test_photo_camera import box, cabinet, camera, render_ids

from asset_pipeline.assets.build import build_asset
from asset_pipeline.geometry.metric import to_metric
from asset_pipeline.photo.texture import bake_photo_texture
from generator.articulated import Joint, Part, Primitive
from generator.bundle import save_bundle
from generator.mesh_repair.closing import has_texture_image, is_closed_volume, watertight_object

BACKGROUND = (20, 40, 200)  # blue: must never reach a texture that is sampled
DRAWER = (220, 30, 30)


def photo_of(obj, cam):
    """A photo of ``obj``: the base painted with a left-to-right gradient, the drawer red,
    the background blue; with its part mask."""
    ids = render_ids(obj, cam)
    image = np.zeros((cam.height, cam.width, 3), np.uint8)
    image[:] = BACKGROUND
    cols = np.broadcast_to(np.arange(cam.width), ids.shape)
    base = ids == 1
    image[base, 0] = 90 + cols[base] // 2
    image[base, 1] = 160
    image[base, 2] = 70
    image[ids == 2] = DRAWER
    return image, ids


def texture_at(mesh: trimesh.Trimesh, uv: np.ndarray) -> np.ndarray:
    """(N, 3) texels (nearest) at trimesh uv coordinates (origin bottom-left)."""
    img = np.asarray(mesh.visual.material.baseColorTexture.convert("RGB"))
    h, w = img.shape[:2]
    c = np.clip((uv[:, 0] * w).astype(int), 0, w - 1)
    r = np.clip(((1 - uv[:, 1]) * h).astype(int), 0, h - 1)
    return img[r, c].astype(int)


def face_texels(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F, 3) texel at every face's centroid in texture space."""
    return texture_at(mesh, mesh.visual.uv[mesh.faces].mean(axis=1))


@pytest.fixture(scope="module")
def baked():
    obj = cabinet()
    cam = camera(az=30.0, el=20.0, w=200, h=150)
    image, ids = photo_of(obj, cam)
    out, info = bake_photo_texture(obj, image, cam, ids > 0, ids, {"base": 1, "drawer_0": 2})
    return obj, cam, image, ids, out, info


def test_seen_faces_carry_the_photo(baked):
    obj, cam, image, ids, out, info = baked
    drawer = out.part("drawer_0").mesh
    front = drawer.face_normals[:, 0] > 0.99  # the drawer's front (+x) faces the camera
    assert front.any()
    assert np.abs(face_texels(drawer)[front] - DRAWER).max() <= 2
    base = out.part("base").mesh
    side = base.face_normals[:, 1] > 0.99  # +y side of the body, seen at azimuth 30
    assert side.any()
    uv, _ = cam.project(base.triangles_center[side])
    expected = image[uv[:, 1].astype(int), uv[:, 0].astype(int)].astype(int)
    error = np.abs(face_texels(base)[side] - expected).max(axis=1)
    # every face of the side but the ring that borders unseen faces (its texture
    # coordinates blend toward the unseen colour's block)
    rim = np.zeros(len(base.faces), bool)
    unseen = base.face_normals[:, 1] < 0.99
    ring = np.zeros(len(base.vertices), bool)
    ring[base.faces[unseen].ravel()] = True
    rim = ring[base.faces].any(axis=1)
    assert (error[~rim[side]] <= 3).all()
    assert (~rim[side]).mean() > 0.7
    assert info["parts"]["base"]["seen"] > 0.5 and info["parts"]["drawer_0"]["seen"] > 0.5


def test_unseen_faces_get_the_parts_colour_not_grey(baked):
    obj, cam, image, ids, out, info = baked
    drawer = out.part("drawer_0").mesh
    back = drawer.face_normals[:, 0] < -0.99  # inside the body: never seen
    assert back.any()
    assert np.abs(face_texels(drawer)[back] - DRAWER).max() <= 2
    base = out.part("base").mesh
    hidden = (base.face_normals[:, 0] < -0.99) | (base.face_normals[:, 2] < -0.99)
    assert hidden.any()
    colours = face_texels(base)[hidden]
    seen_colours = image[ids == 1].astype(int)
    lo, hi = seen_colours.min(0), seen_colours.max(0)
    assert ((colours >= lo - 2) & (colours <= hi + 2)).all()  # the body's photo colours
    assert info["parts"]["base"]["fill_from"] == "seen"
    # no texture that a face samples holds the photo's background
    for p in out.parts:
        texels = face_texels(p.mesh)
        assert (np.abs(texels - BACKGROUND).sum(axis=1) > 30).all(), p.name


def test_a_part_hidden_in_the_photo_takes_the_objects_colour():
    obj = cabinet()
    hidden = Part(
        "door_1",
        "door",
        box((0.02, 0.5, 0.5), (-0.31, 0.0, 0.4)),  # on the back: the camera sees the front
        Joint("revolute", origin=(-0.32, 0.25, 0.4), axis=(0, 0, 1), lower=0.0, upper=1.5),
    )
    obj.parts.append(hidden)
    cam = camera(az=30.0, el=20.0, w=200, h=150)
    image, ids = photo_of(obj, cam)
    assert not (ids == 3).any()
    out, info = bake_photo_texture(obj, image, cam, ids > 0, ids, {"base": 1, "drawer_0": 2})
    assert info["parts"]["door_1"]["seen"] == 0.0
    assert info["parts"]["door_1"]["fill_from"] == "object"
    texels = face_texels(out.part("door_1").mesh)
    assert np.allclose(texels, np.median(image[ids > 0], axis=0), atol=2)
    assert not np.allclose(texels, 128, atol=20) and not np.allclose(texels, 180, atol=20)


def test_textured_meshes_stay_closed_and_build_writes_base_colour_textures(baked, tmp_path):
    obj, cam, image, ids, out, info = baked
    for p in out.parts:
        assert has_texture_image(p.mesh) and is_closed_volume(p.mesh), p.name
    # the build's closing step keeps a textured closed mesh unchanged
    metric = to_metric(out)
    kept = watertight_object(metric)
    for a, b in zip(metric.parts, kept.parts, strict=True):
        assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
        assert np.array_equal(a.mesh.faces, b.mesh.faces)
        assert np.array_equal(a.mesh.visual.uv, b.mesh.visual.uv)
    # give the parts their boxes as collision primitives and build
    for p, extents, centre in (
        (out.part("base"), (0.6, 1.0, 0.8), (0.0, 0.0, 0.4)),
        (out.part("drawer_0"), (0.05, 0.8, 0.22), (0.325, 0.0, 0.62)),
    ):
        T = np.eye(4)
        T[:3, 3] = centre
        p.primitives = [Primitive("box", np.array(extents), T)]
    folder = save_bundle(out, tmp_path / "cab")
    build_asset(folder)
    for name in ("base", "drawer_0"):
        data = (folder / "visual" / f"{name}.glb").read_bytes()
        length = struct.unpack_from("<I", data, 12)[0]
        gltf = json.loads(data[20 : 20 + length])
        pbr = gltf["materials"][0]["pbrMetallicRoughness"]
        assert "baseColorTexture" in pbr and gltf["images"], name
        visual = trimesh.load(folder / "visual" / f"{name}.glb", force="mesh")
        assert has_texture_image(visual)
        # read back as it is (no vertex merging): as many pieces as the untextured part,
        # each still closed (texture coordinates never split a vertex)
        pieces = len(obj.part(name).mesh.split(only_watertight=False))
        assert len(visual.split(only_watertight=False)) == pieces, name
        assert visual.is_watertight, name


def test_fine_mesh_splits_the_long_edges_only():
    from asset_pipeline.photo.texture import _fine_mesh

    coarse = trimesh.creation.box((1.0, 1.0, 1.0))  # 12 faces, edges up to 1.41
    fine, origin = _fine_mesh(coarse, 0.2, 500_000)
    assert fine.edges_unique_length.max() <= 0.2 and fine.is_watertight
    assert len(origin) == len(fine.faces) and set(origin.tolist()) == set(range(12))
    # a finely meshed part whose one cut left a small cap of long faces: only the cap and
    # the faces round it split, the rest of the sphere keeps its faces
    sphere = trimesh.creation.icosphere(subdivisions=4)  # 5120 faces, edges ~0.06
    cut = trimesh.intersections.slice_mesh_plane(sphere, [0, 0, -1], [0, 0, 0.95], cap=True)
    assert cut.is_watertight
    split, origin = _fine_mesh(cut, 0.2, 500_000)
    assert split.is_watertight and split.edges_unique_length.max() <= 0.2
    assert len(cut.faces) < len(split.faces) < len(cut.faces) + 400
    assert (np.bincount(origin, minlength=len(cut.faces)) == 1).mean() > 0.9
    # and never past max_faces
    capped, _ = _fine_mesh(coarse, 0.01, 1000)
    assert 12 < len(capped.faces) <= 1000
