"""The ``diffuse_tree`` import format: CAGE, SINGAPO and the official PAct release.

Supported input: the ``diffuse_tree`` object.json layout shared by CAGE, SINGAPO
(and their PartNet-Mobility / ACD preprocessed data) and the official PAct
release's ``--export_arti_objects`` output (``exported_arti_objects/<id>/object.json``
with ``glb/`` and ``ply/`` part meshes, "SINGAPO format" in its README)::

    {"meta": {"obj_cat": "StorageFurniture", ...},
     "diffuse_tree": [                       # older files call it "arti_tree"
        {"id": 0, "parent": -1, "name": "base", "children": [1],
         "aabb": {"center": [..], "size": [..]},
         "joint": {"type": "fixed", "range": [0, 0],
                   "axis": {"origin": [..], "direction": [..]}},
         "objs": ["objs/0.obj"], "plys": ["plys/0.ply"], "glb": ["glb/part_0.glb"]},
        ...]}

Conventions of that format, as its reference code reads it (CAGE ``utils/render.py``,
SINGAPO ``retrieval``, PAct ``scripts/json_to_urdf.py``): part meshes are stored in
the object frame at joint value 0; ``axis.origin`` is a point on the axis and
``axis.direction`` its direction; ``range`` is ``[lower, upper]`` in degrees for
revolute/continuous joints and in model units for prismatic/screw joints; mesh
paths are relative to the object.json's folder; the frame is +y up with the front
facing +z (the PartNet-Mobility convention); sizes are normalized, not metric.

Conversion to this project's object model (``generator.articulated``):

- Frame: with the default ``up="y"``, source (x right, y up, z front) maps to ours
  (x front, y = the viewer's right when facing the front, z up) by the rotation
  ``x' = z, y' = x, z' = y`` (a cyclic permutation, det +1), applied to mesh
  vertices, joint origins and axes. ``up="z"`` takes the source as already in this
  project's axes (+z up, front +x).
- Scale: the object is normalized into the cube [-0.5, 0.5]^3 (rest bounding-box
  centre at the origin, largest extent 1) and saved with ``scale = None``; the
  pipeline applies metric scale (height hint or category default).
  ``provenance["normalization"]`` = [cx, cy, cz, s] maps back: ``x_src_rotated = x * s + c``.
- Tree: the root node becomes ``base``. A ``fixed`` node is merged into its nearest
  movable ancestor (or the base): handles, knobs and shelves become part of the
  door, drawer or body they hang on. A movable node under a movable node is
  re-rooted onto ``base`` with its joint unchanged (exact at rest; it no longer
  follows its parent when that opens; logged as a warning).
- Joints: revolute ranges go from degrees to radians; prismatic ranges scale with
  the normalization. When the range opens only toward negative values
  (``upper <= 0``) the axis is flipped so that positive motion opens, as the
  object model requires. ``continuous`` becomes a revolute joint over [0, 2*pi]
  (``continuous="revolute"``, default), is merged as fixed (``"fixed"``) or refused
  (``"error"``). ``screw`` (coupled rotation and translation) is refused by default
  (``screw="error"``), or kept as its translation (``"prismatic"``) or merged as
  fixed (``"fixed"``). A movable joint with an empty range is merged as fixed.
- Meshes: per node, the first non-empty list among ``objs`` (textured),
  ``glb``/``glbs``, ``plys`` (override with ``mesh_priority``); all meshes of a part
  (its own and its merged fixed descendants') are concatenated. A mesh path must lead
  to a file inside the object.json's folder (``../x.obj`` or an absolute path elsewhere
  is refused, as for PartNet-Mobility: :func:`~asset_pipeline.importers.source_format.mesh_in_folder`).
- Degenerate meshes (:func:`~asset_pipeline.importers.source_format.check_part_mesh`, as for
  PartNet-Mobility): a part whose meshes have non-finite vertices or no face of non-zero
  area, or that cannot be closed, is refused naming the node and its files; one that is
  flat, has far too few faces, mostly zero-area faces or is badly non-manifold is
  imported with a warning naming them (``provenance["warnings"]``, logged, and in
  :func:`~asset_pipeline.importers.import_path`'s result).
- Names: parts are named ``<semantic>_<k>`` (``door_0``, ``drawer_1``) in node order;
  the semantic is the node's ``name`` (door, drawer, lid, knob, ...).
- Category: ``meta.obj_cat`` mapped with :data:`CATEGORY_MAP` (e.g.
  StorageFurniture -> cabinet, Table -> desk), else "unknown".
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from asset_pipeline.importers.source_format import (
    CATEGORY_MAP,
    ImportFormatError,
    check_part_mesh,
    mesh_in_folder,
    sanitize_id,
)
from generator.articulated import BASE, ArticulatedObject, Joint, ObjectModelError, Part

log = logging.getLogger(__name__)


TREE_KEYS = ("diffuse_tree", "arti_tree")
MESH_KEYS = ("objs", "glb", "glbs", "plys")

#: Source (x right, y up, z front) -> ours (x front, y right-of-viewer, z up).
Y_UP_TO_OURS = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


@dataclass
class ImportOptions:
    """How :func:`import_path` reads a source; defaults follow the SINGAPO convention."""

    up: str = "y"
    mesh_priority: Sequence[str] = MESH_KEYS
    continuous: str = "revolute"  # "revolute" | "fixed" | "error"
    screw: str = "error"  # "error" | "prismatic" | "fixed"
    category: str | None = None  # override the category of every imported object
    overwrite: bool = False
    material: str = "wood"

    def __post_init__(self) -> None:
        if self.up not in ("y", "z"):
            raise ValueError(f"up must be 'y' or 'z', got {self.up!r}")
        if self.continuous not in ("revolute", "fixed", "error"):
            raise ValueError(
                f"continuous must be revolute, fixed or error, got {self.continuous!r}"
            )
        if self.screw not in ("error", "prismatic", "fixed"):
            raise ValueError(f"screw must be error, prismatic or fixed, got {self.screw!r}")
        bad = [k for k in self.mesh_priority if k not in MESH_KEYS]
        if bad:
            raise ValueError(f"mesh_priority: unknown keys {bad}; known: {MESH_KEYS}")


# --------------------------------------------------------------------------- discovery


def tree_of(data: Any) -> list[Any] | None:
    if isinstance(data, dict):
        for k in TREE_KEYS:
            if isinstance(data.get(k), list):
                return data[k]
    return None


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as e:
        raise ImportFormatError(f"{path}: not found") from e
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ImportFormatError(f"{path}: not readable JSON: {e}") from e


@dataclass
class _Node:
    id: int
    parent: int | None
    name: str
    type: str
    origin: np.ndarray
    direction: np.ndarray
    range: tuple[float, float]
    meshes: list[Path]
    where: str
    children: list[int] = field(default_factory=list)


def _vec3(v: Any, src: Path, where: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=float).reshape(-1)
    except (TypeError, ValueError) as e:
        raise ImportFormatError(f"{src}: {where}: must be 3 numbers, got {v!r}") from e
    if a.shape != (3,) or not np.isfinite(a).all():
        raise ImportFormatError(f"{src}: {where}: must be 3 finite numbers, got {v!r}")
    return a


def _parse_node(raw: Any, i: int, src: Path, opts: ImportOptions) -> _Node:
    where = f"diffuse_tree[{i}]"
    if not isinstance(raw, dict):
        raise ImportFormatError(f"{src}: {where}: must be an object")
    if "id" not in raw:
        raise ImportFormatError(f"{src}: {where}.id: missing")
    nid = raw["id"]
    if isinstance(nid, bool) or not isinstance(nid, int):
        raise ImportFormatError(f"{src}: {where}.id: must be an integer, got {nid!r}")
    parent = raw.get("parent", -1)
    if parent is not None and (isinstance(parent, bool) or not isinstance(parent, int)):
        raise ImportFormatError(f"{src}: {where}.parent: must be an integer or -1, got {parent!r}")
    parent = None if parent is None or parent < 0 else parent
    name = raw.get("name", "part")
    if not isinstance(name, str) or not name.strip():
        raise ImportFormatError(f"{src}: {where}.name: must be a non-empty string, got {name!r}")
    joint = raw.get("joint") or {}
    if not isinstance(joint, dict):
        raise ImportFormatError(f"{src}: {where}.joint: must be an object")
    jtype = str(joint.get("type", "fixed")).lower()
    axis = joint.get("axis") or {}
    if not isinstance(axis, dict):
        raise ImportFormatError(
            f"{src}: {where}.joint.axis: must be an object with origin and direction"
        )
    origin = _vec3(axis.get("origin", [0, 0, 0]), src, f"{where}.joint.axis.origin")
    direction = _vec3(axis.get("direction", [0, 0, 0]), src, f"{where}.joint.axis.direction")
    rng = joint.get("range", [0.0, 0.0])
    if isinstance(rng, (int, float)) and not isinstance(rng, bool):
        rng = [0.0, float(rng)]
    try:
        lo, hi = (float(x) for x in rng)
    except (TypeError, ValueError) as e:
        raise ImportFormatError(
            f"{src}: {where}.joint.range: must be [lower, upper], got {rng!r}"
        ) from e
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ImportFormatError(f"{src}: {where}.joint.range: must be finite, got {rng!r}")
    if jtype not in ("fixed", "revolute", "prismatic", "continuous", "screw"):
        raise ImportFormatError(
            f"{src}: {where}.joint.type: {jtype!r} is not supported "
            "(fixed, revolute, prismatic, continuous, screw)"
        )
    meshes: list[Path] = []
    for key in opts.mesh_priority:
        files = raw.get(key)
        if not files:
            continue
        if isinstance(files, str):
            files = [files]
        if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
            raise ImportFormatError(f"{src}: {where}.{key}: must be a list of file paths")
        for f in files:
            meshes.append(mesh_in_folder(src.parent, f, src, f"{where}.{key}"))
        break
    return _Node(nid, parent, name.strip(), jtype, origin, direction, (lo, hi), meshes, where)


def _load_mesh(path: Path, src: Path, where: str) -> trimesh.Trimesh:
    try:
        m = trimesh.load(str(path), force="mesh", process=False)
    except Exception as e:  # trimesh raises many types on corrupt files
        raise ImportFormatError(f"{src}: {where}: cannot read mesh {path}: {e}") from e
    if not isinstance(m, trimesh.Trimesh) or len(m.faces) == 0:
        raise ImportFormatError(f"{src}: {where}: mesh {path} holds no triangles")
    if not np.isfinite(m.vertices).all():
        raise ImportFormatError(
            f"{src}: {where}: mesh {path} has NaN or infinite vertex coordinates; repair or "
            "replace that mesh"
        )
    return m


def _concatenate(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    if len(meshes) == 1:
        return meshes[0]
    try:
        return trimesh.util.concatenate(meshes)
    except Exception as e:  # mixed visuals (textures + colours) may not merge
        log.warning("could not merge part textures (%s); using vertex colours", e)
        plain = []
        for m in meshes:
            m = m.copy()
            m.visual = m.visual.to_color()
            plain.append(m)
        return trimesh.util.concatenate(plain)


# --------------------------------------------------------------------------- conversion


def convert_tree(src: str | Path, options: ImportOptions | None = None) -> ArticulatedObject:
    """Read one ``diffuse_tree`` object.json into an :class:`ArticulatedObject`.

    See the module docstring for the conventions and the conversion.
    """
    opts = options or ImportOptions()
    src = Path(src)
    data = _read_json(src)
    tree = tree_of(data)
    if tree is None:
        raise ImportFormatError(
            f"{src}: diffuse_tree: missing (supported: CAGE/SINGAPO/PAct object.json)"
        )
    if not tree:
        raise ImportFormatError(f"{src}: diffuse_tree: empty")
    nodes: dict[int, _Node] = {}
    for i, raw in enumerate(tree):
        n = _parse_node(raw, i, src, opts)
        if n.id in nodes:
            raise ImportFormatError(f"{src}: {n.where}.id: id {n.id} is used twice")
        nodes[n.id] = n
    roots = [n.id for n in nodes.values() if n.parent is None]
    if len(roots) != 1:
        raise ImportFormatError(
            f"{src}: diffuse_tree: exactly one root node (parent -1) is required, found ids {roots}"
        )
    for n in nodes.values():
        if n.parent is not None:
            if n.parent not in nodes:
                raise ImportFormatError(f"{src}: {n.where}.parent: no node with id {n.parent}")
            nodes[n.parent].children.append(n.id)
    root = roots[0]

    # Which nodes become movable parts: map joint types through the options.
    kind: dict[int, str] = {}  # node id -> "fixed" | "revolute" | "prismatic"
    for n in nodes.values():
        t = n.type
        if n.id == root:
            t = "fixed"
        elif t == "continuous":
            if opts.continuous == "error":
                raise ImportFormatError(
                    f"{src}: {n.where}.joint.type: 'continuous' joints are refused "
                    "(continuous='error'); use continuous='revolute' or 'fixed'"
                )
            t = "revolute" if opts.continuous == "revolute" else "fixed"
        elif t == "screw":
            if opts.screw == "error":
                raise ImportFormatError(
                    f"{src}: {n.where}.joint.type: 'screw' joints (coupled rotation and translation) "
                    "are not supported by the object model; import with screw='prismatic' to keep "
                    "the translation or screw='fixed' to freeze the part"
                )
            t = opts.screw
        if t != "fixed" and np.linalg.norm(n.direction) < 1e-9:
            raise ImportFormatError(
                f"{src}: {n.where}.joint.axis.direction: zero vector for a {t} joint"
            )
        if t != "fixed" and n.type != "continuous" and n.range[0] == n.range[1]:
            log.warning("%s: %s (%s) has an empty range; merged as fixed", src, n.where, n.name)
            t = "fixed"
        kind[n.id] = t

    # Owner of each node: itself when movable, else its nearest movable ancestor (or root).
    def owner(nid: int) -> int:
        while nid != root and kind[nid] == "fixed":
            p = nodes[nid].parent
            assert p is not None
            nid = p
        return nid

    def check_acyclic(nid: int) -> None:
        seen = set()
        while nid is not None:
            if nid in seen:
                raise ImportFormatError(
                    f"{src}: diffuse_tree: the parent links form a cycle at id {nid}"
                )
            seen.add(nid)
            nid = nodes[nid].parent  # type: ignore[assignment]

    for nid in nodes:
        check_acyclic(nid)

    order = sorted(nodes)  # stable node order
    groups: dict[int, list[trimesh.Trimesh]] = {}
    sources: dict[int, list[Path]] = {}  # the mesh files of each part
    for nid in order:
        n = nodes[nid]
        meshes = [_load_mesh(p, src, n.where) for p in n.meshes]
        groups.setdefault(owner(nid), []).extend(meshes)
        sources.setdefault(owner(nid), []).extend(n.meshes)
        if kind[nid] != "fixed" and nid != root:
            anc = nodes[nid].parent
            assert anc is not None
            if owner(anc) != root:
                log.warning(
                    "%s: %s (%s) hangs off movable node %d; re-rooted onto base "
                    "(it will not follow its parent's motion)",
                    src,
                    n.where,
                    n.name,
                    owner(anc),
                )

    R = Y_UP_TO_OURS if opts.up == "y" else np.eye(3)
    T = np.eye(4)
    T[:3, :3] = R

    movable_ids = [nid for nid in order if nid != root and kind[nid] != "fixed"]
    for nid in [root, *movable_ids]:
        if not groups.get(nid):
            n = nodes[nid]
            raise ImportFormatError(
                f"{src}: {n.where} ({n.name}): no mesh (none of {list(opts.mesh_priority)} lists a file)"
            )

    names, semantics = {root: BASE}, {root: "base"}
    counters: dict[str, int] = {}
    for nid in movable_ids:
        semantic = sanitize_id(nodes[nid].name.lower()).replace(".", "_").replace("-", "_")
        semantics[nid] = semantic or "part"
        k = counters.get(semantics[nid], 0)
        counters[semantics[nid]] = k + 1
        names[nid] = f"{semantics[nid]}_{k}"

    part_meshes: dict[int, trimesh.Trimesh] = {}
    warnings: list[str] = []
    for nid in [root, *movable_ids]:
        m = _concatenate(groups[nid]).copy()
        part = f"{names[nid]} ({nodes[nid].where})"
        files = [p.relative_to(src.parent.resolve()).as_posix() for p in sources[nid]]
        warnings += check_part_mesh(m.vertices, m.faces, part, files, src)
        m.apply_transform(T)
        part_meshes[nid] = m
    for w in warnings:
        log.warning("%s: %s", src, w)

    # Normalize into the unit cube of our axes (rest pose).
    allv = np.concatenate([m.vertices for m in part_meshes.values()])
    lo, hi = allv.min(0), allv.max(0)
    centre = (lo + hi) / 2.0
    s = float((hi - lo).max())
    if not s > 0:
        raise ImportFormatError(f"{src}: all meshes together have zero extent")
    N = np.eye(4)
    N[:3, :3] /= s
    N[:3, 3] = -centre / s
    for m in part_meshes.values():
        m.apply_transform(N)

    parts = [
        Part(name=BASE, semantic="base", mesh=part_meshes[root], joint=None, material=opts.material)
    ]
    for nid in movable_ids:
        n = nodes[nid]
        t = kind[nid]
        axis = R @ (n.direction / np.linalg.norm(n.direction))
        origin = (R @ n.origin - centre) / s
        if n.type == "continuous":
            lower, upper = 0.0, 2.0 * math.pi
        else:
            lower, upper = sorted(n.range)
            if upper <= 0.0 and lower < 0.0:  # opens toward negative values: flip
                axis, lower, upper = -axis, -upper, -lower
            if t == "revolute":
                lower, upper = math.radians(lower), math.radians(upper)
            else:
                lower, upper = lower / s, upper / s
        parts.append(
            Part(
                name=names[nid],
                semantic=semantics[nid],
                mesh=part_meshes[nid],
                joint=Joint(
                    type=t,
                    origin=origin,
                    axis=axis / np.linalg.norm(axis),
                    lower=lower,
                    upper=upper,
                    parent=BASE,
                ),
                material=opts.material,
            )
        )

    meta = data.get("meta", {}) if isinstance(data, dict) else {}
    raw_cat = (
        str(meta.get("obj_cat", "") or meta.get("class_id", "") or "")
        if isinstance(meta, dict)
        else ""
    )
    category = opts.category or CATEGORY_MAP.get(raw_cat.lower().replace(" ", ""), "unknown")
    obj = ArticulatedObject(
        parts=parts,
        category=category,
        scale=None,
        provenance={
            "importer": "diffuse_tree",
            "source": str(src.resolve()),
            "source_category": raw_cat or None,
            "source_up": opts.up,
            "normalization": [*map(float, centre), s],
            "meshes": {
                names[nid]: [p.relative_to(src.parent.resolve()).as_posix() for p in sources[nid]]
                for nid in [root, *movable_ids]
            },
            "warnings": warnings,
        },
    )
    try:
        obj.validate(str(src))
    except ObjectModelError as e:
        raise ImportFormatError(str(e)) from e
    return obj


def object_id(src: Path) -> str:
    """An asset id from the object.json's folder name (``a@b@01`` -> ``a_b_01``)."""
    return sanitize_id(src.parent.name if src.name == "object.json" else src.stem)
