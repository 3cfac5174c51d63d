"""Light meshes: an object's visual meshes within a triangle budget, their looks kept.

A robot-learning run loads hundreds of assets into many parallel scenes, often with
cameras; a part mesh straight from marching cubes holds hundreds of thousands of
triangles, most of them on flat faces. :func:`light_object` brings an object's part
meshes within ``max_faces`` triangles in all (``DEFAULT_VISUAL_FACES``; 0 keeps every
triangle) by quadric edge collapse (MeshLab, through ``pymeshlab``):

- the budget is shared out by surface area (:func:`part_budgets`: a part within its share
  keeps its mesh and leaves the rest to the others; none gets fewer than
  ``MIN_PART_FACES``);
- the collapse keeps the mesh's topology (a closed piece stays one closed piece, no
  sliver is made) and its normals (no face flips), and places vertices where the
  quadric error is least; vertex colours go with their vertices;
- a closed mesh far above its budget is first brought to ``PRESIMPLIFY_FACTOR`` times it
  by meshoptimizer's collapse onto existing vertices (:func:`_presimplify`, far faster
  than MeshLab's: a marching-cubes base of 226,000 triangles to 47,000 in 1.5-1.7 s
  instead of 4.2-5.4 s in all, its mean distance to the original 0.11 mm on a metre-tall
  object instead of 0.19 mm), kept only when it is still closed: that collapse does not guard
  the topology (it may pinch two sheets into a non-manifold edge; a thin wall it folds
  flat, two faces on the same three vertices, is dropped, and a vertex where the surface
  then touches itself is split before MeshLab's collapse), MeshLab's
  topology-keeping collapse does the rest, and the result is kept only when it is closed
  without a zero-area face (else MeshLab alone on the mesh);
- a textured mesh (an artist's texture, a baked photo) is collapsed by MeshLab's
  texture-aware variant, which keeps texture seams and weighs the texture coordinates'
  error.

:func:`split_long_edges` does the opposite where it is needed: it splits the edges longer
than a length (conforming: the faces on both sides of an edge split it alike), for a
texture that is projected per vertex.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np
import trimesh

from generator.articulated import ArticulatedObject, Part
from generator.mesh_repair.closing import is_closed

log = logging.getLogger(__name__)

#: Visual triangles per object by default (``--visual-faces``); 0 keeps every triangle.
DEFAULT_VISUAL_FACES = 60_000
#: A part's mesh is never decimated below this many triangles.
MIN_PART_FACES = 400
#: A closed mesh with more than this many times its budget is pre-simplified
#: (:func:`_presimplify`) to this many times its budget before MeshLab's collapse.
PRESIMPLIFY_FACTOR = 1.5


def part_budgets(meshes: Mapping[str, trimesh.Trimesh], max_faces: int) -> dict[str, int]:
    """Triangles allowed per part: ``max_faces`` shared by surface area, a part within its
    share keeping its own count and leaving the rest to the others, none below
    ``MIN_PART_FACES`` (or its own count, when smaller). ``max_faces <= 0``: every part
    keeps its count."""
    counts = {k: len(m.faces) for k, m in meshes.items()}
    if max_faces <= 0 or sum(counts.values()) <= max_faces:
        return dict(counts)
    budget: dict[str, int] = {}
    left = dict(meshes)
    remaining = float(max_faces)
    while left:
        area = {k: max(float(m.area), 1e-12) for k, m in left.items()}
        total = sum(area.values())
        share = {k: remaining * a / total for k, a in area.items()}
        within = [k for k in left if counts[k] <= max(share[k], MIN_PART_FACES)]
        if not within:
            for k in left:
                budget[k] = max(int(share[k]), min(MIN_PART_FACES, counts[k]))
            break
        for k in within:
            budget[k] = counts[k]
            remaining = max(remaining - counts[k], 0.0)
            del left[k]
    return budget


def _is_textured(mesh: trimesh.Trimesh) -> bool:
    uv = getattr(mesh.visual, "uv", None)
    return mesh.visual.kind == "texture" and uv is not None and len(uv) == len(mesh.vertices)


def _drop_folded_pairs(faces: np.ndarray) -> np.ndarray:
    """``faces`` (F, 3) without the faces whose three vertices another face also has: where
    a collapse folds a thin wall flat, two faces on the same vertices, facing apart, make
    a zero-volume pocket whose edges four faces share; without the pair the surface
    round it is closed again (touching itself at a vertex at most)."""
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inverse.reshape(-1)] == 1]


def _presimplify(mesh: trimesh.Trimesh, target: int) -> trimesh.Trimesh | None:
    """``mesh`` (closed, untextured) with about ``target`` triangles by meshoptimizer's
    edge collapse onto existing vertices (vertex colours kept by index), its folded face
    pairs dropped (:func:`_drop_folded_pairs`), or None when the result is not closed."""
    import meshoptimizer

    indices = np.ascontiguousarray(mesh.faces, np.uint32).reshape(-1)
    out = np.zeros_like(indices)
    n = meshoptimizer.simplify(
        out,
        indices,
        np.ascontiguousarray(mesh.vertices, np.float32),
        target_index_count=3 * int(target),
        target_error=1.0,  # relative to the mesh's size: the triangle count decides
    )
    faces = _drop_folded_pairs(out[:n].reshape(-1, 3).astype(np.int64))
    used = np.unique(faces)
    remap = np.full(len(mesh.vertices), -1, np.int64)
    remap[used] = np.arange(len(used))
    pre = trimesh.Trimesh(
        vertices=np.asarray(mesh.vertices, np.float64)[used], faces=remap[faces], process=False
    )
    if mesh.visual.kind in ("vertex", "face"):
        colours = np.asarray(mesh.visual.vertex_colors)[used]
        pre.visual = trimesh.visual.ColorVisuals(pre, vertex_colors=colours)
    return pre if is_closed(pre) else None


def _collapse(mesh: trimesh.Trimesh, target: int) -> trimesh.Trimesh:
    """MeshLab's topology-keeping quadric collapse of an untextured mesh; vertex colours
    (face colours become vertex colours) stay with their vertices. A closed mesh above
    ``PRESIMPLIFY_FACTOR`` times ``target`` is pre-simplified first (:func:`_presimplify`),
    its zero-area faces flipped away (MeshLab's T-vertex removal: its clean-up would
    drop them and leave holes); the result is kept when it is closed and has no
    zero-area face, else the collapse runs again on ``mesh`` alone."""
    if len(mesh.faces) > PRESIMPLIFY_FACTOR * target and is_closed(mesh):
        pre = _presimplify(mesh, int(PRESIMPLIFY_FACTOR * target))
        if pre is not None:
            out = _meshlab_collapse(pre, target, flip_t_vertices=True)
            if is_closed(out) and (out.area_faces > 0).all():
                return out
        log.debug("pre-simplifying a %d-face mesh broke it; MeshLab alone", len(mesh.faces))
    return _meshlab_collapse(mesh, target)


def _meshlab_collapse(
    mesh: trimesh.Trimesh, target: int, flip_t_vertices: bool = False
) -> trimesh.Trimesh:
    import pymeshlab

    colours = None
    if mesh.visual.kind in ("vertex", "face"):
        colours = np.asarray(mesh.visual.vertex_colors, np.float64) / 255.0
    ms = pymeshlab.MeshSet()
    kwargs = {} if colours is None else {"v_color_matrix": colours}
    ms.add_mesh(
        pymeshlab.Mesh(
            vertex_matrix=np.asarray(mesh.vertices, np.float64),
            face_matrix=np.asarray(mesh.faces, np.int32),
            **kwargs,
        )
    )
    if flip_t_vertices:
        # where the pre-pass left the surface touching itself at a vertex, the vertex is
        # split (one per fan of faces round it; MeshLab's filters refuse such a mesh)
        ms.meshing_repair_non_manifold_vertices(vertdispratio=0)
        ms.meshing_remove_t_vertices(method=1, threshold=40, repeat=True)  # 1: edge flips
    ms.meshing_decimation_quadric_edge_collapse(
        targetfacenum=int(target),
        preservetopology=True,
        preserveboundary=True,
        preservenormal=True,
        optimalplacement=True,
        planarquadric=True,
    )
    m = ms.current_mesh()
    out = trimesh.Trimesh(
        vertices=np.asarray(m.vertex_matrix(), np.float64),
        faces=np.asarray(m.face_matrix(), np.int64),
        process=False,
    )
    if colours is not None and m.has_vertex_color():
        rgba = np.clip(np.round(np.asarray(m.vertex_color_matrix()) * 255.0), 0, 255)
        out.visual = trimesh.visual.ColorVisuals(out, vertex_colors=rgba.astype(np.uint8))
    return out


def _collapse_textured(mesh: trimesh.Trimesh, target: int) -> trimesh.Trimesh:
    """MeshLab's texture-aware quadric collapse; one texture coordinate per vertex in and
    out (vertices split where the texture is)."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(
        pymeshlab.Mesh(
            vertex_matrix=np.asarray(mesh.vertices, np.float64),
            face_matrix=np.asarray(mesh.faces, np.int32),
            v_tex_coords_matrix=np.asarray(mesh.visual.uv, np.float64),
        )
    )
    ms.compute_texcoord_transfer_vertex_to_wedge()
    # seams split vertices: merge coincident ones so that the collapse sees one surface
    ms.meshing_merge_close_vertices(threshold=pymeshlab.PercentageValue(1e-4))
    ms.meshing_decimation_quadric_edge_collapse_with_texture(
        targetfacenum=int(target),
        preserveboundary=True,
        optimalplacement=True,
        preservenormal=True,
        planarquadric=True,
    )
    m = ms.current_mesh()
    faces = np.asarray(m.face_matrix(), np.int64)
    wedge = np.asarray(m.wedge_tex_coord_matrix(), np.float64).reshape(-1, 2)
    corner = np.concatenate([faces.reshape(-1, 1).astype(np.float64), np.round(wedge, 7)], axis=1)
    unique, inverse = np.unique(corner, axis=0, return_inverse=True)
    vertices = np.asarray(m.vertex_matrix(), np.float64)[unique[:, 0].astype(np.int64)]
    out = trimesh.Trimesh(vertices=vertices, faces=inverse.reshape(-1, 3), process=False)
    out.visual = trimesh.visual.TextureVisuals(uv=unique[:, 1:], material=mesh.visual.material)
    return out


def decimate(mesh: trimesh.Trimesh, target: int) -> trimesh.Trimesh:
    """``mesh`` with at most ``target`` triangles (``mesh`` itself when it has no more):
    textured meshes keep their texture, coloured ones their colours; a mesh the collapse
    cannot handle comes back unchanged (logged)."""
    target = max(int(target), 4)
    if len(mesh.faces) <= target:
        return mesh
    try:
        out = (_collapse_textured if _is_textured(mesh) else _collapse)(mesh, target)
    except Exception as e:  # noqa: BLE001 - a heavy visual is better than none
        log.warning("decimating a %d-face mesh failed (%s); kept as it is", len(mesh.faces), e)
        return mesh
    if len(out.faces) == 0:
        log.warning("decimating a %d-face mesh left nothing; kept as it is", len(mesh.faces))
        return mesh
    return out


def light_meshes(
    meshes: Mapping[str, trimesh.Trimesh], max_faces: int = DEFAULT_VISUAL_FACES
) -> dict[str, trimesh.Trimesh]:
    """Every mesh of ``meshes`` (part name -> mesh) decimated to its share of
    ``max_faces`` (:func:`part_budgets`); ``max_faces = 0`` keeps them all."""
    budgets = part_budgets(meshes, max_faces)
    return {k: decimate(m, budgets[k]) for k, m in meshes.items()}


def light_object(
    obj: ArticulatedObject, max_faces: int = DEFAULT_VISUAL_FACES
) -> ArticulatedObject:
    """``obj`` with its part meshes within ``max_faces`` triangles in all (the module
    docstring); ``obj`` itself when it is within already. Joints, primitives, handles and
    materials are kept."""
    meshes = {p.name: p.mesh for p in obj.parts}
    light = light_meshes(meshes, max_faces)
    if all(light[k] is m for k, m in meshes.items()):
        return obj
    parts = [
        Part(p.name, p.semantic, light[p.name], p.joint, p.primitives, p.handle, p.material)
        for p in obj.parts
    ]
    return ArticulatedObject(parts, obj.category, obj.scale, dict(obj.provenance))


# --------------------------------------------------------------------------- refinement

#: Face corners of the split edges' midpoints, per count of split edges; the face is
#: first turned so that its split edges come first (edge k runs from corner k to k + 1).
_SPLIT_FACES = {
    1: [(0, 3, 2), (3, 1, 2)],
    2: [(3, 1, 4), (0, 3, 4), (0, 4, 2)],
    3: [(0, 3, 5), (3, 1, 4), (5, 4, 2), (3, 4, 5)],
}


def split_long_edges(
    vertices: np.ndarray, faces: np.ndarray, max_edge: float, max_faces: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Split every edge longer than ``max_edge`` at its middle until none is (or another
    round would pass ``max_faces``). Conforming: both faces of an edge split it alike, so
    a closed mesh stays closed and no crack opens.

    Returns the new vertices (V', 3), faces (F', 3), the two parent vertices of every
    vertex (V', 2) (an old vertex is its own parents) and the original face of every new
    face (F',).
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    parents = np.stack([np.arange(len(v)), np.arange(len(v))], axis=1)
    origin = np.arange(len(f))
    while len(f):
        edges = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)  # (3F, 2) k->k+1
        key = np.sort(edges, axis=1)
        uniq, inverse = np.unique(key, axis=0, return_inverse=True)
        length = np.linalg.norm(v[uniq[:, 0]] - v[uniq[:, 1]], axis=1)
        long = length > max_edge
        if not long.any():
            break
        split = long[inverse].reshape(-1, 3)  # (F, 3): edge k of face i splits
        count = split.sum(axis=1)
        grow = np.array([0, 1, 2, 3])[count].sum()
        if max_faces is not None and len(f) + grow > max_faces:
            break
        mid_id = np.full(len(uniq), -1, np.int64)
        mid_id[long] = len(v) + np.arange(int(long.sum()))
        v = np.concatenate([v, 0.5 * (v[uniq[long, 0]] + v[uniq[long, 1]])])
        parents = np.concatenate([parents, uniq[long]])
        mids = mid_id[inverse].reshape(-1, 3)  # (F, 3) midpoint of edge k, -1 when whole
        new_faces, new_origin = [f[count == 0]], [origin[count == 0]]
        for n, pattern in _SPLIT_FACES.items():
            sel = np.flatnonzero(count == n)
            if len(sel) == 0:
                continue
            # turn each face so that its split edges are edges 0 .. n-1
            s = split[sel]
            if n == 1:
                shift = np.argmax(s, axis=1)
            elif n == 2:
                shift = (np.argmin(s, axis=1) + 1) % 3  # the whole edge becomes edge 2
            else:
                shift = np.zeros(len(sel), np.int64)
            idx = (np.arange(3)[None, :] + shift[:, None]) % 3
            corners = np.take_along_axis(f[sel], idx, axis=1)
            m = np.take_along_axis(mids[sel], idx, axis=1)
            table = np.concatenate([corners, m], axis=1)  # corners 0-2, midpoints 3-5
            for tri in pattern:
                new_faces.append(table[:, list(tri)])
                new_origin.append(origin[sel])
        f = np.concatenate(new_faces)
        origin = np.concatenate(new_origin)
    return v, f, parents, origin
