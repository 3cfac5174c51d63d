"""Probes of pact convert with hostile inputs: each ends as a clear error, a recorded
failure, or correct handling, never as a traceback, a silent skip, a false ok or lost work."""

from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from asset_pipeline.catalog import batch
from asset_pipeline.catalog.batch import (
    ConvertSettings,
    OutputFolderError,
    OutputLockedError,
    _convert_in_worker,
    run_convert,
)
from asset_pipeline.catalog.registry import Catalog
from asset_pipeline.inputs.folder import discover_inputs
from pact_cli.main import app
from sim_envs import FolderSource

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "images"
FAST = ConvertSettings(generator="retrieval", validate=False, preview=False)
runner = CliRunner()


def _photos(dst: Path, names: list[str]) -> Path:
    dst.mkdir(parents=True, exist_ok=True)
    for f in sorted(EXAMPLES.iterdir()):
        if f.name.split(".")[0] in names:
            shutil.copy(f, dst / f.name)
    return dst


def _rows(out: Path) -> dict[str, str]:
    with Catalog(out, readonly=True) as cat:
        return {r.id: r.status for r in cat.query()}


def test_reserved_id_in_hints_fails_the_item_and_keeps_the_catalog(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001", "oven_t0000001"])
    (images / "oven_t0000001.json").write_text(json.dumps({"id": "registry.sqlite"}))
    out = tmp_path / "out"
    summary = run_convert(images, out, FAST)
    (failed,) = summary.failed
    assert "oven_t0000001.json" in failed.reason and "reserved" in failed.reason
    assert (out / "registry.sqlite").is_file()
    assert _rows(out)["microwave_t0000001"] == "ok"
    again = run_convert(images, out, FAST)  # a second run reads the catalog fine
    assert again.skipped == ["microwave_t0000001"]


def test_two_photos_with_one_id_both_fail_and_nothing_is_overwritten(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001", "oven_t0000001", "desk_t0000001"])
    for name in ("microwave_t0000001", "oven_t0000001"):
        (images / f"{name}.json").write_text(json.dumps({"id": "kitchen"}))
    out = tmp_path / "out"
    summary = run_convert(images, out, FAST)
    failed = {r.name: r.reason for r in summary.failed}
    assert set(failed) == {"microwave_t0000001", "oven_t0000001"}
    assert all("'kitchen'" in why for why in failed.values())
    assert not (out / "kitchen").exists() and _rows(out) == {"desk_t0000001": "ok"}


def test_an_id_the_catalog_gives_to_another_photo_is_refused(tmp_path):
    first = _photos(tmp_path / "a", ["microwave_t0000001"])
    (first / "microwave_t0000001.json").write_text(json.dumps({"id": "kitchen"}))
    out = tmp_path / "out"
    assert [r.status for r in run_convert(first, out, FAST).results] == ["ok"]
    before = (out / "kitchen" / "asset.json").read_bytes()
    second = _photos(tmp_path / "b", ["oven_t0000001"])
    (second / "oven_t0000001.json").write_text(json.dumps({"id": "kitchen"}))
    (refused,) = run_convert(second, out, FAST).failed
    assert "already belongs to" in refused.reason and "microwave_t0000001.png" in refused.reason
    assert (out / "kitchen" / "asset.json").read_bytes() == before
    assert _rows(out) == {"kitchen": "ok"}


def _edit(photo: Path) -> None:
    """Change one pixel of ``photo`` (its input hash changes)."""
    img = Image.open(photo)
    img.load()
    img.putpixel((0, 0), tuple(255 - v for v in img.getpixel((0, 0))))
    img.save(photo)


def test_an_edited_photo_converted_from_another_directory_is_not_another_photo(
    tmp_path, monkeypatch
):
    _photos(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    monkeypatch.chdir(tmp_path)
    assert [r.status for r in run_convert("in", "out", FAST).results] == ["ok"]
    with Catalog(out, readonly=True) as cat:
        stored = cat.get("microwave_t0000001").source_image
    assert stored == str(tmp_path / "in" / "microwave_t0000001.png")  # absolute
    _edit(tmp_path / "in" / "microwave_t0000001.png")
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    summary = run_convert("../in", out, FAST)
    assert [(r.id, r.status) for r in summary.results] == [("microwave_t0000001", "ok")]


def test_a_relative_photo_path_of_an_older_catalog_is_not_another_photo(tmp_path, monkeypatch):
    images = _photos(tmp_path / "in", ["microwave_t0000001", "oven_t0000001"])
    out = tmp_path / "out"
    run_convert(images, out, FAST)
    with Catalog(out) as cat:  # as an older pact stored them: relative to its directory
        for name, photo in (
            ("microwave_t0000001", "microwave_t0000001"),
            ("oven_t0000001", "stove"),
        ):
            row = cat.get(name)  # the oven's names a photo of another name
            row = replace(row, source_image=f"in/{photo}.png", path=str(cat.asset_dir(row)))
            cat.upsert_asset(row, row.parts, row.checks)
    for name in ("microwave_t0000001", "oven_t0000001"):
        _edit(images / f"{name}.png")
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")  # "in/..." names no file from here
    results = {r.id: r for r in run_convert(images, out, FAST).results}
    assert results["microwave_t0000001"].status == "ok"
    assert results["oven_t0000001"].status == "failed"
    assert "already belongs to in/stove.png" in results["oven_t0000001"].reason


def test_a_second_run_on_the_same_out_stops_and_touches_nothing(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    (out / ".staging" / "busy").mkdir(parents=True)  # the first run's work in progress
    with batch.output_lock(out):
        with pytest.raises(OutputLockedError, match=f"{out}: another pact run"):
            run_convert(images, out, FAST)
    assert (out / ".staging" / "busy").is_dir()
    assert not (out / "registry.sqlite").exists()


def test_deleting_the_lock_file_during_a_run_lets_no_second_run_in(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    out.mkdir()
    busy = out / ".staging" / f"{os.getpid()}.{time.time_ns()}" / "microwave_t0000001"
    with batch.output_lock(out):  # the first run
        busy.mkdir(parents=True)  # its item in progress
        (out / ".lock").unlink()  # someone cleans up hidden files
        with pytest.raises(OutputLockedError, match=f"{out}: another pact run"):
            run_convert(images, out, FAST)
        assert busy.is_dir()
    assert not (out / "registry.sqlite").exists()


def test_a_lock_file_replaced_while_it_is_locked_is_locked_again(tmp_path, monkeypatch):
    """Another process deletes OUT/.lock between our open and our flock: the flock is on
    a file nobody else sees, so it is taken again on the file now at OUT/.lock."""
    out = tmp_path / "out"
    out.mkdir()
    real_flock, replaced = fcntl.flock, []
    lock = out / ".lock"

    def racing_flock(fd, operation):
        if not replaced and lock.exists() and os.fstat(fd).st_ino == lock.stat().st_ino:
            replaced.append(fd)
            lock.unlink()
            lock.write_text("")  # the other process's new lock file
        return real_flock(fd, operation)

    monkeypatch.setattr(fcntl, "flock", racing_flock)
    with batch.output_lock(out):
        assert replaced and lock.read_text() == str(os.getpid())
        fd = os.open(lock, os.O_RDWR)  # what a second run would lock
        try:
            with pytest.raises(BlockingIOError):
                real_flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            os.close(fd)


def test_a_run_removes_only_the_staging_folders_of_dead_processes(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()  # a pid that is no longer running
    now = time.time_ns()
    dead = out / ".staging" / f"{child.pid}.{now}"
    live = out / ".staging" / f"{os.getppid()}.{now}"  # pytest's parent: alive
    for folder in (dead, live):
        (folder / "microwave_t0000001").mkdir(parents=True)
    assert [r.status for r in run_convert(images, out, FAST).results] == ["ok"]
    assert not dead.exists()
    assert (live / "microwave_t0000001").is_dir()
    assert os.listdir(out / ".staging") == [live.name]


def test_rerun_rebuilds_assets_whose_files_were_deleted(tmp_path):
    names = ["microwave_t0000001", "oven_t0000001", "desk_t0000001"]
    images = _photos(tmp_path / "in", names)
    out = tmp_path / "out"
    run_convert(images, out, FAST)
    (out / "microwave_t0000001" / "model.urdf").unlink()
    shutil.rmtree(out / "oven_t0000001" / "collision")
    summary = run_convert(images, out, FAST)
    assert sorted(r.id for r in summary.results) == ["microwave_t0000001", "oven_t0000001"]
    assert summary.skipped == ["desk_t0000001"]
    assert set(_rows(out).values()) == {"ok"}
    assert (out / "microwave_t0000001" / "model.urdf").is_file()
    assert list((out / "oven_t0000001" / "collision").glob("*.obj"))


def test_a_damaged_asset_whose_photo_is_gone_is_marked_failed(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001", "oven_t0000001"])
    out = tmp_path / "out"
    run_convert(images, out, FAST)
    (out / "oven_t0000001" / "model.urdf").unlink()
    for f in images.glob("oven_t0000001*"):
        f.unlink()
    summary = run_convert(images, out, FAST)
    assert any("oven_t0000001" in note and "model.urdf" in note for note in summary.reconciled)
    assert _rows(out) == {"microwave_t0000001": "ok", "oven_t0000001": "failed"}
    assert [a.id for a in FolderSource(out)] == ["microwave_t0000001"]


def test_a_photo_that_became_unreadable_sets_its_old_asset_aside(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    run_convert(images, out, FAST)
    (images / "microwave_t0000001.png").write_bytes(b"\x89PNG\r\n\x1a\nbroken")
    (failed,) = run_convert(images, out, FAST).failed
    assert "microwave_t0000001.png" in failed.reason and ".previous" in failed.reason
    assert _rows(out) == {"microwave_t0000001": "failed"}
    assert not (out / "microwave_t0000001").exists()
    assert (out / ".previous" / "microwave_t0000001" / "model.urdf").is_file()  # not lost
    assert len(FolderSource(out)) == 0


VALIDATED = ConvertSettings(generator="retrieval", preview=False, texture=False, fidelity=False)


def _validation_says(monkeypatch, status: str) -> None:
    """Replace SAPIEN validation by a report of ``status`` (one load check)."""
    import asset_pipeline.validate as validate
    from asset_pipeline.validate import Check, Report, write_report

    def fake(staging, **_options) -> Report:
        passed = status != "failed"
        check = Check("sapien_load", "load", "asset", passed, message=f"says {status}")
        report = Report(asset=Path(staging).name, status=status, checks=[check])
        write_report(report, staging)
        return report

    monkeypatch.setattr(validate, "validate_asset", fake)


def _good_then_failing(tmp_path: Path, monkeypatch) -> tuple[Path, Path]:
    """A good asset of the microwave in OUT, then validation of every item fails."""
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    _validation_says(monkeypatch, "ok")
    assert [r.status for r in run_convert(images, out, VALIDATED).results] == ["ok"]
    _validation_says(monkeypatch, "failed")
    return images, out


def _report_status(folder: Path) -> str:
    return json.loads((folder / "report.json").read_text())["status"]


def test_failing_twice_in_a_row_keeps_the_last_good_asset_in_previous(tmp_path, monkeypatch):
    images, out = _good_then_failing(tmp_path, monkeypatch)
    kept = out / ".previous" / "microwave_t0000001"
    for _rerun in range(2):  # the same command twice: the second failure must not lose it
        (failed,) = run_convert(images, out, VALIDATED, force=True).failed
        assert failed.stage == "validate"
        assert _report_status(kept) == "ok" and (kept / "model.urdf").is_file()
        assert _rows(out) == {"microwave_t0000001": "failed"}
    assert _report_status(out / "microwave_t0000001") == "failed"  # kept to be looked at
    assert str(kept) in failed.reason  # the later failure still says where the good one is


def test_the_first_failure_says_where_the_good_asset_went(tmp_path, monkeypatch):
    images, out = _good_then_failing(tmp_path, monkeypatch)
    (failed,) = run_convert(images, out, VALIDATED, force=True).failed
    kept = out / ".previous" / "microwave_t0000001"
    assert "validation failed" in failed.reason and f"moved to {kept}" in failed.reason
    with Catalog(out, readonly=True) as cat:
        assert f"moved to {kept}" in cat.get("microwave_t0000001").failure_reason


def _convert_or_die(job: tuple, report) -> batch.ItemResult:
    """A worker that is killed (SIGKILL) while it holds the oven."""
    if job[0].name == "oven_t0000001":
        report("generate")
        os.kill(os.getpid(), signal.SIGKILL)
    return _convert_in_worker(job, report)


def test_a_crashed_worker_fails_only_its_own_item_and_names_it(tmp_path):
    names = ["microwave_t0000001", "oven_t0000001", "desk_t0000001", "dishwasher_t0000001"]
    images = _photos(tmp_path / "in", names)
    out = tmp_path / "out"
    out.mkdir()
    todo = list(discover_inputs(images))
    results = {
        r.name: r for r in batch._local_results(todo, out, FAST, 2, None, work=_convert_or_die)
    }
    assert set(results) == set(names)
    oven = results.pop("oven_t0000001")
    assert oven.status == "failed" and oven.reason.startswith("oven_t0000001:")
    assert "SIGKILL" in oven.reason and "generate" in oven.reason
    assert {r.status for r in results.values()} == {"ok"}


def test_photos_that_cannot_hold_an_object_fail_at_load_by_name(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    Image.new("RGB", (1, 1), (200, 10, 10)).save(images / "dot.png")
    Image.new("RGBA", (64, 64), (200, 10, 10, 0)).save(images / "invisible.png")
    shutil.copy(images / "microwave_t0000001.png", images / "nomask.png")
    Image.new("L", (256, 256), 0).save(images / "nomask.mask.png")
    summary = run_convert(images, tmp_path / "out", FAST)
    failed = {r.name: r.reason for r in summary.failed}
    assert set(failed) == {"dot", "invisible", "nomask"}
    assert "dot.png" in failed["dot"] and "1x1" in failed["dot"]
    assert "invisible.png" in failed["invisible"] and "silhouette" in failed["invisible"]
    assert "nomask.mask.png" in failed["nomask"] and "empty" in failed["nomask"]
    assert all(r.stage == "load" for r in summary.failed)


def test_another_photos_mask_is_refused_or_flagged(tmp_path):
    # a washing machine's mask on a dishwasher's photo: its part boundaries lie where the
    # photo has no edges at all, refused
    images = _photos(tmp_path / "in", ["dishwasher_t0000001"])
    shutil.copy(
        EXAMPLES / "washing_machine_t0000001.mask.png", images / "dishwasher_t0000001.mask.png"
    )
    (failed,) = run_convert(images, tmp_path / "out", FAST).failed
    assert "dishwasher_t0000001.mask.png" in failed.reason and "another photo" in failed.reason
    # a cabinet's mask on a microwave's photo: weak edges (as a real photo's own mask of a
    # drawer in a frame of its colour can have), converted with a warning naming it
    images = _photos(tmp_path / "in2", ["microwave_t0000001"])
    shutil.copy(EXAMPLES / "cabinet_t0000002.mask.png", images / "microwave_t0000001.mask.png")
    summary = run_convert(images, tmp_path / "out2", FAST)
    assert not summary.failed
    with Catalog(tmp_path / "out2", readonly=True) as cat:
        (row,) = cat.query()
    assert any("microwave_t0000001.mask.png" in w and "another photo" in w for w in row.warnings)


def test_a_mask_with_a_hidden_part_converts_and_the_catalog_keeps_the_warning(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    mask = images / "microwave_t0000001.mask.png"
    ids = np.asarray(Image.open(mask)).copy()
    ids[ids == 2] = 3  # the door numbered as if a part before it were hidden
    Image.fromarray(ids).save(mask)
    (result,) = run_convert(images, tmp_path / "out", FAST).results
    assert result.status == "ok"
    with Catalog(tmp_path / "out", readonly=True) as cat:
        (row,) = cat.query()
    assert any(str(mask) in w and "renumbered 3 -> 2" in w for w in row.warnings)


def test_webp_photos_convert_and_skipped_files_are_listed(tmp_path):
    images = tmp_path / "in"
    images.mkdir()
    rgb = Image.open(EXAMPLES / "microwave_t0000001.png").convert("RGB")
    rgb.save(images / "microwave.webp", lossless=True)
    (images / "notes.txt").write_text("shopping list")
    os.symlink("loop_b.png", images / "loop_a.png")
    os.symlink("loop_a.png", images / "loop_b.png")
    summary = run_convert(images, tmp_path / "out", FAST)
    assert [(r.id, r.status) for r in summary.results] == [("microwave", "ok")]
    ignored = {f.path.name: f.reason for f in summary.ignored}
    assert set(ignored) == {"notes.txt", "loop_a.png", "loop_b.png"}
    assert "loop" in ignored["loop_a.png"]


def test_output_and_input_folders_are_checked_before_anything_is_made(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    not_a_folder = tmp_path / "out.txt"
    not_a_folder.write_text("x")
    with pytest.raises(OutputFolderError, match="out.txt: exists and is not a folder"):
        run_convert(images, not_a_folder, FAST)
    res = runner.invoke(app, ["convert", str(tmp_path / "nope"), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "nope" in res.output and "Traceback" not in res.output
    assert not (tmp_path / "o").exists()
    res = runner.invoke(app, ["convert", str(images), "--out", str(not_a_folder)])
    assert res.exit_code == 2 and "error:" in res.output
    res = runner.invoke(
        app,
        ["convert", str(images), "--out", str(tmp_path / "o2"), "--log-json", "/nope/log.jsonl"],
    )
    assert res.exit_code == 2 and "/nope/log.jsonl" in res.output


@pytest.mark.parametrize(
    "code, words",
    [(errno.EROFS, "it is on a read-only file system"), (errno.EACCES, "no permission to write")],
)
@pytest.mark.parametrize("where", ["the lock", "a new file"])
def test_an_output_folder_that_cannot_be_written_is_one_error_line(
    tmp_path, monkeypatch, code, words, where
):
    """A read-only mount or a folder without write permission (simulated: the tests run
    as root): one error line naming the folder, nothing converted."""
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    out.mkdir()
    if where == "a new file":
        (out / ".lock").touch()  # an existing file opens; nothing new can be made
    real_open = os.open

    def refusing_open(path, flags, *args, **kwargs):
        p = Path(path)
        if p.parent == out and (
            p.name == ".lock" if where == "the lock" else flags & os.O_CREAT and not p.exists()
        ):
            raise OSError(code, os.strerror(code), str(path))
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", refusing_open)
    res = runner.invoke(
        app, ["convert", str(images), "--out", str(out), "--generator", "retrieval"]
    )
    assert res.exit_code == 2, res.output
    assert isinstance(res.exception, SystemExit)  # an exit code, not a traceback
    assert f"error: {out}: cannot write to the output folder: {words}" in res.output
    assert not (out / "registry.sqlite").exists() and not (out / "microwave_t0000001").exists()


@pytest.mark.parametrize("fault", ["the catalog", "the lock"])
def test_a_disk_full_before_the_run_is_called_full_and_the_catalog_is_kept(
    tmp_path, monkeypatch, fault
):
    images = _photos(tmp_path / "in", ["microwave_t0000001", "oven_t0000001"])
    out = tmp_path / "out"
    run_convert(images, out, FAST)
    (images / "oven_t0000001.json").write_text('{"height": 0.7}')  # something to do
    if fault == "the catalog":  # SQLite in WAL mode on a full disk: "disk I/O error"
        real = sqlite3.connect

        class FullDisk(sqlite3.Connection):
            def execute(self, sql, *args):
                if sql.upper().startswith("PRAGMA JOURNAL_MODE"):
                    raise sqlite3.OperationalError("disk I/O error")
                return super().execute(sql, *args)

        monkeypatch.setattr(sqlite3, "connect", lambda *a, **k: real(*a, factory=FullDisk, **k))
    else:

        def no_space(fd, data, offset):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        monkeypatch.setattr(os, "pwrite", no_space)
    res = runner.invoke(
        app, ["convert", str(images), "--out", str(out), "--generator", "retrieval"]
    )
    assert res.exit_code == 2 and isinstance(res.exception, SystemExit), res.output
    (line,) = [x for x in res.output.splitlines() if x.startswith("error:")]
    assert line.startswith(f"error: {out}: cannot write") and "the disk is full" in line
    assert "damaged" not in line and "not a readable catalog" not in line
    monkeypatch.undo()
    assert _rows(out) == {"microwave_t0000001": "ok", "oven_t0000001": "ok"}


def test_a_damaged_catalog_is_one_error_line(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    out.mkdir()
    (out / "registry.sqlite").write_bytes(b"SQLite format 3\x00" + os.urandom(4000))
    for args in (
        ["convert", str(images), "--out", str(out)],
        ["gallery", str(out)],
        ["ls", str(out)],
    ):
        res = runner.invoke(app, args)
        assert res.exit_code == 2, (args, res.output)
        assert "error:" in res.output and "registry.sqlite" in res.output
        assert isinstance(res.exception, SystemExit)  # an exit code, not a traceback


def test_generated_files_are_readable_by_others(tmp_path):
    images = _photos(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    old = os.umask(0o022)
    try:
        run_convert(images, out, FAST)
    finally:
        os.umask(old)
    for name in ("model.urdf", "model.xml", "asset.json", "input.png", "visual/base.glb"):
        assert (out / "microwave_t0000001" / name).stat().st_mode & 0o777 == 0o644


def test_train_gen_passes_its_options_and_guards_the_shipped_weights(tmp_path, monkeypatch):
    import generator.pact.training.train_stage2 as stage2

    seen = []
    monkeypatch.setattr(stage2, "main", lambda argv: seen.append(argv))
    res = runner.invoke(
        app,
        ["train-gen", "--stage", "2", "--what", "vae", "--data", "D", "--out", str(tmp_path),
         "--config", "full", "--no-resume", "--minutes", "3", "--threads", "1"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    (argv,) = seen
    assert argv[:3] == ["vae", "--data", "D"]
    assert argv[argv.index("--out") + 1] == str(tmp_path)
    assert "--config" in argv and "stage2_full" in argv and "--resume" not in argv
    assert ["--minutes", "3.0"] == argv[argv.index("--minutes") : argv.index("--minutes") + 2]
    monkeypatch.undo()
    shipped = Path(stage2.__file__).parents[1] / "weights" / "small"
    before = sorted((p, p.stat().st_mtime) for p in shipped.rglob("*"))
    with pytest.raises(SystemExit, match="shipped weights"):
        stage2.main(["vae", "--data", "D", "--out", str(shipped / "slat_vae")])
    res = runner.invoke(app, ["train-gen", "--stage", "1", "--data", "D", "--out", str(shipped)])
    assert res.exit_code == 2 and "shipped weights" in res.output
    assert sorted((p, p.stat().st_mtime) for p in shipped.rglob("*")) == before


@pytest.mark.parametrize(
    "what, option", [("cache", "--cache"), ("flow", "--cache"), ("vae", "--logdir")]
)
def test_train_gen_never_writes_the_shipped_weights_through_any_folder(
    tmp_path, monkeypatch, what, option
):
    """Not only --out: the stage-2 token cache and the logs are written too."""
    import generator.pact.training.train_stage2 as stage2

    ran = []
    monkeypatch.setattr(stage2, "build_cache", lambda data, cache: ran.append(cache))
    for step in ("train_vae", "train_flow"):
        monkeypatch.setattr(stage2, step, lambda args: ran.append(args))
    shipped = Path(stage2.__file__).parents[1] / "weights" / "small"
    before = sorted((p, p.stat().st_mtime) for p in shipped.rglob("*"))
    folders = {"--cache": str(tmp_path / "cache"), "--logdir": str(tmp_path / "logs")}
    folders[option] = str(shipped / "cache")
    argv = [what, "--data", "D", "--out", str(tmp_path / "w"), *sum(folders.items(), ())]
    with pytest.raises(SystemExit, match=f"error: {option} .*shipped weights"):
        stage2.main(argv)
    if option == "--cache":
        cli = ["train-gen", "--stage", "2", "--what", what, "--data", "D"]
        res = runner.invoke(app, [*cli, "--out", str(tmp_path / "w"), "--cache", folders[option]])
        assert res.exit_code == 2 and "error: --cache" in res.output, res.output
        assert "shipped weights" in res.output
    assert ran == []
    assert sorted((p, p.stat().st_mtime) for p in shipped.rglob("*")) == before
    folders[option] = str(tmp_path / "elsewhere")  # anywhere else is fine
    stage2.main([what, "--data", "D", "--out", str(tmp_path / "w"), *sum(folders.items(), ())])
    assert len(ran) == 1


def test_the_flock_is_released_when_a_run_dies(tmp_path):
    """The lock is an flock: the kernel drops it with the process, so a killed run never
    leaves a stale lock behind."""
    out = tmp_path / "out"
    out.mkdir()
    pid = os.fork()
    if pid == 0:  # child: take the lock and die without cleaning up
        fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT)
        fcntl.flock(fd, fcntl.LOCK_EX)
        os._exit(0)
    os.waitpid(pid, 0)
    with batch.output_lock(out):
        assert (out / ".lock").read_text() == str(os.getpid())
