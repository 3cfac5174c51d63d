"""Per-part training targets from meshes: occupancy grids, coloured surface samples.

Pure functions over trimesh meshes and numpy arrays. Meshes passed here are already in
the normalized object frame (the cube [-0.5, 0.5]^3, see docs/dataset.md).

Occupancy of a grid of resolution R has voxel centres at ``-0.5 + (i + 0.5) / R`` and
index order [x, y, z]. A voxel is occupied when its centre is inside the part or the
part's surface passes through it, so panels thinner than a voxel keep their voxels.
"""

from __future__ import annotations

import numpy as np
import trimesh

# Ray columns are shifted by this (irrational-looking) fraction of a voxel so that rays
# never run exactly along the edges of axis-aligned boxes, whose faces often sit on the
# voxel-centre lattice; a ray through a shared edge would count one crossing twice.
_RAY_JITTER = np.array([1.3e-4 * np.sqrt(2.0), 1.7e-4 * np.sqrt(3.0)])
_TRI_CHUNK = 256


def voxel_centres(resolution: int) -> np.ndarray:
    """(R,) voxel-centre coordinates along one axis of the normalized cube."""
    return -0.5 + (np.arange(resolution) + 0.5) / resolution


def _parity_along_axis(
    vertices: np.ndarray, faces: np.ndarray, resolution: int, axis: int
) -> np.ndarray:
    """(R, R, R) bool: voxel centres with an odd number of surface crossings below them.

    Rays run along ``axis`` through every column of voxel centres; correct for closed
    (watertight) surfaces.
    """
    R = resolution
    b, c = [a for a in range(3) if a != axis]
    centres = voxel_centres(R)
    # columns over the (b, c) plane, flattened as b * R + c
    cb, cc = np.meshgrid(centres + _RAY_JITTER[0] / R, centres + _RAY_JITTER[1] / R, indexing="ij")
    cb, cc = cb.ravel(), cc.ravel()  # (R*R,)
    tri = vertices[faces]  # (F, 3, 3)
    counts = np.zeros((R * R, R + 1), dtype=np.int32)
    for start in range(0, len(tri), _TRI_CHUNK):
        t = tri[start : start + _TRI_CHUNK]  # (T, 3, 3)
        p0, p1, p2 = t[:, 0], t[:, 1], t[:, 2]
        # 2D barycentrics of every column point in every projected triangle: (T, C)
        d1b, d1c = p1[:, b] - p0[:, b], p1[:, c] - p0[:, c]
        d2b, d2c = p2[:, b] - p0[:, b], p2[:, c] - p0[:, c]
        det = d1b * d2c - d2b * d1c  # (T,)
        ok = np.abs(det) > 1e-14
        if not ok.any():
            continue
        t, p0, d1b, d1c, d2b, d2c, det = t[ok], p0[ok], d1b[ok], d1c[ok], d2b[ok], d2c[ok], det[ok]
        qb = cb[None, :] - p0[:, b, None]
        qc = cc[None, :] - p0[:, c, None]
        u = (qb * d2c[:, None] - d2b[:, None] * qc) / det[:, None]
        v = (d1b[:, None] * qc - qb * d1c[:, None]) / det[:, None]
        hit = (u >= 0) & (v >= 0) & (u + v <= 1)
        ti, ci = np.nonzero(hit)
        if len(ti) == 0:
            continue
        uu, vv = u[ti, ci], v[ti, ci]
        depth = t[ti, 0, axis] * (1 - uu - vv) + t[ti, 1, axis] * uu + t[ti, 2, axis] * vv  # (H,)
        # a crossing at depth d flips every voxel centre above it
        first = np.searchsorted(centres, depth, side="right")
        np.add.at(counts, (ci, first), 1)
    inside = (np.cumsum(counts[:, :R], axis=1) % 2).astype(bool)  # (R*R, R) over (b, c, axis)
    grid = inside.reshape(R, R, R)  # axes (b, c, axis)
    order = np.argsort([b, c, axis])
    return np.transpose(grid, order)


def solid_voxels(mesh: trimesh.Trimesh, resolution: int) -> np.ndarray:
    """(R, R, R) bool: voxel centres inside the mesh.

    The mesh may be a concatenation of overlapping closed pieces (boxes of a procedural
    part): each connected piece is filled on its own and the results are united. Pieces
    that are not watertight take a majority vote of rays along x, y and z.
    """
    grid = np.zeros((resolution,) * 3, dtype=bool)
    pieces = mesh.split(only_watertight=False) if len(mesh.faces) else []
    for piece in pieces:
        v, f = np.asarray(piece.vertices, float), np.asarray(piece.faces)
        if piece.is_watertight:
            grid |= _parity_along_axis(v, f, resolution, axis=2)
        else:
            votes = sum(
                _parity_along_axis(v, f, resolution, axis=a).astype(np.int8) for a in range(3)
            )
            grid |= votes >= 2
    return grid


def _lattice(n: int) -> np.ndarray:
    """(K, 3) barycentric weights of the triangular lattice with n steps per edge."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = (i + j) <= n
    i, j = i[keep], j[keep]
    return np.stack([n - i - j, i, j], axis=1) / n


def surface_points_dense(mesh: trimesh.Trimesh, spacing: float) -> np.ndarray:
    """(K, 3) points covering every face on a barycentric lattice at most ``spacing`` apart."""
    tri = np.asarray(mesh.vertices, float)[mesh.faces]  # (F, 3, 3)
    edges = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)  # (F,)
    steps = np.maximum(1, np.ceil(edges / spacing)).astype(np.int64)
    out = []
    for n in np.unique(steps):
        w = _lattice(int(n))  # (K, 3)
        out.append(np.einsum("kj,fjd->fkd", w, tri[steps == n]).reshape(-1, 3))
    return np.concatenate(out) if out else np.zeros((0, 3))


def surface_voxels(mesh: trimesh.Trimesh, resolution: int) -> np.ndarray:
    """(R, R, R) bool: voxels the surface passes through.

    Every face is covered by a barycentric lattice of points at most half a voxel apart;
    the voxels holding those points are marked.
    """
    R = resolution
    grid = np.zeros((R, R, R), dtype=bool)
    if len(mesh.faces) == 0:
        return grid
    idx = np.floor((surface_points_dense(mesh, 0.5 / R) + 0.5) * R).astype(np.int64)
    idx = idx[((idx >= 0) & (idx < R)).all(axis=1)]
    grid[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    return grid


def occupancy(mesh: trimesh.Trimesh, resolution: int) -> np.ndarray:
    """(R, R, R) bool occupancy of a part mesh in the normalized frame (inside or surface)."""
    return solid_voxels(mesh, resolution) | surface_voxels(mesh, resolution)


# --------------------------------------------------------------------------- colours


def _rgba_u8(colors: np.ndarray) -> np.ndarray:
    colors = np.asarray(colors)
    if colors.dtype != np.uint8:
        colors = np.clip(np.round(colors * (255.0 if colors.max() <= 1.0 else 1.0)), 0, 255)
        colors = colors.astype(np.uint8)
    if colors.shape[-1] == 3:
        colors = np.concatenate([colors, np.full(colors.shape[:-1] + (1,), 255, np.uint8)], -1)
    return colors


def texture_image(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """(H, W, 4) uint8 base-colour image of a textured mesh (None when it has none).

    The material's base colour factor, if any, is multiplied in.
    """
    visual = mesh.visual
    if getattr(visual, "kind", None) != "texture" or getattr(visual, "uv", None) is None:
        return None
    material = visual.material
    image = getattr(material, "baseColorTexture", None)
    if image is None:
        image = getattr(material, "image", None)
    if image is None:
        return None
    rgba = np.asarray(image.convert("RGBA"), dtype=np.uint8)
    factor = getattr(material, "baseColorFactor", None)
    if factor is not None:
        f = _rgba_u8(np.asarray(factor)[None])[0].astype(np.float32) / 255.0
        rgba = np.clip(np.round(rgba * f), 0, 255).astype(np.uint8)
    return rgba


def sample_texture(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(N, 4) uint8 texels at trimesh uv coordinates (origin bottom-left, wrapping)."""
    h, w = image.shape[:2]
    u = np.mod(uv[:, 0], 1.0)
    v = np.mod(uv[:, 1], 1.0)
    col = np.clip((u * w).astype(np.int64), 0, w - 1)
    row = np.clip(((1.0 - v) * h).astype(np.int64), 0, h - 1)
    return image[row, col]


def face_colors(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F, 4) uint8 colour of every face of a colour-visual mesh (vertex colours averaged)."""
    visual = mesh.visual
    if getattr(visual, "kind", None) == "texture":
        image = texture_image(mesh)
        if image is not None:
            uv_centres = np.asarray(visual.uv)[mesh.faces].mean(axis=1)
            return sample_texture(image, uv_centres)
        material = getattr(visual, "material", None)
        main = getattr(material, "main_color", None)
        base = np.asarray(main if main is not None else [200, 200, 200, 255])
        return np.tile(_rgba_u8(base[None])[0], (len(mesh.faces), 1))
    if getattr(visual, "kind", None) == "vertex":
        vc = _rgba_u8(visual.vertex_colors).astype(np.float32)
        return np.round(vc[mesh.faces].mean(axis=1)).astype(np.uint8)
    return _rgba_u8(visual.face_colors)


def sample_surface(
    mesh: trimesh.Trimesh, count: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted surface samples: (count, 3) float points and (count, 3) uint8 colours.

    Colours come from the texture (at the interpolated uv), the interpolated vertex
    colours, or the face colours, whichever the mesh carries.
    """
    area = np.asarray(mesh.area_faces, dtype=float)
    if area.sum() <= 0:
        raise ValueError("cannot sample a surface with zero area")
    fi = rng.choice(len(area), size=count, p=area / area.sum())
    r = rng.random((count, 2))
    flip = r.sum(axis=1) > 1
    r[flip] = 1 - r[flip]
    w = np.stack([1 - r[:, 0] - r[:, 1], r[:, 0], r[:, 1]], axis=1)  # (count, 3)
    tri = np.asarray(mesh.vertices)[mesh.faces[fi]]  # (count, 3, 3)
    points = (w[:, :, None] * tri).sum(axis=1)
    visual = mesh.visual
    kind = getattr(visual, "kind", None)
    image = texture_image(mesh) if kind == "texture" else None
    if image is not None:
        uv = (w[:, :, None] * np.asarray(visual.uv)[mesh.faces[fi]]).sum(axis=1)
        colors = sample_texture(image, uv)
    elif kind == "vertex":
        vc = _rgba_u8(visual.vertex_colors).astype(np.float32)[mesh.faces[fi]]  # (count, 3, 4)
        colors = np.round((w[:, :, None] * vc).sum(axis=1)).astype(np.uint8)
    else:
        colors = face_colors(mesh)[fi]
    return points, colors[:, :3]
