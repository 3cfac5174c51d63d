"""Dynamic checks (PhysX CPU, the :class:`~asset_pipeline.simulation.sim_options.SimOptions` the
tasks use): rest under gravity, a PD drive to 90 % of the range and back, the free
base standing on the floor, nothing non-finite.

``rest_drift``, ``drive_reach``, ``free_base_stable``, ``finite`` (docs/validation.md).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.simulation.sapien_scenes import load_articulation, physics_scene
from asset_pipeline.simulation.sim_options import SimOptions
from asset_pipeline.validate.report import Check, Tolerances


def _effective_inertia(art: Any, joint: Any, jtype: str) -> float:
    """Mass (prismatic) or moment of inertia about the hinge (revolute) of the joint's child."""
    link = joint.child_link
    m = float(link.mass)
    if jtype == "prismatic":
        return max(m, 1e-3)
    jp = np.asarray(joint.get_global_pose().to_transformation_matrix())
    a, p = jp[:3, 0], jp[:3, 3]
    cm = np.asarray((link.entity_pose * link.cmass_local_pose).to_transformation_matrix())
    R = cm[:3, :3]
    inertia = R @ np.diag(np.asarray(link.inertia, dtype=float)) @ R.T
    r = cm[:3, 3] - p
    r_perp = r - (r @ a) * a
    return max(float(a @ inertia @ a + m * (r_perp @ r_perp)), 1e-5)


def dynamic_checks(asset: BuiltAsset, tol: Tolerances, options: SimOptions) -> list[Check]:
    """Rest under gravity, PD drive to 90 % and back, free base standing on the floor."""
    checks: list[Check] = []
    finite_ok, finite_where = True, []
    movable = asset.movable_joints
    dt = options.timestep
    scene = physics_scene(options)
    art = load_articulation(scene, asset, options, visuals=False, fix_root=True)
    art.set_sleep_threshold(0.0)
    joints = {j.name: j for j in art.get_active_joints()}
    names = [j.name for j in art.get_active_joints()]
    spec_of = {j.name: j for j in movable}
    lower = np.array([spec_of[n].lower for n in names], dtype=float)
    art.set_qpos(lower.astype(np.float32))
    art.set_qvel(np.zeros(len(names), dtype=np.float32))
    # --- rest under gravity, no drive (the URDF's damping acts, as in the tasks)
    q0 = np.asarray(art.get_qpos(), dtype=float)
    tau = -np.asarray(art.compute_passive_force(True, False), dtype=float)  # gravity, at start
    masses = {n: float(joints[n].child_link.mass) for n in names}
    maxdev = np.zeros(len(names))
    for _ in range(round(tol.settle_time / dt)):
        scene.step()
        q = np.asarray(art.get_qpos(), dtype=float)
        if not np.isfinite(q).all():
            break
        maxdev = np.maximum(maxdev, np.abs(q - q0))
    q = np.asarray(art.get_qpos(), dtype=float)
    qd = np.asarray(art.get_qvel(), dtype=float)
    if not (np.isfinite(q).all() and np.isfinite(qd).all()):
        finite_ok = False
        finite_where.append("rest")
    for i, n in enumerate(names):
        js = spec_of[n]
        lin = js.type == "prismatic"
        lim = tol.drift_linear if lin else tol.drift_angular
        vlim = tol.max_linear_velocity if lin else tol.max_angular_velocity
        ok = bool(np.isfinite(maxdev[i]) and maxdev[i] <= lim and abs(qd[i]) <= vlim)
        checks.append(
            Check(
                "rest_drift",
                "dynamic",
                n,
                ok,
                value={"drift": maxdev[i], "speed": abs(qd[i])},
                tolerance={"drift": lim, "speed": vlim},
                message=""
                if ok
                else f"drifts {maxdev[i]:.4f} {'m' if lin else 'rad'} in "
                f"{tol.settle_time:g} s under gravity (speed {abs(qd[i]):.3f})",
                details={
                    "gravity_force": float(tau[i]),
                    "mass": masses[n],
                    "damping": js.physics.damping,
                    "friction": js.physics.friction,
                    "duration": tol.settle_time,
                },
            )
        )
    # --- PD drive, one joint at a time, the others held closed
    art.set_qpos(lower.astype(np.float32))
    art.set_qvel(np.zeros(len(names), dtype=np.float32))
    w = 2 * math.pi * tol.drive_frequency
    gains = {}
    for n in names:
        js = spec_of[n]
        m = _effective_inertia(art, joints[n], js.type)
        # PhysX joint friction resists in proportion to the joint's load (about the
        # part's weight): stiffen the drive so that it beats that within the error band
        weight = float(joints[n].child_link.mass) * 9.81
        band = 0.5 * tol.drive_error * (js.upper - js.lower)
        k = m * w * w + js.physics.friction * weight / band
        c = 2 * math.sqrt(k * m) + js.physics.damping
        limit = js.physics.effort if js.physics.effort > 0 else 3.4e38
        gains[n] = (k, c, limit)
        joints[n].set_drive_properties(k, c, limit, "force")
        joints[n].set_drive_target(float(js.lower))
    steps = round(tol.drive_time / dt)
    for i, n in enumerate(names):
        js = spec_of[n]
        rng = js.upper - js.lower
        target = js.lower + tol.drive_fraction * rng
        times: list[float | None] = []
        reached_q = []
        for goal in (target, js.lower):
            joints[n].set_drive_target(float(goal))
            t_hit = None
            for s in range(steps):
                # gravity compensation, as a robot's PD controller balances passive forces
                art.set_qf(art.compute_passive_force(True, True))
                scene.step()
                qi = float(art.get_qpos()[i])
                if not math.isfinite(qi):
                    finite_ok = False
                    finite_where.append(f"drive {n}")
                    break
                if abs(qi - goal) <= tol.drive_error * rng:
                    t_hit = (s + 1) * dt
                    break
            times.append(t_hit)
            reached_q.append(float(art.get_qpos()[i]))
        ok = all(t is not None for t in times)
        checks.append(
            Check(
                "drive_reach",
                "dynamic",
                n,
                ok,
                value={"open_s": times[0], "close_s": times[1]},
                tolerance={"time_s": tol.drive_time, "error": tol.drive_error * rng},
                message=""
                if ok
                else f"PD drive jammed: reached q={reached_q} toward "
                f"[{target:.3f}, {js.lower:.3f}] within {tol.drive_time:g} s",
                details={"gains": gains[n], "q": reached_q},
            )
        )
    # --- a touch and a pull, as a hand would give them
    checks += _touch_and_pull_checks(asset, tol, options)
    # --- free base on the floor
    checks.append(_free_base_check(asset, tol, options))
    checks.append(
        Check(
            "finite",
            "dynamic",
            "asset",
            finite_ok,
            value=finite_where or None,
            tolerance="no NaN/inf",
            message="" if finite_ok else f"non-finite state in {finite_where}",
        )
    )
    return checks


def _opening_direction(asset: BuiltAsset, joint_name: str) -> tuple[np.ndarray, np.ndarray]:
    """The handle point (3,) of a movable part at rest (object frame) and the unit
    direction (3,) it moves in when the part starts to open."""
    j = asset.joint(joint_name)
    part = next(p for p in asset.movable_parts() if p.joint_name == joint_name)
    point = np.asarray(part.handle_object)
    axis = np.asarray(part.axis)
    if j.type == "prismatic":
        return point, axis
    tangent = np.cross(axis, point - np.asarray(part.origin))
    n = float(np.linalg.norm(tangent))
    return point, (tangent / n if n > 1e-9 else axis)


def _touch_and_pull_checks(asset: BuiltAsset, tol: Tolerances, options: SimOptions) -> list[Check]:
    """``touch_hold``: nudged open a little (``touch`` of the range, base fixed, no
    drive) a part stays where it was put; ``handle_pull``: pulled at its handle by
    ``pull_force`` newtons along its opening direction, it opens ``pull_fraction`` of its
    range within ``pull_time``. Together: a door neither swings open at a touch nor
    jams. Parts without a handle (an asset made elsewhere) get the pull at the centre
    of their front face as built (asset.json's handle is what the tasks use)."""
    import sapien

    checks: list[Check] = []
    dt = options.timestep
    with_handle = {p.joint_name for p in asset.movable_parts()} if asset.handles else set()
    for js in asset.movable_joints:
        rng = js.upper - js.lower
        lin = js.type == "prismatic"
        # touch
        scene = physics_scene(options)
        art = load_articulation(scene, asset, options, visuals=False, fix_root=True)
        art.set_sleep_threshold(0.0)
        names = [j.name for j in art.get_active_joints()]
        spec_of = {j.name: j for j in asset.movable_joints}
        q = np.array([spec_of[n].lower for n in names], dtype=np.float32)
        i = names.index(js.name)
        nudge = min(tol.touch * rng, tol.touch_max_linear if lin else tol.touch_max_angular)
        q[i] += nudge
        art.set_qpos(q)
        art.set_qvel(np.zeros(len(names), dtype=np.float32))
        for _ in range(round(tol.settle_time / dt)):
            scene.step()
        # falling back shut (a lid) is fine: only further opening counts
        moved = max(0.0, float(art.get_qpos()[i]) - float(q[i]))
        limit = tol.drift_linear if lin else tol.drift_angular
        ok = bool(np.isfinite(moved) and moved <= limit)
        checks.append(
            Check(
                "touch_hold",
                "dynamic",
                js.name,
                ok,
                value=moved,
                tolerance=limit,
                message=""
                if ok
                else f"nudged {nudge:.3f} {'m' if lin else 'rad'} open it opens {moved:.3f} further "
                f"in {tol.settle_time:g} s (too little friction to stay put)",
                details={"nudge": nudge, "friction": js.physics.friction},
            )
        )
        if js.name not in with_handle:
            continue
        # pull at the handle
        scene = physics_scene(options)
        art = load_articulation(scene, asset, options, visuals=False, fix_root=True)
        art.set_sleep_threshold(0.0)
        art.set_qpos(np.array([spec_of[n].lower for n in names], dtype=np.float32))
        art.set_qvel(np.zeros(len(names), dtype=np.float32))
        link = next(k for k in art.links if k.name == js.child)
        point, direction = _opening_direction(asset, js.name)
        local = np.asarray(link.entity_pose.inv().to_transformation_matrix()) @ np.append(
            point, 1.0
        )
        axis = np.asarray(next(p for p in asset.movable_parts() if p.joint_name == js.name).axis)
        best = 0.0
        for _ in range(round(tol.pull_time / dt)):
            T = np.asarray(link.entity_pose.to_transformation_matrix())
            p_world = T[:3, :3] @ local[:3] + T[:3, 3]
            # the pull follows the part: along the current opening direction
            qi = float(art.get_qpos()[i]) - js.lower
            d = direction
            if js.type != "prismatic":
                R = sapien.Pose(q=_axis_angle_quat(axis, qi)).to_transformation_matrix()[:3, :3]
                d = np.asarray(R) @ direction
            link.add_force_at_point(tol.pull_force * d, p_world)
            scene.step()
            best = max(best, (float(art.get_qpos()[i]) - js.lower) / rng)
        ok = bool(np.isfinite(best) and best >= tol.pull_fraction)
        checks.append(
            Check(
                "handle_pull",
                "dynamic",
                js.name,
                ok,
                value=best,
                tolerance=tol.pull_fraction,
                message=""
                if ok
                else f"pulled at its handle with {tol.pull_force:g} N it opens {best:.0%} of its "
                f"range in {tol.pull_time:g} s (jammed, too heavy or too much friction)",
                details={"force": tol.pull_force, "point": point.tolist()},
            )
        )
    return checks


def _axis_angle_quat(axis: np.ndarray, angle: float) -> np.ndarray:
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.array([math.cos(angle / 2), *(math.sin(angle / 2) * a)])


#: Natural frequency (Hz) of the drives that hold the parts closed in the free-base check.
FREE_BASE_HOLD_HZ = 5.0


def _free_base_check(asset: BuiltAsset, tol: Tolerances, options: SimOptions) -> Check:
    import sapien

    scene = physics_scene(options)
    scene.add_ground(
        0.0,
        render=False,
        material=sapien.physx.PhysxMaterial(
            options.static_friction, options.dynamic_friction, options.restitution
        ),
    )
    art = load_articulation(scene, asset, options, visuals=False, fix_root=False)
    art.set_sleep_threshold(0.0)
    start = np.array([0.0, 0.0, 0.002])
    art.set_root_pose(sapien.Pose(start))
    names = [j.name for j in art.get_active_joints()]
    spec_of = {j.name: j for j in asset.movable_joints}
    art.set_qpos(np.array([spec_of[n].lower for n in names], dtype=np.float32))
    # the parts are held closed, as latches, springs and magnets hold real ones (PhysX's
    # joint friction holds nothing on a floating base): this check is about the base
    for joint in art.get_active_joints():
        m = max(float(joint.child_link.mass), 1e-3)
        w = 2 * math.pi * FREE_BASE_HOLD_HZ
        joint.set_drive_properties(m * w * w, 2 * m * w, 3.4e38, "force")
        joint.set_drive_target(float(spec_of[joint.name].lower))
    for _ in range(round(tol.free_time / options.timestep)):
        scene.step()
    T = np.asarray(art.get_root_pose().to_transformation_matrix())
    if not np.isfinite(T).all():
        return Check(
            "free_base_stable",
            "dynamic",
            "asset",
            False,
            value=None,
            message="non-finite base pose",
        )
    tilt = float(math.acos(float(np.clip(T[2, 2], -1, 1))))
    disp = float(np.linalg.norm(T[:3, 3] - start))
    v = float(np.linalg.norm(art.get_root_linear_velocity()))
    wv = float(np.linalg.norm(art.get_root_angular_velocity()))
    ok = (
        tilt <= tol.free_tilt
        and disp <= tol.free_displacement
        and v <= tol.max_linear_velocity
        and wv <= tol.max_angular_velocity
    )
    return Check(
        "free_base_stable",
        "dynamic",
        "asset",
        ok,
        value={"tilt": tilt, "displacement": disp, "speed": v, "angular_speed": wv},
        tolerance={
            "tilt": tol.free_tilt,
            "displacement": tol.free_displacement,
            "speed": tol.max_linear_velocity,
            "angular_speed": tol.max_angular_velocity,
        },
        message=""
        if ok
        else f"free on the floor the base tilts {math.degrees(tilt):.1f} deg "
        f"and moves {disp * 1000:.0f} mm",
    )
