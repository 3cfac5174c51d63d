"""SAPIEN scenes that work on these machines, and the one loader of built assets.

:func:`load_articulation` is how validation, previews and the tasks (through
:func:`articulation_builder` and ManiSkill's loader) put a
:class:`~asset_pipeline.assets.built_asset.BuiltAsset` into a scene: the URDF with the
shared :class:`~asset_pipeline.simulation.sim_options.SimOptions`, one shape per
``<collision>``, visuals optional, and the URDF's joint friction (which SAPIEN's
builder drops) applied afterwards.

SAPIEN 3 needs a render system to load a URDF with visual meshes. On CPU the
render device is Mesa's lavapipe (``VK_ICD_FILENAMES`` pointing at
``lvp_icd.json``, set here when the file exists and the variable is unset);
when no Vulkan device works, a render system on ``sapien.Device("cpu")`` lets
visuals load without drawing them. Physics never needs the renderer
(:func:`physics_scene`).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.simulation.sim_options import (
    DEFAULT_SIM_OPTIONS,
    SimOptions,
    apply_sim_options,
    configure_urdf_loader,
)

if TYPE_CHECKING:
    import sapien

log = logging.getLogger(__name__)

LAVAPIPE_ICD = Path("/usr/share/vulkan/icd.d/lvp_icd.json")


def configure_vulkan() -> None:
    """Point Vulkan at lavapipe when it is installed and nothing else is configured."""
    if "VK_ICD_FILENAMES" not in os.environ and LAVAPIPE_ICD.is_file():
        os.environ["VK_ICD_FILENAMES"] = str(LAVAPIPE_ICD)


def make_scene(timestep: float = 1 / 240, render: bool | None = None) -> sapien.Scene:
    """A SAPIEN scene with a CPU PhysX system and a render system.

    ``render=True``: a render system that draws (``generator.data.render.new_render_system``:
    without CUDA SAPIEN's CPU device, lavapipe, as ManiSkill's CPU render backend uses);
    raises RuntimeError when none exists. ``render=False``: a render system on the CPU
    device for physics-only checks (visuals load; nothing is drawn unless asked).
    ``render=None``: a drawing one when one works, else the CPU device. SAPIEN allows
    one rendering device per process: once a renderer on another device exists, a
    CPU-device render system cannot be made, so ``render=False`` then shares that one.
    ``timestep`` is in seconds.
    """
    configure_vulkan()
    import sapien

    from generator.data.render import new_render_system, use_sapien_camera_defaults

    use_sapien_camera_defaults()
    physx = sapien.physx.PhysxCpuSystem()
    render_system = None
    if render is not False:
        try:
            render_system = new_render_system()
        except Exception as e:  # noqa: BLE001 - SAPIEN raises RuntimeError without a device
            if render:
                raise RuntimeError(f"no Vulkan render device for SAPIEN: {e}") from e
            log.info("no Vulkan render device (%s); using a CPU render system", e)
    if render_system is None:
        try:
            render_system = sapien.render.RenderSystem(sapien.Device("cpu"))
        except RuntimeError as e:  # a Vulkan renderer already lives in this process
            log.debug("CPU render system refused (%s); sharing the process's renderer", e)
            render_system = sapien.render.RenderSystem()
    scene = sapien.Scene([physx, render_system])
    scene.set_timestep(timestep)
    return scene


def physics_scene(options: SimOptions = DEFAULT_SIM_OPTIONS) -> sapien.Scene:
    """A physics-only SAPIEN scene (CPU PhysX, no renderer) with the options' timestep."""
    import sapien

    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(options.timestep)
    return scene


def articulation_builder(
    loader: Any,
    asset: BuiltAsset,
    options: SimOptions = DEFAULT_SIM_OPTIONS,
    *,
    visuals: bool = True,
    fix_root: bool | None = None,
) -> Any:
    """The articulation builder of ``asset``'s URDF from a SAPIEN or ManiSkill URDF loader.

    The loader is configured with ``options`` (material, fixed root unless
    ``fix_root`` says otherwise) and one collision shape per ``<collision>`` element.
    ``visuals=False`` drops the visual meshes (physics-only scenes). Build it, then
    call :func:`asset_pipeline.simulation.sim_options.apply_sim_options` with
    ``asset.joint_friction`` (:func:`load_articulation` does both).
    """
    configure_urdf_loader(loader, options)
    if fix_root is not None:
        loader.fix_root_link = fix_root
    loader.load_multiple_collisions_from_file = False
    parsed = loader.parse(str(asset.urdf_path))
    if isinstance(parsed, dict):  # ManiSkill's loader
        builders, actors = parsed["articulation_builders"], parsed["actor_builders"]
    else:  # SAPIEN's: (articulations, actors, cameras)
        builders, actors = parsed[0], parsed[1]
    if len(builders) != 1 or actors:
        raise RuntimeError(
            f"{asset.urdf_path}: expected one articulation, SAPIEN found {len(builders)} "
            f"and {len(actors)} separate bodies"
        )
    builder = builders[0]
    if not visuals:
        for lb in builder.link_builders:
            lb.visual_records = []
    return builder


def load_articulation(
    scene: sapien.Scene,
    asset: BuiltAsset,
    options: SimOptions = DEFAULT_SIM_OPTIONS,
    *,
    visuals: bool = True,
    fix_root: bool | None = None,
    fresh_meshes: bool = False,
) -> sapien.physx.PhysxArticulation:
    """Load ``asset`` into a plain SAPIEN ``scene`` with ``options`` applied.

    ``fresh_meshes=True`` clears SAPIEN's cache of cooked meshes first: a repaired
    collision file keeps its name, and SAPIEN would otherwise reuse the old shape.
    """
    import sapien

    if fresh_meshes:
        sapien.physx.clear_cache()
    builder = articulation_builder(
        scene.create_urdf_loader(), asset, options, visuals=visuals, fix_root=fix_root
    )
    art = builder.build()
    apply_sim_options(art, options, joint_friction=asset.joint_friction)
    return art


def collision_shape_counts(articulation: sapien.physx.PhysxArticulation) -> dict[str, int]:
    """Number of collision shapes SAPIEN actually created per link (it drops uncookable ones)."""
    return {link.name: len(link.collision_shapes) for link in articulation.links}
