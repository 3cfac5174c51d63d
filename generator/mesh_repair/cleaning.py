"""Clean part geometry for every generator's output: one solid piece per part.

A generated part mesh can carry debris (islands of a network's SDF, stray fragments),
a door can have a modelled handle beside its panel, and pieces may be open or inside
out. :func:`clean_parts` returns the object with

* every movable part reduced to its largest *group* (below) plus at most one more, when
  that one is a plausible handle (:func:`is_handle`: not a fleck, at most half the
  main group's area, within ``HANDLE_GAP`` of it and over its footprint);
* the base and fixed parts keeping every group but flecks (groups whose largest extent
  is under ``FLECK`` of the part's);
* every kept piece closed: watertight, consistently wound, positive volume; an open or
  inside-out piece is repaired in place (winding, inversion, holes) or, failing that,
  voxel-remeshed, with vertex colours from the nearest old vertex
  (:func:`generator.mesh_repair.closing.watertight`, the toolkit the asset build closes its
  part meshes with).

A *group* is a set of mesh pieces (connected components of the face graph) that touch
or overlap (within ``TOUCH`` of the part's size): a procedural part is a union of
overlapping closed boxes and cylinders, many pieces but one group, and is left as it
is. A part whose pieces are all closed and which loses no group comes back as the same
mesh object; an object where no part changes comes back as the same object.

PAct's decoder already gives one closed piece per part (per connected piece of the
base's occupancy, ``generator.pact.model.slat_vae.constrain_sdf``); this is the safety net
every generator's output goes through (``PActGenerator``, ``Stage1Generator``,
``RetrievalGenerator``).
"""

from __future__ import annotations

import logging

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from generator.articulated import ArticulatedObject, Part
from generator.mesh_repair.closing import MeshRepairError, is_closed, watertight

log = logging.getLogger(__name__)

#: Pieces closer than this fraction of the part's largest extent touch (one group).
TOUCH = 1e-3
#: A group whose largest extent is under this fraction of its part's is a fleck.
FLECK = 0.05
#: A handle lies within this fraction of its part's largest extent of the main group ...
HANDLE_GAP = 0.15
#: ... and has at most this fraction of the main group's surface area.
HANDLE_AREA = 0.5


def piece_report(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray, bool]:
    """Fast checks for large meshes (marching cubes output): per face its piece (label of
    the connected component of the vertex graph), per piece its signed volume, and
    whether the whole mesh is watertight with consistent winding (every directed edge
    once, and its reverse once)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(mesh.faces, np.int64)
    nv = len(mesh.vertices)
    if len(f) == 0:
        return np.zeros(0, np.int64), np.zeros(0), False
    a = f.ravel()
    b = f[:, [1, 2, 0]].ravel()
    graph = coo_matrix((np.ones(len(a), np.int8), (a, b)), shape=(nv, nv))
    _, vlab = connected_components(graph, directed=False)
    flab = vlab[f[:, 0]]
    _, flab = np.unique(flab, return_inverse=True)
    v = np.asarray(mesh.vertices, np.float64)
    vol = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])) / 6.0
    volumes = np.bincount(flab, weights=vol)
    fwd = np.sort(a * nv + b)
    rev = np.sort(b * nv + a)
    closed = bool(np.all(fwd[1:] != fwd[:-1]) and np.array_equal(fwd, rev))
    return flab, volumes, closed


def pieces(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    """The connected pieces of a mesh's face graph (the issue's count: ``len(pieces)``)."""
    if len(mesh.faces) == 0:
        return []
    return list(mesh.split(only_watertight=False))


def _points(mesh: trimesh.Trimesh, n: int = 600) -> np.ndarray:
    """Vertices (at most ``n``) and ``n`` area samples of a mesh."""
    v = mesh.vertices
    if len(v) > n:
        v = v[np.random.default_rng(0).choice(len(v), n, replace=False)]
    if mesh.area <= 0:
        return np.asarray(v)
    s, _ = trimesh.sample.sample_surface(mesh, n, seed=0)
    return np.concatenate([v, s])


def _distance(a: trimesh.Trimesh, b: trimesh.Trimesh) -> float:
    """Approximate distance between two pieces: 0 when one's points are inside the other
    (closed), else the nearest distance from one's vertices and surface samples to the
    other's surface (both ways)."""
    best = np.inf
    for x, y in ((a, b), (b, a)):
        pts = _points(x)
        if is_closed(y) and y.contains(pts[:64]).any():
            return 0.0
        _, d, _ = trimesh.proximity.closest_point(y, pts)
        best = min(best, float(d.min()))
    return best


def groups(parts: list[trimesh.Trimesh], tol: float) -> list[list[int]]:
    """Indices of ``parts`` grouped by touching (within ``tol``) or overlapping."""
    n = len(parts)
    root = list(range(n))

    def find(i: int) -> int:
        while root[i] != i:
            root[i] = root[root[i]]
            i = root[i]
        return i

    bounds = np.array([p.bounds for p in parts])  # (n, 2, 3)
    for i in range(n):
        for j in range(i + 1, n):
            if find(i) == find(j):
                continue
            if np.any(bounds[i, 0] > bounds[j, 1] + tol) or np.any(
                bounds[j, 0] > bounds[i, 1] + tol
            ):
                continue
            if _distance(parts[i], parts[j]) <= tol:
                root[find(i)] = find(j)
    out: dict[int, list[int]] = {}
    for i in range(n):
        out.setdefault(find(i), []).append(i)
    return list(out.values())


def _gap(a: trimesh.Trimesh, b: trimesh.Trimesh) -> float:
    """Nearest distance between the surface samples of two meshes."""
    d, _ = cKDTree(_points(a, 2000)).query(_points(b, 2000))
    return float(d.min())


def is_handle(main: trimesh.Trimesh, other: trimesh.Trimesh, size: float) -> bool:
    """``other`` could be a handle of a part whose main group is ``main`` (``size``: the
    part's largest extent): not a fleck, at most ``HANDLE_AREA`` of the main group's
    area, within ``HANDLE_GAP`` x size of it, and its centre over the main group's box
    grown by that gap."""
    if float(other.extents.max()) < FLECK * size or other.area > HANDLE_AREA * main.area:
        return False
    gap = HANDLE_GAP * size
    lo, hi = main.bounds[0] - gap, main.bounds[1] + gap
    centre = other.bounds.mean(axis=0)
    return bool(np.all(centre >= lo) and np.all(centre <= hi) and _gap(main, other) <= gap)


def _closed_copy(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """``mesh`` itself when closed, else its closed copy (:func:`generator.mesh_repair.closing.watertight`:
    flipped when inside out, repaired in place, else voxel-remeshed); a piece not even
    the remesh closes is kept as it is."""
    if is_closed(mesh):
        return mesh
    try:
        return watertight(mesh)
    except MeshRepairError as e:
        log.info("clean_parts: a piece stays open: %s", e)
        return mesh


def _closed_group(ps: list[trimesh.Trimesh]) -> list[trimesh.Trimesh]:
    """The pieces of one group made closed. Kept as they are (the same objects) when
    every piece is watertight and consistently wound and each inside-out piece is the
    wall of a cavity inside an outward one (a hollow solid: a procedural oven's base);
    else each piece is made closed on its own (``_closed_copy``)."""
    if all(p.is_watertight and p.is_winding_consistent for p in ps):
        outer = [p for p in ps if p.volume > 0]
        inner = [p for p in ps if p.volume <= 0]
        if outer and all(any(o.contains(c.vertices[:16]).all() for o in outer) for c in inner):
            return ps
    return [_closed_copy(p) for p in ps]


def clean_mesh(mesh: trimesh.Trimesh, movable: bool) -> trimesh.Trimesh:
    """One part's mesh cleaned (the module docstring); ``mesh`` itself when nothing
    changes."""
    if len(mesh.faces) == 0:
        return mesh
    size = float(mesh.extents.max())
    flab, volumes, closed = piece_report(mesh)
    if closed and np.all(volumes > 0):  # fast path: closed pieces (none a cavity's wall)
        if len(volumes) == 1:
            return mesh
        if not movable:
            v = np.asarray(mesh.vertices)[np.asarray(mesh.faces)[:, 0]]
            lo = np.full((len(volumes), 3), np.inf)
            hi = np.full((len(volumes), 3), -np.inf)
            np.minimum.at(lo, flab, v)
            np.maximum.at(hi, flab, v)
            if np.all((hi - lo).max(axis=1) >= FLECK * size):
                return mesh
    ps = pieces(mesh)
    if len(ps) == 1:
        return _closed_copy(mesh)
    gs = groups(ps, TOUCH * size)
    merged = [trimesh.util.concatenate([ps[i] for i in g]) if len(g) > 1 else ps[g[0]] for g in gs]
    if movable:
        order = sorted(range(len(gs)), key=lambda k: -merged[k].area)
        keep = [order[0]]
        keep += [k for k in order[1:] if is_handle(merged[order[0]], merged[k], size)][:1]
    else:
        extents = [float(m.extents.max()) for m in merged]
        keep = [k for k in range(len(gs)) if extents[k] >= FLECK * size]
        keep = keep or [int(np.argmax(extents))]
    kept = [[ps[i] for i in gs[k]] for k in sorted(keep)]
    closed = [_closed_group(g) for g in kept]
    same = all(
        c is k for cg, kg in zip(closed, kept, strict=True) for c, k in zip(cg, kg, strict=True)
    )
    if len(keep) == len(gs) and same:
        return mesh
    if len(keep) < len(gs):
        log.info("clean_parts: dropped %d of %d groups", len(gs) - len(keep), len(gs))
    out = [p for g in closed for p in g]
    return trimesh.util.concatenate(out) if len(out) > 1 else out[0]


def clean_parts(obj: ArticulatedObject) -> ArticulatedObject:
    """``obj`` with clean part geometry (the module docstring); ``obj`` itself when no
    part changes. Joints, primitives, handles and materials are kept."""
    parts, changed = [], False
    for p in obj.parts:
        movable = p.joint is not None and p.joint.movable
        mesh = clean_mesh(p.mesh, movable)
        if mesh is p.mesh:
            parts.append(p)
            continue
        changed = True
        parts.append(Part(p.name, p.semantic, mesh, p.joint, p.primitives, p.handle, p.material))
    if not changed:
        return obj
    return ArticulatedObject(parts, obj.category, obj.scale, dict(obj.provenance))


# --------------------------------------------------------------------------- visual pieces

#: A visual piece whose largest extent is under this share of its mesh's is a sliver ...
SLIVER = 0.02
#: ... and so is one holding under this share of its mesh's surface area.
SLIVER_AREA = 1e-3


def strict_pieces(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F,) piece label of every face, on the strictest count a reader may make: faces
    belong to one piece only when they share an edge (two faces meeting at a vertex, or
    through an edge that three faces share, are pieces apart), after coincident vertices
    are merged (texture seams and split normals do not separate pieces)."""
    n = len(mesh.faces)
    if n == 0:
        return np.zeros(0, np.int64)
    g = trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.faces, process=False)
    g.merge_vertices(merge_tex=True, merge_norm=True)
    comps = trimesh.graph.connected_components(g.face_adjacency, nodes=np.arange(n), min_len=1)
    labels = np.empty(n, np.int64)
    for k, c in enumerate(comps):
        labels[c] = k
    return labels


def drop_slivers(
    mesh: trimesh.Trimesh, extent: float = SLIVER, area: float = SLIVER_AREA
) -> trimesh.Trimesh:
    """``mesh`` without its slivers: zero-area faces, and pieces (:func:`strict_pieces`)
    whose largest extent is under ``extent`` x the mesh's or whose area is under ``area`` x
    its area. Visuals (texture coordinates, colours) are kept; ``mesh`` itself comes back
    when nothing is dropped. A mesh with nothing but slivers keeps its largest piece."""
    faces = np.asarray(mesh.faces)
    if len(faces) == 0:
        return mesh
    tri = np.asarray(mesh.vertices, float)[faces]
    face_area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    labels = strict_pieces(mesh)
    n = int(labels.max()) + 1
    size = float(np.linalg.norm(mesh.extents)) or 1.0
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    np.minimum.at(lo, labels, tri.min(axis=1))
    np.maximum.at(hi, labels, tri.max(axis=1))
    piece_area = np.bincount(labels, weights=face_area, minlength=n)
    keep_piece = (np.linalg.norm(hi - lo, axis=1) >= extent * size) & (
        piece_area >= area * max(float(piece_area.sum()), 1e-30)
    )
    if not keep_piece.any():
        keep_piece[int(np.argmax(piece_area))] = True
    keep = keep_piece[labels] & (face_area > 0)
    if keep.all():
        return mesh
    log.debug("drop_slivers: %d of %d faces dropped", int((~keep).sum()), len(keep))
    out = mesh.submesh([np.flatnonzero(keep)], append=True)
    return out


def _colour_properties(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """(V, 4) float RGBA in 0..1 of a vertex- or face-coloured mesh, None otherwise."""
    if mesh.visual.kind not in ("vertex", "face"):
        return None
    return np.asarray(mesh.visual.vertex_colors, float) / 255.0


def union_solids(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh | None:
    """The boolean union of closed ``meshes`` as one mesh (manifold3d), their vertex
    colours carried over; None when one of them is not a closed volume (then nothing is
    joined). Touching or overlapping solids become one piece; apart, they stay apart."""
    import manifold3d

    if not meshes or not all(is_closed(m) for m in meshes):
        return None
    colours = [_colour_properties(m) for m in meshes]
    coloured = all(c is not None for c in colours)
    solids = []
    for m, c in zip(meshes, colours, strict=True):
        props = np.asarray(m.vertices, np.float32)
        if coloured:
            props = np.concatenate([props, np.asarray(c, np.float32)], axis=1)
        solids.append(
            manifold3d.Manifold(
                mesh=manifold3d.Mesh(
                    vert_properties=np.ascontiguousarray(props),
                    tri_verts=np.asarray(m.faces, np.uint32),
                )
            )
        )
    result = manifold3d.Manifold.batch_boolean(solids, manifold3d.OpType.Add).to_mesh()
    props = np.asarray(result.vert_properties, float)
    faces = np.asarray(result.tri_verts, np.int64)
    if len(faces) == 0:
        return None
    out = trimesh.Trimesh(vertices=props[:, :3], faces=faces, process=False)
    if coloured:
        rgba = np.clip(np.round(props[:, 3:7] * 255.0), 0, 255).astype(np.uint8)
        out.visual = trimesh.visual.ColorVisuals(out, vertex_colors=rgba)
    # manifold3d splits a vertex whose colour differs between the solids that meet there
    closed = trimesh.Trimesh(vertices=out.vertices, faces=out.faces, process=False)
    closed.merge_vertices(merge_tex=True, merge_norm=True)
    return out if closed.is_watertight and closed.is_winding_consistent else None


def panel_and_handle(
    mesh: trimesh.Trimesh, handle: trimesh.Trimesh | None = None
) -> trimesh.Trimesh:
    """A movable part's visual as at most two pieces: its panel and its handle.

    Slivers are dropped (:func:`drop_slivers`); the pieces touching or overlapping the
    largest one (a drawer's front and its tray) are joined with it into the panel
    (:func:`union_solids`, when they are closed); ``handle`` (a handle the caller added)
    is the handle, else the largest other piece when it is a plausible handle
    (:func:`is_handle`). Whatever else is left is dropped (logged)."""
    mesh = drop_slivers(mesh)
    labels = strict_pieces(mesh)
    ps = [mesh.submesh([np.flatnonzero(labels == k)], append=True) for k in np.unique(labels)]
    if len(ps) == 1:
        panel = ps[0]
        others: list[trimesh.Trimesh] = []
    else:
        size = float(mesh.extents.max())
        gs = groups(ps, TOUCH * size)
        merged = []
        for g in gs:
            members = [ps[i] for i in g]
            joined = union_solids(members) if len(members) > 1 else members[0]
            merged.append(joined if joined is not None else trimesh.util.concatenate(members))
        merged.sort(key=lambda m: -m.area)
        panel, others = merged[0], merged[1:]
    if handle is None and others and is_handle(panel, others[0], float(mesh.extents.max())):
        handle, others = others[0], others[1:]
    if others:
        log.info(
            "panel_and_handle: dropped %d piece(s), %.1f%% of the area",
            len(others),
            100.0 * sum(o.area for o in others) / max(mesh.area, 1e-30),
        )
    out = [panel] if handle is None else [panel, handle]
    return trimesh.util.concatenate(out) if len(out) > 1 else panel
