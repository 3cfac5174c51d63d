"""The behaviour scenarios of :mod:`.engines` in SAPIEN (PhysX on CPU), on ``model.urdf``
loaded as validation and the tasks load it (:mod:`asset_pipeline.simulation.sapien_scenes`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.simulation.sapien_scenes import load_articulation, physics_scene
from asset_pipeline.simulation.sim_options import DEFAULT_SIM_OPTIONS, SimOptions
from asset_pipeline.validate.engine_scenarios import Scenario, Trajectory, hold_gains


def _run(asset: BuiltAsset, s: Scenario, options: SimOptions) -> Trajectory:
    import sapien

    scene = physics_scene(options)
    if s.free_base:
        scene.add_ground(0.0, render=False, material=sapien.physx.PhysxMaterial(
            options.static_friction, options.dynamic_friction, options.restitution))  # fmt: skip
    art = load_articulation(scene, asset, options, visuals=False, fix_root=not s.free_base)
    art.set_sleep_threshold(0.0)
    if s.free_base:
        art.set_root_pose(sapien.Pose([0.0, 0.0, 0.002]))
    active = art.get_active_joints()
    spec = {j.name: j for j in asset.movable_joints}
    order = [j.name for j in asset.movable_joints]
    names = [j.name for j in active]
    index = [names.index(n) for n in order]
    q0 = np.array([s.q0.get(n, spec[n].lower) for n in names], dtype=np.float32)
    art.set_qpos(q0)
    art.set_qvel(np.zeros(len(names), dtype=np.float32))
    if s.free_base:
        for joint in active:
            k, c = hold_gains(asset, spec[joint.name])
            joint.set_drive_properties(k, c, 3.4e38, "force")
            joint.set_drive_target(float(spec[joint.name].lower))
    link = None
    if s.pull is not None:
        link = next(k for k in art.links if k.name == s.pull.link)
        point = np.asarray(s.pull.point)
        direction = np.asarray(s.pull.direction) * s.pull.force
    steps = round(s.duration / options.timestep)
    times, qs = [0.0], [np.asarray(art.get_qpos(), dtype=float)[index]]
    finite = True
    for k in range(steps):
        if link is not None:
            T = np.asarray(link.entity_pose.to_transformation_matrix())
            link.add_force_at_point(T[:3, :3] @ direction, T[:3, :3] @ point + T[:3, 3])
        scene.step()
        q = np.asarray(art.get_qpos(), dtype=float)[index]
        if not np.isfinite(q).all():
            finite = False
            break
        times.append((k + 1) * options.timestep)
        qs.append(q)
    base = np.asarray(art.get_root_pose().to_transformation_matrix(), dtype=float)
    return Trajectory(
        times=np.asarray(times),
        q=np.asarray(qs).reshape(len(qs), len(order)),
        base_pose=base,
        base_speed=float(np.linalg.norm(art.get_root_linear_velocity())),
        base_angular_speed=float(np.linalg.norm(art.get_root_angular_velocity())),
        finite=finite and bool(np.isfinite(base).all()),
    )


def simulate(
    asset: BuiltAsset, scenarios: Sequence[Scenario], options: SimOptions = DEFAULT_SIM_OPTIONS
) -> list[Trajectory]:
    """One SAPIEN scene per scenario, with validation's :class:`SimOptions`."""
    return [_run(asset, s, options) for s in scenarios]
