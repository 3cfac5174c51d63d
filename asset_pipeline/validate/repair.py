"""Automatic repairs of a built asset, driven by failed validation checks.

:func:`plan_repairs` maps failed checks to edits of the asset's model
(:class:`~asset_pipeline.assets.built_asset.BuiltAsset`) and returns one
:class:`~asset_pipeline.validate.report.RepairRecord` per edit (what, on which joint or
link, before and after). It touches no file: the runner
(:mod:`asset_pipeline.validate.runner`) writes the edited model with
:func:`asset_pipeline.asset_io.save_asset` and checks everything again. Repairs, by
the check that triggers them:

``hinge_on_part``      move the revolute joint's origin onto the closest point of the
                       part's AABB surface (PAct's post-processing); the part's geometry,
                       centre of mass and handle move back by the same amount (their
                       ``origin`` in the link frame), so the part stays put
``opens_outward``      flip the joint axis (the part opened into the base)
``drawer_engaged``     shorten the prismatic range so that ``ENGAGED_TARGET`` of the part's
                       length stays inside the base at the upper limit
``rest_penetration``   shrink the overlapping convex pieces of the movable part(s) along
                       the contact normal, about their centroid
``rest_drift``         raise the joint's damping and friction
``free_base_stable``   a 3 mm plate under the base's feet (``level_base``): uneven feet
                       stand level on it

At most one joint-level repair per joint per round (the first in the order
above), because each changes what the later checks measure. Everything else
(reversed limits, zero mass, uncookable pieces, a jammed drive, ...) is not
repairable and is reported with its reason.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from typing import Any

import numpy as np
import trimesh

from asset_pipeline.assets.built_asset import BuiltAsset, CollisionPiece
from asset_pipeline.assets.mesh_files import read_obj
from asset_pipeline.validate.report import Check, RepairRecord, Tolerances

log = logging.getLogger(__name__)

#: Fraction of a drawer's length kept inside the base after shortening its range.
ENGAGED_TARGET = 0.15
#: A shortened range keeps at least this fraction of the original, else unrepairable.
MIN_RANGE_KEPT = 0.25
#: Extra clearance (m) added when shrinking overlapping pieces.
SHRINK_MARGIN = 0.001
#: A piece may lose at most this fraction of its extent along the contact normal.
MAX_SHRINK = 0.5
#: Damping ceilings (N s/m for prismatic, N m s/rad for revolute) and friction floor.
MAX_DAMPING = {"prismatic": 20.0, "revolute": 5.0}
MIN_DAMPING = {"prismatic": 1.0, "revolute": 0.2}
MIN_FRICTION = 0.1
MAX_FRICTION = 2.0

REPAIR_ORDER = ("hinge_on_part", "opens_outward", "drawer_engaged", "rest_drift")


def _translation(d: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = d
    return T


def flip_axis(asset: BuiltAsset, joint: str, reason: str) -> RepairRecord:
    j = asset.joint(joint)
    before = j.axis.copy()
    j.axis = -before
    return RepairRecord("flip_axis", joint, before.tolist(), j.axis.tolist(), reason)


def shorten_range(
    asset: BuiltAsset, joint: str, details: dict[str, Any], reason: str
) -> RepairRecord | str:
    lower, upper = float(details["lower"]), float(details["upper"])
    need = ENGAGED_TARGET * float(details["length"]) - float(details["overlap"])
    new_upper = upper - need
    if new_upper - lower < MIN_RANGE_KEPT * (upper - lower) or new_upper - lower < 0.01:
        return (
            f"{joint}: the range would shrink from {upper - lower:.3f} m to "
            f"{new_upper - lower:.3f} m to keep the part engaged; the part is too short for its slide"
        )
    asset.joint(joint).upper = new_upper
    return RepairRecord(
        "shorten_prismatic_range", joint, [lower, upper], [lower, new_upper], reason
    )


def add_damping(
    asset: BuiltAsset,
    joint: str,
    details: dict[str, Any],
    drift: float,
    limit: float,
    reason: str,
) -> RepairRecord | str:
    j = asset.joint(joint)
    d0, f0 = float(details.get("damping", 0.0)), float(details.get("friction", 0.0))
    duration = float(details.get("duration", 2.0))
    tau = abs(float(details.get("gravity_force", 0.0)))
    cap = MAX_DAMPING.get(j.type, 5.0)
    # damping that would hold the measured gravity force to half the tolerance
    need = tau * duration / (0.5 * limit) if limit > 0 else cap
    d1 = min(cap, max(2.0 * d0, MIN_DAMPING.get(j.type, 0.2), min(need, cap)))
    # PhysX joint friction resists up to about ``friction * |joint load|``; the load of a
    # resting part is about its weight, so holding the gravity force needs roughly
    # tau / (m g) (measured: 0.5 holds an 18.7 kg oven door with 17 N m, 0.05 does not)
    weight = 9.81 * max(float(details.get("mass", 0.0)), 1e-6)
    f1 = min(MAX_FRICTION, max(4.0 * f0, MIN_FRICTION, 2.0 * tau / weight))
    if d1 <= d0 + 1e-12 and f1 <= f0 + 1e-12:
        return (
            f"{joint}: drifts {drift:.4f} under a gravity force of {tau:.3f} even with damping "
            f"{d0:g} and friction {f0:g} (ceilings {cap:g}, {MAX_FRICTION:g}); the part is not "
            "balanced at rest"
        )
    j.physics = replace(j.physics, damping=d1, friction=f1)
    return RepairRecord(
        "add_damping",
        joint,
        {"damping": d0, "friction": f0},
        {"damping": d1, "friction": f1},
        reason,
    )


def project_hinge(
    asset: BuiltAsset, joint: str, details: dict[str, Any], reason: str
) -> RepairRecord:
    """Move the hinge onto the part's AABB surface; move the part's contents back."""
    j = asset.joint(joint)
    delta = np.asarray(details["target_link"], dtype=float)  # new origin, in the old link frame
    a = j.unit_axis
    delta = delta - (delta @ a) * a  # moving along the hinge line changes nothing
    before = j.origin[:3, 3].copy()
    j.origin = j.origin @ _translation(delta)
    back = _translation(-delta)
    link = asset.link(j.child)
    for element in [*link.visuals, *link.collisions]:
        element.origin = back @ element.origin
    if link.inertial is not None:
        link.inertial.com = link.inertial.com - delta
    for grandchild in asset.joints:
        if grandchild.parent == j.child:
            grandchild.origin = back @ grandchild.origin
    h = asset.handles.get(j.child)
    if h is not None:
        h.position_link = h.position_link - delta
    return RepairRecord(
        "project_hinge_origin", joint, before.tolist(), j.origin[:3, 3].tolist(), reason
    )


def shrink_pieces(
    asset: BuiltAsset, pairs: list[dict[str, Any]], reason: str
) -> tuple[list[RepairRecord], list[str]]:
    """Shrink the movable side(s) of overlapping piece pairs along the contact normal."""
    root = asset.root
    poses = asset.link_poses()
    records, problems = [], []
    for pair in pairs:
        links, pieces, depth = pair["links"], pair["pieces"], float(pair["depth"])
        movable = [(ln, k) for ln, k in zip(links, pieces, strict=True) if ln != root]
        if not movable:
            problems.append(f"{links}: base pieces overlap each other")
            continue
        amount = depth / len(movable) + SHRINK_MARGIN
        n_world = np.asarray(pair["normal"], dtype=float)
        for ln, k in movable:
            piece = asset.link(ln).collisions[k]
            if piece.mesh is None:
                piece.mesh = read_obj(asset.path_of(piece.filename))
            v = np.asarray(piece.mesh.vertices, dtype=float)
            # contact normal in the piece's own frame
            R = poses[ln][:3, :3] @ piece.origin[:3, :3]
            n = R.T @ n_world
            n /= np.linalg.norm(n)
            c = v.mean(0)
            s = (v - c) @ n
            h = float(np.abs(s).max())
            if h <= 0 or amount / h > MAX_SHRINK:
                problems.append(
                    f"{ln} piece {k}: overlap {depth * 1000:.1f} mm would need more than "
                    f"{MAX_SHRINK:.0%} of its {2 * h * 1000:.1f} mm extent"
                )
                continue
            scale = (h - amount) / h
            before = [float(s.min()), float(s.max())]
            piece.mesh = trimesh.Trimesh(
                v - np.outer(s * (1 - scale), n), piece.mesh.faces, process=False
            )
            records.append(
                RepairRecord(
                    "shrink_piece",
                    f"{ln}#{k}",
                    {"extent_along_normal": before},
                    {
                        "extent_along_normal": [before[0] * scale, before[1] * scale],
                        "normal": n.tolist(),
                    },
                    reason,
                )
            )
    return records, list(dict.fromkeys(problems))


#: A levelling plate: under the base's collision within this height (m) of its lowest
#: point (its feet or plinth), this thick (m), set in by this much (m) from their outline.
LEVEL_FEET = 0.05
LEVEL_THICKNESS = 0.003
LEVEL_INSET = 0.002


def level_base(asset: BuiltAsset, reason: str) -> RepairRecord | str:
    """Give the base a thin plate under its feet (a collision piece spanning the outline
    of its collision within ``LEVEL_FEET`` of its lowest point, its bottom at that
    point): an artist's base that stands on uneven feet (two in front, one feature at
    the back) rests level on it. At most once per asset."""
    root = asset.link(asset.root)
    name = f"{root.name}_levelling"
    if any(p.name == name for p in root.collisions):
        return f"{reason}; the base already stands on a levelling plate"
    points = []
    for piece in root.collisions:
        if piece.mesh is None:
            piece.mesh = read_obj(asset.path_of(piece.filename))
        v = np.asarray(piece.mesh.vertices, dtype=float)
        points.append(v @ piece.origin[:3, :3].T + piece.origin[:3, 3])
    if not points:
        return f"{reason}; the base has no collision pieces"
    v = np.concatenate(points)
    zmin = float(v[:, 2].min())
    feet = v[v[:, 2] < zmin + LEVEL_FEET]
    lo, hi = feet[:, :2].min(0) + LEVEL_INSET, feet[:, :2].max(0) - LEVEL_INSET
    if (hi - lo).min() < 0.02:
        return f"{reason}; the base's feet span {hi - lo} m: too narrow to level"
    plate = trimesh.creation.box(
        bounds=[[lo[0], lo[1], zmin], [hi[0], hi[1], zmin + LEVEL_THICKNESS]]
    )
    k = len(root.collisions)
    root.collisions.append(
        CollisionPiece(filename=f"collision/{root.name}_{k}.obj", name=name, mesh=plate)
    )
    return RepairRecord(
        "level_base",
        root.name,
        {"lowest_z": zmin},
        {"plate": [[*lo.tolist(), zmin], [*hi.tolist(), zmin + LEVEL_THICKNESS]]},
        reason,
    )


def plan_repairs(
    asset: BuiltAsset, checks: list[Check], tol: Tolerances
) -> tuple[list[RepairRecord], list[str]]:
    """Edit ``asset`` as the failed ``checks`` allow; return (records, unrepairable reasons).

    Pieces whose geometry changed hold their new mesh (``CollisionPiece.mesh``), so
    that saving the asset writes them.
    """
    failed = [c for c in checks if not c.passed]
    joints = {j.name: j for j in asset.joints}
    records: list[RepairRecord] = []
    problems: list[str] = []
    done_joints: set[str] = set()
    by_name: dict[str, list[Check]] = {}
    for c in failed:
        by_name.setdefault(c.name, []).append(c)
    for name in REPAIR_ORDER:
        for c in by_name.get(name, []):
            j = c.subject
            if j in done_joints or j not in joints:
                continue
            why = f"{c.key}: {c.message}"
            rec: RepairRecord | str
            if name == "hinge_on_part":
                rec = project_hinge(asset, j, c.details, why)
            elif name == "opens_outward":
                rec = flip_axis(asset, j, why)
            elif name == "drawer_engaged":
                rec = shorten_range(asset, j, c.details, why)
            else:  # rest_drift
                lim = c.tolerance["drift"] if isinstance(c.tolerance, dict) else 0.0
                rec = add_damping(asset, j, c.details, float(c.value["drift"]), lim, why)
            if isinstance(rec, str):
                problems.append(rec)
                continue
            done_joints.add(j)
            records.append(rec)
    for c in by_name.get("rest_penetration", []):
        pairs = [
            p
            for p in c.details.get("pairs", [])
            if not (
                {asset.joint_of(ln).name for ln in p["links"] if asset.joint_of(ln)} & done_joints
            )
        ]
        recs, probs = shrink_pieces(asset, pairs, f"{c.key}: {c.message}")
        records += recs
        problems += probs
    for c in by_name.get("free_base_stable", []):
        rec = level_base(asset, f"{c.key}: {c.message}")
        if isinstance(rec, str):
            problems.append(rec)
        else:
            records.append(rec)
    repairable = set(REPAIR_ORDER) | {"rest_penetration", "free_base_stable"}
    for c in failed:
        if c.name not in repairable:
            problems.append(f"{c.key}: no automatic repair ({c.message or 'failed'})")
    return records, list(dict.fromkeys(problems))
