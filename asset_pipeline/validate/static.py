"""Static checks: the asset's model and its collision pieces, no simulator.

``single_root``, ``has_movable_part``, ``axis_unit``, ``limits_ordered``,
``mass_positive``, ``inertia_valid``, ``collision_hulls``, ``hinge_on_part``
(docs/validation.md). Whether the files read at all (``urdf``) is decided by
:func:`asset_pipeline.asset_io.load_asset` in the runner.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from asset_pipeline.assets.built_asset import BuiltAsset, Joint, Link
from asset_pipeline.assets.mesh_files import piece_vertices
from asset_pipeline.validate.report import Check, Tolerances


def hull_thickness(v: np.ndarray) -> float:
    """Smallest extent (m) of a point set along its principal axes (0 for a flat set)."""
    if len(v) < 4:
        return 0.0
    c = v - v.mean(0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    proj = c @ vt.T
    return float(np.ptp(proj, axis=0).min())


def static_checks(asset: BuiltAsset, tol: Tolerances) -> list[Check]:
    """Checks on the asset's model and its collision OBJs alone (no simulator)."""
    checks: list[Check] = []
    roots = asset.roots
    names = {k.name for k in asset.links}
    bad_refs = [
        f"{j.name}: {j.parent}->{j.child}"
        for j in asset.joints
        if j.parent not in names or j.child not in names
    ]
    parents: dict[str, int] = {}
    for j in asset.joints:
        parents[j.child] = parents.get(j.child, 0) + 1
    multi = sorted(k for k, n in parents.items() if n > 1)
    ok = len(roots) == 1 and not bad_refs and not multi
    checks.append(
        Check(
            "single_root",
            "static",
            "asset",
            ok,
            value=roots,
            tolerance="exactly one root link",
            message=""
            if ok
            else f"roots {roots}; unknown links in {bad_refs}; several parents: {multi}",
        )
    )
    n_movable = len(asset.movable_joints)
    checks.append(
        Check(
            "has_movable_part",
            "static",
            "asset",
            n_movable > 0,
            value=n_movable,
            tolerance=">= 1 prismatic or revolute joint",
            message=""
            if n_movable
            else f"model.urdf has {len(asset.links)} link(s) and no prismatic or revolute "
            "joint: nothing to articulate (the generator found no movable part; give a part "
            "mask, or check the input image)",
        )
    )
    for j in asset.movable_joints:
        n = float(np.linalg.norm(j.axis))
        ok = bool(np.isfinite(j.axis).all() and abs(n - 1.0) <= tol.axis_norm)
        checks.append(
            Check(
                "axis_unit",
                "static",
                j.name,
                ok,
                value=n,
                tolerance=tol.axis_norm,
                message="" if ok else f"axis {j.axis.tolist()} is not a finite unit vector",
            )
        )
        ok = bool(math.isfinite(j.lower) and math.isfinite(j.upper) and j.lower < j.upper)
        checks.append(
            Check(
                "limits_ordered",
                "static",
                j.name,
                ok,
                value=[j.lower, j.upper],
                tolerance="finite, lower < upper",
                message=""
                if ok
                else f"limits [{j.lower}, {j.upper}] are not finite and ordered "
                "(lower = closed); fix the joint range in object.json and rebuild",
            )
        )
    for link in asset.links:
        m = None if link.inertial is None else link.inertial.mass
        ok = m is not None and math.isfinite(m) and m > 0
        checks.append(
            Check(
                "mass_positive",
                "static",
                link.name,
                bool(ok),
                value=m,
                tolerance="> 0",
                message=""
                if ok
                else f"mass {m} must be finite and > 0 (SAPIEN would silently "
                "replace it from the collision shapes); rebuild with a material density",
            )
        )
        checks.append(_inertia_check(link, tol))
        checks.append(_hull_check(asset, link, tol))
    for j in asset.movable_joints:
        if j.type != "revolute" or j.child not in names:
            continue
        pieces = [piece_vertices(asset, p) for p in asset.link(j.child).collisions]
        checks.append(_hinge_check(j, pieces, tol))
    return checks


def _inertia_check(link: Link, tol: Tolerances) -> Check:
    inertia = None if link.inertial is None else link.inertial.inertia
    if inertia is None or not np.isfinite(inertia).all():
        return Check(
            "inertia_valid",
            "static",
            link.name,
            False,
            value=None,
            tolerance="positive definite, triangle inequality",
            message="missing or non-finite <inertia>",
        )
    eig = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
    scale = max(float(np.abs(eig).max()), 1e-12)
    pd = bool((eig > tol.inertia_rel * scale).all())
    tri = bool(
        all(
            eig[i] <= eig[(i + 1) % 3] + eig[(i + 2) % 3] + tol.inertia_rel * scale
            for i in range(3)
        )
    )
    ok = pd and tri
    msg = "" if ok else ("not positive definite" if not pd else "violates I_i <= I_j + I_k")
    return Check(
        "inertia_valid",
        "static",
        link.name,
        ok,
        value=eig.tolist(),
        tolerance="positive definite, triangle inequality",
        message=msg,
    )


def _hull_check(asset: BuiltAsset, link: Link, tol: Tolerances) -> Check:
    bad: list[dict[str, Any]] = []
    counts, thick = [], []
    for k, p in enumerate(link.collisions):
        try:
            v = piece_vertices(asset, p)
        except (OSError, ValueError) as e:
            bad.append({"piece": k, "file": p.filename, "problem": f"unreadable: {e}"})
            continue
        n = len(v)
        t = hull_thickness(v) if n else 0.0
        counts.append(n)
        thick.append(t)
        if not tol.hull_min_vertices <= n <= tol.hull_max_vertices:
            bad.append({"piece": k, "file": p.filename, "problem": f"{n} vertices"})
        elif not np.isfinite(v).all():
            bad.append({"piece": k, "file": p.filename, "problem": "non-finite vertices"})
        elif t < tol.hull_min_thickness:
            bad.append({"piece": k, "file": p.filename, "problem": f"flat (thickness {t:.2e} m)"})
    ok = not bad and bool(link.collisions)
    value = {
        "pieces": len(link.collisions),
        "vertices": [min(counts), max(counts)] if counts else None,
        "min_thickness": min(thick) if thick else None,
    }
    msg = (
        ""
        if ok
        else (
            "no collision pieces"
            if not link.collisions
            else "; ".join(f"{b['file']}: {b['problem']}" for b in bad)
        )
    )
    return Check(
        "collision_hulls",
        "static",
        link.name,
        ok,
        value=value,
        tolerance={
            "vertices": [tol.hull_min_vertices, tol.hull_max_vertices],
            "min_thickness": tol.hull_min_thickness,
        },
        message=msg,
        details={"bad": bad},
    )


def hinge_offset(axis: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[float, np.ndarray]:
    """Distance (m) of the hinge line (through the origin along ``axis``) from the AABB surface.

    Returns the distance and the point of the AABB surface closest to the line
    (the PAct post-processing target), both in the link frame. The line is
    represented by its point closest to the box centre.
    """
    a = axis / np.linalg.norm(axis)
    c = 0.5 * (lo + hi)
    p = (c @ a) * a  # point of the line closest to the centre
    inside = bool(np.all(p >= lo) & np.all(p <= hi))
    if not inside:
        q = np.clip(p, lo, hi)
        return float(np.linalg.norm(p - q)), q
    # inside: move to the nearest face among those not perpendicular to the axis
    best, target = math.inf, p
    for i in range(3):
        if abs(a[i]) > 0.999:  # a face perpendicular to the axis does not hold a hinge line
            continue
        for bound in (lo[i], hi[i]):
            d = abs(p[i] - bound)
            if d < best:
                best, target = d, p.copy()
                target[i] = bound
    return float(best), target


def _hinge_check(j: Joint, pieces: list[np.ndarray], tol: Tolerances) -> Check:
    if not pieces or not any(len(v) for v in pieces):
        return Check(
            "hinge_on_part", "static", j.name, False, message="part has no collision geometry"
        )
    allv = np.concatenate([v for v in pieces if len(v)])
    lo, hi = allv.min(0), allv.max(0)
    d, target = hinge_offset(j.unit_axis, lo, hi)
    limit = max(tol.hinge_offset, tol.hinge_offset_relative * float(np.max(hi - lo)))
    ok = d <= limit
    return Check(
        "hinge_on_part",
        "static",
        j.name,
        ok,
        value=d,
        tolerance=limit,
        message="" if ok else f"hinge line is {d:.3f} m from the part's bounding box surface",
        details={"target_link": target.tolist(), "aabb": [lo.tolist(), hi.tolist()]},
    )
