"""SAPIEN scenes that work on these machines, and loading a built asset into one.

SAPIEN 3 needs a render system to load a URDF with visual meshes. On CPU the
render device is Mesa's lavapipe (``VK_ICD_FILENAMES`` pointing at
``lvp_icd.json``, set here when the file exists and the variable is unset);
when no Vulkan device works, a render system on ``sapien.Device("cpu")`` lets
visuals load without drawing them. Physics never needs the renderer.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING

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

    ``render=True``: a render system on the default (Vulkan) device; raises
    RuntimeError when none exists. ``render=False``: a render system on the CPU
    device (visuals load, nothing draws; fastest, for physics-only checks).
    ``render=None``: the Vulkan device when one works, else the CPU device.
    SAPIEN allows one rendering device per process: once a Vulkan renderer exists,
    a CPU-device render system cannot be made, so ``render=False`` then shares the
    Vulkan one (still nothing is drawn unless asked). ``timestep`` is in seconds.
    """
    configure_vulkan()
    import sapien

    physx = sapien.physx.PhysxCpuSystem()
    render_system = None
    if render is not False:
        try:
            render_system = sapien.render.RenderSystem()
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


def load_articulation(
    scene: sapien.Scene, urdf_path: str | Path, fix_root: bool = True
) -> sapien.physx.PhysxArticulation:
    """Load a built asset's URDF into ``scene`` (one ``<collision>`` per convex piece).

    Raises FileNotFoundError for a missing file and RuntimeError when SAPIEN
    returns nothing.
    """
    path = Path(urdf_path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: URDF not found")
    loader = scene.create_urdf_loader()
    loader.fix_root_link = fix_root
    art = loader.load(str(path))
    if art is None:
        raise RuntimeError(f"{path}: SAPIEN loaded no articulation")
    return art


def collision_shape_counts(articulation: sapien.physx.PhysxArticulation) -> dict[str, int]:
    """Number of collision shapes SAPIEN actually created per link (it drops uncookable ones)."""
    return {link.name: len(link.collision_shapes) for link in articulation.links}
