"""model.usdc: written for every kind of asset, checked with USD's own tools (the stage
opens, USD's validators report nothing, USD's physics parser reads back the URDF)."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

pxr = pytest.importorskip("pxr")
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade  # noqa: E402

from asset_pipeline.assets.build import BuildOptions, build_asset  # noqa: E402
from asset_pipeline.assets.folder import load_asset  # noqa: E402
from asset_pipeline.assets.usd import axis_frame, principal_inertia  # noqa: E402
from asset_pipeline.validate.usd_checks import (  # noqa: E402
    read_usd_physics,
    usd_checks,
    usd_urdf_differences,
    usd_validation_errors,
)
from generator.bundle import save_bundle  # noqa: E402
from generator.procedural import sample_object  # noqa: E402
from tests.asset_fixtures import write_two_part_cabinet  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "images"


def _independent_readback(folder: Path) -> None:
    """Compare the USD with the URDF using pxr and the XML alone (not the project's reader)."""
    import xml.etree.ElementTree as ET

    stage = Usd.Stage.Open(str(folder / "model.usdc"))
    assert UsdGeom.GetStageUpAxis(stage) == "Z" and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    root = stage.GetDefaultPrim()
    assert root.HasAPI(UsdPhysics.ArticulationRootAPI)
    urdf = ET.parse(folder / "model.urdf").getroot()
    for link in urdf.findall("link"):
        prim = root.GetChild(link.get("name"))
        assert prim.HasAPI(UsdPhysics.RigidBodyAPI), link.get("name")
        mass = float(link.find("inertial/mass").get("value"))
        assert UsdPhysics.MassAPI(prim).GetMassAttr().Get() == pytest.approx(mass, rel=1e-6)
        colliders = [c for c in prim.GetChildren() if c.HasAPI(UsdPhysics.CollisionAPI)]
        assert len(colliders) == len(link.findall("collision"))
        for c in colliders:
            approx = UsdPhysics.MeshCollisionAPI(c).GetApproximationAttr().Get()
            assert approx == "convexHull"
    for joint in urdf.findall("joint"):
        prim = root.GetPrimAtPath(f"joints/{joint.get('name')}")
        lim = joint.find("limit")
        if joint.get("type") == "revolute":
            j = UsdPhysics.RevoluteJoint(prim)
            assert j.GetUpperLimitAttr().Get() == pytest.approx(
                math.degrees(float(lim.get("upper"))), rel=1e-5
            )
        elif joint.get("type") == "prismatic":
            j = UsdPhysics.PrismaticJoint(prim)
            assert j.GetUpperLimitAttr().Get() == pytest.approx(float(lim.get("upper")), rel=1e-5)
        else:
            continue
        assert [str(t.name) for t in j.GetBody1Rel().GetTargets()] == [
            joint.find("child").get("link")
        ]
    fixed = UsdPhysics.FixedJoint(root.GetPrimAtPath("joints/root_joint"))
    assert not fixed.GetBody0Rel().GetTargets()


def _assert_good_usd(folder: Path) -> None:
    asset = load_asset(folder)
    checks = usd_checks(asset)
    assert [c.name for c in checks] == ["usd_stage", "usd_matches_urdf"]
    assert all(c.passed for c in checks), [c.message for c in checks]
    _independent_readback(folder)


def test_procedural_asset_usd_validates_and_reads_back_like_the_urdf(tmp_path):
    obj = sample_object("cabinet", 0)
    result = build_asset(save_bundle(obj, tmp_path / "cabinet"))
    folder = result.directory
    _assert_good_usd(folder)
    stage = Usd.Stage.Open(str(folder / "model.usdc"))
    # the visuals carry the photo/procedural texture through UsdPreviewSurface, the image
    # referenced next to the USD (visual/<link>.png, the MJCF's): no third copy
    textures = []
    for prim in stage.Traverse():
        shader = UsdShade.Shader(prim)
        if shader and shader.GetIdAttr().Get() == "UsdUVTexture":
            textures.append(shader.GetInput("file").Get().path)
    assert textures, "no texture in the stage"
    for t in textures:
        assert (folder / t).is_file() and t.startswith("./visual/") and t.endswith(".png")
    assert sorted(p.suffix for p in folder.rglob("*.png")) == [".png"] * len(textures)
    # damping and friction as the readers understand them
    door = next(j for j in result.asset.joints if j.type == "revolute")
    prim = stage.GetDefaultPrim().GetPrimAtPath(f"joints/{door.name}")
    drive = UsdPhysics.DriveAPI(prim, "angular")
    assert drive.GetDampingAttr().Get() == pytest.approx(door.physics.damping / math.degrees(1))
    assert prim.GetAttribute("physxJoint:jointFriction").Get() == pytest.approx(
        door.physics.friction
    )


@pytest.mark.slow
def test_imported_partnet_asset_usd_validates(tmp_path):
    from asset_pipeline.importers.partnet import import_objects
    from tests.partnet_fixtures import links_from_object, write_partnet

    obj = sample_object("refrigerator", 1)
    src = write_partnet(tmp_path / "src" / "7001", links_from_object(obj), model_cat="Refrigerator")
    result = import_objects([src], tmp_path / "imported")
    assert not result.failures, result.failures
    built = build_asset(result[0])
    _assert_good_usd(built.directory)


@pytest.mark.slow
def test_generated_asset_usd_validates(tmp_path):
    from asset_pipeline.catalog.batch import ConvertSettings, run_convert

    images = tmp_path / "in"
    images.mkdir()
    for f in EXAMPLES.glob("microwave_t0000001*"):
        shutil.copy(f, images / f.name)
    settings = ConvertSettings(generator="retrieval", validate=False, preview=False)
    run_convert(images, tmp_path / "out", settings)
    _assert_good_usd(tmp_path / "out" / "microwave_t0000001")


def test_formats_choose_the_files_and_export_adds_the_usd(tmp_path):
    from pact_cli.main import app

    obj = sample_object("oven", 0)
    folder = save_bundle(obj, tmp_path / "oven")
    build_asset(folder, options=BuildOptions(formats=("urdf", "mjcf")))
    assert (folder / "model.xml").is_file() and not (folder / "model.usdc").exists()
    with pytest.raises(ValueError, match="urdf"):
        BuildOptions(formats=("usd",))
    res = CliRunner().invoke(app, ["export", str(tmp_path), "--format", "usd"])
    assert res.exit_code == 0, res.output
    _assert_good_usd(folder)
    # a build without it removes the USD of an older build
    build_asset(folder, options=BuildOptions(formats=("urdf",)))
    assert not (folder / "model.usdc").exists() and not (folder / "model.xml").exists()


def test_validators_and_readback_find_a_broken_stage(tmp_path):
    folder = write_two_part_cabinet(tmp_path / "cab", "cab", status=None)
    asset = load_asset(folder)
    stage = Usd.Stage.Open(str(folder / "model.usdc"))
    assert usd_validation_errors(stage) == []
    assert usd_urdf_differences(asset, read_usd_physics(stage)) == []
    # a joint to a body that does not exist, and an articulation nested in another
    joint = UsdPhysics.RevoluteJoint(stage.GetPrimAtPath("/cab/joints/joint_door_0"))
    joint.GetBody1Rel().SetTargets([Sdf.Path("/cab/nowhere")])
    UsdPhysics.ArticulationRootAPI.Apply(stage.GetPrimAtPath("/cab/base"))
    errors = usd_validation_errors(stage)
    assert any("PhysicsJointChecker" in e for e in errors), errors
    assert any("ArticulationChecker" in e for e in errors), errors
    # the physics parser sees a changed limit and a lost collider
    stage = Usd.Stage.Open(str(folder / "model.usdc"))
    UsdPhysics.PrismaticJoint(
        stage.GetPrimAtPath("/cab/joints/joint_drawer_0")
    ).GetUpperLimitAttr().Set(0.5)
    stage.RemovePrim("/cab/base/collision_0")
    diffs = usd_urdf_differences(asset, read_usd_physics(stage))
    assert any("joint_drawer_0: limits" in d for d in diffs), diffs
    assert any(d.startswith("base: 0 colliders") for d in diffs), diffs
    # and validation reports it when the USD on disk is broken
    stage.GetRootLayer().Export(str(folder / "model.usdc"))
    from asset_pipeline.validate import check_asset

    checks, _ = check_asset(folder)
    bad = [c for c in checks if c.name == "usd_matches_urdf"]
    assert bad and not bad[0].passed


def test_mass_frames_and_axes():
    inertia = np.array([[0.3, 0.05, 0.0], [0.05, 0.2, 0.01], [0.0, 0.01, 0.1]])
    d, R = principal_inertia(inertia)
    np.testing.assert_allclose(R @ np.diag(d) @ R.T, inertia, atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    for axis in ([1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, -1, 0], [0.6, 0.8, 0]):
        a = np.asarray(axis, float) / np.linalg.norm(axis)
        R = axis_frame(a)
        np.testing.assert_allclose(R @ [1, 0, 0], a, atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
    assert Gf is not None
