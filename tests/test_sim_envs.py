"""sim_envs: asset sources (folder, catalog) and loading a built asset into a ManiSkill scene."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from asset_fixtures import write_box_cabinet

from asset_pipeline.catalog.registry import AssetRecord, Catalog
from sim_envs import AssetSourceError, CatalogSource, FolderSource, open_source, read_task_asset


@pytest.fixture()
def asset_dir(tmp_path: Path) -> Path:
    write_box_cabinet(tmp_path / "cab_drawer", "prismatic", "cab_drawer")
    write_box_cabinet(tmp_path / "cab_door", "revolute", "cab_door")
    write_box_cabinet(tmp_path / "mw_door", "revolute", "mw_door", category="microwave")
    bad = write_box_cabinet(tmp_path / "bad", "prismatic", "bad")
    (bad / "report.json").write_text(json.dumps({"schema": "pact.validation", "status": "failed"}))
    (tmp_path / "not_an_asset").mkdir()
    return tmp_path


def test_read_asset_parts_and_handles(asset_dir: Path) -> None:
    rec = read_task_asset(asset_dir / "cab_door")
    assert rec.id == "cab_door" and rec.category == "cabinet"
    (part,) = rec.movable_parts()
    assert (
        part.name == "door_0"
        and part.joint_type == "revolute"
        and part.joint_name == "joint_door_0"
    )
    assert part.range == pytest.approx(1.57)
    assert part.handle_object[0] == pytest.approx(part.handle_link[0] + 0.2)


def test_folder_source_filters_and_skips_failed(asset_dir: Path) -> None:
    assert [r.id for r in FolderSource(asset_dir)] == ["cab_door", "cab_drawer", "mw_door"]
    assert [r.id for r in FolderSource(asset_dir, joint_type="prismatic")] == ["cab_drawer"]
    assert [r.id for r in FolderSource(asset_dir, category="microwave")] == ["mw_door"]
    assert [r.id for r in open_source(asset_dir / "cab_drawer")] == ["cab_drawer"]
    with pytest.raises(AssetSourceError, match="no usable asset"):
        FolderSource(asset_dir, category="oven").require()


def test_catalog_source(asset_dir: Path) -> None:
    with Catalog(asset_dir) as cat:
        for aid, status, path in [
            ("cab_drawer", "ok", "cab_drawer"),
            ("cab_door", "repaired", str(asset_dir / "cab_door")),
            ("mw_door", "ok", "mw_door"),
            ("bad", "failed", "bad"),
        ]:
            cat.upsert_asset(AssetRecord(id=aid, status=status, path=str(asset_dir / path)))
    db = asset_dir / "registry.sqlite"
    src = open_source(db)
    assert isinstance(src, CatalogSource)
    assert [r.id for r in src] == ["cab_door", "cab_drawer", "mw_door"]
    assert [r.id for r in open_source(db, category="cabinet", joint_type="revolute")] == [
        "cab_door"
    ]


def test_sources_skip_hidden_and_damaged_folders(asset_dir: Path) -> None:
    """A hidden folder (a set-aside asset) is never used; an asset whose URDF lost a
    collision file path to outside the folder is skipped with the reason logged."""
    write_box_cabinet(asset_dir / ".previous" / "cab_drawer", "prismatic", "old")
    write_box_cabinet(asset_dir / ".hidden_asset", "prismatic", "hidden")
    urdf = asset_dir / "cab_drawer" / "model.urdf"
    urdf.write_text(urdf.read_text().replace("collision/drawer_0_0.obj", "/etc/hosts"))
    assert [r.id for r in FolderSource(asset_dir)] == ["cab_door", "mw_door"]
    with pytest.raises(AssetSourceError, match="absolute"):
        read_task_asset(asset_dir / "cab_drawer")


def test_load_asset_in_maniskill_scene(asset_dir: Path) -> None:
    """The env loads the asset with a fixed base, every collision shape, and the shared options."""
    import gymnasium as gym

    import tasks  # noqa: F401
    from asset_pipeline.simulation.sim_options import DEFAULT_SIM_OPTIONS
    from sim_envs.scene import count_collision_shapes

    env = gym.make(
        "OpenDrawer-v0",
        assets=asset_dir / "cab_drawer",
        sim_backend="physx_cpu",
        render_backend="none",
    )
    try:
        env.reset(seed=0)
        u = env.unwrapped
        obj = u.object._objs[0]
        assert obj.root.entity.components  # built
        assert obj.get_links()[0].name.endswith("base")
        counts = count_collision_shapes(u.object)
        assert counts[next(k for k in counts if k.endswith("base"))] == 5
        assert counts[next(k for k in counts if k.endswith("drawer_0"))] == 5
        shape = obj.get_links()[1].collision_shapes[0]
        assert shape.physical_material.static_friction == pytest.approx(
            DEFAULT_SIM_OPTIONS.static_friction
        )
        # the URDF's joint friction, not PhysX's default 0.05 (SAPIEN's builder drops it)
        (joint,) = obj.get_active_joints()
        assert joint.friction == pytest.approx(0.02)
        # the front of the object faces the robot: the robot base is on the +x side
        assert float(u.agent.robot.pose.p[0, 0]) > 0.5
        # a fixed base does not move under gravity
        p0 = u.object.pose.p.clone()
        for _ in range(10):
            env.step(env.action_space.sample() * 0)
        assert float((u.object.pose.p - p0).abs().max()) < 1e-6
    finally:
        env.close()


def test_joint_names_match_by_suffix() -> None:
    from asset_pipeline.simulation.sim_options import match_joint_name

    names = ["joint_door_0", "joint_door_10", "joint_drawer_0"]
    assert match_joint_name("joint_door_0", names) == "joint_door_0"  # SAPIEN keeps names
    assert match_joint_name("scene-0-object-0_joint_door_0", names) == "joint_door_0"
    assert match_joint_name("scene-0-object-0_joint_door_10", names) == "joint_door_10"
    assert match_joint_name("scene-0-object-0_xjoint_door_0", names) is None
    assert match_joint_name("joint_lid_0", names) is None


def test_handle_world_positions_rotates_by_the_link_quaternion() -> None:
    """Hand-computed: a link at (1, 0, 0.5) turned 90 degrees about +z carries the
    link-frame point (0.1, 0, 0.2) to (1, 0.1, 0.7); a second link unrotated."""
    import torch

    from sim_envs.scene import handle_world_positions

    h = float(np.sqrt(0.5))
    p = torch.tensor([[1.0, 0.0, 0.5], [0.0, 0.0, 0.0]])
    q = torch.tensor([[h, 0.0, 0.0, h], [1.0, 0.0, 0.0, 0.0]])
    v = torch.tensor([[0.1, 0.0, 0.2], [0.3, -0.2, 0.1]])
    out = handle_world_positions(p, q, v).numpy()
    np.testing.assert_allclose(out, [[1.0, 0.1, 0.7], [0.3, -0.2, 0.1]], atol=1e-6)


def test_floor_lift_of_a_door_that_swings_through_the_floor() -> None:
    """An oven door hinged 3 cm above its bottom edge and 3 cm behind its front face
    (hinge at z = 0.03, so the door's bottom rests on the floor): its front-bottom edge
    (+0.03, -0.03 from the hinge) turns about +y and dips to -0.03 (sin t + cos t), lowest
    -0.03 sqrt(2) at 45 degrees, i.e. 0.03 (sqrt(2) - 1) = 12.4 mm below the floor. A
    drawer (prismatic, level) never dips."""
    from asset_pipeline.assets.built_asset import BuiltAsset, CollisionPiece, Joint, Link
    from sim_envs.scene import FLOOR_CLEARANCE, floor_lift

    def piece(lo: list[float], hi: list[float]) -> CollisionPiece:
        import trimesh

        return CollisionPiece("unused.obj", mesh=trimesh.creation.box(bounds=[lo, hi]))

    origin = np.eye(4)
    origin[:3, 3] = [0.3, 0.0, 0.03]
    base = Link("base", collisions=[piece([-0.3, -0.3, 0.0], [0.28, 0.3, 0.9])])
    door = Link("door_0", collisions=[piece([-0.01, -0.28, -0.03], [0.03, 0.28, 0.7])])
    hinge = Joint("joint_door_0", "revolute", "base", "door_0", origin, [0, 1, 0], 0.0, np.pi / 2)
    oven = BuiltAsset("oven", [base, door], [hinge])
    expected = 0.03 * (np.sqrt(2) - 1) + FLOOR_CLEARANCE
    assert floor_lift(oven) == pytest.approx(expected, abs=2e-4)
    slide = Joint("joint_door_0", "prismatic", "base", "door_0", origin, [1, 0, 0], 0.0, 0.3)
    assert floor_lift(BuiltAsset("chest", [base, door], [slide])) == 0.0
