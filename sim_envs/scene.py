"""Load built assets into ManiSkill3 scenes: fixed base, materials, collision groups, placement.

Physics options come from :mod:`asset_pipeline.simulation.sim_options` (the same
:class:`~asset_pipeline.simulation.sim_options.SimOptions` validation proves assets with):
friction material, contact offsets, solver iterations and the object's collision
policy (by default sibling parts collide with each other and with the robot; a
part never collides with its parent, PhysX skips that pair).

On top of that, for the tasks: the robot's links and the ground share
``ROBOT_GROUND_COLLISION_BIT`` in group 2 (SAPIEN: two shapes sharing a group-2 bit
do not collide). The fixed Panda is mounted at whatever height puts the handle in
reach, its base may sit below the floor plane and must not fight it. With
``self_collisions=False`` the ground also joins the object's ignore bit, as in
ManiSkill's cabinet tasks.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

import numpy as np
import sapien
import torch

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.simulation.sapien_scenes import articulation_builder
from asset_pipeline.simulation.sim_options import (
    DEFAULT_SIM_OPTIONS,
    OBJECT_IGNORE_BIT,
    SimOptions,
    apply_sim_options,
)

if TYPE_CHECKING:
    from mani_skill.envs.scene import ManiSkillScene
    from mani_skill.utils.structs import Actor, Articulation

log = logging.getLogger(__name__)

ROBOT_GROUND_COLLISION_BIT = 28


def add_to_scene(
    scene: ManiSkillScene,
    asset: BuiltAsset,
    scene_idxs: list[int] | None = None,
    name: str | None = None,
    options: SimOptions = DEFAULT_SIM_OPTIONS,
    initial_pose: sapien.Pose | None = None,
) -> Articulation:
    """Build ``asset`` as a fixed-base articulation in the sub-scenes ``scene_idxs``.

    The one SAPIEN loader (:func:`asset_pipeline.simulation.sapien_scenes.articulation_builder`),
    through ManiSkill's URDF loader. Links keep their URDF (part) names. Must run while
    the scene is being built (``_load_scene``), before GPU setup.
    """
    builder = articulation_builder(scene.create_urdf_loader(), asset, options, fix_root=True)
    if scene_idxs is not None:
        builder.set_scene_idxs(scene_idxs)
    builder.initial_pose = initial_pose or sapien.Pose()
    art = builder.build(name=name or asset.id)
    for obj in art._objs:
        # materials, groups, solver iterations and the URDF's joint friction (SAPIEN's
        # builder drops it); joints match by name suffix despite ManiSkill's prefixes
        apply_sim_options(obj, options, joint_friction=asset.joint_friction)
    return art


def scale_part_physics(
    articulation: Articulation, mass: float = 1.0, damping: float = 1.0, friction: float = 1.0
) -> None:
    """Scale, in every sub-scene copy of a loaded object, each movable part's mass and
    inertia by ``mass`` and its joint's damping and friction by ``damping`` and
    ``friction`` (the tasks' physics randomization). Run it while the scene is being
    built (``_load_scene``), after :func:`add_to_scene`."""
    if min(mass, damping, friction) <= 0:
        raise ValueError(f"scales must be positive, got {mass}, {damping}, {friction}")
    for obj in articulation._objs:
        for joint in obj.get_active_joints():
            joint.set_drive_properties(
                joint.stiffness, joint.damping * damping, joint.force_limit, joint.drive_mode
            )
            joint.set_friction(joint.friction * friction)
            link = joint.child_link
            link.set_mass(link.mass * mass)
            link.set_inertia(np.asarray(link.inertia) * mass)


#: Clearance (m) left between the floor and the lowest point any part sweeps through.
FLOOR_CLEARANCE = 0.003


def floor_lift(asset: BuiltAsset, steps: int = 24) -> float:
    """How high (m) to stand the object so that no part dips through the floor.

    An asset rests with its lowest point at z = 0. A door hinged above its bottom edge
    (an oven's, set flush with the floor) swings that edge below its rest height: on
    the floor it would jam. Returns how far the collision pieces of any link reach
    below the rest minimum over each movable joint's range (``steps`` values, the other
    joints closed), plus ``FLOOR_CLEARANCE``; 0 when nothing dips.
    """
    from asset_pipeline.assets.mesh_files import link_piece_vertices

    verts = link_piece_vertices(asset)

    def lowest(poses: dict[str, np.ndarray]) -> float:
        z = [
            float((v @ poses[name][:3, :3].T + poses[name][:3, 3])[:, 2].min())
            for name, pieces in verts.items()
            if name in poses
            for v in pieces
            if len(v)
        ]
        return min(z, default=0.0)

    rest = lowest(asset.link_poses())
    reach = rest
    for j in asset.movable_joints:
        for q in np.linspace(j.lower, j.upper, steps):
            reach = min(reach, lowest(asset.link_poses({j.name: float(q)})))
    dip = rest - reach
    return dip + FLOOR_CLEARANCE if dip > 1e-4 else 0.0


def configure_ground(ground: Actor, options: SimOptions = DEFAULT_SIM_OPTIONS) -> None:
    """Let the ground ignore the robot (and the object when its links ignore each other)."""
    ground.set_collision_group_bit(group=2, bit_idx=ROBOT_GROUND_COLLISION_BIT, bit=1)
    if not options.self_collisions:
        ground.set_collision_group_bit(group=2, bit_idx=OBJECT_IGNORE_BIT, bit=1)


def robot_ignores_ground(robot: Articulation) -> None:
    for link in robot.links:
        link.set_collision_group_bit(group=2, bit_idx=ROBOT_GROUND_COLLISION_BIT, bit=1)


def count_collision_shapes(art: Articulation) -> dict[str, int]:
    """Collision shapes per link in the first sub-scene (SAPIEN drops shapes it cannot cook)."""
    return {link.name: len(link.collision_shapes) for link in art._objs[0].links}


def yaw_quat(yaw: torch.Tensor) -> torch.Tensor:
    """(B,) yaw angles about +z -> (B, 4) wxyz quaternions."""
    q = torch.zeros((*yaw.shape, 4), dtype=torch.float32, device=yaw.device)
    q[..., 0] = torch.cos(yaw / 2)
    q[..., 3] = torch.sin(yaw / 2)
    return q


def rotate_z(v: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """Rotate (B, 3) vectors by (B,) yaw angles about +z."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    out = v.clone()
    out[..., 0] = c * v[..., 0] - s * v[..., 1]
    out[..., 1] = s * v[..., 0] + c * v[..., 1]
    return out


def handle_world_positions(
    link_p: torch.Tensor, link_q: torch.Tensor, handle_link: torch.Tensor
) -> torch.Tensor:
    """(B, 3) link positions, (B, 4) wxyz link orientations and (B, 3) link-frame handle
    points -> (B, 3) world points: p + v + w t + u x t with t = 2 u x v (q = [w, u]),
    a quarter of the cost of building the rotation matrices on CPU."""
    w, u = link_q[:, :1], link_q[:, 1:]
    t = 2.0 * torch.linalg.cross(u, handle_link)
    return link_p + handle_link + w * t + torch.linalg.cross(u, t)


def as_tensor(x: Any, device: torch.device | str) -> torch.Tensor:
    return torch.as_tensor(np.asarray(x, dtype=np.float32), device=device)
