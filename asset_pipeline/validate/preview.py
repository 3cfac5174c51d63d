"""``preview.png`` of a built asset: at rest and with every joint open, side by side.

Rendered by a SAPIEN camera (lavapipe's Vulkan on CPU machines) from a
front-right-above view: the object's front faces +x, so the camera sits at
+x (front), +y (the viewer's right when facing the front) and above, looking at
the centre of the object's bounds. Both halves use the same camera so the
opening motion reads directly. Without a render device :func:`render_preview`
logs why and returns None; validation goes on without a preview.
"""

from __future__ import annotations

import io
import logging
import math
from pathlib import Path

import numpy as np

from generator.atomic_files import atomic_write_bytes

log = logging.getLogger(__name__)

PREVIEW_NAME = "preview.png"
#: Background grey (0..1) composited behind the object.
BACKGROUND = 0.92


def look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """4x4 pose of a SAPIEN camera at ``eye`` looking at ``target`` (camera x forward, z up)."""
    fwd = target - eye
    fwd = fwd / np.linalg.norm(fwd)
    left = np.cross([0.0, 0.0, 1.0], fwd)
    left = left / np.linalg.norm(left)
    up = np.cross(fwd, left)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = fwd, left, up, eye
    return T


def _bounds(art: object) -> np.ndarray:
    boxes = [link.compute_global_aabb_tight() for link in art.links]  # type: ignore[attr-defined]
    b = np.array(boxes, dtype=float)
    return np.stack([b[:, 0].min(0), b[:, 1].max(0)])


def render_preview(
    asset_dir: str | Path, *, size: int = 384, fovy_deg: float = 40.0
) -> Path | None:
    """Render ``preview.png`` (two ``size`` x ``size`` views) into the asset folder.

    Returns the path, or None (with a logged reason) when no render device exists
    or the asset cannot be loaded for rendering.
    """
    asset_dir = Path(asset_dir)
    stage = _stage(size, fovy_deg)
    if stage is None:
        log.warning("%s: no preview: %s", asset_dir.name, _NO_DEVICE[0])
        return None
    import sapien
    from PIL import Image

    from asset_pipeline.assets.folder import load_asset
    from asset_pipeline.simulation.sapien_scenes import load_articulation

    scene, cam = stage
    try:
        asset = load_asset(asset_dir, metadata=False)
        art = load_articulation(scene, asset, fix_root=True, fresh_meshes=True)
    except Exception as e:  # noqa: BLE001 - SAPIEN raises many types
        log.warning("%s: no preview: the asset does not load for rendering: %s", asset_dir.name, e)
        return None
    try:
        return _render(scene, cam, art, asset_dir, fovy_deg, Image, sapien)
    finally:
        scene.remove_articulation(art)


#: One render scene and camera per (size, fov), reused: lavapipe compiles the render
#: pipelines of a new scene in 15-20 s on these CPUs, a reused one renders in ~0.03 s.
_STAGES: dict[tuple[int, float], tuple[object, object]] = {}
_NO_DEVICE: list[str] = []


def _stage(size: int, fovy_deg: float) -> tuple[object, object] | None:
    if _NO_DEVICE:
        return None
    key = (size, fovy_deg)
    if key not in _STAGES:
        from asset_pipeline.simulation.sapien_scenes import make_scene

        try:
            scene = make_scene(render=True)
        except RuntimeError as e:
            _NO_DEVICE.append(str(e))
            return None
        scene.set_ambient_light([0.45, 0.45, 0.45])
        scene.add_directional_light([-0.4, -0.6, -1.0], [0.9, 0.9, 0.9])
        scene.add_directional_light([0.5, 0.3, -0.4], [0.35, 0.35, 0.35])
        cam = scene.add_camera("preview", size, size, math.radians(fovy_deg), 0.01, 100.0)
        _STAGES[key] = (scene, cam)
    return _STAGES[key]


def render_device_available() -> bool:
    """True when SAPIEN can open a Vulkan render device (lavapipe on CPU machines)."""
    return _stage(64, 40.0) is not None


def _render(scene, cam, art, asset_dir: Path, fovy_deg: float, Image, sapien) -> Path:  # noqa: ANN001
    limits = np.asarray(art.get_qlimits(), dtype=float).reshape(-1, 2)
    closed = limits[:, 0].astype(np.float32)
    opened = limits[:, 1].astype(np.float32)
    art.set_qpos(opened)
    b_open = _bounds(art)
    art.set_qpos(closed)
    b_closed = _bounds(art)
    lo = np.minimum(b_open[0], b_closed[0])
    hi = np.maximum(b_open[1], b_closed[1])
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    dist = radius / math.sin(math.radians(fovy_deg) / 2) * 1.05
    direction = np.array([1.0, 0.75, 0.65])
    eye = centre + dist * direction / np.linalg.norm(direction)
    cam.entity.set_pose(sapien.Pose(look_at(eye, centre)))
    views = []
    for q in (closed, opened):
        art.set_qpos(q)
        scene.update_render()
        cam.take_picture()
        rgba = np.asarray(cam.get_picture("Color"), dtype=np.float32)  # (H, W, 4) in [0, 1]
        alpha = rgba[..., 3:4]
        rgb = rgba[..., :3] * alpha + BACKGROUND * (1 - alpha)
        views.append((np.clip(rgb, 0, 1) * 255).astype(np.uint8))
    image = Image.fromarray(np.concatenate(views, axis=1))
    buf = io.BytesIO()
    image.save(buf, format="PNG")
    path = asset_dir / PREVIEW_NAME
    atomic_write_bytes(path, buf.getvalue())
    return path
