"""The HTML gallery of an output folder: ``OUT/index.html``.

One card per asset: the input photo and its part mask (colour-coded), the asset
rendered from the photo's estimated camera (``photo_view.png``) and its fidelity
numbers (silhouette and part IoU, PSNR, SSIM, score; a "low fidelity" badge when
flagged), the validation preview (``preview.png``: the object at rest and open), an
interactive 3D view with one slider per movable joint, the joint table and the
validation status with every failed check's measured value and tolerance, the
repairs and the failure reason. What an asset lacks (imported assets have no photo,
unconverted ones no fidelity) is left out or shown as missing.

Assets come from the catalog (``OUT/registry.sqlite``) when there is one, else
from the subfolders of OUT that hold an ``asset.json``. The page uses relative links
only. Thumbnails of inputs, masks and photo views and each asset's 3D scene
(``scene.json``: links with their visual GLBs, joints with parent, origin, axis,
type and limits) are written to ``OUT/gallery/<id>/``; previews and visuals inside
OUT are linked, those elsewhere are copied there.

The 3D view is three.js (0.187.0, MIT; ``scripts/setup.sh`` fetches it from the npm
registry into ``asset_pipeline/gallery/web/three/``, which is not kept in the repository) loaded as
ES modules through an import map; the static files are copied to
``OUT/gallery_web/``. Without three.js the page is written all the same and its 3D
panels say how to install it. Browsers refuse ES-module imports and
``fetch()`` of local files from a ``file://`` page, so the 3D view needs the folder
served over HTTP, on the loopback interface and with no other network:
``pact gallery OUT --serve`` (or ``python -m http.server -b
127.0.0.1 -d OUT``). Opened as a file, the rest of the page works and the 3D panels
say how to serve it. The views load lazily (when their card scrolls into view) and
at most four hold a WebGL context at once.

A card of an asset converted from a photo has an "edit mask" button, which
``web/editor.js`` enables when the page is served by ``pact gallery OUT --serve``: the
mask editor (server side :mod:`asset_pipeline.gallery.editor`, routes
:mod:`asset_pipeline.gallery.server`; docs/gallery.md). Screenshots of the served page:
:mod:`asset_pipeline.gallery.screenshots`.
"""

from __future__ import annotations

import html
import json
import logging
import math
import os
import shutil
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
from PIL import Image

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.assets.folder import load_asset
from asset_pipeline.assets.layout import ASSET_JSON_NAME, AssetFormatError
from asset_pipeline.catalog.registry import (
    AssetRecord,
    Catalog,
    CatalogError,
    CheckRecord,
    catalog_path,
    checks_from_report,
    records_from_asset_dir,
    repair_text,
    source_text,
)
from asset_pipeline.gallery.editor import MASK_PALETTE
from asset_pipeline.inputs.folder import IMAGE_SUFFIXES, MASK_SUFFIX
from asset_pipeline.validate import ReportFormatError, read_report
from generator.atomic_files import atomic_write_bytes

log = logging.getLogger(__name__)

THUMB_SIZE = 320
#: The static files of the page (viewer; three.js once scripts/setup.sh has fetched it),
#: copied to OUT/gallery_web/.
WEB_SOURCE = Path(__file__).with_name("web")
WEB_DIR_NAME = "gallery_web"
#: Fidelity numbers shown on a card, in order: (key in the fidelity object, label, unit).
FIDELITY_FIELDS = (
    ("score", "score", ""),
    ("silhouette_iou", "silhouette IoU", ""),
    ("part_iou", "part IoU", ""),
    ("psnr", "PSNR", " dB"),
    ("ssim", "SSIM", ""),
)
#: Joint types that get a slider in the 3D view.
SLIDER_JOINT_TYPES = ("prismatic", "revolute", "continuous")


@dataclass
class _Entry:
    record: AssetRecord
    asset_dir: Path | None
    checks: list[CheckRecord] = field(default_factory=list)
    asset: BuiltAsset | None = None
    error: str | None = None
    fidelity: Mapping[str, Any] | None = None


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
    e.fidelity = _fidelity(e)
    if e.asset_dir is None or not (e.asset_dir / ASSET_JSON_NAME).is_file():
        return
    try:
        e.asset = load_asset(e.asset_dir)
        if not e.checks:
            e.checks = checks_from_report(read_report(e.asset_dir))
    except (AssetFormatError, ReportFormatError) as err:
        log.warning("%s", err)
        e.error = str(err)


def _fidelity(e: _Entry) -> Mapping[str, Any] | None:
    """The asset's fidelity object: the catalog's, else ``report.json``'s, else None."""
    if isinstance(e.record.fidelity, Mapping):
        return e.record.fidelity
    if e.asset_dir is None or not (e.asset_dir / "report.json").is_file():
        return None
    try:
        fid = json.loads((e.asset_dir / "report.json").read_text()).get("fidelity")
    except (OSError, ValueError, AttributeError):
        return None
    return fid if isinstance(fid, Mapping) else None


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


def _inside_or_copied(src: Path, out: Path, dest: Path) -> Path:
    """``src`` when it lies inside OUT (the server can reach it), else a copy at ``dest``
    (kept when it has the source's size and time)."""
    try:
        src.resolve().relative_to(out.resolve())
        return src
    except ValueError:
        _copy_if_changed(src, dest)
        return dest


def _copy_if_changed(src: Path, dest: Path) -> None:
    st = src.stat()
    if dest.is_file():
        dt = dest.stat()
        if dt.st_size == st.st_size and int(dt.st_mtime) == int(st.st_mtime):
            return
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy2(src, dest)


def _rows(T: np.ndarray) -> list[float]:
    return [round(float(x) + 0.0, 9) for x in np.asarray(T, dtype=float).reshape(16)]


def _joint_range(j: Any) -> tuple[float, float]:
    lo, hi = float(j.lower), float(j.upper)
    if j.type == "continuous" and not hi > lo:
        return -math.pi, math.pi
    return lo, hi


def photo_camera(asset_dir: Path) -> dict[str, Any] | None:
    """The photo's estimated camera (``camera.json``) as the 3D view takes it, or None.

    ``pose``: camera-to-object (16 numbers, row-major) in three.js camera axes (x right,
    y up, looking down -z; ``camera.json`` has OpenCV's: y down, z forward); ``fov``:
    the vertical field of view in degrees; ``aspect``: the photo's width / height.
    """
    try:
        doc = json.loads((asset_dir / "camera.json").read_text(encoding="utf-8"))
        w, h, fy = float(doc["width"]), float(doc["height"]), float(doc["fy"])
        pose = np.asarray(doc["pose"], dtype=float).reshape(4, 4)
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not (np.isfinite(pose).all() and w > 0 and h > 0 and fy > 0):
        return None
    gl = pose @ np.diag([1.0, -1.0, -1.0, 1.0])
    return {"pose": _rows(gl), "fov": math.degrees(2 * math.atan(h / (2 * fy))), "aspect": w / h}


def write_scene(asset: BuiltAsset, out: Path, gallery_dir: Path) -> Path | None:
    """Write ``gallery_dir/scene.json``, the 3D view's description of ``asset``; return it.

    Links with their visual GLBs (URLs relative to the scene file, each placed by its
    ``origin`` in the link frame), joints (parent, child, type, ``origin``: the child
    frame in the parent link frame at rest, ``axis`` in the child frame,
    ``lower``/``upper``) and, when the asset has a ``camera.json``, the photo's camera
    (:func:`photo_camera`); 4x4 matrices as 16 numbers, row-major. None when the asset
    has no GLB visual on disk.
    """
    links = []
    count = 0
    for link in asset.links:
        visuals = []
        for k, v in enumerate(link.visuals):
            src = asset.path_of(v.filename)
            if src.suffix.lower() != ".glb" or not src.is_file():
                continue
            glb = _inside_or_copied(src, out, gallery_dir / "visual" / f"{link.name}_{k}.glb")
            rel = Path(os.path.relpath(glb.resolve(), gallery_dir.resolve())).as_posix()
            visuals.append({"url": quote(rel), "origin": _rows(v.origin)})
            count += 1
        links.append(
            {
                "name": link.name,
                "semantic": link.semantic,
                "visuals": visuals,
                "rgba": [round(float(x), 4) for x in link.rgba],
            }
        )
    if count == 0:
        return None
    joints = []
    for j in asset.joints:
        lo, hi = _joint_range(j)
        joints.append(
            {
                "name": j.name,
                "type": j.type,
                "parent": j.parent,
                "child": j.child,
                "origin": _rows(j.origin),
                "axis": [round(float(x) + 0.0, 9) for x in j.unit_axis],
                "lower": lo,
                "upper": hi,
            }
        )
    scene = {
        "schema": "pact.gallery_scene",
        "version": 1,
        "id": asset.id,
        "root": asset.root,
        "links": links,
        "joints": joints,
        "bounds": None if asset.bounds is None else np.asarray(asset.bounds).tolist(),
        "photo_camera": None if asset.folder is None else photo_camera(asset.folder),
    }
    path = gallery_dir / "scene.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, json.dumps(scene, separators=(",", ":")).encode("utf-8"))
    return path


def _copy_web(out: Path) -> None:
    """Copy the page's static files (viewer, three.js) to ``OUT/gallery_web/``."""
    dest = out / WEB_DIR_NAME
    for src in sorted(WEB_SOURCE.rglob("*")):
        if not src.is_file() or "__pycache__" in src.parts:
            continue
        _copy_if_changed(src, dest / src.relative_to(WEB_SOURCE))


# --------------------------------------------------------------------------- html

_CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:0;background:#f4f4f6;color:#222}
body.has-focus{overflow:hidden}
header{background:#223;color:#fff;padding:14px 24px}
header h1{margin:0;font-size:20px} header p{margin:4px 0 0;color:#ccd}
header .serve{display:none;margin-top:8px;background:#334;border-radius:6px;padding:8px 12px;color:#fff}
body.file-mode header .serve{display:block}
code{font:12px ui-monospace,monospace;background:#0001;padding:1px 4px;border-radius:3px}
header code{background:#fff2;user-select:all}
main{padding:16px 24px;display:flex;flex-direction:column;gap:16px}
.card{background:#fff;border-radius:8px;box-shadow:0 1px 3px #0002;padding:14px 18px}
.card h2{margin:0 0 6px;font-size:17px;display:flex;align-items:center;gap:10px}
.badge{font-size:12px;padding:2px 8px;border-radius:10px;color:#fff}
.ok{background:#2a8a3a}.repaired{background:#c98a00}.failed{background:#c0392b}
.lowfid{background:#d35400}
.parsed{background:#7d3c98}
.meta{color:#555;margin-bottom:8px}
.body{display:flex;gap:20px;align-items:flex-start;flex-wrap:wrap}
.info{flex:1 1 520px;min-width:0}
.imgs{display:flex;gap:12px;flex-wrap:wrap;margin:4px 0 8px}
figure{margin:0;text-align:center} figcaption{font-size:12px;color:#666}
figure img{height:160px;width:auto;max-width:400px;object-fit:contain;border:1px solid #ddd;background:
 repeating-conic-gradient(#eee 0 25%,#fff 0 50%) 50%/16px 16px}
.missing{width:140px;height:160px;display:flex;align-items:center;justify-content:center;
 border:1px dashed #bbb;color:#999;font-size:12px}
.swap{position:relative;display:inline-block;line-height:0}
.swap .alt{position:absolute;left:0;top:0;opacity:0;transition:opacity .15s}
.swap:hover .alt{opacity:1}
.fid{display:flex;gap:6px;flex-wrap:wrap;align-items:center;margin:2px 0 8px;font-size:13px}
.fid .n{background:#f0f0f4;border-radius:4px;padding:1px 8px;font-variant-numeric:tabular-nums}
.fid .n b{font-weight:600}
.fid.low .n{background:#fdebd0}
table{border-collapse:collapse;margin:6px 0 10px;font-size:13px}
th,td{border-bottom:1px solid #e4e4e8;padding:3px 10px;text-align:left}
th{background:#f0f0f4} td.num{text-align:right;font-variant-numeric:tabular-nums}
tr.fail td{color:#b0281a} .reason{color:#b0281a;font-weight:600}
.warnings{color:#8a5a00;margin:4px 0;padding-left:18px}
.cols{display:flex;gap:28px;flex-wrap:wrap}
.viewer{flex:0 0 460px;max-width:100%;border:1px solid #d8dce3;border-radius:6px;overflow:hidden;
 background:#eef1f5;display:flex;flex-direction:column}
.viewer .stage{position:relative;height:340px;cursor:grab;touch-action:none}
.viewer .stage canvas,.viewer .stage img.snapshot{position:absolute;inset:0;width:100%;height:100%;display:block}
.viewer .stage img.snapshot{object-fit:cover;cursor:pointer;filter:saturate(.7)}
.viewer .note{position:absolute;inset:0;display:flex;align-items:center;justify-content:center;
 color:#667;font-size:13px;text-align:center;padding:16px}
.viewer .expand{position:absolute;top:6px;right:6px;z-index:2;border:0;border-radius:4px;
 background:#fffc;padding:2px 8px;cursor:pointer;font-size:13px}
.viewer .panel{background:#fff;border-top:1px solid #d8dce3;padding:6px 10px 8px}
.viewer .vtitle{display:none;font-weight:600;margin:2px 0 8px}
.viewer .joint{display:grid;grid-template-columns:110px 1fr 66px;gap:8px;align-items:center;font-size:12px}
.viewer .joint label{overflow:hidden;text-overflow:ellipsis;white-space:nowrap}
.viewer .joint output{text-align:right;font-variant-numeric:tabular-nums}
.viewer .joint input{width:100%;margin:2px 0}
.viewer .vbtns{display:flex;gap:6px;margin-top:4px}
.viewer .vbtns button{font-size:12px;padding:1px 8px;cursor:pointer}
.viewer .nojoints{font-size:12px;color:#777}
.viewer.focus{position:fixed;inset:0;z-index:100;border:0;border-radius:0;flex-direction:row;max-width:none}
.viewer.focus .stage{flex:1;height:auto}
.viewer.focus .panel{flex:0 0 280px;border-top:0;border-left:1px solid #d8dce3;overflow:auto;padding:12px}
.viewer.focus .vtitle{display:block}
.viewer.focus .joint{grid-template-columns:1fr 70px}
.viewer.focus .joint input{grid-column:1/3;grid-row:2}
header .editor-off{display:none;margin-top:8px;color:#fc9}
header .editor-off:not(:empty){display:block}
.edit-row{display:flex;gap:8px;align-items:center;margin:0 0 8px;font-size:12px;color:#666}
.edit-row button{font-size:12px;padding:2px 10px;cursor:pointer}
.edit-row button:disabled{cursor:default}
.card[data-edit-state=failed] .edit-note{color:#b0281a}
.card[data-edit-state=converting] .edit-note{color:#225}
body.has-editor{overflow:hidden}
#mask-editor{position:fixed;inset:0;z-index:200;display:flex;background:#1d2029;color:#222}
#mask-editor .me-stage{flex:1;position:relative;overflow:hidden;display:flex;align-items:center;
 justify-content:center;padding:12px}
#mask-editor .me-wrap{position:relative;line-height:0;cursor:crosshair;touch-action:none;
 box-shadow:0 0 0 1px #fff3}
#mask-editor .me-wrap canvas,#mask-editor .me-wrap svg{position:absolute;inset:0;width:100%;height:100%}
#mask-editor .me-wrap canvas.me-photo{position:static;display:block}
#mask-editor .me-wrap canvas.me-mask{image-rendering:pixelated}
#mask-editor .me-hint{position:absolute;left:12px;bottom:8px;color:#ccd;font-size:12px}
#mask-editor .me-panel{flex:0 0 340px;background:#fff;overflow:auto;padding:12px 14px;
 display:flex;flex-direction:column;gap:10px;font-size:13px}
#mask-editor h3{margin:0;font-size:16px} #mask-editor .sub{color:#666;font-size:12px}
#mask-editor fieldset{border:1px solid #dde;border-radius:6px;padding:6px 10px 8px;margin:0;min-width:0}
#mask-editor legend{font-size:12px;color:#556;padding:0 4px}
#mask-editor .me-tools{display:flex;flex-wrap:wrap;gap:6px;align-items:center}
#mask-editor button{font-size:12px;padding:3px 10px;cursor:pointer}
#mask-editor button.on{background:#2a5db0;color:#fff;border-color:#2a5db0}
#mask-editor select{font-size:12px;max-width:100%}
#mask-editor .me-part{display:grid;grid-template-columns:14px 1fr;gap:2px 8px;align-items:center;
 padding:4px 0;border-bottom:1px solid #eef}
#mask-editor .me-part .sw{width:14px;height:14px;border-radius:3px;border:1px solid #0003}
#mask-editor .me-part select{grid-column:2;width:100%}
#mask-editor .me-part .src,#mask-editor .src{grid-column:2;font-size:11px;color:#777}
#mask-editor .src button{font-size:11px;padding:0 6px;margin-left:4px}
#mask-editor .me-actions{display:flex;gap:8px;flex-wrap:wrap}
#mask-editor .me-actions .save{background:#2a8a3a;color:#fff;border:0;padding:6px 14px;font-size:13px}
#mask-editor .me-actions .save:disabled{opacity:.5;cursor:default}
#mask-editor .me-panel>*{flex-shrink:0}
#mask-editor .me-status{font-size:12px;min-height:1.4em;white-space:pre-wrap;overflow-wrap:anywhere}
#mask-editor .me-status.error{color:#b0281a}
"""

#: Runs on pages opened from the file system: browsers do not let such a page load the
#: viewer's modules and GLBs, so the 3D panels say how to serve the folder instead.
_FILE_MODE_JS = """
if (location.protocol === 'file:') {
  document.body.classList.add('file-mode');
  var dir = decodeURIComponent(location.pathname.replace(/\\/[^\\/]*$/, '') || '/');
  var cmd = document.getElementById('serve-cmd');
  if (cmd) cmd.textContent = "python3 -m http.server -b 127.0.0.1 -d '" + dir + "' 8000";
  var pact = document.getElementById('serve-pact');
  if (pact) pact.textContent = "pact gallery '" + dir + "' --serve";
  document.querySelectorAll('.edit-note').forEach(function (n) {
    n.textContent = 'opened as a file: the mask editor needs the page served (see the top)';
  });
  document.body.dataset.galleryReady = 'file';
  document.querySelectorAll('.viewer').forEach(function (v) {
    v.dataset.state = 'file';
    var n = v.querySelector('.note');
    if (n) n.textContent = 'The 3D view needs this folder served over HTTP (see the top of the page).';
    v.querySelectorAll('input').forEach(function (i) { i.disabled = true; });
  });
}
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
    if joint_type in ("revolute", "continuous"):
        return f"{math.degrees(lo):.1f}° … {math.degrees(hi):.1f}°"
    if joint_type == "prismatic":
        return f"{lo:.3f} … {hi:.3f} m"
    return f"{lo:g} … {hi:g}"


def _figure(src: str | None, caption: str) -> str:
    if src is None:
        return f'<figure><div class="missing">no {_e(caption)}</div><figcaption>{_e(caption)}</figcaption></figure>'
    return (
        f'<figure><img src="{_e(src)}" alt="{_e(caption)}" loading="lazy">'
        f"<figcaption>{_e(caption)}</figcaption></figure>"
    )


def _photo_figure(photo: str, mask: str) -> str:
    """The photo, its part mask shown in its place while the pointer is over it."""
    return (
        f'<figure class="photo"><div class="swap"><img src="{_e(photo)}" alt="photo">'
        f'<img class="alt" src="{_e(mask)}" alt="part mask" loading="lazy"></div>'
        "<figcaption>photo (hover: part mask)</figcaption></figure>"
    )


def _inputs_line(inputs: Mapping[str, Any]) -> str:
    """Where the part mask and each part's motion came from: the user or the photo parser
    (with its confidence), the parser's words marked for a person to check."""
    if not inputs:
        return ""
    mask = inputs.get("mask") or {}
    items = [f"mask: {mask.get('source', 'none')}"]
    items += [
        f"{k}: {v.get('motion', '?')}{source_text(v)}"
        for k, v in sorted((inputs.get("parts") or {}).items(), key=lambda kv: int(kv[0]))
    ]
    parsed = any(
        (v or {}).get("source") == "parser"
        for v in [inputs.get("category"), mask, *(inputs.get("parts") or {}).values()]
    )
    note = " <span class='badge parsed'>read by the parser: check it</span>" if parsed else ""
    return f"<p class='meta inputs'>{_e(' · '.join(items))}{note}</p>"


def _joint_table(asset: BuiltAsset | None) -> str:
    try:
        parts = [] if asset is None else asset.movable_parts()
    except KeyError:  # a movable part without a handle: list the joints alone
        parts = []
    if parts:
        rows = "".join(
            f"<tr><td>{_e(p.name)}</td><td>{_e(p.joint_type)}</td>"
            f"<td class='num'>{_e(_num([round(a, 3) for a in p.axis]))}</td>"
            f"<td class='num'>{_e(_num([round(a, 3) for a in p.origin]))}</td>"
            f"<td class='num'>{_e(_limits(p.joint_type, p.lower, p.upper))}</td></tr>"
            for p in parts
        )
    elif asset is not None and asset.movable_joints:
        rows = "".join(
            f"<tr><td>{_e(j.child)}</td><td>{_e(j.type)}</td>"
            f"<td class='num'>{_e(_num([round(float(a), 3) for a in j.unit_axis]))}</td>"
            f"<td class='num'>-</td>"
            f"<td class='num'>{_e(_limits(j.type, *_joint_range(j)))}</td></tr>"
            for j in asset.movable_joints
        )
    else:
        return "<p class='meta'>no joints recorded</p>"
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


def _is_low(fid: Mapping[str, Any] | None) -> bool:
    return bool(fid and fid.get("low_fidelity") is True)


def _fidelity_line(fid: Mapping[str, Any] | None, has_photo: bool) -> str:
    """The fidelity numbers (and why they are low), or a note when not measured."""
    if not fid:
        return "<div class='fid meta'>fidelity not measured</div>" if has_photo else ""
    chips = []
    for key, label, unit in FIDELITY_FIELDS:
        v = fid.get(key)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
            text = f"{v:.1f}" if key == "psnr" else f"{v:.2f}"
            chips.append(f"<span class='n'>{_e(label)} <b>{_e(text)}{_e(unit)}</b></span>")
    if not chips:
        why = fid.get("skipped") or fid.get("reason")
        return f"<div class='fid meta'>fidelity not measured{_e(f': {why}' if why else '')}</div>"
    reasons = fid.get("reasons") or []
    if isinstance(reasons, str):
        reasons = [reasons]
    low = _is_low(fid)
    tail = ""
    if low and reasons:
        tail = f"<span class='reason'>{_e('; '.join(str(r) for r in reasons))}</span>"
    return f"<div class='fid{' low' if low else ''}'><span>fidelity</span> {''.join(chips)} {tail}</div>"


def _viewer(e: _Entry, scene: str | None) -> str:
    """The 3D view's block: a stage the script fills, one slider per movable joint."""
    if e.asset is None or scene is None:
        return ""
    has_camera = e.asset_dir is not None and photo_camera(e.asset_dir) is not None
    photo_button = (
        "<button type='button' data-action='photo' title=\"the photo's estimated camera\">"
        "photo view</button>"
        if has_camera
        else ""
    )
    r = e.record
    sliders = []
    for j in e.asset.joints:
        if j.type not in SLIDER_JOINT_TYPES:
            continue
        lo, hi = _joint_range(j)
        step = (hi - lo) / 200 if hi > lo else 0.01
        sid = f"q-{r.id}-{j.name}"
        sliders.append(
            f"<div class='joint'><label for='{_e(sid)}' title='{_e(j.name)} ({_e(j.type)})'>"
            f"{_e(j.child)}</label>"
            f"<input type='range' id='{_e(sid)}' data-joint='{_e(j.name)}' data-type='{_e(j.type)}'"
            f" min='{lo:.6g}' max='{hi:.6g}' step='{step:.6g}' value='{lo:.6g}' disabled>"
            f"<output for='{_e(sid)}'></output></div>"
        )
    pose_buttons = (
        "<button type='button' data-pose='lower'>closed</button>"
        "<button type='button' data-pose='upper'>open</button>"
        if sliders
        else ""
    )
    controls = (
        ("".join(sliders) if sliders else "<p class='nojoints'>no movable joints</p>")
        + f"<div class='vbtns'>{pose_buttons}"
        "<button type='button' data-action='reset'>reset view</button>"
        f"{photo_button}</div>"
    )
    return (
        f"<div class='viewer' data-asset='{_e(r.id)}' data-scene='{_e(scene)}'>"
        "<div class='stage'><div class='note'>3D view</div>"
        "<button type='button' class='expand' title='full window (Esc closes)'>⤢</button></div>"
        f"<div class='panel'><div class='vtitle'>{_e(r.id)}</div>{controls}</div></div>"
    )


def _edit_row(asset_id: str) -> str:
    """The mask editor's button (web/editor.js enables it when the server has the editor)."""
    return (
        f"<div class='edit-row'><button type='button' class='edit-mask' data-asset='{_e(asset_id)}'"
        " disabled title='fix the part mask, the motions and the category, then convert again'>"
        "edit mask</button> <span class='edit-note'>the mask editor needs "
        "<code>pact gallery OUT --serve</code></span></div>"
    )


def _card(e: _Entry, imgs: dict[str, str | None], scene: str | None = None) -> str:
    r = e.record
    size = "-" if any(v is None for v in r.size) else " × ".join(f"{v:.2f}" for v in r.size) + " m"
    gen = (r.generator or "") + (f" {r.generator_version}" if r.generator_version else "")
    facts = [
        f"category {r.category}{source_text((r.inputs or {}).get('category'))}",
        f"{r.part_count or '-'} parts",
        f"size {size}",
    ]
    if gen:
        facts.append(f"generator {gen}")
    if r.stage_seconds:
        facts.append("time " + ", ".join(f"{k} {v:.1f}s" for k, v in r.stage_seconds.items()))
    low = " <span class='badge lowfid'>low fidelity</span>" if _is_low(e.fidelity) else ""
    parts = [
        f"<section class='card' id='{_e(r.id)}'>",
        f"<h2>{_e(r.id)} <span class='badge {_e(r.status)}'>{_e(r.status)}</span>{low}</h2>",
        f"<div class='meta'>{_e(' · '.join(facts))}</div>",
    ]
    if r.failure_reason:
        parts.append(f"<p class='reason'>failure: {_e(r.failure_reason)}</p>")
    if r.warnings:  # what the conversion asks a person to check (as `pact ls` lists them)
        parts.append(
            "<ul class='warnings'>"
            + "".join(f"<li>warning: {_e(w)}</li>" for w in r.warnings)
            + "</ul>"
        )
    if e.error:
        parts.append(f"<p class='reason'>unreadable: {_e(e.error)}</p>")
    has_photo = imgs["input"] is not None
    figures = []
    if has_photo and imgs.get("mask") is not None:
        figures.append(_photo_figure(imgs["input"], imgs["mask"]))
    elif has_photo:
        figures.append(_figure(imgs["input"], "photo"))
    elif imgs.get("mask") is not None:
        figures.append(_figure(imgs["mask"], "part mask"))
    if has_photo or imgs.get("photo_view") is not None:
        figures.append(_figure(imgs.get("photo_view"), "asset from the photo's camera"))
    figures.append(_figure(imgs["preview"], "preview: rest / open"))
    parts.append("<div class='body'><div class='info'>")
    parts.append("<div class='imgs'>" + "".join(figures) + "</div>")
    if r.source_image:
        parts.append(_edit_row(r.id))
    parts.append(_inputs_line(r.inputs or {}))
    parts.append(_fidelity_line(e.fidelity, has_photo))
    parts.append("<div class='cols'><div>" + _joint_table(e.asset) + "</div><div>")
    parts.append(_checks_table(e.checks))
    if r.repairs:
        parts.append(
            "<p class='meta'>repairs:</p><ul>"
            + "".join(f"<li>{_e(repair_text(x))}</li>" for x in r.repairs)
            + "</ul>"
        )
    parts.append("</div></div></div>")
    parts.append(_viewer(e, scene))
    parts.append("</div></section>")
    return "\n".join(parts)


def write_gallery(out_dir: str | Path) -> Path:
    """Write ``out_dir/index.html`` (thumbnails and 3D scenes under ``out_dir/gallery/``,
    the viewer's static files under ``out_dir/gallery_web/``); return its path.

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
    _copy_web(out)
    cards = []
    for e in entries:
        _complete(e)
        gdir = out / "gallery" / e.record.id
        image, mask = _find_input(e, out)
        thumb = None if image is None else _thumbnail(image, gdir / "input.png")
        mthumb = None if mask is None else _thumbnail(mask, gdir / "mask.png", colourize=True)
        pview = None
        if e.asset_dir is not None and (e.asset_dir / "photo_view.png").is_file():
            pview = _thumbnail(e.asset_dir / "photo_view.png", gdir / "photo_view.png")
        prev = _preview(e, out, gdir)
        scene = None
        if e.asset is not None:
            try:
                scene_path = write_scene(e.asset, out, gdir)
                scene = None if scene_path is None else _rel(scene_path, out)
            except (OSError, ValueError) as err:
                log.warning("%s: no 3D view: %s", e.record.id, err)
        imgs = {
            "input": None if thumb is None else _rel(thumb, out),
            "mask": None if mthumb is None else _rel(mthumb, out),
            "photo_view": None if pview is None else _rel(pview, out),
            "preview": None if prev is None else _rel(prev, out),
        }
        cards.append(_card(e, imgs, scene))
    counts = {s: sum(e.record.status == s for e in entries) for s in ("ok", "repaired", "failed")}
    low = sum(_is_low(e.fidelity) for e in entries)
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    body = "\n".join(cards) or "<p>No assets yet.</p>"
    low_text = f" · {low} low fidelity" if low else ""
    importmap = json.dumps(
        {
            "imports": {
                "three": f"./{WEB_DIR_NAME}/three/build/three.module.js",
                "three/addons/": f"./{WEB_DIR_NAME}/three/examples/jsm/",
            }
        }
    )
    no_three = ""
    if not (WEB_SOURCE / "three" / "build" / "three.module.js").is_file():
        log.warning(
            "no three.js in %s: the gallery has no 3D views (run scripts/setup.sh)", WEB_SOURCE
        )
        no_three = (
            "<p class='no-three'>No 3D views: three.js is not installed here "
            "(<code>bash scripts/setup.sh</code> fetches it from the npm registry).</p>"
        )
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>pact assets: {_e(out.resolve().name)}</title>
<style>{_CSS}</style>
<script type="importmap">{importmap}</script>
<script type="module" src="{WEB_DIR_NAME}/viewer.js"></script>
<script type="module" src="{WEB_DIR_NAME}/editor.js"></script>
</head>
<body><header><h1>{len(entries)} asset{"" if len(entries) == 1 else "s"} in {_e(out.resolve().name)}</h1>
<p>{counts["ok"]} ok · {counts["repaired"]} repaired · {counts["failed"]} failed{low_text} · from the {source} · {stamp}</p>
<div class="serve">This page was opened as a file, and browsers do not let a local page load
its 3D views. Serve the folder on this machine and open <b>http://127.0.0.1:8000/</b>:
<code id="serve-cmd">python3 -m http.server -b 127.0.0.1 -d OUT 8000</code>
<br>The mask editor (the <b>edit mask</b> buttons) also needs the gallery's own server, which
answers this machine only (127.0.0.1): <code id="serve-pact">pact gallery OUT --serve</code></div>
<div class="editor-off" id="editor-off"></div>
{no_three}</header>
<main>
{body}
</main>
<script>{_FILE_MODE_JS}</script>
</body></html>
"""
    index = out / "index.html"
    atomic_write_bytes(index, page.encode("utf-8"))
    log.info("wrote %s (%d assets)", index, len(entries))
    return index
