"""The asset catalog: one SQLite file, ``OUT/registry.sqlite``, beside the assets.

Tables (schema version :data:`SCHEMA_VERSION`, stored in ``PRAGMA user_version``):

``assets``  one row per asset id: where it came from (``source_image``,
            ``source_hash`` = the input item's hash, ``settings_hash`` = the hash of
            the build settings), who made it (``generator``, ``generator_version``),
            what it is (``category``, ``part_count`` = parts including the base,
            ``joint_types`` = comma-separated sorted distinct movable joint types,
            ``size_x/y/z`` = rest bounding-box extents in metres), how it went
            (``status`` 'ok' | 'repaired' | 'failed', ``failure_reason``,
            ``repairs`` = JSON list, ``stage_seconds`` = JSON object), ``path`` (the
            asset folder, relative to the catalog's folder when inside it),
            ``created_at`` (UTC ISO-8601 time the row was written), ``warnings`` (JSON
            list of doubts that did not fail the item), ``fidelity`` (JSON object of
            the asset's likeness to its photo, NULL when not measured) and ``inputs``
            (JSON object: where the category, the part mask and each part's motion
            came from, the user or the photo parser with its confidence).
``parts``   per part: ``name``, ``semantic``, ``joint_type`` (NULL for the base),
            ``lower``, ``upper`` (metres or radians), ``mass`` (kg).
``checks``  per validation check: ``name``, ``passed`` (0/1), ``value`` and
            ``tolerance`` (numbers, or JSON text when not numeric), ``detail``.

Concurrency: WAL journal; one writer at a time (the batch driver) and any number
of readers (``pact ls``, the gallery). Every write of an asset is one transaction,
so a reader never sees an asset without its parts and checks.

Errors: :class:`CatalogError` names the file. SQLite's errors that blame the disk or
the folder (full, read-only, an I/O error: :func:`disk_fault`) are
:class:`CatalogDiskError`, naming the folder; only the others call the file damaged.

Resumable batches: :meth:`Catalog.is_done` is true only for an asset built from the
same input and settings whose status is 'ok' or 'repaired' and whose folder still
exists. Failed items are retried on a rerun.
"""

from __future__ import annotations

import functools
import json
import logging
import math
import sqlite3
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from rich.markup import escape
from rich.table import Table

from asset_pipeline.assets.folder import load_asset, missing_files
from asset_pipeline.assets.layout import MJCF_NAME, AssetFormatError
from asset_pipeline.validate.report import (
    REPORT_NAME,
    Report,
    ReportFormatError,
    jsonable,
    read_report,
)

log = logging.getLogger(__name__)

CATALOG_NAME = "registry.sqlite"
SCHEMA_VERSION = 3
#: SQL that takes a catalog from schema version k to k + 1 (applied in one transaction).
_MIGRATIONS = {
    1: (
        "ALTER TABLE assets ADD COLUMN warnings TEXT NOT NULL DEFAULT '[]';"
        "ALTER TABLE assets ADD COLUMN fidelity TEXT;"
    ),
    2: "ALTER TABLE assets ADD COLUMN inputs TEXT NOT NULL DEFAULT '{}';",
}
STATUSES = ("ok", "repaired", "failed")

_SCHEMA = """
CREATE TABLE IF NOT EXISTS assets (
    id                TEXT PRIMARY KEY,
    source_image      TEXT,
    source_hash       TEXT,
    settings_hash     TEXT,
    generator         TEXT,
    generator_version TEXT,
    category          TEXT NOT NULL DEFAULT 'unknown',
    part_count        INTEGER,
    joint_types       TEXT NOT NULL DEFAULT '',
    size_x            REAL,
    size_y            REAL,
    size_z            REAL,
    status            TEXT NOT NULL CHECK (status IN ('ok', 'repaired', 'failed')),
    failure_reason    TEXT,
    repairs           TEXT NOT NULL DEFAULT '[]',
    stage_seconds     TEXT NOT NULL DEFAULT '{}',
    path              TEXT,
    created_at        TEXT NOT NULL,
    warnings          TEXT NOT NULL DEFAULT '[]',
    fidelity          TEXT,
    inputs            TEXT NOT NULL DEFAULT '{}'
);
CREATE INDEX IF NOT EXISTS assets_status ON assets (status);
CREATE INDEX IF NOT EXISTS assets_category ON assets (category);
CREATE TABLE IF NOT EXISTS parts (
    asset_id   TEXT NOT NULL REFERENCES assets (id) ON DELETE CASCADE,
    name       TEXT NOT NULL,
    semantic   TEXT,
    joint_type TEXT,
    lower      REAL,
    upper      REAL,
    mass       REAL,
    PRIMARY KEY (asset_id, name)
);
CREATE INDEX IF NOT EXISTS parts_joint_type ON parts (joint_type);
CREATE TABLE IF NOT EXISTS checks (
    asset_id  TEXT NOT NULL REFERENCES assets (id) ON DELETE CASCADE,
    name      TEXT NOT NULL,
    passed    INTEGER NOT NULL,
    value,
    tolerance,
    detail    TEXT,
    PRIMARY KEY (asset_id, name)
);
"""


class CatalogError(RuntimeError):
    """The catalog file is missing, unreadable or of an unsupported schema."""


class CatalogDiskError(CatalogError):
    """The catalog cannot be written or read because of its disk or folder (full,
    read-only, failing), not because of the file; the message names the folder."""


#: SQLite primary result codes (the low byte of ``sqlite_errorcode``) that blame the
#: disk or the folder, never the catalog file's content, and what to tell the user.
_DISK_FAULTS = {
    8: "the folder or the catalog file is read-only",  # SQLITE_READONLY
    10: "the disk is full or failing (a disk I/O error)",  # SQLITE_IOERR
    13: "the disk is full",  # SQLITE_FULL
    14: "the catalog file cannot be opened or created there",  # SQLITE_CANTOPEN
}
#: The same faults by SQLite's message, for errors that carry no code.
_DISK_FAULT_WORDS = {
    "readonly database": 8,
    "disk i/o error": 10,
    "database or disk is full": 13,
    "unable to open database file": 14,
}


def disk_fault(e: sqlite3.Error) -> str | None:
    """What is wrong with the disk or folder when SQLite's error ``e`` blames them (a
    full disk says "database or disk is full" or, in WAL mode, "disk I/O error"), else
    None (the file itself may be at fault)."""
    code = getattr(e, "sqlite_errorcode", None)
    if code is None:
        text = str(e).lower()
        code = next((c for words, c in _DISK_FAULT_WORDS.items() if words in text), None)
    return None if code is None else _DISK_FAULTS.get(code & 0xFF)


# --------------------------------------------------------------------------- records


@dataclass(frozen=True)
class PartRecord:
    name: str
    semantic: str | None = None
    joint_type: str | None = None
    lower: float | None = None
    upper: float | None = None
    mass: float | None = None


@dataclass(frozen=True)
class CheckRecord:
    name: str
    passed: bool
    value: Any = None
    tolerance: Any = None
    detail: str | None = None


@dataclass(frozen=True)
class AssetRecord:
    """One ``assets`` row. ``size`` is (x, y, z) in metres; see the module docstring."""

    id: str
    status: str
    source_image: str | None = None
    source_hash: str | None = None
    settings_hash: str | None = None
    generator: str | None = None
    generator_version: str | None = None
    category: str = "unknown"
    part_count: int | None = None
    joint_types: str = ""
    size: tuple[float | None, float | None, float | None] = (None, None, None)
    failure_reason: str | None = None
    repairs: tuple[str, ...] = ()
    stage_seconds: Mapping[str, float] = field(default_factory=dict)
    path: str | None = None
    created_at: str | None = None
    warnings: tuple[str, ...] = ()
    fidelity: Mapping[str, Any] | None = None
    #: Where the category, the part mask and each part's motion came from
    #: (asset_pipeline.inputs.parsing.InputSources.to_json: the user or the photo parser,
    #: with its confidence).
    inputs: Mapping[str, Any] = field(default_factory=dict)
    #: Filled when read back with details (:meth:`Catalog.get`, ``query(details=True)``).
    parts: tuple[PartRecord, ...] = ()
    checks: tuple[CheckRecord, ...] = ()

    @property
    def failed_checks(self) -> list[CheckRecord]:
        return [c for c in self.checks if not c.passed]


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _db_value(v: Any) -> Any:
    """A check's value/tolerance for SQLite: numbers as numbers, anything else as JSON."""
    if v is None:
        return None
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, (int, float)):
        return float(v) if isinstance(v, float) and not math.isfinite(v) else v
    return json.dumps(v)


def _py_value(v: Any) -> Any:
    if isinstance(v, str):
        try:
            return json.loads(v)
        except json.JSONDecodeError:
            return v
    return v


# --------------------------------------------------------------------------- catalog


def catalog_path(out: str | Path) -> Path:
    """The catalog file of an output folder (or ``out`` itself when it names a file)."""
    out = Path(out)
    return out if out.suffix in (".sqlite", ".db") else out / CATALOG_NAME


def _database_errors(method: Callable) -> Callable:
    """Turn SQLite's errors on a damaged file into CatalogError naming the file."""

    @functools.wraps(method)
    def wrapped(self: Catalog, *args: Any, **kwargs: Any) -> Any:
        try:
            return method(self, *args, **kwargs)
        except sqlite3.IntegrityError:  # a caller's mistake, not a damaged file
            raise
        except sqlite3.DatabaseError as e:
            if disk_fault(e) is not None:
                raise self.disk_error(e) from e
            raise CatalogError(
                f"{self.path}: the catalog is damaged or not a catalog ({e}); move it away "
                "and convert again to start a new one"
            ) from e

    return wrapped


class Catalog:
    """The SQLite catalog; use as a context manager.

    ``path``: the output folder (the file is ``path/registry.sqlite``) or the file
    itself. ``readonly=True`` never creates or changes the file and fails with
    :class:`CatalogError` when it does not exist.
    """

    def __init__(self, path: str | Path, readonly: bool = False) -> None:
        self.path = catalog_path(path)
        self.root = self.path.parent
        self.readonly = readonly
        self._conn: sqlite3.Connection | None = None

    # ---- connection
    def open(self) -> Catalog:
        if self._conn is not None:
            return self
        if self.readonly:
            if not self.path.is_file():
                raise CatalogError(
                    f"{self.path}: no catalog here (build assets into this folder first)"
                )
            target, uri = f"{self.path.resolve().as_uri()}?mode=ro", True
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            target, uri = str(self.path), False
        try:
            conn = sqlite3.connect(target, uri=uri, timeout=30.0, isolation_level=None)
        except sqlite3.Error as e:
            if disk_fault(e) is not None:
                raise self.disk_error(e) from e
            raise CatalogError(f"{self.path}: cannot open the catalog: {e}") from e
        try:
            conn.execute("PRAGMA busy_timeout = 30000")
            if not self.readonly:
                conn.execute("PRAGMA journal_mode = WAL")
                conn.execute("PRAGMA synchronous = NORMAL")
            conn.execute("PRAGMA foreign_keys = ON")
            self._check_schema(conn)
        except sqlite3.DatabaseError as e:
            conn.close()
            if disk_fault(e) is not None:
                raise self.disk_error(e) from e
            raise CatalogError(f"{self.path}: not a readable catalog: {e}") from e
        except BaseException:
            conn.close()
            raise
        self._conn = conn
        return self

    def disk_error(self, e: sqlite3.Error) -> CatalogDiskError:
        """The error for SQLite's ``e`` when :func:`disk_fault` blames the disk or folder:
        it names the folder and never calls the catalog damaged."""
        what = "write" if not self.readonly else "read"
        return CatalogDiskError(
            f"{self.root}: cannot {what} the catalog {self.path.name} in this folder: "
            f"{disk_fault(e)} (SQLite: {e}); free space on its disk or make the folder "
            f"writable, then run again (keep {self.path.name}: the file is not at fault)"
        )

    def _check_schema(self, conn: sqlite3.Connection) -> None:
        version = conn.execute("PRAGMA user_version").fetchone()[0]
        if version == SCHEMA_VERSION:
            return
        if version > SCHEMA_VERSION:
            raise CatalogError(
                f"{self.path}: catalog schema version {version} was written by a newer pact "
                f"(this one reads version {SCHEMA_VERSION}); upgrade pact or use another output folder"
            )
        tables = conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'").fetchall()
        if 1 <= version < SCHEMA_VERSION:
            self._migrate(version)
            return
        if version == 0 and not tables:
            if self.readonly:
                raise CatalogError(f"{self.path}: the catalog is empty (no schema)")
            # IF NOT EXISTS + one immediate transaction: two processes racing to
            # create the catalog both succeed.
            try:
                conn.executescript(
                    "BEGIN IMMEDIATE;" + _SCHEMA + f"PRAGMA user_version = {SCHEMA_VERSION};COMMIT;"
                )
            except BaseException:
                if conn.in_transaction:
                    conn.execute("ROLLBACK")
                raise
            log.info("created catalog %s (schema %d)", self.path, SCHEMA_VERSION)
            return
        raise CatalogError(
            f"{self.path}: catalog schema version {version} is not supported "
            f"(this pact reads version {SCHEMA_VERSION}); move the file away to start a new catalog"
        )

    def _migrate(self, version: int) -> None:
        """Bring an older catalog to :data:`SCHEMA_VERSION` (also when opened read-only:
        the upgrade only adds columns)."""
        conn = sqlite3.connect(str(self.path), timeout=30.0, isolation_level=None)
        try:
            conn.execute("BEGIN IMMEDIATE")
            current = conn.execute("PRAGMA user_version").fetchone()[0]
            for k in range(current, SCHEMA_VERSION):
                for statement in _MIGRATIONS[k].split(";"):
                    if statement.strip():
                        conn.execute(statement)
            conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
            conn.execute("COMMIT")
        except sqlite3.OperationalError as e:
            if conn.in_transaction:
                conn.execute("ROLLBACK")
            raise CatalogError(
                f"{self.path}: catalog schema version {version} needs an upgrade to "
                f"{SCHEMA_VERSION} and the file cannot be changed ({e})"
            ) from e
        finally:
            conn.close()
        log.info("upgraded catalog %s from schema %d to %d", self.path, version, SCHEMA_VERSION)

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def __enter__(self) -> Catalog:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def conn(self) -> sqlite3.Connection:
        if self._conn is None:
            self.open()
        assert self._conn is not None
        return self._conn

    # ---- paths
    def _store_path(self, path: str | Path | None) -> str | None:
        """Asset folders inside the catalog's folder are stored relative to it."""
        if path is None:
            return None
        p = Path(path)
        try:
            return p.resolve().relative_to(self.root.resolve()).as_posix()
        except ValueError:
            return str(p.resolve())

    def asset_dir(self, row: AssetRecord) -> Path | None:
        """The absolute asset folder of ``row`` (None when it has no path)."""
        if row.path is None:
            return None
        p = Path(row.path)
        return p if p.is_absolute() else self.root / p

    # ---- writes
    @_database_errors
    def upsert_asset(
        self,
        record: AssetRecord,
        parts: Iterable[PartRecord] = (),
        checks: Iterable[CheckRecord] = (),
    ) -> None:
        """Insert or replace an asset with its parts and checks, in one transaction."""
        if record.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {record.status!r}")
        parts, checks = list(parts), list(checks)
        sx, sy, sz = record.size
        row = (
            record.id,
            record.source_image,
            record.source_hash,
            record.settings_hash,
            record.generator,
            record.generator_version,
            record.category or "unknown",
            record.part_count,
            record.joint_types or "",
            sx,
            sy,
            sz,
            record.status,
            record.failure_reason,
            json.dumps(list(record.repairs)),
            json.dumps(dict(record.stage_seconds)),
            self._store_path(record.path),
            record.created_at or _now(),
            json.dumps(list(record.warnings)),
            None if record.fidelity is None else json.dumps(jsonable(dict(record.fidelity))),
            json.dumps(jsonable(dict(record.inputs))),
        )
        c = self.conn
        c.execute("BEGIN IMMEDIATE")
        try:
            c.execute("DELETE FROM parts WHERE asset_id = ?", (record.id,))
            c.execute("DELETE FROM checks WHERE asset_id = ?", (record.id,))
            c.execute(
                "INSERT OR REPLACE INTO assets (id, source_image, source_hash, settings_hash, generator,"
                " generator_version, category, part_count, joint_types, size_x, size_y, size_z, status,"
                " failure_reason, repairs, stage_seconds, path, created_at, warnings, fidelity,"
                " inputs) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                row,
            )
            c.executemany(
                "INSERT INTO parts (asset_id, name, semantic, joint_type, lower, upper, mass)"
                " VALUES (?, ?, ?, ?, ?, ?, ?)",
                [
                    (record.id, p.name, p.semantic, p.joint_type, p.lower, p.upper, p.mass)
                    for p in parts
                ],
            )
            c.executemany(
                "INSERT INTO checks (asset_id, name, passed, value, tolerance, detail)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                [
                    (
                        record.id,
                        k.name,
                        int(bool(k.passed)),
                        _db_value(k.value),
                        _db_value(k.tolerance),
                        k.detail,
                    )
                    for k in checks
                ],
            )
            c.execute("COMMIT")
        except BaseException:
            c.execute("ROLLBACK")
            raise

    def record_failure(
        self,
        id: str,
        reason: str,
        *,
        source_image: str | None = None,
        source_hash: str | None = None,
        settings_hash: str | None = None,
        generator: str | None = None,
        generator_version: str | None = None,
        category: str = "unknown",
        stage_seconds: Mapping[str, float] | None = None,
        path: str | Path | None = None,
        checks: Iterable[CheckRecord] = (),
        warnings: Iterable[str] = (),
        inputs: Mapping[str, Any] | None = None,
    ) -> None:
        """Record that building ``id`` failed with ``reason`` (replaces any earlier row)."""
        rec = AssetRecord(
            id=id,
            status="failed",
            source_image=source_image,
            source_hash=source_hash,
            settings_hash=settings_hash,
            generator=generator,
            generator_version=generator_version,
            category=category,
            failure_reason=reason,
            stage_seconds=dict(stage_seconds or {}),
            path=None if path is None else str(path),
            warnings=tuple(warnings),
            inputs=dict(inputs or {}),
        )
        self.upsert_asset(rec, (), checks)

    @_database_errors
    def delete(self, id: str) -> None:
        c = self.conn
        c.execute("BEGIN IMMEDIATE")
        try:
            c.execute("DELETE FROM assets WHERE id = ?", (id,))
            c.execute("COMMIT")
        except BaseException:
            c.execute("ROLLBACK")
            raise

    # ---- reads
    _COLUMNS = (
        "id, status, source_image, source_hash, settings_hash, generator, generator_version,"
        " category, part_count, joint_types, size_x, size_y, size_z, failure_reason, repairs,"
        " stage_seconds, path, created_at, warnings, fidelity, inputs"
    )

    @staticmethod
    def _row(r: Sequence[Any]) -> AssetRecord:
        return AssetRecord(
            id=r[0],
            status=r[1],
            source_image=r[2],
            source_hash=r[3],
            settings_hash=r[4],
            generator=r[5],
            generator_version=r[6],
            category=r[7],
            part_count=r[8],
            joint_types=r[9] or "",
            size=(r[10], r[11], r[12]),
            failure_reason=r[13],
            repairs=tuple(json.loads(r[14] or "[]")),
            stage_seconds=json.loads(r[15] or "{}"),
            path=r[16],
            created_at=r[17],
            warnings=tuple(json.loads(r[18] or "[]")),
            fidelity=None if r[19] is None else json.loads(r[19]),
            inputs=json.loads(r[20] or "{}"),
        )

    def _details(self, row: AssetRecord) -> AssetRecord:
        parts = tuple(
            PartRecord(*p)
            for p in self.conn.execute(
                "SELECT name, semantic, joint_type, lower, upper, mass FROM parts"
                " WHERE asset_id = ? ORDER BY rowid",
                (row.id,),
            )
        )
        checks = tuple(
            CheckRecord(
                name=n, passed=bool(ok), value=_py_value(v), tolerance=_py_value(t), detail=d
            )
            for n, ok, v, t, d in self.conn.execute(
                "SELECT name, passed, value, tolerance, detail FROM checks WHERE asset_id = ? ORDER BY rowid",
                (row.id,),
            )
        )
        return replace(row, parts=parts, checks=checks)

    @_database_errors
    def get(self, id: str) -> AssetRecord | None:
        """The asset ``id`` with its parts and checks, or None."""
        r = self.conn.execute(f"SELECT {self._COLUMNS} FROM assets WHERE id = ?", (id,)).fetchone()
        return None if r is None else self._details(self._row(r))

    @_database_errors
    def query(
        self,
        status: str | None = None,
        category: str | None = None,
        joint_type: str | None = None,
        details: bool = False,
        min_fidelity: float | None = None,
    ) -> list[AssetRecord]:
        """Assets matching every given filter, sorted by id.

        ``joint_type`` keeps assets with at least one movable part of that type.
        ``min_fidelity`` keeps assets whose fidelity score (docs/fidelity.md) is at least
        that; an asset without a score (not measured) is left out.
        ``details=True`` also loads parts and checks.
        """
        where, args = [], []
        if status is not None:
            if status not in STATUSES:
                raise ValueError(f"status must be one of {STATUSES}, got {status!r}")
            where.append("status = ?")
            args.append(status)
        if category is not None:
            where.append("category = ?")
            args.append(category)
        if joint_type is not None:
            where.append("id IN (SELECT asset_id FROM parts WHERE joint_type = ?)")
            args.append(joint_type)
        sql = f"SELECT {self._COLUMNS} FROM assets"
        if where:
            sql += " WHERE " + " AND ".join(where)
        rows = [self._row(r) for r in self.conn.execute(sql + " ORDER BY id", args)]
        if min_fidelity is not None:
            rows = [r for r in rows if (fidelity_score(r) or -1.0) >= min_fidelity]
        return [self._details(r) for r in rows] if details else rows

    def is_done(self, id: str, source_hash: str | None, settings_hash: str | None) -> bool:
        """True when ``id`` was built from the same input and settings, did not fail, and
        its folder still holds the complete asset (:func:`folder_problem`).

        A failed asset, a changed input or settings hash, or a missing or damaged
        folder all make this False: the batch builds the item again.
        """
        row = self.get(id)
        if row is None or row.status == "failed":
            return False
        if row.source_hash != source_hash or row.settings_hash != settings_hash:
            return False
        folder = self.asset_dir(row)
        if folder is None:
            return False
        return folder_problem(folder, row.status, validated=bool(row.checks)) is None


# --------------------------------------------------------------------------- built asset -> records


def checks_from_report(report: Report | None) -> list[CheckRecord]:
    """The catalog rows of a validation report's checks.

    A check's catalog name is ``name[subject]`` (one check per link or joint); a key
    that repeats (the same check in several sweep configurations) gets ``#2``, ``#3``.
    """
    out: list[CheckRecord] = []
    seen: dict[str, int] = {}
    for c in [] if report is None else report.checks:
        name = f"{c.name}[{c.subject}]" if c.subject else c.name
        seen[name] = seen.get(name, 0) + 1
        key = name if seen[name] == 1 else f"{name}#{seen[name]}"
        detail: Any = c.message or (c.details or None)
        out.append(
            CheckRecord(
                name=key,
                passed=bool(c.passed),
                value=c.value,
                tolerance=c.tolerance,
                detail=None
                if detail is None
                else (detail if isinstance(detail, str) else json.dumps(jsonable(detail))),
            )
        )
    return out


def folder_problem(
    asset_dir: str | Path, status: str | None = None, validated: bool = True
) -> str | None:
    """Why ``asset_dir`` does not hold a complete built asset (None when it does).

    Complete: ``asset.json`` and ``model.urdf`` read, every file they reference exists,
    ``model.xml`` exists, and ``report.json`` reads and says ``status`` (when given).
    ``validated=False``: an asset built without validation, that may have no report.
    """
    asset_dir = Path(asset_dir)
    if not asset_dir.is_dir():
        return f"{asset_dir}: folder not found"
    try:
        asset = load_asset(asset_dir)
        report = read_report(asset_dir)
    except (AssetFormatError, ReportFormatError) as e:
        return str(e)
    missing = missing_files(asset)
    if not (asset_dir / MJCF_NAME).is_file():
        missing.append(MJCF_NAME)
    if missing:
        return f"{asset_dir}: missing {', '.join(missing)}"
    if report is None:
        if not validated:
            return None
        return f"{asset_dir / REPORT_NAME}: not found (the asset was never validated)"
    if status is not None and report.status != status:
        return f"{asset_dir / REPORT_NAME}: says {report.status!r}, the catalog says {status!r}"
    return None


def records_from_asset_dir(
    asset_dir: str | Path, **provenance: Any
) -> tuple[AssetRecord, list[PartRecord], list[CheckRecord]]:
    """Catalog records of a built asset folder (``asset.json`` + optional ``report.json``).

    ``provenance`` fills the fields the folder does not know (``source_image``,
    ``source_hash``, ``settings_hash``, ``generator``, ``generator_version``,
    ``stage_seconds``, ``status``, ...); a ``status`` given here wins over the report's.
    Without a report the status is 'ok' (built, not validated). Raises CatalogError
    naming the file when the folder cannot be read.
    """
    asset_dir = Path(asset_dir)
    try:
        asset = load_asset(asset_dir)
        report = read_report(asset_dir)
    except (AssetFormatError, ReportFormatError) as e:
        raise CatalogError(str(e)) from e
    parts = []
    for link in asset.links:
        j = asset.joint_of(link.name)
        parts.append(
            PartRecord(
                name=link.name,
                semantic=link.semantic,
                joint_type=None if j is None else j.type,
                lower=None if j is None else j.lower,
                upper=None if j is None else j.upper,
                mass=None if link.inertial is None else round(link.inertial.mass, 9),
            )
        )
    movable = sorted({p.joint_type for p in parts if p.joint_type and p.joint_type != "fixed"})
    size: tuple[float | None, float | None, float | None] = (None, None, None)
    if asset.bounds is not None:
        ext = asset.bounds[1] - asset.bounds[0]
        size = (float(ext[0]), float(ext[1]), float(ext[2]))
    checks = checks_from_report(report)
    status = provenance.pop("status", None) or (report.status if report else "ok")
    reason = provenance.pop("failure_reason", None)
    if status == "failed" and reason is None:
        reason = ", ".join(c.name for c in checks if not c.passed) or None
    repairs = [] if report is None else report.repairs
    if "fidelity" not in provenance and report is not None:
        provenance["fidelity"] = report.fidelity
    if "inputs" not in provenance:
        provenance["inputs"] = asset.provenance.get("inputs", {})
    known = {f.name for f in fields(AssetRecord)}
    extra = sorted(set(provenance) - known)
    if extra:
        raise TypeError(f"unknown asset record fields: {extra}")
    rec = AssetRecord(
        id=str(provenance.pop("id", None) or asset.id or asset_dir.name),
        status=status,
        category=provenance.pop("category", None) or asset.category,
        part_count=len(parts),
        joint_types=",".join(movable),
        size=size,
        failure_reason=reason,
        repairs=tuple(json.dumps(jsonable(asdict(r))) for r in repairs),
        path=str(provenance.pop("path", asset_dir)),
        **provenance,
    )
    return rec, parts, checks


def register_asset_dir(catalog: Catalog, asset_dir: str | Path, **provenance: Any) -> AssetRecord:
    """Read a built asset folder and upsert it into ``catalog``; returns the record."""
    rec, parts, checks = records_from_asset_dir(asset_dir, **provenance)
    catalog.upsert_asset(rec, parts, checks)
    return rec


# --------------------------------------------------------------------------- display


def fidelity_score(row: AssetRecord) -> float | None:
    """The fidelity score in [0, 1] of a row, None when it was not measured."""
    score = (row.fidelity or {}).get("score")
    if isinstance(score, bool) or not isinstance(score, (int, float)) or not math.isfinite(score):
        return None
    return float(score)


def fidelity_text(row: AssetRecord) -> str:
    """``0.83`` (``0.52 low`` when flagged low_fidelity); ``-`` when not measured."""
    score = fidelity_score(row)
    if score is None:
        return "-"
    return f"{score:.2f} low" if (row.fidelity or {}).get("low_fidelity") else f"{score:.2f}"


_STATUS_STYLE = {"ok": "green", "repaired": "yellow", "failed": "red"}


def repair_text(stored: str) -> str:
    """``kind(target)`` of a catalogued repair (the JSON of a RepairRecord)."""
    try:
        r = json.loads(stored)
        return f"{r['kind']}({r['target']})"
    except (json.JSONDecodeError, KeyError, TypeError):
        return stored


def _size_text(size: tuple[float | None, ...]) -> str:
    if any(v is None for v in size):
        return "-"
    return "x".join(f"{v:.2f}" for v in size)  # type: ignore[str-format]


def source_text(source: Mapping[str, Any] | None) -> str:
    """`` (parser 0.93)`` for a field the photo parser gave, ``""`` for the user's."""
    if not source or source.get("source") != "parser":
        return ""
    c = source.get("confidence")
    return " (parser)" if c is None else f" (parser {c:.2f})"


def motions_text(row: AssetRecord) -> str:
    """Each part's motion with where it came from: ``2 door_left (parser 0.88), 3 drawer``."""
    parts = row.inputs.get("parts") or {}
    return ", ".join(
        f"{k} {v.get('motion', '?')}{source_text(v)}"
        for k, v in sorted(parts.items(), key=lambda kv: int(kv[0]))
    )


def format_table(rows: Iterable[AssetRecord], title: str | None = None) -> Table:
    """A rich table of assets for ``pact ls``."""
    t = Table(title=title, show_lines=False)
    t.add_column("id", style="bold")
    t.add_column("status")
    t.add_column("category")
    t.add_column("parts", justify="right")
    t.add_column("motions (or joints)")
    t.add_column("size m (x*y*z)", justify="right")
    t.add_column("generator")
    t.add_column("fidelity", justify="right")
    t.add_column("failure / repairs / warnings", overflow="fold", max_width=48)
    for r in rows:
        style = _STATUS_STYLE.get(r.status, "")
        note = r.failure_reason or "; ".join(
            [repair_text(x) for x in r.repairs] + [f"warning: {w}" for w in r.warnings]
        )
        gen = r.generator or "-"
        if r.generator_version:
            gen += f" {r.generator_version}"
        t.add_row(
            escape(r.id),
            f"[{style}]{r.status}[/{style}]" if style else r.status,
            r.category + source_text(r.inputs.get("category")),
            "-" if r.part_count is None else str(r.part_count),
            motions_text(r) or r.joint_types or "-",
            _size_text(r.size),
            gen,
            fidelity_text(r),
            escape(note),
        )
    return t
