"""The asset's USD checked with USD's own tools: the stage opens, USD's validators report
nothing, and USD's physics parser reads back what the URDF says.

:func:`usd_validation_errors` runs every validator of ``UsdValidation``'s registry (the
``usdPhysicsValidators`` for articulations, rigid bodies, colliders and joints among
them) on the stage. :func:`read_usd_physics` reads the stage with
``UsdPhysics.LoadUsdPhysicsFromRange`` (bodies, joints, limits, drives, collision shapes)
and ``UsdPhysics.MassAPI`` (masses); :func:`usd_urdf_differences` compares that with the
asset's model read from ``model.urdf``. :func:`usd_checks` makes them the ``usd_stage``
and ``usd_matches_urdf`` checks of validation's static stage (run when the folder holds
a USD).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.assets.usd import USD_NAME, prim_name
from asset_pipeline.validate.report import Check

#: Relative tolerance of numbers read back (the stage stores 32-bit floats).
READBACK_RTOL = 1e-5
READBACK_ATOL = 1e-6


@dataclass
class UsdBody:
    mass: float | None = None
    com: np.ndarray | None = None
    inertia: np.ndarray | None = None  # (3, 3) about the centre of mass, body frame
    colliders: int = 0
    convex_hulls: int = 0


@dataclass
class UsdJoint:
    type: str  # "prismatic", "revolute" or "fixed"
    body0: str | None
    body1: str | None
    lower: float | None = None  # metres or radians
    upper: float | None = None
    axis0: np.ndarray | None = None  # (3,) joint axis in body0's frame
    pos0: np.ndarray | None = None  # (3,) joint position in body0's frame
    drive: dict[str, float] = field(default_factory=dict)


@dataclass
class UsdPhysicsContent:
    """What USD's physics parser reads from a stage: bodies and joints by prim name."""

    articulations: int
    bodies: dict[str, UsdBody]
    joints: dict[str, UsdJoint]
    up_axis: str
    meters_per_unit: float


def open_stage(path: str | Path):
    """The stage of a USD file; raises ValueError naming the file when it does not open."""
    from pxr import Usd

    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as e:  # noqa: BLE001 - pxr raises Tf errors of several kinds
        raise ValueError(f"{path}: the stage does not open: {e}") from e
    if stage is None:
        raise ValueError(f"{path}: the stage does not open")
    return stage


def usd_validation_errors(stage) -> list[str]:
    """Every error or warning of every registered USD validator, as
    ``validator: error: message``."""
    from pxr import UsdValidation

    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    out = []
    for e in errors:
        validator = e.GetValidator()
        by = validator.GetMetadata().name if validator is not None else "?"
        out.append(f"{by}: {e.GetName()}: {e.GetMessage()}")
    return out


def _name(path: Any) -> str | None:
    text = str(path)
    return None if not text or text == "/" else text.rsplit("/", 1)[-1]


def _rotate(q, v: np.ndarray) -> np.ndarray:
    from pxr import Gf

    r = Gf.Rotation(Gf.Quatd(q))
    return np.asarray(r.TransformDir(Gf.Vec3d(*[float(x) for x in v])), dtype=float)


_AXES = {"X": np.array([1.0, 0, 0]), "Y": np.array([0, 1.0, 0]), "Z": np.array([0, 0, 1.0])}


def read_usd_physics(stage) -> UsdPhysicsContent:
    """Bodies, joints, limits, drives, masses and colliders of a stage, as USD reads them."""
    from pxr import Sdf, UsdGeom, UsdPhysics

    found = UsdPhysics.LoadUsdPhysicsFromRange(stage, [Sdf.Path("/")])
    bodies: dict[str, UsdBody] = {}
    joints: dict[str, UsdJoint] = {}
    articulations = 0
    for kind, (paths, descs) in found.items():
        kind = str(kind).rsplit(".", 1)[-1]
        for path, desc in zip(paths, descs, strict=True):
            name = _name(path)
            if kind == "Articulation":
                articulations += 1
            elif kind == "RigidBody":
                body = bodies.setdefault(name, UsdBody())
                mass = UsdPhysics.MassAPI(stage.GetPrimAtPath(path))
                if mass:
                    body.mass = float(mass.GetMassAttr().Get())
                    body.com = np.asarray(mass.GetCenterOfMassAttr().Get(), dtype=float)
                    d = np.asarray(mass.GetDiagonalInertiaAttr().Get(), dtype=float)
                    q = mass.GetPrincipalAxesAttr().Get()
                    R = np.stack([_rotate(q, e) for e in np.eye(3)], axis=1)
                    body.inertia = R @ np.diag(d) @ R.T
            elif kind.endswith("Shape"):
                body = bodies.setdefault(_name(desc.rigidBody), UsdBody())
                body.colliders += 1
                if kind == "MeshShape" and str(desc.approximation) == "convexHull":
                    body.convex_hulls += 1
            elif kind.endswith("Joint"):
                jtype = {"PrismaticJoint": "prismatic", "RevoluteJoint": "revolute"}.get(
                    kind, "fixed" if kind == "FixedJoint" else kind
                )
                joint = UsdJoint(jtype, _name(desc.body0), _name(desc.body1))
                joint.pos0 = np.asarray(desc.localPose0Position, dtype=float)
                if jtype in ("prismatic", "revolute"):
                    scale = math.radians(1.0) if jtype == "revolute" else 1.0
                    axis = _AXES[str(desc.axis).rsplit(".", 1)[-1][-1]]
                    joint.axis0 = _rotate(desc.localPose0Orientation, axis)
                    if desc.limit.enabled:
                        joint.lower = float(desc.limit.lower) * scale
                        joint.upper = float(desc.limit.upper) * scale
                    if desc.drive.enabled:
                        joint.drive = {
                            "stiffness": float(desc.drive.stiffness),
                            "damping": float(desc.drive.damping),
                            "max_force": float(desc.drive.forceLimit),
                        }
                joints[name] = joint
    return UsdPhysicsContent(
        articulations=articulations,
        bodies=bodies,
        joints=joints,
        up_axis=str(UsdGeom.GetStageUpAxis(stage)),
        meters_per_unit=float(UsdGeom.GetStageMetersPerUnit(stage)),
    )


def _close(a: Any, b: Any, scale: float = 1.0) -> bool:
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(
        np.allclose(a, b, rtol=READBACK_RTOL, atol=READBACK_ATOL * max(scale, 1.0))
    )


def usd_urdf_differences(asset: BuiltAsset, usd: UsdPhysicsContent) -> list[str]:
    """Every way the USD's physics differs from the asset's URDF model (empty when equal):
    links, masses, centres of mass, inertias, collider counts, joint types, parents,
    children, axes, origins, limits; one articulation; the root fixed to the world."""
    out: list[str] = []
    if usd.up_axis != "Z" or usd.meters_per_unit != 1.0:
        out.append(f"stage is {usd.up_axis} up, {usd.meters_per_unit} m per unit (want Z, 1)")
    if usd.articulations != 1:
        out.append(f"{usd.articulations} articulations (want 1)")
    want_links = {prim_name(k.name): k for k in asset.links}
    if set(usd.bodies) != set(want_links):
        out.append(f"rigid bodies {sorted(usd.bodies)} != links {sorted(want_links)}")
    for name, link in want_links.items():
        body = usd.bodies.get(name)
        if body is None:
            continue
        if len(link.collisions) != body.colliders or body.colliders != body.convex_hulls:
            out.append(
                f"{name}: {body.colliders} colliders ({body.convex_hulls} convex hulls), "
                f"URDF {len(link.collisions)}"
            )
        if link.inertial is None:
            continue
        inertial = link.inertial
        if body.mass is None or not _close(body.mass, inertial.mass, inertial.mass):
            out.append(f"{name}: mass {body.mass} != {inertial.mass}")
        elif not _close(body.com, inertial.com):
            out.append(f"{name}: centre of mass {body.com} != {inertial.com}")
        # UsdPhysics keeps the principal axes as a float quaternion (quatf): rotating
        # the diagonal back moves every entry by up to ~1e-7 of the largest moment, and
        # more for a near-degenerate pair of moments, so entries compare on that scale.
        elif not np.allclose(
            body.inertia, inertial.inertia, rtol=0, atol=1e-4 * np.abs(inertial.inertia).max()
        ):
            out.append(f"{name}: inertia {body.inertia.tolist()} != {inertial.inertia.tolist()}")
    want_joints = {prim_name(j.name): j for j in asset.joints}
    fixed = [n for n, j in usd.joints.items() if n not in want_joints]
    roots = [n for n in fixed if usd.joints[n].type == "fixed" and usd.joints[n].body0 is None]
    if [usd.joints[n].body1 for n in roots] != [prim_name(asset.root)]:
        out.append(f"the root {asset.root!r} is not fixed to the world by one fixed joint")
    for name, j in want_joints.items():
        uj = usd.joints.get(name)
        if uj is None:
            out.append(f"joint {name} missing")
            continue
        want_type = "revolute" if j.type == "continuous" else j.type
        if uj.type != want_type:
            out.append(f"{name}: type {uj.type} != {j.type}")
            continue
        if (uj.body0, uj.body1) != (prim_name(j.parent), prim_name(j.child)):
            out.append(f"{name}: bodies {uj.body0} -> {uj.body1} != {j.parent} -> {j.child}")
        if not _close(uj.pos0, j.origin[:3, 3]):
            out.append(f"{name}: origin {uj.pos0} != {j.origin[:3, 3]}")
        if not j.movable:
            continue
        axis = j.origin[:3, :3] @ j.unit_axis
        if uj.axis0 is None or not np.allclose(uj.axis0, axis, atol=1e-5):
            out.append(f"{name}: axis {uj.axis0} != {axis}")
        if j.type != "continuous" and (
            uj.lower is None
            or not _close([uj.lower, uj.upper], [j.lower, j.upper], abs(j.upper) + abs(j.lower))
        ):
            out.append(f"{name}: limits [{uj.lower}, {uj.upper}] != [{j.lower}, {j.upper}]")
    return out


def usd_checks(asset: BuiltAsset, name: str = USD_NAME) -> list[Check]:
    """``usd_stage`` (opens; USD's validators report nothing) and ``usd_matches_urdf``
    (USD's physics parser reads back the URDF's links, joints, limits, masses, colliders)."""
    path = asset.path_of(name)
    try:
        stage = open_stage(path)
    except ValueError as e:
        return [Check("usd_stage", "static", "asset", False, str(e), "opens", str(e))]
    errors = usd_validation_errors(stage)
    checks = [
        Check(
            "usd_stage",
            "static",
            "asset",
            not errors,
            value=errors or "valid",
            tolerance="no validator error",
            message="" if not errors else f"{len(errors)} USD validator errors: {errors[:3]}",
        )
    ]
    diffs = usd_urdf_differences(asset, read_usd_physics(stage))
    checks.append(
        Check(
            "usd_matches_urdf",
            "static",
            "asset",
            not diffs,
            value=diffs or "equal",
            tolerance=f"rtol {READBACK_RTOL:g}",
            message="" if not diffs else "; ".join(diffs[:4]),
        )
    )
    return checks
