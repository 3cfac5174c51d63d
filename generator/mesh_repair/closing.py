"""Closing a triangle mesh: a watertight, consistently wound, positive volume.

:func:`watertight` returns a mesh that already is one as it is (textures and colours
kept); otherwise trimesh's repairs run (merge vertices, drop degenerate and duplicate
faces, fix winding and inversion, fill small holes); when the result is still not a
volume the mesh is voxel-remeshed (:func:`voxel_remesh`: voxelize at a pitch relative
to the part's size, fill the interior, marching cubes) and colours are carried over
from the nearest original vertex.

One toolkit for both sides of the pipeline: the generators' part cleaning
(:mod:`generator.mesh_repair.cleaning`) and the asset build's metric part meshes
(:mod:`asset_pipeline.geometry.metric`).
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Collection

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from generator.articulated import ArticulatedObject, Part

log = logging.getLogger(__name__)

#: Voxel remesh resolution: the pitch is the part's largest extent divided by this
#: (made finer for thin parts, see :func:`remesh_pitch`).
REMESH_RESOLUTION = 64


class MeshRepairError(ValueError):
    """A part mesh could not be made watertight (the message says which step failed);
    ``part`` names the part when the mesh was one of an object's."""

    def __init__(self, message: str, part: str | None = None) -> None:
        super().__init__(message)
        self.part = part


def _geometry_copy(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Positions and faces only, with coincident vertices merged (UV seams ignored)."""
    g = trimesh.Trimesh(vertices=mesh.vertices.copy(), faces=mesh.faces.copy(), process=False)
    g.merge_vertices(merge_tex=True, merge_norm=True)
    return g


def is_closed(mesh: trimesh.Trimesh) -> bool:
    """Watertight, consistently wound, positive volume, on the mesh's own vertex
    indexing (at least four faces)."""
    return bool(
        len(mesh.faces) >= 4
        and mesh.is_watertight
        and mesh.is_winding_consistent
        and mesh.volume > 0
    )


def is_closed_volume(mesh: trimesh.Trimesh) -> bool:
    """True when the mesh's geometry encloses a positive volume with consistent winding.

    Checked on the mesh's own vertex indexing (so closed bodies that merely touch,
    like a union of stacked boxes, count as closed) and, failing that, with
    coincident vertices merged (so vertices split only by texture seams or normals
    count as one).
    """
    if len(mesh.faces) < 4:
        return False
    return is_closed(mesh) or is_closed(_geometry_copy(mesh))


def slice_closed(
    mesh: trimesh.Trimesh, normal: np.ndarray, origin: np.ndarray
) -> trimesh.Trimesh | None:
    """The side of ``mesh`` the plane's ``normal`` points to (the plane through
    ``origin``), a closed volume kept closed. A closed volume is trimmed by manifold3d
    (the cut capped exactly; trimesh's capping leaves a few open edges where the cut
    runs along the mesh's edges), as merged when it is closed only with its coincident
    vertices merged (a union of differently coloured solids: manifold3d splits the
    vertices where the colours meet). An open mesh is cut open by trimesh, and so is a
    closed one manifold3d refuses. Colours: every vertex takes the nearest old vertex's
    (:func:`transfer_colors`). None when nothing is left."""
    out = None
    if is_closed_volume(mesh):
        out = _trim_solid(mesh if mesh.is_watertight else _geometry_copy(mesh), normal, origin)
    if out is None:
        out = trimesh.intersections.slice_mesh_plane(mesh, normal, origin)
    if out is None or len(out.faces) == 0:
        return None
    return transfer_colors(mesh, out)


def _trim_solid(
    mesh: trimesh.Trimesh, normal: np.ndarray, origin: np.ndarray
) -> trimesh.Trimesh | None:
    """manifold3d's trim of a closed mesh by a plane (positions only, double precision);
    None when manifold3d does not take the mesh as a manifold."""
    import manifold3d

    solid = manifold3d.Manifold(
        mesh=manifold3d.Mesh64(
            # copies: manifold3d takes writable C arrays only
            vert_properties=np.array(mesh.vertices, np.float64, order="C"),
            tri_verts=np.array(mesh.faces, np.uint64, order="C"),
        )
    )
    if solid.status() != manifold3d.Error.NoError:
        return None
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    cut = solid.trim_by_plane(tuple(n.tolist()), float(np.asarray(origin, np.float64) @ n))
    result = cut.to_mesh64()
    faces = np.array(result.tri_verts, np.int64)
    vertices = np.array(result.vert_properties, np.float64)[:, :3]
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


def remesh_pitch(extents: np.ndarray, resolution: int = REMESH_RESOLUTION) -> float:
    """Voxel pitch (same units as ``extents``, shape (3,)) for remeshing one part.

    ``max(extents) / resolution``, made finer for thin parts so that the thinnest
    side spans at least about 3 voxels, but never finer than ``max(extents) / (4 *
    resolution)`` (bounds memory and time).
    """
    ext = np.asarray(extents, dtype=float)
    big = float(ext.max())
    if big <= 0:
        raise MeshRepairError(f"cannot remesh a part with zero extent {ext.tolist()}")
    pitch = big / resolution
    thin = float(ext[ext > 0].min()) if (ext > 0).any() else big
    pitch = min(pitch, thin / 3.0)
    return max(pitch, big / (4 * resolution))


def vertex_colors(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """(V, 4) uint8 RGBA per vertex of ``mesh``, or None when it has no colour."""
    vis = mesh.visual
    try:
        if vis.kind == "texture":
            vis = vis.to_color()
        if vis.kind in ("vertex", "face"):
            return np.asarray(vis.vertex_colors, dtype=np.uint8)
    except Exception as e:  # noqa: BLE001 - colour is cosmetic; never fail the geometry
        log.debug("cannot read colours for transfer: %s", e)
    return None


def transfer_colors(source: trimesh.Trimesh, target: trimesh.Trimesh) -> trimesh.Trimesh:
    """Colour ``target``'s vertices from the nearest vertex of ``source`` (in place; returned)."""
    colors = vertex_colors(source)
    if colors is None or len(source.vertices) == 0:
        return target
    _, idx = cKDTree(source.vertices).query(target.vertices)
    target.visual = trimesh.visual.ColorVisuals(target, vertex_colors=colors[idx])
    return target


def voxel_remesh(mesh: trimesh.Trimesh, pitch: float | None = None) -> trimesh.Trimesh:
    """Closed surface of ``mesh`` by voxelization (pitch in mesh units) + marching cubes.

    The surface lies up to half a voxel outside the input (surface voxels are kept
    whole). Colours are transferred from the nearest input vertex.
    """
    if pitch is None:
        pitch = remesh_pitch(mesh.extents)
    grid = mesh.voxelized(pitch).fill()
    out = grid.marching_cubes
    out.apply_transform(grid.transform)
    out.merge_vertices()
    trimesh.repair.fix_winding(out)
    trimesh.repair.fix_inversion(out, multibody=True)
    if not is_closed_volume(out):
        raise MeshRepairError(
            f"voxel remesh at pitch {pitch:.4g} did not give a closed volume "
            f"({len(out.faces)} faces)"
        )
    return transfer_colors(mesh, out)


def watertight(mesh: trimesh.Trimesh, resolution: int = REMESH_RESOLUTION) -> trimesh.Trimesh:
    """A closed, outward-wound copy of ``mesh`` (same units and frame).

    Already closed meshes come back unchanged (a copy; inverted ones flipped), keeping
    textures. Otherwise repair, then voxel remesh as the last resort (vertex colours
    by nearest point; a texture is baked to vertex colours).
    """
    if len(mesh.faces) == 0:
        raise MeshRepairError("the mesh has no faces")
    out = mesh.copy()
    if is_closed_volume(out):
        return out
    for candidate in (out, _geometry_copy(out)):
        # an inside-out but otherwise closed mesh only needs flipping
        if candidate.is_watertight and candidate.is_winding_consistent and candidate.volume < 0:
            flipped = out.copy()
            flipped.invert()
            if is_closed_volume(flipped):
                return flipped
            break
    if out.visual.kind != "texture":
        # first without merging vertices (keeps touching closed bodies apart), then merged
        for merge in (False, True):
            rep = out.copy()
            if merge:
                rep.merge_vertices()
            rep.update_faces(rep.nondegenerate_faces() & rep.unique_faces())
            rep.remove_unreferenced_vertices()
            trimesh.repair.fix_winding(rep)
            trimesh.repair.fix_inversion(rep, multibody=True)
            trimesh.repair.fill_holes(rep)
            trimesh.repair.fix_winding(rep)
            trimesh.repair.fix_inversion(rep, multibody=True)
            if is_closed_volume(rep):
                log.info("repaired mesh (%d -> %d faces)", len(mesh.faces), len(rep.faces))
                return rep
    pitch = remesh_pitch(mesh.extents, resolution)
    log.info("mesh not repairable in place; voxel remesh at pitch %.4g", pitch)
    return voxel_remesh(mesh, pitch)


def has_texture_image(mesh: trimesh.Trimesh) -> bool:
    """True when ``mesh`` is textured with an image (an artist's or a baked texture)."""
    material = getattr(mesh.visual, "material", None)
    image = getattr(material, "image", None) or getattr(material, "baseColorTexture", None)
    return mesh.visual.kind == "texture" and image is not None


def watertight_object(
    obj: ArticulatedObject,
    resolution: int = REMESH_RESOLUTION,
    keep: Collection[str] = (),
) -> ArticulatedObject:
    """Copy of ``obj`` with every part mesh replaced by :func:`watertight` of it.

    Parts named in ``keep`` keep their meshes as they are, and so does a part whose
    mesh carries a texture image and is not a closed volume (remeshing would lose the
    texture): their meshes are visuals only, and their physics comes from primitives
    or articulation-aware collision boxes (:mod:`asset_pipeline.geometry.voxel_collision`). An
    artist's open shells stay as the artist made them. Raises MeshRepairError naming
    the part when one cannot be closed.
    """
    parts = []
    for p in obj.parts:
        try:
            if p.name in keep or (has_texture_image(p.mesh) and not is_closed_volume(p.mesh)):
                m = p.mesh.copy()
            else:
                m = watertight(p.mesh, resolution)
        except MeshRepairError as e:
            raise MeshRepairError(f"part {p.name!r}: {e}", part=p.name) from e
        parts.append(
            Part(
                name=p.name,
                semantic=p.semantic,
                mesh=m,
                joint=p.joint,
                primitives=list(p.primitives),
                handle=p.handle,
                material=p.material,
            )
        )
    return ArticulatedObject(
        parts=parts,
        category=obj.category,
        scale=obj.scale,
        provenance=copy.deepcopy(obj.provenance),
    )
