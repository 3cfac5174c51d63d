"""What the import formats share: the error for a malformed source, the source category
names mapped to ours, asset ids made from source names, and the rules every importer
applies to the meshes a source names (inside the object's folder; a part mesh that can
be built, else refused or warned about, naming the file).
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import trimesh

log = logging.getLogger(__name__)


#: Source categories (PartNet-Mobility / CAGE / SINGAPO / PAct class ids) -> ours.
CATEGORY_MAP = {
    "storagefurniture": "cabinet",
    "cabinet": "cabinet",
    "table": "desk",
    "desk": "desk",
    "microwave": "microwave",
    "oven": "oven",
    "dishwasher": "dishwasher",
    "refrigerator": "refrigerator",
    "fridge": "refrigerator",
    "washingmachine": "washing_machine",
    "washing_machine": "washing_machine",
}


class ImportFormatError(ValueError):
    """An import source is unsupported or malformed; the message names the file and field."""


def sanitize_id(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._-")
    return s or "object"


def mesh_in_folder(
    folder: Path,
    name: str,
    src: Path,
    where: str,
    error: type[ImportFormatError] = ImportFormatError,
    given: str | None = None,
) -> Path:
    """The resolved mesh file ``name`` of an object whose files are in ``folder``.

    The rule of every importer: a mesh path (relative to ``folder``, or absolute) must
    resolve, symlinks followed, to an existing file inside ``folder``; an object never
    reads files outside its own folder (``../x.obj``, ``/etc/x.obj``). Raises ``error``
    naming the source file ``src``, the field ``where`` and the path as written
    (``given``, else ``name``).
    """
    shown = name if given is None else given
    p = (folder / name).resolve() if not os.path.isabs(name) else Path(name).resolve()
    if not p.is_relative_to(folder.resolve()):
        raise error(
            f"{src}: {where}: mesh {shown!r} lies outside the object folder {folder}; "
            "copy it into that folder and give its path relative to it"
        )
    if not p.is_file():
        raise error(f"{src}: {where}: mesh file {shown} not found")
    return p


# --------------------------------------------------------------------------- degenerate part meshes

#: A face has zero area when its area is below this x its longest edge squared (its
#: corners on a line, up to float32 rounding) or its longest edge is below this x the
#: mesh's size (its corners at one point). Small faces of a dense mesh are not zero.
ZERO_AREA = 1e-6
#: Fewer faces of non-zero area cannot enclose a volume (a tetrahedron has four).
MIN_PART_FACES = 4
#: A part is flat (no volume) when its thinnest extent is below this x its largest.
FLAT_SHARE = 1e-6
#: A part is noted when more than this share of its faces have zero area ...
ZERO_FACE_SHARE = 0.5
#: ... or more than this share of its edges (coincident vertices merged, a face and its
#: reverse counted once) are shared by three faces or more (non-manifold fins, fans).
NONMANIFOLD_SHARE = 0.25


def part_mesh_problems(vertices: np.ndarray, faces: np.ndarray) -> tuple[str | None, list[str]]:
    """``(refusal, doubts)`` about one part's mesh (its source meshes together).

    Refused (nothing sensible can be built): non-finite vertex coordinates; no face of
    non-zero area (a point or a line); a mesh with doubts that the build's closing
    (:func:`generator.mesh_repair.closing.watertight`) cannot make a closed volume.
    Doubts (it builds, possibly into a wrong shape or collisions): fewer than
    :data:`MIN_PART_FACES` faces of non-zero area, flat (:data:`FLAT_SHARE`), mostly
    zero-area faces (:data:`ZERO_FACE_SHARE`), badly non-manifold
    (:data:`NONMANIFOLD_SHARE`). Every measure is relative to the mesh's size, so any
    unit works; artists' open shells and double-sided faces within a part raise no doubt.
    """
    from generator.mesh_repair.closing import MeshRepairError, watertight

    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        return "holds no triangles", []
    if not np.isfinite(v[f]).all():
        return "has NaN or infinite vertex coordinates", []
    tri = v[f]
    size = float(np.ptp(tri.reshape(-1, 3), axis=0).max())
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    good = (area > ZERO_AREA * longest**2) & (longest > ZERO_AREA * size)
    if not good.any():
        return (
            f"all of its {len(f)} faces have zero area (the mesh is a point or a line): "
            "there is no surface to build"
        ), []
    doubts = []
    if good.sum() < MIN_PART_FACES:
        doubts.append(
            f"only {int(good.sum())} faces of non-zero area, far too few to enclose a volume"
        )
    extents = np.ptp(v[f[good]].reshape(-1, 3), axis=0)
    if extents.min() <= FLAT_SHARE * extents.max():
        doubts.append("flat (no thickness, no volume): the build closes it as a thin slab")
    if 1.0 - good.mean() > ZERO_FACE_SHARE:
        doubts.append(f"{1.0 - good.mean():.0%} of its faces have zero area")
    mesh = trimesh.Trimesh(vertices=v, faces=f[good], process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    mesh.update_faces(mesh.unique_faces())
    _, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    fins = float((counts > 2).mean()) if len(counts) else 0.0
    if fins > NONMANIFOLD_SHARE:
        doubts.append(f"badly non-manifold: {fins:.0%} of its edges are shared by 3 faces or more")
    if doubts:
        try:
            watertight(mesh)
        except MeshRepairError as e:
            return f"cannot be closed into a volume ({e}): " + "; ".join(doubts), []
    return None, doubts


def check_part_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    part: str,
    files: Sequence[str],
    src: Path,
    error: type[ImportFormatError] = ImportFormatError,
) -> list[str]:
    """Refuse a part mesh that cannot be built, or return warnings about one that can.

    :func:`part_mesh_problems` of the part ``part`` made of the mesh ``files``: raises
    ``error`` naming ``src`` (the object's description file), the part and the files;
    returns the doubts as one warning naming the part and the files (none when there is
    no doubt), which an importer logs and records in the bundle's and the import
    result's warnings.
    """
    refusal, doubts = part_mesh_problems(vertices, faces)
    named = f"{part}: mesh {', '.join(files) or '(no file)'}"
    if refusal is not None:
        raise error(f"{src}: {named}: {refusal}; repair or replace that mesh")
    if not doubts:
        return []
    return [
        f"{named}: {'; '.join(doubts)}; if the asset fails validation on {part.split()[0]} "
        "(penetration, an odd shape), this mesh is the likely cause"
    ]
