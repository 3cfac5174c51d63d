"""End to end: bundle -> built asset (files, URDF in yourdfpy and SAPIEN, MJCF in MuJoCo).

The test cabinet is made here (the procedural factory is not a dependency of these
tests): a carcass of six boxes open at the front (+x) with a shelf, a drawer (an
open box with primitives, its mesh missing two triangles so it needs repair) in
the lower compartment, and a side-hinged door with a knob and NO primitives (CoACD)
in the upper one. It is stored in normalized units (``scale=None``) and built with
``height=0.8`` so the built asset has the design dimensions below, in metres.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from asset_pipeline.assets.build import BuildError, BuildOptions, build_asset
from asset_pipeline.assets.folder import load_asset
from asset_pipeline.assets.rig import fallback_handle
from asset_pipeline.geometry.coacd_collision import MAX_HULL_VERTICES
from asset_pipeline.simulation.sapien_scenes import (
    collision_shape_counts,
    load_articulation,
    make_scene,
)
from generator.articulated import (
    ArticulatedObject,
    Handle,
    Joint,
    ObjectModelError,
    Part,
    Primitive,
)
from generator.bundle import save_bundle

H = 0.8  # design height (m)
DRAWER_UPPER = 0.30
DOOR_UPPER = 1.5


def _box(lo, hi) -> Primitive:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    T = np.eye(4)
    T[:3, 3] = (lo + hi) / 2
    return Primitive("box", hi - lo, T)


def _mesh(prims: list[Primitive], rgba) -> trimesh.Trimesh:
    m = trimesh.util.concatenate([p.to_mesh() for p in prims])
    m.visual.face_colors = rgba
    return m


def design_cabinet() -> ArticulatedObject:
    """The test cabinet in metres (frame convention), before normalization."""
    carcass = [
        _box([-0.25, -0.30, 0.00], [0.25, 0.30, 0.02]),  # bottom
        _box([-0.25, -0.30, 0.78], [0.25, 0.30, 0.80]),  # top
        _box([-0.25, -0.30, 0.02], [0.25, -0.28, 0.78]),  # left
        _box([-0.25, 0.28, 0.02], [0.25, 0.30, 0.78]),  # right
        _box([-0.25, -0.28, 0.02], [-0.23, 0.28, 0.78]),  # back
        _box([-0.23, -0.28, 0.39], [0.25, 0.28, 0.41]),  # shelf
    ]
    drawer = [
        _box([0.23, -0.275, 0.025], [0.25, 0.275, 0.385]),  # front
        _box([-0.20, -0.265, 0.03], [0.23, 0.265, 0.04]),  # bottom
        _box([-0.20, -0.27, 0.03], [0.23, -0.265, 0.30]),  # left
        _box([-0.20, 0.265, 0.03], [0.23, 0.27, 0.30]),  # right
        _box([-0.21, -0.27, 0.03], [-0.20, 0.27, 0.30]),  # back
    ]
    drawer_mesh = _mesh(drawer, [150, 100, 60, 255])
    # a hole: drop the two triangles of the front panel's +x face -> needs repair
    front_faces = np.where(
        (drawer_mesh.face_normals[:, 0] > 0.99) & (drawer_mesh.triangles_center[:, 0] > 0.249)
    )[0]
    assert len(front_faces) == 2
    keep = np.ones(len(drawer_mesh.faces), bool)
    keep[front_faces] = False
    drawer_mesh.update_faces(keep)
    assert not drawer_mesh.is_watertight

    door_panel = trimesh.creation.box(extents=[0.02, 0.55, 0.36])
    door_panel.apply_translation([0.24, 0.0, 0.595])
    knob = trimesh.creation.box(extents=[0.04, 0.03, 0.08])
    knob.apply_translation([0.27, 0.22, 0.595])
    door_mesh = trimesh.boolean.union([door_panel, knob], engine="manifold")
    door_mesh.visual.face_colors = [200, 200, 210, 255]

    parts = [
        Part("base", "base", _mesh(carcass, [120, 80, 50, 255]), primitives=carcass),
        Part(
            "drawer_0",
            "drawer",
            drawer_mesh,
            joint=Joint("prismatic", [0.25, 0.0, 0.205], [1, 0, 0], 0.0, DRAWER_UPPER),
            primitives=drawer,
            handle=Handle([0.27, 0.0, 0.30], [0, 1, 0], "bar"),
        ),
        Part(
            "door_0",
            "door",
            door_mesh,
            joint=Joint("revolute", [0.25, -0.28, 0.595], [0, 0, -1], 0.0, DOOR_UPPER),
            material="plastic",
        ),
    ]
    return ArticulatedObject(parts, category="cabinet", scale=1.0)


def normalized_cabinet() -> ArticulatedObject:
    """The design cabinet scaled by 1/H into the unit cube, z centred, ``scale=None``."""
    from asset_pipeline.geometry.metric import transform_object

    obj = transform_object(design_cabinet(), 1.0 / H, np.array([0.0, 0.0, -0.5]))
    obj.scale = None
    return obj


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("assets")
    bundle = save_bundle(normalized_cabinet(), root / "cab_test")
    opts = BuildOptions(cache_dir=root / "coacd-cache", collision="coacd")  # CoACD is tested here
    t0 = time.perf_counter()
    result = build_asset(bundle, height=H, options=opts)
    first = time.perf_counter() - t0
    return result, opts, first


def test_layout_and_asset_json(built):
    result, _, _ = built
    d = result.directory
    assert result.id == "cab_test"
    meta = json.loads((d / "asset.json").read_text())
    assert meta["schema"] == "pact.asset" and meta["version"] == 1
    assert meta["category"] == "cabinet"
    assert meta["metric_scale"] == pytest.approx(H)
    np.testing.assert_allclose(meta["bounds"], [[-0.25, -0.30, 0.0], [0.29, 0.30, 0.80]], atol=1e-4)
    assert [link["name"] for link in meta["links"]] == ["base", "drawer_0", "door_0"]
    for link in meta["links"]:
        assert (d / link["visual"]).is_file()
        assert (d / "visual" / f"{link['name']}.obj").is_file()
        assert len(link["collision"]) == result.pieces[link["name"]] >= 1
        assert all((d / c).is_file() for c in link["collision"])
        assert link["mass"] > 0
    assert result.pieces["base"] == 6 and result.pieces["drawer_0"] == 5  # the primitives
    assert result.pieces["door_0"] >= 2  # CoACD splits the panel and its knob
    joints = {j["name"]: j for j in meta["joints"]}
    dj = joints["joint_drawer_0"]
    assert dj["type"] == "prismatic" and dj["parent"] == "base" and dj["child"] == "drawer_0"
    assert dj["upper"] == pytest.approx(DRAWER_UPPER)  # prismatic limit scaled back to metres
    np.testing.assert_allclose(dj["origin"], [0.25, 0.0, 0.205], atol=1e-5)
    assert joints["joint_door_0"]["upper"] == pytest.approx(DOOR_UPPER)  # radians unchanged
    # drawer keeps its modelled handle; the door gets the fallback near the free edge
    hd = meta["handles"]["drawer_0"]
    np.testing.assert_allclose(hd["position"], [0.27, 0.0, 0.30], atol=1e-5)
    np.testing.assert_allclose(
        np.subtract(hd["position"], dj["origin"]), hd["position_link"], atol=1e-6
    )
    door = meta["handles"]["door_0"]
    assert door["kind"] == "none"
    assert door["position"][0] == pytest.approx(0.29, abs=1e-3)  # knob's front face
    assert 0.15 < door["position"][1] < 0.28  # toward the edge opposite the hinge (y=-0.28)
    # no temporary files left behind
    assert not [p for p in d.rglob("*") if p.name.endswith(".tmp")]


def test_collision_files_are_bounded_convex_hulls(built):
    result, _, _ = built
    for path in sorted((result.directory / "collision").glob("*.obj")):
        m = trimesh.load(path, force="mesh", process=True)
        assert 4 <= len(m.vertices) <= MAX_HULL_VERTICES, path
        assert m.is_volume and m.volume > 0, path
        hull = m.convex_hull
        assert hull.volume == pytest.approx(m.volume, rel=1e-6), path  # convex


def test_coacd_pieces_cover_the_door(built):
    result, opts, _ = built
    d = result.directory
    pieces = [trimesh.load(p, force="mesh") for p in sorted((d / "collision").glob("door_0_*.obj"))]
    door = trimesh.load(d / "visual" / "door_0.obj", force="mesh")
    assert sum(p.volume for p in pieces) == pytest.approx(door.volume, rel=0.15)
    np.testing.assert_allclose(
        np.array([p.bounds for p in pieces])[:, 0].min(0), door.bounds[0], atol=0.01
    )
    assert len(list(Path(opts.cache_dir).glob("*.npz"))) == 1  # one CoACD result cached


def test_pieces_in_link_frame(built):
    result, _, _ = built
    d = result.directory
    # drawer front panel in the drawer's link frame: origin at (0.25, 0, 0.205)
    pieces = [
        trimesh.load(p, force="mesh") for p in sorted((d / "collision").glob("drawer_0_*.obj"))
    ]
    bounds = np.array([p.bounds for p in pieces])
    np.testing.assert_allclose(bounds[:, 1, 0].max(), 0.0, atol=1e-6)
    np.testing.assert_allclose(bounds[:, 0, 2].min(), 0.025 - 0.205, atol=1e-6)
    vis = trimesh.load(d / "visual" / "drawer_0.glb", force="mesh")
    np.testing.assert_allclose(vis.bounds[1, 0], 0.0, atol=1e-4)


def test_urdf_yourdfpy(built):
    import yourdfpy

    result, _, _ = built
    urdf = yourdfpy.URDF.load(str(result.urdf), load_meshes=False, build_scene_graph=False)
    assert urdf.validate()
    assert set(urdf.link_map) == {"base", "drawer_0", "door_0"}
    j = urdf.joint_map["joint_drawer_0"]
    assert j.type == "prismatic" and j.limit.upper == pytest.approx(DRAWER_UPPER)
    assert float(j.dynamics.damping) > 0 and float(j.dynamics.friction) > 0  # yourdfpy keeps text
    for link in urdf.robot.links:
        inertia = link.inertial.inertia
        eig = np.linalg.eigvalsh(inertia)
        assert link.inertial.mass > 0 and (eig > 0).all()
        assert eig[2] <= eig[0] + eig[1] + 1e-12  # triangle inequality
        assert len(link.collisions) == result.pieces[link.name]


def test_sapien_loads_with_all_shapes_and_limits(built):
    result, _, _ = built
    scene = make_scene(render=False)
    art = load_articulation(scene, load_asset(result.directory))
    assert collision_shape_counts(art) == result.pieces
    joints = {j.name: j for j in art.active_joints}
    assert set(joints) == {"joint_drawer_0", "joint_door_0"}
    assert joints["joint_drawer_0"].type == "prismatic"
    assert joints["joint_door_0"].type.startswith("revolute")
    np.testing.assert_allclose(joints["joint_drawer_0"].limits, [[0.0, DRAWER_UPPER]], atol=1e-6)
    np.testing.assert_allclose(joints["joint_door_0"].limits, [[0.0, DOOR_UPPER]], atol=1e-6)


def _simulate(urdf: Path, link_name: str, force: np.ndarray, point_fn, seconds: float = 1.0):
    scene = make_scene(render=False)
    art = load_articulation(scene, load_asset(urdf.parent))
    link = next(k for k in art.links if k.name == link_name)
    names = [j.name for j in art.active_joints]
    idx = names.index(f"joint_{link_name}")
    trace = []
    for _ in range(int(seconds / scene.timestep)):
        if force is not None:
            link.add_force_at_point(force, point_fn(link))
        scene.step()
        trace.append(float(art.qpos[idx]))
    return np.array(trace)


def test_sapien_drawer_slides_and_door_swings(built):
    result, _, _ = built
    rest = _simulate(result.urdf, "drawer_0", None, None, seconds=0.5)
    assert np.abs(rest).max() < 1e-3  # nothing drifts at rest
    drawer = _simulate(
        result.urdf, "drawer_0", np.array([20.0, 0, 0]), lambda k: k.entity_pose.p, seconds=1.0
    )
    assert drawer[-1] > 0.1
    assert drawer.min() > -1e-3 and drawer.max() < DRAWER_UPPER + 0.01
    # pull the door outward (+x) at its free edge: it swings open (positive angle)
    door = _simulate(
        result.urdf,
        "door_0",
        np.array([10.0, 0, 0]),
        lambda k: k.entity_pose.p + np.array([0.02, 0.5, 0.0]),
        seconds=1.0,
    )
    assert door[-1] > 0.3
    assert door.min() > -1e-3 and door.max() < DOOR_UPPER + 0.02


def test_mjcf_mujoco(built):
    import mujoco

    result, _, _ = built
    model = mujoco.MjModel.from_xml_path(str(result.mjcf))
    assert model.njnt == 2
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(model.njnt)]
    types = dict(zip(names, model.jnt_type, strict=True))
    assert types["joint_drawer_0"] == mujoco.mjtJoint.mjJNT_SLIDE
    assert types["joint_door_0"] == mujoco.mjtJoint.mjJNT_HINGE
    ranges = dict(zip(names, model.jnt_range.tolist(), strict=True))
    np.testing.assert_allclose(ranges["joint_drawer_0"], [0.0, DRAWER_UPPER])
    np.testing.assert_allclose(ranges["joint_door_0"], [0.0, DOOR_UPPER])
    assert model.ngeom == sum(result.pieces.values()) + 3  # + one visual geom per body
    # each visual maps its texture image (visual/<part>.png) through the OBJ's texcoords
    assert model.ntex == 3 and model.nmat == 3
    for body in ("base", "drawer_0", "door_0"):
        gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{body}_visual")
        assert model.geom_matid[gid] >= 0
        mid = model.geom_dataid[gid]
        assert model.mesh_texcoordnum[mid] > 0
        assert (result.directory / "visual" / f"{body}.png").is_file()
    assert (model.body_mass[1:] > 0).all()
    # the drawer slides in MuJoCo too when pushed along +x
    data = mujoco.MjData(model)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "drawer_0")
    for _ in range(250):
        data.xfrc_applied[bid, :3] = [20.0, 0, 0]
        mujoco.mj_step(model, data)
    assert 0.05 < data.qpos[model.jnt_qposadr[names.index("joint_drawer_0")]] <= DRAWER_UPPER + 0.01


def test_rebuild_identical_cached_and_clean(built, tmp_path, monkeypatch):
    from asset_pipeline.geometry import coacd_collision as collision

    result, opts, _ = built
    d = result.directory
    urdf_before = result.urdf.read_text()
    # a stale piece from an imagined earlier build with more pieces
    stale = d / "collision" / "base_17.obj"
    stale.write_text((d / "collision" / "base_0.obj").read_text())

    def no_coacd(*args, **kwargs):
        raise AssertionError("CoACD ran although its result is cached")

    monkeypatch.setattr(collision, "_run_coacd_subprocess", no_coacd)
    again = build_asset(d, height=H, options=opts)
    assert again.urdf.read_text() == urdf_before
    assert not stale.exists()
    assert not [p for p in d.rglob("*") if p.name.endswith(".tmp")]


def test_bad_bundles_name_the_file(built, tmp_path):
    result, _, _ = built
    broken = tmp_path / "broken"
    shutil.copytree(result.directory, broken)
    (broken / "parts" / "door_0.glb").unlink()
    with pytest.raises(ObjectModelError, match="door_0.glb"):
        build_asset(broken)
    corrupt = tmp_path / "corrupt"
    shutil.copytree(result.directory, corrupt)
    (corrupt / "object.json").write_text("{ not json")
    with pytest.raises(ObjectModelError, match="object.json"):
        build_asset(corrupt)
    assert issubclass(BuildError, ValueError)


def test_fallback_handle_prismatic_is_front_centre():
    part = design_cabinet().part("drawer_0")
    part.handle = None
    h = fallback_handle(part)
    assert h.kind == "none"
    np.testing.assert_allclose(h.position, [0.25, 0.0, 0.205], atol=1e-6)


def test_fallback_handle_uses_the_primitives_of_a_generated_part():
    """A generated part's mesh can reach past its layout box (stray fragments); the grasp
    point is on the box's front face, where the gripper meets the collision solid."""
    from generator.articulated import Primitive

    part = design_cabinet().part("drawer_0")
    part.handle = None
    lo, hi = (np.array(b) for b in part.mesh.bounds)
    T = np.eye(4)
    T[:3, 3] = (lo + hi) / 2 - [0.05, 0, 0]
    part.primitives = [Primitive("box", hi - lo, T)]
    h = fallback_handle(part)
    np.testing.assert_allclose(
        h.position, [hi[0] - 0.05, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2], atol=1e-6
    )


def test_visuals_are_light_and_physics_comes_from_the_full_meshes(tmp_path):
    """A dense base mesh (a sphere of 20k triangles over its box primitive) is built with
    a 3000-triangle budget: its visual holds no more, the URDF's collisions and inertials
    are those of the full build, and MuJoCo loads the decimated, textured visual."""
    import mujoco

    obj = design_cabinet()
    base = obj.parts[0]
    dense = trimesh.creation.icosphere(subdivisions=5, radius=0.3)
    dense.apply_translation([0.0, 0.0, 0.4])
    dense.visual.vertex_colors = [120, 80, 50, 255]
    obj.parts[0] = Part("base", "base", dense, primitives=base.primitives)
    obj.parts[2].primitives = [_box([0.23, -0.275, 0.415], [0.25, 0.275, 0.775])]
    folders = {}
    for n in (0, 3000):
        folder = save_bundle(obj, tmp_path / f"faces_{n}")
        build_asset(folder, options=BuildOptions(visual_faces=n))
        folders[n] = folder
    faces = {
        n: sum(len(trimesh.load(f / "visual" / f"{p}.glb", force="mesh").faces) for p in
               ("base", "drawer_0", "door_0"))
        for n, f in folders.items()
    }  # fmt: skip
    assert faces[0] > 20_000 and faces[3000] <= 3000
    full, light = (load_asset(folders[n]) for n in (0, 3000))
    for a, b in zip(full.links, light.links, strict=True):
        assert a.inertial.mass == pytest.approx(b.inertial.mass)
        assert [c.filename for c in a.collisions] == [c.filename for c in b.collisions]
    for name in ("base_0.obj", "door_0_0.obj"):
        assert (folders[0] / "collision" / name).read_text() == (
            folders[3000] / "collision" / name
        ).read_text()
    model = mujoco.MjModel.from_xml_path(str(folders[3000] / "model.xml"))
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "base_visual")
    assert model.mesh_facenum[model.geom_dataid[gid]] <= 3000


def test_a_part_that_cannot_be_closed_names_its_bundle_mesh_and_source_meshes(
    tmp_path, monkeypatch
):
    """An imported bundle records each part's source meshes; a part the build cannot close
    is named with them, so that a user knows which artist's file to repair."""
    from generator.mesh_repair import closing

    obj = normalized_cabinet()
    obj.provenance.update(
        source="/data/partnet/4711", meshes={"door_0": ["textured_objs/original-3.obj"]}
    )
    folder = save_bundle(obj, tmp_path / "imported")
    real = closing.watertight

    def refuse_the_door(mesh, resolution=closing.REMESH_RESOLUTION):
        if len(mesh.faces) == len(obj.part("door_0").mesh.faces):
            raise closing.MeshRepairError("voxel remesh did not give a closed volume")
        return real(mesh, resolution)

    monkeypatch.setattr(closing, "watertight", refuse_the_door)
    with pytest.raises(BuildError) as err:
        build_asset(folder, height=H, options=BuildOptions(collision="coacd"))
    message = str(err.value)
    assert "parts/door_0.glb" in message and "textured_objs/original-3.obj" in message
    assert "/data/partnet/4711" in message and "closed volume" in message
