"""Load built articulated assets into SAPIEN / ManiSkill3 scenes.

- :mod:`sim_envs.asset_sources`: where assets come from (a folder, a catalog or a
  list), filtered by category and joint type;
- :mod:`sim_envs.scene`: loading one asset into a ManiSkill scene (fixed base,
  friction material and collision policy from asset_pipeline.simulation.sim_options)
  and placement helpers.
"""

from asset_pipeline.assets.built_asset import BuiltAsset, MovablePart
from sim_envs.asset_sources import (
    AssetSource,
    AssetSourceError,
    CatalogSource,
    FolderSource,
    ListSource,
    open_source,
    read_task_asset,
)
from sim_envs.scene import add_to_scene, configure_ground, robot_ignores_ground

__all__ = [
    "add_to_scene",
    "AssetSource",
    "AssetSourceError",
    "BuiltAsset",
    "CatalogSource",
    "FolderSource",
    "ListSource",
    "MovablePart",
    "configure_ground",
    "open_source",
    "read_task_asset",
    "robot_ignores_ground",
]
