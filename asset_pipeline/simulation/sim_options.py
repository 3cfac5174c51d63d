"""How a built asset is loaded into SAPIEN: the options validation and the tasks share.

Validation (:mod:`asset_pipeline.validate`) proves an asset under exactly the
physics the tasks (``sim_envs``) later train with, so both take their loader
settings from here: :class:`SimOptions` (one frozen dataclass, defaults that
work) and :func:`apply_sim_options` (applies it to a loaded articulation).

Collision-group policy (SAPIEN / PhysX filtering, see
``PhysxCollisionShape.set_collision_groups``): a shape has four 32-bit groups
``g0..g3``; shapes A and B collide iff ``(A.g0 & B.g1 or A.g1 & B.g0)`` and not
``(A.g2 & B.g2 and A.g3 == B.g3)``.

- The object's links keep SAPIEN's default contact groups (``g0 = g1 = 1``), so
  they collide with robots, the ground and each other.
- Sibling parts (two drawers, a door and a drawer) collide with each other: that
  is what keeps a drawer from passing through its neighbour, so ``g2`` is left
  clear (``self_collisions=True``). ManiSkill's PartNet cabinet tasks instead put
  every cabinet link in one ignore group (bit 29 of ``g2``); ``self_collisions=False``
  reproduces that, for assets whose siblings are known to touch.
- A part never collides with its parent (the base): PhysX skips contacts between
  a link and its parent link in an articulation, whatever the groups say. A drawer
  is kept in its carcass by its joint limits alone, which is why validation checks
  part-against-base penetration geometrically.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import sapien

log = logging.getLogger(__name__)

#: ``g2`` bit ManiSkill uses for "all links of this articulation ignore each other".
OBJECT_IGNORE_BIT = 29


@dataclass(frozen=True)
class SimOptions:
    """Physics settings for loading an articulated asset.

    Units: seconds (``timestep``), metres (offsets). Friction coefficients are
    PhysX material coefficients of every collision shape of the object.
    """

    #: Material of every collision shape of the object.
    static_friction: float = 0.6
    dynamic_friction: float = 0.5
    restitution: float = 0.0
    #: Fix the base link to the world (True for tasks and most checks).
    fix_root: bool = True
    #: Sibling parts collide with each other (see the module docstring).
    self_collisions: bool = True
    #: PhysX articulation solver iterations (ManiSkill's defaults: 15 and 1).
    solver_position_iterations: int = 15
    solver_velocity_iterations: int = 1
    #: Simulation step in seconds.
    timestep: float = 1 / 240
    #: Contacts are generated within this distance (metres); rest offset 0.
    contact_offset: float = 0.01
    rest_offset: float = 0.0

    def with_(self, **changes: Any) -> SimOptions:
        """A copy with some fields changed."""
        return replace(self, **changes)


DEFAULT_SIM_OPTIONS = SimOptions()


def make_material(options: SimOptions = DEFAULT_SIM_OPTIONS) -> sapien.physx.PhysxMaterial:
    """The PhysX material of the object's collision shapes."""
    import sapien

    return sapien.physx.PhysxMaterial(
        options.static_friction, options.dynamic_friction, options.restitution
    )


def configure_urdf_loader(loader: Any, options: SimOptions = DEFAULT_SIM_OPTIONS) -> None:
    """Set a SAPIEN ``URDFLoader`` to load with ``options`` (fixed root, material)."""
    loader.fix_root_link = options.fix_root
    loader.set_material(options.static_friction, options.dynamic_friction, options.restitution)


def match_joint_name(loaded: str, urdf_names: Iterable[str]) -> str | None:
    """The URDF joint name a loaded joint was built from, or None.

    Plain SAPIEN keeps URDF names (``joint_door_0``); ManiSkill prefixes them with
    the sub-scene and articulation (``scene-0-object-0_joint_door_0``). A name
    matches when it is the loaded name or its suffix after an underscore; of
    several matches the longest wins (``joint_door_10`` is not ``joint_door_0``).
    """
    best: str | None = None
    for name in urdf_names:
        if (loaded == name or loaded.endswith("_" + name)) and (
            best is None or len(name) > len(best)
        ):
            best = name
    return best


def apply_sim_options(
    articulation: sapien.physx.PhysxArticulation,
    options: SimOptions = DEFAULT_SIM_OPTIONS,
    joint_friction: Mapping[str, float] | None = None,
) -> None:
    """Apply ``options`` to a loaded articulation, in place.

    Sets the material, contact/rest offsets and collision groups of every shape
    of every link, and the articulation's solver iterations. The fixed root and
    the timestep are load-time and scene settings: use
    :func:`configure_urdf_loader` and ``scene.set_timestep(options.timestep)``.
    :func:`asset_pipeline.simulation.sapien_scenes.load_articulation` does all of it.

    ``joint_friction``: the URDF joint friction by joint name
    (``BuiltAsset.joint_friction``). SAPIEN 3.0.3's ``ArticulationBuilder`` drops
    the ``friction`` it parses (every joint gets PhysX's default 0.05, measured), so
    pass it wherever friction matters. Joints are matched by name suffix
    (:func:`match_joint_name`), so this works for SAPIEN's own names and for
    ManiSkill's prefixed ones alike.
    """
    material = make_material(options)
    for link in articulation.links:
        for shape in link.collision_shapes:
            shape.set_physical_material(material)
            shape.set_contact_offset(options.contact_offset)
            shape.set_rest_offset(options.rest_offset)
            groups = list(shape.get_collision_groups())
            if options.self_collisions:
                groups[2] &= ~(1 << OBJECT_IGNORE_BIT)
            else:
                groups[2] |= 1 << OBJECT_IGNORE_BIT
            shape.set_collision_groups(groups)
    if joint_friction is not None:
        for joint in articulation.get_active_joints():
            urdf_name = match_joint_name(joint.name, joint_friction)
            if urdf_name is not None:
                joint.set_friction(joint_friction[urdf_name])
    articulation.set_solver_position_iterations(options.solver_position_iterations)
    articulation.set_solver_velocity_iterations(options.solver_velocity_iterations)
