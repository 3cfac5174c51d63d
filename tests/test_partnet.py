"""Importing PartNet-Mobility objects (``asset_pipeline.importers.partnet``) as bundles.

No real PartNet data: ``partnet_fixtures`` writes procedural objects and hand-made hard
cases in the PartNet-Mobility layout (raw y-up meshes, URDF visual origins, annotation
files), and every check undoes the importer's normalization to compare with them.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh
from partnet_fixtures import (
    BAR_CENTRE,
    BAR_RADIUS,
    KNOB_CENTRES,
    TEXTURE_COLOURS,
    JointSpec,
    LinkSpec,
    MeshSpec,
    bar_handle_door,
    box,
    cabinet_body,
    links_from_object,
    many_pieces_drawer,
    open_shell_cabinet,
    oven_with_knobs,
    write_partnet,
)
from typer.testing import CliRunner

from asset_pipeline.importers import find_sources, import_path
from asset_pipeline.importers.partnet import (
    PartnetFormatError,
    PartnetOptions,
    convert_object,
    find_objects,
    import_objects,
)
from asset_pipeline.importers.source_format import ImportFormatError
from generator.articulated import ArticulatedObject
from generator.bundle import load_bundle, save_bundle
from generator.procedural import sample_object

UNIT = 0.6  # metres per raw unit in the fixtures (partnet_fixtures.write_partnet default)
MODEL_CAT = {
    "cabinet": "StorageFurniture",
    "desk": "Table",
    "microwave": "Microwave",
    "oven": "Oven",
    "refrigerator": "Refrigerator",
    "dishwasher": "Dishwasher",
    "washing_machine": "WashingMachine",
}


def metric(obj: ArticulatedObject, unit: float = UNIT):
    """Map normalized object-frame points of an imported object back to the fixture's metres."""
    *c, s = obj.provenance["normalization"]
    return lambda p: unit * (np.asarray(p, float) * s + np.asarray(c))


def metres(obj: ArticulatedObject, unit: float = UNIT) -> float:
    return unit * obj.provenance["normalization"][3]


def write_procedural(
    folder: Path, category: str, seed: int, **kw
) -> tuple[Path, ArticulatedObject]:
    obj = sample_object(category, seed)
    write_partnet(folder, links_from_object(obj), model_cat=MODEL_CAT[category], **kw)
    return folder, obj


def line_distance(p: np.ndarray, q: np.ndarray, axis: np.ndarray) -> float:
    """Distance between the parallel lines through p and q along axis."""
    d = p - q
    return float(np.linalg.norm(d - (d @ axis) * axis))


# --------------------------------------------------------------------------- round trip


@pytest.mark.parametrize(
    ("category", "seed"),
    [("cabinet", 0), ("oven", 1), ("refrigerator", 0), ("desk", 0), ("microwave", 1)],
)
def test_procedural_round_trip(tmp_path: Path, category: str, seed: int) -> None:
    folder, orig = write_procedural(tmp_path / "obj", category, seed)
    obj = convert_object(folder)
    back, m = metric(obj), metres(obj)
    assert obj.category == category and obj.scale is None
    assert [p.name for p in obj.parts] == [p.name for p in orig.parts]
    assert np.allclose(back(obj.bounds()), orig.bounds(), atol=1e-4)
    for o in orig.parts:
        p = obj.part(o.name)
        assert p.semantic == (o.semantic if o.joint else "base")
        assert np.allclose(back(p.mesh.bounds), o.mesh.bounds, atol=1e-4), o.name
        if o.joint is None:
            assert p.joint is None
            continue
        assert p.joint.type == o.joint.type
        assert np.allclose(p.joint.axis, o.joint.axis, atol=1e-6), o.name
        assert p.joint.lower == 0.0
        scale = m if o.joint.type == "prismatic" else 1.0
        assert p.joint.upper * scale == pytest.approx(o.joint.upper, abs=1e-5)
        assert line_distance(back(p.joint.origin), o.joint.origin, o.joint.axis) < 1e-4
        if o.handle is not None and o.handle.kind in ("bar", "knob"):
            assert p.handle is not None and p.handle.kind == o.handle.kind, o.name
            assert np.linalg.norm(back(p.handle.position) - o.handle.position) < 0.004
            assert abs(p.handle.axis @ o.handle.axis) > 0.99
        else:  # recessed pulls are panel geometry: no handle node
            assert p.handle is None
    prov = obj.provenance
    assert prov["importer"] == "partnet-mobility" and prov["source_category"] == MODEL_CAT[category]
    assert prov["frame"]["yaw_deg"] == 180 and prov["frame"]["front"] == "voted"
    assert set(prov["links"]) == {p.name for p in obj.parts}


def test_bundle_round_trip_and_height(tmp_path: Path) -> None:
    folder, orig = write_procedural(tmp_path / "obj", "cabinet", 0)
    written = import_objects([folder], tmp_path / "out", PartnetOptions(height=0.9))
    assert written == [tmp_path / "out" / "obj"] and not written.failures
    obj = load_bundle(written[0])
    # the closed object is 0.9 m tall once the build applies the stored scale
    assert obj.scale == pytest.approx(0.9 / np.ptp(obj.bounds()[:, 2]))
    from asset_pipeline.geometry.metric import to_metric

    built = to_metric(obj, height=2.0)  # a known scale wins over a build-time height
    assert np.ptp(built.bounds()[:, 2]) == pytest.approx(0.9, rel=1e-6)
    assert obj.provenance["height"] == 0.9 and obj.provenance["id"] == "obj"


# --------------------------------------------------------------------------- frame


@pytest.mark.parametrize("yaw", [90, 180, 270])
def test_front_found_from_the_articulation(tmp_path: Path, yaw: int) -> None:
    """An object whose front faces another side is turned so that doors and drawers open +x."""
    ref_folder, orig = write_procedural(tmp_path / "ref", "cabinet", 0)
    folder, _ = write_procedural(tmp_path / "turned", "cabinet", 0, yaw_deg=yaw)
    ref, obj = convert_object(ref_folder), convert_object(folder)
    assert obj.provenance["frame"]["yaw_deg"] == (180 - yaw) % 360
    assert obj.provenance["frame"]["front"] == "voted"
    assert np.allclose(obj.bounds(), ref.bounds(), atol=1e-6)
    for p in obj.movable_parts:
        assert np.allclose(p.joint.axis, ref.part(p.name).joint.axis, atol=1e-6)
        assert np.allclose(p.mesh.bounds, ref.part(p.name).mesh.bounds, atol=1e-6)


def test_up_without_root_rotation_and_default_front(tmp_path: Path) -> None:
    """A URDF without the root rpy is taken as raw y-up; an object without doors or drawers
    keeps the PartNet default front (raw +z -> +x)."""
    ref_folder, _ = write_procedural(tmp_path / "ref", "desk", 0)
    folder, _ = write_procedural(tmp_path / "plain", "desk", 0, root_rotation=False)
    ref, obj = convert_object(ref_folder), convert_object(folder)
    assert obj.provenance["frame"]["root_rotation_added"]
    assert any("no rotation on the URDF root chain" in w for w in obj.provenance["warnings"])
    assert np.allclose(obj.bounds(), ref.bounds(), atol=1e-6)
    body = write_partnet(tmp_path / "body", [LinkSpec("furniture_body", "heavy", cabinet_body())])
    with pytest.raises(PartnetFormatError, match="nothing to articulate"):
        convert_object(body)
    static = convert_object(body, PartnetOptions(keep_static=True))
    assert [p.name for p in static.parts] == ["base"]
    assert static.provenance["frame"] == {
        "rotation": [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]],
        "yaw_deg": 180,
        "front": "default",
        "root_rotation_added": False,
    }
    # raw +z (the body's depth 0.5 m) is +x, raw +y up is +z
    assert np.allclose(np.ptp(metric(static)(static.bounds()), axis=0), [0.5, 0.6, 0.8], atol=1e-6)


def test_negative_range_and_part_modelled_open(tmp_path: Path) -> None:
    """A range written negative flips the axis; a part modelled open is moved to its closed
    pose (lower = 0), found from where it sits inside the body."""
    folder, orig = write_procedural(
        tmp_path / "obj", "cabinet", 0, flip=(1,), open_at={1: 0.2, 5: 0.9}
    )
    obj = convert_object(folder)
    back, m = metric(obj), metres(obj)
    for o in orig.movable_parts:
        p = obj.part(o.name)
        assert p.joint.lower == 0.0 and np.allclose(p.joint.axis, o.joint.axis, atol=1e-6)
        assert p.joint.upper * (m if o.joint.type == "prismatic" else 1) == pytest.approx(
            o.joint.upper, abs=1e-5
        )
        assert np.allclose(back(p.mesh.bounds), o.mesh.bounds, atol=1e-4), o.name
    # in the flipped source coordinates the drawer closes at +0.2 m, the door at -0.9 rad
    assert obj.provenance["closed_value"]["drawer_0"] == pytest.approx(0.2 / UNIT)
    assert obj.provenance["closed_value"]["door_0"] == pytest.approx(-0.9)


def test_joint_frozen_in_the_urdf_is_restored_from_mobility_v2(tmp_path: Path) -> None:
    folder, orig = write_procedural(tmp_path / "obj", "refrigerator", 0, fixed_in_urdf=(1, 2))
    obj = convert_object(folder)
    back = metric(obj)
    assert [p.name for p in obj.parts] == ["base", "door_0", "door_1"]
    for o in orig.movable_parts:
        p = obj.part(o.name)
        assert p.joint.type == "revolute" and p.joint.upper == pytest.approx(o.joint.upper)
        assert line_distance(back(p.joint.origin), o.joint.origin, o.joint.axis) < 1e-4
    assert sorted(obj.provenance["restored_joints"]) == ["link_0", "link_1"]
    off = convert_object(folder, PartnetOptions(restore_fixed=False, keep_static=True))
    assert [p.name for p in off.parts] == ["base"]


# --------------------------------------------------------------------------- hard cases


def test_open_shell_body_and_tight_drawer_kept_as_modelled(tmp_path: Path) -> None:
    """(a) Single-sided quads, internal and degenerate faces are kept; nothing is closed."""
    links = open_shell_cabinet()
    obj = convert_object(write_partnet(tmp_path / "shell", links))
    back = metric(obj)
    base, drawer = obj.part("base"), obj.part("drawer_0")
    assert len(base.mesh.faces) == sum(len(m.mesh.faces) for m in links[0].meshes) == 16
    assert not base.mesh.is_watertight
    want = np.concatenate([m.mesh.vertices for m in links[0].meshes])
    assert np.allclose(np.sort(back(base.mesh.vertices), axis=0), np.sort(want, axis=0), atol=1e-6)
    width = np.ptp(back(drawer.mesh.vertices)[:, 1])
    assert width == pytest.approx(0.598, abs=1e-6)  # the 2 mm play survives
    assert drawer.joint.type == "prismatic" and np.allclose(drawer.joint.axis, [1, 0, 0])
    assert drawer.joint.upper * metres(obj) == pytest.approx(0.35)
    assert obj.provenance["closed_value"]["drawer_0"] == 0.0


@pytest.mark.parametrize("kind", ["bar", "knob"])
def test_modelled_handle_gives_the_grasp_point(tmp_path: Path, kind: str) -> None:
    """(b) The grasp point is on the bar (its outermost part along the door's normal,
    centred along it), the axis along the bar; a round knob is a knob."""
    obj = convert_object(write_partnet(tmp_path / kind, bar_handle_door(kind)))
    door = obj.part("door_0")
    h = door.handle
    assert h is not None and h.kind == kind
    pos = metric(obj)(h.position)
    if kind == "bar":
        assert np.linalg.norm(pos - BAR_CENTRE) < BAR_RADIUS  # on the bar, not on a standoff
        assert abs(h.axis @ [0, 0, 1]) > 0.999
    else:
        disc = np.array([0.25 + 0.018 + 0.02 + 0.0075, BAR_CENTRE[1], BAR_CENTRE[2]])
        assert np.linalg.norm(pos - disc) < 0.005
        assert abs(h.axis @ [0, 0, 1]) > 0.999  # the door's long side
    assert door.joint.type == "revolute" and np.allclose(door.joint.axis, [0, 0, -1])
    # the handle moves out (+x) when the door opens
    moved = door.joint.transform(0.3)[:3, :3] @ (h.position - door.joint.origin)
    assert moved[0] > (h.position - door.joint.origin)[0]


def test_part_of_dozens_of_disconnected_pieces(tmp_path: Path) -> None:
    """(c) 5 drawer boxes + 36 studs in three OBJ files stay 41 separate pieces in one mesh."""
    links = many_pieces_drawer()
    obj = convert_object(write_partnet(tmp_path / "studs", links))
    drawer = obj.part("drawer_0")
    pieces = trimesh.graph.connected_components(
        drawer.mesh.face_adjacency, nodes=np.arange(len(drawer.mesh.faces))
    )
    assert len(pieces) == 41
    assert len(drawer.mesh.faces) == sum(len(m.mesh.faces) for m in links[1].meshes)
    assert obj.provenance["links"]["drawer_0"] == ["link_0"]


def test_oven_knobs_and_button_stay_on_the_body(tmp_path: Path) -> None:
    """(d) Knobs on continuous joints and a button with 2 mm travel merge into the base."""
    links = oven_with_knobs()
    obj = convert_object(write_partnet(tmp_path / "oven", links, model_cat="Oven"))
    assert obj.category == "oven"
    assert [p.name for p in obj.parts] == ["base", "door_0"]
    base, door = obj.part("base"), obj.part("door_0")
    assert sorted(obj.provenance["links"]["base"]) == sorted(
        ["base", "link_1", "link_2", "link_3", "link_4", "link_5", "link_6"]
    )
    back = metric(obj)
    verts = back(base.mesh.vertices)
    for c in KNOB_CENTRES:  # every knob's geometry is in the base, where it was modelled
        assert np.min(np.linalg.norm(verts - c, axis=1)) < 0.03
    assert door.joint.type == "revolute" and np.allclose(door.joint.axis, [0, 1, 0])
    assert door.handle is not None and door.handle.kind == "bar"
    assert np.linalg.norm(back(door.handle.position) - [0.36, 0.0, 0.68]) < 0.008
    assert base.material == door.material == "metal"
    links[1].meshes[0].node = "glass"  # a door that is mostly glass panes
    glassy = convert_object(write_partnet(tmp_path / "glassy", links, model_cat="Oven"))
    assert glassy.part("door_0").material == "glass" and glassy.base.material == "metal"


def test_tiny_and_unknown_movable_parts_are_merged(tmp_path: Path) -> None:
    body = cabinet_body()
    tiny = LinkSpec(
        "drawer",
        "slider",
        [MeshSpec(box([0.2, -0.1, 0.3], [0.25, 0.1, 0.4]))],
        JointSpec("prismatic", np.array([0, 0, 0.35]), np.array([1.0, 0, 0]), 0.0, 0.004),
    )
    wheel = LinkSpec(
        "wheel",
        "hinge",
        [MeshSpec(box([0.1, -0.3, 0.0], [0.2, -0.25, 0.05]))],
        JointSpec("revolute", np.array([0.15, 0, 0.02]), np.array([0, 1.0, 0]), 0.0, 6.0),
    )
    obj = convert_object(
        write_partnet(tmp_path / "o", [LinkSpec("furniture_body", "heavy", body), tiny, wheel]),
        PartnetOptions(keep_static=True),
    )
    assert [p.name for p in obj.parts] == ["base"]
    assert any("tiny range" in w for w in obj.provenance["warnings"])


# --------------------------------------------------------------------------- textures


def _surface_colours(mesh: trimesh.Trimesh, n: int = 4000) -> np.ndarray:
    """RGB at ``n`` random points of the textured mesh's faces, looked up through the UVs."""
    from trimesh.visual.color import uv_to_interpolated_color

    rng = np.random.default_rng(0)
    faces = rng.integers(0, len(mesh.faces), n)
    w = rng.dirichlet([1, 1, 1], n)
    uv = (np.asarray(mesh.visual.uv)[mesh.faces[faces]] * w[:, :, None]).sum(axis=1)
    img = mesh.visual.material.baseColorTexture
    return uv_to_interpolated_color(uv, img)[:, :3].astype(int)


def test_texture_and_colours_survive_the_bundle(tmp_path: Path) -> None:
    folder = write_partnet(tmp_path / "tex", bar_handle_door())  # body: one textured box
    written = import_objects([folder], tmp_path / "out")
    glb = written[0] / "parts" / "base.glb"
    scene = trimesh.load(glb, process=False)
    mesh = next(iter(scene.geometry.values()))
    tex = mesh.visual.material.baseColorTexture
    assert tex is not None and min(tex.size) >= 16  # an image in the GLB
    assert mesh.visual.uv is not None and len(mesh.visual.uv) == len(mesh.vertices)
    obj = load_bundle(written[0])
    base = obj.part("base")
    cols = _surface_colours(base.mesh)
    # the textured box samples the four texture colours; the four plain boxes their grey
    for c in TEXTURE_COLOURS:
        assert (np.abs(cols - c).max(axis=1) < 40).sum() >= 10, c
    assert (np.abs(cols - (120, 120, 125)).max(axis=1) < 12).mean() > 0.5
    # a part without any texture keeps its material colour as vertex colours
    door = obj.part("door_0")
    assert door.mesh.visual.kind == "vertex"
    vc = np.asarray(door.mesh.visual.vertex_colors)[:, :3]
    assert {tuple(c) for c in vc} == {(200, 200, 205), (40, 40, 40)}
    info = obj.provenance["textures"]
    assert info["base"]["atlas"] is not None and max(info["base"]["atlas"]) <= 2048
    assert info["door_0"]["atlas"] is None
    again = tmp_path / "again"
    save_bundle(obj, again)  # a loaded bundle saves and loads again with its texture
    assert load_bundle(again).part("base").mesh.visual.material.baseColorTexture is not None


def test_atlas_size_limit(tmp_path: Path) -> None:
    folder, _ = write_procedural(tmp_path / "obj", "oven", 1)
    obj = convert_object(folder, PartnetOptions(atlas_size=64))
    for name, info in obj.provenance["textures"].items():
        if info["atlas"] is not None:
            assert max(info["atlas"]) <= 64, name


# --------------------------------------------------------------------------- category


def test_category_mapping_and_override(tmp_path: Path) -> None:
    links = [LinkSpec("furniture_body", "heavy", cabinet_body())]
    for cat, want in [
        ("StorageFurniture", "cabinet"),
        ("Table", "desk"),
        ("Microwave", "microwave"),
        ("Oven", "oven"),
        ("Refrigerator", "refrigerator"),
        ("Dishwasher", "dishwasher"),
        ("WashingMachine", "washing_machine"),
        ("Chair", "unknown"),
    ]:
        obj = convert_object(
            write_partnet(tmp_path / cat, links, model_cat=cat), PartnetOptions(keep_static=True)
        )
        assert obj.category == want, cat
        assert obj.base.material == (
            "metal" if want not in ("cabinet", "desk", "unknown") else "wood"
        )
    static = PartnetOptions(keep_static=True)
    obj = convert_object(tmp_path / "Table", PartnetOptions(category="cabinet", keep_static=True))
    assert obj.category == "cabinet"
    (tmp_path / "Table" / "meta.json").unlink()
    obj = convert_object(tmp_path / "Table", static)
    assert obj.category == "unknown" and "meta.json missing" in obj.provenance["warnings"]


# --------------------------------------------------------------------------- folders, errors, CLI


def _collection(root: Path) -> dict[str, Path]:
    """Three good objects (one nested deeper) and three broken ones."""
    objs = {
        "cab": write_procedural(root / "cab", "cabinet", 0)[0],
        "fridge": write_procedural(root / "sub" / "fridge", "refrigerator", 0)[0],
        "knobs": write_partnet(root / "knobs", oven_with_knobs(), model_cat="Oven"),
    }
    bad_xml = write_partnet(root / "bad_xml", bar_handle_door())
    (bad_xml / "mobility.urdf").write_text("<robot><link name='base'>")
    no_obj = write_partnet(root / "no_obj", bar_handle_door())
    (no_obj / "textured_objs" / "original-3.obj").unlink()
    bad_joint = write_partnet(root / "bad_joint", bar_handle_door())
    urdf = (
        (bad_joint / "mobility.urdf")
        .read_text()
        .replace('<parent link="link_1"/>', '<parent link="link_9"/>')
    )
    (bad_joint / "mobility.urdf").write_text(urdf)
    return {**objs, "bad_xml": bad_xml, "no_obj": no_obj, "bad_joint": bad_joint}


def test_folder_with_broken_objects(tmp_path: Path) -> None:
    objs = _collection(tmp_path / "src")
    assert find_objects(tmp_path / "src") == sorted(objs.values())
    assert find_sources(tmp_path / "src") == sorted(objs.values())
    out = tmp_path / "out"
    result = import_path(tmp_path / "src", out)
    assert sorted(p.name for p in result) == ["cab", "fridge", "knobs"]
    msgs = {f.source.name: f.message for f in result.failures}
    assert set(msgs) == {"bad_xml", "no_obj", "bad_joint"}
    assert (
        msgs["bad_xml"].startswith(str(objs["bad_xml"] / "mobility.urdf"))
        and "not valid XML" in msgs["bad_xml"]
    )
    assert "mesh file textured_objs/original-3.obj not found" in msgs["no_obj"]
    assert "parent link 'link_9' is not defined" in msgs["bad_joint"]
    for name in ("bad_xml", "no_obj", "bad_joint"):  # nothing half-written
        assert not (out / name).exists()
    for d in result:
        assert load_bundle(d).provenance["importer"] == "partnet-mobility"
    # a second run refuses to overwrite, per object, unless asked
    again = import_path(tmp_path / "src", out)
    assert list(again) == [] and len(again.failures) == 6
    assert any("a bundle already exists" in f.message for f in again.failures)
    from asset_pipeline.importers.diffuse_tree import ImportOptions

    assert len(import_path(tmp_path / "src", out, ImportOptions(overwrite=True))) == 3


def test_errors_name_the_file(tmp_path: Path) -> None:
    folder = write_partnet(tmp_path / "o", bar_handle_door())
    (folder / "mobility_v2.json").write_text("{ nope")
    with pytest.raises(PartnetFormatError, match=r"mobility_v2.json: not readable JSON"):
        convert_object(folder)
    (folder / "mobility_v2.json").unlink()
    (folder / "semantics.txt").write_text("link_0 hinge\n")
    with pytest.raises(PartnetFormatError, match=r"semantics.txt: line 1: expected"):
        convert_object(folder)
    (folder / "semantics.txt").unlink()
    urdf = (folder / "mobility.urdf").read_text()
    (folder / "mobility.urdf").write_text(
        urdf.replace('filename="textured_objs/original-0.obj"', 'filename="../../etc/passwd"')
    )
    with pytest.raises(PartnetFormatError, match="outside the object folder"):
        convert_object(folder)
    (folder / "mobility.urdf").write_text(
        re.sub(r'<axis xyz="[^"]*"/>', '<axis xyz="0 0 0"/>', urdf)
    )
    with pytest.raises(PartnetFormatError, match="zero vector"):
        convert_object(folder)
    with pytest.raises(
        ImportFormatError, match="no CAGE/SINGAPO/PAct object.json .* or PartNet-Mobility"
    ):
        find_sources(_empty(tmp_path))
    # without semantics.txt and mobility_v2.json the v2-less link names are still enough
    (folder / "mobility.urdf").write_text(urdf)
    obj = convert_object(folder, PartnetOptions(keep_static=True))
    assert "semantics.txt missing" in obj.provenance["warnings"]


def _empty(tmp_path: Path) -> Path:
    d = tmp_path / "empty"
    d.mkdir()
    (d / "notes.json").write_text("{}")
    return d


def test_mixed_folder_dispatch(tmp_path: Path) -> None:
    """A folder holding a SINGAPO object.json and a PartNet-Mobility folder imports both."""
    write_procedural(tmp_path / "src" / "pn", "desk", 0)
    sg = tmp_path / "src" / "sg"
    sg.mkdir()
    trimesh.creation.box([1, 1, 1]).export(sg / "0.ply")
    trimesh.creation.box(
        [0.5, 0.5, 0.1], trimesh.transformations.translation_matrix([0, 0, 0.55])
    ).export(sg / "1.ply")
    node = lambda i, p, n, j, **k: {"id": i, "parent": p, "name": n, "joint": j, **k}  # noqa: E731
    tree = [
        node(0, -1, "base", {"type": "fixed"}, plys=["0.ply"]),
        node(
            1,
            0,
            "drawer",
            {
                "type": "prismatic",
                "range": [0, 0.3],
                "axis": {"origin": [0, 0, 0], "direction": [0, 0, 1]},
            },
            plys=["1.ply"],
        ),
    ]
    (sg / "object.json").write_text(
        json.dumps({"meta": {"obj_cat": "Table"}, "diffuse_tree": tree})
    )
    result = import_path(tmp_path / "src", tmp_path / "out")
    assert [p.name for p in result] == ["pn", "sg"] and not result.failures
    assert load_bundle(result[0]).provenance["importer"] == "partnet-mobility"
    assert load_bundle(result[1]).provenance["importer"] == "diffuse_tree"
    assert find_sources(tmp_path / "src" / "pn" / "mobility.urdf") == [tmp_path / "src" / "pn"]


def test_cli_import(tmp_path: Path) -> None:
    from pact_cli.main import app

    runner = CliRunner()
    objs = _collection(tmp_path / "src")
    good = tmp_path / "good"
    good.mkdir()
    shutil.copytree(objs["cab"], good / "cab")
    res = runner.invoke(
        app,
        [
            "import",
            str(good),
            "--out",
            str(tmp_path / "o1"),
            "--height",
            "1.2",
            "--category",
            "desk",
        ],
    )
    assert res.exit_code == 0, res.output
    assert res.stdout.split() == [str(tmp_path / "o1" / "cab")]
    obj = load_bundle(tmp_path / "o1" / "cab")
    assert obj.category == "desk" and obj.scale == pytest.approx(1.2 / np.ptp(obj.bounds()[:, 2]))

    res = runner.invoke(app, ["import", str(tmp_path / "src"), "--out", str(tmp_path / "o2")])
    assert res.exit_code == 1
    out = " ".join(res.output.split())
    for name in ("cab", "fridge", "knobs"):
        assert str(tmp_path / "o2" / name) in res.stdout
    assert f"failed {objs['bad_xml'] / 'mobility.urdf'}: not valid XML" in out
    assert "mesh file textured_objs/original-3.obj not found" in out
    assert "imported 3 of 6 objects; 3 failed" in out

    bad = tmp_path / "bad"
    bad.mkdir()
    shutil.copytree(objs["bad_xml"], bad / "bad_xml")
    res = runner.invoke(app, ["import", str(bad), "--out", str(tmp_path / "o3")])
    assert res.exit_code == 2 and "failed" in res.output and res.stdout == ""
    res = runner.invoke(app, ["import", str(_empty(tmp_path)), "--out", str(tmp_path / "o4")])
    assert res.exit_code == 2 and "error:" in res.output
    res = runner.invoke(app, ["import", str(good), "--out", str(tmp_path / "o5"), "--height", "-1"])
    assert res.exit_code == 2 and "height" in res.output


def test_nested_part_rerooted_and_continuous_door(tmp_path: Path) -> None:
    """A drawer hanging off a door is re-rooted onto the base; a continuous door is revolute."""
    xf = 0.25
    door = LinkSpec(
        "rotation_door",
        "hinge",
        [MeshSpec(box([xf, -0.29, 0.42], [xf + 0.02, 0.29, 0.78]))],
        JointSpec("continuous", np.array([xf, -0.29, 0.0]), np.array([0.0, 0.0, -1.0])),
    )
    drawer = LinkSpec(
        "drawer",
        "slider",
        [MeshSpec(box([-0.2, -0.28, 0.05], [xf, 0.28, 0.35]))],
        JointSpec("prismatic", np.array([0, 0, 0.2]), np.array([1.0, 0, 0]), 0.0, 0.3),
        parent=1,
    )
    links = [LinkSpec("furniture_body", "heavy", cabinet_body()), door, drawer]
    obj = convert_object(write_partnet(tmp_path / "o", links))
    assert [p.name for p in obj.parts] == ["base", "door_0", "drawer_0"]
    assert obj.part("door_0").joint.type == "revolute"
    assert obj.part("door_0").joint.upper == pytest.approx(math.pi / 2)
    assert obj.part("drawer_0").joint.parent == "base"
    warnings = " ".join(obj.provenance["warnings"])
    assert "re-rooted onto base" in warnings and "continuous door" in warnings


def test_failed_write_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import asset_pipeline.importers.partnet as pn

    def broken_save(obj: ArticulatedObject, directory: Path) -> Path:
        (Path(directory) / "parts").mkdir(parents=True)
        (Path(directory) / "parts" / "base.glb").write_bytes(b"partial")
        raise OSError(28, "No space left on device", str(Path(directory) / "parts" / "door_0.glb"))

    monkeypatch.setattr(pn, "save_bundle", broken_save)
    folder = write_partnet(tmp_path / "o", bar_handle_door())
    result = import_objects([folder], tmp_path / "out")
    assert list(result) == [] and not (tmp_path / "out" / "o").exists()
    assert result.failures[0].message.endswith("door_0.glb: No space left on device")


# --------------------------------------------------------------------------- handles on the geometry, added grips


def test_bar_inside_the_door_mesh_is_found(tmp_path: Path) -> None:
    """A bar modelled in the door's own mesh (no handle node): the surface standing out of
    the door's face is the handle, on the bar, away from the hinge, the mesh untouched."""
    links = bar_handle_door()
    for ms in links[1].meshes:  # one "door_frame" leaf: the bar is just more door
        ms.node, ms.group = "door_frame", "door"
    obj = convert_object(write_partnet(tmp_path / "door", links))
    door = obj.part("door_0")
    h = door.handle
    assert h is not None and h.kind == "bar"
    pos = metric(obj)(h.position)
    assert np.linalg.norm(pos - BAR_CENTRE) < BAR_RADIUS  # on the bar, not on a standoff
    assert abs(h.axis @ [0, 0, 1]) > 0.999  # along the bar (and the hinge)
    assert abs(pos[1] - (-0.29)) > 0.45  # the hinge is at y = -0.29, the bar at y = 0.22
    record = obj.provenance["handles"]["door_0"]
    assert record["source"] == "geometry" and record["kind"] == "bar"
    assert len(door.mesh.faces) == sum(len(m.mesh.faces) for m in links[1].meshes)
    assert not any("grip" in w for w in obj.provenance["warnings"])


def _flush_drawer() -> list[LinkSpec]:
    """A 0.4 m cabinet with one drawer whose front is a flat panel: no handle anywhere."""
    xf = 0.25
    front = box([xf - 0.015, -0.28, 0.05], [xf, 0.28, 0.35])
    sides = [
        box([xf - 0.4, -0.28, 0.05], [xf - 0.015, 0.28, 0.062]),
        box([xf - 0.4, -0.28, 0.062], [xf - 0.015, -0.268, 0.3]),
        box([xf - 0.4, 0.268, 0.062], [xf - 0.015, 0.28, 0.3]),
    ]
    meshes = [MeshSpec(front, node="drawer_front", color=(150, 40, 40))]
    meshes += [MeshSpec(m, node="drawer_box", color=(90, 90, 90)) for m in sides]
    return [
        LinkSpec("furniture_body", "heavy", cabinet_body(height=0.4), name="frame"),
        LinkSpec(
            "drawer",
            "slider",
            meshes,
            JointSpec("prismatic", np.array([0.0, 0.0, 0.2]), np.array([1.0, 0.0, 0.0]), 0.0, 0.3),
            name="drawer",
        ),
    ]


def test_flush_drawer_gets_a_grip_that_collides(tmp_path: Path) -> None:
    """A drawer without any handle gets a bar grip centred on its front (in its visual mesh,
    in the drawer's colour, recorded); the build gives the grip collision boxes."""
    from asset_pipeline.assets.build import BuildOptions, build_asset
    from asset_pipeline.assets.folder import load_asset

    links = _flush_drawer()
    src = write_partnet(tmp_path / "src" / "flush", links)
    written = import_objects([src], tmp_path / "out")
    assert len(written) == 1 and not written.failures
    assert any("drawer_0: no handle modelled; added a" in w for w in written.warnings)
    obj = load_bundle(written[0])
    drawer = obj.part("drawer_0")
    h = drawer.handle
    assert h is not None and h.kind == "bar" and abs(h.axis @ [0, 1, 0]) > 0.999
    record = obj.provenance["handles"]["drawer_0"]
    assert record["source"] == "added" and record["on_surface"]
    assert record["length_cm"] == 12.0 and "centred on the front" in record["where"]
    # centred on the front, standing off it (the category height makes it 0.9/0.4 larger)
    back = metric(obj)
    pos = back(h.position)
    assert np.allclose(pos[1:], [0.0, 0.2], atol=0.005)
    grow = 0.4 / 0.9
    assert pos[0] - 0.25 == pytest.approx(0.033 * grow, abs=0.002)
    # the grip is in the drawer's visual mesh, in the front's colour, standoffs to the face
    n_src = sum(len(m.mesh.faces) for m in links[1].meshes)
    assert len(drawer.mesh.faces) == n_src + 36  # a bar and two standoffs: 3 boxes
    added = np.unique(drawer.mesh.faces[n_src:])  # the grip's vertices
    grip = back(drawer.mesh.vertices[added])
    assert np.ptp(grip[:, 1]) == pytest.approx(0.12 * grow, abs=1e-3)
    assert grip[:, 0].max() - 0.25 == pytest.approx((0.033 + 0.008) * grow, abs=1e-3)
    assert grip[:, 0].min() == pytest.approx(0.25 - 0.002 * grow)  # standoffs 2 mm into the front
    colours = np.asarray(drawer.mesh.visual.vertex_colors)[added, :3]
    assert {tuple(c) for c in colours} == {(150, 40, 40)}
    # the build: a collision piece holds the bar's middle and both ends
    result = build_asset(written[0], options=BuildOptions(cache_dir=tmp_path / "cache"))
    asset = load_asset(result.directory, metadata=False)
    bar = asset.handles["drawer_0"]
    assert bar.kind == "bar"
    pieces = [trimesh.load(f) for f in result.directory.glob("collision/drawer_0_*.obj")]
    for t in (-0.04, 0.0, 0.04):
        p = bar.position_link + t * bar.axis
        assert any(pc.contains([p])[0] for pc in pieces), t
    visual = trimesh.load(result.directory / "visual" / "drawer_0.obj", force="mesh")
    assert visual.bounds[1][0] >= bar.position_link[0] + 0.005  # the bar is drawn


def test_no_added_grips_keeps_the_mesh(tmp_path: Path) -> None:
    """add_handles=False (``pact import --no-add-handles``): no grip, no handle."""
    from pact_cli.main import app

    links = _flush_drawer()
    src = write_partnet(tmp_path / "src" / "flush", links)
    obj = convert_object(src, PartnetOptions(add_handles=False))
    drawer = obj.part("drawer_0")
    assert drawer.handle is None and obj.provenance["handles"]["drawer_0"] is None
    assert len(drawer.mesh.faces) == sum(len(m.mesh.faces) for m in links[1].meshes)
    assert not any("grip" in w for w in obj.provenance["warnings"])
    res = CliRunner().invoke(
        app, ["import", str(src), "--out", str(tmp_path / "o"), "--no-add-handles"]
    )
    assert res.exit_code == 0, res.output
    assert load_bundle(tmp_path / "o" / "flush").part("drawer_0").handle is None
    res = CliRunner().invoke(app, ["import", str(src), "--out", str(tmp_path / "o2")])
    assert res.exit_code == 0 and "grip" in res.output and "drawer_0" in res.output
    assert load_bundle(tmp_path / "o2" / "flush").part("drawer_0").handle.kind == "bar"


def test_flush_door_gets_a_grip_near_its_free_edge(tmp_path: Path) -> None:
    """A plain door panel: the grip stands near the edge away from the hinge, along it."""
    links = bar_handle_door()
    links[1].meshes = links[1].meshes[:1]  # the panel only
    obj = convert_object(write_partnet(tmp_path / "door", links))
    h = obj.part("door_0").handle
    assert h is not None and h.kind == "bar" and abs(h.axis @ [0, 0, 1]) > 0.999
    pos = metric(obj)(h.position)
    grow = 0.8 / 0.9  # the cabinet is 0.8 m tall, the grip sized for the default 0.9 m
    # hinge at y = -0.29, free edge at y = 0.29: 5 cm in from it, at mid-height
    assert np.allclose(pos[1:], [0.29 - 0.05 * grow, 0.40], atol=0.003)
    assert pos[0] - (0.25 + 0.018) == pytest.approx(0.033 * grow, abs=0.002)
    assert "5 cm from the free edge, parallel to the hinge" in " ".join(obj.provenance["warnings"])


def _door_as(links: list[LinkSpec], mesh: trimesh.Trimesh) -> list[LinkSpec]:
    """``links`` of :func:`bar_handle_door` with the door's meshes replaced by ``mesh``."""
    links[1].meshes = [MeshSpec(mesh, node="door_frame")]
    return links


def test_degenerate_part_meshes_are_refused_or_warned_naming_the_obj(tmp_path: Path) -> None:
    xf, corners = 0.25, [[0.25, -0.29, 0.02], [0.25, 0.29, 0.02], [0.25, 0.29, 0.78]]
    line = np.array([[xf, -0.29, 0.02], [xf, 0.29, 0.78], [xf, 0.0, 0.4]])  # collinear
    folder = write_partnet(
        tmp_path / "line", _door_as(bar_handle_door(), trimesh.Trimesh(line, [[0, 1, 2]] * 3))
    )
    with pytest.raises(PartnetFormatError) as e:
        convert_object(folder)
    assert str(e.value).startswith(
        f"{folder / 'mobility.urdf'}: door_0: mesh textured_objs/original-0.obj: "
        "all of its 3 faces have zero area"
    )
    result = import_objects([folder], tmp_path / "out")
    assert not result and "original-0.obj" in result.failures[0].message
    sheet = trimesh.Trimesh(corners + [[0.25, -0.29, 0.78]], [[0, 1, 2], [0, 2, 3]])
    folder = write_partnet(tmp_path / "flat", _door_as(bar_handle_door(), sheet))
    result = import_objects([folder], tmp_path / "out")
    (warning,) = [w for w in result.warnings if "mesh textured_objs" in w]
    assert warning.startswith(f"{folder}: door_0: mesh textured_objs/original-0.obj: only 2 faces")
    assert "flat" in warning
    obj = load_bundle(result[0])
    assert obj.provenance["meshes"]["door_0"] == ["textured_objs/original-0.obj"]
    clean = import_objects([write_partnet(tmp_path / "ok", bar_handle_door())], tmp_path / "o2")
    assert not [w for w in clean.warnings if "mesh textured_objs" in w]
