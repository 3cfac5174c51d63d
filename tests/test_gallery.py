"""The HTML gallery: page structure, 3D scenes, the local server, and headless-Chromium
screenshots (the page as a whole, and the 3D view drawing an object whose door a
slider opens)."""

from __future__ import annotations

import json
import math
import re
import subprocess
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import trimesh
from asset_fixtures import write_box_cabinet, write_two_part_cabinet
from PIL import Image

from asset_pipeline.catalog.registry import Catalog, register_asset_dir
from asset_pipeline.gallery.page import Shot, screenshots, serving, write_gallery

REPO = Path(__file__).resolve().parents[1]
CHROMIUM = Path("/usr/bin/chromium")
THREE = REPO / "asset_pipeline" / "gallery" / "web" / "three" / "build" / "three.module.js"
needs_chromium = pytest.mark.skipif(
    not CHROMIUM.exists() or not THREE.exists(),
    reason="needs /usr/bin/chromium and three.js (scripts/setup.sh installs both: apt-get "
    "install -y chromium as root; npm pack three)",
)


def write_asset(folder: Path, id: str, status: str, category: str) -> Path:
    return write_two_part_cabinet(folder, id, status, category)


def _fake_outputs(tmp_path: Path) -> tuple[Path, Path]:
    """Photos + masks in one folder, three built assets (ok, repaired, failed) in OUT."""
    photos, out = tmp_path / "photos", tmp_path / "out"
    photos.mkdir()
    rng = np.random.default_rng(0)
    for k, (name, status) in enumerate([("cab_a", "ok"), ("cab_b", "repaired"), ("mw", "failed")]):
        img = np.full((96, 128, 3), 235, np.uint8)
        img[20:80, 30:100] = rng.integers(60, 200, 3)
        Image.fromarray(img).save(photos / f"{name}.png")
        mask = np.zeros((96, 128), np.uint8)
        mask[20:80, 30:100] = 1
        mask[30:50, 40:90] = 2
        Image.fromarray(mask, "L").save(photos / f"{name}.mask.png")
        d = write_asset(out / name, name, status, "microwave" if name == "mw" else "cabinet")
        prev = np.zeros((120, 240, 3), np.uint8)
        prev[:, :120] = (200, 120, 40)
        prev[:, 120:] = (40, 120, 200 - 40 * k)
        Image.fromarray(prev).save(d / "preview.png")
    return photos, out


def test_gallery_from_folders(tmp_path: Path) -> None:
    _, out = _fake_outputs(tmp_path)
    index = write_gallery(out)
    assert index == out / "index.html"
    page = index.read_text()
    assert page.count("class='card'") == 3
    assert "from the asset folders" in page
    assert 'src="cab_a/preview.png"' in page
    assert "rest_drift" in page and "0.004" in page and "0.002" in page  # failed check of mw
    assert "add_damping(joint_door_0)" in page  # repairs of cab_b
    assert "90.0°" in page and "0.350 m" in page  # limits in degrees and metres
    assert_relative_links(page, out)


def test_gallery_from_catalog_with_inputs(tmp_path: Path) -> None:
    photos, out = _fake_outputs(tmp_path)
    with Catalog(out) as cat:
        for name in ("cab_a", "cab_b", "mw"):
            register_asset_dir(
                cat, out / name, source_image=str(photos / f"{name}.png"), generator="pact"
            )
        cat.record_failure("lost_one", "generator crashed <OOM>")
    page = write_gallery(out).read_text()
    assert "from the catalog" in page and page.count("class='card'") == 4
    assert 'src="gallery/cab_a/input.png"' in page and 'src="gallery/cab_a/mask.png"' in page
    assert "generator crashed &lt;OOM&gt;" in page  # escaped
    mask = np.asarray(Image.open(out / "gallery" / "cab_a" / "mask.png"))
    assert mask.ndim == 3 and len(np.unique(mask.reshape(-1, 3), axis=0)) == 3  # colour-coded ids
    for src in re.findall(r'src="([^"]+)"', page):
        assert (out / src).is_file(), src


@needs_chromium
def test_screenshot_is_not_blank(tmp_path: Path) -> None:
    photos, out = _fake_outputs(tmp_path)
    with Catalog(out) as cat:
        for name in ("cab_a", "cab_b", "mw"):
            register_asset_dir(cat, out / name, source_image=str(photos / f"{name}.png"))
    write_gallery(out)
    res = subprocess.run(
        ["bash", str(REPO / "scripts" / "gallery_screenshot.sh"), str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        env={"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "HEIGHT": "1400"},
    )
    assert res.returncode == 0, res.stderr
    png = out / "gallery.png"
    img = np.asarray(Image.open(png).convert("RGB")).astype(float)
    assert img.shape[:2] == (1400, 1280)
    assert img.std() > 10  # not a blank page
    assert len(np.unique(img.reshape(-1, 3)[::37], axis=0)) > 20  # text, images, badges


# --------------------------------------------------------------------------- structure


def assert_relative_links(page: str, out: Path) -> None:
    """Every src, href, data-scene and import-map URL is relative and names a file in OUT."""
    urls = re.findall(r"(?:src|href|data-scene)=[\"']([^\"']+)[\"']", page)
    imap = json.loads(re.search(r'<script type="importmap">(.*?)</script>', page, re.S).group(1))
    urls += list(imap["imports"].values())
    assert urls
    for url in urls:
        assert not re.match(r"(/|[a-z]+:)", url), url  # no absolute path, no scheme
        if not url.endswith("/"):
            assert (out / url.split("?")[0]).is_file(), url


def test_page_structure_sliders_and_scenes(tmp_path: Path) -> None:
    _, out = _fake_outputs(tmp_path)
    page = write_gallery(out).read_text()
    assert_relative_links(page, out)
    assert page.count("class='card'") == 3 and page.count("class='viewer'") == 3
    # the viewer: local ES modules through an import map, three.js and its licence copied
    assert '<script type="module" src="gallery_web/viewer.js">' in page
    web = out / "gallery_web"
    assert (web / "viewer.js").is_file()
    three = (
        "three/LICENSE",
        "three/build/three.module.js",
        "three/build/three.core.js",
        "three/examples/jsm/loaders/GLTFLoader.js",
        "three/examples/jsm/controls/OrbitControls.js",
    )
    if THREE.exists():  # scripts/setup.sh fetched it
        for f in three:
            assert (web / f).is_file(), f
        assert "No 3D views" not in page
    else:
        assert "No 3D views: three.js is not installed" in page
    # one slider per movable joint, its range the joint's limits, starting closed
    card = page[page.index("id='cab_a'") :].split("</section>")[0]
    sliders = re.findall(r"<input type='range'[^>]*>", card)
    assert len(sliders) == 2
    attrs = [dict(re.findall(r"([\w-]+)='([^']*)'", x)) for x in sliders]
    by_joint = {a["data-joint"]: a for a in attrs}
    assert set(by_joint) == {"joint_drawer_0", "joint_door_0"}
    assert by_joint["joint_drawer_0"]["data-type"] == "prismatic"
    assert float(by_joint["joint_drawer_0"]["max"]) == pytest.approx(0.35)
    assert float(by_joint["joint_door_0"]["max"]) == pytest.approx(1.57)
    assert all(float(a["min"]) == 0.0 == float(a["value"]) for a in attrs)
    # the scene: links with their GLBs (relative to the scene file), joints with frames
    scene_url = re.search(r"data-scene='([^']+)'", card).group(1)
    assert scene_url == "gallery/cab_a/scene.json"
    scene = json.loads((out / scene_url).read_text())
    assert scene["root"] == "base"
    assert [k["name"] for k in scene["links"]] == ["base", "drawer_0", "door_0"]
    for link in scene["links"]:
        (v,) = link["visuals"]
        assert v["url"] == f"../../cab_a/visual/{link['name']}.glb"
        assert (out / "gallery" / "cab_a" / v["url"]).resolve().is_file()
        assert np.allclose(np.reshape(v["origin"], (4, 4)), np.eye(4))
    door = next(j for j in scene["joints"] if j["name"] == "joint_door_0")
    assert door["type"] == "revolute" and door["parent"] == "base" and door["child"] == "door_0"
    assert door["axis"] == [0, 0, 1] and door["upper"] == pytest.approx(1.57)
    T = np.reshape(door["origin"], (4, 4))  # row-major: the translation in the last column
    assert np.allclose(T[:3, 3], [0.3, -0.4, 0.6]) and np.allclose(T[3], [0, 0, 0, 1])
    assert scene["photo_camera"] is None and "data-action='photo'" not in card
    # the photo's camera, when estimated: three.js axes (y up, looking down -z), fov
    write_front_camera(out / "cab_a")
    page = write_gallery(out).read_text()
    card = page[page.index("id='cab_a'") :].split("</section>")[0]
    assert "data-action='photo'" in card
    cam = json.loads((out / scene_url).read_text())["photo_camera"]
    P = np.reshape(cam["pose"], (4, 4))
    assert np.allclose(P[:3, 3], [2.0, 0.0, 0.3])
    assert np.allclose(P[:3, :3] @ [0, 0, -1], [-1, 0, 0])  # looks at the front (-x)
    assert np.allclose(P[:3, :3] @ [0, 1, 0], [0, 0, 1])  # its up is +z
    assert cam["fov"] == pytest.approx(math.degrees(2 * math.atan(240 / 896)))
    assert cam["aspect"] == pytest.approx(640 / 480)
    # from a file:// page the 3D panels explain how to serve the folder
    assert "python3 -m http.server -b 127.0.0.1" in page
    assert "location.protocol === 'file:'" in page


def test_fidelity_photo_view_and_assets_without_photo(tmp_path: Path) -> None:
    photos, out = _fake_outputs(tmp_path)
    photo_view = np.zeros((96, 128, 3), np.uint8)
    photo_view[20:80, 30:100] = (90, 160, 90)
    Image.fromarray(photo_view).save(out / "cab_a" / "photo_view.png")
    report = json.loads((out / "cab_b" / "report.json").read_text())
    report["fidelity"] = {
        "silhouette_iou": 0.41, "part_iou": 0.22, "psnr": 14.25, "ssim": 0.31, "score": 0.35,
        "low_fidelity": True, "reasons": ["silhouette IoU 0.41 < 0.6"],
    }  # fmt: skip
    (out / "cab_b" / "report.json").write_text(json.dumps(report))
    good = {
        "silhouette_iou": 0.93, "part_iou": 0.81, "psnr": 21.5, "ssim": 0.7, "score": 0.86,
        "low_fidelity": False, "reasons": [],
    }  # fmt: skip
    with Catalog(out) as cat:
        register_asset_dir(
            cat, out / "cab_a", source_image=str(photos / "cab_a.png"), fidelity=good
        )
        register_asset_dir(cat, out / "cab_b", source_image=str(photos / "cab_b.png"))
        register_asset_dir(cat, out / "mw")  # imported: no photo, no fidelity
    page = write_gallery(out).read_text()
    assert_relative_links(page, out)
    cards = {c.split("'")[0]: c for c in page.split("<section class='card' id='")[1:]}
    a, b, mw = cards["cab_a"], cards["cab_b"], cards["mw"]
    # the photo beside the asset seen from the photo's camera, then the preview
    assert a.index('src="gallery/cab_a/input.png"') < a.index("gallery/cab_a/photo_view.png")
    assert a.index("photo_view.png") < a.index('src="cab_a/preview.png"')
    assert Image.open(out / "gallery" / "cab_a" / "photo_view.png").size == (128, 96)
    assert "silhouette IoU <b>0.93</b>" in a and "PSNR <b>21.5 dB</b>" in a
    assert "low fidelity" not in a
    # flagged in report.json (not in the catalog row): badge, numbers and reasons
    assert "badge lowfid'>low fidelity" in b and "score <b>0.35</b>" in b
    assert "silhouette IoU 0.41 &lt; 0.6" in b
    assert "no asset from the photo&#x27;s camera" in b  # a photo but no photo_view.png
    assert "fidelity not measured" not in a + b
    # no photo: no photo figures and no fidelity; the preview and the 3D view stay
    assert "photo" not in mw and "fidelity" not in mw
    assert 'src="mw/preview.png"' in mw and "class='viewer'" in mw
    assert "1 low fidelity" in page


def test_gallery_server_serves_the_folder(tmp_path: Path) -> None:
    _, out = _fake_outputs(tmp_path)
    write_gallery(out)
    with serving(out) as url:
        assert url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(url + "index.html", timeout=10) as r:
            assert b"class='viewer'" in r.read()
        with urllib.request.urlopen(url + "gallery_web/viewer.js", timeout=10) as r:
            assert r.headers["Content-Type"].startswith("text/javascript")
        with urllib.request.urlopen(url + "cab_a/visual/door_0.glb", timeout=10) as r:
            assert r.read(4) == b"glTF"


def write_front_camera(folder: Path, distance: float = 2.0, z: float = 0.3) -> None:
    """A ``camera.json`` (OpenCV axes, camera-to-object) of a 640 x 480 photo taken from
    ``distance`` m in front of the object (+x), level, at height ``z``."""
    pose = np.eye(4)
    pose[:3, :3] = np.array([[0, 0, -1], [1, 0, 0], [0, -1, 0]])  # columns: right, down, forward
    pose[:3, 3] = [distance, 0.0, z]
    doc = {"schema": "pact.camera", "version": 1, "width": 640, "height": 480,
           "fx": 896.0, "fy": 896.0, "cx": 320.0, "cy": 240.0, "pose": pose.tolist()}  # fmt: skip
    (folder / "camera.json").write_text(json.dumps(doc))


# --------------------------------------------------------------------------- 3D view

BASE_RGB, DOOR_RGB = (205, 60, 45), (40, 90, 225)


def _colour_visual(glb: Path, rgb: tuple[int, int, int]) -> None:
    mesh = trimesh.load(glb, force="mesh", process=False)
    mesh.visual = trimesh.visual.ColorVisuals(mesh, face_colors=[*rgb, 255])
    glb.write_bytes(trimesh.Scene(mesh).export(file_type="glb"))


def _object_pixels(img: np.ndarray) -> np.ndarray:
    """Pixels of colour: the object (red base, blue door), not the grey background or grid."""
    return (img.max(axis=2).astype(int) - img.min(axis=2)) > 50


def _blue(img: np.ndarray) -> np.ndarray:
    return (img[..., 2].astype(int) > img[..., 0].astype(int) + 60) & _object_pixels(img)


def _red(img: np.ndarray) -> np.ndarray:
    return (img[..., 0].astype(int) > img[..., 2].astype(int) + 60) & _object_pixels(img)


@needs_chromium
def test_3d_view_draws_the_object_and_a_slider_opens_the_door(tmp_path: Path) -> None:
    """One headless Chromium: the asset's 3D view full-window with the door closed, then
    opened by its slider (through the page's ?q=); the page from file:// (no 3D); the
    whole gallery of six assets in a tall window (at most four WebGL contexts); and the
    view through the photo's camera (in front of the door)."""
    out = tmp_path / "out"
    write_box_cabinet(out / "cab", "revolute", aid="cab")
    _colour_visual(out / "cab" / "visual" / "base.glb", BASE_RGB)
    _colour_visual(out / "cab" / "visual" / "door_0.glb", DOOR_RGB)
    write_front_camera(out / "cab", distance=2.5, z=0.3)
    for k in range(1, 6):
        write_box_cabinet(out / f"cab_{k}", "prismatic", aid=f"cab_{k}")
    index = write_gallery(out)
    W, H, PANEL = 800, 600, 290  # the full-window view: canvas left, joint panel right
    probe = (
        "JSON.stringify({canvases: document.querySelectorAll('.viewer canvas').length,"
        " states: [...document.querySelectorAll('.viewer')].map(v => v.dataset.state)})"
    )
    with serving(out) as url:
        shots = screenshots(
            [
                Shot(url + "index.html?asset=cab&q=joint_door_0:0", tmp_path / "closed.png"),
                Shot(url + "index.html?asset=cab&q=joint_door_0:1.5", tmp_path / "open.png"),
                Shot(index.resolve().as_uri(), tmp_path / "file.png"),
                Shot(url + "index.html", tmp_path / "all.png", size=(1280, 3200), probe=probe),
                Shot(url + "index.html?asset=cab&view=photo", tmp_path / "photo.png"),
            ],
            width=W,
            height=H,
            timeout=45,
        )
    # both views drew; the file:// page says how to serve; the list loaded what it may
    assert [s.state for s in shots] == ["1", "1", "file", "1", "1"]
    listing = json.loads(shots[3].value)
    assert listing["canvases"] == 4, listing  # six views in sight, four WebGL contexts
    assert sorted(listing["states"]) == ["idle"] * 2 + ["ready"] * 4
    closed, opened = (
        np.asarray(Image.open(s.png).convert("RGB"))[40 : H - 10, 10 : W - PANEL] for s in shots[:2]
    )
    for img in (closed, opened):
        obj = _object_pixels(img)
        assert obj.mean() > 0.04, obj.mean()  # the object covers part of the canvas
        assert len(np.unique(img[obj] // 8, axis=0)) > 15  # shaded faces, not a flat colour
        assert _red(img).mean() > 0.01 and _blue(img).mean() > 0.005
    moved = np.abs(closed.astype(int) - opened.astype(int)).sum(axis=2) > 60
    assert moved.mean() > 0.02, moved.mean()  # the door swung: many pixels changed
    centre = [np.argwhere(_blue(img)).mean(axis=0) for img in (closed, opened)]
    assert math.dist(centre[0], centre[1]) > 15  # the blue door is elsewhere in the picture
    # through the photo's camera, straight in front: the blue door fills the middle
    front = np.asarray(Image.open(shots[4].png).convert("RGB"))[40 : H - 10, 10 : W - PANEL]
    assert _blue(front).mean() > 4 * _red(front).mean() and _blue(front).mean() > 0.05
    rows, cols = np.nonzero(_blue(front))
    assert abs(cols.mean() - front.shape[1] / 2) < 40 and abs(rows.mean() - front.shape[0] / 2) < 60
    for img in (closed, opened):
        assert _red(img).mean() > _blue(img).mean() / 4  # the 3/4 view shows top and side
