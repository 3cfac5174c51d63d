"""Where task environments find built assets: a folder of assets or a catalog file.

A *built asset* is a folder holding ``asset.json`` and ``model.urdf`` (see
docs/architecture.md, "Built asset"). An :class:`AssetSource` lists the usable ones,
optionally filtered by category and by the joint type of their movable parts:

- :class:`FolderSource` scans the sub-folders of a directory (or takes one asset
  folder) and skips assets whose ``report.json`` says validation failed;
- :class:`CatalogSource` reads an SQLite catalog with a table
  ``assets(id, path, category, status, joint_types)`` (``path`` relative to the
  catalog's folder or absolute, ``joint_types`` a comma-separated list or a JSON
  list, ``status`` of a usable row ``ok``/``passed``/``repaired``/``built``).

:func:`open_source` picks the right one for a path.
"""

from __future__ import annotations

import json
import logging
import sqlite3
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

log = logging.getLogger(__name__)

ASSET_SCHEMA = "pact.asset"
MOVABLE_JOINT_TYPES = ("prismatic", "revolute")
FAILED_STATUSES = frozenset({"failed", "fail", "error", "rejected"})
CATALOG_SUFFIXES = (".sqlite", ".sqlite3", ".db")


class AssetSourceError(ValueError):
    """An asset folder or catalog cannot be read; the message names the file and what to do."""


HANDLE_KINDS = ("bar", "knob", "recessed", "none")


@dataclass(frozen=True)
class MovablePart:
    """One movable part of a built asset, as the tasks need it.

    ``lower``/``upper`` are the joint limits (``lower`` = closed; metres or radians);
    ``handle_link`` is the grasp point in the part's link frame (metres), ``handle_axis``
    the unit direction of the handle bar in the object frame, ``handle_kind`` one of
    "bar", "knob", "recessed", "none".
    """

    name: str
    joint_name: str
    joint_type: str
    lower: float
    upper: float
    axis: tuple[float, float, float]
    origin: tuple[float, float, float]
    handle_link: tuple[float, float, float]
    handle_object: tuple[float, float, float]
    handle_axis: tuple[float, float, float]
    handle_kind: str

    @property
    def range(self) -> float:
        return self.upper - self.lower

    @property
    def handle_kind_onehot(self) -> tuple[float, ...]:
        """``handle_kind`` as a one-hot over :data:`HANDLE_KINDS` (all zero if unknown)."""
        return tuple(float(self.handle_kind == k) for k in HANDLE_KINDS)


@dataclass(frozen=True)
class AssetRecord:
    """A built asset ready to load: its folder, URDF, category and movable parts."""

    id: str
    path: Path
    category: str
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]]
    parts: tuple[MovablePart, ...] = field(default_factory=tuple)

    @property
    def urdf(self) -> Path:
        return self.path / "model.urdf"

    @property
    def joint_types(self) -> tuple[str, ...]:
        return tuple(sorted({p.joint_type for p in self.parts}))

    def parts_of_type(self, joint_type: str | None) -> list[MovablePart]:
        return [p for p in self.parts if joint_type is None or p.joint_type == joint_type]


def _vec3(v: Any, where: str) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.shape != (3,) or not np.isfinite(a).all():
        raise AssetSourceError(f"{where}: expected 3 finite numbers, got {v!r}")
    return (float(a[0]), float(a[1]), float(a[2]))


def read_asset(folder: str | Path) -> AssetRecord:
    """Read ``folder/asset.json`` into an :class:`AssetRecord` (raises AssetSourceError)."""
    folder = Path(folder)
    meta_path = folder / "asset.json"
    if not meta_path.is_file():
        raise AssetSourceError(f"{meta_path}: missing; build the asset first (`pact build`)")
    if not (folder / "model.urdf").is_file():
        raise AssetSourceError(f"{folder / 'model.urdf'}: missing; rebuild the asset")
    try:
        meta = json.loads(meta_path.read_text())
    except json.JSONDecodeError as e:
        raise AssetSourceError(f"{meta_path}: not valid JSON ({e}); rebuild the asset") from e
    if meta.get("schema", ASSET_SCHEMA) != ASSET_SCHEMA:
        raise AssetSourceError(f"{meta_path}: schema {meta.get('schema')!r} is not {ASSET_SCHEMA}")
    handles = meta.get("handles", {})
    parts = []
    for j in meta.get("joints", []):
        if j.get("type") not in MOVABLE_JOINT_TYPES:
            continue
        child = j["child"]
        h = handles.get(child)
        where = f"{meta_path}: handles[{child}]"
        if h is None:
            raise AssetSourceError(f"{where}: missing; every movable part needs a handle point")
        parts.append(
            MovablePart(
                name=child,
                joint_name=j.get("name", f"joint_{child}"),
                joint_type=j["type"],
                lower=float(j["lower"]),
                upper=float(j["upper"]),
                axis=_vec3(j.get("axis", [1, 0, 0]), f"{meta_path}: joints[{child}].axis"),
                origin=_vec3(j.get("origin", [0, 0, 0]), f"{meta_path}: joints[{child}].origin"),
                handle_link=_vec3(h["position_link"], f"{where}.position_link"),
                handle_object=_vec3(h.get("position", h["position_link"]), f"{where}.position"),
                handle_axis=_vec3(h.get("axis", [0, 0, 1]), f"{where}.axis"),
                handle_kind=str(h.get("kind", "bar")),
            )
        )
    b = meta.get("bounds", [[-0.5, -0.5, 0.0], [0.5, 0.5, 1.0]])
    return AssetRecord(
        id=str(meta.get("id", folder.name)),
        path=folder.resolve(),
        category=str(meta.get("category", "unknown")),
        bounds=(_vec3(b[0], f"{meta_path}: bounds"), _vec3(b[1], f"{meta_path}: bounds")),
        parts=tuple(parts),
    )


def validation_failed(folder: Path) -> bool:
    """True when ``folder/report.json`` exists and says the asset failed validation."""
    report = folder / "report.json"
    if not report.is_file():
        return False
    try:
        data = json.loads(report.read_text())
    except json.JSONDecodeError:
        log.warning("%s: unreadable report, treating the asset as failed", report)
        return True
    status = str(data.get("status", "")).lower()
    return status in FAILED_STATUSES or data.get("passed") is False or data.get("ok") is False


def _matches(
    rec: AssetRecord, category: str | Sequence[str] | None, joint_type: str | None
) -> bool:
    if category is not None:
        cats = {category} if isinstance(category, str) else set(category)
        if rec.category not in cats:
            return False
    return bool(rec.parts_of_type(joint_type))


class AssetSource:
    """A filtered, ordered list of usable built assets (subclasses say where they come from)."""

    def __init__(
        self, category: str | Sequence[str] | None = None, joint_type: str | None = None
    ) -> None:
        if joint_type is not None and joint_type not in MOVABLE_JOINT_TYPES:
            raise AssetSourceError(
                f"joint_type must be one of {MOVABLE_JOINT_TYPES} or None, got {joint_type!r}"
            )
        self.category = category
        self.joint_type = joint_type
        self._records: list[AssetRecord] | None = None

    def _candidates(self) -> Iterable[Path]:
        raise NotImplementedError

    def records(self) -> list[AssetRecord]:
        """Usable assets matching the filters, sorted by id (read once, then cached)."""
        if self._records is None:
            out = []
            for folder in self._candidates():
                try:
                    rec = read_asset(folder)
                except AssetSourceError as e:
                    log.warning("skipping asset: %s", e)
                    continue
                if _matches(rec, self.category, self.joint_type):
                    out.append(rec)
            self._records = sorted(out, key=lambda r: r.id)
        return self._records

    def __len__(self) -> int:
        return len(self.records())

    def __iter__(self):
        return iter(self.records())

    def require(self) -> list[AssetRecord]:
        """The records, or AssetSourceError when nothing matches the filters."""
        recs = self.records()
        if not recs:
            raise AssetSourceError(
                f"{self}: no usable asset with category={self.category!r}, "
                f"joint_type={self.joint_type!r}; build and validate assets first or relax the filters"
            )
        return recs


class FolderSource(AssetSource):
    """Built assets in the sub-folders of ``root`` (or ``root`` itself when it is one)."""

    def __init__(self, root: str | Path, **filters: Any) -> None:
        super().__init__(**filters)
        self.root = Path(root)
        if not self.root.is_dir():
            raise AssetSourceError(f"{self.root}: not a folder of built assets")

    def _candidates(self) -> Iterable[Path]:
        if (self.root / "asset.json").is_file():
            folders = [self.root]
        else:
            folders = sorted(p for p in self.root.iterdir() if (p / "asset.json").is_file())
        for f in folders:
            if validation_failed(f):
                log.info("skipping %s: report.json says validation failed", f)
                continue
            yield f

    def __repr__(self) -> str:
        return f"FolderSource({str(self.root)!r})"


class CatalogSource(AssetSource):
    """Built assets listed in an SQLite catalog table ``assets(id, path, category, status, joint_types)``."""

    usable_statuses = ("ok", "passed", "pass", "repaired", "built", "valid", "validated")

    def __init__(self, catalog: str | Path, **filters: Any) -> None:
        super().__init__(**filters)
        self.catalog = Path(catalog)
        if not self.catalog.is_file():
            raise AssetSourceError(f"{self.catalog}: catalog file not found")

    def rows(self) -> list[dict[str, Any]]:
        """The catalog rows passing the status/category/joint-type filters."""
        try:
            con = sqlite3.connect(f"file:{self.catalog}?mode=ro", uri=True)
        except sqlite3.Error as e:
            raise AssetSourceError(f"{self.catalog}: cannot open catalog: {e}") from e
        try:
            con.row_factory = sqlite3.Row
            rows = [dict(r) for r in con.execute("SELECT * FROM assets ORDER BY id")]
        except sqlite3.Error as e:
            raise AssetSourceError(
                f"{self.catalog}: cannot read table assets(id, path, category, status, joint_types): {e}"
            ) from e
        finally:
            con.close()
        out = []
        for r in rows:
            if str(r.get("status", "ok")).lower() not in self.usable_statuses:
                continue
            if self.category is not None:
                cats = {self.category} if isinstance(self.category, str) else set(self.category)
                if r.get("category") not in cats:
                    continue
            if self.joint_type is not None and self.joint_type not in _split_types(
                r.get("joint_types")
            ):
                continue
            out.append(r)
        return out

    def _candidates(self) -> Iterable[Path]:
        for r in self.rows():
            p = Path(r["path"])
            yield p if p.is_absolute() else (self.catalog.parent / p)

    def __repr__(self) -> str:
        return f"CatalogSource({str(self.catalog)!r})"


def _split_types(v: Any) -> set[str]:
    if v is None:
        return set()
    s = str(v).strip()
    if s.startswith("["):
        try:
            return {str(t) for t in json.loads(s)}
        except json.JSONDecodeError:
            pass
    return {t.strip() for t in s.replace(";", ",").split(",") if t.strip()}


def open_source(
    assets: str | Path | AssetSource | Sequence[str | Path],
    category: str | Sequence[str] | None = None,
    joint_type: str | None = None,
) -> AssetSource:
    """An AssetSource for a folder, a single asset folder, a catalog file or a list of folders."""
    if isinstance(assets, AssetSource):
        return assets
    if isinstance(assets, (list, tuple)):
        return ListSource([Path(a) for a in assets], category=category, joint_type=joint_type)
    p = Path(assets)
    if p.is_file() and (p.suffix in CATALOG_SUFFIXES or _is_sqlite(p)):
        return CatalogSource(p, category=category, joint_type=joint_type)
    return FolderSource(p, category=category, joint_type=joint_type)


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
