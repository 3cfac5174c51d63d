"""Load checks: the articulation loads in SAPIEN as written.

``sapien_load``, ``collision_shapes`` (SAPIEN drops pieces it cannot cook),
``joint_matches_urdf`` (type, limits and axis as written).
"""

from __future__ import annotations

import numpy as np

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.simulation.sapien_scenes import load_articulation, physics_scene
from asset_pipeline.simulation.sim_options import SimOptions
from asset_pipeline.validate.report import Check, Tolerances

_SAPIEN_TYPES = {
    "prismatic": ("prismatic",),
    "revolute": ("revolute", "revolute_unwrapped"),
    "continuous": ("revolute",),
    "fixed": ("fixed",),
}


def load_checks(asset: BuiltAsset, tol: Tolerances, options: SimOptions) -> list[Check]:
    """The articulation loads; shapes, joint types, limits and axes are as written."""
    scene = physics_scene(options)
    try:
        art = load_articulation(scene, asset, options, visuals=False, fresh_meshes=True)
    except Exception as e:  # noqa: BLE001 - SAPIEN raises many types
        return [
            Check(
                "sapien_load",
                "load",
                "asset",
                False,
                value=str(e),
                tolerance="loads",
                message=f"SAPIEN cannot load the URDF: {e}",
            )
        ]
    checks = [Check("sapien_load", "load", "asset", True, value="loaded", tolerance="loads")]
    links = {link.name: link for link in art.links}
    for link in asset.links:
        name = link.name
        n = len(links[name].collision_shapes) if name in links else 0
        ok = n == len(link.collisions)
        checks.append(
            Check(
                "collision_shapes",
                "load",
                name,
                ok,
                value=n,
                tolerance=len(link.collisions),
                message=""
                if ok
                else f"SAPIEN made {n} of {len(link.collisions)} collision shapes "
                "(it drops pieces it cannot cook)",
            )
        )
    sj = {j.name: j for j in art.get_joints()}
    for j in asset.movable_joints:
        s = sj.get(j.name)
        if s is None:
            checks.append(
                Check("joint_matches_urdf", "load", j.name, False, message="joint missing")
            )
            continue
        problems = []
        if s.type not in _SAPIEN_TYPES.get(j.type, ()):
            problems.append(f"type {s.type} != {j.type}")
        lim = np.asarray(s.limit, dtype=float).reshape(-1)
        if j.type != "continuous" and (
            abs(lim[0] - j.lower) > tol.limit_match or abs(lim[1] - j.upper) > tol.limit_match
        ):
            problems.append(f"limits {lim.tolist()} != [{j.lower}, {j.upper}]")
        ax = np.asarray(s.get_pose_in_parent().to_transformation_matrix())[:3, 0]
        want = j.origin[:3, :3] @ j.unit_axis
        if np.isfinite(want).all() and np.linalg.norm(ax - want) > 1e-3:
            problems.append(f"axis {ax.round(4).tolist()} != {want.round(4).tolist()}")
        checks.append(
            Check(
                "joint_matches_urdf",
                "load",
                j.name,
                not problems,
                value={"type": s.type, "limits": lim.tolist()},
                tolerance=tol.limit_match,
                message="; ".join(problems),
            )
        )
    return checks
