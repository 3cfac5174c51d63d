"""Kinematic checks: overlaps at rest, open and along every sweep; drawer engagement;
outward motion.

PhysX never reports contacts between a link and its parent, so these checks do not
ask the articulation: :class:`PenetrationProbe` builds one free rigid body per link
from the same convex pieces in a private scene, places them by the asset's forward
kinematics and reads PhysX's contact separations (negative = overlap).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import trimesh

from asset_pipeline.assets.built_asset import BuiltAsset, Joint
from asset_pipeline.assets.mesh_files import link_piece_vertices
from asset_pipeline.validate.report import Check, Tolerances
from asset_pipeline.validate.static import hull_thickness


def _transform(T: np.ndarray, v: np.ndarray) -> np.ndarray:
    return v @ T[:3, :3].T + T[:3, 3]


def link_centroid(pieces: list[np.ndarray]) -> np.ndarray:
    """Volume-weighted centroid (3,) of a link's convex pieces (mean of vertices if flat)."""
    total, acc = 0.0, np.zeros(3)
    for v in pieces:
        if len(v) < 4 or hull_thickness(v) < 1e-9:
            continue
        try:
            h = trimesh.convex.convex_hull(v)
            vol = float(abs(h.volume))
            acc += vol * np.asarray(h.center_mass)
            total += vol
        except Exception:  # noqa: BLE001 - qhull errors on degenerate input
            continue
    if total > 0:
        return acc / total
    allv = np.concatenate([v for v in pieces if len(v)] or [np.zeros((1, 3))])
    return allv.mean(0)


class PenetrationProbe:
    """One free rigid body per link in a private PhysX scene, for overlap queries.

    :meth:`query` places every link at the given poses, runs PhysX contact
    generation (one tiny step, gravity off) and returns the deepest overlap of
    every pair of (link, piece) with a negative separation.
    """

    def __init__(self, pieces: Mapping[str, list[np.ndarray]]) -> None:
        import sapien

        self._sapien = sapien
        self.scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
        self.scene.set_timestep(1e-6)
        mat = sapien.physx.PhysxMaterial(0.0, 0.0, 0.0)
        self.bodies: dict[str, Any] = {}
        self.shape_ids: dict[int, tuple[str, int]] = {}
        self._keep: list[Any] = []
        for name, plist in pieces.items():
            ent = sapien.Entity()
            ent.name = name
            body = sapien.physx.PhysxRigidDynamicComponent()
            n = 0
            for k, v in enumerate(plist):
                if len(v) < 4 or not np.isfinite(v).all():
                    continue
                shape = sapien.physx.PhysxCollisionShapeConvexMesh(
                    np.asarray(v, dtype=np.float32), np.ones(3, dtype=np.float32), mat
                )
                shape.set_contact_offset(0.002)
                shape.set_rest_offset(0.0)
                body.attach(shape)
                self.shape_ids[id(shape)] = (name, k)
                self._keep.append(shape)
                n += 1
            if n == 0:
                continue
            body.disable_gravity = True
            ent.add_component(body)
            self.scene.add_entity(ent)
            self.bodies[name] = (ent, body)

    def query(self, poses: Mapping[str, np.ndarray]) -> list[dict[str, Any]]:
        """Overlapping piece pairs at ``poses`` (4x4 per link): link, piece, depth, normal."""
        for name, (ent, body) in self.bodies.items():
            ent.pose = self._sapien.Pose(np.asarray(poses[name], dtype=np.float32))
            body.linear_velocity = np.zeros(3)
            body.angular_velocity = np.zeros(3)
        self.scene.step()
        out: dict[tuple, dict[str, Any]] = {}
        for c in self.scene.get_contacts():
            if not c.points:
                continue
            a = self.shape_ids.get(id(c.shapes[0]))
            b = self.shape_ids.get(id(c.shapes[1]))
            if a is None or b is None or a[0] == b[0]:
                continue
            pt = min(c.points, key=lambda p: p.separation)
            depth = -float(pt.separation)
            if depth <= 0:
                continue
            (a, b) = sorted([a, b])
            key = (a, b)
            if key not in out or depth > out[key]["depth"]:
                out[key] = {
                    "links": [a[0], b[0]],
                    "pieces": [a[1], b[1]],
                    "depth": depth,
                    "normal": np.asarray(pt.normal, dtype=float).tolist(),
                    "position": np.asarray(pt.position, dtype=float).tolist(),
                }
        return sorted(out.values(), key=lambda d: -d["depth"])


def _worst(pairs: Iterable[dict[str, Any]], link: str | None = None) -> dict[str, Any] | None:
    sel = [p for p in pairs if link is None or link in p["links"]]
    return max(sel, key=lambda p: p["depth"]) if sel else None


def kinematic_checks(asset: BuiltAsset, tol: Tolerances) -> list[Check]:
    """Overlap at rest, open and along every joint's sweep; drawer engagement; outward motion."""
    pieces = link_piece_vertices(asset)
    probe = PenetrationProbe(pieces)
    movable = asset.movable_joints
    closed = {j.name: j.lower for j in movable}
    opened = {j.name: j.upper for j in movable}
    checks: list[Check] = []
    for name, q in (("rest_penetration", closed), ("open_penetration", opened)):
        pairs = probe.query(asset.link_poses(q))
        w = _worst(pairs)
        depth = w["depth"] if w else 0.0
        bad = [p for p in pairs if p["depth"] > tol.penetration]
        checks.append(
            Check(
                name,
                "kinematic",
                "asset",
                not bad,
                value=depth,
                tolerance=tol.penetration,
                message=""
                if not bad
                else "; ".join(
                    f"{p['links'][0]}#{p['pieces'][0]} / {p['links'][1]}#{p['pieces'][1]} overlap "
                    f"{p['depth'] * 1000:.1f} mm"
                    for p in bad[:4]
                ),
                details={"pairs": bad, "qpos": q},
            )
        )
    base = asset.roots[0] if asset.roots else None
    base_centroid = link_centroid(pieces.get(base, [])) if base else np.zeros(3)
    base_all = np.concatenate([v for v in pieces.get(base, []) if len(v)] or [np.zeros((1, 3))])
    closed_poses = asset.link_poses(closed)
    all_closed = np.concatenate(
        [_transform(closed_poses[n], v) for n, vs in pieces.items() for v in vs if len(v)]
        or [np.zeros((1, 3))]
    )
    for j in movable:
        if not (math.isfinite(j.lower) and math.isfinite(j.upper) and j.lower < j.upper):
            continue  # already failed statically; a sweep would be meaningless
        worst: dict[str, Any] | None = None
        for mode, others in (("others_closed", closed), ("others_open", opened)):
            for q in np.linspace(j.lower, j.upper, tol.sweep_steps + 1):
                qpos = dict(others)
                qpos[j.name] = float(q)
                w = _worst(probe.query(asset.link_poses(qpos)), j.child)
                if w and (worst is None or w["depth"] > worst["depth"]):
                    worst = dict(w, q=float(q), mode=mode)
        depth = worst["depth"] if worst else 0.0
        ok = depth <= tol.penetration
        checks.append(
            Check(
                "sweep_penetration",
                "kinematic",
                j.name,
                ok,
                value=depth,
                tolerance=tol.penetration,
                message=""
                if ok
                else f"{worst['links'][0]} and {worst['links'][1]} overlap "  # type: ignore[index]
                f"{depth * 1000:.1f} mm at q={worst['q']:.3f} ({worst['mode']})",  # type: ignore[index]
                details={"worst": worst},
            )
        )
        child = [v for v in pieces.get(j.child, []) if len(v)]
        if not child:
            continue
        c_local = link_centroid(child)
        poses_closed = asset.link_poses(closed)
        c0 = _transform(poses_closed[j.child], c_local[None])[0]
        increase = []
        for frac in (0.1, 1.0):
            qpos = dict(closed)
            qpos[j.name] = j.lower + frac * (j.upper - j.lower)
            c1 = _transform(asset.link_poses(qpos)[j.child], c_local[None])[0]
            increase.append(
                float(np.linalg.norm(c1 - base_centroid) - np.linalg.norm(c0 - base_centroid))
            )
        # at least the full opening must move away; a first step inward is also a fault
        ok = increase[1] > tol.outward_min and increase[0] > -tol.outward_min
        value, message = increase[1], "opening moves the part toward the base's centre"
        details = {"increase_at_10pct": increase[0], "increase_at_upper": increase[1]}
        if j.type == "revolute":  # a hinged part: its reach out of the closed object
            value = _swings_out(j, asset, child, closed, all_closed)
            ok = value > tol.outward_min
            message = "opening swings the part into the object, not out of it"
            details["reach_out_minus_reversed"] = value
        checks.append(
            Check(
                "opens_outward",
                "kinematic",
                j.name,
                ok,
                value=value,
                tolerance=tol.outward_min,
                message="" if ok else f"{message} (axis inverted?)",
                details=details,
            )
        )
        if j.type == "prismatic":
            checks.append(_engagement_check(j, asset, child, base_all, opened, closed, tol))
    return checks


def _swings_out(
    j: Joint,
    asset: BuiltAsset,
    child: list[np.ndarray],
    closed: Mapping[str, float],
    all_closed: np.ndarray,
) -> float:
    """How much further a hinged part reaches out of the closed object's bounding box
    (``all_closed``: every piece's vertices at rest) opened by its range, at most a
    quarter turn, than it would swung as far the other way (mean over its vertices, m):
    positive when it opens out of the object. The centroid's distance from the base's
    centroid, which decides for a sliding part, misjudges a deep, narrow door hinged at
    the object's side both ways: opened right, its centroid first moves sideways toward
    the base's centre while its free edge leaves the front; opened the wrong way, into
    the base, its centroid moves away sideways."""
    lo, hi = all_closed.min(axis=0), all_closed.max(axis=0)
    pts = np.concatenate(child)

    def outside(q: float) -> float:
        qpos = dict(closed)
        qpos[j.name] = q
        p = _transform(asset.link_poses(qpos)[j.child], pts)
        gap = np.maximum(lo - p, 0.0) + np.maximum(p - hi, 0.0)
        return float(np.linalg.norm(gap, axis=1).mean())

    span = min(j.upper - j.lower, math.pi / 2)  # at +-180 degrees both ways meet
    return outside(j.lower + span) - outside(j.lower - span)


def _engagement_check(
    j: Joint,
    asset: BuiltAsset,
    child: list[np.ndarray],
    base_all: np.ndarray,
    opened: Mapping[str, float],
    closed: Mapping[str, float],
    tol: Tolerances,
) -> Check:
    qpos = dict(closed)
    qpos[j.name] = j.upper
    T = asset.link_poses(qpos)[j.child]
    parent_T = asset.link_poses(qpos)[j.parent]
    axis_w = parent_T[:3, :3] @ j.origin[:3, :3] @ j.unit_axis
    cv = _transform(T, np.concatenate(child)) @ axis_w
    bv = base_all @ axis_w
    length = float(np.ptp(cv))
    overlap = float(min(cv.max(), bv.max()) - max(cv.min(), bv.min()))
    frac = overlap / length if length > 0 else 0.0
    ok = frac >= tol.min_engaged_fraction
    return Check(
        "drawer_engaged",
        "kinematic",
        j.name,
        ok,
        value=frac,
        tolerance=tol.min_engaged_fraction,
        message=""
        if ok
        else f"at its upper limit the part keeps {overlap * 1000:.0f} mm "
        f"({frac:.0%}) of its {length * 1000:.0f} mm inside the base",
        details={"overlap": overlap, "length": length, "upper": j.upper, "lower": j.lower},
    )
