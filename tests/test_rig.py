"""asset_pipeline.assets.rig: mass properties, the rig, URDF and MJCF text."""

from __future__ import annotations

import io

import numpy as np
import pytest
import trimesh
from lxml import etree

from asset_pipeline.assets.built_asset import JointPhysics
from asset_pipeline.assets.mjcf import mjcf_string
from asset_pipeline.assets.rig import (
    DENSITIES,
    MATERIALS,
    MaterialModel,
    PhysicsDefaults,
    build_rig,
    mass_properties,
    sanitize_inertia,
)
from asset_pipeline.assets.urdf import urdf_string
from generator.articulated import ArticulatedObject, Joint, Part


def _check_physical(inertia: np.ndarray) -> None:
    np.testing.assert_allclose(inertia, inertia.T)
    e = np.linalg.eigvalsh(inertia)
    assert (e > 0).all()
    for i in range(3):
        assert e[i] <= e.sum() - e[i] + 1e-15


def test_sanitize_inertia():
    good = np.array([[2.0, 0.1, 0.0], [0.1, 3.0, 0.0], [0.0, 0.0, 4.0]])
    np.testing.assert_allclose(sanitize_inertia(good), good, atol=1e-12)
    for bad in (np.diag([1.0, 1.0, 0.0]), np.diag([1.0, 0.1, 0.1]), np.diag([1.0, -1e-9, 1.0])):
        fixed = sanitize_inertia(bad)
        _check_physical(fixed)
        assert np.linalg.eigvalsh(fixed).max() == pytest.approx(1.0, rel=1e-3)


def test_box_mass_properties_match_closed_form():
    a, b, c = 0.5, 0.3, 0.02
    box = trimesh.creation.box([a, b, c])
    box.apply_translation([1.0, 2.0, 3.0])
    mp = mass_properties(box, 600.0)
    m = 600.0 * a * b * c
    assert mp.mass == pytest.approx(m)
    np.testing.assert_allclose(mp.com, [1.0, 2.0, 3.0], atol=1e-9)
    expected = np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) * m / 12
    np.testing.assert_allclose(mp.inertia, expected, rtol=1e-6, atol=1e-12)


def test_overlapping_bodies_count_once_and_min_mass():
    a = trimesh.creation.box([0.2, 0.2, 0.2])
    b = trimesh.creation.box([0.2, 0.2, 0.2])
    b.apply_translation([0.1, 0, 0])  # half overlaps a
    both = trimesh.util.concatenate([a, b])
    assert both.volume == pytest.approx(0.016)  # trimesh alone counts the overlap twice
    mp = mass_properties(both, 1000.0)
    assert mp.mass == pytest.approx(1000.0 * 0.3 * 0.2 * 0.2, rel=1e-6)
    np.testing.assert_allclose(mp.com, [0.05, 0, 0], atol=1e-9)
    tiny = mass_properties(trimesh.creation.box([0.01, 0.01, 0.01]), 600.0, min_mass=0.05)
    assert tiny.mass == pytest.approx(0.05)
    _check_physical(tiny.inertia)


def _box_surface_inertia(a: float, b: float, c: float, sigma: float) -> np.ndarray:
    """Closed-form inertia of the six faces of an a x b x c box, area density sigma."""
    dims = np.array([a, b, c])
    out = np.zeros(3)
    for n in range(3):  # the two faces normal to axis n, at +-dims[n] / 2
        u, v = [k for k in range(3) if k != n]
        m = 2 * sigma * dims[u] * dims[v]
        out[n] += m * (dims[u] ** 2 + dims[v] ** 2) / 12
        out[u] += m * (dims[v] ** 2 / 12 + dims[n] ** 2 / 4)
        out[v] += m * (dims[u] ** 2 / 12 + dims[n] ** 2 / 4)
    return np.diag(out)


def test_shell_model_mass_and_inertia_of_a_hollow_box():
    a, b, c = 0.7, 1.2, 0.06  # a refrigerator door
    box = trimesh.creation.box([a, b, c])
    box.apply_translation([0.1, 0.2, 0.3])
    skin = MaterialModel(density=7800.0, shell_thickness=0.001)  # no core
    mp = mass_properties(box, skin)
    area = 2 * (a * b + a * c + b * c)
    assert mp.mass == pytest.approx(7800.0 * 0.001 * area)
    np.testing.assert_allclose(mp.com, [0.1, 0.2, 0.3], atol=1e-9)
    expected = _box_surface_inertia(a, b, c, 7.8)
    np.testing.assert_allclose(mp.inertia, expected, rtol=1e-6, atol=1e-12)
    _check_physical(mp.inertia)
    # with a foam core: skin + core, still physical
    foam = mass_properties(box, MATERIALS["metal"])
    assert 8.0 < foam.mass < 15.0  # real refrigerator doors weigh 8-15 kg
    _check_physical(foam.inertia)


def test_shell_model_keeps_thin_boards_solid():
    board = trimesh.creation.box([0.02, 0.5, 0.7])  # a 20 mm cabinet door
    mp = mass_properties(board, MATERIALS["wood"])
    assert mp.mass == pytest.approx(DENSITIES["wood"] * 0.02 * 0.5 * 0.7)
    np.testing.assert_allclose(mp.inertia, mass_properties(board, 600.0).inertia)
    assert PhysicsDefaults().material("unobtainium") == MATERIALS["wood"]


def _object() -> ArticulatedObject:
    base = trimesh.creation.box([0.5, 0.6, 0.8])
    base.apply_translation([0, 0, 0.4])
    base.visual.face_colors = [255, 0, 0, 255]
    drawer = trimesh.creation.box([0.4, 0.5, 0.2])
    drawer.apply_translation([0.1, 0, 0.2])
    door = trimesh.creation.box([0.02, 0.5, 0.3])
    door.apply_translation([0.26, 0, 0.6])
    return ArticulatedObject(
        [
            Part("base", "base", base),
            Part(
                "drawer_0",
                "drawer",
                drawer,
                joint=Joint("prismatic", [0.3, 0.0, 0.2], [1, 0, 0], 0.0, 0.3),
                material="metal",
            ),
            Part(
                "door_0",
                "door",
                door,
                joint=Joint("revolute", [0.27, -0.25, 0.6], [0, 0, -1], 0.0, 1.5),
            ),
        ],
        category="cabinet",
    )


def _pieces(obj: ArticulatedObject, counts: dict[str, int]) -> dict[str, list[trimesh.Trimesh]]:
    """``counts[part]`` copies of each part's convex hull, as collision pieces."""
    return {p.name: [p.mesh.convex_hull] * counts[p.name] for p in obj.parts}


def test_build_rig_frames_masses_and_files():
    obj = _object()
    physics = PhysicsDefaults(prismatic=JointPhysics(damping=3.0, friction=0.2, velocity=0.5))
    rig = build_rig(obj, _pieces(obj, {"base": 1, "drawer_0": 2, "door_0": 1}), "cab", physics)
    assert [link.name for link in rig.links] == ["base", "drawer_0", "door_0"]
    drawer = rig.link("drawer_0")
    assert [p.filename for p in drawer.collisions] == [
        "collision/drawer_0_0.obj",
        "collision/drawer_0_1.obj",
    ]
    assert drawer.visuals[0].filename == "visual/drawer_0.glb"
    assert drawer.visuals[0].obj_filename == "visual/drawer_0.obj"
    # meshes are in the link frame: the drawer's box centre minus its joint origin
    np.testing.assert_allclose(
        drawer.collisions[0].mesh.bounds.mean(0), [0.1 - 0.3, 0, 0.2 - 0.2], atol=1e-7
    )
    metal = MATERIALS["metal"]  # a closed 0.4 x 0.5 x 0.2 metal box is a skin around foam
    area, volume = 2 * (0.4 * 0.5 + 0.4 * 0.2 + 0.5 * 0.2), 0.4 * 0.5 * 0.2
    skin = area * metal.shell_thickness
    expected = metal.density * skin + metal.core_density * (volume - skin)
    assert drawer.inertial.mass == pytest.approx(expected)
    np.testing.assert_allclose(drawer.inertial.com, [0.1 - 0.3, 0, 0], atol=1e-7)  # link frame
    np.testing.assert_allclose(rig.link("base").rgba, [1, 0, 0, 1])
    j = {x.name: x for x in rig.joints}
    assert j["joint_drawer_0"].physics.damping == 3.0  # override applies
    assert j["joint_door_0"].physics == PhysicsDefaults().revolute
    np.testing.assert_allclose(j["joint_door_0"].origin[:3, 3], [0.27, -0.25, 0.6])
    # handles: the door has none modelled, so the fallback point, in the link frame
    assert set(rig.handles) == {"drawer_0", "door_0"}
    assert rig.handles["door_0"].kind == "none"


def test_a_heavy_drawer_gets_less_friction_so_a_pull_opens_it():
    obj = _object()  # its drawer: a 0.4 x 0.5 x 0.2 metal box, about 5 kg
    pieces = _pieces(obj, {"base": 1, "drawer_0": 1, "door_0": 1})
    physics = PhysicsDefaults(prismatic=JointPhysics(damping=3.0, friction=0.2, velocity=0.5))
    rig = build_rig(obj, pieces, "cab", physics)
    mass = rig.link("drawer_0").inertial.mass
    assert 0.2 * mass * 9.81 < 15.0  # a light drawer keeps its friction
    assert {j.name: j for j in rig.joints}["joint_drawer_0"].physics.friction == 0.2
    # the same drawer allowed only 5 N of friction: the coefficient times its weight is 5 N
    strict = PhysicsDefaults(
        prismatic=JointPhysics(damping=3.0, friction=0.2, velocity=0.5), max_slide_friction=5.0
    )
    joint = {j.name: j for j in build_rig(obj, pieces, "cab", strict).joints}["joint_drawer_0"]
    assert joint.physics.friction * mass * 9.81 == pytest.approx(5.0)
    assert joint.physics.damping == 3.0


def test_mass_comes_from_the_primitives_when_a_part_has_them():
    """A generated part: a small fragment of mesh, a layout box as its collision solid.
    Its mass is the box's (wood: a 19 mm skin around air), not the fragment's."""
    from generator.articulated import Primitive

    obj = _object()
    door = obj.part("door_0")
    fragment = trimesh.creation.box([0.02, 0.05, 0.05])
    fragment.apply_translation([0.26, -0.2, 0.6])
    T = np.eye(4)
    T[:3, 3] = [0.24, 0, 0.6]
    door.mesh = fragment
    door.primitives = [Primitive("box", [0.06, 0.5, 0.3], T)]
    rig = build_rig(obj, _pieces(obj, {"base": 1, "drawer_0": 1, "door_0": 1}), "cab")
    area = 2 * (0.06 * 0.5 + 0.06 * 0.3 + 0.5 * 0.3)
    mass = rig.link("door_0").inertial
    assert mass.mass == pytest.approx(
        MATERIALS["wood"].density * MATERIALS["wood"].shell_thickness * area
    )
    np.testing.assert_allclose(mass.com, np.array([0.24, 0, 0.6]) - [0.27, -0.25, 0.6], atol=1e-7)


def test_damping_of_a_tiny_part_is_capped_by_its_inertia():
    """A 5 cm wooden flap on a vertical hinge: its moment of inertia about the hinge,
    by hand, over min_damping_time; the ordinary door and the drawer keep the defaults."""
    obj = _object()
    flap = trimesh.creation.box([0.01, 0.05, 0.05])
    flap.apply_translation([0.265, 0.3, 0.6])
    obj.parts.append(
        Part(
            "door_1", "door", flap, joint=Joint("revolute", [0.27, 0.275, 0.6], [0, 0, 1], 0.0, 1.5)
        )
    )
    rig = build_rig(obj, _pieces(obj, {"base": 1, "drawer_0": 1, "door_0": 1, "door_1": 1}), "cab")
    j = {x.name: x for x in rig.joints}
    m = DENSITIES["wood"] * 0.01 * 0.05 * 0.05  # thinner than two skins: solid
    m = max(m, PhysicsDefaults().min_mass)
    izz = m * (0.01**2 + 0.05**2) / 12 + m * (0.005**2 + 0.025**2)  # + parallel axis
    assert j["joint_door_1"].physics.damping == pytest.approx(izz / 0.01, rel=1e-6)
    assert j["joint_door_0"].physics == PhysicsDefaults().revolute
    assert j["joint_drawer_0"].physics == PhysicsDefaults().prismatic


def test_urdf_text_is_valid_and_complete():
    import yourdfpy

    obj = _object()
    rig = build_rig(obj, _pieces(obj, {"base": 3, "drawer_0": 2, "door_0": 1}), "cab")
    text = urdf_string(rig)
    assert text == urdf_string(rig)  # deterministic
    urdf = yourdfpy.URDF.load(io.BytesIO(text.encode()), load_meshes=False, build_scene_graph=False)
    assert urdf.validate()
    assert len(urdf.link_map["base"].collisions) == 3
    assert urdf.link_map["drawer_0"].visuals[0].geometry.mesh.filename == "visual/drawer_0.glb"
    door = urdf.joint_map["joint_door_0"]
    assert door.type == "revolute" and door.parent == "base" and door.child == "door_0"
    np.testing.assert_allclose(door.axis, [0, 0, -1])
    assert (door.limit.lower, door.limit.upper) == (0.0, 1.5)
    assert door.limit.effort == 100.0 and door.limit.velocity == 2.0
    inertial = urdf.link_map["drawer_0"].inertial
    np.testing.assert_allclose(inertial.origin[:3, 3], [-0.2, 0, 0], atol=1e-7)
    _check_physical(inertial.inertia)


def test_mjcf_compiles_in_mujoco():
    import mujoco

    obj = _object()
    counts = {"base": 1, "drawer_0": 1, "door_0": 1}
    rig = build_rig(obj, _pieces(obj, counts), "cab")
    assets = {}
    for p in obj.parts:
        m = rig.link(p.name).visuals[0].mesh
        text = trimesh.exchange.obj.export_obj(m, include_color=False, include_texture=False)
        assets[f"visual/{p.name}.obj"] = text.encode()
        assets[f"collision/{p.name}_0.obj"] = text.encode()
    xml = mjcf_string(rig)
    root = etree.fromstring(xml.encode())
    assert root.find("worldbody/body").get("name") == "base"
    assert root.find("worldbody/body/freejoint") is None
    model = mujoco.MjModel.from_xml_string(xml, assets)
    assert model.njnt == 2 and model.nbody == 4
    assert list(model.jnt_type) == [mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_HINGE]
    np.testing.assert_allclose(model.jnt_range, [[0.0, 0.3], [0.0, 1.5]])
    np.testing.assert_allclose(model.dof_damping, [2.0, 0.5])
    drawer_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "drawer_0")
    assert model.body_mass[drawer_id] == pytest.approx(rig.link("drawer_0").inertial.mass)
    visual = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "base_visual")
    assert model.geom_contype[visual] == 0 and model.geom_conaffinity[visual] == 0
    # the drawer body sits at its joint origin in the world
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.xpos[drawer_id], [0.3, 0.0, 0.2], atol=1e-9)
