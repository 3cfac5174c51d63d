"""The behaviour scenarios of :mod:`.engines` in MuJoCo, on ``model.xml`` as written
(its own timestep and contact settings: what a MuJoCo user gets). A free base gets a
free joint and a floor plane (through ``mujoco.MjSpec``) and its holding drives are joint
springs and dampers; the pull is an applied force (``mj_applyFT``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.assets.layout import MJCF_NAME
from asset_pipeline.validate.engine_scenarios import Scenario, Trajectory, hold_gains


def load_model(path: Path, free_base: bool = False):
    """The compiled ``mujoco.MjModel`` of an MJCF file; ``free_base`` frees its root body
    and adds a floor plane at z = 0."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(path))
    if free_base:
        spec.worldbody.first_body().add_freejoint()
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5.0, 5.0, 0.1])
    return spec.compile()


def _run(asset: BuiltAsset, model, s: Scenario) -> Trajectory:
    import mujoco

    data = mujoco.MjData(model)
    joints = asset.movable_joints
    qadr = [int(model.joint(j.name).qposadr[0]) for j in joints]
    dadr = [int(model.joint(j.name).dofadr[0]) for j in joints]
    if s.free_base:
        data.qpos[0:3] = [0.0, 0.0, 0.002]
        data.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
    for j, a in zip(joints, qadr, strict=True):
        data.qpos[a] = s.q0.get(j.name, j.lower)
    mujoco.mj_forward(model, data)
    if s.free_base:
        # the holding drives as joint springs and dampers: MuJoCo's Euler integrator
        # treats damping implicitly (an applied PD force would blow up a light door)
        for j, a, d in zip(joints, qadr, dadr, strict=True):
            kp, kd = hold_gains(asset, j)
            jid = model.joint(j.name).id
            model.jnt_stiffness[jid] = kp
            model.qpos_spring[a] = j.lower
            model.dof_damping[d] = kd + j.physics.damping
    body = None
    if s.pull is not None:
        body = model.body(s.pull.link).id
        point = np.asarray(s.pull.point)
        direction = np.asarray(s.pull.direction) * s.pull.force
    dt = float(model.opt.timestep)
    steps = round(s.duration / dt)
    times, qs = [0.0], [data.qpos[qadr].copy()]
    finite = True
    for k in range(steps):
        data.qfrc_applied[:] = 0.0
        if body is not None:
            R = data.xmat[body].reshape(3, 3)
            p = R @ point + data.xpos[body]
            mujoco.mj_applyFT(model, data, R @ direction, np.zeros(3), p, body, data.qfrc_applied)
        mujoco.mj_step(model, data)
        q = data.qpos[qadr].copy()
        if not np.isfinite(q).all():
            finite = False
            break
        times.append((k + 1) * dt)
        qs.append(q)
    # MuJoCo resets a simulation that blew up (and warns): count that as non-finite
    if int(data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number) > 0:
        finite = False
    root = model.body(asset.root).id
    base = np.eye(4)
    base[:3, :3] = data.xmat[root].reshape(3, 3)
    base[:3, 3] = data.xpos[root]
    speed = ang = 0.0
    if s.free_base:
        ang, speed = (float(np.linalg.norm(data.qvel[3:6])), float(np.linalg.norm(data.qvel[0:3])))
    return Trajectory(
        times=np.asarray(times),
        q=np.asarray(qs).reshape(len(qs), len(joints)),
        base_pose=base,
        base_speed=speed,
        base_angular_speed=ang,
        finite=finite and bool(np.isfinite(data.qpos).all()),
    )


def simulate(asset: BuiltAsset, scenarios: Sequence[Scenario]) -> list[Trajectory]:
    """The scenarios on ``model.xml`` of the asset's folder."""
    path = asset.path_of(MJCF_NAME)
    fixed = load_model(path)
    free = load_model(path, free_base=True) if any(s.free_base for s in scenarios) else None
    return [_run(asset, free if s.free_base else fixed, s) for s in scenarios]
