"""The behaviour scenarios of :mod:`.engines` in Newton (on Warp's CPU device), on the
asset's USD read by Newton's own importer (``ModelBuilder.add_usd``).

Every scenario is one Newton *world* of a single model, so the whole plan is one
simulation (Warp launches its kernels once per step for all worlds). Solver: XPBD
(:data:`SOLVER_ITERATIONS` iterations, :data:`SUBSTEPS` substeps of each
:data:`FRAME_DT` frame, contacts found once per frame), which holds joint limits as hard
constraints. The USD's drives act as written (stiffness 0, the joint damping as drive
damping); a free-base world ignores the stage's ``root_joint`` and gets a FREE joint and a
floor, its parts held closed by stiffening those drives (``joint_target_ke``/``kd``). The
pull is a world-frame wrench on the part (``State.body_f``), recomputed every substep.

XPBD measures a revolute joint's angle from the relative rotation of its two frames, in
(-pi, pi]: a joint limited at 180 deg (a refrigerator door) wraps to -180 deg the moment
it reaches its limit, and the limit then throws it apart (Newton's XPBD, like Warp's,
handles joint coordinates only within [-pi, pi]). :func:`_center_revolute` therefore
turns each revolute joint's parent frame to the middle of its range, so that the solver's
angle is the joint's position less that middle (limits at +-90 deg for 0..180 deg); the
bodies, the limits and the drives are where they were, and the trajectories report the
joint's own position.

XPBD does not model joint friction (Newton's solver docs: ``joint_friction`` is not
supported; only the MuJoCo solver has it, and that needs ``mujoco-warp``, whose MuJoCo
pin conflicts with the project's ``mujoco==4.0.0``), so :class:`_StickSlip` applies the
friction Newton's importer read from the USD through the solver's drives and joint
forces (docs/validation.md, "Engine parity").
"""

from __future__ import annotations

import logging
import math
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.validate.engine_scenarios import Scenario, Trajectory, hold_gains

log = logging.getLogger(__name__)

FRAME_DT = 1 / 120
SUBSTEPS = 4
SOLVER_ITERATIONS = 2


def _quiet_warp():
    import warp as wp

    wp.config.quiet = True
    return wp


def usd_path(asset: BuiltAsset, scratch: Path) -> Path:
    """The asset's ``model.usdc`` (or ``.usda``), or one written into ``scratch`` when the
    folder has none (an asset built without the USD format)."""
    from asset_pipeline.assets.usd import USD_NAME, usd_stage

    for name in (USD_NAME, Path(USD_NAME).with_suffix(".usda").name):
        if asset.path_of(name).is_file():
            return asset.path_of(name)
    log.info("%s: no USD in the folder; exporting one for the check", asset.id)
    tmp = scratch / USD_NAME
    usd_stage(asset).GetRootLayer().Export(str(tmp))
    return tmp


def builders(path: Path):
    """(fixed-base builder, free-base builder with a floor) of one USD file."""
    import newton

    fixed = newton.ModelBuilder()
    fixed.add_usd(str(path), load_visual_shapes=False)
    free = newton.ModelBuilder()
    free.add_usd(
        str(path), load_visual_shapes=False, ignore_paths=[".*/root_joint$"], floating=True
    )
    free.add_ground_plane()
    return fixed, free


def _labels_tail(labels) -> list[str]:
    return [str(x).rsplit("/", 1)[-1] for x in labels]


def simulate(asset: BuiltAsset, scenarios: Sequence[Scenario]) -> list[Trajectory]:
    """All scenarios as worlds of one Newton model, stepped together."""
    _quiet_warp()
    import newton

    from asset_pipeline.assets.usd import prim_name

    with tempfile.TemporaryDirectory() as scratch:
        path = usd_path(asset, Path(scratch))
        fixed, free = builders(path)
    builder = newton.ModelBuilder()
    for s in scenarios:
        builder.add_world(free if s.free_base else fixed)
    model = builder.finalize(device="cpu")
    W = len(scenarios)
    joints = asset.movable_joints
    J = len(joints)
    jlabel = _labels_tail(model.joint_label)
    jworld = model.joint_world.numpy()
    q_start = model.joint_q_start.numpy()
    qd_start = model.joint_qd_start.numpy()
    blabel = _labels_tail(model.body_label)
    bworld = model.body_world.numpy()
    # per world: coordinate index of each movable joint, body of each link
    qi = np.zeros((W, J), dtype=np.int64)
    di = np.zeros((W, J), dtype=np.int64)
    body = {}
    for k, (name, w) in enumerate(zip(jlabel, jworld, strict=True)):
        for n, j in enumerate(joints):
            if name == prim_name(j.name):
                qi[w, n], di[w, n] = q_start[k], qd_start[k]
    for k, (name, w) in enumerate(zip(blabel, bworld, strict=True)):
        body[(int(w), name)] = k
    root = prim_name(asset.root)
    mid = _center_revolute(model, asset, jlabel, W)
    joint_q = model.joint_q.numpy()
    ke = model.joint_target_ke.numpy()
    kd = model.joint_target_kd.numpy()
    target = model.joint_target_q.numpy() if model.joint_target_q is not None else None
    for w, s in enumerate(scenarios):
        if s.free_base:
            fq = q_start[
                [k for k, (n, ww) in enumerate(zip(jlabel, jworld, strict=True)) if ww == w][0]
            ]
            joint_q[fq : fq + 7] = [0.0, 0.0, 0.002, 0.0, 0.0, 0.0, 1.0]
        for n, j in enumerate(joints):
            joint_q[qi[w, n]] = s.q0.get(j.name, j.lower) - mid[w, n]
            if target is not None:
                target[qi[w, n]] = j.lower - mid[w, n]
            if s.free_base:
                ke[di[w, n]], kd[di[w, n]] = hold_gains(asset, j)
    model.joint_q.assign(joint_q)
    model.joint_target_ke.assign(ke)
    model.joint_target_kd.assign(kd)
    control = model.control()
    if target is not None and control.joint_target_q is not None:
        control.joint_target_q.assign(target)
    friction = _StickSlip(
        model.joint_friction.numpy()[di],
        passive=np.array([[not s.free_base] * J for s in scenarios], dtype=bool).reshape(W, J),
        linear=np.array([j.type == "prismatic" for j in joints], dtype=bool),
        q=joint_q[qi],
    )
    joint_f = np.zeros(model.joint_dof_count, dtype=np.float32)
    solver = newton.solvers.SolverXPBD(model, iterations=SOLVER_ITERATIONS)
    s0, s1 = model.state(), model.state()
    newton.eval_fk(model, model.joint_q, model.joint_qd, s0)
    pipeline = newton.CollisionPipeline(model)
    contacts = pipeline.contacts()
    # pulls: (world, body, point (3,), force (3,)) in the body (link) frame
    pulls = []
    com = model.body_com.numpy()
    for w, s in enumerate(scenarios):
        if s.pull is not None:
            b = body[(w, prim_name(s.pull.link))]
            f = np.asarray(s.pull.direction) * s.pull.force
            pulls.append((b, np.asarray(s.pull.point), f))
    duration = max(s.duration for s in scenarios)
    frames = round(duration / FRAME_DT)
    dt = FRAME_DT / SUBSTEPS
    body_f = np.zeros((model.body_count, 6), dtype=np.float32)
    q_rec = [joint_q[qi] + mid]
    times = [0.0]
    finite = np.ones(W, dtype=bool)
    for frame in range(frames):
        if friction.any:
            stick_ke, stick_q, force = friction.drive()
            ke[di] = np.where(friction.passive, stick_ke, ke[di])
            model.joint_target_ke.assign(ke)
            if target is not None and control.joint_target_q is not None:
                target[qi] = np.where(friction.passive, stick_q, target[qi])
                control.joint_target_q.assign(target)
            joint_f[di] = force
            control.joint_f.assign(joint_f)
        pipeline.collide(s0, contacts)
        for _ in range(SUBSTEPS):
            s0.clear_forces()
            if pulls:
                bq = s0.body_q.numpy()
                body_f[:] = 0.0
                for b, p, f in pulls:
                    R = _rot(bq[b, 3:7])
                    fw = R @ f
                    arm = R @ (p - com[b])
                    body_f[b, :3] = fw
                    body_f[b, 3:] = np.cross(arm, fw)
                s0.body_f.assign(body_f)
            solver.step(s0, s1, control, contacts, dt)
            s0, s1 = s1, s0
        newton.eval_ik(model, s0, s0.joint_q, s0.joint_qd)
        q = s0.joint_q.numpy()[qi]
        friction.update(q, s0.joint_qd.numpy()[di])
        finite &= np.isfinite(q).all(axis=1)
        times.append((frame + 1) * FRAME_DT)
        q_rec.append(q + mid)
    q_all = np.asarray(q_rec)  # (n, W, J)
    times_all = np.asarray(times)
    bq = s0.body_q.numpy()
    bqd = s0.body_qd.numpy()
    out = []
    for w, s in enumerate(scenarios):
        keep = times_all <= s.duration + 1e-9
        b = body[(w, root)]
        T = np.eye(4)
        T[:3, :3] = _rot(bq[b, 3:7])
        T[:3, 3] = bq[b, :3]
        out.append(
            Trajectory(
                times=times_all[keep],
                q=q_all[keep, w, :].reshape(int(keep.sum()), J),
                base_pose=T,
                base_speed=float(np.linalg.norm(bqd[b, :3])) if s.free_base else 0.0,
                base_angular_speed=float(np.linalg.norm(bqd[b, 3:])) if s.free_base else 0.0,
                finite=bool(finite[w] and np.isfinite(T).all()),
            )
        )
    return out


def _center_revolute(model, asset: BuiltAsset, jlabel: list[str], W: int) -> np.ndarray:
    """Turn the parent frame of every limited revolute joint of ``model`` to the middle
    of its range (module docstring); return the middles, (worlds, joints) radians: the
    solver's coordinate of a joint is its position less its middle."""
    from asset_pipeline.assets.usd import prim_name

    joints = asset.movable_joints
    mid = np.zeros((W, len(joints)))
    revolute = {prim_name(j.name): n for n, j in enumerate(joints) if j.type == "revolute"}
    if not revolute:
        return mid
    jworld = model.joint_world.numpy()
    qd_start = model.joint_qd_start.numpy()
    X_p = model.joint_X_p.numpy()
    axis = model.joint_axis.numpy()
    lower = model.joint_limit_lower.numpy()
    upper = model.joint_limit_upper.numpy()
    for k, (name, w) in enumerate(zip(jlabel, jworld, strict=True)):
        n = revolute.get(name)
        if n is None or w < 0:
            continue
        d = qd_start[k]
        m = 0.5 * (float(lower[d]) + float(upper[d]))
        a = axis[d] / np.linalg.norm(axis[d])
        turn = np.array([*(a * math.sin(m / 2)), math.cos(m / 2)])
        X_p[k, 3:7] = _qmul(X_p[k, 3:7], turn)
        lower[d] -= m
        upper[d] -= m
        mid[w, n] = m
    model.joint_X_p.assign(X_p)
    model.joint_limit_lower.assign(lower)
    model.joint_limit_upper.assign(upper)
    return mid


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product of two quaternions (x, y, z, w)."""
    ax, ay, az, aw = (float(c) for c in a)
    bx, by, bz, bw = (float(c) for c in b)
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


class _StickSlip:
    """Coulomb joint friction for a solver without it (XPBD), from the friction Newton read
    from the USD (``newton:friction`` -> ``Model.joint_friction``, N or N m).

    A sticking joint is held where it stuck by a stiff position drive (XPBD drives are
    compliant constraints: stable at any stiffness) whose force is read back from its
    stretch; once that force would exceed the friction the joint slips, and a slipping
    joint feels the friction as a joint force against its motion until it stops or turns
    back, when it sticks again. Arrays are (worlds, joints); ``passive`` marks the joints
    it acts on (not the ones a drive holds)."""

    #: Stretch of a sticking joint's drive at the full friction force (m or rad).
    STRETCH_LINEAR = 1e-4
    STRETCH_ANGULAR = 1e-3
    #: Below this speed (m/s or rad/s) a slipping joint sticks again.
    STICK_SPEED = 1e-3

    def __init__(self, force, passive, linear, q):
        self.force = np.where(passive, np.maximum(np.asarray(force, dtype=float), 0.0), 0.0)
        self.passive = passive & (self.force > 0)
        stretch = np.where(linear, self.STRETCH_LINEAR, self.STRETCH_ANGULAR)[None, :]
        self.stiffness = self.force / stretch
        self.stuck = self.passive.copy()
        self.q_stick = np.asarray(q, dtype=float).copy()
        self.qd = np.zeros_like(self.q_stick)
        self.any = bool(self.passive.any())

    def drive(self):
        """(drive stiffness, drive target, joint force) for the next frame."""
        ke = np.where(self.stuck, self.stiffness, 0.0)
        f = np.where(self.passive & ~self.stuck, -self.force * np.sign(self.qd), 0.0)
        return ke, self.q_stick, f

    def update(self, q, qd) -> None:
        """Stick or slip after a frame that ended at ``q``, ``qd``."""
        held = self.stiffness * (self.q_stick - q)
        slip = self.stuck & (np.abs(held) > self.force)
        turned = (~self.stuck) & ((np.abs(qd) < self.STICK_SPEED) | (qd * self.qd < 0))
        self.stuck = self.passive & ((self.stuck & ~slip) | turned)
        self.q_stick = np.where(turned, q, self.q_stick)
        self.qd = np.where(
            slip & (np.abs(qd) < self.STICK_SPEED), np.sign(-held) * self.STICK_SPEED, qd
        )


def _rot(quat_xyzw: np.ndarray) -> np.ndarray:
    x, y, z, w = (float(c) for c in quat_xyzw)
    n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
