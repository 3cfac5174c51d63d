"""Where task environments find built assets: a folder of assets, a catalog, or a list.

An :class:`AssetSource` lists the usable built assets
(:class:`~asset_pipeline.assets.built_asset.BuiltAsset`, read with
:func:`asset_pipeline.asset_io.load_asset`), optionally filtered by category and by
the joint type of their movable parts:

- :class:`FolderSource` scans the sub-folders of a directory (or takes one asset
  folder) and skips assets whose ``report.json`` says validation failed;
- :class:`CatalogSource` takes the assets an SQLite catalog
  (:class:`asset_pipeline.catalog.registry.Catalog`) lists as ``ok`` or ``repaired``;
- :class:`ListSource` takes an explicit list of asset folders.

:func:`open_source` picks the right one for a path.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.assets.folder import load_asset
from asset_pipeline.assets.layout import ASSET_JSON_NAME, AssetFormatError
from asset_pipeline.catalog.registry import CATALOG_NAME, Catalog, CatalogError
from asset_pipeline.validate import ReportFormatError, read_report

log = logging.getLogger(__name__)

#: Joint types a task can target.
TASK_JOINT_TYPES = ("prismatic", "revolute")
CATALOG_SUFFIXES = (".sqlite", ".sqlite3", ".db")


class AssetSourceError(ValueError):
    """An asset folder or catalog cannot be read; the message names the file and what to do."""


def read_task_asset(folder: str | Path) -> BuiltAsset:
    """The built asset in ``folder``, checked for what the tasks need (handles, bounds).

    Raises AssetSourceError naming the file.
    """
    try:
        asset = load_asset(folder)
        asset.movable_parts()  # every movable part has a handle
    except AssetFormatError as e:
        raise AssetSourceError(f"{e}; rebuild the asset (`pact build`)") from e
    except KeyError as e:
        raise AssetSourceError(f"{Path(folder) / ASSET_JSON_NAME}: {e.args[0]}") from e
    if asset.bounds is None:
        raise AssetSourceError(f"{Path(folder) / ASSET_JSON_NAME}: bounds missing; rebuild it")
    return asset


def validation_failed(folder: Path) -> bool:
    """True when ``folder/report.json`` exists and says the asset failed validation (or
    cannot be read)."""
    try:
        report = read_report(folder)
    except ReportFormatError as e:
        log.warning("%s; treating the asset as failed", e)
        return True
    return report is not None and not report.ok


class AssetSource:
    """A filtered, ordered list of usable built assets (subclasses say where they come from)."""

    def __init__(
        self, category: str | Sequence[str] | None = None, joint_type: str | None = None
    ) -> None:
        if joint_type is not None and joint_type not in TASK_JOINT_TYPES:
            raise AssetSourceError(
                f"joint_type must be one of {TASK_JOINT_TYPES} or None, got {joint_type!r}"
            )
        self.category = category
        self.joint_type = joint_type
        self._assets: list[BuiltAsset] | None = None

    def _candidates(self) -> Iterable[Path]:
        raise NotImplementedError

    def _matches(self, asset: BuiltAsset) -> bool:
        if self.category is not None:
            cats = {self.category} if isinstance(self.category, str) else set(self.category)
            if asset.category not in cats:
                return False
        return bool(asset.parts_of_type(self.joint_type))

    def assets(self) -> list[BuiltAsset]:
        """Usable assets matching the filters, sorted by id (read once, then cached)."""
        if self._assets is None:
            out = []
            for folder in self._candidates():
                try:
                    asset = read_task_asset(folder)
                except AssetSourceError as e:
                    log.warning("skipping asset: %s", e)
                    continue
                if self._matches(asset):
                    out.append(asset)
            self._assets = sorted(out, key=lambda a: a.id)
        return self._assets

    def __len__(self) -> int:
        return len(self.assets())

    def __iter__(self):
        return iter(self.assets())

    def require(self) -> list[BuiltAsset]:
        """The assets, or AssetSourceError when nothing matches the filters."""
        assets = self.assets()
        if not assets:
            raise AssetSourceError(
                f"{self}: no usable asset with category={self.category!r}, "
                f"joint_type={self.joint_type!r}; build and validate assets first or relax the filters"
            )
        return assets


class FolderSource(AssetSource):
    """Built assets in the sub-folders of ``root`` (or ``root`` itself when it is one).

    Hidden folders (``.staging``, ``.previous``) are not looked into.
    """

    def __init__(self, root: str | Path, **filters: Any) -> None:
        super().__init__(**filters)
        self.root = Path(root)
        if not self.root.is_dir():
            raise AssetSourceError(f"{self.root}: not a folder of built assets")

    def _candidates(self) -> Iterable[Path]:
        if (self.root / ASSET_JSON_NAME).is_file():
            folders = [self.root]
        else:
            folders = sorted(
                p
                for p in self.root.iterdir()
                if not p.name.startswith(".") and (p / ASSET_JSON_NAME).is_file()
            )
        for f in folders:
            if validation_failed(f):
                log.info("skipping %s: report.json says validation failed", f)
                continue
            yield f

    def __repr__(self) -> str:
        return f"FolderSource({str(self.root)!r})"


class CatalogSource(AssetSource):
    """The assets a catalog (``registry.sqlite``) lists as ``ok`` or ``repaired``."""

    def __init__(self, catalog: str | Path, **filters: Any) -> None:
        super().__init__(**filters)
        self.catalog = Path(catalog)
        if not self.catalog.is_file():
            raise AssetSourceError(f"{self.catalog}: catalog file not found")

    def _candidates(self) -> Iterable[Path]:
        try:
            with Catalog(self.catalog, readonly=True) as cat:
                rows = [r for r in cat.query() if r.status in ("ok", "repaired")]
                folders = [cat.asset_dir(r) for r in rows]
        except CatalogError as e:
            raise AssetSourceError(str(e)) from e
        return [f for f in folders if f is not None]

    def __repr__(self) -> str:
        return f"CatalogSource({str(self.catalog)!r})"


class ListSource(AssetSource):
    """An explicit list of asset folders (train/held-out splits)."""

    def __init__(self, folders: Sequence[Path], **filters: Any) -> None:
        super().__init__(**filters)
        self.folders = [Path(f) for f in folders]

    def _candidates(self) -> Iterable[Path]:
        return [f for f in self.folders if not validation_failed(f)]

    def __repr__(self) -> str:
        return f"ListSource({len(self.folders)} folders)"


def _is_sqlite(p: Path) -> bool:
    with open(p, "rb") as f:
        return f.read(16) == b"SQLite format 3\x00"


def open_source(
    assets: str | Path | AssetSource | Sequence[str | Path],
    category: str | Sequence[str] | None = None,
    joint_type: str | None = None,
) -> AssetSource:
    """An AssetSource for a folder, a single asset folder, a catalog file or a list of folders.

    A folder holding a catalog (``registry.sqlite``) is read as a folder: the catalog's
    statuses and the folders' reports agree (``pact convert`` reconciles them).
    """
    if isinstance(assets, AssetSource):
        return assets
    if isinstance(assets, (list, tuple)):
        return ListSource([Path(a) for a in assets], category=category, joint_type=joint_type)
    p = Path(assets)
    if p.is_file() and (p.suffix in CATALOG_SUFFIXES or p.name == CATALOG_NAME or _is_sqlite(p)):
        return CatalogSource(p, category=category, joint_type=joint_type)
    return FolderSource(p, category=category, joint_type=joint_type)
