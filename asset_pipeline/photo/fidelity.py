"""How much a built asset looks like its photo: render it from the photo's camera and compare.

:func:`measure_fidelity` loads the built asset in SAPIEN at rest (every joint at its lower
limit), renders it from the camera of ``camera.json`` (:mod:`asset_pipeline.photo.camera`)
at the photo's size, writes the render as ``photo_view.png`` (RGBA: alpha is the asset's
silhouette) and compares it with ``input.<ext>`` and ``input.mask.png``.

The render is *unlit* (ambient light 1, no lamps): a baked photo texture already holds the
photo's light (:mod:`asset_pipeline.photo.texture`), so the render shows the texture as it
is; an untextured asset shows its own colours.

Metrics (all on the photo's pixel grid):

- ``silhouette_iou``: IoU of the render's silhouette and the photo's (the part mask's ids
  > 0, else the alpha channel, else the silhouette estimated on a plain background).
- ``part_iou``: the rendered link ids matched to the mask's ids by the Hungarian method
  (maximum total IoU); the mean over the mask's ids (base included) of each id's IoU with
  its link (0 for an id left without one). None without a part mask.
- ``psnr`` (dB) and ``ssim`` inside the photo's silhouette: inside it, the render where
  the asset covers the pixel and mid grey (128) where it does not; outside it, the photo
  itself (so that SSIM windows across the outline compare only what lies inside).
  PSNR = 10 log10(255^2 / MSE) over the silhouette's pixels and channels (100 dB for
  identical images), SSIM the mean over those pixels of the per-pixel SSIM map
  (Gaussian window, sigma 1.5, per channel, averaged over channels; scikit-image). A
  photo pixel the asset does not cover thus counts against both. ``psnr_overlap`` is the
  PSNR over the pixels both silhouettes cover (colour alone, shape aside).
- ``score`` in [0, 1]: the mean of ``silhouette_iou``, ``part_iou`` (when there is a
  mask), ``(psnr - 10) / 20`` clipped to [0, 1] (10 dB -> 0, 30 dB -> 1) and ``ssim``
  clipped to [0, 1]. ``pact ls --min-fidelity`` filters on it.

An asset is flagged ``low_fidelity`` (kept, not failed) when any metric falls below its
threshold (:class:`FidelityThresholds`); ``reasons`` says which and by how much.
"""

from __future__ import annotations

import io
import logging
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from asset_pipeline.photo.camera import (
    PhotoCamera,
    match_parts,
    photo_silhouette,
    read_camera,
    silhouette_iou,
)
from generator.atomic_files import atomic_write_bytes

log = logging.getLogger(__name__)

PHOTO_VIEW_NAME = "photo_view.png"
#: Grey (0..255) behind the render where the asset does not cover the photo.
BACKGROUND = 128
#: PSNR of identical images (dB).
MAX_PSNR = 100.0
#: Longest side (px) rendered; larger photos are compared at this size.
MAX_RENDER_SIZE = 2048


@dataclass(frozen=True)
class FidelityThresholds:
    """Below any of these an asset is flagged ``low_fidelity`` (docs/fidelity.md)."""

    silhouette_iou: float = 0.85
    part_iou: float = 0.6
    psnr: float = 18.0
    ssim: float = 0.5


DEFAULT_THRESHOLDS = FidelityThresholds()

_WHY = {
    "silhouette_iou": "the asset's outline does not match the photo's",
    "part_iou": "its parts do not line up with the photo's part mask",
    "psnr": "its colours differ from the photo's",
    "ssim": "its surface pattern differs from the photo's",
}


class FidelityUnavailable(RuntimeError):
    """Fidelity cannot be measured (no render device, no camera, no silhouette); the
    message says why."""


# --------------------------------------------------------------------------- metrics


def psnr(a: np.ndarray, b: np.ndarray, where: np.ndarray) -> float:
    """PSNR (dB, peak 255) of images ``a``, ``b`` (H, W, 3) over pixels ``where`` (H, W),
    at most :data:`MAX_PSNR` (identical images)."""
    d = a[where].astype(float) - b[where].astype(float)
    mse = float(np.mean(d**2)) if d.size else 0.0
    return MAX_PSNR if mse == 0 else min(MAX_PSNR, 10.0 * math.log10(255.0**2 / mse))


def ssim(a: np.ndarray, b: np.ndarray, where: np.ndarray) -> float:
    """Mean SSIM of ``a``, ``b`` (H, W, 3) uint8 over pixels ``where`` (H, W)."""
    from skimage.metrics import structural_similarity

    if not where.any():
        return 1.0
    _, full = structural_similarity(
        a,
        b,
        channel_axis=2,
        data_range=255,
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        full=True,
    )
    return float(full.mean(axis=2)[where].mean())


def fidelity_score(silhouette: float, part: float | None, psnr_db: float, ssim_v: float) -> float:
    """The one number in [0, 1] of the module docstring."""
    terms = [silhouette, float(np.clip((psnr_db - 10.0) / 20.0, 0, 1))]
    terms.append(float(np.clip(ssim_v, 0, 1)))
    if part is not None:
        terms.append(part)
    return float(np.mean(terms))


def compare(
    photo: np.ndarray,
    silhouette: np.ndarray,
    mask: np.ndarray | None,
    rendered: np.ndarray,
    covered: np.ndarray,
    link_ids: np.ndarray,
    thresholds: FidelityThresholds = DEFAULT_THRESHOLDS,
) -> dict[str, Any]:
    """The fidelity record of a render against its photo.

    ``photo`` (H, W, 3) uint8, ``silhouette`` (H, W) bool, ``mask`` (H, W) ids or None,
    ``rendered`` (H, W, 3) uint8 (anything where not ``covered``), ``covered`` (H, W)
    bool, ``link_ids`` (H, W) int (0 background, k + 1 for link k).
    """
    composite = np.where(covered[..., None], rendered, np.uint8(BACKGROUND)).astype(np.uint8)
    # outside the photo's silhouette the photo itself: SSIM windows on the outline then
    # compare only what lies inside it
    composite = np.where(silhouette[..., None], composite, photo).astype(np.uint8)
    sil = silhouette_iou(covered, silhouette)
    part, per_id, match = None, {}, {}
    if mask is not None and (mask > 0).any():
        match, per_id = match_parts(np.where(covered, link_ids, 0), mask)
        part = float(np.mean(list(per_id.values())))
    p = psnr(composite, photo, silhouette)
    s = ssim(composite, photo, silhouette)
    overlap = silhouette & covered
    record: dict[str, Any] = {
        "silhouette_iou": sil,
        "part_iou": part,
        "psnr": p,
        "ssim": s,
        "psnr_overlap": psnr(composite, photo, overlap),
        "part_iou_per_id": {str(k): v for k, v in per_id.items()},
        "part_match": {str(k): v for k, v in match.items()},
    }
    record["score"] = fidelity_score(sil, part, p, s)
    reasons = []
    for key in ("silhouette_iou", "part_iou", "psnr", "ssim"):
        value, limit = record[key], getattr(thresholds, key)
        if value is not None and value < limit:
            unit = " dB" if key == "psnr" else ""
            reasons.append(f"{key} {value:.3g}{unit} < {limit:g}{unit}: {_WHY[key]}")
    record["low_fidelity"] = bool(reasons)
    record["reasons"] = reasons
    record["thresholds"] = asdict(thresholds)
    return record


# --------------------------------------------------------------------------- render

#: One unlit render scene per process (lavapipe compiles a new context's pipelines in
#: 10-20 s; a scene kept alive makes later scenes and cameras cheap) and its cameras.
_SCENE: list[Any] = []
_CAMERAS: dict[tuple[int, int], Any] = {}
_NO_DEVICE: list[str] = []

# OpenCV camera axes (x right, y down, z forward) -> SAPIEN's (x forward, y left, z up)
_CV_TO_SAPIEN = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


def _scene() -> Any:
    if _NO_DEVICE:
        raise FidelityUnavailable(_NO_DEVICE[0])
    if not _SCENE:
        from asset_pipeline.simulation.sapien_scenes import make_scene

        try:
            scene = make_scene(render=True)
        except RuntimeError as e:
            _NO_DEVICE.append(f"no render device: {e}")
            raise FidelityUnavailable(_NO_DEVICE[0]) from e
        scene.set_ambient_light([1.0, 1.0, 1.0])
        _SCENE.append(scene)
    return _SCENE[0]


def render_device_available() -> bool:
    """True when SAPIEN can render (lavapipe on CPU machines)."""
    try:
        _scene()
    except FidelityUnavailable:
        return False
    return True


def render_view(asset_dir: str | Path, camera: PhotoCamera) -> tuple[np.ndarray, np.ndarray]:
    """Render the built asset in ``asset_dir`` at rest, unlit, from ``camera`` (object frame,
    metres). Returns (rgba (H, W, 4) uint8, link ids (H, W) int: 0 background, k + 1 for
    the asset's k-th link). Raises FidelityUnavailable without a render device."""
    import sapien

    from asset_pipeline.assets.folder import load_asset
    from asset_pipeline.simulation.sapien_scenes import load_articulation

    scene = _scene()
    key = (camera.width, camera.height)
    if key not in _CAMERAS:
        _CAMERAS[key] = scene.add_camera(
            f"photo_{camera.width}x{camera.height}", camera.width, camera.height, 1.0, 0.01, 100.0
        )
    cam = _CAMERAS[key]
    cam.set_focal_lengths(camera.fx, camera.fy)
    cam.set_principal_point(camera.cx, camera.cy)
    pose = camera.pose.copy()
    pose[:3, :3] = pose[:3, :3] @ _CV_TO_SAPIEN
    cam.entity.set_pose(sapien.Pose(pose.astype(np.float32)))
    asset = load_asset(asset_dir, metadata=False)
    art = load_articulation(scene, asset, fix_root=True, fresh_meshes=True)
    try:
        limits = np.asarray(art.get_qlimits(), dtype=float).reshape(-1, 2)
        if len(limits):
            art.set_qpos(limits[:, 0].astype(np.float32))
        scene.update_render()
        cam.take_picture()
        rgba = np.asarray(cam.get_picture("Color"), dtype=np.float32)
        seg = np.asarray(cam.get_picture("Segmentation"))[..., 1].astype(np.int64)
        names = [k.name for k in asset.links]
        lut = {link.entity.per_scene_id: names.index(link.name) + 1 for link in art.links}
    finally:
        scene.remove_articulation(art)
    ids = np.zeros(seg.shape, dtype=np.int64)
    for sid, k in lut.items():
        ids[seg == sid] = k
    out = np.clip(np.round(rgba * 255.0), 0, 255).astype(np.uint8)
    out[..., 3] = np.where(ids > 0, 255, 0)
    return out, ids


# --------------------------------------------------------------------------- one asset


def _photo_path(asset_dir: Path) -> Path | None:
    found = sorted(p for p in asset_dir.glob("input.*") if not p.name.endswith(".mask.png"))
    return found[0] if found else None


def measure_fidelity(
    asset_dir: str | Path, thresholds: FidelityThresholds = DEFAULT_THRESHOLDS
) -> dict[str, Any]:
    """Render ``photo_view.png`` and return the fidelity record (module docstring) of the
    built asset in ``asset_dir`` against its ``input.*`` photo and ``input.mask.png``.

    Raises FidelityUnavailable naming why when it cannot be measured: no photo, no
    ``camera.json``, no silhouette, or no render device.
    """
    from asset_pipeline.inputs.mask import read_mask
    from asset_pipeline.inputs.photo import read_image

    t0, c0 = time.perf_counter(), time.process_time()
    asset_dir = Path(asset_dir)
    photo_path = _photo_path(asset_dir)
    if photo_path is None:
        raise FidelityUnavailable("no photo (input.*) in the asset folder")
    camera = read_camera(asset_dir)
    if camera is None:
        raise FidelityUnavailable("no camera.json (the photo's camera was not estimated)")
    image, alpha = read_image(photo_path)
    mask_path = asset_dir / "input.mask.png"
    height, width = image.shape[:2]
    mask = read_mask(mask_path, (width, height)) if mask_path.is_file() else None
    silhouette = photo_silhouette(image, mask, alpha)
    if silhouette is None:
        raise FidelityUnavailable(
            "the photo has no silhouette (no mask, alpha or plain background)"
        )
    H, W = silhouette.shape
    f = min(1.0, MAX_RENDER_SIZE / max(H, W))
    w, h = max(1, round(W * f)), max(1, round(H * f))
    if f < 1.0:
        from asset_pipeline.photo.camera import resample_nearest

        image = np.asarray(Image.fromarray(image).resize((w, h), Image.BILINEAR))
        silhouette = resample_nearest(silhouette, h, w)
        mask = None if mask is None else resample_nearest(mask, h, w)
    rgba, ids = render_view(asset_dir, camera.resized(w, h))
    buf = io.BytesIO()
    Image.fromarray(rgba).save(buf, format="PNG")
    atomic_write_bytes(asset_dir / PHOTO_VIEW_NAME, buf.getvalue())
    record = compare(image, silhouette, mask, rgba[..., :3], rgba[..., 3] > 0, ids, thresholds)
    record["photo_view"] = PHOTO_VIEW_NAME
    record["seconds"] = time.perf_counter() - t0
    record["cpu_seconds"] = time.process_time() - c0
    return record


def skipped_record(reason: str, thresholds: FidelityThresholds = DEFAULT_THRESHOLDS) -> dict:
    """The fidelity record of an asset that could not be measured (score None)."""
    return {
        "silhouette_iou": None,
        "part_iou": None,
        "psnr": None,
        "ssim": None,
        "score": None,
        "low_fidelity": False,
        "reasons": [],
        "skipped": reason,
        "thresholds": asdict(thresholds),
    }


def record_fidelity(asset_dir: str | Path, record: dict[str, Any]) -> None:
    """Store ``record`` as the ``fidelity`` of the asset's ``report.json`` (which must exist)."""
    from asset_pipeline.validate.report import read_report, write_report

    report = read_report(asset_dir)
    if report is None:
        raise FileNotFoundError(f"{Path(asset_dir) / 'report.json'}: no validation report")
    report.fidelity = record
    write_report(report, asset_dir)
