"""Shared base of the drawer / door tasks: a fixed Panda in front of one built asset.

Everything here is batched over parallel environments so that the same code runs
on ``physx_cpu`` (one env per process, vectorized with gymnasium's AsyncVectorEnv)
and ``physx_cuda`` (many envs in one process):

- at reconfiguration each sub-scene ``i`` gets its own asset (``scene_idxs=[i]``),
  sampled with ``_batched_episode_rng`` so CPU and GPU pick the same ones for the
  same seeds; the per-env articulations are merged into one view
  (``Articulation.merge``) and the per-env target links into one ``Link`` view, so
  qpos, poses and velocities are read as (num_envs, ...) tensors;
- the assets are fixed per reconfiguration; with one env the scene is rebuilt on
  every reset by default (``reconfiguration_freq=1``: a new asset each episode),
  with many envs never (``0``: each env keeps its asset). Reloading an asset costs
  0.3-0.5 s on CPU, more than a 100-step episode, so ``reconfiguration_freq=k``
  reloads only every k resets; the resets in between re-sample the target part
  among the loaded asset's parts (per-part data is tabulated at load time) and the
  object, robot and joint poses.

Placement: the object stands on the floor at the origin with its front (+x of the
object frame) toward the robot, turned by a small random yaw. The robot's base is
placed per target part (:mod:`tasks.placement`): for a drawer it faces the front,
its ready pose putting the gripper ``handle_standoff`` metres in front of the
handle; for a door or lid it stands where the whole opening path of the handle is
within comfortable reach and clear of the swept door (beside a side-hinged door,
in front of and beside a bottom-hinged one). Plus a little noise.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np
import sapien
import torch
from gymnasium.utils import seeding as gym_seeding
from mani_skill.agents.robots import Panda
from mani_skill.envs.sapien_env import BaseEnv
from mani_skill.sensors.camera import CameraConfig
from mani_skill.utils import sapien_utils
from mani_skill.utils.building.ground import build_ground
from mani_skill.utils.structs import Articulation, Link, Pose
from mani_skill.utils.structs.types import GPUMemoryConfig, SimConfig

from asset_pipeline.assets.built_asset import BuiltAsset, MovablePart
from asset_pipeline.simulation.sim_options import DEFAULT_SIM_OPTIONS, SimOptions
from sim_envs.asset_sources import AssetSource, open_source
from sim_envs.scene import (
    add_to_scene,
    configure_ground,
    floor_lift,
    handle_world_positions,
    robot_ignores_ground,
    rotate_z,
    scale_part_physics,
    yaw_quat,
)
from tasks.placement import PandaReach, face_normal_link, robot_base_for_part

log = logging.getLogger(__name__)

# Panda joint angles with the gripper horizontal, pointing along the base's +x, fingers
# closing vertically (tcp y axis = world z): the start of every episode. The wrist joint
# (index 6) turns by pi/2 for vertical handle bars so that the fingers close across them.
READY_QPOS = np.array([0.0, -0.2, 0.0, -1.8, 0.0, 3.171, -0.785, 0.04, 0.04], dtype=np.float32)
VERTICAL_BAR_WRIST = 0.785
# robot placements per (asset folder, part, standoff): inverse kinematics is run once
_PLACEMENTS: dict[tuple[str, str, float], tuple[np.ndarray, float]] = {}


@dataclass(frozen=True)
class PhysicsRandomization:
    """Scale factors, each drawn log-uniformly in its (low, high) once per object load,
    for the object's movable parts: mass (and inertia), joint damping, joint friction
    (``sim_envs.scene.scale_part_physics``). For training: what a generator makes is
    lighter and looser than many real parts (a refrigerator door of 16 kg against the
    2.4 kg of a generated side door, ``bench/task_assets.py``)."""

    mass: tuple[float, float] = (0.5, 4.0)
    damping: tuple[float, float] = (0.5, 2.0)
    friction: tuple[float, float] = (0.5, 2.0)

    def __post_init__(self) -> None:
        for lo, hi in (self.mass, self.damping, self.friction):
            if not 0 < lo <= hi:
                raise ValueError(f"a scale range must be 0 < low <= high, got ({lo}, {hi})")

    def draw(self, rng: np.random.RandomState) -> tuple[float, float, float]:
        """(mass, damping, friction) scales."""
        ranges = (self.mass, self.damping, self.friction)
        u = rng.uniform(size=3)
        return tuple(  # type: ignore[return-value]
            float(np.exp(np.log(lo) + x * (np.log(hi) - np.log(lo))))
            for x, (lo, hi) in zip(u, ranges, strict=True)
        )


class ArticulatedPartEnv(BaseEnv):
    """Base task: move one movable part (drawer or door) of a built asset with a Panda.

    Subclasses set ``joint_type`` ("prismatic" or "revolute") and ``closing``.
    Success (as ManiSkill's OpenCabinetDrawer): the target joint reaches
    ``lower + open_goal * range`` (``<= lower + close_goal * range`` when closing)
    while the part is nearly still (|v| <= 0.1 m/s, |w| <= 1 rad/s).
    """

    SUPPORTED_ROBOTS = ["panda"]
    SUPPORTED_REWARD_MODES = ("normalized_dense", "dense", "sparse", "none")
    agent: Panda

    joint_type: str = "prismatic"
    closing: bool = False
    open_goal = 0.75
    close_goal = 0.25
    start_open_range = (0.8, 1.0)  # closing tasks start with the part this far open
    handle_standoff = 0.12
    max_reward = 6.0

    def __init__(
        self,
        *args: Any,
        assets: str | AssetSource | list[str],
        category: str | list[str] | None = None,
        target_part: str | None = None,
        robot_uids: str = "panda",
        robot_init_qpos_noise: float = 0.02,
        object_pos_noise: float = 0.03,
        object_yaw_noise: float = 0.1,
        robot_pos_noise: float = 0.02,
        near_start_prob: float = 0.0,
        require_grasp: bool = False,
        robot_frame_obs: bool = False,
        physics_randomization: PhysicsRandomization | None = None,
        sim_options: SimOptions = DEFAULT_SIM_OPTIONS,
        reconfiguration_freq: int | None = None,
        num_envs: int = 1,
        **kwargs: Any,
    ) -> None:
        self.asset_source = open_source(assets, category=category, joint_type=self.joint_type)
        self.assets: list[BuiltAsset] = self.asset_source.require()
        self.target_part = target_part
        self.robot_init_qpos_noise = robot_init_qpos_noise
        self.object_pos_noise = object_pos_noise
        self.object_yaw_noise = object_yaw_noise
        self.robot_pos_noise = robot_pos_noise
        if near_start_prob > 0 and (self.joint_type != "prismatic" or self.closing):
            raise ValueError("near_start_prob applies to the drawer opening task only")
        self.near_start_prob = float(near_start_prob)
        self.require_grasp = bool(require_grasp)
        self.robot_frame_obs = bool(robot_frame_obs)
        self.physics_randomization = physics_randomization
        self.sim_options = sim_options
        if reconfiguration_freq is None:
            reconfiguration_freq = 1 if num_envs == 1 else 0
        # every reset draws its randomization from the episode seed, so that
        # reset(seed=s) followed by reset() repeats (gymnasium's env checker)
        kwargs.setdefault("enhanced_determinism", True)
        super().__init__(
            *args,
            robot_uids=robot_uids,
            reconfiguration_freq=reconfiguration_freq,
            num_envs=num_envs,
            **kwargs,
        )

    # ------------------------------------------------------------------ configuration
    @property
    def _default_sim_config(self) -> SimConfig:
        return SimConfig(
            spacing=5,
            gpu_memory_config=GPUMemoryConfig(
                max_rigid_contact_count=2**21, max_rigid_patch_count=2**19
            ),
        )

    @property
    def _default_sensor_configs(self) -> list[CameraConfig]:
        # mounted on the robot base (which is placed relative to the handle), looking
        # over the arm at the target part
        pose = sapien_utils.look_at(eye=[-0.25, 0.0, 0.9], target=[0.6, 0.0, 0.3])
        return [
            CameraConfig(
                "base_camera",
                pose=pose,
                width=128,
                height=128,
                fov=np.pi / 2,
                near=0.01,
                far=10,
                mount=self.agent.robot.links_map["panda_link0"],
            )
        ]

    @property
    def _default_human_render_camera_configs(self) -> CameraConfig:
        pose = sapien_utils.look_at(eye=[2.2, -1.6, 1.6], target=[0.3, 0.0, 0.5])
        return CameraConfig(
            "render_camera", pose=pose, width=512, height=512, fov=1.0, near=0.01, far=20
        )

    # ------------------------------------------------------------------ loading
    def _load_agent(self, options: dict) -> None:
        super()._load_agent(options, sapien.Pose(p=[1.5, 0.0, 0.0], q=[0, 0, 0, 1]))
        robot_ignores_ground(self.agent.robot)

    def _load_scene(self, options: dict) -> None:
        self.ground = build_ground(self.scene)
        configure_ground(self.ground, self.sim_options)
        asset_idx = self._batched_episode_rng.randint(0, len(self.assets))
        objects: list[Articulation] = []
        self.episode_assets: list[BuiltAsset] = []
        self.candidate_parts: list[list[MovablePart]] = []  # per env: the parts to pick from
        cand_links: list[list[Link]] = []
        # per env the (mass, damping, friction) scales of its object's movable parts
        self.physics_scales = torch.ones((self.num_envs, 3), device=self.device)
        for i in range(self.num_envs):
            rec = self.assets[int(asset_idx[i])]
            parts = rec.parts_of_type(self.joint_type)
            if self.target_part is not None:
                parts = [p for p in parts if p.name == self.target_part]
                if not parts:
                    raise ValueError(
                        f"{rec.id}: no {self.joint_type} part named {self.target_part!r}"
                    )
            art = add_to_scene(
                self.scene, rec, scene_idxs=[i], name=f"object-{i}", options=self.sim_options
            )
            if self.physics_randomization is not None:
                scales = self.physics_randomization.draw(self._batched_episode_rng[i])
                scale_part_physics(art, *scales)
                self.physics_scales[i] = torch.tensor(scales)
            self.remove_from_state_dict_registry(art)
            objects.append(art)
            cand_links.append([art.links_map[p.name] for p in parts])
            self.episode_assets.append(rec)
            self.candidate_parts.append(parts)
        # an object whose door would swing through the floor stands that much higher
        self._object_lift = torch.tensor(
            [floor_lift(rec) for rec in self.episode_assets], dtype=torch.float32,
            device=self.device,
        )  # fmt: skip
        self.object = Articulation.merge(objects, name="object")
        self.add_to_state_dict_registry(self.object)
        self._tabulate_parts(objects, cand_links)

    def _tabulate_parts(self, objects: list[Articulation], cand_links: list[list[Link]]) -> None:
        """Per env and candidate part (padded to the largest count): (N, P, ...) tensors."""
        n_slots = max(len(c) for c in self.candidate_parts)
        self._cand_links = cand_links
        self.num_candidates = torch.tensor(
            [len(c) for c in self.candidate_parts], device=self.device, dtype=torch.long
        )
        # slot k of env i is candidate k mod P_i; one merged Link view per slot
        self._slot_links = [
            Link.merge([links[k % len(links)] for links in cand_links], name=f"target_link_{k}")
            for k in range(n_slots)
        ]
        rows: dict[str, list] = {k: [] for k in ("dof", "hl", "ho", "ha", "ja", "lo", "hi")}
        rows.update(base=[], yaw=[], normal=[], qstart=[], kind=[])
        for i, parts in enumerate(self.candidate_parts):
            joint_names = [j.name for j in objects[i].active_joints]
            rec = self.episode_assets[i]
            slot_parts = [parts[k % len(parts)] for k in range(n_slots)]
            rows["dof"].append([joint_names.index(p.joint_name) for p in slot_parts])
            rows["hl"].append([p.handle_link for p in slot_parts])
            rows["ho"].append([p.handle_object for p in slot_parts])
            rows["ha"].append([p.handle_axis for p in slot_parts])
            rows["ja"].append([p.axis for p in slot_parts])
            rows["lo"].append([p.lower for p in slot_parts])
            rows["hi"].append([p.upper for p in slot_parts])
            placements = [self._placement(rec, p) for p in slot_parts]
            rows["base"].append([b for b, _, _ in placements])
            rows["yaw"].append([y for _, y, _ in placements])
            rows["qstart"].append(
                [_start_qpos(p, q) for p, (_, _, q) in zip(slot_parts, placements, strict=True)]
            )
            rows["normal"].append([face_normal_link(p) for p in slot_parts])
            rows["kind"].append([p.handle_kind_onehot for p in slot_parts])

        def tensor(v: list) -> torch.Tensor:
            return torch.tensor(np.asarray(v, dtype=np.float32), device=self.device)

        self._slot_dof_idx = torch.tensor(rows["dof"], device=self.device, dtype=torch.long)
        self._slot_handle_link = tensor(rows["hl"])  # (N, P, 3) link frame
        self._slot_handle_rest = tensor(rows["ho"])  # (N, P, 3) object frame
        self._slot_handle_axis = tensor(rows["ha"])  # (N, P, 3)
        self._slot_joint_axis = tensor(rows["ja"])  # (N, P, 3)
        self._slot_qlow = tensor(rows["lo"])  # (N, P)
        self._slot_qhigh = tensor(rows["hi"])  # (N, P)
        self._slot_base = tensor(rows["base"])  # (N, P, 3) robot base, object frame
        self._slot_base_yaw = tensor(rows["yaw"])  # (N, P)
        self._slot_normal = tensor(rows["normal"])  # (N, P, 3) handle face normal, link frame
        self._slot_qstart = tensor(rows["qstart"])  # (N, P, 9) robot joints at the start
        self._slot_handle_kind = tensor(
            rows["kind"]
        )  # (N, P, K) one-hot of built_asset.HANDLE_KINDS
        n = self.num_envs
        self.part_slot = torch.zeros(n, device=self.device, dtype=torch.long)
        self.episode_parts: list[MovablePart] = [c[0] for c in self.candidate_parts]
        self.target_dof_idx = self._slot_dof_idx[:, 0].clone()
        self.handle_link_pos = self._slot_handle_link[:, 0].clone()  # (N, 3) link frame
        self.handle_rest_pos = self._slot_handle_rest[:, 0].clone()  # (N, 3) object frame
        self.handle_axis_obj = self._slot_handle_axis[:, 0].clone()  # (N, 3)
        self.handle_normal_link = self._slot_normal[:, 0].clone()  # (N, 3)
        self.handle_kind = self._slot_handle_kind[:, 0].clone()  # (N, K) one-hot
        self.joint_axis_obj = self._slot_joint_axis[:, 0].clone()  # (N, 3)
        self.qlow = self._slot_qlow[:, 0].clone()  # (N,)
        self.qhigh = self._slot_qhigh[:, 0].clone()  # (N,)
        self.qrange = self.qhigh - self.qlow
        self.start_fraction = torch.zeros(n, device=self.device)
        self.object_yaw = torch.zeros(n, device=self.device)
        self.robot_yaw = torch.zeros(n, device=self.device)
        self._merged_target: dict[tuple[int, ...], Link] = {}

    def _placement(
        self, rec: BuiltAsset, part: MovablePart
    ) -> tuple[np.ndarray, float, np.ndarray | None]:
        """Robot base (object frame), yaw and start joints for ``part``, cached per process."""
        key = (str(rec.folder), part.name, self.handle_standoff)
        if key not in _PLACEMENTS:
            reach = None
            if part.joint_type == "revolute":
                reach = PandaReach(self.agent.robot._objs[0], self.agent.ee_link_name, READY_QPOS)
            _PLACEMENTS[key] = robot_base_for_part(part, rec.bounds, self.handle_standoff, reach)
        return _PLACEMENTS[key]

    def _select_parts(self, env_idx: torch.Tensor) -> None:
        """Pick each env's target part for this episode and copy its row of the tables."""
        slot = (torch.rand(len(env_idx)) * self.num_candidates[env_idx]).long()
        slot = torch.minimum(slot, self.num_candidates[env_idx] - 1)
        self.part_slot[env_idx] = slot
        for name, table in (
            ("target_dof_idx", self._slot_dof_idx),
            ("handle_link_pos", self._slot_handle_link),
            ("handle_rest_pos", self._slot_handle_rest),
            ("handle_axis_obj", self._slot_handle_axis),
            ("handle_normal_link", self._slot_normal),
            ("handle_kind", self._slot_handle_kind),
            ("joint_axis_obj", self._slot_joint_axis),
            ("qlow", self._slot_qlow),
            ("qhigh", self._slot_qhigh),
        ):
            getattr(self, name)[env_idx] = table[env_idx, slot]
        self.qrange = self.qhigh - self.qlow
        for i, k in zip(env_idx.tolist(), slot.tolist(), strict=True):
            self.episode_parts[i] = self.candidate_parts[i][k]

    @property
    def target_link(self) -> Link:
        """A Link view of each env's current target part (one view per slot combination)."""
        slots = tuple(self.part_slot.tolist())
        if len(set(slots)) == 1:
            return self._slot_links[slots[0]]
        if slots not in self._merged_target:
            self._merged_target[slots] = Link.merge(
                [self._cand_links[i][k] for i, k in enumerate(slots)], name="target_link"
            )
        return self._merged_target[slots]

    # ------------------------------------------------------------------ episodes
    def reset(self, seed: int | list[int] | None = None, options: dict | None = None):
        """ManiSkill's reset; also seeds gymnasium's ``np_random`` (the env checker asks for it)."""
        if seed is not None:
            first = int(seed) if np.isscalar(seed) else int(list(seed)[0])
            self._np_random, self._np_random_seed = gym_seeding.np_random(first)
        return super().reset(seed=seed, options=options)

    def _initialize_episode(self, env_idx: torch.Tensor, options: dict) -> None:
        with torch.device(self.device):
            b = len(env_idx)
            self._select_parts(env_idx)
            slot = self.part_slot[env_idx]
            # object: on the floor at the origin (raised where a part would swing through
            # it: sim_envs.scene.floor_lift), front (+x) toward the robot, small yaw
            yaw = (torch.rand(b) * 2 - 1) * self.object_yaw_noise
            pos = torch.zeros((b, 3))
            pos[:, :2] = (torch.rand((b, 2)) * 2 - 1) * self.object_pos_noise
            pos[:, 2] = self._object_lift[env_idx]
            self.object.set_pose(Pose.create_from_pq(p=pos, q=yaw_quat(yaw)))
            self.object_yaw[env_idx] = yaw

            # joints: everything closed; the target part open when the task is closing
            qpos = self.object.get_qlimits()[env_idx][..., 0].clone()
            lo, rng = self.qlow[env_idx], self.qrange[env_idx]
            frac = torch.zeros(b)
            if self.closing:
                a, c = self.start_open_range
                frac = a + (c - a) * torch.rand(b)
            qpos[torch.arange(b), self.target_dof_idx[env_idx]] = lo + frac * rng
            self.object.set_qpos(qpos)
            self.object.set_qvel(torch.zeros_like(qpos))
            self.start_fraction[env_idx] = frac

            # robot: where the target part's opening path is in reach (tasks.placement)
            base = pos + rotate_z(self._slot_base[env_idx, slot], yaw)
            base = base + (torch.rand((b, 3)) * 2 - 1) * self.robot_pos_noise
            robot_yaw = yaw + self._slot_base_yaw[env_idx, slot]
            robot_yaw = robot_yaw + (torch.rand(b) * 2 - 1) * 0.05
            if self.near_start_prob > 0:
                base = base + self._near_start_shift(robot_yaw)
            self.agent.robot.set_pose(Pose.create_from_pq(p=base, q=yaw_quat(robot_yaw)))
            self.robot_yaw[env_idx] = robot_yaw
            rq = self._slot_qstart[env_idx, slot].clone()
            rq[:, :7] += torch.randn((b, 7)) * self.robot_init_qpos_noise
            self.agent.robot.set_qpos(rq)
            self.agent.robot.set_qvel(torch.zeros_like(rq))

    def _near_start_shift(self, robot_yaw: torch.Tensor) -> torch.Tensor:
        """(b, 3) base offsets for a training start-state curriculum: with probability
        ``near_start_prob`` the robot starts moved forward along its heading (the ready
        pose points the gripper along the base's +x) so that the open fingers are from
        2 cm in front of the handle centre to 1 cm past it (plus the pose noise) instead
        of ``handle_standoff`` in front, i.e. around the handle, where closing them grasps
        it; otherwise no offset."""
        b = len(robot_yaw)
        near = torch.rand(b) < self.near_start_prob
        forward = self.handle_standoff - 0.02 + torch.rand(b) * 0.03
        heading = torch.stack([torch.cos(robot_yaw), torch.sin(robot_yaw), torch.zeros(b)], 1)
        return heading * (forward * near)[:, None]

    # ------------------------------------------------------------------ task
    def target_qpos(self) -> torch.Tensor:
        """(N,) joint value of each env's target part."""
        return self.object.get_qpos()[
            torch.arange(self.num_envs, device=self.device), self.target_dof_idx
        ]

    def target_qvel(self) -> torch.Tensor:
        return self.object.get_qvel()[
            torch.arange(self.num_envs, device=self.device), self.target_dof_idx
        ]

    def open_fraction(self) -> torch.Tensor:
        return (self.target_qpos() - self.qlow) / self.qrange

    def handle_positions(self) -> torch.Tensor:
        """(N, 3) world position of each env's target handle."""
        pose = self.target_link.pose
        return handle_world_positions(pose.p, pose.q, self.handle_link_pos)

    def joint_axis_world(self) -> torch.Tensor:
        return rotate_z(self.joint_axis_obj, self.object_yaw)

    def hinge_to_handle(self) -> torch.Tensor:
        """(N, 3) world vector from a revolute target part's hinge line to its handle,
        square to the hinge (the target link's origin lies on the hinge)."""
        axis = self.joint_axis_world()
        arm = self.handle_positions() - self.target_link.pose.p
        return arm - (arm * axis).sum(1, keepdim=True) * axis

    def evaluate(self) -> dict[str, torch.Tensor]:
        frac = self.open_fraction()
        handle = self.handle_positions()
        tcp_to_handle = handle - self.agent.tcp.pose.p
        if self.closing:
            goal_reached = frac <= self.close_goal
        else:
            goal_reached = frac >= self.open_goal
        link_static = (torch.linalg.norm(self.target_link.angular_velocity, dim=1) <= 1.0) & (
            torch.linalg.norm(self.target_link.linear_velocity, dim=1) <= 0.1
        )
        return {
            "success": goal_reached & link_static,
            "goal_reached": goal_reached,
            "open_fraction": frac,
            "handle_pos": handle,
            "tcp_to_handle": tcp_to_handle,
            "tcp_to_handle_dist": torch.linalg.norm(tcp_to_handle, dim=1),
            "is_grasped": self.is_grasped(),
        }

    def is_grasped(self, min_force: float = 0.5) -> torch.Tensor:
        """(N,) both fingers press on the target part: ManiSkill's ``Panda.is_grasping``
        (force and direction per finger), whose direction test is skipped when no env
        has both fingers touching the part (most steps; it is a third of a CPU step)."""
        fingers = (self.agent.finger1_link, self.agent.finger2_link)
        forces = self._finger_forces(fingers, self.target_link)
        norms = [torch.linalg.norm(f, dim=1) for f in forces]
        touching = (norms[0] >= min_force) & (norms[1] >= min_force)
        if not bool(touching.any()):
            return touching
        # each finger pushes the part along its closing direction (within 85 degrees)
        for finger, force, norm, sign in zip(fingers, forces, norms, (1.0, -1.0), strict=True):
            opening = sign * finger.pose.to_transformation_matrix()[..., :3, 1]
            cos = (opening * force).sum(dim=1) / torch.clamp(norm, min=1e-9)
            touching &= cos >= float(np.cos(np.deg2rad(85.0)))
        return touching

    def _finger_forces(self, fingers: tuple[Link, Link], link: Link) -> list[torch.Tensor]:
        """(N, 3) contact force of each finger on ``link``: ManiSkill's pairwise query on
        the GPU; on a CPU scene one pass over its contacts for both fingers (the query
        walks the contact list once per pair)."""
        if self.gpu_sim_enabled:
            return [self.scene.get_pairwise_contact_forces(f, link) for f in fingers]
        part = link._bodies[0].entity
        ends = [f._bodies[0].entity for f in fingers]
        impulses = np.zeros((2, 3))
        for contact in self.scene.px.get_contacts():
            e0, e1 = contact.bodies[0].entity, contact.bodies[1].entity
            for k, end in enumerate(ends):
                if e0 == end and e1 == part:
                    sign = 1.0  # the impulse acts on the first body
                elif e1 == end and e0 == part:
                    sign = -1.0
                else:
                    continue
                impulses[k] += sign * np.sum([pt.impulse for pt in contact.points], axis=0)
        forces = torch.as_tensor(impulses / self.scene.px.timestep, dtype=torch.float32)
        return [forces[k : k + 1].to(self.device) for k in range(2)]

    def _get_obs_extra(self, info: dict) -> dict[str, torch.Tensor]:
        obs = dict(tcp_pose=self.agent.tcp.pose.raw_pose)
        if self.obs_mode_struct.use_state:
            obs.update(
                handle_pos=info["handle_pos"],
                tcp_to_handle=info["tcp_to_handle"],
                target_qpos=self.target_qpos()[:, None],
                target_qvel=self.target_qvel()[:, None],
                target_qlimits=torch.stack([self.qlow, self.qhigh], dim=1),
                open_fraction=info["open_fraction"][:, None],
                is_grasped=info["is_grasped"][:, None].float(),
                joint_axis=self.joint_axis_world(),
                handle_kind=self.handle_kind,
            )
            if self.robot_frame_obs:
                # the same vectors along the robot base's axes, the axes its actions move
                # the hand along (pd_ee_delta_pos), and for a door where its hinge is
                inv = -self.robot_yaw
                obs.update(
                    tcp_to_handle_robot=rotate_z(info["tcp_to_handle"], inv),
                    joint_axis_robot=rotate_z(self.joint_axis_world(), inv),
                )
                if self.joint_type == "revolute":
                    obs["hinge_to_handle_robot"] = rotate_z(self.hinge_to_handle(), inv)
        return obs

    def progress(self, info: dict) -> torch.Tensor:
        """(N,) task progress in [0, 1]: 1 when the goal fraction is reached."""
        frac = info["open_fraction"]
        if self.closing:
            denom = torch.clamp(self.start_fraction - self.close_goal, min=1e-3)
            return torch.clamp((self.start_fraction - frac) / denom, 0.0, 1.0)
        return torch.clamp(frac / self.open_goal, 0.0, 1.0)

    def compute_dense_reward(self, obs: Any, action: torch.Tensor, info: dict) -> torch.Tensor:
        """reach (1 - tanh(5 d), d = tcp to handle) + grasp (1 while both fingers press on
        the target part) + 3 x progress; ``max_reward`` on success. Once the part has
        moved 5% of the way, reach counts as full, and so does grasp (a push or a hook is
        as good as a grasp) unless the env was made with ``require_grasp=True``: then
        only a real grasp earns the grasp term."""
        reach = 1.0 - torch.tanh(5.0 * info["tcp_to_handle_dist"])
        grasp = info["is_grasped"].float()
        progress = self.progress(info)
        moved = progress > 0.05
        reach = torch.where(moved, torch.ones_like(reach), reach)
        if not self.require_grasp:
            grasp = torch.where(moved, torch.ones_like(grasp), grasp)
        reward = reach + grasp + 3.0 * progress
        reward = torch.where(info["success"], torch.full_like(reward, self.max_reward), reward)
        return reward

    def compute_normalized_dense_reward(
        self, obs: Any, action: torch.Tensor, info: dict
    ) -> torch.Tensor:
        return self.compute_dense_reward(obs=obs, action=action, info=info) / self.max_reward


def _start_qpos(part: MovablePart, placed: np.ndarray | None) -> np.ndarray:
    """(9,) robot joints at the start: the placement's pre-grasp, else the ready pose
    (wrist turned for vertical bars so that the fingers close across them)."""
    q = READY_QPOS.copy()
    if placed is not None:
        q[:7] = np.asarray(placed, dtype=np.float32)[:7]
    elif abs(part.handle_axis[2]) > 0.7:
        q[6] = VERTICAL_BAR_WRIST
    return q
