"""Render an ArticulatedObject with a SAPIEN camera: RGB, part-id masks, cameras.

The scene is built straight from the object's part meshes: one entity per part with one
render shape (no physics), posed per view by the part's joint transform. Colours are
kept exactly: a vertex- or face-coloured mesh is drawn with its face colours baked into
a small atlas texture (nearest filtering), a textured mesh with its own texture.

Views (``sample_view``) look at the object from the front hemisphere: azimuth within
+-60 degrees of +x, elevation 0 to 40 degrees, the distance chosen so that the posed
object fills 75-95 % of the frame. Lighting is an ambient term plus one or two
directional lights of random direction, intensity and tint; the background is a plain
colour or a procedural texture composited behind the object through the mask. A
fraction of views open some movable parts to random joint values.

Cameras follow OpenCV: extrinsics map world (the metric object frame) to camera
coordinates with x right, y down, z forward; intrinsics are the 3x3 pinhole K in pixels.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field

import numpy as np
import trimesh

from generator.articulated import ArticulatedObject, Part
from generator.data.backgrounds import random_background
from generator.data.geometry import face_colors, texture_image

log = logging.getLogger(__name__)

_LAVAPIPE_ICD = "/usr/share/vulkan/icd.d/lvp_icd.json"
if os.path.exists(_LAVAPIPE_ICD):
    os.environ.setdefault("VK_ICD_FILENAMES", _LAVAPIPE_ICD)

import sapien  # noqa: E402  (after VK_ICD_FILENAMES is set)


class RenderUnavailableError(RuntimeError):
    """SAPIEN found no Vulkan device; install Mesa lavapipe (see shared/FIELD-NOTES.md)."""


@dataclass
class ViewConfig:
    """Ranges the random views are drawn from (angles in degrees)."""

    azimuth: float = 60.0  # +- around +x
    elevation: tuple[float, float] = (0.0, 40.0)
    fovy: tuple[float, float] = (35.0, 55.0)
    fill: tuple[float, float] = (0.75, 0.95)  # fraction of the half-frame the object spans
    target_jitter: float = 0.03  # look-at jitter, fraction of the object's size
    open_fraction: float = 0.3  # views with some parts opened
    ambient: tuple[float, float] = (0.15, 0.45)
    light_intensity: tuple[float, float] = (0.5, 1.6)


@dataclass
class View:
    """Everything random about one rendered view."""

    qpos: np.ndarray  # (P,) joint value per part in object.parts order (native units)
    eye: np.ndarray  # (3,) camera centre, object frame
    target: np.ndarray  # (3,) look-at point
    fovy: float  # radians
    ambient: np.ndarray  # (3,)
    lights: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)  # (direction, rgb)
    background: np.ndarray | None = None  # (H, W, 3) uint8


@dataclass
class RenderedView:
    rgb: np.ndarray  # (H, W, 3) uint8
    mask: np.ndarray  # (H, W) uint8: 0 background, slot + 1 for parts
    intrinsics: np.ndarray  # (3, 3) float32
    extrinsics: np.ndarray  # (4, 4) float32 world -> camera (OpenCV)


# --------------------------------------------------------------------------- views


def part_slots(obj: ArticulatedObject) -> list[Part]:
    """Parts in slot order: the base, then every other part in ``obj.parts`` order."""
    return [obj.base] + [p for p in obj.parts if not p.is_base]


def rest_qpos(obj: ArticulatedObject) -> np.ndarray:
    """(P,) joint values at rest (``lower``; 0 for the base), in ``obj.parts`` order."""
    return np.array([p.joint.lower if p.joint is not None else 0.0 for p in obj.parts])


def posed_vertices(obj: ArticulatedObject, qpos: np.ndarray) -> np.ndarray:
    """(K, 3) all vertices of the object posed at ``qpos`` (``obj.parts`` order)."""
    out = []
    for p, q in zip(obj.parts, qpos, strict=True):
        v = np.asarray(p.mesh.vertices, float)
        if p.joint is not None:
            T = p.joint.transform(float(q))
            v = v @ T[:3, :3].T + T[:3, 3]
        out.append(v)
    return np.concatenate(out)


def look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """4x4 camera-to-world pose with OpenCV axes (x right, y down, z forward), +z world up."""
    z = target - eye
    z = z / np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-8:  # looking straight down or up
        x = np.cross(z, [1.0, 0.0, 0.0])
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T


def fit_distance(
    points: np.ndarray, target: np.ndarray, back: np.ndarray, tan_half: float
) -> float:
    """Smallest distance along ``back`` (unit, target -> camera) at which every point
    projects within ``tan_half`` (the tangent of the half field of view) of the centre."""
    T = look_at(target + back, target)
    rel = points - target
    lateral = np.maximum(np.abs(rel @ T[:3, 0]), np.abs(rel @ T[:3, 1]))
    return float(np.max(lateral / tan_half + rel @ back))


def sample_qpos(
    obj: ArticulatedObject, rng: np.random.Generator, open_fraction: float
) -> np.ndarray:
    """(P,) joint values: all closed, or (with ``open_fraction``) some movable parts opened."""
    q = rest_qpos(obj)
    movable = [i for i, p in enumerate(obj.parts) if p.joint is not None and p.joint.movable]
    if movable and rng.random() < open_fraction:
        chosen = [i for i in movable if rng.random() < 0.5]
        if not chosen:
            chosen = [movable[int(rng.integers(len(movable)))]]
        for i in chosen:
            j = obj.parts[i].joint
            q[i] = rng.uniform(j.lower + 0.1 * j.range, j.upper)
    return q


def sample_view(
    obj: ArticulatedObject,
    rng: np.random.Generator,
    image_size: int,
    config: ViewConfig | None = None,
) -> View:
    """Draw one random view of ``obj`` (pose, camera, lights, background)."""
    cfg = config or ViewConfig()
    qpos = sample_qpos(obj, rng, cfg.open_fraction)
    pts = posed_vertices(obj, qpos)
    lo, hi = pts.min(0), pts.max(0)
    size = float(np.max(hi - lo))
    target = (lo + hi) / 2 + rng.uniform(-1, 1, 3) * cfg.target_jitter * size
    az = np.deg2rad(rng.uniform(-cfg.azimuth, cfg.azimuth))
    el = np.deg2rad(rng.uniform(*cfg.elevation))
    back = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    fovy = np.deg2rad(rng.uniform(*cfg.fovy))
    tan_half = np.tan(fovy / 2) * rng.uniform(*cfg.fill)
    eye = target + back * fit_distance(pts, target, back, tan_half)

    ambient = rng.uniform(*cfg.ambient) * rng.uniform(0.9, 1.1, 3)
    lights = []
    for _ in range(int(rng.integers(1, 3))):
        # light arrives from above, from any side: source elevation 15-80 degrees
        s_az, s_el = rng.uniform(-np.pi, np.pi), np.deg2rad(rng.uniform(15, 80))
        source = np.array([np.cos(s_el) * np.cos(s_az), np.cos(s_el) * np.sin(s_az), np.sin(s_el)])
        colour = rng.uniform(*cfg.light_intensity) * rng.uniform(0.85, 1.15, 3)
        lights.append((-source, colour))
    background = random_background(rng, image_size)
    return View(qpos, eye, target, float(fovy), ambient, lights, background)


# --------------------------------------------------------------------------- scene


# SAPIEN frees its Vulkan context (and the compiled shader pipelines) when the last
# render system dies; lavapipe then takes 10-20 s to recompile them for the next scene.
# One idle render system kept for the life of the process keeps the context warm.
_KEEPALIVE: list[sapien.render.RenderSystem] = []


def use_sapien_camera_defaults() -> None:
    """Cameras made from now on use SAPIEN's own shader pack and float picture formats.

    The setting is process-wide, and ManiSkill changes it when it makes its cameras
    (its "minimal" pack: no ``Segmentation`` picture, 8-bit colour), so a process that
    ran a ManiSkill env with a camera would otherwise render this project's images
    with ManiSkill's pack.
    """
    sapien.render.set_camera_shader_dir("default")
    for picture in ("Color", "ColorRaw", "PositionSegmentation"):
        sapien.render.set_picture_format(picture, "r32g32b32a32sfloat")


def new_render_system() -> sapien.render.RenderSystem:
    """A SAPIEN render system on the device ManiSkill's CPU render backend uses.

    SAPIEN renders on one device per process, fixed by the first render system made.
    ManiSkill's ``render_backend="cpu"`` (the tasks' cameras and videos) asks for
    ``sapien.Device("cpu")`` (lavapipe), which SAPIEN refuses once a render system lives on
    the default device (the same lavapipe, named by its PCI address). Without CUDA the CPU
    device is therefore asked for first, so a process that rendered a preview or a photo
    can still make the tasks' cameras; with CUDA, or without that device, the default.
    Raises RuntimeError when there is no render device at all.
    """
    import torch

    if not torch.cuda.is_available():
        try:
            return sapien.render.RenderSystem(sapien.Device("cpu"))
        except RuntimeError:  # no lavapipe, or a renderer on another device already exists
            pass
    return sapien.render.RenderSystem()


def render_system() -> sapien.render.RenderSystem:
    use_sapien_camera_defaults()
    try:
        if not _KEEPALIVE:
            _KEEPALIVE.append(new_render_system())
        return new_render_system()
    except Exception as e:  # SAPIEN raises RuntimeError with a device message
        raise RenderUnavailableError(
            f"SAPIEN found no render device ({e}); on CPU install Mesa lavapipe "
            f"(shared/FIELD-NOTES.md) and set VK_ICD_FILENAMES={_LAVAPIPE_ICD}"
        ) from e


def check_render_device() -> None:
    """Raise RenderUnavailableError when SAPIEN cannot create a render system."""
    render_system()


def render_shape(part: Part, rng: np.random.Generator) -> sapien.render.RenderShapeTriangleMesh:
    """One SAPIEN shape for a part mesh (object frame), flat-shaded, colours preserved."""
    mesh: trimesh.Trimesh = part.mesh
    faces = np.asarray(mesh.faces)
    F = len(faces)
    corners = np.asarray(mesh.vertices, np.float32)[faces].reshape(-1, 3)  # (3F, 3)
    normals = np.repeat(np.asarray(mesh.face_normals, np.float32), 3, axis=0)
    image = texture_image(mesh)
    if image is not None:
        uv = np.asarray(mesh.visual.uv, np.float32)[faces].reshape(-1, 2)
        uv[:, 1] = 1.0 - uv[:, 1]  # trimesh uv origin is bottom-left, texture rows top-first
        texture = sapien.render.RenderTexture2D(
            np.ascontiguousarray(image), "R8G8B8A8Unorm", 1, "linear", "repeat", True
        )
    else:  # bake face colours into an atlas, one texel per face
        side = int(np.ceil(np.sqrt(F)))
        atlas = np.zeros((side * side, 4), np.uint8)
        atlas[:F] = face_colors(mesh)
        atlas[:, 3] = 255
        k = np.arange(F)
        uv_face = np.stack([(k % side + 0.5) / side, (k // side + 0.5) / side], axis=1)
        uv = np.repeat(uv_face, 3, axis=0).astype(np.float32)
        texture = sapien.render.RenderTexture2D(
            atlas.reshape(side, side, 4), "R8G8B8A8Unorm", 1, "nearest", "edge", True
        )
    metal = part.material == "metal"
    material = sapien.render.RenderMaterial(
        base_color=[1.0, 1.0, 1.0, 1.0],
        roughness=float(rng.uniform(0.3, 0.6) if metal else rng.uniform(0.5, 0.95)),
        metallic=float(rng.uniform(0.3, 0.7) if metal else 0.0),
        specular=float(rng.uniform(0.1, 0.5)),
    )
    material.base_color_texture = texture
    return sapien.render.RenderShapeTriangleMesh(
        corners, np.arange(3 * F, dtype=np.uint32).reshape(-1, 3), normals, uv, material
    )


class ObjectRenderer:
    """A SAPIEN scene holding one object, a camera and lights; ``render(view)`` per view.

    ``rng`` draws the parts' material roughness / specularity (one draw per object).
    """

    def __init__(self, obj: ArticulatedObject, image_size: int, rng: np.random.Generator):
        self.obj = obj
        self.image_size = image_size
        self.scene = sapien.Scene([render_system()])
        slot_of = {id(p): k for k, p in enumerate(part_slots(obj))}
        self.entities: list[sapien.Entity] = []
        lut: dict[int, int] = {}
        for part in obj.parts:
            body = sapien.render.RenderBodyComponent()
            body.attach(render_shape(part, rng))
            entity = sapien.Entity()
            entity.set_name(part.name)
            entity.add_component(body)
            self.scene.add_entity(entity)
            self.entities.append(entity)
            lut[entity.per_scene_id] = slot_of[id(part)] + 1
        self.mask_lut = np.zeros(max(lut) + 1, np.uint8)
        for sid, mid in lut.items():
            self.mask_lut[sid] = mid
        self.camera = sapien.render.RenderCameraComponent(image_size, image_size)
        self.camera.set_near(0.01)
        self.camera.set_far(100.0)
        cam_entity = sapien.Entity()
        cam_entity.set_name("camera")
        cam_entity.add_component(self.camera)
        self.scene.add_entity(cam_entity)
        self.lights = [
            self.scene.add_directional_light([0, 0, -1], [0, 0, 0], shadow=False) for _ in range(2)
        ]

    def render(self, view: View) -> RenderedView:
        for part, entity, q in zip(self.obj.parts, self.entities, view.qpos, strict=True):
            T = np.eye(4) if part.joint is None else part.joint.transform(float(q))
            entity.set_pose(sapien.Pose(T.astype(np.float32)))
        self.scene.set_ambient_light(np.asarray(view.ambient, np.float32))
        for k, light in enumerate(self.lights):
            if k < len(view.lights):
                direction, colour = view.lights[k]
                light.set_color(np.asarray(colour, np.float32))
                q = sapien.math.shortest_rotation([1, 0, 0], np.asarray(direction, np.float32))
                light.set_entity_pose(sapien.Pose([0, 0, 0], q))
            else:
                light.set_color([0.0, 0.0, 0.0])
        cam2world = look_at(np.asarray(view.eye, float), np.asarray(view.target, float))
        # SAPIEN camera entities use x forward, y left, z up
        sapien_pose = cam2world.copy()
        sapien_pose[:3, :3] = cam2world[:3, :3] @ np.array(
            [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]
        )
        self.camera.entity.set_pose(sapien.Pose(sapien_pose.astype(np.float32)))
        self.camera.set_fovy(view.fovy, compute_x=True)
        self.scene.update_render()
        self.camera.take_picture()
        colour = self.camera.get_picture("Color")[..., :3]
        seg = self.camera.get_picture("Segmentation")[..., 1]
        ids = np.clip(seg, 0, len(self.mask_lut) - 1)
        mask = np.where(seg < len(self.mask_lut), self.mask_lut[ids], 0).astype(np.uint8)
        rgb = np.clip(np.round(colour * 255.0), 0, 255).astype(np.uint8)
        if view.background is not None:
            bg = mask == 0
            rgb[bg] = view.background[bg]
        K = np.asarray(self.camera.get_intrinsic_matrix(), np.float32)
        E = np.eye(4, dtype=np.float32)
        E[:3, :3] = cam2world[:3, :3].T
        E[:3, 3] = -cam2world[:3, :3].T @ cam2world[:3, 3]
        return RenderedView(rgb, mask, K, E)

    def close(self) -> None:
        for entity in list(self.scene.entities):
            self.scene.remove_entity(entity)
        self.scene = None  # type: ignore[assignment]

    def __enter__(self) -> ObjectRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
