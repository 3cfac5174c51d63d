"""The static HTML gallery and its headless-Chromium screenshot."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from asset_fixtures import write_two_part_cabinet
from PIL import Image

from asset_pipeline.catalog import Catalog, register_asset_dir
from asset_pipeline.gallery import write_gallery

REPO = Path(__file__).resolve().parents[1]
CHROMIUM = Path("/usr/bin/chromium")


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
    assert "<script" not in page
    assert not re.search(r'src="(/|file:|https?:)', page)  # relative links only


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


@pytest.mark.skipif(
    not CHROMIUM.exists(), reason="needs /usr/bin/chromium (apt-get install -y chromium)"
)
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
