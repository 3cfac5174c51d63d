"""The same behaviour in SAPIEN, MuJoCo and Newton: the engine-neutral checks, each
engine's simulation of them, the report's ``engines`` section, the docs' Newton example."""

from __future__ import annotations

import io
import json
import math
import re
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
import pytest

from asset_pipeline.assets.built_asset import BuiltAsset, Handle, Inertial, Joint, JointPhysics
from asset_pipeline.assets.folder import load_asset, save_asset
from asset_pipeline.validate import read_report, validate_asset
from asset_pipeline.validate.engine_scenarios import Trajectory, scenarios
from asset_pipeline.validate.engines import engine_checks, engine_report
from asset_pipeline.validate.report import DEFAULT_TOLERANCES
from tests.asset_fixtures import box, box_link, write_box_cabinet, write_two_part_cabinet

DOCS = Path(__file__).resolve().parents[1] / "docs" / "usd.md"


@pytest.fixture(scope="module")
def cabinets(tmp_path_factory):
    root = tmp_path_factory.mktemp("engines")
    return {
        kind: load_asset(write_box_cabinet(root / kind, kind, aid=f"box_{kind}"))
        for kind in ("prismatic", "revolute")
    }


def _by_key(checks):
    return {c.key: c for c in checks}


def test_checks_judge_trajectories_the_same_for_every_engine(cabinets):
    """A part that passes its limit or does not open fails, whichever engine says so."""
    asset = cabinets["prismatic"]
    plan = scenarios(asset, DEFAULT_TOLERANCES)
    assert [s.name for s in plan] == [
        "rest",
        "touch:joint_drawer_0",
        "pull:joint_drawer_0",
        "limit:joint_drawer_0",
        "close:joint_drawer_0",
        "free",
    ]

    def fake(q_of: dict[str, float]):
        def simulate(asset, plan):
            out = []
            for s in plan:
                q0 = s.q0.get("joint_drawer_0", 0.0)
                q = np.array([[q0], [q_of.get(s.name.split(":")[0], q0)]])
                out.append(Trajectory(np.array([0.0, 1.0]), q, np.eye(4)))
            return out

        return simulate

    good = fake({"pull": 0.3, "limit": 0.3})
    checks = _by_key(engine_checks(asset, "fake", DEFAULT_TOLERANCES, simulate=good))
    assert all(c.passed for c in checks.values()), [c.key for c in checks.values() if not c.passed]
    bad = fake({"pull": 0.05, "limit": 0.33, "close": -0.02, "touch": 0.05})
    checks = _by_key(engine_checks(asset, "fake", DEFAULT_TOLERANCES, simulate=bad))
    failed = {k for k, c in checks.items() if not c.passed}
    assert failed == {
        "handle_pull[joint_drawer_0]",
        "limit_stop[joint_drawer_0]",
        "closed_stop[joint_drawer_0]",
        "touch_hold[joint_drawer_0]",
    }


@pytest.mark.parametrize("kind", ["prismatic", "revolute"])
def test_mujoco_behaves_as_sapien(cabinets, kind):
    """The MJCF's drawer slides out under a pull and stops at its limit (the MJCF's stiff
    joint limits), its door swings, the base rests on the floor: as in SAPIEN."""
    report = engine_report(cabinets[kind], ["sapien", "mujoco"], DEFAULT_TOLERANCES)
    for engine in ("sapien", "mujoco"):
        bad = [c.key for c in report[engine]["checks"] if not c.passed]
        assert not bad, (engine, bad, report[engine]["checks"])
    assert all(row["agree"] for row in report["parity"].values())
    joint = cabinets[kind].movable_joints[0].name
    pull = _by_key(report["mujoco"]["checks"])[f"handle_pull[{joint}]"]
    assert pull.value >= 0.9  # it opens (nearly) fully in 2 s


def _flap_door(folder: Path) -> BuiltAsset:
    """An oven: a 2.8 kg door hinged along its bottom edge (0..90 deg), its centre of mass
    ahead of the hinge, so gravity pulls it open and only its joint friction (1.9 N m,
    three times gravity's pull when it is ajar) holds it."""
    W, D, H = 0.6, 0.5, 0.5
    base = box_link(
        "base",
        "base",
        30.0,
        [box([D, W, 0.02], [0, 0, 0.01]), box([0.02, W, H], [-D / 2, 0, H / 2])],
    )
    door = box_link(
        "door_0",
        "door",
        2.8,
        [box([0.02, W, 0.3], [0.01, 0, 0.15]), box([0.04, 0.3, 0.02], [0.05, 0, 0.27])],
    )
    door.inertial = Inertial(2.8, np.array([0.018, 0.0, 0.14]), np.diag([0.1, 0.02, 0.1]))
    hinge = np.eye(4)
    hinge[:3, 3] = [D / 2, 0.0, 0.05]
    physics = JointPhysics(damping=0.5, friction=0.07, effort=100.0, velocity=1.0)
    asset = BuiltAsset(
        id="flap",
        links=[base, door],
        joints=[
            Joint(
                "joint_door_0", "revolute", "base", "door_0", hinge, [0, 1, 0], 0.0, 1.57, physics
            )
        ],
        handles={"door_0": Handle([0.07, 0.0, 0.27], [0, 1, 0], "bar")},
        category="oven",
        bounds=np.array([[-D / 2, -W / 2, 0.0], [D / 2, W / 2, H]]),
    )
    save_asset(asset, folder)
    return load_asset(folder)


def test_mujoco_friction_holds_a_door_ajar_as_sapien(tmp_path):
    """The MJCF's joint friction holds: an oven door nudged ajar stays (MuJoCo's default,
    soft ``frictionloss`` lets it creep open more than 1 deg in 2 s; SAPIEN holds it)."""
    report = engine_report(_flap_door(tmp_path / "flap"), ["sapien", "mujoco"], DEFAULT_TOLERANCES)
    assert all(row["agree"] for row in report["parity"].values()), report["parity"]
    checks = _by_key(report["mujoco"]["checks"])
    for key in ("touch_hold[joint_door_0]", "rest_drift[joint_door_0]"):
        assert checks[key].value <= 0.5 * DEFAULT_TOLERANCES.drift_angular, checks[key]


def test_mujoco_parts_do_not_collide_with_their_parent(tmp_path):
    """A drawer and a door whose pieces overlap the (solid) carcass they are jointed to
    are not pushed by it in MuJoCo: parent-child contacts are excluded, as PhysX filters
    them, although the carcass is welded to the world (where MuJoCo's own filter stops)."""
    asset = load_asset(write_two_part_cabinet(tmp_path / "solid", "solid", status=None))
    report = engine_report(asset, ["sapien", "mujoco"], DEFAULT_TOLERANCES)
    assert all(row["agree"] for row in report["parity"].values()), report["parity"]
    checks = _by_key(report["mujoco"]["checks"])
    for joint in ("joint_drawer_0", "joint_door_0"):
        assert checks[f"touch_hold[{joint}]"].passed and checks[f"limit_stop[{joint}]"].passed
    assert "<exclude" in asset.path_of("model.xml").read_text()


def test_validate_with_engines_writes_each_verdict(tmp_path):
    folder = write_box_cabinet(tmp_path / "cab", "prismatic")
    report = validate_asset(folder, preview=False, engines=["sapien", "mujoco"])
    assert report.status in ("ok", "repaired")
    doc = json.loads((folder / "report.json").read_text())
    section = doc["engines"]
    assert set(section) == {"sapien", "mujoco", "parity"}
    assert section["mujoco"]["file"] == "model.xml" and section["mujoco"]["passed"]
    names = {c["name"] for c in section["mujoco"]["checks"]}
    assert {"handle_pull", "limit_stop", "closed_stop", "free_base_stable"} <= names
    assert section["parity"]["limit_stop[joint_drawer_0]"] == {
        "sapien": True,
        "mujoco": True,
        "agree": True,
    }
    assert read_report(folder).engines["mujoco"]["passed"]
    # the USD is checked in the static stage: the stage opens, validators, read-back
    usd = [c for c in report.checks if c.name.startswith("usd_")]
    assert [c.name for c in usd] == ["usd_stage", "usd_matches_urdf"] and all(c.passed for c in usd)
    # without --engines nothing is added
    validate_asset(folder, preview=False)
    assert "engines" not in json.loads((folder / "report.json").read_text())


@pytest.mark.slow
def test_newton_drawer_slides_stops_and_door_swings(cabinets):
    """The USD in Newton (XPBD on Warp's CPU device): the drawer slides out under a pull at
    its handle and stops at its limit, the door swings, nothing drifts, the base rests."""
    for kind in ("prismatic", "revolute"):
        checks = _by_key(engine_checks(cabinets[kind], "usd", DEFAULT_TOLERANCES))
        bad = [k for k, c in checks.items() if not c.passed]
        assert not bad, (kind, bad, [checks[k].value for k in bad])
        joint = cabinets[kind].movable_joints[0]
        assert checks[f"handle_pull[{joint.name}]"].value >= 0.9
        assert checks[f"limit_stop[{joint.name}]"].value <= DEFAULT_TOLERANCES.limit_angular


@pytest.mark.slow
def test_newton_door_stops_at_180_degrees(tmp_path):
    """A door that opens 180 deg stops at its limit in Newton, as in SAPIEN (XPBD's
    revolute angle wraps at 180 deg: the adapter centres the joint's frame in its range)."""
    folder = write_box_cabinet(tmp_path / "door180", "revolute", aid="box_door180")
    asset = load_asset(folder)
    asset.joints[0].upper = math.pi
    save_asset(asset, folder)
    checks = _by_key(engine_checks(load_asset(folder), "usd", DEFAULT_TOLERANCES))
    bad = [k for k, c in checks.items() if not c.passed]
    assert not bad, (bad, [checks[k].value for k in bad])
    assert checks["handle_pull[joint_door_0]"].value >= 0.9


@pytest.mark.slow
def test_docs_newton_example_opens_the_drawer(cabinets):
    text = DOCS.read_text()
    code = re.search(r"## Opening a drawer in Newton.*?```python\n(.*?)```", text, re.S).group(1)
    path = cabinets["prismatic"].path_of("model.usdc")
    assert "out/examples/cabinet_t0000001/model.usdc" in code
    code = code.replace("out/examples/cabinet_t0000001/model.usdc", str(path))
    out = io.StringIO()
    scope: dict = {}
    with redirect_stdout(out):
        exec(compile(code, str(DOCS), "exec"), scope)  # noqa: S102 - the docs' own example
    assert scope["opened"] >= 0.8 * scope["upper"], out.getvalue()
    assert "drawer open" in out.getvalue()


def test_cli_validate_engines_reports_each_engine(tmp_path):
    from typer.testing import CliRunner

    from pact_cli.main import app

    folder = write_box_cabinet(tmp_path / "cab", "revolute")
    runner = CliRunner()
    res = runner.invoke(
        app, ["validate", str(folder), "--no-preview", "--engines", "sapien,mujoco"]
    )
    assert res.exit_code == 0, res.output
    assert "mujoco" in res.output and "passed" in res.output
    assert json.loads((folder / "report.json").read_text())["engines"]["mujoco"]["passed"]
    res = runner.invoke(app, ["validate", str(folder), "--engines", "bullet"])
    assert res.exit_code != 0 and "bullet" in res.output
