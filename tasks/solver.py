"""Scripted solver: grasp the handle and move the part along its joint, and ``check_tasks``.

The solver drives the Panda with ``pd_ee_delta_pose`` as a Cartesian controller
(one env, CPU simulation). The env has already placed the robot where the handle's
opening path is reachable and started the arm at the pre-grasp (:mod:`tasks.placement`).

1. pre-grasp: the gripper 10 cm in front of the handle, pointing into the face that
   carries it (its outward normal comes from the joint: the direction the handle
   moves as the part opens, so a lid is approached from above), fingers closing
   across a bar or knob; a recessed pull (a pocket bridged by a flush grip bar, see
   ``generator.procedural.blocks``) is entered with the fingers opened just wider than
   the bridge, lined up 2 cm in front of it, the fingertips on either side of the
   bridge; a part without a modelled handle (kind ``none``) is entered with closed
   fingertips;
2. approach the handle, 3. close the fingers (pinching the bar, knob or bridge;
   without a handle: lean on the surface toward the free edge);
4. pull: every step the goal is the grasp pose carried by the part's link moved a
   little further along its joint (a translation for drawers, a rotation about the
   hinge for doors, the tcp turning with the door), computed from the link's
   *current* pose, so the command is a velocity along the joint's own path that
   tolerates lag and slip; when the controller's IK finds no solution for the
   turning hand (the tcp freezes), only the position follows the path;
4b. when the pull stalls short of the goal: a bottom-hinged door whose weight now
   opens it is let go to fall to its stop; another door at least ``push_min_angle``
   ajar is pushed from inside (the closed fingers go round its free edge and press
   on its inner face along the hinge circle, as a paddle along the face or poking
   it, whichever the arm's kinematics follow further; if going round the edge knocks
   the part back by ``push_max_loss``, the push is abandoned). A door whose handle
   the arm cannot follow round its whole arc (a wide fridge door) but can push on
   from part of the way is pulled only that far, then pushed: before pulling, the
   plan (switch fraction, pusher orientation) is chosen by inverse kinematics from
   the robot's actual pose (:func:`tasks.placement.best_push_plan`, which the
   placement also ranks bases by);
4c. a side door still short of the goal but ajar after those pushes is pushed on
   from inside from another stand: the robot lets go, draws the hand in over its
   base, and the base moves, as a mobile base would, to a stand in front of the
   opening (:func:`tasks.placement.push_stand`, chosen by inverse kinematics, clear
   of what the door sweeps from there) along a route that keeps clear of the object
   and the door (:func:`tasks.placement.base_route`), 3 cm and 0.06 rad per control
   step; the arm then presses the inner face on. A door whose pressing point swings
   round the object's corner takes up to three such stands (``restand_max``; each
   adds ``restand_steps`` to the step budget);
5. hold still until the success flag holds (the part must be nearly still); a part
   that stalls already past the goal fraction is held there (a lid let go falls shut).

Knobs are pinched sideways (a vertical pinch catches a worktop overhanging a drawer).
A grasp stopped short of the handle is tried again with the fingers closing along the
bar; a pull that does not move the part at all (the fingers, opened wide, stopped on a
worktop's lip just above the pull and never held it) is tried again once with the
fingers opened just past the bar, the hand pitched 20 degrees toward the part's nearer
edge (coming from below under a worktop).
A door's handle moves at most ``handle_speed`` per step (a wide fridge door's grasp
slips when swung at the revolute speed). Every action is checked against the arm
controller's own inverse kinematics (CPU: Pinocchio CLIK, 100 iterations from the
current joints; where it fails the controller holds the arm still, for good near a
singularity): the step is halved until it converges; holding the handle at a wrist
singularity, where no shortened step converges, the step is sent with the hand turned
0.1 rad about the held bar (the twist escape; the pinch holds, and the arm gets off
the singularity); away from the handle a stuck arm is drawn in toward its shoulder.
A bottom-hinged door is let go with the hand drawn out of its face, up and back
toward the base.

``SolverConfig(trace=True)`` records per step the phase, open fraction, tcp-handle
distance, finger gap (a grasp that slipped closes to 0), the arm's smallest
joint-limit margin and the number of twist escapes so far in ``SolveResult.trace``
(also ``ScriptedSolver.trace``).
``check_tasks(path)`` runs the solver on every movable part of every built asset
under ``path`` and reports which ones the robot can really open.
"""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from scipy.spatial.transform import Rotation

from asset_pipeline.assets.built_asset import BuiltAsset
from sim_envs.asset_sources import ListSource, open_source
from tasks.placement import (
    PUSH_MARGIN,
    PUSH_TILTS,
    READY_TCP,
    PandaReach,
    base_route,
    best_push_plan,
    grasp_score,
    hinge_frame_link,
    push_stand,
    push_steps,
    push_waypoints_link,
)

log = logging.getLogger(__name__)

POS_STEP = 0.1  # metres per unit action (pd_ee_delta_pose of ManiSkill's Panda)
ROT_STEP = -0.1  # radians per unit action: ManiSkill scales rotations by rot_lower (= -0.1)
GRIPPER_OPEN, GRIPPER_CLOSED = 1.0, -1.0
TUCK_TCP = np.array([0.2, 0.0, 0.75])  # tcp in the robot base frame while the base drives


@dataclass
class SolverConfig:
    pregrasp_distance: float = 0.10
    grasp_depth: float = 0.005  # how far past the handle point the tcp goes (into the bar)
    prismatic_speed: float = 0.02  # metres of joint motion commanded per control step
    revolute_speed: float = 0.05  # radians per control step
    handle_speed: float = 0.02  # metres per control step of a door's handle along its arc
    overshoot: float = 0.06  # open (or close) this far past the goal fraction
    stall_steps: int = 10
    max_steps: int = 400
    hold_steps: int = 15
    recess_depth: float = -0.0045  # tcp past a recessed pull's point (the bridge's middle):
    # 4.5 mm short of it, so the 18.5 mm fingertips clear the bottom of a 10 mm pocket
    recess_open: float = -0.08  # gripper action: fingers 13 mm from the centre (bridge 12 mm)
    narrow_open: float = 0.04  # gripper action: fingers 16 mm from the centre (a bar's regrasp)
    narrow_pitch_deg: float = 20.0  # that regrasp comes in pitched toward the nearer edge
    none_depth: float = 0.008  # how far past an unmodelled handle point the closed fingers go
    recess_press: float = 0.04  # m the pulling goal is set into the pocket's side wall
    release_fraction: float = 0.08  # a bottom-hinged door this far open falls open if let go
    release_steps: int = 60
    push_min_angle: float = 0.25  # rad a door must be ajar before it can be pushed open
    push_edge_clearance: float = 0.08  # m beyond the free edge when going round it
    push_clearance: float = 0.025  # m between the part's inner face and the tcp line
    push_max_loss: float = 0.05  # open fraction the push approach may lose before it gives up
    push_retry_steps: int = 100  # steps a second push needs; fewer left: no retry
    # a push presses this x the handle's radius from the hinge: nearer the hinge than the
    # plans' tasks.placement.PUSH_RADIUS (0.85) that ranked the robot's base, so the hand
    # travels less
    push_radial: float = 0.7
    push_retry_radial: float = 0.55  # a second push presses this x the handle's radius out
    push_turn_tol: float = 0.3  # rad: a hand not turned this near for the push turns at home
    push_home_clearance: float = 0.1  # m in front of the door's outer face for that turn
    push_out_clearance: float = 0.25  # m in front of it the hand first backs straight out to
    goal_margin: float = 0.01  # a stalled part this far past the goal fraction is held there
    # a door the arm cannot push on from its stand: the base moves (as a mobile base
    # would) to another stand in front of the opening and the arm pushes from inside
    restand: bool = True
    restand_first: bool = False  # another stand before any push from the first
    restand_gain: float = 0.08  # open fraction a stand's push must add, else none is taken
    restand_max: int = 3  # stands after the first at most
    restand_steps: int = 200  # control steps each further stand adds to the budget
    drive_step: float = 0.03  # m the base moves per control step
    drive_turn: float = 0.06  # rad the base turns per control step
    ik_check: bool = True  # shrink steps the arm controller's IK cannot follow
    twist_escape: bool = True  # holding at a wrist singularity: turn the hand about the bar
    pinch_retry: bool = True  # a grasp stopped short of the handle: again along the bar
    approach_blocked: float = 0.02  # m short of the grasp point that counts as stopped
    pull_moved: float = 0.01  # open fraction a pull must move the part by to count as held
    regrasp_steps: int = 150  # steps the narrow second grasp needs, else it is not tried
    trace: bool = False  # record per-step diagnostics in SolveResult.trace


@dataclass
class SolveResult:
    success: bool
    steps: int
    final_fraction: float
    phase: str  # last phase reached: pregrasp, approach, grasp, move, hold
    reason: str = ""
    trace: list[dict[str, Any]] = field(default_factory=list, repr=False)  # if config.trace
    stands: int = 0  # stands the base moved to after the first (the restand step)


def _pose_matrix(raw: Any) -> np.ndarray:
    """(7,) [p, wxyz] -> (4, 4)."""
    raw = np.asarray(raw, dtype=float).reshape(-1)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([raw[4], raw[5], raw[6], raw[3]]).as_matrix()
    T[:3, 3] = raw[:3]
    return T


def _np(x: Any) -> np.ndarray:
    return x.detach().cpu().numpy() if hasattr(x, "detach") else np.asarray(x)


def grasp_frame(
    approach: np.ndarray, bar_axis: np.ndarray, center: np.ndarray, hint_y: np.ndarray
) -> np.ndarray:
    """Tcp pose (4, 4) at ``center``: z along ``approach``, fingers (y) closing across the bar.

    Of the two closing directions the one nearer ``hint_y`` (the current tcp y) is used.
    """
    a = approach / np.linalg.norm(approach)
    c = np.cross(a, bar_axis)
    if np.linalg.norm(c) < 1e-3:  # knob or bar along the approach: close vertically
        c = np.cross(a, np.cross(np.array([0.0, 0.0, 1.0]), a))
    c = c - a * (c @ a)
    c /= np.linalg.norm(c)
    if c @ hint_y < 0:
        c = -c
    T = np.eye(4)
    T[:3, :3] = np.stack([np.cross(c, a), c, a], axis=1)
    T[:3, 3] = center
    return T


def joint_motion(joint_type: str, axis: np.ndarray, pivot: np.ndarray, dq: float) -> np.ndarray:
    """(4, 4) world motion of a part moved by ``dq`` along its joint (axis through pivot)."""
    M = np.eye(4)
    if joint_type == "prismatic":
        M[:3, 3] = axis * dq
    else:
        R = Rotation.from_rotvec(axis * dq).as_matrix()
        M[:3, :3] = R
        M[:3, 3] = pivot - R @ pivot
    return M


class _PushDone(Exception):
    """Going round to push, the hand swung the part past its target."""


class _PushAborted(Exception):
    """The push approach knocked the part shut."""


class ScriptedSolver:
    """Cartesian grasp-and-move solver for one CPU env of an ArticulatedPartEnv task."""

    def __init__(self, env: gym.Env, config: SolverConfig | None = None) -> None:
        self.env = env
        self.u = env.unwrapped
        if self.u.num_envs != 1:
            raise ValueError("the scripted solver drives one env (num_envs=1, physx_cpu)")
        if self.u.control_mode != "pd_ee_delta_pose":
            raise ValueError(
                f"the scripted solver needs control_mode='pd_ee_delta_pose', got {self.u.control_mode!r}"
            )
        self.cfg = config or SolverConfig()
        self._ik_failed = False  # the last step's inverse kinematics failed at every scale
        self._phase = ""
        self._reach: PandaReach | None = None  # the arm's kinematics, for planning a push
        self._grip_axis: np.ndarray | None = None  # world axis of the held bar (twist escape)
        self._twists = 0  # steps sent with a twist escape so far

    # ---- state
    def _tcp(self) -> np.ndarray:
        return _pose_matrix(_np(self.u.agent.tcp.pose.raw_pose)[0])

    def _base(self) -> np.ndarray:
        return _pose_matrix(_np(self.u.agent.robot.pose.raw_pose)[0])

    def _link(self) -> np.ndarray:
        return _pose_matrix(_np(self.u.target_link.pose.raw_pose)[0])

    def _action(self, goal: np.ndarray, gripper: float) -> np.ndarray:
        """pd_ee_delta_pose action moving the tcp toward ``goal`` (4, 4, world)."""
        base = self._base()
        cur = self._tcp()
        Rb = base[:3, :3]
        dp = Rb.T @ (goal[:3, 3] - cur[:3, 3])
        n = np.linalg.norm(dp)
        if n > POS_STEP:
            dp *= POS_STEP / n
        # rotation error in the root frame: R_goal_b = dR @ R_cur_b
        dR = (Rb.T @ goal[:3, :3]) @ (Rb.T @ cur[:3, :3]).T
        rv = Rotation.from_matrix(dR).as_rotvec()
        rn = np.linalg.norm(rv)
        if rn > abs(ROT_STEP):
            rv *= abs(ROT_STEP) / rn
        euler = Rotation.from_rotvec(rv).as_euler("XYZ")
        return np.concatenate([dp / POS_STEP, euler / ROT_STEP, [gripper]]).astype(np.float32)

    def _ik_solvable(self, action: np.ndarray) -> bool:
        """Whether the arm controller's inverse kinematics (CPU: Pinocchio CLIK, 100
        iterations, from the current joints) converges for ``action``; where it does not,
        the controller holds the arm where it is (see ``_feasible``)."""
        try:
            import torch

            ctrl = self.u.agent.controller.controllers["arm"]
            a = ctrl._preprocess_action(torch.as_tensor(action[None, :6], dtype=torch.float32))
            prev = ctrl._target_pose if ctrl.config.use_target else ctrl.ee_pose_at_base
            target = ctrl.compute_target_pose(prev, a)
            q = ctrl.kinematics.compute_ik(
                pose=target,
                q0=ctrl.articulation.get_qpos(),
                is_delta_pose=False,
                current_pose=ctrl.ee_pose_at_base,
                solver_config=ctrl.config.delta_solver_config,
            )
        except Exception:  # another controller layout: no check
            return True
        return q is not None

    def _feasible(self, action: np.ndarray) -> np.ndarray:
        """``action`` with its arm part shrunk (halved up to 4 times) until the controller's
        inverse kinematics converges: near a singularity it fails for a full step (the arm
        then freezes) but not for a smaller one in the same direction."""
        self._ik_failed = False
        for k in range(5):
            scaled = action.copy()
            scaled[:6] *= 0.5**k
            if self._ik_solvable(scaled):
                return scaled
        self._ik_failed = True
        if not self._phase.startswith(("push", "release")):
            twisted = None
            if self.cfg.twist_escape and self._phase.startswith("move"):
                twisted = self._twist_escape(action)
                self._twists += twisted is not None
            return action if twisted is None else twisted  # else keep the grasp where it is
        # stuck at a stretched singularity: pull the hand in toward the shoulder a little
        tcp, base = self._tcp(), self._base()
        shoulder = base[:3, :3] @ np.array([0.0, 0.0, 0.333]) + base[:3, 3]
        d = base[:3, :3].T @ (shoulder - tcp[:3, 3])
        escape = np.zeros_like(action)
        escape[:3] = 0.02 * d / max(np.linalg.norm(d), 1e-6) / POS_STEP
        escape[6:] = action[6:]
        return escape if self._ik_solvable(escape) else action

    def _twist_escape(self, action: np.ndarray) -> np.ndarray | None:
        """The pull ``action`` (shortened up to 4x) with the hand turned a little, about the
        handle's bar first (the fingers pinch it, so the grasp holds), else about a base
        axis, for an arm holding the handle at a wrist singularity: there (joint 5 near 0,
        the Jacobian's smallest singular value ~0.01) the controller's damped IK stalls for
        any step of the pull itself, shortened or not, but converges once the hand may turn
        off it. None if no such step converges."""
        base_R = self._base()[:3, :3]
        axes = [base_R.T @ self._grip_axis] if self._grip_axis is not None else []
        axes += list(np.eye(3))
        for scale in (1.0, 0.5, 0.25):
            for ax in axes:
                for sign in (1.0, -1.0):
                    twisted = action.copy()
                    twisted[:3] *= scale
                    rv = sign * abs(ROT_STEP) * ax / np.linalg.norm(ax)
                    twisted[3:6] = Rotation.from_rotvec(rv).as_euler("XYZ") / ROT_STEP
                    if self._ik_solvable(twisted):
                        self._ik_failed = False
                        return twisted
        return None

    def _errors(self, goal: np.ndarray) -> tuple[float, float]:
        cur = self._tcp()
        dp = float(np.linalg.norm(goal[:3, 3] - cur[:3, 3]))
        dr = float(np.linalg.norm(Rotation.from_matrix(goal[:3, :3] @ cur[:3, :3].T).as_rotvec()))
        return dp, dr

    def _finger_gap(self) -> float:
        return float(_np(self.u.agent.robot.get_qpos())[0, 7:9].sum())

    def _arm_limit_margins(self) -> np.ndarray:
        """(7,) distance (rad) of each arm joint to its nearer limit."""
        q = _np(self.u.agent.robot.get_qpos())[0, :7]
        lim = _np(self.u.agent.robot.get_qlimits())[0, :7]
        return np.minimum(q - lim[:, 0], lim[:, 1] - q)

    def _arm_limit_margin(self) -> float:
        """Smallest distance (rad) of an arm joint to its limit."""
        return float(self._arm_limit_margins().min())

    @staticmethod
    def _frozen(before: np.ndarray, after: np.ndarray) -> bool:
        """The tcp did not move between two steps (< 0.2 mm, < 2 mrad): IK failed."""
        dp = float(np.linalg.norm(after[:3, 3] - before[:3, 3]))
        dr = float(
            np.linalg.norm(Rotation.from_matrix(after[:3, :3] @ before[:3, :3].T).as_rotvec())
        )
        return dp < 2e-4 and dr < 2e-3

    def _retreat(self, back: float) -> np.ndarray:
        """Tcp goal ``back`` metres out of the face it holds, a little up and drawn back
        toward the robot's base (a falling door comes down toward the hand; a stretched
        arm can still pull in)."""
        goal = self._tcp()
        p = goal[:3, 3]
        to_base = self._base()[:3, 3] - p
        to_base[2] = 0.0
        n = np.linalg.norm(to_base)
        pull = to_base / n * min(0.1, n) if n > 1e-6 else np.zeros(3)
        goal[:3, 3] = p - goal[:3, 2] * back + pull + np.array([0.0, 0.0, 0.05])
        return goal

    def _go(
        self, goal_fn, gripper: float, do, tol: float = 0.02, budget: int = 30, rot_tol: float = 9.0
    ) -> bool:
        """Step toward ``goal_fn()`` (a (4, 4) pose, re-evaluated every step) until within
        ``tol`` (m) and ``rot_tol`` (rad)."""
        for _ in range(budget):
            goal = goal_fn()
            dp, dr = self._errors(goal)
            if dp < tol and dr < rot_tol:
                return True
            do(self._action(goal, gripper))
        return False

    def _push_open(
        self,
        part: Any,
        target: float,
        axis: np.ndarray,
        do,
        frac,
        tilt: float,
        radial: float,
        inside: bool = False,
    ) -> None:
        """Let go of the handle, go round the free edge and push the inner face open
        (the pusher tilted by ``tilt``, pressing ``radial`` x the handle's radius from the
        hinge, see :func:`tasks.placement.push_waypoints_link`). ``inside``: the hand is
        free, in front of the opening (after :meth:`_restand`), and comes to the inner
        face from there."""
        cfg = self.cfg
        _, radial_l, normal_l, _ = hinge_frame_link(part)
        depth = self._inner_face_depth(normal_l)
        edge = self._part_extent(radial_l)
        waypoints = push_waypoints_link(
            part, tilt, depth, cfg.push_clearance, cfg.push_edge_clearance, edge, radial, inside
        )

        def nearest(poses: list) -> np.ndarray:
            """Of a waypoint's finger orientations, the one nearest the hand's now."""
            L, R = self._link(), self._tcp()[:3, :3]
            return min(poses, key=lambda T: -np.trace((L[:3, :3] @ T[:3, :3]).T @ R))

        # 1. open and back off along the face normal
        back = self._tcp()
        back[:3, 3] -= back[:3, 2] * 0.12
        self._phase = "push:back"
        self._go(lambda: back, GRIPPER_OPEN, do, budget=15)
        # 2. turn the closed fingers to the pushing orientation there
        turned = back.copy()
        turned[:3, :3] = (self._link() @ nearest(waypoints[0][1]))[:3, :3]
        self._phase = "push:turn"
        self._go(lambda: turned, GRIPPER_CLOSED, do, budget=15, rot_tol=0.1)
        log.debug("push: tilt %.2f, turned to %.2f rad off", tilt, self._errors(turned)[1])
        backed_off = self._errors(back)[0] < 0.04
        if not inside and backed_off and self._errors(turned)[1] > cfg.push_turn_tol:
            # the arm, stretched along the pulled handle, cannot turn the hand there (a
            # joint at its limit): turn it at the ready pose's tcp, where the arm is most
            # dexterous, on its way round (the hand is then the wrong way round in front
            # of the door, its 0.2 m width sweeping the free edge shut); not while the
            # hand is still at the handle (it would drag the door along)
            self._phase = "push:home"
            home = turned.copy()
            home[:3, 3] = self._base()[:3, :3] @ READY_TCP + self._base()[:3, 3]
            # a robot standing behind the opened door's plane would take the hand through
            # the door (sweeping it shut): keep the turn in front of its outer face
            L = self._link()
            n_w = L[:3, :3] @ normal_l
            handle_w = L[:3, :3] @ np.asarray(part.handle_link, dtype=float) + L[:3, 3]
            behind = cfg.push_home_clearance - n_w @ (home[:3, 3] - handle_w)
            if behind > 0:
                home[:3, 3] += n_w * behind
            # first straight out of the door's face, the hand as it is, so that the arm
            # does not sweep the door on its way home
            out = self._tcp()
            out[:3, 3] += n_w * max(cfg.push_out_clearance - n_w @ (out[:3, 3] - handle_w), 0.0)
            self._go(lambda: out, GRIPPER_CLOSED, do, tol=0.03, budget=20)
            self._go(lambda: home, GRIPPER_CLOSED, do, tol=0.03, budget=40, rot_tol=0.1)
            log.debug("push: turned at home to %.2f rad off", self._errors(home)[1])
        start = frac()

        def guarded(action: np.ndarray) -> None:
            do(action)
            if frac() < start - cfg.push_max_loss:
                raise _PushAborted
            if frac() >= target:  # going round already swung it open: stop there
                raise _PushDone

        # 3. round the free edge, behind the inner face and along it to the pressing point
        try:
            for name, poses in waypoints:
                self._phase = f"push:{name}"
                T = nearest(poses)
                self._go(lambda T=T: self._link() @ T, GRIPPER_CLOSED, guarded, budget=25)
        except _PushDone:
            log.debug("push approach opened the part to %.3f", frac())
            return
        except _PushAborted:
            # going round the free edge swept the part shut: back off, keep what is left
            log.debug("push approach closed the part (%.3f -> %.3f); aborting", start, frac())
            self._phase = "push:abort"
            away = self._tcp()
            away[:3, 3] -= away[:3, 2] * 0.08
            for _ in range(10):
                do(self._action(away, GRIPPER_CLOSED))
            return
        self._phase = "push"
        # 4. push: the pressing pose carried a little further along the hinge circle;
        # once the arm cannot turn the hand any further (a wrist joint at its limit),
        # the hand keeps its orientation and only its position follows the circle
        press = nearest(waypoints[-1][1])
        history: list[float] = []
        follow_rotation = True
        last_tcp = self._tcp()
        while True:
            f = frac()
            if f >= target or self._step >= self._max_steps - cfg.hold_steps:
                break
            history.append(f)
            tcp = self._tcp()
            stuck = self._ik_failed if cfg.ik_check else self._frozen(last_tcp, tcp)
            last_tcp = tcp
            if follow_rotation and len(history) > 2 and stuck:
                follow_rotation = False
                history = [f]
                self._phase = "push:translate"
            if len(history) > 2 * cfg.stall_steps and f - history[-2 * cfg.stall_steps] < 0.005:
                break
            L = self._link()
            dq = min(cfg.revolute_speed, (target - f) * part.range + 0.01)
            goal = joint_motion("revolute", axis, L[:3, 3], dq) @ L @ press
            if not follow_rotation:
                goal[:3, :3] = tcp[:3, :3]
            do(self._action(goal, GRIPPER_CLOSED))

    def _push_from_stands(
        self, part: Any, target: float, axis: np.ndarray, do, frac, depth: float
    ) -> int:
        """Push the door on from further stands (:meth:`_restand`), up to ``restand_max``
        of them, while it is short of the goal; returns how many were taken."""
        cfg, u = self.cfg, self.u
        taken = 0
        while taken < cfg.restand_max and frac() < u.open_goal + cfg.goal_margin:
            tilt = self._restand(part, do, frac, depth, target)
            if tilt is None:
                break
            taken += 1
            self._stands += 1
            self._push_open(part, target, axis, do, frac, tilt, cfg.push_radial, True)
        return taken

    def _restand(self, part: Any, do, frac, depth: float, target: float) -> float | None:
        """Move the robot's base, as a mobile base would, to another stand in front of
        the opening from which the arm pushes the door's inner face on toward ``target``
        (:func:`tasks.placement.push_stand`): let go, draw the hand in over the base and
        drive along a route clear of the object and the door
        (:func:`tasks.placement.base_route`), ``drive_step`` and ``drive_turn`` per
        control step. Returns the pusher's tilt, or None (no stand from which the push
        adds ``restand_gain``, or no route: the robot stays where it is)."""
        import torch
        from mani_skill.utils.structs.pose import Pose

        from sim_envs.scene import yaw_quat

        cfg = self.cfg
        reach, base, yaw, _ = self._reach_model()
        bounds = self.u.episode_assets[0].bounds
        fraction = frac()
        stand = push_stand(reach, part, bounds, fraction, depth, end=min(target + 0.04, 1.0))
        if stand is None or stand[2] < fraction + cfg.restand_gain:
            log.debug("no further stand (%s)", None if stand is None else round(stand[2], 2))
            return None
        goal, goal_yaw, _, tilt = stand
        route = base_route(part, bounds, fraction, base, goal)
        if route is None:
            log.debug("no route to another stand")
            return None
        self._max_steps += cfg.restand_steps
        # let go, back out of the face and draw the hand in over the base
        self._phase = "restand:let-go"
        for waypoint in self._let_go_waypoints(part, do):
            self._go(lambda w=waypoint: w, GRIPPER_CLOSED, do, tol=0.03, budget=30)
        # drive: along the route's legs, the height and heading turned evenly on the way
        self._phase = "restand:drive"
        legs = np.diff(route, axis=0)
        length = float(np.linalg.norm(legs, axis=1).sum())
        turn = float(np.angle(np.exp(1j * (goal_yaw - yaw))))
        n = max(1, int(np.ceil(max(length / cfg.drive_step, abs(turn) / cfg.drive_turn))))
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(legs, axis=1))])
        obj = _pose_matrix(_np(self.u.object.pose.raw_pose)[0])
        obj_yaw = float(np.arctan2(obj[1, 0], obj[0, 0]))
        hold = np.zeros(7)
        hold[6] = GRIPPER_CLOSED
        for k in range(1, n + 1):
            t = k / n
            xy = np.array([np.interp(t * length, cum, route[:, i]) for i in (0, 1)])
            p = np.append(xy, (1 - t) * base[2] + t * goal[2])
            world = obj[:3, :3] @ p + obj[:3, 3]
            q = yaw_quat(torch.tensor([obj_yaw + yaw + t * turn], dtype=torch.float32))
            self.u.agent.robot.set_pose(
                Pose.create_from_pq(p=torch.tensor(world[None], dtype=torch.float32), q=q)
            )
            do(hold)
        log.debug("another stand: %.2f m, %.2f rad in %d steps; tilt %.2f", length, turn, n, tilt)
        return tilt

    def _let_go_waypoints(self, part: Any, do) -> list[np.ndarray]:
        """Open the fingers where the hand is, then the tcp poses (world) that take it,
        without sweeping the door, to ``TUCK_TCP`` over the base: straight out of the
        door's outer face first when it is on that side (it was holding the handle),
        round the free edge when the way to the base crosses the door."""
        cfg = self.cfg
        here = self._tcp()
        for _ in range(4):
            do(self._action(here, GRIPPER_OPEN))
        L = self._link()
        axis_l, radial_l, normal_l, _ = hinge_frame_link(part)
        a_w, r_w, n_w = (L[:3, :3] @ v for v in (axis_l, radial_l, normal_l))
        hinge = L[:3, 3]
        out: list[np.ndarray] = []
        hand = self._tcp()
        side = float(n_w @ (hand[:3, 3] - hinge))
        if side > -0.02:  # at the outer face
            hand[:3, 3] += n_w * max(cfg.push_out_clearance - side, 0.0)
            out.append(hand.copy())
        tucked = hand.copy()
        base = self._base()
        tucked[:3, 3] = base[:3, :3] @ TUCK_TCP + base[:3, 3]
        p0, p1 = hand[:3, 3], tucked[:3, 3]
        s0, s1 = float(n_w @ (p0 - hinge)), float(n_w @ (p1 - hinge))
        edge = self._part_extent(radial_l)
        if s0 * s1 < 0:
            crossing = p0 + s0 / (s0 - s1) * (p1 - p0)
            if r_w @ (crossing - hinge) < edge + cfg.push_edge_clearance:
                round_edge = hand.copy()
                round_edge[:3, 3] = (
                    hinge
                    + a_w * (a_w @ (p0 - hinge))
                    + r_w * (edge + 2 * cfg.push_edge_clearance)
                    + n_w * np.sign(s0) * cfg.push_edge_clearance
                )
                out.append(round_edge)
        out.append(tucked)
        return out

    def _reach_model(self) -> tuple[PandaReach, np.ndarray, float, np.ndarray]:
        """The arm's kinematics (for planning), the robot base's position and yaw in the
        object frame and the arm's joints now."""
        from tasks.articulated import READY_QPOS

        if self._reach is None:
            robot = self.u.agent.robot._objs[0]
            self._reach = PandaReach(robot, self.u.agent.ee_link_name, READY_QPOS)
        obj = _pose_matrix(_np(self.u.object.pose.raw_pose)[0])
        base = np.linalg.inv(obj) @ self._base()
        yaw = float(np.arctan2(base[1, 0], base[0, 0]))
        return self._reach, base[:3, 3], yaw, _np(self.u.agent.robot.get_qpos())[0]

    def _plan_push(self, part: Any, fraction: float, depth: float) -> tuple[float | None, float]:
        """Whether to stop pulling at some fraction and push from there: (the switch
        fraction or None: pull all the way, the pusher's tilt).

        From the arm's joints now, the grasp's path and the pull-then-push plans
        (:func:`tasks.placement.best_push_plan`) are followed by inverse kinematics;
        a push is planned only when it scores ``PUSH_MARGIN`` better than the grasp
        (as in the placement, which chose the robot's base for one or the other)."""
        reach, base, yaw, q = self._reach_model()
        bounds = self.u.episode_assets[0].bounds
        pulled, _, _ = grasp_score(reach, part, bounds, base, yaw, q0=q, start=fraction)
        if pulled == 1.0:
            return None, 0.0
        pushed, switch, tilt, _ = best_push_plan(reach, part, base, yaw, q0=q, depth=depth)
        log.debug("plan: pull %.2f, push plan %.2f (switch %.2f)", pulled, pushed, switch)
        if pushed - PUSH_MARGIN <= pulled:
            return None, 0.0
        return switch, tilt

    def _push_tilt(
        self, part: Any, fraction: float, depth: float, tilts: Any = PUSH_TILTS
    ) -> float:
        """Of ``tilts``, the pusher's tilt whose push from ``fraction`` the arm follows
        furthest."""
        reach, base, yaw, q = self._reach_model()
        best, tilt = -1.0, float(tilts[0])
        for t in tilts:
            steps, _ = push_steps(part, fraction, t, depth)
            got, _ = reach.follow(base, yaw, steps, q0=q)
            if got > best:
                best, tilt = got, t
        return tilt

    def _inner_face_depth(self, normal_link: np.ndarray) -> float:
        """How far (m) the target part's collision shapes reach behind its hinge plane
        (negative: the inner face is in front of it, a hinge set back inside the body)."""
        return self._part_extent(-normal_link, floor=-np.inf)

    def _part_extent(self, direction_link: np.ndarray, floor: float = 0.0) -> float:
        """How far (m, >= ``floor``) the target part's collision shapes reach from its
        link origin along ``direction_link`` (e.g. the radial: the free edge's distance)."""
        depth = floor
        for shape in self.u.target_link._objs[0].get_collision_shapes():
            verts = getattr(shape, "vertices", None)
            if verts is None:
                continue
            pose = shape.get_local_pose()
            R = Rotation.from_quat(np.roll(np.asarray(pose.q, dtype=float), -1)).as_matrix()
            v = np.asarray(verts, dtype=float) * np.asarray(shape.scale, dtype=float)
            v = v @ R.T + np.asarray(pose.p, dtype=float)
            depth = max(depth, float((v @ direction_link).max()))
        return depth if np.isfinite(depth) else 0.0

    def _gravity_torque(self) -> float:
        """Gravity's torque (N m) on the target part about its joint axis, positive = opening."""
        link = self.u.target_link._objs[0]
        L = self._link()
        com = L[:3, :3] @ np.asarray(link.cmass_local_pose.p, dtype=float)  # from the hinge
        axis = _np(self.u.joint_axis_world())[0].astype(float)
        weight = np.array([0.0, 0.0, -9.81 * float(link.mass)])
        return float(np.cross(com, weight) @ axis)

    # ---- run
    def solve(self) -> SolveResult:
        """Run one episode from the env's current state (call ``env.reset`` first)."""
        u, cfg = self.u, self.cfg
        part = u.episode_parts[0]
        closing = bool(u.closing)
        # a recessed pull is pinched at its bridge with the fingers opened just past it;
        # a part without a modelled handle is touched with closed fingertips (slim side,
        # 17 mm, across), which press toward the free edge while pulling
        bridged = part.handle_kind == "recessed"
        bare = part.handle_kind == "none"
        recessed = bridged or bare
        knob = part.handle_kind == "knob"
        g_reach = GRIPPER_CLOSED if bare else (cfg.recess_open if bridged else GRIPPER_OPEN)
        g_hold = GRIPPER_CLOSED
        step = 0
        info: dict[str, Any] = {}
        self.trace: list[dict[str, Any]] = []
        self._max_steps = cfg.max_steps
        self._stands = 0
        self._twists, self._grip_axis = 0, None
        phase = self._phase = "pregrasp"

        def frac() -> float:
            return float(_np(u.open_fraction())[0])

        def steps_left() -> int:  # before the final hold
            return self._max_steps - cfg.hold_steps - step

        def do(action: np.ndarray) -> dict:
            nonlocal step, info
            if cfg.ik_check:
                action = self._feasible(action)
            _, _, _, _, info = u.step(action[None])
            step += 1
            self._step = step
            if cfg.trace:
                self.trace.append(
                    {
                        "step": step,
                        "phase": self._phase,
                        "fraction": round(frac(), 4),
                        "tcp_handle": round(float(_np(info["tcp_to_handle_dist"])[0]), 4),
                        "finger_gap": round(self._finger_gap(), 4),
                        "arm_limit_margin": round(self._arm_limit_margin(), 3),
                        "arm_at_limit": int(np.argmin(self._arm_limit_margins())),
                        "twists": self._twists,
                        "tcp_in_link": np.round(
                            (np.linalg.inv(self._link()) @ self._tcp())[:3, 3], 3
                        ).tolist(),
                    }
                )
            return info

        handle_link = _np(u.handle_link_pos)[0].astype(float)
        handle_axis_link = _np(u.handle_axis_obj)[0].astype(float)
        normal_link = _np(u.handle_normal_link)[0].astype(float)
        depth = cfg.recess_depth if bridged else (cfg.none_depth if bare else cfg.grasp_depth)

        across = False  # the second try of a blocked approach: fingers along the bar
        # the second try of a pull that did not move the part: the direction (link frame)
        # its approach is pitched toward, the part's nearer edge across the bar; None: no
        # such try
        narrow_toward: np.ndarray | None = None

        def pinch_axis(L: np.ndarray, approach: np.ndarray) -> np.ndarray:
            """The axis the fingers close across (world frame)."""
            bar = L[:3, :3] @ handle_axis_link
            if bare:  # fingers closing along the face: the "bar" across that
                bar = np.cross(approach, bar)
            elif knob and abs(approach[2]) < 0.7:
                # fingers closing sideways round a knob: a vertical pinch would catch
                # the worktop overhanging a drawer (or the drawer above)
                bar = np.array([0.0, 0.0, 1.0])
            if across:
                bar = np.cross(approach, bar)
            return bar

        def grasp_goal(offset: float) -> np.ndarray:
            L = self._link()
            approach = -(L[:3, :3] @ normal_link)  # into the face carrying the handle
            center = L[:3, :3] @ handle_link + L[:3, 3]
            bar = pinch_axis(L, approach)
            if narrow_toward is not None:  # pitched about the bar
                pitch = np.deg2rad(cfg.narrow_pitch_deg)
                approach = np.cos(pitch) * approach + np.sin(pitch) * (L[:3, :3] @ narrow_toward)
            T = grasp_frame(approach, bar, center, self._tcp()[:3, 1])
            T[:3, 3] = center - approach * offset
            return T

        start = frac()
        for grip_try in range(2):
            narrow = narrow_toward is not None
            # 1-2. pre-grasp then approach
            stages = [("pregrasp", cfg.pregrasp_distance, 0.015, 80)]
            if recessed or narrow:  # line the fingertips up with the pocket (the bar)
                stages.append(("align", 0.02, 0.003, 30))
            stages.append(("approach", -depth, 0.006, 40))
            for _ in range(1 if across or narrow or recessed or not cfg.pinch_retry else 2):
                for name, offset, tol, budget in stages:
                    style = ":across" if across else (":narrow" if narrow else "")
                    phase = self._phase = name + style
                    goal = grasp_goal(offset)
                    for _ in range(budget):
                        dp, dr = self._errors(goal)
                        if dp < tol and dr < 0.05:
                            break
                        do(self._action(goal, cfg.narrow_open if narrow else g_reach))
                        goal = grasp_goal(offset)
                # 3. grasp (without a modelled handle: lean on the face toward the free edge)
                phase = self._phase = "grasp"
                goal = grasp_goal(-depth)
                for _ in range(10):
                    do(self._action(goal, g_hold))
                short = self._errors(goal)[0]
                if bare or short < cfg.approach_blocked:
                    break
                # the fingers met something short of the handle (a worktop overhanging a
                # drawer's short pull, the drawer above): back off and come in again with
                # them closing along the bar (a pull shorter than the 8 cm opening). Fingers
                # that stop wide on the handle are no sign: they often slide onto the bar
                # once the pull starts.
                log.debug("grasp blocked %.3f m short; pinching along the bar", short)
                across = True
            tcp_in_link = np.linalg.inv(self._link()) @ self._tcp()
            if bare:
                # lean across the face (tcp x); for a door, toward its free edge
                press = np.eye(4)
                press[0, 3] = cfg.recess_press
                if part.joint_type == "revolute":
                    _, radial_l, _, _ = hinge_frame_link(part)
                    if tcp_in_link[:3, 0] @ radial_l < 0:
                        press[0, 3] = -cfg.recess_press
                tcp_in_link = tcp_in_link @ press
            # the axis the hand may turn about while holding: the bar the fingers pinch across
            # (a knob pinched sideways: the vertical; a bare face: none)
            sideways_knob = knob and abs((self._link()[:3, :3] @ normal_link)[2]) < 0.7
            # 4. move along the joint
            target = (u.close_goal - cfg.overshoot) if closing else (u.open_goal + cfg.overshoot)
            target = float(np.clip(target, 0.02, 0.98))
            sign = -1.0 if closing else 1.0
            speed = cfg.prismatic_speed
            if part.joint_type == "revolute":  # the handle no faster than a drawer's
                speed = min(
                    cfg.revolute_speed, cfg.handle_speed / max(hinge_frame_link(part)[3], 0.05)
                )
            axis_obj = _np(u.joint_axis_world())[0].astype(float)
            # a door whose handle the arm cannot follow all the way but can push on from
            # part of the way (a wide fridge door): pull only that far, then push
            switch, tilt = None, 0.0
            pushable = not closing and part.joint_type == "revolute"
            if pushable:
                face_depth = self._inner_face_depth(hinge_frame_link(part)[2])
                switch, tilt = self._plan_push(part, frac(), face_depth)
            pull_to = target if switch is None else min(target, switch)
            phase = self._phase = "move"
            history: list[float] = []
            follow_rotation = True
            last_tcp = self._tcp()
            while step < self._max_steps - cfg.hold_steps:
                f = frac()
                if (f <= target) if closing else (f >= pull_to):
                    break
                history.append(f)
                tcp = self._tcp()
                stuck = self._ik_failed if cfg.ik_check else self._frozen(last_tcp, tcp)
                if follow_rotation and len(history) > 2 and stuck:
                    # the controller's IK found no solution for the turning grasp (it then
                    # holds its last target): keep the hand's orientation and only pull along
                    # the path; the grasp pivots about the pads' normal or the bar
                    follow_rotation = False
                    history = [f]
                    self._phase = "move:translate"
                    log.debug("IK stuck at fraction %.3f; translating only", f)
                last_tcp = tcp
                if (
                    len(history) > cfg.stall_steps
                    and abs(f - history[-cfg.stall_steps - 1]) < 0.005
                ):
                    break  # stalled (reach or joint limit, lost grip): settle and let success decide
                L = self._link()
                self._grip_axis = (
                    None
                    if bare
                    else (
                        pinch_axis(L, -(L[:3, :3] @ normal_link))
                        if across
                        else (
                            np.array([0.0, 0.0, 1.0])
                            if sideways_knob
                            else L[:3, :3] @ handle_axis_link
                        )
                    )
                )
                remaining = abs(target - f) * part.range
                dq = sign * min(speed, remaining + 0.01)
                goal = joint_motion(part.joint_type, axis_obj, L[:3, 3], dq) @ L @ tcp_in_link
                if not follow_rotation:
                    goal[:3, :3] = tcp[:3, :3]
                do(self._action(goal, g_hold))
            # the pull did not move the part at all: the fingers never held the handle
            # (opened wide across the bar, one of them met a worktop overhanging the
            # drawer, less than ``approach_blocked`` short of the bar): back off and come
            # in again with the fingers opened just past the bar
            moved = abs(frac() - start)
            if (
                grip_try > 0
                or recessed
                or not cfg.pinch_retry
                or moved >= cfg.pull_moved
                or steps_left() < cfg.regrasp_steps
            ):
                break
            log.debug("the pull did not move the part (%.3f); a narrow pinch", moved)
            phase = self._phase = "regrasp"
            self._go(lambda: grasp_goal(cfg.pregrasp_distance), GRIPPER_OPEN, do, budget=30)
            across = False
            L = self._link()
            approach = -(L[:3, :3] @ normal_link)
            # the fingers' closing direction in the link frame; toward its nearer edge
            fingers = L[:3, :3].T @ np.cross(approach, pinch_axis(L, approach))
            fingers /= max(np.linalg.norm(fingers), 1e-9)
            above = self._part_extent(fingers) - handle_link @ fingers
            below = self._part_extent(-fingers) + handle_link @ fingers
            narrow_toward = fingers if above < below else -fingers
        # 4b. not there yet: a door hanging from a bottom hinge, once ajar, falls open
        # under its own weight when let go; any other door or lid is pushed open from
        # inside (the gripper goes round its free edge and presses on its inner face)
        g_final = g_hold
        short = frac() < u.open_goal + cfg.goal_margin  # past the goal: just hold on
        if pushable and short:
            if frac() >= cfg.release_fraction and self._gravity_torque() > 0.5:
                phase = self._phase = "release"
                g_final = GRIPPER_OPEN
                away = self._retreat(0.08)
                for _ in range(cfg.release_steps):
                    info = do(self._action(away, GRIPPER_OPEN))
                    if bool(_np(info["success"])[0]):
                        break
                if not bool(_np(info["success"])[0]) and steps_left() >= cfg.push_retry_steps:
                    # it came to rest short (on the arm): press its inner face on down
                    phase = self._phase = "push"
                    g_final = GRIPPER_CLOSED
                    tilt = self._push_tilt(part, frac(), face_depth)
                    self._push_open(part, target, axis_obj, do, frac, tilt, cfg.push_radial)
            elif frac() * part.range >= cfg.push_min_angle:
                phase = self._phase = "push"
                g_final = GRIPPER_CLOSED
                stood = 0
                if cfg.restand and cfg.restand_first:
                    stood = self._push_from_stands(part, target, axis_obj, do, frac, face_depth)
                if not stood:
                    if switch is None or frac() < switch - 0.1:  # stalled before the switch
                        tilt = self._push_tilt(part, frac(), face_depth)
                    self._push_open(part, target, axis_obj, do, frac, tilt, cfg.push_radial)
                if (
                    not stood
                    and frac() < u.open_goal + cfg.goal_margin
                    and steps_left() >= cfg.push_retry_steps
                ):
                    # stalled short (the arm at a joint limit): push again from here
                    # with the pusher held another way, nearer the hinge (the hand
                    # travels less for the same swing)
                    others = [t for t in PUSH_TILTS if t != tilt]
                    tilt = self._push_tilt(part, frac(), face_depth, others)
                    log.debug("push stalled at %.3f; again with tilt %.2f", frac(), tilt)
                    self._push_open(part, target, axis_obj, do, frac, tilt, cfg.push_retry_radial)
                if cfg.restand and not stood and frac() * part.range >= cfg.push_min_angle:
                    # still short, out of the arm's reach from here: further stands
                    stood = self._push_from_stands(part, target, axis_obj, do, frac, face_depth)
        # 5. hold still (keep the grasp, or the pushing paddle) until the part settles
        phase = self._phase = "hold"
        hold = self._tcp()
        for _ in range(cfg.hold_steps):
            info = do(self._action(hold, g_final))
            if bool(_np(info["success"])[0]):
                break
        success = bool(_np(info.get("success", [False]))[0]) if info else False
        reason = "" if success else f"final open fraction {frac():.2f}"
        return SolveResult(
            success=success,
            steps=step,
            final_fraction=frac(),
            phase=phase,
            reason=reason,
            trace=self.trace,
            stands=self._stands,
        )


# --------------------------------------------------------------------------- check_tasks

ENV_FOR_JOINT = {"prismatic": "OpenDrawer-v0", "revolute": "OpenDoor-v0"}


@dataclass
class PartCheck:
    asset_id: str
    part: str
    joint_type: str
    env_id: str
    success: bool
    steps: int
    final_fraction: float
    seconds: float
    reason: str = ""
    stands: int = 0  # further stands the robot's base moved to (0: opened where it stood)


def solve_part(
    record: BuiltAsset,
    part_name: str,
    seed: int = 0,
    closing: bool = False,
    config: SolverConfig | None = None,
    **env_kwargs: Any,
) -> tuple[SolveResult, str]:
    """Run the scripted solver on one part of one asset; return the result and env id."""
    import tasks  # noqa: F401  (registers the envs)

    part = next(p for p in record.movable_parts() if p.name == part_name)
    env_id = ENV_FOR_JOINT[part.joint_type]
    if closing:
        env_id = env_id.replace("Open", "Close")
    env = gym.make(
        env_id,
        assets=ListSource([record.folder]),
        target_part=part_name,
        obs_mode="state",
        control_mode="pd_ee_delta_pose",
        sim_backend="physx_cpu",
        render_backend="none",
        **env_kwargs,
    )
    try:
        env.reset(seed=seed)
        res = ScriptedSolver(env, config).solve()
    finally:
        env.close()
    return res, env_id


def check_tasks(
    path: str | Path, seed: int = 0, category: str | None = None, config: SolverConfig | None = None
) -> list[PartCheck]:
    """Try to open every movable part of every built asset under ``path`` with the solver.

    ``path``: a folder of built assets, one asset folder or a catalog file. Returns one
    :class:`PartCheck` per part (``success`` = the robot really opened it).
    """
    out: list[PartCheck] = []
    for rec in open_source(path, category=category):
        for part in rec.movable_parts():
            t0 = time.perf_counter()
            try:
                res, env_id = solve_part(rec, part.name, seed=seed, config=config)
                pc = PartCheck(
                    rec.id,
                    part.name,
                    part.joint_type,
                    env_id,
                    res.success,
                    res.steps,
                    res.final_fraction,
                    time.perf_counter() - t0,
                    res.reason,
                    res.stands,
                )
            except Exception as e:  # a broken asset is a failed check, not a crash
                log.exception("check of %s/%s failed", rec.id, part.name)
                pc = PartCheck(
                    rec.id,
                    part.name,
                    part.joint_type,
                    ENV_FOR_JOINT[part.joint_type],
                    False,
                    0,
                    0.0,
                    time.perf_counter() - t0,
                    f"{type(e).__name__}: {e}",
                )
            log.info(
                "%s/%s: %s", rec.id, part.name, "opened" if pc.success else f"failed ({pc.reason})"
            )
            out.append(pc)
    return out


def summarize(results: list[PartCheck]) -> dict[str, Any]:
    n = len(results)
    ok = sum(r.success for r in results)
    return {
        "parts": n,
        "opened": ok,
        "rate": ok / n if n else 0.0,
        "opened_where_placed": sum(r.success and not r.stands for r in results),
        "failed": [asdict(r) for r in results if not r.success],
    }
