"""Fidelity (asset_pipeline.photo.fidelity): metrics, report.json, the catalog, pact ls, convert."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from asset_fixtures import write_two_part_cabinet
from typer.testing import CliRunner

from asset_pipeline.catalog.registry import Catalog, format_table, register_asset_dir
from asset_pipeline.photo.camera import silhouette_iou
from asset_pipeline.photo.fidelity import (
    FidelityThresholds,
    compare,
    fidelity_score,
    psnr,
    render_device_available,
    ssim,
)
from asset_pipeline.validate import read_report, write_report

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "images"


def test_silhouette_iou_by_hand():
    a = np.zeros((10, 10), bool)
    b = np.zeros((10, 10), bool)
    a[0:4, 0:5] = True  # 20 px
    b[2:6, 0:5] = True  # 20 px, 10 shared
    assert silhouette_iou(a, b) == pytest.approx(10 / 30)
    assert silhouette_iou(a, a) == 1.0


def test_psnr_of_a_known_noise_and_ssim_of_identical_images():
    rng = np.random.default_rng(0)
    a = rng.integers(20, 230, (32, 40, 3)).astype(np.uint8)
    noise = rng.choice([-10, 10], size=a.shape)  # |error| 10 everywhere: MSE 100
    b = (a.astype(int) + noise).astype(np.uint8)
    where = np.ones((32, 40), bool)
    assert psnr(a, b, where) == pytest.approx(10 * math.log10(255**2 / 100), abs=1e-9)
    # only the pixels inside ``where`` count
    c = b.copy()
    c[:, 20:] = 0
    where[:, 20:] = False
    assert psnr(a, c, where) == pytest.approx(28.1308, abs=1e-3)
    assert psnr(a, a, where) == 100.0
    assert ssim(a, a, where) == pytest.approx(1.0)
    assert ssim(a, b, where) < 1.0


def test_compare_matches_permuted_parts_and_flags_low_fidelity():
    photo = np.full((40, 60, 3), 200, np.uint8)
    photo[10:30, 10:50] = (120, 80, 40)
    mask = np.zeros((40, 60), np.int64)
    mask[10:30, 10:30], mask[10:30, 30:50] = 1, 2
    silhouette = mask > 0
    links = np.zeros_like(mask)
    links[10:30, 10:30], links[10:30, 30:50] = 2, 1  # link ids are not mask ids
    rendered = photo.copy()
    good = compare(photo, silhouette, mask, rendered, links > 0, links)
    assert good["silhouette_iou"] == 1.0 and good["part_iou"] == 1.0
    assert good["part_match"] == {"1": 2, "2": 1}
    assert good["psnr"] == 100.0 and good["ssim"] == pytest.approx(1.0)
    assert good["score"] == pytest.approx(1.0) and not good["low_fidelity"]
    # half the object missing from the render: the grey background counts against it
    half = links.copy()
    half[:, 30:] = 0
    bad = compare(photo, silhouette, mask, rendered, half > 0, half, FidelityThresholds())
    assert bad["silhouette_iou"] == pytest.approx(0.5)
    assert bad["part_iou"] == pytest.approx(0.5)  # id 1 lost its link, id 2 perfect
    assert bad["low_fidelity"] and any("silhouette_iou" in r for r in bad["reasons"])
    assert bad["thresholds"]["psnr"] == FidelityThresholds().psnr
    # without a mask there is no part term
    none = compare(photo, silhouette, None, rendered, links > 0, links)
    assert none["part_iou"] is None
    assert none["score"] == pytest.approx(fidelity_score(1.0, None, 100.0, 1.0))


def test_report_and_catalog_carry_fidelity(tmp_path):
    folder = write_two_part_cabinet(tmp_path / "out" / "cab", "cab")
    report = read_report(folder)
    assert report.fidelity is None
    record = {"silhouette_iou": 0.9, "part_iou": 0.8, "psnr": 24.0, "ssim": 0.7,
              "score": 0.79, "low_fidelity": False, "reasons": [], "thresholds": {}}  # fmt: skip
    report.fidelity = record
    write_report(report, folder)
    assert read_report(folder).fidelity == record
    assert json.loads((folder / "report.json").read_text())["fidelity"]["score"] == 0.79
    other = write_two_part_cabinet(tmp_path / "out" / "plain", "plain")
    with Catalog(tmp_path / "out") as cat:
        register_asset_dir(cat, folder)
        register_asset_dir(cat, other)
        assert cat.get("cab").fidelity == record and cat.get("plain").fidelity is None
        assert [r.id for r in cat.query(min_fidelity=0.5)] == ["cab"]
        assert cat.query(min_fidelity=0.99) == []
        assert len(cat.query()) == 2
        from rich.console import Console

        console = Console(width=200, record=True)
        console.print(format_table(cat.query()))
        assert "0.79" in console.export_text()


@pytest.mark.render
@pytest.mark.slow
def test_convert_records_fidelity_and_ls_filters_on_it(tmp_path):
    if not render_device_available():
        pytest.skip("no Vulkan render device (install Mesa lavapipe >= 24.3, see FIELD-NOTES)")
    from PIL import Image

    from asset_pipeline.catalog.batch import ConvertSettings, run_convert
    from pact_cli.main import app

    images = tmp_path / "in"
    images.mkdir()
    for f in EXAMPLES.glob("dishwasher_t0000001*"):
        shutil.copy(f, images / f.name)
    # a photo taller than wide (its mask alike): the score reads the mask at the photo's size
    for name in ("dishwasher_t0000001.png", "dishwasher_t0000001.mask.png"):
        Image.open(images / name).crop((24, 0, 232, 256)).save(images / name)
    out = tmp_path / "out"
    settings = ConvertSettings(generator="retrieval", repair=False, preview=False)
    summary = run_convert(images, out, settings)
    assert [r.status for r in summary.results] == ["ok"], summary.results
    asset = out / "dishwasher_t0000001"
    fidelity = json.loads((asset / "report.json").read_text())["fidelity"]
    for key in ("silhouette_iou", "part_iou", "psnr", "ssim", "score", "low_fidelity"):
        assert fidelity[key] is not None, key
    assert 0.0 <= fidelity["score"] <= 1.0 and fidelity["silhouette_iou"] > 0.7
    camera = json.loads((asset / "camera.json").read_text())
    assert camera["schema"] == "pact.camera" and np.shape(camera["pose"]) == (4, 4)
    assert (asset / "photo_view.png").is_file() and list((asset / "visual").glob("*.png"))
    with Catalog(out, readonly=True) as cat:
        assert cat.get("dishwasher_t0000001").fidelity["score"] == fidelity["score"]
    runner = CliRunner()
    shown = runner.invoke(app, ["ls", str(out), "--min-fidelity", "0"])
    assert shown.exit_code == 0 and "dishwasher" in shown.output
    hidden = runner.invoke(app, ["ls", str(out), "--min-fidelity", "0.99"])
    assert hidden.exit_code == 0 and "dishwasher" not in hidden.output
