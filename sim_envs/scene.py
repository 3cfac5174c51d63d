"""Load built assets into ManiSkill3 scenes: fixed base, materials, collision groups, placement.

Collision groups (SAPIEN's four 32-bit words per shape; two shapes never collide
when their third words share a bit):

- every link of a loaded object gets ``OBJECT_COLLISION_BIT``, so sibling parts do
  not push on each other (PhysX never reports link-parent contacts anyway: a part
  is held only by its joint limits); the ground gets the same bit, so a door
  swinging down to the floor (oven, dishwasher) is not stopped by it;
- the robot's links and the ground share ``ROBOT_GROUND_COLLISION_BIT``: the fixed
  Panda is mounted at whatever height puts the handle in reach, its base may be
  below the floor plane and must not fight it.

When ``asset_pipeline.sim_options`` exists its friction material and collision
policy are used (the same options validation uses); otherwise the defaults below.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import sapien
import torch

from sim_envs.catalog import AssetRecord

if TYPE_CHECKING:
    from mani_skill.envs.scene import ManiSkillScene
    from mani_skill.utils.structs import Actor, Articulation

log = logging.getLogger(__name__)

OBJECT_COLLISION_BIT = 29
ROBOT_GROUND_COLLISION_BIT = 28


@dataclass(frozen=True)
class LoadOptions:
    """How an asset is loaded: friction material and whether its own links collide."""

    static_friction: float = 1.0
    dynamic_friction: float = 1.0
    restitution: float = 0.0
    self_collision: bool = False
    """False (default): no contacts between the object's links (ManiSkill's cabinet policy)."""
    collide_with_ground: bool = False


def default_load_options() -> LoadOptions:
    """Loader options from ``asset_pipeline.sim_options`` when it exists, else the defaults."""
    try:
        from asset_pipeline import sim_options  # noqa: PLC0415  (optional, written by another issue)
    except ImportError:
        return LoadOptions()
    return _options_from_module(sim_options)


def _options_from_module(mod: Any) -> LoadOptions:
    kw: dict[str, Any] = {}
    material = None
    for name in ("FRICTION_MATERIAL", "MATERIAL", "friction_material", "material"):
        material = getattr(mod, name, None)
        if material is not None:
            break
    if callable(material):
        material = material()
    if material is not None:
        get = material.get if isinstance(material, dict) else lambda k, d=None: getattr(material, k, d)
        for k in ("static_friction", "dynamic_friction", "restitution"):
            v = get(k, None)
            if v is not None:
                kw[k] = float(v)
    for name in ("SELF_COLLISION", "self_collision"):
        v = getattr(mod, name, None)
        if isinstance(v, bool):
            kw["self_collision"] = v
    return LoadOptions(**kw)


def load_asset(
    scene: ManiSkillScene,
    record: AssetRecord,
    scene_idxs: list[int] | None = None,
    name: str | None = None,
    options: LoadOptions | None = None,
    initial_pose: sapien.Pose | None = None,
) -> Articulation:
    """Build ``record``'s URDF as a fixed-base articulation in the sub-scenes ``scene_idxs``.

    One ``<collision>`` element per convex piece (the built-asset layout), so the
    loader's multiple-collisions option stays off. Every link keeps its URDF name.
    """
    options = options or default_load_options()
    loader = scene.create_urdf_loader()
    loader.fix_root_link = True
    loader.load_multiple_collisions_from_file = False
    loader.set_material(options.static_friction, options.dynamic_friction, options.restitution)
    builders = loader.parse(str(record.urdf))["articulation_builders"]
    if len(builders) != 1:
        raise ValueError(f"{record.urdf}: expected one articulation, found {len(builders)}")
    builder = builders[0]
    if scene_idxs is not None:
        builder.set_scene_idxs(scene_idxs)
    builder.initial_pose = initial_pose or sapien.Pose()
    art = builder.build(name=name or record.id)
    apply_collision_policy(art, options)
    return art


def apply_collision_policy(art: Articulation, options: LoadOptions) -> None:
    """Set the object's collision groups (see the module docstring)."""
    if not options.self_collision:
        for link in art.links:
            link.set_collision_group_bit(group=2, bit_idx=OBJECT_COLLISION_BIT, bit=1)


def configure_ground(ground: Actor, options: LoadOptions | None = None) -> None:
    """Let the ground ignore the robot and (by default) the object's links."""
    options = options or default_load_options()
    ground.set_collision_group_bit(group=2, bit_idx=ROBOT_GROUND_COLLISION_BIT, bit=1)
    if not options.collide_with_ground:
        ground.set_collision_group_bit(group=2, bit_idx=OBJECT_COLLISION_BIT, bit=1)


def robot_ignores_ground(robot: Articulation) -> None:
    for link in robot.links:
        link.set_collision_group_bit(group=2, bit_idx=ROBOT_GROUND_COLLISION_BIT, bit=1)


def count_collision_shapes(art: Articulation) -> dict[str, int]:
    """Collision shapes per link of the first sub-scene (SAPIEN drops shapes it cannot cook)."""
    return {link.name: len(link._objs[0].collision_shapes) for link in art.links}


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


def handle_world_positions(link_pose_matrix: torch.Tensor, handle_link: torch.Tensor) -> torch.Tensor:
    """(B, 4, 4) link poses and (B, 3) link-frame handle points -> (B, 3) world points."""
    return (link_pose_matrix[:, :3, :3] @ handle_link[:, :, None])[..., 0] + link_pose_matrix[:, :3, 3]


def as_tensor(x: Any, device: torch.device | str) -> torch.Tensor:
    return torch.as_tensor(np.asarray(x, dtype=np.float32), device=device)
