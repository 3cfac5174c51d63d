"""Load built articulated assets into SAPIEN / ManiSkill3 scenes.

- :mod:`sim_envs.catalog`: where assets come from (a folder or an SQLite catalog),
  filtered by category and joint type;
- :mod:`sim_envs.scene`: loading one asset into a ManiSkill scene (fixed base,
  friction material and collision policy from asset_pipeline.sim_options)
  and placement helpers.
"""

from sim_envs.catalog import (
    AssetRecord,
    AssetSource,
    AssetSourceError,
    CatalogSource,
    FolderSource,
    ListSource,
    MovablePart,
    open_source,
    read_asset,
)
from sim_envs.scene import configure_ground, load_asset, robot_ignores_ground

__all__ = [
    "AssetRecord",
    "AssetSource",
    "AssetSourceError",
    "CatalogSource",
    "FolderSource",
    "ListSource",
    "MovablePart",
    "configure_ground",
    "load_asset",
    "open_source",
    "read_asset",
    "robot_ignores_ground",
]
