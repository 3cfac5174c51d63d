"""Procedural objects of every category build into assets that yourdfpy, MuJoCo and SAPIEN load."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest
import yourdfpy

from asset_pipeline.assets.build import build_asset
from asset_pipeline.simulation.sapien_scenes import (
    collision_shape_counts,
    load_articulation,
    make_scene,
)
from generator.bundle import save_bundle
from generator.procedural import CATEGORIES, object_id, sample_object

SEEDS = (11, 12)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("procedural_assets")
    out = {}
    for cat in CATEGORIES:
        for seed in SEEDS:
            obj = sample_object(cat, seed)
            d = save_bundle(obj, root / object_id(cat, seed))
            out[(cat, seed)] = (obj, build_asset(d))
    return out


@pytest.mark.parametrize("cat", CATEGORIES)
def test_urdf_mjcf_and_sapien_agree_with_the_object(built, cat):
    for seed in SEEDS:
        obj, res = built[(cat, seed)]
        movable = {p.name: p.joint for p in obj.movable_parts}
        # yourdfpy: loads, validates, joint types and limits as generated.
        urdf = yourdfpy.URDF.load(str(res.urdf), build_scene_graph=False, load_meshes=False)
        assert urdf.validate()
        for name, joint in movable.items():
            j = urdf.joint_map[f"joint_{name}"]
            assert j.type == joint.type
            assert np.allclose(j.axis, joint.axis, atol=1e-6)
            assert j.limit.upper - j.limit.lower == pytest.approx(joint.range, rel=1e-6)
        # One <collision> per convex piece.
        tree = ET.parse(res.urdf)
        for link in tree.getroot().iter("link"):
            assert len(link.findall("collision")) == res.pieces[link.get("name")]
        # MuJoCo: the MJCF loads with one joint per movable part and the same ranges.
        model = mujoco.MjModel.from_xml_path(str(res.mjcf))
        assert model.njnt == len(movable)
        for k in range(model.njnt):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, k)
            part = name.removeprefix("joint_")
            joint = movable[part]
            kind = {
                int(mujoco.mjtJoint.mjJNT_SLIDE): "prismatic",
                int(mujoco.mjtJoint.mjJNT_HINGE): "revolute",
            }
            assert kind[int(model.jnt_type[k])] == joint.type
            assert model.jnt_range[k][1] - model.jnt_range[k][0] == pytest.approx(
                joint.range, rel=1e-5
            )
        # SAPIEN: every piece cooked (none silently dropped), joint limits as written.
        scene = make_scene(render=False)
        art = load_articulation(scene, res.asset, fix_root=True)
        assert collision_shape_counts(art) == res.pieces
        limits = {j.name: j.limits[0] for j in art.active_joints}
        for name, joint in movable.items():
            lo, hi = limits[f"joint_{name}"]
            assert hi - lo == pytest.approx(joint.range, rel=1e-5)
