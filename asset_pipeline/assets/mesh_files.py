"""Mesh files of a built asset: OBJ text for collision pieces (and MJCF visuals), a
visual's texture image, and reading pieces back.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path

import numpy as np
import trimesh

from asset_pipeline.assets.built_asset import BuiltAsset, CollisionPiece

log = logging.getLogger(__name__)

# --------------------------------------------------------------------------- OBJ


def obj_text(mesh: trimesh.Trimesh, uv: np.ndarray | None = None) -> str:
    """Wavefront OBJ of the geometry (positions and faces; MuJoCo and PhysX read it), with
    ``uv`` (one texture coordinate per vertex, origin bottom-left) as ``vt`` lines."""
    if uv is None:
        return trimesh.exchange.obj.export_obj(
            mesh, include_normals=False, include_color=False, include_texture=False, header=None
        )
    # positions and texture coordinates indexed apart, each written once: a textured
    # mesh splits its vertices where the texture does, and many vertices share one
    # palette texel (7 significant digits: a micrometre on a metre-sized object)
    v, vi = np.unique(np.asarray(mesh.vertices, dtype=np.float32), axis=0, return_inverse=True)
    t, ti = np.unique(np.asarray(uv, dtype=np.float32), axis=0, return_inverse=True)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    fv, ft = vi.reshape(-1)[faces] + 1, ti.reshape(-1)[faces] + 1
    lines = [f"v {x:.7g} {y:.7g} {z:.7g}" for x, y, z in v.astype(float)]
    lines += [f"vt {a:.7g} {b:.7g}" for a, b in t.astype(float)]
    lines += [
        f"f {a}/{d} {b}/{e} {c}/{g}"
        for (a, b, c), (d, e, g) in zip(fv.tolist(), ft.tolist(), strict=True)
    ]
    return "\n".join(lines) + "\n"


def texture_image(mesh: trimesh.Trimesh | None) -> tuple[np.ndarray, bytes] | None:
    """(uv (n, 2), PNG bytes) of a mesh textured with one texture coordinate per vertex
    and a base-colour image; None otherwise."""
    visual = getattr(mesh, "visual", None)
    if mesh is None or getattr(visual, "kind", None) != "texture":
        return None
    uv = getattr(visual, "uv", None)
    material = getattr(visual, "material", None)
    image = getattr(material, "baseColorTexture", None) or getattr(material, "image", None)
    if uv is None or image is None or len(uv) != len(mesh.vertices):
        return None
    buf = io.BytesIO()
    image.convert("RGB").save(buf, format="PNG")
    return np.asarray(uv, dtype=float), buf.getvalue()


def read_obj_vertices(path: str | Path) -> np.ndarray:
    """(n, 3) vertex positions of an OBJ file (only ``v`` lines are read)."""
    verts = []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append([float(v) for v in line.split()[1:4]])
    return np.array(verts, dtype=float).reshape(-1, 3)


def read_obj(path: str | Path) -> trimesh.Trimesh:
    """The triangle mesh of a collision OBJ file (``v`` and ``f`` lines; vertex order kept)."""
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append([float(v) for v in line.split()[1:4]])
            elif line.startswith("f "):
                idx = [int(tok.split("/")[0]) for tok in line.split()[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
    return trimesh.Trimesh(
        np.array(verts, dtype=float).reshape(-1, 3),
        np.array(faces, dtype=np.int64).reshape(-1, 3),
        process=False,
    )


def piece_vertices(asset: BuiltAsset, piece: CollisionPiece) -> np.ndarray:
    """(n, 3) vertices of a collision piece in its link frame (its ``origin`` applied)."""
    v = (
        np.asarray(piece.mesh.vertices, dtype=float)
        if piece.mesh is not None
        else read_obj_vertices(asset.path_of(piece.filename))
    )
    return v @ piece.origin[:3, :3].T + piece.origin[:3, 3]


def link_piece_vertices(asset: BuiltAsset) -> dict[str, list[np.ndarray]]:
    """Vertices (n, 3) of every collision piece of every link, in the link frame."""
    return {k.name: [piece_vertices(asset, p) for p in k.collisions] for k in asset.links}
