"""pact convert: end to end, bad items, kill and resume, the Ray executor."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from asset_pipeline.catalog.batch import ConvertSettings, run_convert
from asset_pipeline.catalog.registry import Catalog

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "images"
FAST = ConvertSettings(generator="retrieval", validate=False, preview=False)


def _copy_examples(dst: Path, names: list[str] | None = None) -> Path:
    dst.mkdir(parents=True, exist_ok=True)
    for f in sorted(EXAMPLES.iterdir()):
        stem = f.name.split(".")[0]
        if names is None or stem in names:
            shutil.copy(f, dst / f.name)
    return dst


def _assets(out: Path) -> dict[str, str]:
    con = sqlite3.connect(out / "registry.sqlite")
    try:
        return dict(con.execute("SELECT id, status FROM assets").fetchall())
    finally:
        con.close()


def test_bad_items_are_recorded_and_the_rest_convert(tmp_path):
    images = _copy_examples(tmp_path / "in", ["microwave_t0000001", "oven_t0000001"])
    (images / "corrupt.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really a png")
    shutil.copy(images / "oven_t0000001.png", images / "badmask.png")
    from PIL import Image

    Image.new("L", (256, 256), 40).save(images / "badmask.mask.png")  # id 40 > 16
    shutil.copy(images / "oven_t0000001.png", images / "badhints.png")
    (images / "badhints.json").write_text("{height: tall")
    out = tmp_path / "out"
    summary = run_convert(images, out, FAST)
    status = _assets(out)
    assert status["microwave_t0000001"] == "ok" and status["oven_t0000001"] == "ok"
    failed = {r.id: r.reason for r in summary.failed}
    assert set(failed) == {"corrupt", "badmask", "badhints"}
    assert "corrupt.png" in failed["corrupt"]
    assert "badmask.mask.png" in failed["badmask"]
    assert "badhints.json" in failed["badhints"]
    with Catalog(out, readonly=True) as cat:
        row = cat.get("badmask")
        assert row.status == "failed" and "badmask.mask.png" in row.failure_reason
    assert not (out / "corrupt").exists()
    assert not (out / ".staging").exists()
    # Every converted asset is complete, and holds the asset alone: one visual GLB per link
    # (with the OBJ and texture MJCF reads), no generator bundle, no texture folder.
    for name in ("microwave_t0000001", "oven_t0000001"):
        for f in ("asset.json", "model.urdf", "model.xml", "input.png"):
            assert (out / name / f).is_file()
        assert not (out / name / "object.json").exists() and not (out / name / "parts").exists()
        assert not (out / name / "texture").exists()
        links = json.loads((out / name / "asset.json").read_text())["links"]
        glbs = sorted(p.name for p in (out / name / "visual").glob("*.glb"))
        assert glbs == sorted(f"{link['name']}.glb" for link in links)
        assert {p.suffix for p in (out / name / "visual").iterdir()} <= {".glb", ".obj", ".png"}


def test_keep_intermediate_keeps_the_generators_bundle_for_a_rebuild(tmp_path):
    from asset_pipeline.assets.build import build_asset

    images = _copy_examples(tmp_path / "in", ["microwave_t0000001"])
    out = tmp_path / "out"
    run_convert(images, out, ConvertSettings(**{**FAST.__dict__, "keep_intermediate": True}))
    folder = out / "microwave_t0000001"
    assert (folder / "object.json").is_file() and list((folder / "parts").glob("*.glb"))
    build_asset(folder)  # the bundle builds again in place
    assert (folder / "model.urdf").is_file()


def test_rerun_skips_done_items_and_force_redoes_them(tmp_path):
    images = _copy_examples(tmp_path / "in", ["dishwasher_t0000001"])
    out = tmp_path / "out"
    first = run_convert(images, out, FAST)
    assert [r.status for r in first.results] == ["ok"]
    again = run_convert(images, out, FAST)
    assert again.results == [] and again.skipped == ["dishwasher_t0000001"]
    forced = run_convert(images, out, FAST, force=True)
    assert [r.id for r in forced.results] == ["dishwasher_t0000001"]
    # A changed input is redone without --force.
    hints = json.loads((images / "dishwasher_t0000001.json").read_text())
    hints["height"] = 0.9
    (images / "dishwasher_t0000001.json").write_text(json.dumps(hints))
    changed = run_convert(images, out, FAST)
    assert [r.id for r in changed.results] == ["dishwasher_t0000001"]


def test_killed_run_resumes_without_losing_or_half_making_anything(tmp_path):
    images = _copy_examples(tmp_path / "in")
    n = len(list(images.glob("*.mask.png")))
    out = tmp_path / "out"
    cmd = [
        sys.executable,
        "-m",
        "pact_cli",
        "convert",
        str(images),
        "--out",
        str(out),
        "--generator",
        "retrieval",
        "--no-validate",
        "--no-preview",
        "--quiet",
    ]
    proc = subprocess.Popen(cmd, start_new_session=True)
    deadline = time.time() + 240
    done: dict[str, str] = {}
    while time.time() < deadline and proc.poll() is None:
        time.sleep(0.2)
        if (out / "registry.sqlite").exists():
            try:
                done = _assets(out)
            except sqlite3.OperationalError:
                continue
            if len(done) >= 2:
                break
    assert proc.poll() is None, "the run finished before it could be killed"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    finished_before = {k for k, v in _assets(out).items() if v == "ok"}
    assert 2 <= len(finished_before) < n
    # Whatever exists under its final name is complete.
    for d in out.iterdir():
        if d.is_dir() and not d.name.startswith("."):
            assert (d / "asset.json").is_file(), f"half-made asset folder {d}"
    mtimes = {k: (out / k / "asset.json").stat().st_mtime for k in finished_before}
    summary = run_convert(images, out, FAST)
    assert set(summary.skipped) >= finished_before  # nothing finished is redone
    assert {k: (out / k / "asset.json").stat().st_mtime for k in finished_before} == mtimes
    assert len(_assets(out)) == n and set(_assets(out).values()) == {"ok"}
    assert not (out / ".staging").exists()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_ray_executor_against_a_local_ray_instance(tmp_path):
    ray_bin = Path(sys.executable).parent / "ray"
    port = _free_port()
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    # Ray's unix sockets need a short path: pytest's tmp_path is too long.
    ray_tmp = tempfile.mkdtemp(prefix="ray", dir="/tmp")
    cmd = [str(ray_bin), "start", "--head", f"--port={port}", "--num-cpus=2",
           "--include-dashboard=false", f"--temp-dir={ray_tmp}"]  # fmt: skip
    # on a loaded machine Ray's head can miss its own start-up deadline: one retry, and
    # Ray's own words in the failure message
    for _attempt in range(2):
        started = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=180)
        if started.returncode == 0:
            break
        subprocess.run([str(ray_bin), "stop", "--force"], env=env, capture_output=True)
    else:
        pytest.fail(f"ray start failed twice: {started.stderr[-2000:]}")
    try:
        images = _copy_examples(tmp_path / "in", ["microwave_t0000001"])
        out = tmp_path / "out"
        summary = run_convert(images, out, FAST, executor="ray", ray_address=f"127.0.0.1:{port}")
        assert [r.id for r in summary.results] == ["microwave_t0000001"]
        assert set(_assets(out).values()) == {"ok"}
        assert (out / "microwave_t0000001" / "model.urdf").is_file()
    finally:
        import ray

        ray.shutdown()
        subprocess.run([str(ray_bin), "stop", "--force"], env=env, capture_output=True, timeout=120)
        shutil.rmtree(ray_tmp, ignore_errors=True)
