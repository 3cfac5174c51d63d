"""``model.urdf``: the one writer (:func:`urdf_string`) and the one reader
(:func:`read_urdf`, strict: every problem named) of a built asset's URDF.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import numpy as np
from lxml import etree

from asset_pipeline.assets.built_asset import (
    BuiltAsset,
    CollisionPiece,
    Inertial,
    Joint,
    JointPhysics,
    Link,
    Visual,
)
from asset_pipeline.assets.layout import AssetFormatError
from asset_pipeline.assets.xml_text import fmt, vec, xyz_rpy

log = logging.getLogger(__name__)

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
            xyz, rpy = xyz_rpy(v.origin)
            etree.SubElement(visual, "origin", xyz=xyz, rpy=rpy)
            geom = etree.SubElement(visual, "geometry")
            etree.SubElement(geom, "mesh", filename=v.filename)
        for k, piece in enumerate(link.collisions):
            col = etree.SubElement(el, "collision", name=piece.name or f"{link.name}_collision_{k}")
            xyz, rpy = xyz_rpy(piece.origin)
            etree.SubElement(col, "origin", xyz=xyz, rpy=rpy)
            geom = etree.SubElement(col, "geometry")
            etree.SubElement(geom, "mesh", filename=piece.filename)
    for j in asset.joints:
        el = etree.SubElement(robot, "joint", name=j.name, type=j.type)
        etree.SubElement(el, "parent", link=j.parent)
        etree.SubElement(el, "child", link=j.child)
        xyz, rpy = xyz_rpy(j.origin)
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
    return xml_text(robot)


def xml_text(root: etree._Element) -> str:
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
