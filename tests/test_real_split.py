"""The real dev split's renderer and writer (generator.data.real_split), on a procedural object."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from generator.bundle import load_bundle
from generator.data.real_split import (
    LABELS,
    STYLES,
    SplitSource,
    read_manifest,
    render_object_views,
    write_real_split,
)
from generator.data.render import part_slots, posed_vertices, rest_qpos
from generator.procedural import sample_object

SIZE = 64


@pytest.fixture(scope="module")
def obj():
    from generator.data.render import RenderUnavailableError, check_render_device

    try:
        check_render_device()
    except RenderUnavailableError as e:
        pytest.skip(str(e))
    return sample_object("cabinet", 5)


@pytest.fixture(scope="module")
def renders(obj):
    out = render_object_views(obj, "cab", views=2, image_size=SIZE, seed=0, supersample=1)
    return {iid: (style, view, rv) for iid, style, _k, view, rv in out}


def test_masks_hold_part_ids_and_no_scenery(obj, renders):
    n_slots = len(part_slots(obj))
    assert {s for s, _, _ in renders.values()} == set(STYLES)
    for style, _view, rv in renders.values():
        assert rv.rgb.shape == (SIZE, SIZE, 3) and rv.mask.shape == (SIZE, SIZE)
        ids = set(np.unique(rv.mask).tolist())
        assert ids <= set(range(n_slots + 1))
        assert 1 in ids and len(ids - {0, 1}) >= 1, (style, ids)
        # the mask is exactly the object's pixels: floor, walls, clutter are 0
        assert np.array_equal(rv.mask > 0, rv.labels == LABELS.index("object"))
        scenery = np.isin(
            rv.labels, [LABELS.index(k) for k in ("floor", "wall", "clutter", "furniture")]
        )
        assert scenery.sum() > 0.2 * SIZE * SIZE
        assert not rv.mask[scenery].any()


def test_product_background_is_near_white(renders):
    for style, _view, rv in renders.values():
        if style != "product":
            continue
        bg = rv.rgb[rv.mask == 0].astype(float)
        assert np.median(bg) > 225 and bg.mean() > 205
        assert np.median(bg.max(1) - bg.min(1)) < 12  # white or light grey, not coloured


def test_room_has_floor_walls_and_clutter_beside_the_object(obj, renders):
    hi_x = posed_vertices(obj, rest_qpos(obj))[:, 0].max()
    clutter_px = 0
    for style, view, rv in renders.values():
        if style != "room":
            continue
        assert (rv.labels == LABELS.index("floor")).any()
        assert (rv.labels == LABELS.index("wall")).any()
        clutter = rv.labels == LABELS.index("clutter")
        assert not rv.mask[clutter].any()
        clutter_px += int(clutter.sum())
        props = [p for p in view.props if p.label == "clutter"]
        assert props
        for p in props:  # never in front of the object
            assert p.pose[0, 3] <= hi_x + 1e-6
    assert clutter_px > 0


def test_cameras_project_the_object_onto_its_mask(obj, renders):
    pts = posed_vertices(obj, rest_qpos(obj))
    for _style, _view, rv in renders.values():
        cam = pts @ rv.extrinsics[:3, :3].T.astype(float) + rv.extrinsics[:3, 3]
        uv = cam @ rv.intrinsics.T.astype(float)
        uv = uv[:, :2] / uv[:, 2:]
        assert (cam[:, 2] > 0).all()
        assert (uv >= 0).all() and (uv <= SIZE).all()
        rows, cols = np.nonzero(rv.mask)
        lo, hi = uv.min(0), uv.max(0)
        # the mask's extent is the projected extent of the object (within two pixels)
        assert np.allclose([cols.min(), rows.min()], lo, atol=2.5)
        assert np.allclose([cols.max() + 1, rows.max() + 1], hi, atol=2.5)


def test_deterministic_for_a_seed(obj, renders):
    again = render_object_views(obj, "cab", views=2, image_size=SIZE, seed=0, supersample=1)
    for iid, _style, _k, view, rv in again:
        assert np.array_equal(rv.rgb, renders[iid][2].rgb)
        assert np.array_equal(rv.mask, renders[iid][2].mask)
        assert np.allclose(view.eye, renders[iid][1].eye)
    other = render_object_views(
        obj, "cab", styles=("room",), views=1, image_size=SIZE, seed=1, supersample=1
    )
    assert not np.array_equal(other[0][4].rgb, renders["cab_room_0"][2].rgb)


def test_write_split_layout_manifest_and_resume(obj, tmp_path):
    def broken():
        raise ValueError("nothing to articulate")

    sources = [
        SplitSource("cab", lambda: obj, {"source_repo": "owner/repo", "source_path": "x/cab"}),
        SplitSource("bad", broken, {"source_repo": "owner/repo"}),
    ]
    kw = dict(views=1, image_size=SIZE, seed=0, supersample=2)
    manifest = write_real_split(tmp_path, sources, **kw)
    ids = ["cab_product_0", "cab_room_0"]
    for iid in ids:
        rgb = np.asarray(Image.open(tmp_path / "images" / f"{iid}.png"))
        mask = np.asarray(Image.open(tmp_path / "images" / f"{iid}.mask.png"))
        assert rgb.shape == (SIZE, SIZE, 3) and mask.shape == (SIZE, SIZE) and mask.max() >= 2
        assert json.loads((tmp_path / "images" / f"{iid}.json").read_text()) == {
            "category": "cabinet"
        }
    gt = load_bundle(tmp_path / "gt" / "cab")
    assert [p.name for p in gt.parts] == [p.name for p in obj.parts] and gt.category == "cabinet"
    assert read_manifest(tmp_path) == manifest
    assert manifest["styles"] == list(STYLES) and manifest["views"] == 1
    assert [o["id"] for o in manifest["objects"]] == ["cab"]
    assert manifest["objects"][0]["source"]["source_repo"] == "owner/repo"
    assert [f["id"] for f in manifest["failed"]] == ["bad"]
    images = {im["id"]: im for im in manifest["images"]}
    assert sorted(images) == ids
    for im in images.values():
        assert im["object"] == "cab" and im["category"] == "cabinet"
        assert np.asarray(im["intrinsics"]).shape == (3, 3)
        assert np.asarray(im["extrinsics"]).shape == (4, 4)
        assert 20 <= abs(im["azimuth_deg"]) <= 50 or im["style"] == "room"
    # resumable: a second run keeps the written object as it is
    stamp = (tmp_path / "images" / "cab_room_0.png").stat().st_mtime_ns
    again = write_real_split(tmp_path, sources, **kw)
    assert (tmp_path / "images" / "cab_room_0.png").stat().st_mtime_ns == stamp
    assert again["images"] == manifest["images"]
    with pytest.raises(ValueError, match="written with"):
        write_real_split(tmp_path, sources, views=2, image_size=SIZE, seed=0, supersample=2)


def test_the_dev_halves_are_disjoint_and_named():
    from generator.data.real_split import dev_half

    a, b = dev_half("A"), dev_half("B")
    assert len(a) == 21 and len(b) == 19 and not set(a) & set(b)
    with pytest.raises(ValueError, match="no half 'C'"):
        dev_half("C")
