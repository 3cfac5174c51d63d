"""``model.xml``: the one writer of a built asset's MJCF (MuJoCo); it is never read back."""

from __future__ import annotations

import numpy as np
from lxml import etree

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.assets.urdf import xml_text
from asset_pipeline.assets.xml_text import fmt, is_identity, quat_wxyz, vec

# --------------------------------------------------------------------------- MJCF

_MJCF_JOINT = {"prismatic": "slide", "revolute": "hinge", "continuous": "hinge"}
#: ``solreflimit`` of every joint (time constant, damping ratio): stiff joint limits.
LIMIT_SOLREF = "0.005 1"
#: ``solreffriction`` of every joint: dry friction that holds (as PhysX's joint friction).
FRICTION_SOLREF = "0.005 1"


def _geom_pose(attrs: dict[str, str], T: np.ndarray) -> dict[str, str]:
    if not is_identity(T):
        attrs["pos"] = vec(T[:3, 3])
        attrs["quat"] = vec(quat_wxyz(T))
    return attrs


def mjcf_string(asset: BuiltAsset) -> str:
    """MJCF of ``asset``: the root body welded to the world, slide/hinge joints.

    Contacts between a part and its parent are excluded (``<contact><exclude>``), as a
    URDF's are in PhysX. MuJoCo filters parent-child contacts itself only when the parent
    is not welded to the world, so without the exclusions a part of a fixed base would
    collide with its carcass wherever their convex pieces meet (a drawer pushed shut, a
    piece overlapping the carcass) and be pushed where SAPIEN's part is not.

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
            attrs["quat"] = vec(quat_wxyz(j.origin))
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
                # MuJoCo's default soft limit (time constant 0.02 s) lets a 40 N pull carry a
                # drawer 1 cm and a door 5 deg past its limit; 0.005 s (MuJoCo needs at least
                # twice its 2 ms default timestep) holds it as PhysX does (docs/validation.md)
                solreflimit=LIMIT_SOLREF,
                damping=fmt(j.physics.damping),
                # the asset's friction is PhysX's coefficient; MuJoCo's is a force
                frictionloss=fmt(asset.friction_force(j)),
                # frictionloss is a soft constraint: with MuJoCo's default (0.02 s) a part
                # held by its friction against gravity (an oven door ajar) creeps open
                # ~1 deg/s; 0.005 s makes it hold as PhysX's joint friction does
                solreffriction=FRICTION_SOLREF,
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
    if asset.joints:
        contact = etree.SubElement(root, "contact")
        for j in asset.joints:
            etree.SubElement(contact, "exclude", body1=j.parent, body2=j.child)
    return xml_text(root)
