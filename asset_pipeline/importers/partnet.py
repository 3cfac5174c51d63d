"""Import PartNet-Mobility objects (``mobility.urdf`` + ``textured_objs/``) as bundles.

A PartNet-Mobility object folder holds ``mobility.urdf`` (links with several
``<visual>`` OBJ meshes each, joints), ``textured_objs/*.obj`` with their ``.mtl``
files and texture images, and annotation files: ``semantics.txt`` (``link_k
joint_kind semantic`` per line), ``mobility_v2.json`` (per joint: name, kind, the
PartNet part ids, axis and limits in the raw mesh frame), ``result.json`` (the
PartNet part hierarchy; leaves list their OBJ stems) and ``meta.json``
(``model_cat``). Only ``mobility.urdf`` and ``textured_objs/`` are required; the
others sharpen the conversion and their absence is recorded as a warning.
:func:`find_objects` finds object folders (a folder holding both) at or under a
path; :func:`convert_object` reads one into an :class:`ArticulatedObject`;
:func:`import_objects` writes one bundle per object and goes on past bad objects.

Conversion rules
----------------

Frame. The URDF is evaluated at joint value 0 (forward kinematics of every
``<origin xyz rpy>``, visual origins and ``<mesh scale>``); its world frame is the
frame of the root link ``base``. PartNet-Mobility's root joint carries
``rpy = (pi/2, 0, -pi/2)``, which turns the raw y-up meshes z-up with the object's
front facing -x (raw ``(x, y, z) -> (-z, -x, y)``); a URDF without any rotation on
the root chain is taken as raw y-up and gets that rotation (warning). The front
is then found from the articulation, not assumed: every kept door, drawer and lid
votes with the horizontal direction in which it opens (a drawer's sliding
direction, a door's centroid motion over the first 45 degrees of opening), snapped
to +-x / +-y; the yaw (a multiple of 90 degrees about z) that turns the winning
direction to +x is applied. Without a vote (no kept part, or only lids that open
upward) the PartNet default is used: 180 degrees, i.e. raw ``(x, y, z) -> (z, x,
y)``, the rotation ``asset_pipeline.importers`` applies to SINGAPO data. On 47
objects of PartNet-Mobility (GenSim2, kitchen-worlds, SAPIEN copies) every voting
object agreed with that default.
``provenance["frame"]`` records the 3x3 rotation from the URDF world frame to
ours, the yaw and whether it was voted or defaulted.

Parts. The root link and every link fixed to it form ``base``. A link becomes a
movable part only when it is a door, drawer or lid: its semantic (from
``semantics.txt`` by link name, else by the ``mobility_v2.json`` entry whose parts
hold the link's OBJ files, else the v2 name, else the link name) contains
``door``, ``drawer`` or ``lid`` (``rotation_door``, ``cabinet_door``,
``drawer_box``, ...), its joint is revolute, prismatic or continuous, its range is
at least 10 degrees / 2% of the object's largest extent and its size at least 3%
of that extent. Everything else with a joint (knobs, buttons, wheels, casters,
turntables, trays, shelves, drop leaves, handles with their own joints, ...) is
merged as fixed, at its modelled pose, into the part it hangs on (a knob on an
oven stays on the oven's body, a handle link on a door goes with the door); fixed
links merge into their nearest kept ancestor. A kept part under another kept part
is re-rooted onto ``base`` with its joint unchanged (exact when closed; it no
longer follows its parent; warning). A URDF joint that is ``fixed`` although
``mobility_v2.json`` gives that door/drawer/lid a hinge or slider with limits
(GenSim2 froze some) is restored from the v2 axis and limits (warning; v2
coordinates are in the raw mesh frame, the frame of the link fixed to ``base``).
Links whose name contains ``collision`` (kitchen-worlds collision proxies that
duplicate the body) contribute no visual geometry. Parts are named
``<door|drawer|lid>_<k>``, numbered top to bottom then left to right (descending z,
then ascending y of the part's bounding-box centre when closed), like the
procedural factory.

Joints. Meshes are modelled at joint value 0, which is not always closed (a
drawer modelled 0.19 out with the range ``[-0.19, 0.2]``, a washing-machine door
modelled open with ``[-178, -70]`` degrees, but also a drawer modelled closed with
``[-0.39, 0.40]``, whose lower limit would push it through the back). The closed
value is the candidate among the two limits and 0 (when inside the range) at
which the largest share of the part's surface area lies inside the base's
bounding box (grown by 2% of the object size); ties go to 0, then to the limit
nearer 0. The part's geometry is moved to that closed pose and the joint is
rewritten relative to it: ``lower = 0`` (closed), ``upper`` = the distance to the
limit on the opening side (when 0 is closed and inside the range, the side that
leaves the base more), the axis flipped when that side is negative, so positive
motion opens outward as the object model requires. Revolute limits are in
radians, prismatic limits scale with the normalization. A continuous door becomes
revolute over [0, pi/2] (warning); every other continuous joint is merged. A
"door" whose centre rises more than it moves sideways when it opens (the lid of
a top loader) is named a lid.

Geometry. A part's mesh is all of its OBJ meshes (its own links' and the merged
links'), with the URDF transforms applied, in the object frame, concatenated into
one ``trimesh.Trimesh``; nothing is remeshed, closed or cleaned (open shells,
internal faces and many disconnected pieces are kept; watertightness and
collision geometry are the build's job). Textures: all texture images and flat
material colours of a part are packed into one atlas (at most ``atlas_size``
pixels a side, 2048 by default; images are scaled down evenly to fit) and the
UVs remapped; UVs that tile (span several texture repeats) get the image
repeated in the atlas (up to 8 repeats a side; beyond, each face is moved by
whole repeats and clamped), so tiling survives. The atlas is stored as JPEG in the
part's GLB. A part without any texture keeps its material colours (``Kd``) as
vertex colours; a texture image that cannot be found or read falls back to the
material colour. Transparency is dropped.

Handles. A kept part's handle comes from its handle node, else from its geometry,
else from an added grip; ``provenance["handles"][part]`` records which (``source``
``node``, ``geometry`` or ``added``, ``kind`` and what was measured or placed; None
without a handle).

Handle nodes: ``result.json`` nodes named ``handle`` (and URDF visuals named
``handle-<id>``, links named ``*handle*`` for kitchen-worlds edits) inside a kept
part give the modelled handle's meshes. Per handle node: the opening normal ``n``
(a drawer's axis; for a door or lid the normal of its panel, i.e. the thinnest
side of its closed bounding box, oriented the way the panel moves when it starts to
open), the outermost slab of the handle's surface along ``n`` (its outer 35%: the
bar, not the standoffs; points sampled on the surface, so a knob's rim counts)
whose bounding-box centre is the grasp point; the axis is the long direction of
the handle across ``n`` (principal axis) and the kind ``bar`` when the handle is at
least twice as long as wide, else ``knob`` (axis: along the hinge of a door,
horizontal on a drawer). With several handle nodes the one nearest the part's
centre is used.

Handles on the geometry (no handle node; a bar modelled inside the door's mesh).
Lengths are in metres at the scale the build will give the object (``height``, else
the category's default height, ``asset_pipeline.geometry.metric.DEFAULT_HEIGHTS``). The outer
face plane is the outermost offset along ``n`` (2 mm bins with their neighbours)
whose triangles facing ``n`` (normal within 25 degrees of +-n) hold at least 10% of
the part's bounding-box area across ``n`` and span at least 60% of its extent both
ways (a handle plate running the door's width is not its face); without one, the
offset beyond which 15% of that facing area lies. The surface standing more than
8 mm out of that plane (sampled about 2 mm apart) is clustered into blobs (points
connected through 1 cm voxels). A blob is a handle when it holds at least 2 cm2 of
surface, stands at least 12 mm out, is at least 15 mm long and its outer 35% is at
most 6 cm wide across its long direction (the pinch of a parallel gripper); on a door
or lid it must also lie at least 35% of the way from the hinge to the farthest corner
of the face (not a hinge knuckle). Grasp point, axis and kind as for a handle node
(the blob's outer 35%, principal axis, ``bar`` at least twice as long as wide). Of
several blobs a door or lid takes the one farthest from its hinge, a drawer the one
nearest the centre of its face. On the 47 test objects this finds the bar handles of
both ovens that have no handle node; with the handle nodes ignored it finds 49 of
the 54 modelled handles within 3 cm (4 missed: three measured wider than 6 cm, a knob
6 mm proud; one door gives a thin trim strip 13 cm from its handle).

Added grips (``add_handles``, the default; ``pact import --no-add-handles`` keeps the
artist's meshes and leaves ``handle = None``, for which the build computes a fallback
point of kind ``none``). A part with neither gets a bar grip added to its mesh: a
16 mm square bar, 12 cm long (at most 60% of the face's extent along it, at least
4 cm), its axis
33 mm in front of the outer face plane, on two 12 mm square standoffs that reach
2 mm into the surface under them. A door or lid gets it parallel to its hinge, 5 cm
in from the free edge (at most a quarter of the face's width), at the middle of the
face's extent along the hinge; a drawer gets it horizontal, centred on its front. A
standoff must land on the part's surface at most 3 cm behind the face plane (not in
a window or a hole): otherwise the grip moves nearer the free edge (4, 3, 2 cm) or
farther in, 1 cm at a time (a drawer's off centre), then along the bar by up to
9 cm in 3 cm steps; where nothing fits, the standoffs end at the face plane. The grip has the
colour of the piece with the most area on the outer face plane (a textured piece's
mean texture colour, as a flat swatch in the part's atlas); the rest of the part's
mesh and textures are unchanged. Its handle is the bar's centre, kind ``bar``. Each
added grip is also a warning (``drawer_0: no handle modelled; added a 12 cm bar grip
centred on the front, horizontal, grasp point [...] (object frame)``), which ``pact
import`` prints. Being part of the part's mesh, the grip gets the part's collision
boxes at build time. A part without any triangle facing ``n`` gets neither.

Category and material. ``meta.json`` ``model_cat`` maps through
``asset_pipeline.importers.CATEGORY_MAP`` (StorageFurniture -> cabinet, Table ->
desk, Microwave, Oven, Refrigerator, Dishwasher, WashingMachine), else
``unknown``; ``category`` in the options overrides it. Material: ``wood`` for
cabinets, desks and unknown objects, ``metal`` for appliances, ``glass`` for a
microwave or oven door more than half of whose surface is PartNet ``glass`` parts.

Scale. The object is normalized like the other importers: rest (closed) bounding
box of the source meshes centred at the origin, largest extent 1 (an added grip may
stand a few centimetres out of it), ``scale = None``, so the pipeline
applies the category's default height at build time. With ``height`` (metres,
the closed object's height) the bundle gets ``scale = height / normalized height``
instead: ``asset_pipeline.geometry.metric.metric_factor`` uses a known scale as is (and
ignores a later ``pact build --height``), so the built asset is ``height`` tall,
exactly as ``pact build --height`` would make it. ``provenance["normalization"] =
[cx, cy, cz, s]`` maps back: ``x_rotated = x * s + c`` where ``x_rotated =
R @ x_urdf`` (``R`` = ``provenance["frame"]["rotation"]``).

Degenerate meshes. Each part's meshes together are checked before anything is
written (:func:`check_part_mesh`, shared with the ``diffuse_tree`` importer): refused
naming the part and its mesh files when they have non-finite vertices, no face of
non-zero area, or doubts and cannot be closed; imported with a warning naming them
when flat, with far too few faces, mostly zero-area faces or badly non-manifold.

Provenance also records the source folder, the PartNet id, ``model_cat``, the
URDF links merged into each part and its mesh files (``meshes``), each part's closed
value in source units, each part's handle source and the warnings.
"""

from __future__ import annotations

import io
import json
import logging
import math
import os
import re
import shutil
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
import trimesh.transformations as tf
from PIL import Image
from scipy import ndimage
from trimesh.path import packing

from asset_pipeline.assets.layout import AssetFormatError
from asset_pipeline.assets.urdf import parse_robot
from asset_pipeline.geometry.metric import DEFAULT_HEIGHTS
from asset_pipeline.importers.source_format import (
    CATEGORY_MAP,
    ImportFormatError,
    check_part_mesh,
    mesh_in_folder,
    sanitize_id,
)
from generator.articulated import BASE, ArticulatedObject, Handle, Joint, ObjectModelError, Part
from generator.bundle import is_bundle, save_bundle

log = logging.getLogger(__name__)

URDF_NAME = "mobility.urdf"
MESH_DIR = "textured_objs"

#: The PartNet-Mobility root joint rotation: raw y-up meshes -> z-up, front -x.
STANDARD_ROOT_RPY = (math.pi / 2, 0.0, -math.pi / 2)
#: Yaw (degrees about +z) applied when no part votes for the front direction.
DEFAULT_YAW_DEG = 180
#: Semantic words of the parts kept movable, in priority order.
KEPT_SEMANTICS = ("door", "drawer", "lid")
APPLIANCES = ("microwave", "oven", "dishwasher", "refrigerator", "washing_machine")
#: Categories whose doors are glass when most of their surface is PartNet ``glass`` parts.
GLASS_DOOR_CATEGORIES = ("microwave", "oven")
HANDLE_NODE_NAMES = ("handle",)


class PartnetFormatError(ImportFormatError):
    """A PartNet-Mobility object is malformed; the message names the file and what is wrong."""


@dataclass
class PartnetOptions:
    """How :func:`convert_object` reads an object (defaults: the documented rules)."""

    category: str | None = None  # override the mapped model_cat
    height: float | None = None  # metres, closed height; sets ``scale`` (else None)
    overwrite: bool = False
    atlas_size: int = 2048  # largest atlas side in pixels
    restore_fixed: bool = True  # restore doors/drawers/lids frozen as fixed from mobility_v2.json
    min_revolute_deg: float = 10.0
    min_prismatic_frac: float = 0.02  # of the object's largest extent
    min_part_frac: float = 0.03  # of the object's largest extent (part bounding-box diagonal)
    jpeg_quality: int = 90
    #: Import an object with no door, drawer or lid as one static body (else it fails:
    #: nothing to articulate).
    keep_static: bool = False
    #: Give a movable part with neither a handle node nor a handle on its geometry an
    #: added bar grip (False: the artist's meshes stay untouched, the handle stays None).
    add_handles: bool = True

    def __post_init__(self) -> None:
        if self.height is not None and not (math.isfinite(self.height) and 0 < self.height <= 10):
            raise ValueError(f"height must be a number of metres in (0, 10], got {self.height}")
        if not 16 <= int(self.atlas_size) <= 16384:
            raise ValueError(f"atlas_size must be 16..16384 px, got {self.atlas_size}")


@dataclass
class ImportFailure:
    """An object that could not be imported: its folder and why (file and problem)."""

    source: Path
    message: str

    def __str__(self) -> str:
        return self.message


class ImportResult(list):
    """The bundle folders written (a list of Paths), with ``failures`` and ``warnings``."""

    def __init__(self, written: Iterable[Path] = (), failures: Iterable[ImportFailure] = ()):
        super().__init__(written)
        self.failures: list[ImportFailure] = list(failures)
        self.warnings: list[str] = []
        self.seconds: dict[str, float] = {}


# --------------------------------------------------------------------------- discovery


def is_partnet_folder(path: str | Path) -> bool:
    """True when ``path`` is a folder holding ``mobility.urdf`` and ``textured_objs/``."""
    p = Path(path)
    return (p / URDF_NAME).is_file() and (p / MESH_DIR).is_dir()


def find_objects(path: str | Path) -> list[Path]:
    """PartNet-Mobility object folders at or under ``path`` (recursive, sorted).

    ``path`` may be an object folder, its ``mobility.urdf``, or any folder above
    object folders. Hidden folders are skipped and an object folder is not searched
    further. Raises PartnetFormatError when ``path`` does not exist.
    """
    p = Path(path)
    if p.is_file() and p.name == URDF_NAME:
        p = p.parent
    if not p.exists():
        raise PartnetFormatError(f"{p}: no such file or folder")
    if not p.is_dir():
        return []
    if is_partnet_folder(p):
        return [p]
    found = []
    for root, dirs, _files in os.walk(p):
        r = Path(root)
        keep = []
        for d in sorted(dirs):
            if d.startswith("."):
                continue
            if is_partnet_folder(r / d):
                found.append(r / d)
            else:
                keep.append(d)
        dirs[:] = keep
    return sorted(found)


# --------------------------------------------------------------------------- URDF


@dataclass
class _Visual:
    file: Path | None  # mesh file; None for a primitive
    primitive: trimesh.Trimesh | None
    origin: np.ndarray  # 4x4 in the link frame (scale applied first)
    scale: np.ndarray
    name: str
    index: int


@dataclass
class _Link:
    name: str
    visuals: list[_Visual] = field(default_factory=list)


@dataclass
class _UJoint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray  # 4x4 in the parent link frame
    axis: np.ndarray  # in the joint frame
    lower: float
    upper: float


@dataclass
class _Urdf:
    path: Path
    links: dict[str, _Link]
    joints: dict[str, _UJoint]  # by child link
    root: str

    def children(self, link: str) -> list[str]:
        return sorted(c for c, j in self.joints.items() if j.parent == link)


def _mesh_path(folder: Path, filename: str, where: str, src: Path) -> Path:
    name = filename.strip()
    if name.startswith("package://"):
        name = name[len("package://") :].split("/", 1)[-1]
    if name.startswith("file://"):
        name = name[len("file://") :]
    return mesh_in_folder(folder, name, src, where, PartnetFormatError, given=filename)


def _geometry(
    geometry: Any, folder: Path, where: str, src: Path
) -> tuple[Path | None, trimesh.Trimesh | None, np.ndarray]:
    """(mesh file, primitive mesh, scale) of a yourdfpy ``Geometry``."""
    if geometry is None:
        raise PartnetFormatError(f"{src}: {where}: <geometry> missing or empty")
    if geometry.mesh is not None:
        scale = np.ones(3) if geometry.mesh.scale is None else np.asarray(geometry.mesh.scale)
        return _mesh_path(folder, geometry.mesh.filename, where, src), None, scale * np.ones(3)
    if geometry.box is not None:
        return None, trimesh.creation.box(extents=np.asarray(geometry.box.size)), np.ones(3)
    if geometry.cylinder is not None:
        c = geometry.cylinder
        return None, trimesh.creation.cylinder(radius=c.radius, height=c.length), np.ones(3)
    if geometry.sphere is not None:
        return (
            None,
            trimesh.creation.icosphere(radius=geometry.sphere.radius, subdivisions=2),
            np.ones(3),
        )
    raise PartnetFormatError(f"{src}: {where}: unsupported geometry")


def parse_urdf(path: Path) -> _Urdf:
    """Read ``mobility.urdf`` (links, visuals, joints) with the project's URDF reader
    (:func:`asset_pipeline.asset_io.parse_robot`); errors name the file and element."""
    try:
        robot = parse_robot(path, "not found")
    except AssetFormatError as e:
        raise PartnetFormatError(str(e)) from e
    folder = path.parent
    links: dict[str, _Link] = {}
    for lk in robot.links:
        if lk.name in links:
            raise PartnetFormatError(f"{path}: link {lk.name!r} is defined twice")
        link = _Link(lk.name)
        for i, vis in enumerate(lk.visuals):
            where = f"link {lk.name!r} <visual> {i}"
            file, prim, scale = _geometry(vis.geometry, folder, where, path)
            origin = np.eye(4) if vis.origin is None else np.asarray(vis.origin, dtype=float)
            link.visuals.append(_Visual(file, prim, origin, scale, vis.name or "", i))
        links[lk.name] = link
    if not links:
        raise PartnetFormatError(f"{path}: no <link>")
    joints: dict[str, _UJoint] = {}
    for jt in robot.joints:
        where = f"joint {jt.name!r}"
        jtype = (jt.type or "").lower()
        if jtype not in ("fixed", "revolute", "prismatic", "continuous", "floating", "planar"):
            raise PartnetFormatError(f"{path}: {where}: unknown type {jt.type!r}")
        for role, ln in (("parent", jt.parent), ("child", jt.child)):
            if ln not in links:
                raise PartnetFormatError(f"{path}: {where}: {role} link {ln!r} is not defined")
        if jt.child in joints:
            raise PartnetFormatError(
                f"{path}: {where}: link {jt.child!r} is already the child of joint "
                f"{joints[jt.child].name!r}"
            )
        axis = np.array([1.0, 0.0, 0.0]) if jt.axis is None else np.asarray(jt.axis, dtype=float)
        lower = upper = 0.0
        if jtype in ("revolute", "prismatic"):
            if jt.limit is None:
                raise PartnetFormatError(f"{path}: {where}: a {jtype} joint needs <limit>")
            lower = float(jt.limit.lower or 0.0)
            upper = float(jt.limit.upper or 0.0)
        if jtype in ("revolute", "prismatic", "continuous") and np.linalg.norm(axis) < 1e-9:
            raise PartnetFormatError(f"{path}: {where}: <axis> is the zero vector")
        if jtype in ("floating", "planar"):
            log.warning("%s: %s: %s joint treated as fixed", path, where, jtype)
            jtype = "fixed"
        origin = np.eye(4) if jt.origin is None else np.asarray(jt.origin, dtype=float)
        joints[jt.child] = _UJoint(
            jt.name,
            jtype,
            jt.parent,
            jt.child,
            origin,
            axis / max(np.linalg.norm(axis), 1e-12),
            lower,
            upper,
        )
    roots = [n for n in links if n not in joints]
    if len(roots) != 1:
        raise PartnetFormatError(
            f"{path}: exactly one root link (not the child of a joint) is required, found {roots}"
        )
    for start in links:  # cycles
        seen, n = set(), start
        while n in joints:
            if n in seen:
                raise PartnetFormatError(f"{path}: the joints form a cycle through link {n!r}")
            seen.add(n)
            n = joints[n].parent
    return _Urdf(path, links, joints, roots[0])


def _world(urdf: _Urdf) -> dict[str, np.ndarray]:
    """4x4 pose of every link in the URDF world (root link) frame at joint value 0."""
    W: dict[str, np.ndarray] = {}

    def w(n: str) -> np.ndarray:
        if n not in W:
            j = urdf.joints.get(n)
            W[n] = np.eye(4) if j is None else w(j.parent) @ j.origin
        return W[n]

    for n in urdf.links:
        w(n)
    return W


# --------------------------------------------------------------------------- annotations


@dataclass
class _Annotations:
    semantics: dict[str, tuple[str, str]]  # link name -> (joint kind, semantic)
    v2: list[dict[str, Any]]
    stem_to_v2: dict[str, int]
    handle_nodes: dict[str, int]  # OBJ stem -> handle node id
    glass_stems: set[str]
    meta: dict[str, Any]
    warnings: list[str]


def _read_optional_json(path: Path, warnings: list[str]) -> Any:
    if not path.is_file():
        warnings.append(f"{path.name} missing")
        return None
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise PartnetFormatError(f"{path}: not readable JSON: {e}") from e


def _read_annotations(folder: Path) -> _Annotations:
    warnings: list[str] = []
    sem: dict[str, tuple[str, str]] = {}
    sp = folder / "semantics.txt"
    if sp.is_file():
        try:
            lines = sp.read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as e:
            raise PartnetFormatError(f"{sp}: cannot read: {e}") from e
        for i, line in enumerate(lines, 1):
            f = line.split()
            if not f:
                continue
            if len(f) != 3:
                raise PartnetFormatError(
                    f"{sp}: line {i}: expected 'link_name joint_kind semantic', got {line.strip()!r}"
                )
            sem[f[0]] = (f[1].lower(), f[2].lower())
    else:
        warnings.append("semantics.txt missing")

    v2 = _read_optional_json(folder / "mobility_v2.json", warnings)
    if v2 is not None and not (isinstance(v2, list) and all(isinstance(e, dict) for e in v2)):
        raise PartnetFormatError(f"{folder / 'mobility_v2.json'}: must be a list of joint objects")
    v2 = v2 or []
    result = _read_optional_json(folder / "result.json", warnings)
    if result is not None and not isinstance(result, (list, dict)):
        raise PartnetFormatError(f"{folder / 'result.json'}: must be a list of part nodes")
    meta = _read_optional_json(folder / "meta.json", warnings)
    if meta is not None and not isinstance(meta, dict):
        raise PartnetFormatError(f"{folder / 'meta.json'}: must be a JSON object")

    # result.json: node id -> OBJ stems of its subtree; handle nodes
    subtree: dict[int, list[str]] = {}
    handle_nodes: dict[str, int] = {}
    glass: set[str] = set()

    def walk(node: Any, in_handle: int | None, in_glass: bool) -> list[str]:
        if not isinstance(node, dict):
            return []
        name = str(node.get("name", "")).lower()
        nid = node.get("id")
        if name in HANDLE_NODE_NAMES and isinstance(nid, int) and in_handle is None:
            in_handle = nid
        in_glass = in_glass or name == "glass"
        stems = [str(s) for s in node.get("objs", []) or [] if isinstance(s, str)]
        for s in stems:
            if in_handle is not None:
                handle_nodes[s] = in_handle
            if in_glass:
                glass.add(s)
        for ch in node.get("children", []) or []:
            stems = stems + walk(ch, in_handle, in_glass)
        if isinstance(nid, int):
            subtree[nid] = stems
        return stems

    for node in result if isinstance(result, list) else [result] if result else []:
        walk(node, None, False)

    stem_to_v2: dict[str, int] = {}
    for e in v2:
        jid = e.get("id")
        if not isinstance(jid, int):
            continue
        for p in e.get("parts", []) or []:
            pid = p.get("id") if isinstance(p, dict) else None
            for s in subtree.get(pid, []) if isinstance(pid, int) else []:
                stem_to_v2.setdefault(s, jid)
    return _Annotations(sem, v2, stem_to_v2, handle_nodes, glass, meta or {}, warnings)


# --------------------------------------------------------------------------- meshes


class _Resolver(trimesh.resolvers.FilePathResolver):
    """Resolves MTL/texture references relative to the OBJ, anywhere inside the object folder."""

    def __init__(self, source: Path, root: Path):
        super().__init__(str(source), allow_anywhere=True)
        self.root = root.resolve()

    def absolute(self, name: str) -> Path:
        path = super().absolute(name)
        if not path.is_relative_to(self.root):
            raise ValueError(f"{name!r} lies outside the object folder")
        return path


GREY = np.array([180, 180, 180, 255], np.uint8)


@dataclass
class _Piece:
    """One sub-mesh of an OBJ file (one material), in the current frame."""

    vertices: np.ndarray  # (V, 3) float
    faces: np.ndarray  # (F, 3) int
    uv: np.ndarray | None  # (V, 2) when textured
    image_key: str | None  # key into the object's image table when textured
    color: np.ndarray  # (4,) uint8 flat colour (material diffuse) when not textured
    link: str = ""
    stem: str = ""
    visual_name: str = ""
    source: str = ""  # the mesh file (relative to the object folder) or the URDF primitive

    def copy(self) -> _Piece:
        return _Piece(
            self.vertices.copy(),
            self.faces,
            self.uv,
            self.image_key,
            self.color,
            self.link,
            self.stem,
            self.visual_name,
            self.source,
        )

    def transform(self, T: np.ndarray) -> None:
        self.vertices = self.vertices @ T[:3, :3].T + T[:3, 3]
        if np.linalg.det(T[:3, :3]) < 0:  # a mirror keeps the faces outward
            self.faces = self.faces[:, ::-1]

    @property
    def textured(self) -> bool:
        return self.image_key is not None and self.uv is not None


def _flat_color(g: trimesh.Trimesh) -> np.ndarray:
    """(4,) uint8 colour of an untextured sub-mesh: material diffuse, else its mean colour."""
    vis = g.visual
    try:
        mat = getattr(vis, "material", None)
        if mat is not None:
            c = np.asarray(mat.main_color, dtype=np.uint8).reshape(-1)
            return c if c.shape == (4,) else GREY
        if vis.kind in ("vertex", "face"):
            vc = np.asarray(vis.vertex_colors, dtype=float)
            if len(vc):
                return vc.mean(axis=0).round().astype(np.uint8)
    except Exception:  # noqa: BLE001 - colour is cosmetic; never fail the geometry
        pass
    return GREY


def _load_file(
    path: Path, root: Path, src: Path, where: str, images: dict[str, Image.Image]
) -> list[_Piece]:
    """The sub-meshes of one mesh file (in its own frame); textures go into ``images``."""
    rel = path.relative_to(root.resolve()) if path.is_relative_to(root.resolve()) else path
    try:
        loaded = trimesh.load(
            str(path),
            process=False,
            resolver=_Resolver(path, root),
            file_type=path.suffix[1:].lower() or None,
        )
    except Exception as e:  # trimesh raises many types on corrupt files
        raise PartnetFormatError(f"{src}: {where}: cannot read mesh {rel}: {e}") from e
    geoms: list[tuple[trimesh.Trimesh, np.ndarray]] = []
    if isinstance(loaded, trimesh.Scene):
        for node in loaded.graph.nodes_geometry:
            T, gname = loaded.graph[node]
            g = loaded.geometry[gname]
            if isinstance(g, trimesh.Trimesh):
                geoms.append((g, T))
    elif isinstance(loaded, trimesh.Trimesh):
        geoms.append((loaded, np.eye(4)))
    out = []
    for g, T in geoms:
        if len(g.faces) == 0:
            continue
        v = np.asarray(g.vertices, dtype=float)
        if not np.allclose(T, np.eye(4)):
            v = v @ T[:3, :3].T + T[:3, 3]
        if not np.isfinite(v).all():
            raise PartnetFormatError(f"{src}: {where}: mesh {rel} has NaN or infinite vertices")
        key, uv = None, None
        mat = getattr(g.visual, "material", None)
        img = getattr(mat, "image", None)
        guv = getattr(g.visual, "uv", None)
        if img is not None and guv is not None and len(guv) == len(v):
            ref = img.info.get("file_path")
            key = str((path.parent / ref).resolve()) if ref else f"{path}#{len(images)}"
            images.setdefault(key, img)
            uv = np.asarray(guv, dtype=float)
            if not np.isfinite(uv).all():
                key, uv = None, None
        out.append(_Piece(v, np.asarray(g.faces, dtype=np.int64), uv, key, _flat_color(g)))
    return out


# --------------------------------------------------------------------------- textures


def _geometry_concat(pieces: list[_Piece]) -> tuple[np.ndarray, np.ndarray]:
    verts, faces, off = [], [], 0
    for p in pieces:
        verts.append(p.vertices)
        faces.append(p.faces + off)
        off += len(p.vertices)
    return np.concatenate(verts), np.concatenate(faces)


SWATCH = 16  # pixels a side of a flat colour's patch in a part's atlas
MAX_TILES = 8  # texture repeats per axis kept by repeating the image; beyond: wrapped per face


def _tile_uv(
    uv: np.ndarray, faces: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None, tuple[int, int]]:
    """UVs mapped into [0, 1] over an image repeated (nu, nv) times.

    Returns (uv, per-face vertex index or None, (nu, nv)). When the UVs span more
    than ``MAX_TILES`` repeats, each face is moved by whole repeats so that its
    centre lands in the first one and its vertices are unshared (the returned index
    picks each face corner's original vertex); what still sticks out is clamped.
    """
    lo = np.floor(uv.min(axis=0) + 1e-6)
    hi = np.ceil(uv.max(axis=0) - 1e-6)
    n = np.maximum(hi - lo, 1).astype(int)
    if (n <= MAX_TILES).all():
        return (uv - lo) / n, None, (int(n[0]), int(n[1]))
    corner = faces.reshape(-1)
    fuv = uv[faces]  # (F, 3, 2)
    fuv = fuv - np.floor(fuv.mean(axis=1, keepdims=True))
    flat = fuv.reshape(-1, 2)
    lo = np.floor(flat.min(axis=0) + 1e-6)
    hi = np.ceil(flat.max(axis=0) - 1e-6)
    n = np.clip(hi - lo, 1, MAX_TILES).astype(int)
    return np.clip((flat - lo) / n, 0.0, 1.0), corner, (int(n[0]), int(n[1]))


def _atlas_image(
    key: str, images: dict[str, Image.Image], tiles: tuple[int, int], size: tuple[int, int]
) -> Image.Image:
    """Image ``key`` repeated ``tiles`` times, as an RGB image of ``size`` pixels."""
    nu, nv = tiles
    tw, th = max(1, size[0] // nu), max(1, size[1] // nv)
    img = images[key]
    if img.format == "JPEG" and os.path.isfile(key):
        try:  # a fresh decoder can decode at a reduced scale (fast for big JPEGs)
            fresh = Image.open(key)
            fresh.draft("RGB", (tw, th))
            img = fresh
        except OSError:
            pass
    base = img.convert("RGB")
    if base.size != (tw, th):
        base = base.resize((tw, th), Image.Resampling.BILINEAR)
    if nu == 1 and nv == 1:
        return base
    tiled = Image.new("RGB", (tw * nu, th * nv))
    for i in range(nu):
        for j in range(nv):
            tiled.paste(base, (i * tw, j * th))
    return tiled


def _merge_visual(
    pieces: list[_Piece], images: dict[str, Image.Image], atlas_size: int, jpeg_quality: int
) -> tuple[trimesh.Trimesh, dict[str, Any]]:
    """One mesh of all pieces with one texture atlas (vertex colours when none is textured)."""
    info: dict[str, Any] = {"atlas": None}
    if not any(p.textured for p in pieces):
        verts, faces = _geometry_concat(pieces)
        colors = np.concatenate([np.tile(p.color, (len(p.vertices), 1)) for p in pieces])
        mesh = trimesh.Trimesh(verts, faces, process=False)
        mesh.visual = trimesh.visual.ColorVisuals(mesh, vertex_colors=colors)
        return mesh, info

    # atlas entries: (image key, tiles) of textured pieces; a swatch per flat colour (16 px:
    # JPEG mixes colour over 2x2 pixels and its 8x8 blocks, so a smaller one takes on
    # its neighbours' hue)
    entries: dict[tuple[str, tuple[int, int]], int] = {}
    virtual: list[tuple[int, int]] = []  # full-resolution size of each entry
    per_piece: list[tuple[np.ndarray, np.ndarray, np.ndarray, int]] = []
    for p in pieces:
        if p.textured:
            assert p.uv is not None and p.image_key is not None
            uv, corner, tiles = _tile_uv(p.uv, p.faces)
            verts, faces = p.vertices, p.faces
            if corner is not None:  # unshared: one vertex per face corner
                verts = verts[corner]
                faces = np.arange(len(corner)).reshape(-1, 3)
            key = (p.image_key, tiles)
            if key not in entries:
                entries[key] = len(virtual)
                w, h = images[p.image_key].size
                # a repeated texture gets at most the atlas side across all its repeats
                f = min(1.0, atlas_size / (w * tiles[0]), atlas_size / (h * tiles[1]))
                virtual.append((max(1, round(w * f)) * tiles[0], max(1, round(h * f)) * tiles[1]))
        else:
            key = ("colour:" + ",".join(map(str, p.color.tolist())), (0, 0))
            if key not in entries:
                entries[key] = len(virtual)
                virtual.append((0, 0))
            uv = np.full((len(p.vertices), 2), 0.5)
            verts, faces = p.vertices, p.faces
        per_piece.append((verts, faces, uv, entries[key]))

    keys = sorted(entries, key=lambda k: entries[k])
    sizes = np.array(virtual, dtype=float)
    textured = sizes[:, 0] > 0
    area = float((sizes[textured, 0] * sizes[textured, 1]).sum())
    factor = min(1.0, math.sqrt(0.6 * atlas_size**2 / area), atlas_size / sizes.max())
    for _attempt in range(20):
        scaled = []
        for (key, tiles), (w, h) in zip(keys, virtual, strict=True):
            if w == 0:
                rgb = tuple(int(x) for x in key.split(":", 1)[1].split(",")[:3])
                scaled.append(Image.new("RGB", (SWATCH, SWATCH), rgb))
                continue
            size = (max(tiles[0] * 2, round(w * factor)), max(tiles[1] * 2, round(h * factor)))
            scaled.append(size)  # placeholder; images are made once the layout fits
        dims = [s.size if isinstance(s, Image.Image) else s for s in scaled]
        # pack rectangles first (cheap), then paste
        bounds, inserted = packing.rectangles(
            extents=np.array(dims, dtype=float), rotate=False, iterations=4, seed=0, spacing=2
        )
        ext = np.ptp(bounds.reshape(-1, 2), axis=0) + 4
        if inserted.all() and ext.max() <= atlas_size:
            break
        factor *= 0.85
    else:
        raise PartnetFormatError(f"cannot pack {len(keys)} textures into {atlas_size} px")
    offsets = bounds[:, 0].round().astype(int)
    W, H = (int(x) for x in np.ceil(ext))
    atlas = Image.new("RGB", (W, H), (128, 128, 128))
    final_sizes = []
    for i, ((key, tiles), s) in enumerate(zip(keys, scaled, strict=True)):
        im = s if isinstance(s, Image.Image) else _atlas_image(key, images, tiles, s)
        final_sizes.append(im.size)
        ox, oy = offsets[i]
        atlas.paste(im, (int(ox), int(H - im.size[1] - oy)))  # oy counts from the bottom
    uvs, verts_all, faces_all, off = [], [], [], 0
    for verts, faces, uv, e in per_piece:
        w, h = final_sizes[e]
        ox, oy = offsets[e]
        u = np.clip(uv[:, 0], 0.5 / w, 1 - 0.5 / w)
        v = np.clip(uv[:, 1], 0.5 / h, 1 - 0.5 / h)
        uvs.append(np.column_stack([(ox + u * w) / W, (oy + v * h) / H]))
        verts_all.append(verts)
        faces_all.append(faces + off)
        off += len(verts)
    # stored as JPEG: a few hundred kB per part instead of megabytes of PNG
    buf = io.BytesIO()
    atlas.save(buf, format="JPEG", quality=jpeg_quality)
    buf.seek(0)
    image = Image.open(buf)
    image.load()
    mesh = trimesh.Trimesh(np.concatenate(verts_all), np.concatenate(faces_all), process=False)
    mesh.visual = trimesh.visual.TextureVisuals(
        uv=np.concatenate(uvs), material=trimesh.visual.material.SimpleMaterial(image=image)
    )
    info.update(atlas=[W, H], images=int(textured.sum()), scale=round(float(factor), 4))
    return mesh, info


# --------------------------------------------------------------------------- helpers


def _semantic_word(sem: str) -> str | None:
    s = sem.lower()
    for w in KEPT_SEMANTICS:
        if w in s:
            return w
    return None


def _yaw(deg: int) -> np.ndarray:
    return tf.rotation_matrix(math.radians(deg), [0, 0, 1])[:3, :3].round(12)


def _motion(jtype: str, origin: np.ndarray, axis: np.ndarray, q: float) -> np.ndarray:
    if jtype == "prismatic":
        return tf.translation_matrix(q * axis)
    return tf.rotation_matrix(q, axis, origin)


def _area(v: np.ndarray, f: np.ndarray) -> float:
    tri = v[f]
    return float(
        0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    )


def _inside_share(v: np.ndarray, f: np.ndarray, box: np.ndarray) -> float:
    tri = v[f]
    centres = tri.mean(axis=1)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    inside = ((centres >= box[0]) & (centres <= box[1])).all(axis=1)
    total = float(area.sum())
    return float(area[inside].sum() / total) if total > 0 else 0.0


# --------------------------------------------------------------------------- conversion


@dataclass
class _Kept:
    link: str
    word: str  # door | drawer | lid
    semantic: str
    jtype: str  # revolute | prismatic
    origin: np.ndarray  # world point on the axis
    axis: np.ndarray  # world unit axis
    lower: float
    upper: float
    restored: bool = False
    closed: float = 0.0
    open_sign: float = 1.0
    travel: float = 0.0


def convert_object(folder: str | Path, options: PartnetOptions | None = None) -> ArticulatedObject:
    """Read one PartNet-Mobility object folder into an :class:`ArticulatedObject`.

    See the module docstring for the rules. Raises PartnetFormatError naming the
    file and what is wrong.
    """
    opts = options or PartnetOptions()
    t0 = time.perf_counter()
    folder = Path(folder)
    src = folder / URDF_NAME
    if not src.is_file():
        raise PartnetFormatError(
            f"{src}: not found (a PartNet-Mobility object folder holds {URDF_NAME})"
        )
    if not (folder / MESH_DIR).is_dir():
        raise PartnetFormatError(f"{folder / MESH_DIR}: not found (the OBJ meshes live there)")
    urdf = parse_urdf(src)
    ann = _read_annotations(folder)
    warnings = list(ann.warnings)
    W = _world(urdf)

    # ---- up: the root chain must turn the raw y-up meshes z-up
    body_links = [n for n in urdf.links if urdf.links[n].visuals]
    if not body_links:
        raise PartnetFormatError(f"{src}: no link has a <visual> mesh")
    P = np.eye(4)
    rotated = any(not np.allclose(W[n][:3, :3], np.eye(3), atol=1e-6) for n in body_links)
    if not rotated:
        P[:3, :3] = tf.euler_matrix(*STANDARD_ROOT_RPY, axes="sxyz")[:3, :3]
        warnings.append(
            "no rotation on the URDF root chain: raw y-up meshes assumed, standard rotation applied"
        )

    # ---- semantics per link
    def link_stems(n: str) -> list[str]:
        return [v.file.stem for v in urdf.links[n].visuals if v.file is not None]

    def v2_id(n: str) -> int | None:
        votes: dict[int, int] = {}
        for s in link_stems(n):
            if s in ann.stem_to_v2:
                votes[ann.stem_to_v2[s]] = votes.get(ann.stem_to_v2[s], 0) + 1
        if votes:
            return max(sorted(votes), key=lambda k: votes[k])
        m = re.fullmatch(r"link_(\d+)", n)
        return int(m.group(1)) if m else None

    v2_by_id = {e.get("id"): e for e in ann.v2 if isinstance(e.get("id"), int)}

    def semantic(n: str) -> str:
        if n in ann.semantics:
            return ann.semantics[n][1]
        k = v2_id(n)
        if k is not None and f"link_{k}" in ann.semantics:
            return ann.semantics[f"link_{k}"][1]
        if k is not None and k in v2_by_id and v2_by_id[k].get("name"):
            return str(v2_by_id[k]["name"]).lower()
        return n.lower()

    # ---- candidate movable parts (world frame after P)
    candidates: dict[str, _Kept] = {}
    for child, j in urdf.joints.items():
        sem = semantic(child)
        word = _semantic_word(sem)
        if word is None or "collision" in child.lower() or "handle" in child.lower():
            continue
        Tj = P @ W[j.parent] @ j.origin
        jtype, lo, hi = j.type, j.lower, j.upper
        axis = Tj[:3, :3] @ j.axis
        origin = Tj[:3, 3].copy()
        restored = False
        if jtype == "fixed" and opts.restore_fixed:
            k = v2_id(child)
            e = v2_by_id.get(k) if k is not None else None
            jd = (e or {}).get("jointData") or {}
            kind = str((e or {}).get("joint", "")).lower()
            lim = jd.get("limit") or {}
            ax = jd.get("axis") or {}
            if kind in ("hinge", "slider") and not lim.get("noLimit", False) and ax:
                try:
                    a, b = float(lim["a"]), float(lim["b"])
                    d = np.asarray(ax["direction"], float).reshape(3)
                    o = np.asarray(ax["origin"], float).reshape(3)
                except (KeyError, TypeError, ValueError) as ex:
                    raise PartnetFormatError(
                        f"{folder / 'mobility_v2.json'}: joint {k}: malformed jointData: {ex}"
                    ) from ex
                # v2 coordinates are in the raw mesh frame: the frame of the link fixed to base
                raw = urdf.children(urdf.root)
                R0 = P @ W[raw[0]] if raw else P
                jtype = "revolute" if kind == "hinge" else "prismatic"
                axis = R0[:3, :3] @ d
                origin = (R0 @ np.append(o, 1.0))[:3]
                lo, hi = sorted((a, b))
                if jtype == "revolute":
                    lo, hi = math.radians(lo), math.radians(hi)
                restored = True
                warnings.append(
                    f"{child}: fixed in {URDF_NAME}, restored as {jtype} from mobility_v2.json"
                )
        if jtype == "continuous":
            if word == "door":
                jtype, lo, hi = "revolute", 0.0, math.pi / 2
                warnings.append(f"{child}: continuous door joint made revolute over [0, pi/2]")
            else:
                continue
        if jtype not in ("revolute", "prismatic"):
            continue
        n = np.linalg.norm(axis)
        candidates[child] = _Kept(child, word, sem, jtype, origin, axis / n, lo, hi, restored)

    # ---- load every link's visual meshes in the frame P @ W
    images: dict[str, Image.Image] = {}
    cache: dict[Path, list[_Piece]] = {}
    link_pieces: dict[str, list[_Piece]] = {}
    for n, link in urdf.links.items():
        if "collision" in n.lower() and n != urdf.root:
            continue
        pieces = []
        for v in link.visuals:
            where = f"link {n!r} <visual> {v.index}"
            S = np.diag([*v.scale, 1.0])
            T = P @ W[n] @ v.origin @ S
            if v.file is None:
                assert v.primitive is not None
                items = [
                    _Piece(
                        np.asarray(v.primitive.vertices, float),
                        np.asarray(v.primitive.faces),
                        None,
                        None,
                        GREY,
                    )
                ]
            else:
                if v.file not in cache:
                    cache[v.file] = _load_file(v.file, folder, src, where, images)
                items = [q.copy() for q in cache[v.file]]
            for q in items:
                q.transform(T)
                q.link, q.visual_name = n, v.name
                q.stem = v.file.stem if v.file is not None else f"{n}-{v.index}"
                q.source = (
                    f"{URDF_NAME} {where} (a primitive)"
                    if v.file is None
                    else v.file.relative_to(folder.resolve()).as_posix()
                )
                pieces.append(q)
        link_pieces[n] = pieces
    if not any(link_pieces.values()):
        raise PartnetFormatError(f"{src}: the visual meshes hold no triangles")
    allv = np.concatenate([p.vertices for ps in link_pieces.values() for p in ps])
    extent = float(np.ptp(allv, axis=0).max())
    if not extent > 0:
        raise PartnetFormatError(f"{src}: all meshes together have zero extent")

    # ---- owners: a link belongs to its nearest kept ancestor (or the root)
    kept: dict[str, _Kept] = dict(candidates)

    def owner(n: str) -> str:
        while n != urdf.root and n not in kept:
            n = urdf.joints[n].parent
        return n

    def group() -> dict[str, list[str]]:
        g: dict[str, list[str]] = {}
        for n in urdf.links:
            g.setdefault(owner(n), []).append(n)
        return g

    def geom(links: list[str]) -> tuple[np.ndarray, np.ndarray] | None:
        ps = [p for n in links for p in link_pieces.get(n, [])]
        return _geometry_concat(ps) if ps else None

    # ---- closed pose and range of each kept part; drop the small ones
    for _round in range(2):
        groups = group()
        base_geo = geom(groups.get(urdf.root, []))
        if base_geo is None:
            raise PartnetFormatError(
                f"{src}: the root link {urdf.root!r} and the links fixed to it have no mesh"
            )
        bbox = np.array([base_geo[0].min(0), base_geo[0].max(0)])
        bbox = bbox + np.array([[-1.0], [1.0]]) * 0.02 * extent
        dropped = False
        for n, k in list(kept.items()):
            g = geom(groups[n])
            if g is None:
                warnings.append(f"{n}: a {k.word} without a mesh; dropped")
                del kept[n]
                dropped = True
                continue
            v, f = g
            size = float(np.linalg.norm(np.ptp(v, axis=0)))
            cands = [k.lower, k.upper] + ([0.0] if k.lower < 0.0 < k.upper else [])
            scores = {}
            for q in cands:
                M = _motion(k.jtype, k.origin, k.axis, q)
                scores[q] = _inside_share(v @ M[:3, :3].T + M[:3, 3], f, bbox)
            best = max(scores.values())
            tied = [q for q in cands if scores[q] >= best - 0.02]
            qc = 0.0 if 0.0 in tied or any(abs(q) < 1e-9 for q in tied) else min(tied, key=abs)
            if abs(qc - k.lower) < 1e-9:
                q_open = k.upper
            elif abs(qc - k.upper) < 1e-9:
                q_open = k.lower
            else:  # closed at 0 inside the range: open toward the side that leaves the base more
                q_open = k.upper if scores[k.upper] <= scores[k.lower] else k.lower
            k.closed, k.open_sign, k.travel = qc, (1.0 if q_open >= qc else -1.0), abs(q_open - qc)
            small_range = (
                k.travel < math.radians(opts.min_revolute_deg)
                if k.jtype == "revolute"
                else k.travel < opts.min_prismatic_frac * extent
            )
            if small_range or size < opts.min_part_frac * extent:
                why = "range" if small_range else "size"
                warnings.append(f"{n}: {k.word} with a tiny {why}; merged as fixed")
                del kept[n]
                dropped = True
        if not dropped:
            break

    groups = group()
    for n in kept:
        anc = urdf.joints[n].parent
        if owner(anc) != urdf.root:
            warnings.append(f"{n}: hangs off movable {owner(anc)!r}; re-rooted onto base")

    # ---- move each kept part to its closed pose; world joint with positive = opening
    for n, k in kept.items():
        M = _motion(k.jtype, k.origin, k.axis, k.closed)
        for ln in groups[n]:
            for p in link_pieces.get(ln, []):
                p.transform(M)
        k.axis = k.axis * k.open_sign

    # ---- front: the horizontal direction the parts open toward
    votes = np.zeros(4)  # +x, +y, -x, -y
    for n, k in kept.items():
        v, _f = geom(groups[n])
        if k.jtype == "prismatic":
            d = k.axis.copy()
        else:
            c = (v.min(0) + v.max(0)) / 2
            M = _motion("revolute", k.origin, k.axis, min(k.travel, math.radians(45)))
            d = (M[:3, :3] @ c + M[:3, 3]) - c
            if k.word == "door" and d[2] > np.linalg.norm(d[:2]):
                k.word = "lid"  # a "door" that swings upward (a top loader's) is a lid
        total = np.linalg.norm(d)
        h = d[:2]
        if total < 1e-9 or np.linalg.norm(h) < 0.5 * total:
            continue  # opens mostly up or down (a lid): no vote
        ang = math.degrees(math.atan2(h[1], h[0]))
        votes[int(round(ang / 90.0)) % 4] += 1
    if votes.sum() > 0:
        winner = int(np.argmax(votes))
        yaw = (-90 * winner) % 360
        front = "voted"
        if (votes > 0).sum() > 1:
            warnings.append(
                f"parts open toward different sides (votes +x,+y,-x,-y = {votes.astype(int).tolist()})"
            )
    else:
        yaw, front = DEFAULT_YAW_DEG, "default"
    Y = np.eye(4)
    Y[:3, :3] = _yaw(yaw)
    for ps in link_pieces.values():
        for p in ps:
            p.transform(Y)
    for k in kept.values():
        k.axis = Y[:3, :3] @ k.axis
        k.origin = Y[:3, :3] @ k.origin
    R_total = (Y @ P)[:3, :3]

    # ---- normalize (closed pose): bounding-box centre at the origin, largest extent 1
    allv = np.concatenate([p.vertices for ps in link_pieces.values() for p in ps])
    lo, hi = allv.min(0), allv.max(0)
    centre = (lo + hi) / 2.0
    s = float((hi - lo).max())
    N = np.eye(4)
    N[:3, :3] /= s
    N[:3, 3] = -centre / s
    for ps in link_pieces.values():
        for p in ps:
            p.transform(N)

    # ---- category, materials; metres per unit as the build will make it (for handles)
    raw_cat = str(ann.meta.get("model_cat", "") or "")
    category = opts.category or CATEGORY_MAP.get(raw_cat.lower().replace(" ", ""), "unknown")
    material = "metal" if category in APPLIANCES else "wood"
    height_m = opts.height or DEFAULT_HEIGHTS.get(category, DEFAULT_HEIGHTS["unknown"])
    metres = float(height_m) / max(float(hi[2] - lo[2]) / s, 1e-6)

    # ---- parts
    atlas_info: dict[str, Any] = {}

    def check_pieces(part: str, pieces: list[_Piece]) -> None:
        v, f = _geometry_concat(pieces)
        files = sorted({p.source for p in pieces})
        warnings.extend(check_part_mesh(v, f, part, files, src, PartnetFormatError))

    base_pieces = [p for ln in groups[urdf.root] for p in link_pieces.get(ln, [])]
    check_pieces(BASE, base_pieces)
    base_mesh, atlas_info[BASE] = _merge_visual(
        base_pieces, images, opts.atlas_size, opts.jpeg_quality
    )
    parts = [Part(name=BASE, semantic="base", mesh=base_mesh, joint=None, material=material)]
    order = []
    for n in kept:
        v, _f = geom(groups[n])
        c = (v.min(0) + v.max(0)) / 2
        order.append((-round(float(c[2]), 3), round(float(c[1]), 3), n))
    counters: dict[str, int] = {}
    merged_links = {BASE: sorted(groups[urdf.root])}
    part_files = {BASE: sorted({p.source for p in base_pieces})}
    closed_values = {}
    handles: dict[str, dict[str, Any] | None] = {}
    for _z, _y, n in sorted(order):
        k = kept[n]
        name = f"{k.word}_{counters.get(k.word, 0)}"
        counters[k.word] = counters.get(k.word, 0) + 1
        pieces = [p for ln in groups[n] for p in link_pieces.get(ln, [])]
        check_pieces(name, pieces)
        origin = (k.origin - centre) / s
        if k.jtype == "revolute":
            upper = k.travel
        else:
            upper = k.travel / s
        joint = Joint(
            type=k.jtype,
            origin=origin,
            axis=k.axis / np.linalg.norm(k.axis),
            lower=0.0,
            upper=upper,
            parent=BASE,
        )
        part_material = material
        if category in GLASS_DOOR_CATEGORIES and k.word == "door":
            area = {id(p): _area(p.vertices, p.faces) for p in pieces}
            glass = sum(area[id(p)] for p in pieces if p.stem in ann.glass_stems)
            if glass > 0.5 * sum(area.values()):
                part_material = "glass"
        handle, handles[name], grip = _part_handle(pieces, ann, joint, metres, opts.add_handles)
        if grip is not None:
            record = handles[name]
            assert record is not None
            colour = _grip_colour(pieces, images, grip[1], metres)
            pieces = [
                *pieces,
                _Piece(
                    np.asarray(grip[0].vertices, float),
                    np.asarray(grip[0].faces),
                    None,
                    None,
                    colour,
                    link=n,
                    stem=GRIP_STEM,
                    visual_name=GRIP_STEM,
                ),
            ]
            at = [round(float(x), 3) for x in handle.position]
            warnings.append(
                f"{name}: {GRIP_NOTE} a {record['length_cm']:g} cm bar grip {record['where']}, "
                f"grasp point {at} (object frame)"
            )
        mesh, atlas_info[name] = _merge_visual(pieces, images, opts.atlas_size, opts.jpeg_quality)
        parts.append(
            Part(
                name=name,
                semantic=k.word,
                mesh=mesh,
                joint=joint,
                handle=handle,
                material=part_material,
            )
        )
        merged_links[name] = sorted(groups[n])
        part_files[name] = sorted({p.source for p in pieces if p.stem != GRIP_STEM})
        closed_values[name] = k.closed

    if not kept:
        if not opts.keep_static:
            raise PartnetFormatError(
                f"{folder / 'mobility.urdf'}: nothing to articulate: no door, drawer or lid "
                "(only a body, or knobs, wheels, racks: merged); keep_static imports it as one "
                "static body"
            )
        warnings.append("no door, drawer or lid: imported as one static body")
    for w in warnings:
        log.warning("%s: %s", folder, w)

    pid = folder.name if folder.name.isdigit() else str(ann.meta.get("anno_id") or folder.name)
    obj = ArticulatedObject(
        parts=parts,
        category=category,
        scale=None,
        provenance={
            "importer": "partnet-mobility",
            "source": str(folder.resolve()),
            "partnet_id": pid,
            "source_category": raw_cat or None,
            "frame": {
                "rotation": R_total.round(12).tolist(),
                "yaw_deg": yaw,
                "front": front,
                "root_rotation_added": not rotated,
            },
            "normalization": [*map(float, centre), s],
            "links": merged_links,
            "meshes": part_files,
            "closed_value": closed_values,
            "restored_joints": sorted(n for n, k in kept.items() if k.restored),
            "handles": handles,
            "textures": atlas_info,
            "warnings": warnings,
        },
    )
    if opts.height is not None:
        h = float(np.ptp(obj.bounds()[:, 2]))
        obj.scale = float(opts.height) / h
        obj.provenance["height"] = float(opts.height)
    obj.provenance["seconds"] = round(time.perf_counter() - t0, 3)
    try:
        obj.validate(str(src))
    except ObjectModelError as e:
        raise PartnetFormatError(str(e)) from e
    return obj


def _opening_normal(joint: Joint, vertices: np.ndarray) -> np.ndarray:
    """Unit direction in which the closed part's front moves out when it starts to open.

    A drawer's axis. For a door or lid, the motion of its bounding-box centre, replaced
    by the thinnest axis of its bounding box when the part is a panel (thinnest extent
    under half the next one; the hinge is offset from the panel's mid-plane, so the
    motion alone is tilted), or snapped to the nearest axis within 30 degrees.
    """
    if joint.type == "prismatic":
        return joint.axis / np.linalg.norm(joint.axis)
    lo, hi = vertices.min(0), vertices.max(0)
    v = np.cross(joint.axis, (lo + hi) / 2 - joint.origin)
    if np.linalg.norm(v) < 1e-12:
        return np.array([1.0, 0.0, 0.0])
    v = v / np.linalg.norm(v)
    ext = hi - lo
    order = np.argsort(ext)
    k = int(order[0])
    if ext[k] < 0.5 * ext[order[1]] and abs(v[k]) > 0.3:
        n = np.zeros(3)
        n[k] = np.sign(v[k])
        return n
    k = int(np.argmax(np.abs(v)))
    if abs(v[k]) > math.cos(math.radians(30)):
        n = np.zeros(3)
        n[k] = np.sign(v[k])
        return n
    return v


def _find_handle(
    pieces: list[_Piece], ann: _Annotations, joint: Joint, part_vertices: np.ndarray
) -> Handle | None:
    """The grasp point of the part's modelled handle (object frame), or None without one.

    Handle meshes: pieces whose OBJ is under a ``handle`` node of result.json, whose
    URDF visual is named ``handle-*`` or whose link is named ``*handle*``; one handle
    per node (visual, link). See the module docstring for the grasp point.
    """
    groups: dict[str, list[_Piece]] = {}
    for p in pieces:
        key = None
        if p.stem in ann.handle_nodes:
            key = f"node{ann.handle_nodes[p.stem]}"
        elif p.visual_name.lower().startswith("handle"):
            key = f"visual:{p.visual_name}"
        elif "handle" in p.link.lower():
            key = f"link:{p.link}"
        if key is not None:
            groups.setdefault(key, []).append(p)
    if not groups:
        return None
    n = _opening_normal(joint, part_vertices)
    centre = (part_vertices.min(0) + part_vertices.max(0)) / 2
    best = None
    for key in sorted(groups):
        verts, faces = _geometry_concat(groups[key])
        # surface samples, not just vertices: a disc's rim spans its thickness
        hm = trimesh.Trimesh(verts, faces, process=False)
        v = verts
        if hm.area > 0:
            samples, _ = trimesh.sample.sample_surface(hm, 2000, seed=0)
            v = np.concatenate([verts, samples])
        d = v @ n
        depth = float(d.max() - d.min())
        outer = v[d >= d.max() - 0.35 * depth - 1e-9]  # the bar, not its standoffs
        # in-plane frame: the long direction of the handle across n (principal axis)
        flat = v - np.outer(v @ n, n)
        flat = flat - flat.mean(0)
        _, _sv, vt = np.linalg.svd(flat, full_matrices=False)
        a = vt[0] - (vt[0] @ n) * n
        a = a / np.linalg.norm(a)
        b = np.cross(n, a)
        # grasp point: centre of the outer slab's extent along a, b and n
        frame = np.stack([a, b, n])
        lo_o, hi_o = (outer @ frame.T).min(0), (outer @ frame.T).max(0)
        pos = frame.T @ ((lo_o + hi_o) / 2)
        ext = np.ptp(v @ frame.T, axis=0)
        kind = "bar" if ext[0] >= 2.0 * max(float(ext[1]), 1e-9) else "knob"
        axis = a
        if kind == "knob":  # no long direction: along the hinge, or horizontal on a drawer
            e = joint.axis if joint.type == "revolute" else np.cross([0.0, 0.0, 1.0], n)
            e = e - (e @ n) * n
            if np.linalg.norm(e) > 1e-6:
                axis = e / np.linalg.norm(e)
        if axis[np.argmax(np.abs(axis))] < 0:
            axis = -axis
        off = pos - centre
        dist = float(np.linalg.norm(off - (off @ n) * n))
        if best is None or dist < best[0] - 1e-9:
            best = (dist, Handle(position=pos, axis=axis, kind=kind))
    return None if best is None else best[1]


# --------------------------------------------------------------------------- handles on the geometry

#: Geometric handles and added grips, in metres at the estimated metric scale.
HANDLE_MARGIN = 0.008  # the surface of a handle stands at least this far out of the face plane
HANDLE_MIN_STANDOFF = 0.012  # and its outermost point at least this far
HANDLE_MAX_WIDTH = 0.06  # its outer slab is at most this wide across the pinch
HANDLE_MIN_LENGTH = 0.015  # and it is at least this long (a knob's diameter)
HANDLE_MIN_AREA = 2e-4  # m^2 of protruding surface (a screw head or a logo is no handle)
HANDLE_VOXEL = 0.01  # protruding surface points connected through voxels of this pitch
HANDLE_MIN_HINGE_SHARE = 0.35  # a door handle lies at least this share of the way to the free edge
FACE_BIN = 0.002  # histogram bin of the outer-face search
FACE_MIN_SHARE = 0.10  # of the part's area across n: the outer face plane holds at least this
FACE_MIN_SPAN = 0.6  # of the part's extent along a and b: the outer face plane spans this
GRIP_LENGTH = 0.12  # added grip: bar length (at most 60% of the part's extent along it)
GRIP_THICKNESS = 0.016  # square bar section
GRIP_STANDOFF = 0.033  # face plane -> bar axis (a 2.5 cm gap behind the bar for the fingers)
GRIP_POST = 0.012  # square standoff section
GRIP_INSET = 0.05  # bar axis -> a door's or lid's free edge (at most a quarter of its width)
GRIP_DEPTH = 0.03  # a standoff reaches the part's surface at most this far behind the face plane
GRIP_STEM = "added-grip"  # the stem / visual name of an added grip's piece
GRIP_NOTE = "no handle modelled; added"  # starts the warning that records an added grip


def _part_handle(
    pieces: list[_Piece], ann: _Annotations, joint: Joint, metres: float, add: bool
) -> tuple[Handle | None, dict[str, Any] | None, tuple[trimesh.Trimesh, _Face] | None]:
    """(handle, its provenance record, the added grip's mesh and face plane or None) of a
    closed movable part: its handle node's, else the one on its geometry, else (``add``)
    an added grip's."""
    verts, faces = _geometry_concat(pieces)
    handle = _find_handle(pieces, ann, joint, verts)
    if handle is not None:
        return handle, {"source": "node", "kind": handle.kind}, None
    face = _outer_face(verts, faces, joint, metres)
    if face is None:
        return None, None, None
    found = _geometric_handle(verts, faces, joint, metres, face)
    if found is not None:
        return found[0], found[1], None
    if not add:
        return None, None, None
    mesh, handle, info = _added_grip(verts, faces, joint, metres, face)
    return handle, info, (mesh, face)


def _grip_colour(
    pieces: list[_Piece], images: dict[str, Image.Image], face: _Face, metres: float
) -> np.ndarray:
    """(4,) uint8 colour of an added grip: that of the piece with the most area on the
    outer face plane (a textured piece's mean texture colour)."""
    best, best_area = pieces[0], -1.0
    for p in pieces:
        tri = p.vertices[p.faces]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        dbl = np.linalg.norm(cross, axis=1)
        on = (
            (dbl > 0)
            & (np.abs(cross @ face.n) > 0.9 * dbl)
            & (np.abs(tri.mean(axis=1) @ face.n - face.d) * metres <= 0.003)
        )
        area = float(dbl[on].sum())
        if area > best_area:
            best, best_area = p, area
    if best.textured and best.image_key in images:
        rgb = images[best.image_key].convert("RGB").resize((1, 1), Image.Resampling.BOX)
        return np.array([*rgb.getpixel((0, 0)), 255], np.uint8)
    return best.color


def _bar_direction(joint: Joint, n: np.ndarray) -> np.ndarray:
    """Unit direction of a bar on a part facing ``n``: along a door's or lid's hinge,
    horizontal on a drawer (across ``n`` in both cases)."""
    e = np.asarray(joint.axis, float) if joint.type == "revolute" else np.cross([0.0, 0.0, 1.0], n)
    e = e - (e @ n) * n
    if np.linalg.norm(e) < 1e-6:
        e = np.array([0.0, 1.0, 0.0]) - n[1] * n
    if np.linalg.norm(e) < 1e-6:
        e = np.array([1.0, 0.0, 0.0]) - n[0] * n
    return e / np.linalg.norm(e)


def _positive(axis: np.ndarray) -> np.ndarray:
    return -axis if axis[np.argmax(np.abs(axis))] < 0 else axis


@dataclass
class _Face:
    """A part's outer face plane along its opening normal ``n`` (model units).

    ``d``: the plane's offset ``n . x``; ``lo``/``hi``: the in-plane bounding box, along
    ``a`` and ``b = n x a``, of the triangles facing ``n`` within 3 mm of the plane.
    """

    n: np.ndarray
    a: np.ndarray
    b: np.ndarray
    d: float
    lo: np.ndarray
    hi: np.ndarray

    def point(self, pa: float, pb: float, pn: float) -> np.ndarray:
        return self.a * pa + self.b * pb + self.n * pn


def _outer_face(v: np.ndarray, f: np.ndarray, joint: Joint, metres: float) -> _Face | None:
    """The part's outer face plane: the outermost offset along ``n`` (2 mm bins, with
    their neighbours) whose triangles facing ``n`` (normal within 25 degrees of +-n)
    hold at least ``FACE_MIN_SHARE`` of the part's bounding-box area across ``n`` and
    span at least ``FACE_MIN_SPAN`` of its extent both ways (a handle plate running the
    door's width is not its face); else the offset beyond which 15% of that facing area
    lies. None for a part without facing area."""
    n = _opening_normal(joint, v)
    a = _bar_direction(joint, n)
    b = np.cross(n, a)
    tri = v[f]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    dbl = np.linalg.norm(cross, axis=1)
    facing = (dbl > 0) & (np.abs(cross @ n) > 0.9 * dbl)
    if not facing.any():
        return None
    ftri = tri[facing]
    d = ftri.mean(axis=1) @ n
    area = 0.5 * dbl[facing] * metres**2
    span = np.ptp(np.stack([v @ a, v @ b], axis=1), axis=0)
    across = float(np.prod(span)) * metres**2
    bins = np.floor(d * metres / FACE_BIN).astype(np.int64)
    ub, inv = np.unique(bins, return_inverse=True)
    acc = np.bincount(inv, weights=area)
    face = None
    for k in ub[::-1]:
        sel = (bins >= k - 1) & (bins <= k + 1)
        if acc[(ub >= k - 1) & (ub <= k + 1)].sum() < FACE_MIN_SHARE * across:
            continue
        pts = ftri[sel].reshape(-1, 3)
        if (np.ptp(np.stack([pts @ a, pts @ b], axis=1), axis=0) >= FACE_MIN_SPAN * span).all():
            face = float(np.average(d[sel], weights=area[sel]))
            break
    if face is None:
        order = np.argsort(d)
        cum = np.cumsum(area[order])
        face = float(d[order][np.searchsorted(cum, 0.85 * cum[-1])])
    on = np.abs(d - face) * metres <= 0.003
    pts = ftri[on].reshape(-1, 3)
    ab = np.stack([pts @ a, pts @ b], axis=1)
    return _Face(n, a, b, face, ab.min(axis=0), ab.max(axis=0))


def _geometric_handle(
    v: np.ndarray, f: np.ndarray, joint: Joint, metres: float, face: _Face
) -> tuple[Handle, dict[str, Any]] | None:
    """A handle modelled inside the part's mesh (no handle node): the surface standing
    out of the outer face plane ``face``, clustered into blobs; see the module docstring.

    ``v``, ``f``: the closed part's mesh in the object frame; ``metres``: the estimated
    metres per model unit. Returns the handle and what was measured, or None.
    """
    n = face.n
    margin = HANDLE_MARGIN / metres
    vd = v @ n
    out = vd[f].max(axis=1) > face.d + margin
    if not out.any():
        return None
    sub = trimesh.Trimesh(v, f[out], process=False)
    area = float(sub.area) * metres**2
    if area < HANDLE_MIN_AREA:
        return None
    count = int(np.clip(area / 0.002**2, 500, 40000))
    pts, _ = trimesh.sample.sample_surface(sub, count, seed=0)
    pts = pts[pts @ n > face.d + margin]
    if len(pts) == 0:
        return None
    per_point = area / count
    idx = np.floor((pts - pts.min(axis=0)) * metres / HANDLE_VOXEL).astype(np.int64)
    grid = np.zeros(idx.max(axis=0) + 1, bool)
    grid[tuple(idx.T)] = True
    labels, count_blobs = ndimage.label(grid, structure=np.ones((3, 3, 3)))
    blob_of = labels[tuple(idx.T)]
    centre = (face.lo + face.hi) / 2
    hinge_far = 0.0
    if joint.type == "revolute":
        corners = [
            face.point(x, y, face.d)
            for x in (face.lo[0], face.hi[0])
            for y in (face.lo[1], face.hi[1])
        ]
        hinge_far = max(_axis_distance(c, joint) for c in corners)
    best: tuple[float, Handle, dict[str, Any]] | None = None
    for k in range(1, count_blobs + 1):
        q = pts[blob_of == k]
        dq = q @ n
        depth = float(dq.max() - face.d)
        blob = (
            f"blob {k}: {len(q) * per_point * 1e4:.1f} cm2, standing {depth * metres * 1000:.0f} mm"
        )
        if len(q) * per_point < HANDLE_MIN_AREA:
            log.debug("%s: too small", blob)
            continue
        if depth * metres < HANDLE_MIN_STANDOFF:
            log.debug("%s: too flat", blob)
            continue
        outer = q[dq >= dq.max() - 0.35 * depth - 1e-12]
        flat = q - np.outer(q @ n, n)
        flat = flat - flat.mean(axis=0)
        _, _sv, vt = np.linalg.svd(flat, full_matrices=False)
        a = vt[0] - (vt[0] @ n) * n
        a = a / np.linalg.norm(a)
        b = np.cross(n, a)
        frame = np.stack([a, b, n])
        lo_o, hi_o = (outer @ frame.T).min(axis=0), (outer @ frame.T).max(axis=0)
        width = float(hi_o[1] - lo_o[1]) * metres
        if width > HANDLE_MAX_WIDTH:
            log.debug("%s: %.0f mm wide across the pinch", blob, width * 1000)
            continue
        pos = frame.T @ ((lo_o + hi_o) / 2)
        in_plane = np.array([pos @ face.a, pos @ face.b])
        ext = np.ptp(q @ frame.T, axis=0)
        if float(ext[0]) * metres < HANDLE_MIN_LENGTH:
            log.debug("%s: %.0f mm long", blob, float(ext[0]) * metres * 1000)
            continue  # a stud
        kind = "bar" if ext[0] >= 2.0 * max(float(ext[1]), 1e-9) else "knob"
        axis = a if kind == "bar" else face.a  # a knob: along the hinge, horizontal on a drawer
        if joint.type == "revolute":
            far = _axis_distance(pos, joint)
            if far < HANDLE_MIN_HINGE_SHARE * hinge_far:
                log.debug("%s: at the hinge", blob)  # a knuckle: no use for opening
                continue
            score = -far
        else:
            score = float(np.linalg.norm(in_plane - centre))
        info = {
            "source": "geometry",
            "kind": kind,
            "standoff_mm": round(depth * metres * 1000, 1),
            "width_mm": round(width * 1000, 1),
            "length_mm": round(float(ext[0]) * metres * 1000, 1),
        }
        if best is None or score < best[0] - 1e-9:
            best = (score, Handle(position=pos, axis=_positive(axis), kind=kind), info)
    return None if best is None else (best[1], best[2])


def _axis_distance(p: np.ndarray, joint: Joint) -> float:
    """Distance of point ``p`` from the joint's axis line."""
    axis = np.asarray(joint.axis, float) / np.linalg.norm(joint.axis)
    r = np.asarray(p, float) - joint.origin
    return float(np.linalg.norm(r - (r @ axis) * axis))


def _surface_probe(
    v: np.ndarray, f: np.ndarray, face: _Face
) -> Callable[[float, float], float | None]:
    """A function of an in-plane point (pa, pb) giving the offset along ``n`` of the
    outermost surface of the mesh there (a ray cast along -n), or None where there is none."""
    tri = v[f]
    ta, tb, tn = tri @ face.a, tri @ face.b, tri @ face.n
    a_lo, a_hi, b_lo, b_hi = ta.min(1), ta.max(1), tb.min(1), tb.max(1)

    def probe(pa: float, pb: float) -> float | None:
        near = (a_lo <= pa) & (a_hi >= pa) & (b_lo <= pb) & (b_hi >= pb)
        if not near.any():
            return None
        xa, xb, xn = ta[near], tb[near], tn[near]
        x0, y0 = xa[:, 0], xb[:, 0]
        e1x, e1y, e2x, e2y = xa[:, 1] - x0, xb[:, 1] - y0, xa[:, 2] - x0, xb[:, 2] - y0
        det = e1x * e2y - e2x * e1y
        ok = np.abs(det) > 1e-18
        det = np.where(ok, det, 1.0)
        u = ((pa - x0) * e2y - e2x * (pb - y0)) / det
        w = (e1x * (pb - y0) - (pa - x0) * e1y) / det
        inside = ok & (u >= -1e-9) & (w >= -1e-9) & (u + w <= 1 + 1e-9)
        if not inside.any():
            return None
        depth = xn[:, 0] + u * (xn[:, 1] - xn[:, 0]) + w * (xn[:, 2] - xn[:, 0])
        return float(depth[inside].max())

    return probe


def _added_grip(
    v: np.ndarray, f: np.ndarray, joint: Joint, metres: float, face: _Face
) -> tuple[trimesh.Trimesh, Handle, dict[str, Any]]:
    """A bar grip (two square standoffs and a square bar) for a part without a handle,
    in front of its outer face plane ``face``, in the object frame, with its handle and
    what was placed; see the module docstring."""
    u = 1.0 / metres  # model units per metre
    ext = (face.hi - face.lo) * metres
    length = min(GRIP_LENGTH, max(0.6 * float(ext[0]), 0.04))
    post_at = length / 2 - GRIP_POST  # standoff centres from the bar centre, along a
    mid_a = pa = float(face.lo[0] + face.hi[0]) / 2
    mid_b = float(face.lo[1] + face.hi[1]) / 2
    # candidate bar centres (along a, along b, how to say where), best first
    along = [0.0] + [s * k for k in (0.03, 0.06, 0.09) if k <= 0.25 * ext[0] for s in (1, -1)]
    across: list[tuple[float, str]] = []
    if joint.type == "revolute":  # near the free edge: 5 cm in, else nearer, else farther
        toward = face.point(pa, mid_b, face.d) - joint.origin
        side = 1.0 if toward @ face.b >= 0 else -1.0
        edge = float(face.hi[1] if side > 0 else face.lo[1])
        inset = min(GRIP_INSET, 0.25 * float(ext[1]))
        insets = [inset] + [x for x in (0.04, 0.03, 0.02) if x < inset]
        insets += list(np.arange(inset + 0.01, 0.5 * float(ext[1]) + 1e-9, 0.01))
        for x in insets:
            across.append(
                (edge - side * x * u, f"{x * 100:.0f} cm from the free edge, parallel to the hinge")
            )
    else:  # centred on the front, else a little off centre
        for x in np.arange(0.0, 0.25 * float(ext[1]) + 1e-9, 0.01):
            for sgn in (1.0,) if x == 0 else (1.0, -1.0):
                where = f"{x * 100:.0f} cm off centre on the front" if x else "centred on the front"
                across.append((mid_b + sgn * x * u, where + ", horizontal"))
    probe = _surface_probe(v, f, face)
    feet: list[float] | None = None
    pb, where = across[0]
    for da in along:
        for cb, text in across:
            ca = mid_a + da * u
            hits = [probe(ca + sgn * post_at * u, cb) for sgn in (-1.0, 1.0)]
            if all(
                h is not None and -GRIP_DEPTH * u <= h - face.d <= HANDLE_MARGIN * u for h in hits
            ):
                feet, pa, pb, where = [float(h) for h in hits if h is not None], ca, cb, text
                break
        if feet is not None:
            break
    on_surface = feet is not None
    if feet is None:  # no surface under both standoffs: they reach down to the face plane
        feet = [face.d, face.d]
    R = np.eye(4)
    R[:3, :3] = np.stack([face.a, face.b, face.n], axis=1)
    axis_n = face.d + GRIP_STANDOFF * u
    boxes = []

    def box(ca: float, cn: float, extents: Sequence[float]) -> None:
        T = R.copy()
        T[:3, 3] = face.point(ca, pb, cn)
        boxes.append(trimesh.creation.box(extents=np.asarray(extents) * u, transform=T))

    box(pa, axis_n, (length, GRIP_THICKNESS, GRIP_THICKNESS))
    top = axis_n - (GRIP_THICKNESS / 2 - 0.001) * u  # 1 mm into the bar
    for s, foot in zip((-1.0, 1.0), feet, strict=True):
        low = foot - 0.002 * u  # 2 mm into the part
        box(pa + s * post_at * u, (low + top) / 2, (GRIP_POST, GRIP_POST, (top - low) * metres))
    mesh = trimesh.util.concatenate(boxes)
    pos = face.point(pa, pb, axis_n)
    info = {
        "source": "added",
        "kind": "bar",
        "length_cm": round(length * 100, 1),
        "standoff_cm": round(GRIP_STANDOFF * 100, 1),
        "where": where,
        "on_surface": on_surface,
    }
    return mesh, Handle(position=pos, axis=_positive(face.a), kind="bar"), info


# --------------------------------------------------------------------------- batch


def _object_id(folder: Path) -> str:
    return sanitize_id(folder.name)


def import_objects(
    folders: Sequence[Path],
    out: str | Path,
    options: PartnetOptions | None = None,
    used: set[str] | None = None,
) -> ImportResult:
    """Convert and save each object folder as ``out/<id>/``; failures are recorded, not raised.

    The id is the folder name (made filename-safe; a numeric suffix keeps ids
    unique). An existing bundle is a failure unless ``options.overwrite``. A bundle
    is written only after its object converted completely (and ``save_bundle``
    writes atomically, ``object.json`` last).
    """
    opts = options or PartnetOptions()
    out = Path(out)
    used = set() if used is None else used
    result = ImportResult()
    for folder in folders:
        folder = Path(folder)
        base_id = _object_id(folder)
        oid, k = base_id, 1
        while oid in used:
            oid, k = f"{base_id}_{k}", k + 1
        used.add(oid)
        dest = out / oid
        t0 = time.perf_counter()
        existed = dest.exists()
        try:
            if is_bundle(dest) and not opts.overwrite:
                raise PartnetFormatError(
                    f"{dest}: a bundle already exists; pass overwrite (--overwrite) to replace it"
                )
            obj = convert_object(folder, opts)
            obj.provenance["id"] = oid
            if existed and opts.overwrite:
                for old in (dest / "parts").glob("*.glb"):
                    old.unlink()
            save_bundle(obj, dest)
        except Exception as e:  # noqa: BLE001 - one bad object never stops the batch
            log.debug("import of %s failed", folder, exc_info=True)
            if isinstance(e, (ImportFormatError, ObjectModelError)):
                message = str(e)
            elif isinstance(e, OSError):
                message = f"{e.filename or dest}: {e.strerror or e}"
            else:
                message = f"{folder / URDF_NAME}: {type(e).__name__}: {e}"
            if not existed and dest.exists():  # parts written before a failure: none left
                shutil.rmtree(dest, ignore_errors=True)
            result.failures.append(ImportFailure(folder, message))
            continue
        result.seconds[oid] = round(time.perf_counter() - t0, 3)
        result.warnings.extend(f"{folder}: {w}" for w in obj.provenance.get("warnings", []))
        log.info("imported %s -> %s (%d parts)", folder, dest, len(obj.parts))
        result.append(dest)
    return result
