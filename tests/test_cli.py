"""The pact command line: sample, build (with validation), validate, convert, ls, gallery."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from generator.procedural import CATEGORIES
from pact_cli.main import app

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "images"
runner = CliRunner()


def test_sample_help_lists_categories():
    r = runner.invoke(app, ["sample", "--help"])
    assert r.exit_code == 0
    for cat in CATEGORIES:
        assert cat in r.output


def test_sample_unknown_category_is_a_clear_error(tmp_path):
    r = runner.invoke(app, ["sample", "--category", "sofa", "--out", str(tmp_path)])
    assert r.exit_code == 2
    assert "sofa" in r.output and "cabinet" in r.output


def test_sample_realistic_writes_the_realistic_factorys_objects(tmp_path):
    """--realistic: the parser's realistic objects (ids ``<category>_r...``), the same as
    ``sample_realistic_object`` makes; ``other`` only from that factory; a bad split is
    one error line."""
    from generator.bundle import load_bundle
    from generator.procedural.realistic import sample_realistic_object

    r = runner.invoke(
        app, ["sample", "-c", "oven", "--n", "2", "--seed", "3", "--realistic", "-o", str(tmp_path)]
    )
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["oven_r0000003", "oven_r0000004"]
    got = load_bundle(tmp_path / "oven_r0000004")
    want = sample_realistic_object("oven", 4)
    assert [p.name for p in got.parts] == [p.name for p in want.parts]
    assert got.provenance["generator"] == "procedural_realistic"
    r = runner.invoke(app, ["sample", "-c", "other", "--realistic", "-o", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    assert [p.name for p in (tmp_path / "o").iterdir()] == ["other_r0000000"]
    r = runner.invoke(app, ["sample", "-c", "other", "-o", str(tmp_path / "x")])
    assert r.exit_code == 2 and "other" in r.output
    r = runner.invoke(app, ["sample", "-c", "oven", "--split", "val", "-o", str(tmp_path / "x")])
    assert r.exit_code == 2 and "--split 'val'" in r.output


def test_sample_build_validate_and_bad_bundles(tmp_path):
    r = runner.invoke(
        app, ["sample", "-c", "microwave", "--n", "2", "--seed", "5", "--out", str(tmp_path)]
    )
    assert r.exit_code == 0, r.output
    dirs = sorted(p for p in tmp_path.iterdir())
    assert [d.name for d in dirs] == ["microwave_s0000005", "microwave_s0000006"]
    # A corrupt bundle and a bundle with a missing part mesh beside the good ones.
    bad = tmp_path / "broken"
    shutil.copytree(dirs[0], bad)
    (bad / "object.json").write_text("{")
    missing = tmp_path / "missing_part"
    shutil.copytree(dirs[1], missing)
    (missing / "parts" / "door_0.glb").unlink()
    r = runner.invoke(app, ["build", str(tmp_path), "--no-validate"])
    assert r.exit_code == 1
    assert "broken/object.json" in r.output and "not valid JSON" in r.output
    assert "door_0.glb not found" in r.output
    for d in dirs:  # the good ones were built despite the bad ones
        assert (d / "model.urdf").is_file() and (d / "model.xml").is_file()
        assert list((d / "collision").glob("*.obj"))
    shutil.rmtree(bad)
    shutil.rmtree(missing)
    # Build validates by default and writes the report.
    r = runner.invoke(app, ["build", str(dirs[0]), "--no-repair"])
    assert r.exit_code == 0, r.output
    report = json.loads((dirs[0] / "report.json").read_text())
    assert report["status"] == "ok"
    # pact validate on a broken asset: reversed limits fail, exit code 1.
    urdf = (dirs[1] / "model.urdf").read_text()
    import re

    m = re.search(r'lower="([^"]+)" upper="([^"]+)"', urdf)
    assert m
    (dirs[1] / "model.urdf").write_text(
        urdf.replace(m.group(0), f'lower="{m.group(2)}" upper="{m.group(1)}"')
    )
    r = runner.invoke(app, ["validate", str(dirs[0]), str(dirs[1]), "--no-preview"])
    assert r.exit_code == 1
    assert "failed" in r.output and "limits" in r.output


@pytest.mark.slow
def test_convert_examples_end_to_end_then_ls_and_gallery(tmp_path):
    # four of the bundled examples (two cabinets to list, a door, a bottom hinge); the
    # whole folder is converted by scripts/main.sh
    images = tmp_path / "in"
    images.mkdir()
    for stem in ("cabinet_t0000001", "cabinet_t0000002", "microwave_t0000001", "oven_t0000001"):
        for f in EXAMPLES.glob(f"{stem}.*"):
            shutil.copy(f, images / f.name)
    out = tmp_path / "out"
    r = runner.invoke(
        app,
        [
            "convert",
            str(images),
            "--out",
            str(out),
            "--generator",
            "retrieval",
            "--quiet",
            "--log-json",
            str(tmp_path / "log.jsonl"),
        ],
    )
    assert r.exit_code == 0, r.output
    names = sorted(p.name.split(".")[0] for p in images.glob("*.mask.png"))
    for name in names:
        report = json.loads((out / name / "report.json").read_text())
        assert report["status"] in ("ok", "repaired")
    lines = [json.loads(x) for x in (tmp_path / "log.jsonl").read_text().splitlines()]
    assert sorted(x["id"] for x in lines) == names
    stages = {"load", "parse", "generate", "texture", "build", "validate", "fidelity"}
    assert all(set(x["stage_seconds"]) == stages for x in lines)
    for name in names:  # the photo baked into every part, the asset scored against it
        assert (out / name / "camera.json").is_file()
        assert any((out / name / "visual").glob("*.png"))  # the textures, for MJCF
        fidelity = json.loads((out / name / "report.json").read_text())["fidelity"]
        assert 0.0 <= fidelity["score"] <= 1.0
    r = runner.invoke(app, ["ls", str(out), "--category", "cabinet"])
    assert r.exit_code == 0 and "cabinet_t000000" in r.output and "oven" not in r.output
    r = runner.invoke(app, ["gallery", str(out)])
    assert r.exit_code == 0
    html = (out / "index.html").read_text()
    for name in names:
        assert name in html


def test_check_tasks_says_when_there_is_nothing_to_check(tmp_path: Path) -> None:
    """A folder whose only asset failed validation is skipped: the command says so and
    exits non-zero instead of reporting 'opened 0 of 0 parts'."""
    asset = tmp_path / "cabinet_x"
    asset.mkdir()
    (asset / "asset.json").write_text("{}")
    (asset / "report.json").write_text(json.dumps({"status": "failed"}))
    result = runner.invoke(app, ["check-tasks", str(tmp_path)])
    assert result.exit_code == 1
    assert "no movable parts to check" in result.output
    assert "0 of 0" not in result.output


def test_check_tasks_fixed_base_keeps_the_robot_where_the_env_put_it(
    tmp_path: Path, monkeypatch
) -> None:
    """``--fixed-base`` runs the solver without other stands (``restand=False``); by
    default the base may move, and the report counts the stands and the parts opened
    where the robot was placed."""
    import tasks.solver as solver

    seen = []

    def fake_check_tasks(path, seed=0, category=None, config=None):
        seen.append(config.restand)
        stands = 0 if not config.restand else 2
        return [solver.PartCheck("fridge_x", "door_0", "revolute", "OpenDoor-v0", True, 300,
                                 0.8, 1.0, "", stands)]  # fmt: skip

    monkeypatch.setattr(solver, "check_tasks", fake_check_tasks)
    out = tmp_path / "checks.json"
    r = runner.invoke(app, ["check-tasks", str(tmp_path), "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert "0 without moving the robot's base" in r.output
    assert json.loads(out.read_text())["results"][0]["stands"] == 2
    r = runner.invoke(app, ["check-tasks", str(tmp_path), "--fixed-base"])
    assert r.exit_code == 0, r.output
    assert "1 without moving the robot's base" in r.output
    assert seen == [True, False]


def test_convert_uses_pact_by_default(tmp_path):
    images = tmp_path / "in"
    images.mkdir()
    for f in EXAMPLES.glob("microwave_t0000001*"):
        shutil.copy(f, images / f.name)
    out = tmp_path / "out"
    r = runner.invoke(
        app,
        [
            "convert",
            str(images),
            "--out",
            str(out),
            "--no-validate",
            "--no-preview",
            "--no-texture",
            "--no-fidelity",
            "--quiet",
            "--visual-faces",
            "3000",
            "--keep-intermediate",
        ],
    )
    assert r.exit_code == 0, r.output
    folder = out / "microwave_t0000001"
    asset = json.loads((folder / "asset.json").read_text())
    assert asset["provenance"]["generator"] == "pact"
    assert asset["provenance"]["articulation_features"] == "stage2+types1"
    # --visual-faces: the visuals hold at most 3000 triangles (PAct decodes ~250k)
    import trimesh

    faces = [len(trimesh.load(f, force="mesh").faces) for f in folder.glob("visual/*.glb")]
    assert len(faces) == len(asset["links"]) and 1000 < sum(faces) <= 3000
    # --keep-intermediate: the generator's bundle stays beside the asset
    assert (folder / "object.json").is_file() and (folder / "parts" / "base.glb").is_file()


def test_dataset_parser_needs_objects_or_bundles_and_names_a_bad_bundle(tmp_path):
    r = runner.invoke(app, ["dataset", "parser", "--out", str(tmp_path / "d")])
    assert r.exit_code != 0 and "--objects N" in r.output and "--bundle DIR" in r.output
    r = runner.invoke(
        app,
        ["dataset", "parser", "--out", str(tmp_path / "d"), "--bundle", str(tmp_path), "-q"],
    )
    assert r.exit_code != 0 and "not an object bundle" in r.output and str(tmp_path) in r.output
