"""The camera of the photo: intrinsics and pose fitted to the photo's silhouette and part mask.

Camera model (``PhotoCamera``): a pinhole with square pixels (``fx == fy``) and the
principal point at the image centre, OpenCV axes (x right, y down, z forward); ``pose``
is the 4x4 camera-to-object transform. Pixel ``(col, row)`` covers ``[col, col + 1) x
[row, row + 1)``, so a pixel's centre is at ``(col + 0.5, row + 0.5)``.

Fit (:func:`fit_camera`): the object at rest (every joint at ``lower``) is rasterized
(:func:`rasterize`, a z-buffer over the part meshes, decimated by vertex clustering for
speed) as a part-id image, and compared with the photo's silhouette and, with a part mask,
its parts. Seven numbers are optimized: azimuth and elevation of the camera about the
object (the object frame: front +x, z up), roll, the image position of the object's
bounding-box centre, the image scale (pixels per object unit at that centre) and the
vertical field of view. The loss is ``(1 - silhouette IoU) + (1 - part IoU)`` (part IoU:
the mean over the mask's ids of the IoU with the rendered part matched to it by the
Hungarian method; left out without a mask) plus a weak prior pulling the field of view
toward :attr:`FitOptions.fov_prior`.

1. Start views: a grid of azimuths and elevations round the front (the 45 views of
   ``generator.pact.inference.mask_agreement``: the range of the training and test photos); for
   each, the scale
   and image position that put the projected object's box on the silhouette's box.
2. The best few start views are refined with Nelder-Mead at a coarse resolution
   (``FitOptions.coarse``), the best of them by a compass search (each number stepped
   both ways, steps halved when nothing improves) at a finer one (``FitOptions.fine``).

The fitted camera is reported with the silhouette and part IoU of its final render.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment, minimize

from generator.articulated import ArticulatedObject
from generator.atomic_files import atomic_write_bytes

log = logging.getLogger(__name__)

CAMERA_NAME = "camera.json"
CAMERA_SCHEMA = "pact.camera"
CAMERA_VERSION = 1


class CameraFormatError(ValueError):
    """A ``camera.json`` cannot be read; the message names the file and what is wrong."""


# --------------------------------------------------------------------------- the camera


@dataclass
class PhotoCamera:
    """A pinhole camera of an image ``width`` x ``height`` px (see the module docstring).

    ``pose`` (4, 4): camera-to-object, OpenCV axes, object units (metres in
    ``camera.json``). ``fit``: how well it fits (``silhouette_iou``, ``part_iou``, ...).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    pose: np.ndarray
    fit: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.width, self.height = int(self.width), int(self.height)
        self.fx, self.fy, self.cx, self.cy = map(float, (self.fx, self.fy, self.cx, self.cy))
        self.pose = np.asarray(self.pose, dtype=float).reshape(4, 4)

    @property
    def K(self) -> np.ndarray:
        """(3, 3) intrinsic matrix in pixels."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def extrinsics(self) -> np.ndarray:
        """(4, 4) object-to-camera transform (the inverse of ``pose``)."""
        R, t = self.pose[:3, :3], self.pose[:3, 3]
        E = np.eye(4)
        E[:3, :3] = R.T
        E[:3, 3] = -R.T @ t
        return E

    @property
    def centre(self) -> np.ndarray:
        """(3,) the camera's position in the object frame."""
        return self.pose[:3, 3].copy()

    @property
    def fovy(self) -> float:
        """Vertical field of view in radians."""
        return 2.0 * math.atan(0.5 * self.height / self.fy)

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) object-frame points in camera coordinates."""
        E = self.extrinsics
        return np.asarray(points, dtype=float) @ E[:3, :3].T + E[:3, 3]

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2) pixel coordinates (col, row; continuous) and (N,) depth of object points."""
        p = self.to_camera(points)
        z = p[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.stack([self.fx * p[:, 0] / z + self.cx, self.fy * p[:, 1] / z + self.cy], 1)
        return uv, z

    def resized(self, width: int, height: int) -> PhotoCamera:
        """The same camera for an image resampled to ``width`` x ``height`` px."""
        sx, sy = width / self.width, height / self.height
        return PhotoCamera(
            width, height, self.fx * sx, self.fy * sy, self.cx * sx, self.cy * sy, self.pose
        )

    def transformed(self, scale: float, offset: np.ndarray) -> PhotoCamera:
        """The camera in a frame where object points ``p`` become ``scale * p + offset``
        (e.g. the built asset's metric frame, ``asset_pipeline.geometry.metric.to_metric``)."""
        pose = self.pose.copy()
        pose[:3, 3] = scale * pose[:3, 3] + np.asarray(offset, dtype=float)
        return PhotoCamera(
            self.width, self.height, self.fx, self.fy, self.cx, self.cy, pose, dict(self.fit)
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "schema": CAMERA_SCHEMA,
            "version": CAMERA_VERSION,
            "width": self.width,
            "height": self.height,
            "fx": self.fx,
            "fy": self.fy,
            "cx": self.cx,
            "cy": self.cy,
            "pose": [[float(x) for x in row] for row in self.pose],
            "axes": "OpenCV: x right, y down, z forward; pose = camera-to-object, metres",
            "fit": _jsonable(self.fit),
        }

    @classmethod
    def from_json(cls, doc: Any, source: str = "<camera>") -> PhotoCamera:
        if not isinstance(doc, dict) or doc.get("schema") != CAMERA_SCHEMA:
            raise CameraFormatError(f"{source}: not a camera (schema {CAMERA_SCHEMA!r})")
        if doc.get("version") != CAMERA_VERSION:
            raise CameraFormatError(
                f"{source}: version {doc.get('version')!r}; this pact reads {CAMERA_VERSION}"
            )
        try:
            cam = cls(
                width=doc["width"],
                height=doc["height"],
                fx=doc["fx"],
                fy=doc["fy"],
                cx=doc["cx"],
                cy=doc["cy"],
                pose=np.asarray(doc["pose"], dtype=float),
                fit=dict(doc.get("fit") or {}),
            )
        except (KeyError, TypeError, ValueError) as e:
            raise CameraFormatError(f"{source}: malformed camera: {e!r}") from e
        numbers = np.r_[cam.fx, cam.fy, cam.cx, cam.cy, cam.pose.ravel()]
        if not np.isfinite(numbers).all() or cam.fx <= 0 or cam.fy <= 0:
            raise CameraFormatError(f"{source}: intrinsics or pose are not finite and positive")
        if cam.width < 1 or cam.height < 1:
            raise CameraFormatError(f"{source}: image size {cam.width}x{cam.height}")
        return cam


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(float(x)) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_camera(camera: PhotoCamera, folder: str | Path, **extra: Any) -> Path:
    """Write ``folder/camera.json`` atomically (``extra`` as more top-level keys, e.g. the
    texture bake's report); return its path."""
    path = Path(folder) / CAMERA_NAME
    doc = {**camera.to_json(), **_jsonable(extra)}
    atomic_write_bytes(path, (json.dumps(doc, indent=2) + "\n").encode())
    return path


def read_camera(folder: str | Path) -> PhotoCamera | None:
    """The ``camera.json`` of an asset folder, None when there is none."""
    path = Path(folder) / CAMERA_NAME
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise CameraFormatError(f"{path}: not valid JSON: {e}") from e
    return PhotoCamera.from_json(doc, str(path))


def look_at_pose(eye: np.ndarray, target: np.ndarray, roll: float = 0.0) -> np.ndarray:
    """(4, 4) camera-to-object pose (OpenCV axes) of a camera at ``eye`` looking at
    ``target`` with +z up, rolled by ``roll`` radians about its viewing axis."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-8:  # looking straight down or up
        x = np.cross(z, [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c, s = math.cos(roll), math.sin(roll)
    x, y = c * x + s * y, -s * x + c * y
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T


# --------------------------------------------------------------------------- rasterizer


@dataclass
class Raster:
    """A rasterized view: ``depth`` (H, W) camera z (inf on the background) and
    ``face`` (H, W) index of the visible face (-1 on the background)."""

    depth: np.ndarray
    face: np.ndarray

    @property
    def covered(self) -> np.ndarray:
        return self.face >= 0


def _ranges(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(owner, offset) for ``counts[i]`` consecutive entries per i: the index i of each
    entry and its position 0..counts[i]-1 within its run."""
    owner = np.repeat(np.arange(len(counts)), counts)
    starts = np.cumsum(counts) - counts
    return owner, np.arange(len(owner)) - np.repeat(starts, counts)


def rasterize(
    vertices: np.ndarray,
    faces: np.ndarray,
    camera: PhotoCamera,
    near: float = 1e-6,
    cull: np.ndarray | None = None,
    normals: np.ndarray | None = None,
) -> Raster:
    """Z-buffer of triangles ``faces`` (F, 3) over object points ``vertices`` (V, 3) seen by
    ``camera``: a pixel is covered by a triangle when its centre lies inside it (either
    winding); the nearest triangle (perspective-correct depth) wins. Triangles with a
    vertex behind ``near`` are dropped, and so are the back faces among ``cull`` (F,) bool
    (faces of closed, outward-wound parts, which their front faces hide; ``normals`` (F, 3)
    their unnormalized normals when known, else computed). Scanline spans,
    vectorized over all triangles: the work grows with the pixels covered, not with the
    triangles' boxes."""
    H, W = camera.height, camera.width
    uv, z = camera.project(vertices)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    zf = z[faces]
    ok = (zf[:, 0] > near) & (zf[:, 1] > near) & (zf[:, 2] > near)
    if cull is not None:
        v = np.asarray(vertices, dtype=float)
        if normals is None:
            normals = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
        away = np.einsum("ij,ij->i", normals, v[faces[:, 0]] - camera.centre) >= 0
        ok &= ~(away & cull)
    fidx = np.flatnonzero(ok)
    tri = faces[fidx]
    X, Y, Z = uv[tri, 0], uv[tri, 1], z[tri]
    ymin = np.minimum(np.minimum(Y[:, 0], Y[:, 1]), Y[:, 2])
    ymax = np.maximum(np.maximum(Y[:, 0], Y[:, 1]), Y[:, 2])
    xmin = np.minimum(np.minimum(X[:, 0], X[:, 1]), X[:, 2])
    xmax = np.maximum(np.maximum(X[:, 0], X[:, 1]), X[:, 2])
    y0 = np.ceil(ymin - 0.5).clip(0, H).astype(np.int64)
    y1 = np.floor(ymax - 0.5).clip(-1, H - 1).astype(np.int64)
    det = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (X[:, 2] - X[:, 0]) * (Y[:, 1] - Y[:, 0])
    keep = (y1 >= y0) & (np.abs(det) > 1e-12) & (xmax >= 0) & (xmin <= W)
    fidx, X, Y, Z, y0, y1, det = (
        fidx[keep],
        X[keep],
        Y[keep],
        Z[keep],
        y0[keep],
        y1[keep],
        det[keep],
    )
    depth = np.full(H * W, np.inf)
    face = np.full(H * W, -1, dtype=np.int64)
    if len(fidx) == 0:
        return Raster(depth.reshape(H, W), face.reshape(H, W))
    # 1/z is affine in the image: 1/z = a x + b y + c per triangle (Cramer's rule)
    iz = 1.0 / Z
    a = (
        (iz[:, 1] - iz[:, 0]) * (Y[:, 2] - Y[:, 0]) - (iz[:, 2] - iz[:, 0]) * (Y[:, 1] - Y[:, 0])
    ) / det
    b = (
        (X[:, 1] - X[:, 0]) * (iz[:, 2] - iz[:, 0]) - (X[:, 2] - X[:, 0]) * (iz[:, 1] - iz[:, 0])
    ) / det
    c = iz[:, 0] - a * X[:, 0] - b * Y[:, 0]
    # one entry per (triangle, pixel row): the span of the row's centre line inside it
    tri, off = _ranges(y1 - y0 + 1)
    yc = (y0[tri] + off) + 0.5
    xl = np.full(len(tri), np.inf)
    xr = np.full(len(tri), -np.inf)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        ya, yb, xa, xb = Y[tri, i], Y[tri, j], X[tri, i], X[tri, j]
        cross = (np.minimum(ya, yb) <= yc) & (yc <= np.maximum(ya, yb)) & (ya != yb)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.where(cross, xa + (yc - ya) * (xb - xa) / (yb - ya), np.nan)
        xl = np.fmin(xl, x)
        xr = np.fmax(xr, x)
    xs = np.ceil(xl - 0.5).clip(0, W)
    xe = np.floor(xr - 0.5).clip(-1, W - 1)
    count = np.where(np.isfinite(xs) & np.isfinite(xe), xe - xs + 1, 0).clip(0).astype(np.int64)
    row, offx = _ranges(count)
    px = xs[row].astype(np.int64) + offx
    py = (yc[row] - 0.5).astype(np.int64)
    t = tri[row]
    invz = a[t] * (px + 0.5) + b[t] * (py + 0.5) + c[t]
    pix = py * W + px
    # far to near: numpy's fancy assignment keeps the last of repeated indices
    order = np.argsort(invz)
    pix, t = pix[order], t[order]
    depth[pix] = 1.0 / np.maximum(invz[order], 1e-12)
    face[pix] = fidx[t]
    return Raster(depth.reshape(H, W), face.reshape(H, W))


# --------------------------------------------------------------------------- the object


@dataclass
class SceneMesh:
    """Every part's triangles at rest in one array: ``vertices`` (V, 3) object frame,
    ``faces`` (F, 3), ``face_part`` (F,) index into ``parts`` (part names), ``closed``
    (F,) whether the face's part is a closed, outward-wound volume (its back faces are
    hidden: :func:`rasterize` may cull them)."""

    vertices: np.ndarray
    faces: np.ndarray
    face_part: np.ndarray
    parts: list[str]
    closed: np.ndarray | None = None
    _normals: np.ndarray | None = field(default=None, repr=False)

    @property
    def bounds(self) -> np.ndarray:
        return np.stack([self.vertices.min(0), self.vertices.max(0)])

    @property
    def normals(self) -> np.ndarray:
        """(F, 3) unnormalized face normals (right-handed winding), cached."""
        if self._normals is None:
            v, f = self.vertices, self.faces
            self._normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        return self._normals

    def rasterize(self, camera: PhotoCamera) -> Raster:
        """:func:`rasterize` of these triangles, back faces of closed parts culled."""
        return rasterize(self.vertices, self.faces, camera, cull=self.closed, normals=self.normals)


def rest_transform(part: Any) -> np.ndarray:
    """(4, 4) pose of a part's mesh at rest (its joint at ``lower``; identity for the base)."""
    return np.eye(4) if part.joint is None else part.joint.transform(part.joint.lower)


def scene_mesh(obj: ArticulatedObject) -> SceneMesh:
    """The object's part meshes at rest, in part order."""
    from generator.mesh_repair.closing import is_closed_volume

    verts, faces, owner, closed = [], [], [], []
    n = 0
    for k, p in enumerate(obj.parts):
        T = rest_transform(p)
        v = np.asarray(p.mesh.vertices, dtype=float) @ T[:3, :3].T + T[:3, 3]
        f = np.asarray(p.mesh.faces, dtype=np.int64)
        verts.append(v)
        faces.append(f + n)
        owner.append(np.full(len(f), k, dtype=np.int64))
        closed.append(np.full(len(f), is_closed_volume(p.mesh)))
        n += len(v)
    return SceneMesh(
        np.concatenate(verts),
        np.concatenate(faces),
        np.concatenate(owner),
        [p.name for p in obj.parts],
        np.concatenate(closed),
    )


def decimate(scene: SceneMesh, cell: float) -> SceneMesh:
    """Vertex clustering per part: vertices in one ``cell``-sized grid cell merge (at their
    mean), collapsed and repeated triangles are dropped. Silhouettes move by < ``cell``."""
    v, f, fp = scene.vertices, scene.faces, scene.face_part
    vpart = np.zeros(len(v), dtype=np.int64)
    vpart[f.ravel()] = np.repeat(fp, 3)
    q = np.floor((v - v.min(0)) / cell).astype(np.int64)
    key = np.column_stack([vpart, q])
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    nv = len(counts)
    sums = np.zeros((nv, 3))
    np.add.at(sums, inverse, v)
    nvert = sums / counts[:, None]
    nf = inverse[f]
    good = (nf[:, 0] != nf[:, 1]) & (nf[:, 1] != nf[:, 2]) & (nf[:, 0] != nf[:, 2])
    nf, nfp = nf[good], fp[good]
    srt = np.sort(nf, axis=1)
    _, uniq = np.unique(np.column_stack([srt, nfp]), axis=0, return_index=True)
    uniq.sort()
    closed = None if scene.closed is None else scene.closed[good][uniq]
    return SceneMesh(nvert, nf[uniq], nfp[uniq], scene.parts, closed)


# --------------------------------------------------------------------------- the photo


def photo_silhouette(
    image: np.ndarray, mask: np.ndarray | None = None, alpha: np.ndarray | None = None
) -> np.ndarray | None:
    """(H, W) bool object pixels of a photo: the part mask's ids > 0, else the alpha
    channel (>= 128), else the silhouette estimated against a plain background
    (``asset_pipeline.inputs.estimate_silhouette``); None when none of them exists."""
    if mask is not None and (np.asarray(mask) > 0).any():
        return np.asarray(mask) > 0
    if alpha is not None:
        from asset_pipeline.inputs.photo import ALPHA_FOREGROUND

        sil = np.asarray(alpha) >= ALPHA_FOREGROUND
        return sil if sil.any() else None
    from asset_pipeline.inputs.photo import estimate_silhouette

    return estimate_silhouette(np.asarray(image)[..., :3])


# --------------------------------------------------------------------------- part matching


def match_parts(
    rendered: np.ndarray, mask: np.ndarray, n_rendered: int | None = None
) -> tuple[dict[int, int], dict[int, float]]:
    """Hungarian match of rendered part labels to mask ids.

    ``rendered`` (H, W): 0 background, k >= 1 rendered part k; ``mask`` (H, W): 0
    background, ids >= 1. Returns ({mask id: rendered label}, {mask id: IoU}) maximizing
    the summed IoU; a mask id without a partner has IoU 0 and no entry in the match.
    """
    r = np.asarray(rendered, dtype=np.int64).ravel()
    m = np.asarray(mask, dtype=np.int64).ravel()
    ids = np.unique(m[m > 0])
    nr = int(max(r.max(initial=0), n_rendered or 0)) + 1
    nm = int(m.max(initial=0)) + 1
    conf = np.bincount(m * nr + r, minlength=nm * nr).reshape(nm, nr)
    area_m, area_r = conf.sum(1), conf.sum(0)
    inter = conf[1:, 1:].astype(float)
    union = area_m[1:, None] + area_r[None, 1:] - inter
    iou = np.where(union > 0, inter / np.maximum(union, 1), 0.0)
    match: dict[int, int] = {}
    scores = {int(i): 0.0 for i in ids}
    if iou.size:
        rows, cols = linear_sum_assignment(-iou)
        for a, b in zip(rows, cols, strict=True):
            if a + 1 in scores and iou[a, b] > 0:
                match[int(a + 1)] = int(b + 1)
                scores[int(a + 1)] = float(iou[a, b])
    return match, scores


def silhouette_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two (H, W) bool images (1.0 when both are empty)."""
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 1.0


# --------------------------------------------------------------------------- the fit


@dataclass(frozen=True)
class FitOptions:
    """Knobs of :func:`fit_camera` (angles in degrees, resolutions in pixels of the
    photo's longer side)."""

    azimuths: tuple[float, ...] = (-60.0, -45.0, -30.0, -15.0, 0.0, 15.0, 30.0, 45.0, 60.0)
    elevations: tuple[float, ...] = (0.0, 10.0, 20.0, 30.0, 40.0)
    fov_prior: float = 45.0
    fov_range: tuple[float, float] = (10.0, 90.0)
    #: Weight of ((fov - fov_prior) / 30 degrees)^2 in the loss.
    fov_weight: float = 0.02
    coarse: int = 64
    fine: int = 128
    starts: int = 2
    coarse_evals: int = 80
    fine_evals: int = 60
    #: Decimation cell of the coarse and fine stages, as a fraction of the object's
    #: bounding-box diagonal.
    coarse_cell: float = 1 / 40
    fine_cell: float = 1 / 100
    #: Weight of the part term (1 - part IoU) against the silhouette's (1 - IoU).
    part_weight: float = 1.0


@dataclass
class _Target:
    """The photo at one working resolution."""

    width: int
    height: int
    silhouette: np.ndarray  # (h, w) bool
    mask: np.ndarray | None  # (h, w) ids or None
    n_ids: int


def resample_nearest(a: np.ndarray, height: int, width: int) -> np.ndarray:
    H, W = a.shape[:2]
    rows = ((np.arange(height) + 0.5) * H / height).astype(np.int64).clip(0, H - 1)
    cols = ((np.arange(width) + 0.5) * W / width).astype(np.int64).clip(0, W - 1)
    return a[rows][:, cols]


def _target(silhouette: np.ndarray, mask: np.ndarray | None, size: int) -> _Target:
    H, W = silhouette.shape
    f = min(1.0, size / max(H, W))
    h, w = max(8, round(H * f)), max(8, round(W * f))
    sil = resample_nearest(silhouette, h, w)
    m = None if mask is None else resample_nearest(np.asarray(mask), h, w).astype(np.int64)
    n_ids = 0 if m is None else len(np.unique(m[m > 0]))
    return _Target(w, h, sil, m, n_ids)


@dataclass
class _Params:
    """The fit's seven numbers (see the module docstring); angles in degrees, ``u``/``v``
    in pixels of the photo, ``scale`` in pixels per object unit."""

    azimuth: float
    elevation: float
    roll: float
    u: float
    v: float
    scale: float
    fov: float

    def camera(self, width: int, height: int, centre: np.ndarray) -> PhotoCamera:
        f = 0.5 * height / math.tan(math.radians(self.fov) / 2)
        a, e = math.radians(self.azimuth), math.radians(self.elevation)
        back = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
        R_cam = look_at_pose(centre + back, centre, math.radians(self.roll))[:3, :3]
        zc = f / self.scale
        pc = np.array([(self.u - 0.5 * width) * zc / f, (self.v - 0.5 * height) * zc / f, zc])
        pose = np.eye(4)
        pose[:3, :3] = R_cam
        pose[:3, 3] = centre - R_cam @ pc
        return PhotoCamera(width, height, f, f, 0.5 * width, 0.5 * height, pose)

    def vector(self, height: int) -> np.ndarray:
        """Normalized units: 5 degrees, 2% of the image, 5% of scale."""
        return np.array(
            [
                self.azimuth / 5,
                self.elevation / 5,
                self.roll / 5,
                self.u / (0.02 * height),
                self.v / (0.02 * height),
                math.log(self.scale) / 0.05,
                self.fov / 5,
            ]
        )

    @classmethod
    def from_vector(cls, x: np.ndarray, height: int) -> _Params:
        return cls(
            x[0] * 5,
            x[1] * 5,
            x[2] * 5,
            x[3] * 0.02 * height,
            x[4] * 0.02 * height,
            math.exp(x[5] * 0.05),
            x[6] * 5,
        )


class _Evaluator:
    """Loss of camera parameters against one target at one resolution."""

    def __init__(
        self,
        mesh: SceneMesh,
        target: _Target,
        photo_size: tuple[int, int],
        centre: np.ndarray,
        options: FitOptions,
    ) -> None:
        self.mesh, self.t, self.centre, self.opt = mesh, target, centre, options
        self.W, self.H = photo_size
        self.evals = 0

    def render(self, p: _Params) -> np.ndarray:
        """(h, w) int: 0 background, k + 1 for part k."""
        cam = p.camera(self.W, self.H, self.centre).resized(self.t.width, self.t.height)
        r = self.mesh.rasterize(cam)
        return np.where(r.face >= 0, self.mesh.face_part[np.maximum(r.face, 0)] + 1, 0)

    def scores(self, ids: np.ndarray) -> tuple[float, float | None]:
        sil = silhouette_iou(ids > 0, self.t.silhouette)
        if self.t.mask is None:
            return sil, None
        _, per_id = match_parts(ids, self.t.mask, len(self.mesh.parts))
        return sil, float(np.mean(list(per_id.values()))) if per_id else 0.0

    def loss(self, p: _Params) -> float:
        lo, hi = self.opt.fov_range
        if not (lo <= p.fov <= hi) or not (-89 <= p.elevation <= 89) or p.scale <= 0:
            return 10.0
        self.evals += 1
        sil, part = self.scores(self.render(p))
        value = 1.0 - sil
        if part is not None and self.t.n_ids > 1:
            value += self.opt.part_weight * (1.0 - part)
        return value + self.opt.fov_weight * ((p.fov - self.opt.fov_prior) / 30.0) ** 2


def _box_init(
    mesh: SceneMesh, target: _Target, photo_size: tuple[int, int], centre: np.ndarray,
    azimuth: float, elevation: float, fov: float,
) -> _Params:  # fmt: skip
    """Scale and image position that put the projected vertices' box on the silhouette's."""
    W, H = photo_size
    rows, cols = np.nonzero(target.silhouette)
    fx, fy = W / target.width, H / target.height
    t_lo = np.array([cols.min() * fx, rows.min() * fy])
    t_hi = np.array([(cols.max() + 1) * fx, (rows.max() + 1) * fy])
    size = float(np.linalg.norm(mesh.bounds[1] - mesh.bounds[0]))
    p = _Params(azimuth, elevation, 0.0, 0.5 * W, 0.5 * H, 0.6 * H / size, fov)
    for _ in range(3):
        uv, z = p.camera(W, H, centre).project(mesh.vertices)
        if (z <= 0).any():
            p.scale *= 0.5
            continue
        lo, hi = uv.min(0), uv.max(0)
        ratio = float(np.sqrt(np.prod((t_hi - t_lo) / np.maximum(hi - lo, 1e-9))))
        # scaling about the centre's image (u, v), then shifting box centre onto box centre
        p.scale *= ratio
        p.u = 0.5 * (t_lo[0] + t_hi[0]) - ratio * (0.5 * (lo[0] + hi[0]) - p.u)
        p.v = 0.5 * (t_lo[1] + t_hi[1]) - ratio * (0.5 * (lo[1] + hi[1]) - p.v)
    return p


def _refine(ev: _Evaluator, start: _Params, evals: int, H: int) -> tuple[_Params, float]:
    x0 = start.vector(H)
    simplex = np.vstack([x0, x0 + np.eye(len(x0))])
    res = minimize(
        lambda x: ev.loss(_Params.from_vector(x, H)),
        x0,
        method="Nelder-Mead",
        options={"maxfev": evals, "initial_simplex": simplex, "xatol": 0.05, "fatol": 1e-4},
    )
    return _Params.from_vector(res.x, H), float(res.fun)


def _compass(ev: _Evaluator, start: _Params, evals: int, H: int) -> tuple[_Params, float]:
    """Compass search: each coordinate stepped both ways, steps halved when nothing improves
    (steps in :meth:`_Params.vector` units, the field of view's twice as long)."""
    x = start.vector(H)
    best = ev.loss(_Params.from_vector(x, H))
    step = np.array([0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 1.0])
    used = 1
    while used < evals and step.max() > 0.02:
        improved = False
        for i in range(len(x)):
            for sign in (1.0, -1.0):
                y = x.copy()
                y[i] += sign * step[i]
                value = ev.loss(_Params.from_vector(y, H))
                used += 1
                if value < best:
                    x, best, improved = y, value, True
                    break
            if used >= evals:
                break
        if not improved:
            step *= 0.5
    return _Params.from_vector(x, H), best


def fit_camera(
    obj: ArticulatedObject,
    silhouette: np.ndarray,
    mask: np.ndarray | None = None,
    options: FitOptions = FitOptions(),
) -> PhotoCamera:
    """The camera (in ``obj``'s frame and units) from which ``obj`` at rest looks most like
    the photo's ``silhouette`` (H, W) bool and part ``mask`` (H, W) ids (optional).

    ``fit`` of the result holds ``silhouette_iou`` and ``part_iou`` (at the fine
    resolution; ``part_iou`` None without a mask), ``part_match`` ({mask id: part name}),
    the loss, the number of renders and the seconds taken. Raises ValueError for an
    empty silhouette.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    silhouette = np.asarray(silhouette, bool)
    if not silhouette.any():
        raise ValueError("the photo's silhouette is empty")
    H, W = silhouette.shape
    if mask is not None and not (np.asarray(mask) > 0).any():
        mask = None
    full = scene_mesh(obj)
    centre = full.bounds.mean(0)
    diag = float(np.linalg.norm(full.bounds[1] - full.bounds[0]))
    coarse_mesh = decimate(full, diag * options.coarse_cell)
    fine_mesh = decimate(full, diag * options.fine_cell)
    coarse_t = _target(silhouette, mask, options.coarse)
    fine_t = _target(silhouette, mask, options.fine)
    coarse = _Evaluator(coarse_mesh, coarse_t, (W, H), centre, options)
    fine = _Evaluator(fine_mesh, fine_t, (W, H), centre, options)

    starts = []
    for el in options.elevations:
        for az in options.azimuths:
            p = _box_init(coarse_mesh, coarse_t, (W, H), centre, az, el, options.fov_prior)
            starts.append((coarse.loss(p), p))
    starts.sort(key=lambda s: s[0])
    refined = [_refine(coarse, p, options.coarse_evals, H) for _, p in starts[: options.starts]]
    refined.sort(key=lambda s: s[1])
    best, loss = _compass(fine, refined[0][0], options.fine_evals, H)
    camera = best.camera(W, H, centre)
    ids = fine.render(best)
    sil, part = fine.scores(ids)
    match = {}
    if fine_t.mask is not None:
        m, _ = match_parts(ids, fine_t.mask, len(full.parts))
        match = {k: full.parts[v - 1] for k, v in m.items()}
    camera.fit = {
        "silhouette_iou": sil,
        "part_iou": part,
        "part_match": match,
        "loss": loss,
        "azimuth_deg": best.azimuth,
        "elevation_deg": best.elevation,
        "roll_deg": best.roll,
        "fovy_deg": best.fov,
        "resolution": [fine_t.width, fine_t.height],
        "renders": coarse.evals + fine.evals,
        "seconds": time.perf_counter() - t0,
        "cpu_seconds": time.process_time() - c0,
    }
    log.info(
        "camera fit: silhouette IoU %.3f, part IoU %s, %d renders, %.2f s",
        sil,
        "-" if part is None else f"{part:.3f}",
        camera.fit["renders"],
        camera.fit["seconds"],
    )
    return camera
