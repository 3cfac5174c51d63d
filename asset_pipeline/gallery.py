"""A static HTML gallery of an output folder: ``OUT/index.html``.

One card per asset: the input photo and its part mask (colour-coded), the
validation preview (``preview.png``: the object at rest and open), the joint table
(name, type, axis, limits) and the validation status with every failed check's
measured value and tolerance, the repairs and the failure reason.

Assets come from the catalog (``OUT/registry.sqlite``) when there is one, else
from the subfolders of OUT that hold an ``asset.json``. The page uses relative links
and inline CSS only, so it opens from the file system (no server, no JavaScript).
Thumbnails of inputs and masks are written to ``OUT/gallery/<id>/``; previews
inside OUT are linked, previews elsewhere are copied there.
"""

from __future__ import annotations

import html
import logging
import math
import os
import shutil
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
from PIL import Image

from asset_pipeline.asset_io import ASSET_JSON_NAME, AssetFormatError, load_asset
from asset_pipeline.built_asset import BuiltAsset
from asset_pipeline.catalog import (
    AssetRecord,
    Catalog,
    CatalogError,
    CheckRecord,
    catalog_path,
    checks_from_report,
    records_from_asset_dir,
    repair_text,
)
from asset_pipeline.inputs import IMAGE_SUFFIXES, MASK_SUFFIX
from asset_pipeline.validate import ReportFormatError, read_report
from generator.articulated import atomic_write_bytes

log = logging.getLogger(__name__)

THUMB_SIZE = 320
#: Mask colours by part id: 0 background (dark), 1 base (grey), 2.. movable parts.
MASK_PALETTE = np.array(
    [
        (30, 30, 30), (170, 170, 170), (228, 26, 28), (55, 126, 184), (77, 175, 74),
        (152, 78, 163), (255, 127, 0), (255, 255, 51), (166, 86, 40), (247, 129, 191),
        (102, 194, 165), (252, 141, 98), (141, 160, 203), (231, 138, 195), (166, 216, 84),
        (255, 217, 47), (229, 196, 148),
    ],
    dtype=np.uint8,
)  # fmt: skip


@dataclass
class _Entry:
    record: AssetRecord
    asset_dir: Path | None
    checks: list[CheckRecord] = field(default_factory=list)
    asset: BuiltAsset | None = None
    error: str | None = None


# --------------------------------------------------------------------------- collection


def _entries_from_catalog(out: Path) -> list[_Entry]:
    with Catalog(out, readonly=True) as cat:
        rows = cat.query(details=True)
        entries = []
        for r in rows:
            d = cat.asset_dir(r) or out / r.id
            entries.append(_Entry(record=r, asset_dir=d, checks=list(r.checks)))
    return entries


def _entries_from_folders(out: Path) -> list[_Entry]:
    entries = []
    for d in sorted(
        p
        for p in out.iterdir()
        if p.is_dir() and not p.name.startswith(".") and (p / ASSET_JSON_NAME).is_file()
    ):
        try:
            rec, _, checks = records_from_asset_dir(d)
            entries.append(_Entry(record=rec, asset_dir=d, checks=checks))
        except CatalogError as e:
            rec = AssetRecord(id=d.name, status="failed", failure_reason=str(e), path=str(d))
            entries.append(_Entry(record=rec, asset_dir=d, error=str(e)))
    return entries


def _complete(e: _Entry) -> None:
    if e.asset_dir is None or not (e.asset_dir / ASSET_JSON_NAME).is_file():
        return
    try:
        e.asset = load_asset(e.asset_dir)
        if not e.checks:
            e.checks = checks_from_report(read_report(e.asset_dir))
    except (AssetFormatError, ReportFormatError) as err:
        log.warning("%s", err)
        e.error = str(err)


# --------------------------------------------------------------------------- images


def _rel(target: Path, out: Path) -> str:
    return quote(Path(os.path.relpath(target.resolve(), out.resolve())).as_posix())


def _find_input(e: _Entry, out: Path) -> tuple[Path | None, Path | None]:
    """The input photo and mask of an asset (copies in the asset folder first)."""
    image = mask = None
    if e.asset_dir is not None:
        for name in (f"input{suffix}" for suffix in IMAGE_SUFFIXES):
            if (e.asset_dir / name).is_file():
                image = e.asset_dir / name
                break
        if (e.asset_dir / f"input{MASK_SUFFIX}").is_file():
            mask = e.asset_dir / f"input{MASK_SUFFIX}"
    if image is None and e.record.source_image:
        src = Path(e.record.source_image)
        for cand in (src, out / src) if not src.is_absolute() else (src,):
            if cand.is_file():
                image = cand
                break
    if mask is None and image is not None:
        cand = image.with_name(image.name[: -len(image.suffix)] + MASK_SUFFIX)
        mask = cand if cand.is_file() else None
    return image, mask


def _thumbnail(src: Path, dest: Path, colourize: bool = False) -> Path | None:
    try:
        with Image.open(src) as img:
            img.load()
            if colourize:
                ids = np.asarray(img.convert("L") if img.mode not in ("L", "P") else img)
                img = Image.fromarray(MASK_PALETTE[np.minimum(ids, len(MASK_PALETTE) - 1)], "RGB")
                img.thumbnail((THUMB_SIZE, THUMB_SIZE), Image.Resampling.NEAREST)
            else:
                img = img.convert("RGBA") if "A" in img.getbands() else img.convert("RGB")
                img.thumbnail((THUMB_SIZE, THUMB_SIZE))
            dest.parent.mkdir(parents=True, exist_ok=True)
            img.save(dest)
        return dest
    except (OSError, ValueError) as e:
        log.warning("%s: cannot make a thumbnail: %s", src, e)
        return None


def _preview(e: _Entry, out: Path, gallery_dir: Path) -> Path | None:
    if e.asset_dir is None or not (e.asset_dir / "preview.png").is_file():
        return None
    p = e.asset_dir / "preview.png"
    try:
        p.resolve().relative_to(out.resolve())
        return p
    except ValueError:
        dest = gallery_dir / "preview.png"
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(p, dest)
        return dest


# --------------------------------------------------------------------------- html

_CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:0;background:#f4f4f6;color:#222}
header{background:#223;color:#fff;padding:14px 24px}
header h1{margin:0;font-size:20px} header p{margin:4px 0 0;color:#ccd}
main{padding:16px 24px;display:flex;flex-direction:column;gap:16px}
.card{background:#fff;border-radius:8px;box-shadow:0 1px 3px #0002;padding:14px 18px}
.card h2{margin:0 0 6px;font-size:17px;display:flex;align-items:center;gap:10px}
.badge{font-size:12px;padding:2px 8px;border-radius:10px;color:#fff}
.ok{background:#2a8a3a}.repaired{background:#c98a00}.failed{background:#c0392b}
.meta{color:#555;margin-bottom:8px}
.imgs{display:flex;gap:12px;flex-wrap:wrap;margin:8px 0}
figure{margin:0;text-align:center} figcaption{font-size:12px;color:#666}
figure img{height:180px;width:auto;max-width:480px;object-fit:contain;border:1px solid #ddd;background:
 repeating-conic-gradient(#eee 0 25%,#fff 0 50%) 50%/16px 16px}
.missing{width:160px;height:120px;display:flex;align-items:center;justify-content:center;
 border:1px dashed #bbb;color:#999;font-size:12px}
table{border-collapse:collapse;margin:6px 0 10px;font-size:13px}
th,td{border-bottom:1px solid #e4e4e8;padding:3px 10px;text-align:left}
th{background:#f0f0f4} td.num{text-align:right;font-variant-numeric:tabular-nums}
tr.fail td{color:#b0281a} .reason{color:#b0281a;font-weight:600}
.cols{display:flex;gap:28px;flex-wrap:wrap}
"""


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _num(v: Any) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_num(x) for x in v) + "]"
    return "-" if v is None else str(v)


def _limits(joint_type: str, lo: float, hi: float) -> str:
    if joint_type == "revolute":
        return f"{math.degrees(lo):.1f}° … {math.degrees(hi):.1f}°"
    if joint_type == "prismatic":
        return f"{lo:.3f} … {hi:.3f} m"
    return f"{lo:g} … {hi:g}"


def _figure(src: str | None, caption: str) -> str:
    if src is None:
        return f'<figure><div class="missing">no {_e(caption)}</div><figcaption>{_e(caption)}</figcaption></figure>'
    return (
        f'<figure><img src="{_e(src)}" alt="{_e(caption)}">'
        f"<figcaption>{_e(caption)}</figcaption></figure>"
    )


def _joint_table(asset: BuiltAsset | None) -> str:
    parts = [] if asset is None else asset.movable_parts()
    if not parts:
        return "<p class='meta'>no joints recorded</p>"
    rows = "".join(
        f"<tr><td>{_e(p.name)}</td><td>{_e(p.joint_type)}</td>"
        f"<td class='num'>{_e(_num([round(a, 3) for a in p.axis]))}</td>"
        f"<td class='num'>{_e(_num([round(a, 3) for a in p.origin]))}</td>"
        f"<td class='num'>{_e(_limits(p.joint_type, p.lower, p.upper))}</td></tr>"
        for p in parts
    )
    return (
        "<table><tr><th>part</th><th>type</th><th>axis</th><th>origin (m)</th><th>limits</th></tr>"
        f"{rows}</table>"
    )


def _checks_table(checks: list[CheckRecord]) -> str:
    if not checks:
        return "<p class='meta'>not validated</p>"
    failed = [c for c in checks if not c.passed]
    summary = f"<p class='meta'>{len(checks) - len(failed)} of {len(checks)} checks passed</p>"
    if not failed:
        return summary
    rows = "".join(
        f"<tr class='fail'><td>{_e(c.name)}</td><td class='num'>{_e(_num(c.value))}</td>"
        f"<td class='num'>{_e(_num(c.tolerance))}</td><td>{_e(c.detail or '')}</td></tr>"
        for c in failed
    )
    return (
        summary
        + "<table><tr><th>failed check</th><th>value</th><th>tolerance</th><th>detail</th></tr>"
        f"{rows}</table>"
    )


def _card(e: _Entry, imgs: dict[str, str | None]) -> str:
    r = e.record
    size = "-" if any(v is None for v in r.size) else " × ".join(f"{v:.2f}" for v in r.size) + " m"
    gen = (r.generator or "") + (f" {r.generator_version}" if r.generator_version else "")
    facts = [f"category {r.category}", f"{r.part_count or '-'} parts", f"size {size}"]
    if gen:
        facts.append(f"generator {gen}")
    if r.stage_seconds:
        facts.append("time " + ", ".join(f"{k} {v:.1f}s" for k, v in r.stage_seconds.items()))
    parts = [
        f"<section class='card' id='{_e(r.id)}'>",
        f"<h2>{_e(r.id)} <span class='badge {_e(r.status)}'>{_e(r.status)}</span></h2>",
        f"<div class='meta'>{_e(' · '.join(facts))}</div>",
    ]
    if r.failure_reason:
        parts.append(f"<p class='reason'>failure: {_e(r.failure_reason)}</p>")
    if e.error:
        parts.append(f"<p class='reason'>unreadable: {_e(e.error)}</p>")
    parts.append(
        "<div class='imgs'>"
        + _figure(imgs["input"], "input")
        + _figure(imgs["mask"], "mask")
        + _figure(imgs["preview"], "preview: rest / open")
        + "</div>"
    )
    parts.append("<div class='cols'><div>" + _joint_table(e.asset) + "</div><div>")
    parts.append(_checks_table(e.checks))
    if r.repairs:
        parts.append(
            "<p class='meta'>repairs:</p><ul>"
            + "".join(f"<li>{_e(repair_text(x))}</li>" for x in r.repairs)
            + "</ul>"
        )
    parts.append("</div></div></section>")
    return "\n".join(parts)


def write_gallery(out_dir: str | Path) -> Path:
    """Write ``out_dir/index.html`` (and thumbnails under ``out_dir/gallery/``); return its path.

    Raises FileNotFoundError for a missing folder and CatalogError for a damaged catalog.
    """
    out = Path(out_dir)
    if not out.is_dir():
        raise FileNotFoundError(f"{out}: no such output folder")
    if catalog_path(out).is_file():
        entries = _entries_from_catalog(out)
        source = "catalog"
    else:
        entries = _entries_from_folders(out)
        source = "asset folders"
    cards = []
    for e in entries:
        _complete(e)
        gdir = out / "gallery" / e.record.id
        image, mask = _find_input(e, out)
        thumb = None if image is None else _thumbnail(image, gdir / "input.png")
        mthumb = None if mask is None else _thumbnail(mask, gdir / "mask.png", colourize=True)
        prev = _preview(e, out, gdir)
        imgs = {
            "input": None if thumb is None else _rel(thumb, out),
            "mask": None if mthumb is None else _rel(mthumb, out),
            "preview": None if prev is None else _rel(prev, out),
        }
        cards.append(_card(e, imgs))
    counts = {s: sum(e.record.status == s for e in entries) for s in ("ok", "repaired", "failed")}
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    body = "\n".join(cards) or "<p>No assets yet.</p>"
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>pact assets: {_e(out.resolve().name)}</title>
<style>{_CSS}</style></head>
<body><header><h1>{len(entries)} assets in {_e(out.resolve().name)}</h1>
<p>{counts["ok"]} ok · {counts["repaired"]} repaired · {counts["failed"]} failed · from the {source} · {stamp}</p>
</header>
<main>
{body}
</main></body></html>
"""
    index = out / "index.html"
    atomic_write_bytes(index, page.encode("utf-8"))
    log.info("wrote %s (%d assets)", index, len(entries))
    return index
