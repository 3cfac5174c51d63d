"""The files of a built asset: the one reader and the one writer of each format.

A built asset folder (docs/architecture.md, "Built asset")::

    model.urdf                 links, joints, inertials, one <collision> per convex piece
    model.xml                  MJCF of the same model (written, never read)
    asset.json                 what URDF cannot say: category, semantics, materials,
                               colours, handles, bounds, metric scale (schema pact.asset v1)
    visual/<part>.glb, .obj    visual meshes (the OBJ for MJCF)
    collision/<part>_<k>.obj   convex pieces

:func:`save_asset` writes a :class:`~asset_pipeline.built_asset.BuiltAsset` (and the
meshes it holds in memory) into a folder; :func:`load_asset` reads one back: the
URDF with yourdfpy, then ``asset.json``. Every file is written atomically;
``asset.json`` is removed first and written last, so a folder whose ``asset.json``
exists holds a complete asset.

Reading is strict: a URDF that is not XML or not a ``<robot>``, a joint without a
parent, a number that is NaN or infinite anywhere, a mesh path that leaves the asset
folder (absolute, ``..``, a symlink out) or a malformed ``asset.json`` raise
:class:`AssetFormatError`, whose message names the file and every problem found.
"""

from __future__ import annotations

import io
import json
import logging
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from lxml import etree

from generator.articulated import atomic_write_bytes, mesh_to_glb

from .built_asset import (
    HANDLE_KINDS,
    BuiltAsset,
    CollisionPiece,
    Handle,
    Inertial,
    Joint,
    JointPhysics,
    Link,
    Visual,
)

log = logging.getLogger(__name__)

URDF_NAME = "model.urdf"
MJCF_NAME = "model.xml"
ASSET_JSON_NAME = "asset.json"
ASSET_SCHEMA = "pact.asset"
ASSET_VERSION = 1
#: Folders of the built-asset layout whose files the asset owns (stale ones are removed).
MESH_FOLDERS = ("visual", "collision")


class AssetFormatError(ValueError):
    """A built asset cannot be read; the message names the file and every problem."""

    def __init__(self, path: Path | str, problems: Iterable[str]) -> None:
        self.path = Path(path)
        self.problems = list(problems)
        super().__init__(f"{self.path}: " + "; ".join(self.problems))


# --------------------------------------------------------------------------- numbers


def fmt(x: float) -> str:
    """Deterministic short float text (10 significant digits, no negative zero)."""
    return f"{float(x) + 0.0:.10g}"


def vec(v: Any) -> str:
    return " ".join(fmt(x) for x in np.asarray(v, dtype=float).ravel())


def _round(v: Any) -> list[float]:
    return [round(float(x) + 0.0, 9) for x in np.asarray(v, dtype=float).ravel()]


def _is_identity(T: np.ndarray) -> bool:
    return bool(np.allclose(T, np.eye(4), rtol=0.0, atol=1e-12))


def _xyz_rpy(T: np.ndarray) -> tuple[str, str]:
    """URDF ``xyz`` and ``rpy`` (fixed-axis roll, pitch, yaw) text of a rigid (4, 4)."""
    if np.allclose(T[:3, :3], np.eye(3), rtol=0.0, atol=1e-12):
        rpy = np.zeros(3)
    else:
        rpy = np.array(trimesh.transformations.euler_from_matrix(T, axes="sxyz"))
    return vec(T[:3, 3]), vec(rpy)


def _quat_wxyz(T: np.ndarray) -> np.ndarray:
    return np.asarray(trimesh.transformations.quaternion_from_matrix(T), dtype=float)


# --------------------------------------------------------------------------- OBJ


def obj_text(mesh: trimesh.Trimesh, uv: np.ndarray | None = None) -> str:
    """Wavefront OBJ of the geometry (positions and faces; MuJoCo and PhysX read it), with
    ``uv`` (one texture coordinate per vertex, origin bottom-left) as ``vt`` lines."""
    if uv is None:
        return trimesh.exchange.obj.export_obj(
            mesh, include_normals=False, include_color=False, include_texture=False, header=None
        )
    v = np.asarray(mesh.vertices, dtype=float)
    f = np.asarray(mesh.faces, dtype=np.int64) + 1
    lines = [f"v {x:.8g} {y:.8g} {z:.8g}" for x, y, z in v]
    lines += [f"vt {a:.8g} {b:.8g}" for a, b in np.asarray(uv, dtype=float)]
    lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in f]
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


# --------------------------------------------------------------------------- URDF


def urdf_string(asset: BuiltAsset) -> str:
    """URDF of ``asset``: one link per part, one ``<collision>`` per convex piece."""
    robot = etree.Element("robot", name=asset.id)
    for link in asset.links:
        el = etree.SubElement(robot, "link", name=link.name)
        if link.inertial is not None:
            inertial = etree.SubElement(el, "inertial")
            etree.SubElement(inertial, "origin", xyz=vec(link.inertial.com), rpy="0 0 0")
            etree.SubElement(inertial, "mass", value=fmt(link.inertial.mass))
            i = link.inertial.inertia
            etree.SubElement(
                inertial,
                "inertia",
                ixx=fmt(i[0, 0]),
                ixy=fmt(i[0, 1]),
                ixz=fmt(i[0, 2]),
                iyy=fmt(i[1, 1]),
                iyz=fmt(i[1, 2]),
                izz=fmt(i[2, 2]),
            )
        for v in link.visuals:
            visual = etree.SubElement(el, "visual", name=v.name or f"{link.name}_visual")
            xyz, rpy = _xyz_rpy(v.origin)
            etree.SubElement(visual, "origin", xyz=xyz, rpy=rpy)
            geom = etree.SubElement(visual, "geometry")
            etree.SubElement(geom, "mesh", filename=v.filename)
        for k, piece in enumerate(link.collisions):
            col = etree.SubElement(el, "collision", name=piece.name or f"{link.name}_collision_{k}")
            xyz, rpy = _xyz_rpy(piece.origin)
            etree.SubElement(col, "origin", xyz=xyz, rpy=rpy)
            geom = etree.SubElement(col, "geometry")
            etree.SubElement(geom, "mesh", filename=piece.filename)
    for j in asset.joints:
        el = etree.SubElement(robot, "joint", name=j.name, type=j.type)
        etree.SubElement(el, "parent", link=j.parent)
        etree.SubElement(el, "child", link=j.child)
        xyz, rpy = _xyz_rpy(j.origin)
        etree.SubElement(el, "origin", xyz=xyz, rpy=rpy)
        if j.type != "fixed":
            etree.SubElement(el, "axis", xyz=vec(j.axis))
            etree.SubElement(
                el,
                "limit",
                lower=fmt(j.lower),
                upper=fmt(j.upper),
                effort=fmt(j.physics.effort),
                velocity=fmt(j.physics.velocity),
            )
            etree.SubElement(
                el, "dynamics", damping=fmt(j.physics.damping), friction=fmt(j.physics.friction)
            )
    return _xml_text(robot)


def _xml_text(root: etree._Element) -> str:
    return etree.tostring(root, pretty_print=True, xml_declaration=True, encoding="utf-8").decode()


#: URDF attributes that hold numbers.
_NUMERIC_ATTRIBUTES = frozenset(
    "xyz rpy value ixx ixy ixz iyy iyz izz lower upper effort velocity damping friction "
    "scale radius length size rgba multiplier offset soft_lower_limit soft_upper_limit "
    "k_position k_velocity rising falling".split()
)


def _nonfinite_attributes(root: etree._Element) -> list[str]:
    """Every numeric attribute holding NaN or inf, as ``element[name]/sub@attr = text``."""
    out = []
    for el in root.iter():
        if not isinstance(el.tag, str):
            continue
        for attr, text in el.attrib.items():
            if attr not in _NUMERIC_ATTRIBUTES:
                continue
            for tok in text.split():
                try:
                    x = float(tok)
                except ValueError:
                    continue
                if not math.isfinite(x):
                    owner = el
                    while owner is not None and owner.get("name") is None:
                        owner = owner.getparent()
                    where = f"{owner.tag}[{owner.get('name')}]" if owner is not None else el.tag
                    sub = "" if owner is el else f"/{el.tag}"
                    out.append(f"{where}{sub}@{attr} = {text!r} is not finite")
                    break
    return out


def _structure_problems(root: etree._Element) -> list[str]:
    """What yourdfpy would trip over without naming it: nameless links, joints without
    parent or child, mesh elements without a filename."""
    problems = []
    for k, el in enumerate(root.findall("link")):
        if not el.get("name"):
            problems.append(f"link #{k} has no name")
        for mesh in el.iter("mesh"):
            if not mesh.get("filename"):
                problems.append(f"link[{el.get('name')}]: a <mesh> has no filename")
    for k, el in enumerate(root.findall("joint")):
        name = el.get("name") or f"#{k}"
        if not el.get("name"):
            problems.append(f"joint {name} has no name")
        if not el.get("type"):
            problems.append(f"joint[{name}] has no type")
        for tag in ("parent", "child"):
            sub = el.find(tag)
            if sub is None or not sub.get("link"):
                problems.append(f"joint[{name}] has no <{tag} link=...>")
    return problems


def resolve_inside(folder: Path, filename: str) -> Path | str:
    """The path of ``filename`` (relative to ``folder``, ``package://`` stripped) when it
    stays inside ``folder`` after resolving ``..`` and symlinks, else a problem text."""
    rel = filename.removeprefix("package://")
    if Path(rel).is_absolute():
        return f"mesh path {filename!r} is absolute; it must be relative to the asset folder"
    root = folder.resolve()
    target = (folder / rel).resolve()
    if target != root and root not in target.parents:
        return f"mesh path {filename!r} leaves the asset folder"
    return folder / rel


def parse_robot(path: Path, missing: str = "URDF not found") -> Any:
    """The ``yourdfpy.Robot`` of a URDF file: the project's one URDF reader.

    Raises :class:`AssetFormatError` naming the file and every problem: not XML, not a
    ``<robot>``, a nameless link, a joint without parent or child, a NaN or infinite
    number anywhere (by element and attribute), or whatever yourdfpy refuses.
    """
    import yourdfpy

    if not path.is_file():
        raise AssetFormatError(path, [missing])
    try:
        root = etree.parse(str(path), etree.XMLParser(resolve_entities=False)).getroot()
    except (etree.XMLSyntaxError, OSError) as e:
        raise AssetFormatError(path, [f"not valid XML: {e}"]) from e
    if root.tag != "robot":
        raise AssetFormatError(
            path, [f"not a URDF: the root element is <{root.tag}>, a URDF's is <robot>"]
        )
    problems = _structure_problems(root) + _nonfinite_attributes(root)
    if problems:
        raise AssetFormatError(path, problems)
    try:
        return yourdfpy.URDF._parse_robot(xml_element=root)
    except Exception as e:  # noqa: BLE001 - yourdfpy raises many types on malformed input
        raise AssetFormatError(path, [f"malformed URDF: {type(e).__name__}: {e}"]) from e


def read_urdf(path: Path) -> tuple[str, list[Link], list[Joint]]:
    """(robot name, links, joints) of a built asset's URDF; raises :class:`AssetFormatError`.

    Mesh file names are checked to stay inside the URDF's folder and kept relative
    (``package://`` stripped).
    """
    robot = parse_robot(path, "URDF not found (run `pact build` first)")
    problems: list[str] = []
    folder = path.parent
    links = []
    for lk in robot.links:
        link = Link(name=lk.name)
        if lk.inertial is not None:
            origin = np.eye(4) if lk.inertial.origin is None else np.asarray(lk.inertial.origin)
            if not np.allclose(origin[:3, :3], np.eye(3), atol=1e-9):
                problems.append(f"link[{lk.name}]: a rotated <inertial> frame is not supported")
            inertia = lk.inertial.inertia
            link.inertial = Inertial(
                mass=float("nan") if lk.inertial.mass is None else lk.inertial.mass,
                com=origin[:3, 3],
                inertia=np.zeros((3, 3)) if inertia is None else inertia,
            )
        for elements, make, kind in (
            (lk.visuals, Visual, "visual"),
            (lk.collisions, CollisionPiece, "collision"),
        ):
            for k, el in enumerate(elements):
                mesh = el.geometry.mesh if el.geometry is not None else None
                if mesh is None:
                    problems.append(f"link[{lk.name}]: {kind} #{k} is not a mesh")
                    continue
                if mesh.scale is not None and not np.allclose(mesh.scale, 1.0):
                    problems.append(f"link[{lk.name}]: {kind} #{k} has a mesh scale")
                resolved = resolve_inside(folder, mesh.filename)
                if isinstance(resolved, str):
                    problems.append(f"link[{lk.name}]: {resolved}")
                    continue
                origin = np.eye(4) if el.origin is None else np.asarray(el.origin, dtype=float)
                rel = resolved.relative_to(folder).as_posix()
                if kind == "visual":
                    png = Path(rel).with_suffix(".png").as_posix()
                    texture = png if (folder / png).is_file() else None
                    link.visuals.append(
                        Visual(filename=rel, origin=origin, name=el.name or "", texture=texture)
                    )
                else:
                    link.collisions.append(make(filename=rel, origin=origin, name=el.name or ""))
        links.append(link)
    joints = []
    for jt in robot.joints:
        lim, dyn = jt.limit, jt.dynamics
        physics = JointPhysics(
            damping=float(dyn.damping or 0.0) if dyn is not None else 0.0,
            friction=float(dyn.friction or 0.0) if dyn is not None else 0.0,
            effort=float(lim.effort or 0.0) if lim is not None else 0.0,
            velocity=float(lim.velocity or 0.0) if lim is not None else 0.0,
        )
        lower = jt.limit.lower if jt.limit is not None and jt.limit.lower is not None else 0.0
        upper = jt.limit.upper if jt.limit is not None and jt.limit.upper is not None else 0.0
        joints.append(
            Joint(
                name=jt.name,
                type=jt.type,
                parent=jt.parent,
                child=jt.child,
                origin=np.eye(4) if jt.origin is None else jt.origin,
                axis=np.array([1.0, 0.0, 0.0]) if jt.axis is None else jt.axis,
                lower=lower,
                upper=upper,
                physics=physics,
            )
        )
    if problems:
        raise AssetFormatError(path, problems)
    return robot.name, links, joints


# --------------------------------------------------------------------------- MJCF

_MJCF_JOINT = {"prismatic": "slide", "revolute": "hinge", "continuous": "hinge"}


def _geom_pose(attrs: dict[str, str], T: np.ndarray) -> dict[str, str]:
    if not _is_identity(T):
        attrs["pos"] = vec(T[:3, 3])
        attrs["quat"] = vec(_quat_wxyz(T))
    return attrs


def mjcf_string(asset: BuiltAsset) -> str:
    """MJCF of ``asset``: the root body welded to the world, slide/hinge joints.

    Collision geoms are the convex pieces (group 3); each visual mesh is a
    non-colliding geom (``contype=0 conaffinity=0``, group 1) with a material mapping
    its texture (``Visual.texture``) onto the OBJ's texture coordinates, else the
    link's mean colour. Mesh and texture files are relative to the model file.
    """
    root = etree.Element("mujoco", model=asset.id)
    etree.SubElement(root, "compiler", angle="radian", meshdir=".", autolimits="true")
    assets = etree.SubElement(root, "asset")
    for link in asset.links:
        for k, v in enumerate(link.visuals):
            name = f"{link.name}_visual" if k == 0 else f"{link.name}_visual_{k}"
            etree.SubElement(assets, "mesh", name=name, file=v.obj_filename)
            if v.texture:
                etree.SubElement(
                    assets, "texture", name=f"{name}_texture", type="2d", file=v.texture
                )
                etree.SubElement(
                    assets, "material", name=f"{name}_material", texture=f"{name}_texture"
                )
        for k, piece in enumerate(link.collisions):
            etree.SubElement(assets, "mesh", name=f"{link.name}_collision_{k}", file=piece.filename)
    world = etree.SubElement(root, "worldbody")
    bodies: dict[str, etree._Element] = {}
    joint_of = {j.child: j for j in asset.joints}
    for link in asset.links:
        j = joint_of.get(link.name)
        parent = world if j is None else bodies[j.parent]
        attrs = {"name": link.name, "pos": vec(np.zeros(3) if j is None else j.origin[:3, 3])}
        if j is not None and not np.allclose(j.origin[:3, :3], np.eye(3), atol=1e-12):
            attrs["quat"] = vec(_quat_wxyz(j.origin))
        body = etree.SubElement(parent, "body", **attrs)
        bodies[link.name] = body
        if link.inertial is not None:
            i = link.inertial.inertia
            etree.SubElement(
                body,
                "inertial",
                pos=vec(link.inertial.com),
                mass=fmt(link.inertial.mass),
                # MuJoCo order: Ixx Iyy Izz Ixy Ixz Iyz
                fullinertia=vec(i[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]]),
            )
        if j is not None and j.type in _MJCF_JOINT:
            etree.SubElement(
                body,
                "joint",
                name=j.name,
                type=_MJCF_JOINT[j.type],
                axis=vec(j.axis),
                range=vec([j.lower, j.upper]),
                limited="true",
                damping=fmt(j.physics.damping),
                frictionloss=fmt(j.physics.friction),
                actuatorfrcrange=vec([-j.physics.effort, j.physics.effort]),
            )
        for k, v in enumerate(link.visuals):
            name = f"{link.name}_visual" if k == 0 else f"{link.name}_visual_{k}"
            attrs = {
                "name": name,
                "type": "mesh",
                "mesh": name,
                "contype": "0",
                "conaffinity": "0",
                "group": "1",
                "mass": "0",
            }
            if v.texture:
                attrs["material"] = f"{name}_material"
            else:
                attrs["rgba"] = vec(np.clip(link.rgba, 0, 1))
            etree.SubElement(body, "geom", **_geom_pose(attrs, v.origin))
        for k, piece in enumerate(link.collisions):
            attrs = {
                "name": f"{link.name}_collision_{k}",
                "type": "mesh",
                "mesh": f"{link.name}_collision_{k}",
                "group": "3",
                "mass": "0",
            }
            etree.SubElement(body, "geom", **_geom_pose(attrs, piece.origin))
    return _xml_text(root)


# --------------------------------------------------------------------------- asset.json


def asset_json_document(asset: BuiltAsset) -> dict[str, Any]:
    """The ``asset.json`` document (schema ``pact.asset`` v1) of ``asset``.

    Joint origins and axes, and handle positions, are given in the object frame at
    rest (``position_link`` in the part's link frame), for readers without a URDF
    parser; :func:`load_asset` takes the joints from the URDF.
    """
    rest = asset.link_poses()
    links = [
        {
            "name": link.name,
            "semantic": link.semantic,
            "mass": None if link.inertial is None else round(link.inertial.mass, 9),
            "material": link.material,
            "visual": link.visuals[0].filename if link.visuals else None,
            "collision": [p.filename for p in link.collisions],
            "rgba": _round(link.rgba),
        }
        for link in asset.links
    ]
    joints = []
    for j in asset.joints:
        frame = rest.get(j.parent, np.eye(4)) @ j.origin
        joints.append(
            {
                "name": j.name,
                "parent": j.parent,
                "child": j.child,
                "type": j.type,
                "origin": _round(frame[:3, 3]),
                "axis": _round(frame[:3, :3] @ j.unit_axis),
                "lower": round(j.lower, 9),
                "upper": round(j.upper, 9),
                "damping": j.physics.damping,
                "friction": j.physics.friction,
                "effort": j.physics.effort,
                "velocity": j.physics.velocity,
            }
        )
    handles = {}
    for part, h in asset.handles.items():
        T = rest.get(part, np.eye(4))
        handles[part] = {
            "position": _round(T[:3, :3] @ h.position_link + T[:3, 3]),
            "position_link": _round(h.position_link),
            "axis": _round(h.axis),
            "kind": h.kind,
        }
    bounds = asset.bounds if asset.bounds is not None else np.zeros((2, 3))
    return {
        "schema": ASSET_SCHEMA,
        "version": ASSET_VERSION,
        "id": asset.id,
        "category": asset.category,
        "metric_scale": asset.metric_scale,
        "bounds": [_round(bounds[0]), _round(bounds[1])],
        "links": links,
        "joints": joints,
        "handles": handles,
    }


def _vec3(v: Any, where: str, problems: list[str]) -> np.ndarray | None:
    try:
        a = np.asarray(v, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != (3,) or not np.isfinite(a).all():
        problems.append(f"{where}: expected 3 finite numbers, got {v!r}")
        return None
    return a


def read_asset_json(path: Path) -> dict[str, Any]:
    """The checked ``asset.json`` document; raises :class:`AssetFormatError`."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as e:
        raise AssetFormatError(path, ["not found (run `pact build` first)"]) from e
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise AssetFormatError(path, [f"not valid JSON: {e}"]) from e
    if not isinstance(doc, dict):
        raise AssetFormatError(path, ["the top level must be a JSON object"])
    if doc.get("schema", ASSET_SCHEMA) != ASSET_SCHEMA:
        raise AssetFormatError(path, [f"schema {doc.get('schema')!r} is not {ASSET_SCHEMA!r}"])
    if doc.get("version", ASSET_VERSION) != ASSET_VERSION:
        raise AssetFormatError(
            path, [f"version {doc.get('version')!r}: this pact reads version {ASSET_VERSION}"]
        )
    for key, kind in (("links", list), ("joints", list), ("handles", dict)):
        if not isinstance(doc.get(key, kind()), kind):
            raise AssetFormatError(path, [f"{key}: must be a {kind.__name__}"])
    return doc


def _apply_metadata(asset: BuiltAsset, doc: dict[str, Any], path: Path) -> None:
    """Fill ``asset``'s identity, link semantics and handles from an asset.json document."""
    problems: list[str] = []
    asset.id = str(doc.get("id", asset.id))
    asset.category = str(doc.get("category", asset.category))
    scale = doc.get("metric_scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not scale > 0:
        problems.append(f"metric_scale: must be a positive number, got {scale!r}")
    else:
        asset.metric_scale = float(scale)
    b = doc.get("bounds")
    if b is not None:
        lo = _vec3(b[0] if isinstance(b, list) and len(b) == 2 else None, "bounds", problems)
        hi = _vec3(b[1] if isinstance(b, list) and len(b) == 2 else None, "bounds", problems)
        if lo is not None and hi is not None:
            asset.bounds = np.stack([lo, hi])
    names = {k.name: k for k in asset.links}
    for i, d in enumerate(doc.get("links", [])):
        if not isinstance(d, dict) or d.get("name") not in names:
            continue
        link = names[d["name"]]
        link.semantic = str(d.get("semantic", link.semantic))
        link.material = str(d.get("material", link.material))
        if "rgba" in d:
            try:
                rgba = np.asarray(d["rgba"], dtype=float).reshape(4)
            except (TypeError, ValueError):
                problems.append(f"links[{i}].rgba: expected 4 numbers, got {d['rgba']!r}")
            else:
                link.rgba = rgba
    for part, h in doc.get("handles", {}).items():
        where = f"handles[{part}]"
        if part not in names:
            problems.append(f"{where}: no link named {part!r} in the URDF")
            continue
        if not isinstance(h, dict):
            problems.append(f"{where}: must be an object")
            continue
        pos = _vec3(h.get("position_link"), f"{where}.position_link", problems)
        axis = _vec3(h.get("axis", [0, 0, 1]), f"{where}.axis", problems)
        kind = str(h.get("kind", "none"))
        if kind not in HANDLE_KINDS:
            problems.append(f"{where}.kind: {kind!r} is not one of {list(HANDLE_KINDS)}")
        if pos is not None and axis is not None:
            asset.handles[part] = Handle(position_link=pos, axis=axis, kind=kind)
    if problems:
        raise AssetFormatError(path, problems)


def load_asset(folder: str | Path, *, metadata: bool = True) -> BuiltAsset:
    """Read the built asset in ``folder`` (the URDF, then ``asset.json``).

    ``metadata=False`` reads a folder that has only a URDF (an asset made elsewhere):
    links then have no semantics and movable parts no handles. Raises
    :class:`AssetFormatError`; see the module docstring. Mesh files are not opened.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise AssetFormatError(folder, ["not a folder (a built asset is a folder)"])
    name, links, joints = read_urdf(folder / URDF_NAME)
    asset = BuiltAsset(id=name or folder.name, links=links, joints=joints, folder=folder)
    for link in asset.links:
        if asset.joint_of(link.name) is None:
            link.semantic = "base"
    meta = folder / ASSET_JSON_NAME
    if metadata or meta.is_file():
        _apply_metadata(asset, read_asset_json(meta), meta)
    return asset


def missing_files(asset: BuiltAsset) -> list[str]:
    """Referenced files of ``asset`` (relative names) that do not exist, in link order."""
    out = []
    for link in asset.links:
        for name in [v.filename for v in link.visuals] + [p.filename for p in link.collisions]:
            if not asset.path_of(name).is_file():
                out.append(name)
    return out


# --------------------------------------------------------------------------- writing


def _write(path: Path, data: bytes | str) -> None:
    atomic_write_bytes(path, data.encode() if isinstance(data, str) else data)


def save_asset(asset: BuiltAsset, folder: str | Path | None = None) -> Path:
    """Write ``asset`` into ``folder`` (default: ``asset.folder``) and set ``asset.folder``.

    Meshes held in memory (``Visual.mesh``, ``CollisionPiece.mesh``) are written; files
    under ``visual/`` and ``collision/`` that the asset no longer references are
    removed; then ``model.urdf``, ``model.xml`` and, last, ``asset.json``. Raises
    OSError when a file cannot be written. Returns the folder.
    """
    folder = Path(folder) if folder is not None else asset.folder
    if folder is None:
        raise ValueError(f"asset {asset.id!r}: no folder to save into")
    folder.mkdir(parents=True, exist_ok=True)
    (folder / ASSET_JSON_NAME).unlink(missing_ok=True)
    keep: set[Path] = set()
    for link in asset.links:
        for v in link.visuals:
            keep.update({folder / v.filename, folder / v.obj_filename})
            if v.mesh is not None:
                _write(folder / v.filename, mesh_to_glb(v.mesh))
                textured = texture_image(v.mesh)
                v.texture = None
                if textured is not None:
                    v.texture = Path(v.filename).with_suffix(".png").as_posix()
                    _write(folder / v.texture, textured[1])
                _write(
                    folder / v.obj_filename,
                    obj_text(v.mesh, None if textured is None else textured[0]),
                )
            if v.texture:
                keep.add(folder / v.texture)
        for piece in link.collisions:
            keep.add(folder / piece.filename)
            if piece.mesh is not None:
                _write(folder / piece.filename, obj_text(piece.mesh))
    for sub in MESH_FOLDERS:
        for old in sorted((folder / sub).glob("*")) if (folder / sub).is_dir() else []:
            if old.is_file() and old not in keep and old.suffix in (".obj", ".glb", ".png"):
                log.debug("removing stale %s", old)
                old.unlink()
    _write(folder / URDF_NAME, urdf_string(asset))
    _write(folder / MJCF_NAME, mjcf_string(asset))
    _write(folder / ASSET_JSON_NAME, json.dumps(asset_json_document(asset), indent=2) + "\n")
    asset.folder = folder
    return folder
