"""preview.png of a built asset (asset_pipeline.validate.preview): rendered by SAPIEN on lavapipe.

Rendering needs a Vulkan device; without one the tests that draw are skipped with
the reason, and the no-device path is tested by simulating it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from asset_pipeline.assets.build import build_asset
from asset_pipeline.validate import preview as preview_mod
from asset_pipeline.validate import validate_asset
from asset_pipeline.validate.preview import render_device_available, render_preview
from generator.bundle import save_bundle
from generator.procedural import sample_object


@pytest.fixture(scope="module")
def asset(tmp_path_factory):
    root = tmp_path_factory.mktemp("preview")
    d = save_bundle(sample_object("cabinet", 0), root / "cabinet_0000")
    build_asset(d)
    return d


@pytest.mark.render
def test_preview_png_shows_rest_and_open(asset):
    if not render_device_available():
        pytest.skip("no Vulkan render device (install Mesa lavapipe >= 24.3, see FIELD-NOTES)")
    path = render_preview(asset, size=256)
    assert path == asset / "preview.png" and path.is_file()
    img = np.asarray(Image.open(path).convert("RGB"), dtype=float)
    assert img.shape == (256, 512, 3)
    left, right = img[:, :256], img[:, 256:]
    background = np.abs(img - preview_mod.BACKGROUND * 255).sum(-1) > 30
    assert background.mean() > 0.05, "the object is not in the picture"
    assert img.std() > 10, "blank image"
    assert np.abs(left - right).mean() > 2, "rest and open views are identical"


@pytest.mark.render
def test_validate_writes_preview_into_report(asset):
    if not render_device_available():
        pytest.skip("no Vulkan render device (install Mesa lavapipe >= 24.3, see FIELD-NOTES)")
    report = validate_asset(asset)
    assert report.preview == "preview.png"
    assert json.loads((asset / "report.json").read_text())["preview"] == "preview.png"


def test_no_render_device_returns_none_and_validation_runs(asset, monkeypatch, caplog):
    monkeypatch.setattr(preview_mod, "_NO_DEVICE", ["simulated: no Vulkan device"])
    monkeypatch.setattr(preview_mod, "_STAGES", {})
    assert render_preview(asset) is None
    assert "simulated: no Vulkan device" in caplog.text
    report = validate_asset(asset)
    assert report.ok and report.preview is None
    assert json.loads((asset / "report.json").read_text())["preview"] is None


@pytest.mark.render
def test_a_process_that_drew_a_preview_can_still_make_the_tasks_cameras(asset):
    """SAPIEN renders on one device per process. ManiSkill's CPU render backend (the tasks'
    cameras and videos) asks for ``sapien.Device("cpu")``; a preview drawn first on the
    default device used to make it fail ("only supports single-GPU rendering"). In a
    fresh process: the preview, then the render system ManiSkill makes, then a second
    preview, which must draw the same picture."""
    import subprocess
    import sys

    if not render_device_available():
        pytest.skip("no Vulkan render device (install Mesa lavapipe >= 24.3, see FIELD-NOTES)")
    code = f"""
import numpy as np, sapien, torch
from PIL import Image
from asset_pipeline.validate.preview import render_preview
first = np.asarray(Image.open(render_preview({str(asset)!r}, size=128)))
if not torch.cuda.is_available():  # what ManiSkill's render_backend="cpu" asks for
    assert sapien.render.RenderSystem(sapien.Device("cpu")).device.name == "cpu"
again = np.asarray(Image.open(render_preview({str(asset)!r}, size=128)))
assert first.std() > 10 and np.array_equal(first, again)
print("ok")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), out.stderr[-2000:]
