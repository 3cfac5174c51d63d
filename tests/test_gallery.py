"""The HTML gallery: page structure, 3D scenes, the local server, headless-Chromium
screenshots (the page as a whole, and the 3D view drawing an object whose door a
slider opens), and the mask editor (its server's refusals without a browser; a person's
edit, save and re-conversion driven through Chromium with playwright)."""

from __future__ import annotations

import base64
import io
import json
import math
import re
import shutil
import subprocess
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
from asset_fixtures import write_box_cabinet, write_two_part_cabinet
from PIL import Image

from asset_pipeline.catalog.batch import ConvertSettings, run_convert
from asset_pipeline.catalog.registry import Catalog, register_asset_dir
from asset_pipeline.gallery.editor import MOTION_LABELS, edited_hints
from asset_pipeline.gallery.page import write_gallery
from asset_pipeline.gallery.screenshots import CHROMIUM_FLAGS, Shot, screenshots
from asset_pipeline.gallery.server import serving
from asset_pipeline.inputs.folder import hash_files
from generator.motions import MOTIONS

REPO = Path(__file__).resolve().parents[1]
CHROMIUM = Path("/usr/bin/chromium")
THREE = REPO / "asset_pipeline" / "gallery" / "web" / "three" / "build" / "three.module.js"
needs_chromium = pytest.mark.skipif(
    not CHROMIUM.exists() or not THREE.exists(),
    reason="needs /usr/bin/chromium and three.js (scripts/setup.sh installs both: apt-get "
    "install -y chromium as root; npm pack three)",
)

#: The mask editor's browser test drives Chromium with playwright; it needs no three.js.
needs_browser = pytest.mark.skipif(
    not CHROMIUM.exists(),
    reason="needs /usr/bin/chromium (scripts/setup.sh installs it as root: apt-get install -y "
    "chromium)",
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
                cat,
                out / name,
                source_image=str(photos / f"{name}.png"),
                generator="pact",
                warnings=("p.png: the parser was sure of no moving part <check>",)
                if name == "cab_b"
                else (),
            )
        cat.record_failure("lost_one", "generator crashed <OOM>")
    page = write_gallery(out).read_text()
    assert "from the catalog" in page and page.count("class='card'") == 4
    # the conversion's warnings on the card they belong to, escaped
    card_b = page[page.index("id='cab_b'") : page.index("</section>", page.index("id='cab_b'"))]
    assert "warning: p.png: the parser was sure of no moving part &lt;check&gt;" in card_b
    assert page.count("warning: ") == 1
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


# --------------------------------------------------------------------------- mask editor

EXAMPLES = REPO / "examples" / "images"
OVEN = "oven_t0000001"
#: The hints the photo parser left beside the photo: a category, a mask and part 2's
#: motion, each with its confidence.
PARSER_HINTS = {
    "category": "oven",
    "height": 0.884,
    "notes": "left of the sink",
    "parts": {"2": {"motion": "flap_bottom"}},
    "parsed": {"by": "parser-test", "category": 0.55, "mask": 0.8, "parts": {"2": 0.9}},
}


def _folder_state(folder: Path) -> dict[str, tuple[int, int, bytes]]:
    """Every file under ``folder`` (hidden ones too) with its size, mtime and bytes, and
    every folder; SQLite's shared-memory index (which readers touch) left out."""
    return {
        p.relative_to(folder).as_posix(): (
            (p.stat().st_size, p.stat().st_mtime_ns, p.read_bytes()) if p.is_file() else "dir"
        )
        for p in sorted(folder.rglob("*"))
        if not p.name.endswith("-shm")
    }


def _editor_request(url: str, body: Any, origin: str | None = None, host: str | None = None):
    """POST ``body`` to the editor's save endpoint; returns (status, JSON answer)."""
    data = body if isinstance(body, bytes) else json.dumps(body).encode()
    req = urllib.request.Request(url + "api/editor/save", data=data, method="POST")
    req.add_header("Content-Type", "application/json")
    req.add_header("Origin", origin if origin is not None else url.rstrip("/"))
    if host is not None:
        req.add_header("Host", host)
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def _png_b64(ids: np.ndarray) -> str:
    buf = io.BytesIO()
    Image.fromarray(ids.astype(np.uint8), "L").save(buf, format="PNG")
    return base64.b64encode(buf.getvalue()).decode()


def test_motion_words_name_every_motion() -> None:
    assert tuple(MOTION_LABELS) == MOTIONS
    assert MOTION_LABELS["drawer"] == "drawer (slides out)"
    assert "hinged left" in MOTION_LABELS["door_left"]


def test_edited_hints_move_what_the_parser_wrote_with_the_parts() -> None:
    """Part 3 of the opened mask was erased, so part 4 is saved as 3; the person set part
    2's motion and drew part 4 anew; the category was confirmed; the mask changed."""
    existing = {
        "id": "kitchen_01",
        "category": "cabinet",
        "seed": 3,
        "parts": {"2": {"motion": "door_left"}, "3": {"motion": "lid"}, "4": {"motion": "drawer"}},
        "parsed": {"by": "p1", "category": 0.4, "mask": 0.7, "parts": {"2": 0.6, "3": 0.5, "4": 0.8}},
    }  # fmt: skip
    request = {
        "category": "cabinet",
        "parts": {"2": {"motion": "door_right"}, "3": {"motion": "drawer"}, "4": {"motion": ""}},
        "confirmed": ["2"],
        "from": {"2": 2, "3": 4, "4": None},
    }
    hints = edited_hints(existing, {2, 3, 4}, mask_changed=True, request=request)
    assert hints == {
        "id": "kitchen_01",
        "category": "cabinet",
        "seed": 3,
        "parts": {"2": {"motion": "door_right"}, "3": {"motion": "drawer"}},
        "parsed": {"by": "p1", "parts": {"3": 0.8}},  # old part 4's confidence, now part 3
    }
    # nothing set, mask unchanged: the parser's record stays whole
    same = edited_hints(existing, {2, 3, 4}, False, {"parts": existing["parts"], "confirmed": []})
    assert same == existing
    # a client that sends the mask alone: the parts keep their motions through `from`
    moved = edited_hints(existing, {2, 3}, True, {"from": {"2": 2, "3": 4}})
    assert moved["parts"] == {"2": {"motion": "door_left"}, "3": {"motion": "drawer"}}
    assert moved["parsed"] == {"by": "p1", "category": 0.4, "parts": {"2": 0.6, "3": 0.8}}
    # every field set by the person: no parser record left
    mine = edited_hints(
        {"parsed": {"category": 0.3, "mask": 0.2, "parts": {"2": 0.1}}},
        {2},
        False,
        {"category": "desk", "mask_confirmed": True, "parts": {"2": {"motion": "lid"}},
         "confirmed": ["2"]},
    )  # fmt: skip
    assert mine == {"category": "desk", "parts": {"2": {"motion": "lid"}}}


def test_editor_server_refuses_bad_saves_and_writes_nothing(tmp_path: Path) -> None:
    """Without a browser: a bad motion, an id not in the catalog, a path as id, a mask
    whose ids skip a number or of the wrong size, another origin or host: each refused
    with a reason, and neither the photo folder nor OUT changes."""
    photos, out = _fake_outputs(tmp_path)
    with Catalog(out) as cat:
        for name in ("cab_a", "mw"):
            register_asset_dir(cat, out / name, source_image=str(photos / f"{name}.png"))
        register_asset_dir(cat, out / "cab_b")  # no photo: not editable
    write_gallery(out)
    page = (out / "index.html").read_text()
    assert page.count("class='edit-mask'") == 2  # the two assets with a photo
    assert "pact gallery OUT --serve" in page
    mask = np.asarray(Image.open(photos / "cab_a.mask.png"))
    good = {"id": "cab_a", "mask": _png_b64(mask), "parts": {"2": {"motion": "drawer"}}}
    gap = mask.copy()
    gap[gap == 2] = 3
    cases = [
        ({**good, "parts": {"2": {"motion": "sideways"}}}, {}, 400, "'sideways' is not one of"),
        ({**good, "id": "nope"}, {}, 404, "no asset 'nope'"),
        ({**good, "id": "../photos/cab_a"}, {}, 404, "no asset"),
        ({**good, "id": "cab_b"}, {}, 409, "only assets converted from a photo"),
        ({**good, "mask": _png_b64(gap)}, {}, 400, "ids [2] are missing"),
        ({**good, "mask": _png_b64(mask[:50])}, {}, 400, "must be the same size"),
        ({**good, "parts": {"3": {"motion": "drawer"}}}, {}, 400, "has no part 3"),
        ({**good, "category": "sofa"}, {}, 400, "'sofa' is not one of"),
        (good, {"origin": "http://evil.example"}, 403, "only from its own page"),
        (good, {"origin": "null"}, 403, "only from its own page"),
    ]
    before = (_folder_state(photos), _folder_state(out))
    with serving(out) as url:
        with urllib.request.urlopen(url + "api/editor", timeout=10) as r:
            info = json.loads(r.read())
        assert info["enabled"] and [m for m, _ in info["motions"]] == list(MOTIONS)
        with urllib.request.urlopen(url + "api/editor/asset?id=cab_a", timeout=10) as r:
            state = json.loads(r.read())
        assert (state["width"], state["height"], state["ids"]) == (128, 96, [1, 2])
        with urllib.request.urlopen(url + "api/editor/mask?id=cab_a", timeout=10) as r:
            assert np.array_equal(np.asarray(Image.open(io.BytesIO(r.read()))), mask)
        for body, headers, status, message in cases:
            code, answer = _editor_request(url, body, **headers)
            assert (code, message in answer["error"]) == (status, True), (body.get("id"), answer)
        # a page of another name for this machine (DNS rebinding) may not even read
        port = url.rstrip("/").rsplit(":", 1)[1]
        code, answer = _editor_request(url, good, host=f"attacker.example:{port}")
        assert code == 403 and "answers only requests to http://127.0.0.1" in answer["error"]
    assert (_folder_state(photos), _folder_state(out)) == before  # the catalog too
    # bound to another loopback address the editor is off, and says why
    with serving(out, host="127.0.0.2") as url:
        with urllib.request.urlopen(url + "api/editor", timeout=10) as r:
            info = json.loads(r.read())
        assert (
            not info["enabled"] and "only when the gallery is served on 127.0.0.1" in info["reason"]
        )
        code, answer = _editor_request(url, good)
        assert code == 403
    assert _folder_state(photos) == before[0]


def _launch_chromium(playwright: Any, profile: Path) -> Any:
    return playwright.chromium.launch_persistent_context(
        str(profile),
        executable_path=str(CHROMIUM),
        headless=True,
        args=[f for f in CHROMIUM_FLAGS if f != "--headless"],
        viewport={"width": 1280, "height": 900},
    )


@needs_browser
@pytest.mark.slow
def test_mask_editor_draws_a_part_saves_and_the_card_shows_the_new_asset(tmp_path: Path) -> None:
    """A person opens the editor on a converted oven, draws a rectangle as a new part,
    makes it a drawer, confirms the category and saves: the two files beside the photo
    say so, nothing else is written there, the item is converted again (catalog row,
    asset) and the page shows the new card with its three parts."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="pip install playwright")
    photos = tmp_path / "photos"
    photos.mkdir()
    for suffix in (".png", ".mask.png"):
        shutil.copy(EXAMPLES / f"{OVEN}{suffix}", photos / f"{OVEN}{suffix}")
    (photos / f"{OVEN}.json").write_text(json.dumps(PARSER_HINTS, indent=2))
    out = tmp_path / "out"
    fast = {"validate": False, "preview": False, "fidelity": False}
    summary = run_convert(photos, out, ConvertSettings(generator="retrieval", **fast))
    assert [r.status for r in summary.results] == ["ok"]
    with Catalog(out, readonly=True) as cat:
        row = cat.get(OVEN)
    assert row.part_count == 2 and row.generator == "retrieval"
    write_gallery(out)
    original = np.asarray(Image.open(photos / f"{OVEN}.mask.png"))
    photo_bytes = (photos / f"{OVEN}.png").read_bytes()
    # the new part: a rectangle inside the lower door, in photo pixels
    x0, y0, x1, y1 = 66, 150, 140, 176
    with serving(out, editor_overrides=fast) as url, sync_api.sync_playwright() as pw:
        browser = _launch_chromium(pw, tmp_path / "profile")
        try:
            page = browser.new_page()
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(url + "index.html")
            page.wait_for_selector("body[data-editor=on]", timeout=15000)
            card = page.locator(f"section#{OVEN}")
            card.locator("button.edit-mask").click()
            editor = page.locator("#mask-editor[data-state=ready]")
            editor.wait_for(timeout=15000)
            # the opened mask: base and the parser's door, its motion preselected
            assert page.locator("#mask-editor .me-part").count() == 2
            assert page.locator("#mask-editor select.me-motion[data-part='2']").input_value() == (
                "flap_bottom"
            )
            assert "90% sure" in page.locator("#mask-editor .me-part[data-part='2']").inner_text()
            page.select_option("#mask-editor select.me-paint", label="new part (3)")
            page.locator("#mask-editor button[data-tool=rect]").click()
            box = page.locator("#mask-editor canvas.me-photo").bounding_box()

            def screen(x: float, y: float) -> tuple[float, float]:
                return box["x"] + x * box["width"] / 256, box["y"] + y * box["height"] / 256

            page.mouse.move(*screen(x0, y0))
            page.mouse.down()
            page.mouse.move(*screen((x0 + x1) / 2, (y0 + y1) / 2), steps=4)
            page.mouse.move(*screen(x1, y1), steps=4)
            page.mouse.up()
            part3 = page.locator("#mask-editor select.me-motion[data-part='3']")
            part3.select_option("drawer")
            assert "drawer (slides out)" in part3.inner_text()
            page.locator("#mask-editor .me-category-src button.confirm").click()
            page.screenshot(path=str(tmp_path / "editor.png"))
            page.locator("#mask-editor button.save").click()
            page.wait_for_selector(f"section#{OVEN}[data-edit-state=done]", timeout=120000)
            assert page.locator("#mask-editor").count() == 0  # closed once converted
            meta = page.locator(f"section#{OVEN} .meta").first.inner_text()
            note = page.locator(f"section#{OVEN} .edit-note").inner_text()
            if THREE.exists():  # the new card's own 3D view loads
                page.wait_for_selector(f"section#{OVEN} .viewer[data-state=ready]", timeout=30000)
            page.screenshot(path=str(tmp_path / "after.png"), full_page=True)
            assert not errors, errors
        finally:
            browser.close()
    assert "3 parts" in meta and "ok, 3 parts" in note, (meta, note)
    # beside the photo: its mask and hints rewritten, nothing else, the photo untouched
    assert sorted(p.name for p in photos.iterdir()) == sorted(
        [f"{OVEN}.png", f"{OVEN}.mask.png", f"{OVEN}.json"]
    )
    assert (photos / f"{OVEN}.png").read_bytes() == photo_bytes
    saved = Image.open(photos / f"{OVEN}.mask.png")
    assert saved.mode == "L" and saved.size == (256, 256)
    ids = np.asarray(saved)
    assert sorted(np.unique(ids).tolist()) == [0, 1, 2, 3]
    rows, cols = np.nonzero(ids == 3)
    assert abs(rows.min() - y0) <= 1 and abs(rows.max() + 1 - y1) <= 1
    assert abs(cols.min() - x0) <= 1 and abs(cols.max() + 1 - x1) <= 1
    assert (ids == 3).sum() == (rows.max() - rows.min() + 1) * (cols.max() - cols.min() + 1)
    assert np.array_equal(ids[ids != 3], original[ids != 3])  # the rest as it was
    hints = json.loads((photos / f"{OVEN}.json").read_text())
    assert hints == {
        "category": "oven",  # confirmed: no longer the parser's
        "height": 0.884,
        "notes": "left of the sink",
        "parts": {"2": {"motion": "flap_bottom"}, "3": {"motion": "drawer"}},
        "parsed": {"by": "parser-test", "parts": {"2": 0.9}},  # the mask was edited
    }
    # converted again from those files: the catalog row and the asset
    with Catalog(out, readonly=True) as cat:
        new = cat.get(OVEN)
    assert new.status == "ok" and new.part_count == 3 and new.generator == "retrieval"
    assert new.source_hash == hash_files(
        photos / f"{OVEN}.png", photos / f"{OVEN}.mask.png", photos / f"{OVEN}.json"
    )
    assert new.source_hash != row.source_hash
    assert np.array_equal(np.asarray(Image.open(out / OVEN / "input.mask.png")), ids)
    joints = json.loads((out / OVEN / "asset.json").read_text())["joints"]
    assert sorted(j["type"] for j in joints) == ["prismatic", "revolute"]  # drawer and door
