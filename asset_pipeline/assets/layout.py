"""The built-asset folder's file names, and the error of reading any of its files."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

URDF_NAME = "model.urdf"
MJCF_NAME = "model.xml"
ASSET_JSON_NAME = "asset.json"
ASSET_SCHEMA = "pact.asset"
ASSET_VERSION = 1
#: Folders of the built-asset layout whose files the asset owns (stale ones are removed).
MESH_FOLDERS = ("visual", "collision")


class AssetFormatError(ValueError):
    """A built asset cannot be read; the message names the file and every problem."""

    def __init__(self, path: Path | str, problems: Iterable[str]) -> None:
        self.path = Path(path)
        self.problems = list(problems)
        super().__init__(f"{self.path}: " + "; ".join(self.problems))
