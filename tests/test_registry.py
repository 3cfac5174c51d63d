"""The SQLite asset catalog."""

from __future__ import annotations

import json
import shutil
import sqlite3
from pathlib import Path

import pytest
from asset_fixtures import write_two_part_cabinet
from rich.console import Console

from asset_pipeline.catalog.registry import (
    AssetRecord,
    Catalog,
    CatalogError,
    CheckRecord,
    PartRecord,
    format_table,
    records_from_asset_dir,
    register_asset_dir,
)


def write_asset(folder: Path, id: str, status: str = "ok", category: str = "cabinet") -> Path:
    return write_two_part_cabinet(folder, id, status, category)


def test_register_query_and_read_back(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with Catalog(out) as cat:
        register_asset_dir(
            cat,
            write_asset(out / "cab_a", "cab_a"),
            source_image="photos/a.png",
            source_hash="h1",
            settings_hash="s1",
            generator="pact",
            generator_version="0.1",
            stage_seconds={"generate": 1.5, "collision": 3.0},
        )
        register_asset_dir(cat, write_asset(out / "cab_b", "cab_b", "repaired"))
        register_asset_dir(cat, write_asset(out / "mw", "mw", "failed", "microwave"))
        cat.record_failure("cab_c", "generator crashed: OOM", source_hash="h3", settings_hash="s1")

    assert (out / "registry.sqlite").is_file()
    with Catalog(out, readonly=True) as cat:
        a = cat.get("cab_a")
        assert a.status == "ok" and a.category == "cabinet" and a.part_count == 3
        assert a.joint_types == "prismatic,revolute"
        assert a.size == pytest.approx((0.6, 0.8, 0.9))
        assert a.stage_seconds == {"generate": 1.5, "collision": 3.0}
        assert a.path == "cab_a" and cat.asset_dir(a) == out / "cab_a"
        assert [p.name for p in a.parts] == ["base", "drawer_0", "door_0"]
        assert a.parts[1] == PartRecord("drawer_0", "drawer", "prismatic", 0.0, 0.35, 1.5)
        assert a.parts[0].joint_type is None
        sweep = next(c for c in a.checks if c.name == "drive_reach[joint_drawer_0]")
        assert sweep.value == [0.0, 0.35] and sweep.tolerance == "range"

        assert [r.id for r in cat.query()] == ["cab_a", "cab_b", "cab_c", "mw"]
        assert [r.id for r in cat.query(status="ok")] == ["cab_a"]
        assert [r.id for r in cat.query(category="microwave")] == ["mw"]
        assert [r.id for r in cat.query(joint_type="revolute", status="repaired")] == ["cab_b"]
        (repair,) = cat.get("cab_b").repairs
        assert json.loads(repair)["kind"] == "add_damping"
        mw = cat.get("mw")
        assert mw.failure_reason == "rest_drift[joint_door_0]"
        assert [c.name for c in mw.failed_checks] == ["rest_drift[joint_door_0]"]
        assert mw.failed_checks[0].value == pytest.approx(0.004)
        assert cat.get("cab_c").failure_reason == "generator crashed: OOM"
        assert cat.get("nope") is None


def test_is_done_retries_failures_and_changes(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with Catalog(out) as cat:
        register_asset_dir(cat, write_asset(out / "a", "a"), source_hash="h", settings_hash="s")
        assert cat.is_done("a", "h", "s")
        assert not cat.is_done("a", "h2", "s")  # input changed
        assert not cat.is_done("a", "h", "s2")  # settings changed
        assert not cat.is_done("b", "h", "s")  # never built
        cat.record_failure("a", "boom", source_hash="h", settings_hash="s")
        assert not cat.is_done("a", "h", "s")  # failed items are retried
        register_asset_dir(
            cat, write_asset(out / "a", "a", "repaired"), source_hash="h", settings_hash="s"
        )
        assert cat.is_done("a", "h", "s")
        assert cat.get("a").parts  # the failure's empty parts were replaced
        (out / "a" / "model.urdf").unlink()
        assert not cat.is_done("a", "h", "s")  # the folder lost a file
        shutil.rmtree(out / "a")
        assert not cat.is_done("a", "h", "s")  # the folder is gone


def test_upsert_is_atomic(tmp_path: Path) -> None:
    with Catalog(tmp_path) as cat:
        cat.upsert_asset(AssetRecord(id="x", status="ok"), [PartRecord("base")], [])
        dup = [PartRecord("base"), PartRecord("base")]  # violates the primary key
        with pytest.raises(sqlite3.IntegrityError):
            cat.upsert_asset(AssetRecord(id="x", status="repaired"), dup, [])
        row = cat.get("x")
        assert row.status == "ok" and [p.name for p in row.parts] == ["base"]
        with pytest.raises(ValueError, match="status"):
            cat.upsert_asset(AssetRecord(id="y", status="great"))


def test_wal_and_concurrent_reader(tmp_path: Path) -> None:
    with Catalog(tmp_path) as writer, Catalog(tmp_path, readonly=True) as reader:
        assert writer.conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        writer.upsert_asset(AssetRecord(id="a", status="ok"), [], [CheckRecord("loads", True)])
        assert [r.id for r in reader.query()] == ["a"]
        writer.upsert_asset(AssetRecord(id="b", status="failed", failure_reason="x"))
        assert len(reader.query()) == 2


def test_schema_version_guard(tmp_path: Path) -> None:
    with pytest.raises(CatalogError, match="no catalog"):
        Catalog(tmp_path, readonly=True).open()
    with Catalog(tmp_path):
        pass
    conn = sqlite3.connect(tmp_path / "registry.sqlite")
    conn.execute("PRAGMA user_version = 7")
    conn.close()
    with pytest.raises(CatalogError, match="newer pact"):
        Catalog(tmp_path).open()
    (tmp_path / "junk.sqlite").write_bytes(b"this is not a database at all" * 20)
    with pytest.raises(CatalogError, match="not a readable catalog"):
        Catalog(tmp_path / "junk.sqlite").open()


def test_records_and_table(tmp_path: Path) -> None:
    rec, parts, checks = records_from_asset_dir(write_asset(tmp_path / "a", "a"), generator="pact")
    assert rec.generator == "pact" and len(parts) == 3 and len(checks) == 3
    with pytest.raises(TypeError, match="unknown asset record fields"):
        records_from_asset_dir(tmp_path / "a", colour="red")
    with pytest.raises(CatalogError, match="missing: not a folder"):
        records_from_asset_dir(tmp_path / "missing")
    console = Console(record=True, width=160)
    console.print(format_table([rec, AssetRecord(id="z", status="failed", failure_reason="OOM")]))
    text = console.export_text()
    assert "prismatic,revolute" in text and "0.60x0.80x0.90" in text and "OOM" in text


def _failing_sqlite(monkeypatch: pytest.MonkeyPatch, message: str, when: str) -> None:
    """Connections whose statements starting with ``when`` raise SQLite's ``message``, as
    on a full disk (the WAL mode's shared memory cannot grow: "disk I/O error")."""
    real = sqlite3.connect

    class FullDisk(sqlite3.Connection):
        def execute(self, sql: str, *args: object) -> sqlite3.Cursor:
            if sql.lstrip().upper().startswith(when):
                raise sqlite3.OperationalError(message)
            return super().execute(sql, *args)

    monkeypatch.setattr(sqlite3, "connect", lambda *a, **k: real(*a, factory=FullDisk, **k))


@pytest.mark.parametrize("message", ["disk I/O error", "database or disk is full"])
@pytest.mark.parametrize("when", ["PRAGMA JOURNAL_MODE", "BEGIN IMMEDIATE"])
def test_a_full_disk_is_never_called_a_damaged_catalog(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, message: str, when: str
) -> None:
    out = tmp_path / "out"
    with Catalog(out) as cat:
        register_asset_dir(cat, write_asset(out / "cab_a", "cab_a"))
    before = (out / "registry.sqlite").read_bytes()
    _failing_sqlite(monkeypatch, message, when)
    with pytest.raises(CatalogError) as e, Catalog(out) as cat:
        cat.record_failure("cab_b", "x")
    text = str(e.value)
    assert text.startswith(f"{out}: cannot write the catalog registry.sqlite")
    assert "the disk is full" in text and message in text
    assert "damaged" not in text and "not a readable catalog" not in text
    monkeypatch.undo()
    assert (out / "registry.sqlite").read_bytes() == before
    with Catalog(out, readonly=True) as cat:
        assert [r.id for r in cat.query()] == ["cab_a"]


def test_a_real_sqlite_full_error_is_a_full_disk(tmp_path: Path) -> None:
    """SQLite's own SQLITE_FULL (the page limit reached, as a full disk gives it)."""
    out = tmp_path / "out"
    with Catalog(out) as cat:
        register_asset_dir(cat, write_asset(out / "cab_a", "cab_a"))
        pages = cat.conn.execute("PRAGMA page_count").fetchone()[0]
        cat.conn.execute(f"PRAGMA max_page_count = {pages}")
        with pytest.raises(CatalogError, match=f"^{out}: .*: the disk is full") as e:
            cat.record_failure("cab_b", "x" * 100_000)
        assert "damaged" not in str(e.value)


def test_a_version_2_catalog_is_migrated_keeping_its_rows(tmp_path: Path) -> None:
    """A catalog written before the ``inputs`` column (schema 2) opens, keeps its rows
    (their inputs empty) and takes the new column."""
    conn = sqlite3.connect(tmp_path / "registry.sqlite")
    conn.executescript(
        "CREATE TABLE assets (id TEXT PRIMARY KEY, source_image TEXT, source_hash TEXT,"
        " settings_hash TEXT, generator TEXT, generator_version TEXT,"
        " category TEXT NOT NULL DEFAULT 'unknown', part_count INTEGER,"
        " joint_types TEXT NOT NULL DEFAULT '', size_x REAL, size_y REAL, size_z REAL,"
        " status TEXT NOT NULL, failure_reason TEXT, repairs TEXT NOT NULL DEFAULT '[]',"
        " stage_seconds TEXT NOT NULL DEFAULT '{}', path TEXT, created_at TEXT NOT NULL,"
        " warnings TEXT NOT NULL DEFAULT '[]', fidelity TEXT);"
        "CREATE TABLE parts (asset_id TEXT NOT NULL, name TEXT NOT NULL, semantic TEXT,"
        " joint_type TEXT, lower REAL, upper REAL, mass REAL, PRIMARY KEY (asset_id, name));"
        "CREATE TABLE checks (asset_id TEXT NOT NULL, name TEXT NOT NULL, passed INTEGER NOT NULL,"
        " value, tolerance, detail TEXT, PRIMARY KEY (asset_id, name));"
        "INSERT INTO assets (id, category, status, created_at) VALUES ('old', 'oven', 'ok', 'x');"
        "PRAGMA user_version = 2;"
    )
    conn.close()
    with Catalog(tmp_path) as cat:
        old = cat.get("old")
        assert old.category == "oven" and old.inputs == {}
        cat.upsert_asset(
            AssetRecord(id="new", status="ok", inputs={"category": {"source": "user"}})
        )
        assert cat.get("new").inputs == {"category": {"source": "user"}}
