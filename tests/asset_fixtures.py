"""Small built assets written through the asset model, for tests that need one on disk."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from asset_pipeline.assets.built_asset import (
    BuiltAsset,
    CollisionPiece,
    Handle,
    Inertial,
    Joint,
    JointPhysics,
    Link,
    Visual,
)
from asset_pipeline.assets.folder import save_asset
from asset_pipeline.validate import Check, RepairRecord, Report, write_report


def box(size: list[float], xyz: list[float]) -> trimesh.Trimesh:
    return trimesh.creation.box(
        extents=size, transform=trimesh.transformations.translation_matrix(xyz)
    )


def box_link(name: str, semantic: str, mass: float, boxes: list[trimesh.Trimesh]) -> Link:
    """A link whose visual is the union of ``boxes`` and whose pieces are the boxes."""
    return Link(
        name=name,
        semantic=semantic,
        inertial=Inertial(mass, np.zeros(3), np.eye(3) * 0.05),
        visuals=[Visual(f"visual/{name}.glb", mesh=trimesh.util.concatenate(boxes))],
        collisions=[
            CollisionPiece(f"collision/{name}_{k}.obj", mesh=b) for k, b in enumerate(boxes)
        ],
    )


def movable(
    name: str, joint_type: str, origin: list[float], axis: list[float], upper: float
) -> Joint:
    pivot = np.eye(4)
    pivot[:3, 3] = origin
    return Joint(
        f"joint_{name}",
        joint_type,
        "base",
        name,
        origin=pivot,
        axis=axis,
        upper=upper,
        physics=JointPhysics(damping=1.0, friction=0.02, effort=100.0, velocity=1.0),
    )


def write_box_cabinet(
    folder: Path, joint_type: str = "prismatic", aid: str = "fixture_0", category: str = "cabinet"
) -> Path:
    """A box carcass with one drawer (prismatic) or one door hinged on its left edge
    (revolute), a bar handle; one convex piece per box, geometry in the link frames."""
    W, D, H, t = 0.5, 0.4, 0.6, 0.02
    base = [
        box([D, W, t], [0, 0, t / 2]),
        box([D, W, t], [0, 0, H - t / 2]),
        box([D, t, H], [0, -W / 2 + t / 2, H / 2]),
        box([D, t, H], [0, W / 2 - t / 2, H / 2]),
        box([t, W, H], [-D / 2 + t / 2, 0, H / 2]),
    ]
    if joint_type == "prismatic":
        name, origin, axis, upper = "drawer_0", [0.0, 0.0, 0.0], [1, 0, 0], 0.3
        geom = [
            box([0.02, W - 0.05, H - 0.05], [D / 2 - 0.01, 0, H / 2]),
            box([D - 0.06, W - 0.08, 0.01], [0.0, 0, 0.06]),
            box([0.02, 0.12, 0.015], [D / 2 + 0.04, 0, H * 0.75]),
            box([0.04, 0.015, 0.015], [D / 2 + 0.02, -0.055, H * 0.75]),
            box([0.04, 0.015, 0.015], [D / 2 + 0.02, 0.055, H * 0.75]),
        ]
        handle_link, handle_axis = [D / 2 + 0.04, 0.0, H * 0.75], [0, 1, 0]
    else:
        name, origin, axis, upper = "door_0", [D / 2, W / 2, 0.0], [0, 0, 1], 1.57
        geom = [
            box([0.02, W - 0.01, H - 0.01], [0.01, -W / 2, H / 2]),
            box([0.02, 0.015, 0.14], [0.06, -W + 0.06, H / 2]),
            box([0.04, 0.015, 0.015], [0.03, -W + 0.06, H / 2 + 0.05]),
            box([0.04, 0.015, 0.015], [0.03, -W + 0.06, H / 2 - 0.05]),
        ]
        handle_link, handle_axis = [0.06, -W + 0.06, H / 2], [0, 0, 1]
    asset = BuiltAsset(
        id=aid,
        links=[box_link("base", "base", 10.0, base), box_link(name, name[:-2], 2.0, geom)],
        joints=[movable(name, joint_type, origin, axis, upper)],
        handles={name: Handle(handle_link, handle_axis, "bar")},
        category=category,
        bounds=np.array([[-D / 2, -W / 2, 0], [D / 2, W / 2, H]]),
    )
    save_asset(asset, folder)
    return folder


def write_two_part_cabinet(
    folder: Path, aid: str, status: str | None = "ok", category: str = "cabinet"
) -> Path:
    """A 0.6 x 0.8 x 0.9 m cabinet with a drawer (12 kg base, 1.5 kg drawer, 0..0.35 m)
    and a door (2 kg, 0..1.57 rad), and, unless ``status`` is None, a report.json of
    that status with three checks (``rest_drift`` fails when the status is failed)."""
    asset = BuiltAsset(
        id=aid,
        links=[
            box_link("base", "base", 12.0, [box([0.6, 0.8, 0.9], [0, 0, 0.45])]),
            box_link("drawer_0", "drawer", 1.5, [box([0.5, 0.3, 0.2], [-0.25, 0, 0])]),
            box_link("door_0", "door", 2.0, [box([0.02, 0.4, 0.5], [0.01, 0.2, 0])]),
        ],
        joints=[
            movable("drawer_0", "prismatic", [0.3, 0, 0.4], [1, 0, 0], 0.35),
            movable("door_0", "revolute", [0.3, -0.4, 0.6], [0, 0, 1], 1.57),
        ],
        handles={
            "drawer_0": Handle([0.02, 0, 0], [0, 1, 0], "bar"),
            "door_0": Handle([0.02, 0.35, 0], [0, 0, 1], "bar"),
        },
        category=category,
        bounds=np.array([[-0.3, -0.4, 0.0], [0.3, 0.4, 0.9]]),
    )
    save_asset(asset, folder)
    if status is not None:
        checks = [
            Check("sapien_load", "load", "asset", True, "loaded", "loads"),
            Check(
                "rest_drift",
                "dynamic",
                "joint_door_0",
                status != "failed",
                0.004,
                0.002,
                "" if status != "failed" else "base drifts",
            ),
            Check("drive_reach", "dynamic", "joint_drawer_0", True, [0.0, 0.35], "range"),
        ]
        repairs = (
            [RepairRecord("add_damping", "joint_door_0", 0.5, 1.0, "rest_drift[joint_door_0]")]
            if status == "repaired"
            else []
        )
        write_report(Report(asset=aid, status=status, checks=checks, repairs=repairs), folder)
    return folder


def write_task_assets(root: Path) -> Path:
    """Procedural objects built into ``root`` for the tasks: a desk with drawers, a
    microwave with a side-hinged door, an oven with a bottom-hinged door and a fridge
    with two side-hinged doors."""
    from asset_pipeline.assets.build import build_asset
    from generator.bundle import save_bundle
    from generator.procedural import object_id, sample_object

    for category, seed in (("desk", 0), ("microwave", 1), ("oven", 0), ("refrigerator", 0)):
        build_asset(save_bundle(sample_object(category, seed), root / object_id(category, seed)))
    return root
