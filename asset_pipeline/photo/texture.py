"""The photo's own texture: the photo projected onto the surfaces its camera sees, per part.

:func:`bake_photo_texture` takes an object (its part meshes closed, at rest), the photo
and its camera (:mod:`asset_pipeline.photo.camera`) and gives every part mesh a
base-colour texture (``trimesh`` ``TextureVisuals`` with a ``PBRMaterial``; the build
writes it into ``visual/<part>.glb`` as ``baseColorTexture``):

- **Seen faces** (front-facing to the camera at more than ``TextureOptions.grazing`` from
  edge-on, and not hidden behind other geometry: a vote of its corners and its centroid,
  counted twice, against a z-buffer of the whole object,
  :func:`~asset_pipeline.photo.camera.rasterize`)
  get projective texture coordinates: their vertices' pixel positions in the photo. The
  part's texture image is the photo cropped to its seen faces, where only the photo's
  pixels of *this part* count: those of the part-mask ids it covers in the fitted view
  (:func:`region_ids`: every id whose pixels it covers more than any other part does, and
  the id it covers most), else the photo's silhouette. Pixels outside that region (where
  the geometry overhangs the photo's part, or outside the photo) take the colour of the
  nearest pixel inside it, so a misplaced edge never shows the background or a
  neighbouring part.
- **Unseen faces** (the back, the hidden sides, a drawer's sides) get a colour inferred
  from the part's seen faces: the median of their photo colours (weighted by their
  projected area). Where the generator's own colours (PAct's stage-2 colours) agree with
  the photo on the seen faces (mean RGB distance below ``TextureOptions.agree``), an
  unseen face keeps its generator colour shifted by the seen faces' median difference
  instead, so its variations survive. The colours are quantized into a palette of
  uniform blocks appended below the crop.
- **Parts the camera does not see at all** take the median photo colour of the mask id
  the camera fit matched to them (``part_ids``) when the mask shows it, else the median
  colour of the whole photo silhouette (never a default grey).

Every vertex carries one texture coordinate (a vertex of a seen face its photo position,
any other vertex its palette block), so the mesh keeps its vertices and faces: a closed
piece stays one closed piece when the GLB is read back. The faces between a seen and an
unseen region (one ring at the border of what the camera sees, edge-on in the photo)
blend across the texture between the two.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh
from PIL import Image
from scipy import ndimage

from asset_pipeline.photo.camera import PhotoCamera, rest_transform, scene_mesh
from generator.articulated import ArticulatedObject, Part
from generator.mesh_repair.decimation import split_long_edges

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TextureOptions:
    """Knobs of :func:`bake_photo_texture`."""

    #: Longest side (px) of a part's texture crop; larger crops are downsampled.
    max_size: int = 2048
    #: Pixels added round a part's crop.
    margin: int = 2
    #: Longest side (px) of the visibility z-buffer.
    visibility_resolution: int = 768
    #: A sample point is visible when at most this far (fraction of the object's
    #: bounding-box diagonal) behind the z-buffer.
    depth_tolerance: float = 0.01
    #: Faces seen within this cosine of edge-on (about 81 degrees) count as unseen.
    grazing: float = 0.15
    #: Generator colours agree with the photo below this mean RGB distance (0..441).
    agree: float = 40.0
    #: Side (px) of a palette block for the colours of unseen faces.
    block: int = 8
    #: Erosion (px) of the photo's part regions before use (drops blended edge pixels).
    erode: int = 1
    #: Edges longer than this fraction of the object's bounding-box diagonal are split
    #: (conforming, :func:`generator.mesh_repair.decimation.split_long_edges`) before the
    #: bake, while a part stays within ``max_faces``: a face's texture coordinates come
    #: from its vertices, so a large face (a decimated flat side, a procedural box) would
    #: stretch one projection across it. Only long edges split: a fine mesh gains few faces.
    max_edge: float = 0.06
    max_faces: int = 200_000


def face_colours(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """(F, 3) float RGB of every face from the mesh's own visual (a texture sampled at the
    vertices, vertex colours averaged, or face colours), None when uncoloured."""
    visual = mesh.visual
    try:
        if visual.kind == "texture":
            visual = visual.to_color()
        if visual.kind == "vertex":
            vc = np.asarray(visual.vertex_colors, dtype=float)[:, :3]
            return vc[np.asarray(mesh.faces)].mean(axis=1)
        if visual.kind == "face":
            return np.asarray(visual.face_colors, dtype=float)[:, :3]
    except Exception as e:  # noqa: BLE001 - colour is cosmetic
        log.debug("no generator colours: %s", e)
    return None


def _fine_mesh(
    mesh: trimesh.Trimesh, max_edge: float, max_faces: int
) -> tuple[trimesh.Trimesh, np.ndarray]:
    """``mesh`` (geometry only) with its edges longer than ``max_edge`` split (while it
    stays within ``max_faces``), and the original face of every new face."""
    faces = np.asarray(mesh.faces, dtype=np.int64)
    v, f, _, origin = split_long_edges(mesh.vertices, faces, max_edge, max_faces=max_faces)
    if len(f) == len(faces):
        return mesh, origin
    return trimesh.Trimesh(vertices=v, faces=f, process=False), origin


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(C,) per-channel weighted median of ``values`` (N, C)."""
    out = np.empty(values.shape[1])
    w = np.maximum(weights, 0) + 1e-12
    for c in range(values.shape[1]):
        order = np.argsort(values[:, c])
        cum = np.cumsum(w[order])
        out[c] = values[order[np.searchsorted(cum, 0.5 * cum[-1])], c]
    return out


def _fill_outside(canvas: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``canvas`` (h, w, 3) with every pixel outside ``valid`` (h, w) set to its nearest
    valid pixel's colour."""
    if valid.all() or not valid.any():
        return canvas
    _, (ri, ci) = ndimage.distance_transform_edt(~valid, return_indices=True)
    return canvas[ri, ci]


def _shrink(region: np.ndarray, erode: int) -> np.ndarray:
    """``region`` eroded by ``erode`` px, unless nothing would be left."""
    if erode <= 0:
        return region
    small = ndimage.binary_erosion(region, iterations=erode)
    return small if small.any() else region


def region_ids(
    rendered: np.ndarray, mask: np.ndarray, n_parts: int, part_ids: dict[int, int]
) -> dict[int, list[int]]:
    """Which of the mask's ids each part may take its colours from.

    ``rendered`` (h, w): 0 background, k + 1 where part k is visible; ``mask`` (h, w) ids
    on the same grid. A part gets every id whose pixels it covers more than any other
    part does, and the id it covers most; a part the render does not show gets its
    ``part_ids`` entry (the camera fit's match) when there is one."""
    r = np.asarray(rendered, np.int64).ravel()
    m = np.asarray(mask, np.int64).ravel()
    nm = int(m.max(initial=0)) + 1
    overlap = np.bincount(m * (n_parts + 1) + r, minlength=nm * (n_parts + 1))
    overlap = overlap.reshape(nm, n_parts + 1)[1:, 1:]  # (ids, parts) without background
    out: dict[int, list[int]] = {k: [] for k in range(n_parts)}
    for i in np.flatnonzero(overlap.sum(axis=1) > 0):
        out[int(np.argmax(overlap[i]))].append(int(i) + 1)
    for k in range(n_parts):
        if overlap[:, k].any():
            top = int(np.argmax(overlap[:, k])) + 1
            if top not in out[k]:
                out[k].append(top)
        elif k in part_ids:
            out[k] = [part_ids[k]]
    return out


def _visible_faces(
    obj: ArticulatedObject, camera: PhotoCamera, options: TextureOptions
) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], np.ndarray]:
    """Per part: (seen (F,) bool, projected area weight (F,)) of its faces; and the render
    (h, w) of part indices + 1 (0 background) on the z-buffer's grid."""
    scene = scene_mesh(obj)
    diag = float(np.linalg.norm(np.ptp(scene.vertices, axis=0)))
    f = min(1.0, options.visibility_resolution / max(camera.width, camera.height))
    small = camera.resized(max(1, round(camera.width * f)), max(1, round(camera.height * f)))
    raster = scene.rasterize(small)
    zbuf = raster.depth
    rendered = np.where(raster.face >= 0, scene.face_part[np.maximum(raster.face, 0)] + 1, 0)
    out = {}
    start = 0
    for k, p in enumerate(obj.parts):
        n = int(np.count_nonzero(scene.face_part == k))
        faces = scene.faces[start : start + n]
        start += n
        tri = scene.vertices[faces]  # (F, 3, 3)
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area2 = np.linalg.norm(normal, axis=1)
        normal = normal / np.maximum(area2, 1e-20)[:, None]
        centroid = tri.mean(axis=1)
        ray = centroid - camera.centre
        ray /= np.maximum(np.linalg.norm(ray, axis=1), 1e-20)[:, None]
        facing = -np.einsum("ij,ij->i", normal, ray)
        # visibility vote: the three corners and the centroid (counted twice)
        used, local = np.unique(faces, return_inverse=True)
        pts = np.concatenate([scene.vertices[used], centroid])
        uv, z = small.project(pts)
        col = np.floor(uv[:, 0]).astype(np.int64)
        row = np.floor(uv[:, 1]).astype(np.int64)
        inside = (col >= 0) & (col < small.width) & (row >= 0) & (row < small.height) & (z > 0)
        depth = np.full(len(pts), -np.inf)
        depth[inside] = zbuf[row[inside], col[inside]]
        visible = inside & (z <= depth + options.depth_tolerance * diag)
        corner = visible[: len(used)][local.reshape(-1, 3)].sum(axis=1)
        vote = (corner + 2 * visible[len(used) :]) / 5.0
        seen = (facing > options.grazing) & (vote >= 0.5)
        out[p.name] = (seen, 0.5 * area2 * np.clip(facing, 0, None))
    return out, rendered


def _quantize(colours: np.ndarray, limit: int = 1024) -> tuple[np.ndarray, np.ndarray]:
    """(palette (P, 3) uint8, index (N,)) of RGB colours (N, 3), at most ``limit`` entries."""
    c = np.clip(np.round(colours), 0, 255).astype(np.int64)
    for step in (1, 4, 8, 16, 32, 64):
        q = (c // step) * step + step // 2 if step > 1 else c
        q = np.clip(q, 0, 255)
        palette, index = np.unique(q, axis=0, return_inverse=True)
        if len(palette) <= limit:
            return palette.astype(np.uint8), index.ravel()
    raise AssertionError("unreachable")  # step 64 leaves at most 64 colours


def _textured_part(
    part: Part,
    seen: np.ndarray,
    photo_uv: np.ndarray,
    crop: np.ndarray,
    origin: tuple[int, int],
    fill: np.ndarray,
    block: int,
) -> tuple[trimesh.Trimesh, np.ndarray]:
    """``part``'s mesh textured: ``crop`` (h, w, 3) is the photo from pixel ``origin``
    (col, row); the vertices of seen faces map their photo positions ``photo_uv`` (V, 2)
    into it, every other vertex the palette block of its colour (the mean ``fill`` (F, 3)
    of its faces). One texture coordinate per vertex: the mesh keeps its vertices and
    faces, so a closed piece stays one closed piece. Returns the mesh and the image."""
    mesh = part.mesh
    faces = np.asarray(mesh.faces, dtype=np.int64)
    nv = len(mesh.vertices)
    projective = np.zeros(nv, bool)
    projective[faces[seen].ravel()] = True
    total = np.zeros((nv, 3))
    count = np.zeros(nv)
    np.add.at(total, faces.ravel(), np.repeat(fill, 3, axis=0))
    np.add.at(count, faces.ravel(), 1.0)
    vertex_fill = total / np.maximum(count, 1.0)[:, None]
    other = ~projective
    if other.any():
        palette, pidx = _quantize(vertex_fill[other])
    else:
        palette, pidx = np.zeros((0, 3), np.uint8), np.zeros(0, np.int64)
    h, w = crop.shape[:2]
    cols = max(1, w // block)
    rows = -(-len(palette) // cols) if len(palette) else 0
    width = max(w, min(len(palette), cols) * block, 1)
    height = h + rows * block
    image = np.zeros((height, width, 3), np.uint8)
    # under the crop, where no block is: the unseen vertices' median colour (a face
    # between a seen and an unseen region samples across it)
    if other.any():
        image[h:] = np.median(vertex_fill[other], axis=0).astype(np.uint8)
    image[:h, :w] = crop
    if w < width:  # extend the crop's last column (never sampled, keeps filtering clean)
        image[:h, w:] = crop[:, -1:]
    for i, colour in enumerate(palette):
        r, c = divmod(i, cols)
        image[h + r * block : h + (r + 1) * block, c * block : (c + 1) * block] = colour
    uv = np.zeros((nv, 2))
    uv[projective, 0] = (photo_uv[projective, 0] - origin[0]) / width
    uv[projective, 1] = 1.0 - (photo_uv[projective, 1] - origin[1]) / height
    r, c = np.divmod(pidx, cols)
    uv[other, 0] = (c + 0.5) * block / width
    uv[other, 1] = 1.0 - (h + (r + 0.5) * block) / height
    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(image),
        metallicFactor=0.0,
        roughnessFactor=0.9,
        doubleSided=False,
    )
    out = trimesh.Trimesh(
        vertices=np.asarray(mesh.vertices),
        faces=faces,
        visual=trimesh.visual.TextureVisuals(uv=uv, material=material),
        process=False,
    )
    return out, image


def bake_photo_texture(
    obj: ArticulatedObject,
    image: np.ndarray,
    camera: PhotoCamera,
    silhouette: np.ndarray,
    mask: np.ndarray | None = None,
    part_ids: dict[str, int] | None = None,
    options: TextureOptions = TextureOptions(),
) -> tuple[ArticulatedObject, dict[str, Any]]:
    """``obj`` with the photo baked into every part's texture (see the module docstring).

    ``image`` (H, W, 3) uint8 is the photo, ``camera`` its camera in ``obj``'s frame,
    ``silhouette`` (H, W) bool the photo's object pixels, ``mask`` (H, W) its part ids
    (optional) and ``part_ids`` {part name: mask id} (from the camera fit's match). The
    meshes should be closed (``asset_pipeline.geometry.metric.watertight``): unseen faces are those
    the z-buffer hides. Returns the new object and a report: per part the seen share of
    its projected area, the fill colour of its unseen faces and where that came from
    (``seen``, ``generator``, ``mask``, ``object``), the texture size, and the seconds.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    image = np.ascontiguousarray(np.asarray(image)[..., :3], dtype=np.uint8)
    H, W = image.shape[:2]
    if camera.width != W or camera.height != H:
        camera = camera.resized(W, H)
    part_ids = dict(part_ids or {})
    # small faces: the ring of faces blending seen and unseen colours stays narrow
    max_edge = options.max_edge * float(np.linalg.norm(np.ptp(scene_mesh(obj).vertices, axis=0)))
    generator_colours = {}
    fine_parts = []
    for p in obj.parts:
        mesh, origin_face = _fine_mesh(p.mesh, max_edge, options.max_faces)
        colours = face_colours(p.mesh)
        generator_colours[p.name] = None if colours is None else colours[origin_face]
        fine_parts.append(
            Part(p.name, p.semantic, mesh, p.joint, list(p.primitives), p.handle, p.material)
        )
    obj = ArticulatedObject(fine_parts, obj.category, obj.scale, dict(obj.provenance))
    names = [p.name for p in obj.parts]
    whole = _shrink(np.asarray(silhouette, bool), options.erode)
    object_colour = np.median(image[whole], axis=0).astype(float)
    visible, rendered = _visible_faces(obj, camera, options)
    regions: dict[str, np.ndarray] = {}
    taken: dict[str, list[int]] = {}
    if mask is not None:
        mask = np.asarray(mask)
        from asset_pipeline.photo.camera import resample_nearest

        small = resample_nearest(mask, *rendered.shape)
        fit_ids = {names.index(n): k for n, k in part_ids.items() if n in names}
        for k, ids in region_ids(rendered, small, len(names), fit_ids).items():
            region = np.isin(mask, ids) if ids else np.zeros(mask.shape, bool)
            if region.any():
                regions[names[k]] = _shrink(region, options.erode)
                taken[names[k]] = ids
    parts, report = [], {}
    textures: dict[str, np.ndarray] = {}
    for p in obj.parts:
        seen, weight = visible[p.name]
        region = regions.get(p.name, whole)
        T = rest_transform(p)
        verts = np.asarray(p.mesh.vertices, dtype=float) @ T[:3, :3].T + T[:3, 3]
        photo_uv, _ = camera.project(verts)
        faces = np.asarray(p.mesh.faces, dtype=np.int64)
        generator = generator_colours[p.name]
        if seen.any():
            corners = photo_uv[faces[seen]].reshape(-1, 2)
            lo = np.floor(corners.min(0)).astype(int) - options.margin
            hi = np.ceil(corners.max(0)).astype(int) + options.margin
        else:
            lo, hi = np.array([0, 0]), np.array([1, 1])
        cw, ch = int(hi[0] - lo[0]), int(hi[1] - lo[1])
        canvas = np.zeros((ch, cw, 3), np.uint8)
        valid = np.zeros((ch, cw), bool)
        x0, y0 = max(lo[0], 0), max(lo[1], 0)
        x1, y1 = min(hi[0], W), min(hi[1], H)
        if x1 > x0 and y1 > y0:
            canvas[y0 - lo[1] : y1 - lo[1], x0 - lo[0] : x1 - lo[0]] = image[y0:y1, x0:x1]
            valid[y0 - lo[1] : y1 - lo[1], x0 - lo[0] : x1 - lo[0]] = region[y0:y1, x0:x1]
        source = "seen"
        if seen.any() and valid.any():
            canvas = _fill_outside(canvas, valid)
        elif seen.any():  # the part's photo region is not in its crop: its median colour
            canvas[:] = np.median(image[region], axis=0).astype(np.uint8)
        # photo colour of every seen face (at its centroid's projection)
        cen = photo_uv[faces].mean(axis=1)
        cc = np.clip(np.floor(cen[:, 0]).astype(int) - lo[0], 0, cw - 1)
        rr = np.clip(np.floor(cen[:, 1]).astype(int) - lo[1], 0, ch - 1)
        seen_colour = canvas[rr, cc].astype(float)
        if seen.any():
            colour = _weighted_median(seen_colour[seen], weight[seen])
        elif p.name in regions:
            colour, source = np.median(image[regions[p.name]], axis=0).astype(float), "mask"
        else:
            colour, source = object_colour, "object"
        fill = np.tile(colour, (len(faces), 1))
        agreement = None
        if generator is not None and seen.any():
            diff = np.linalg.norm(generator[seen] - seen_colour[seen], axis=1)
            agreement = float(np.average(diff, weights=weight[seen] + 1e-12))
            if agreement < options.agree:
                shift = colour - _weighted_median(generator[seen], weight[seen])
                fill = np.clip(generator + shift, 0, 255)
                source = "generator"
        # downsample a crop larger than max_size (uv stay in photo pixels: scale them)
        scale = min(1.0, options.max_size / max(cw, ch))
        uv_px = photo_uv
        origin = (int(lo[0]), int(lo[1]))
        if scale < 1.0:
            size = (max(1, round(cw * scale)), max(1, round(ch * scale)))
            canvas = np.asarray(Image.fromarray(canvas).resize(size, Image.BILINEAR))
            uv_px = (photo_uv - lo) * [size[0] / cw, size[1] / ch]
            origin = (0, 0)
        mesh, tex = _textured_part(p, seen, uv_px, canvas, origin, fill, options.block)
        textures[p.name] = tex
        parts.append(
            Part(p.name, p.semantic, mesh, p.joint, list(p.primitives), p.handle, p.material)
        )
        total = float(weight.sum())
        report[p.name] = {
            "seen": float(weight[seen].sum() / total) if total > 0 else 0.0,
            "seen_faces": int(seen.sum()),
            "faces": len(faces),
            "fill_rgb": [round(float(x), 1) for x in colour],
            "fill_from": source,
            "generator_colour_distance": agreement,
            "mask_ids": taken.get(p.name, []),
            "texture_size": [int(tex.shape[1]), int(tex.shape[0])],
        }
    out = ArticulatedObject(parts, obj.category, obj.scale, dict(obj.provenance))
    out.provenance["texture"] = "photo (asset_pipeline.photo.texture)"
    summary = {
        "method": "projective photo texture per part, unseen faces filled from seen ones",
        "parts": report,
        "seconds": time.perf_counter() - t0,
        "cpu_seconds": time.process_time() - c0,
        "images": textures,
    }
    return out, summary
