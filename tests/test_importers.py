"""Importing CAGE/SINGAPO/PAct ``diffuse_tree`` objects as bundles."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from asset_pipeline.importers import find_sources, import_path
from asset_pipeline.importers.diffuse_tree import ImportOptions, convert_tree
from asset_pipeline.importers.source_format import ImportFormatError
from generator.bundle import load_bundle


def _box(path: Path, extents, centre) -> str:
    """Write a box mesh (source frame) and return its path relative to the object folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    m = trimesh.creation.box(extents=extents)
    m.apply_translation(centre)
    m.export(path)
    return path.relative_to(path.parent.parent).as_posix()


def _node(
    nid, parent, name, jtype="fixed", origin=(0, 0, 0), direction=(0, 0, 0), rng=(0, 0), **files
):
    return {
        "id": nid,
        "parent": parent,
        "name": name,
        "children": [],
        "aabb": {"center": [0, 0, 0], "size": [0, 0, 0]},
        "joint": {
            "type": jtype,
            "range": list(rng),
            "axis": {"origin": list(origin), "direction": list(direction)},
        },
        **files,
    }


def make_singapo(folder: Path, door_range=(-90.0, 0.0), extra=None) -> Path:
    """A SINGAPO-style cabinet in the source frame (+y up, front +z): body, door, drawer+handle."""
    folder.mkdir(parents=True, exist_ok=True)
    base = _box(folder / "plys" / "0.ply", (1.0, 1.2, 0.5), (0, 0.6, 0))
    door = _box(folder / "plys" / "1.ply", (0.48, 0.6, 0.02), (-0.25, 0.85, 0.26))
    drawer = _box(folder / "plys" / "2.ply", (0.9, 0.3, 0.45), (0, 0.3, 0.03))
    handle = _box(folder / "plys" / "3.ply", (0.2, 0.03, 0.03), (0, 0.3, 0.27))
    nodes = [
        _node(0, -1, "base", plys=[base]),
        _node(1, 0, "door", "revolute", (-0.49, 0.85, 0.27), (0, 1, 0), door_range, plys=[door]),
        _node(2, 0, "drawer", "prismatic", (0, 0.3, 0.03), (0, 0, 1), (0, 0.35), plys=[drawer]),
        _node(3, 2, "handle", "fixed", plys=[handle]),
    ]
    nodes += extra or []
    data = {"meta": {"obj_cat": "StorageFurniture"}, "diffuse_tree": nodes}
    (folder / "object.json").write_text(json.dumps(data))
    return folder / "object.json"


def test_singapo_object_becomes_a_bundle(tmp_path: Path) -> None:
    make_singapo(tmp_path / "src" / "StorageFurniture@45290@01")
    out = tmp_path / "out"
    written = import_path(tmp_path / "src", out)
    assert written == [out / "StorageFurniture_45290_01"]
    obj = load_bundle(written[0])
    assert obj.category == "cabinet" and obj.scale is None
    assert [p.name for p in obj.parts] == ["base", "door_0", "drawer_0"]

    # Normalized into the unit cube, +z up: the body is 1.2 tall (largest extent).
    b = obj.bounds()
    assert np.allclose(b[1] - b[0], np.array([0.535, 1.0, 1.2]) / 1.2, atol=1e-5)
    assert np.allclose((b[0] + b[1]) / 2, 0, atol=1e-6)
    s = obj.provenance["normalization"][3]
    assert s == pytest.approx(1.2)

    drawer = obj.part("drawer_0")
    assert np.allclose(drawer.joint.axis, [1, 0, 0])  # source +z front -> +x
    assert drawer.joint.upper == pytest.approx(0.35 / 1.2)
    assert len(drawer.mesh.vertices) == 16  # the fixed handle is merged into the drawer

    door = obj.part("door_0")
    # range [-90, 0] about +y opens toward negative angles: flipped to [0, pi/2] about -z
    assert np.allclose(door.joint.axis, [0, 0, -1])
    assert (door.joint.lower, door.joint.upper) == pytest.approx((0.0, math.pi / 2))
    opened = door.posed_mesh(door.joint.upper)
    assert opened.bounds[1, 0] > door.mesh.bounds[1, 0] + 0.2  # swings out of the front (+x)
    # hinge in our frame: source (-0.49, 0.85, 0.27) -> (0.27, -0.49, 0.85), then normalized
    c = np.array(obj.provenance["normalization"][:3])
    assert np.allclose(door.joint.origin * s + c, [0.27, -0.49, 0.85], atol=1e-6)


def test_positive_range_keeps_axis_and_z_up_option(tmp_path: Path) -> None:
    src = make_singapo(tmp_path / "a", door_range=(0.0, 120.0))
    obj = convert_tree(src)
    assert np.allclose(obj.part("door_0").joint.axis, [0, 0, 1])
    assert obj.part("door_0").joint.upper == pytest.approx(math.radians(120))
    obj_z = convert_tree(src, ImportOptions(up="z"))
    assert np.allclose(obj_z.part("drawer_0").joint.axis, [0, 0, 1])  # taken as is


def test_pact_export_layout_with_glb_meshes(tmp_path: Path) -> None:
    run = tmp_path / "outputs" / "run" / "exported_arti_objects"
    for k, oid in enumerate(("Microwave@7128@01", "Oven@101@02")):
        folder = run / oid
        base = _box(folder / "glb" / "part_0.glb", (0.6, 0.4, 0.4), (0, 0.2, 0))
        door = _box(folder / "glb" / "part_1.glb", (0.5, 0.3, 0.02), (0, 0.2, 0.21))
        nodes = [
            _node(0, -1, "base", glb=[base], plys=["ply/missing.ply"]),
            _node(1, 0, "door", "revolute", (0, 0.05, 0.22), (-1, 0, 0), (0, 80 + k), glb=[door]),
        ]
        (folder / "object.json").write_text(
            json.dumps({"meta": {"obj_cat": oid.split("@")[0]}, "diffuse_tree": nodes})
        )
    assert len(find_sources(tmp_path / "outputs")) == 2
    written = import_path(tmp_path / "outputs", tmp_path / "out")
    assert [p.name for p in written] == ["Microwave_7128_01", "Oven_101_02"]
    objs = [load_bundle(p) for p in written]
    assert [o.category for o in objs] == ["microwave", "oven"]
    # a bottom-hinged door (source axis -x) in our frame: axis -y
    assert np.allclose(objs[0].part("door_0").joint.axis, [0, -1, 0])
    with pytest.raises(ImportFormatError, match="already exists"):
        import_path(tmp_path / "outputs", tmp_path / "out")
    assert (
        len(import_path(tmp_path / "outputs", tmp_path / "out", ImportOptions(overwrite=True))) == 2
    )


def test_screw_is_refused_by_default_and_continuous_mapped(tmp_path: Path) -> None:
    folder = tmp_path / "obj"
    knob = _box(folder / "plys" / "9.ply", (0.05, 0.05, 0.02), (0.3, 1.0, 0.26))
    src = make_singapo(
        folder,
        extra=[_node(9, 0, "knob", "screw", (0.3, 1.0, 0.26), (0, 0, 1), (0, 0.01), plys=[knob])],
    )
    with pytest.raises(ImportFormatError) as e:
        convert_tree(src)
    msg = str(e.value)
    assert str(src) in msg and "diffuse_tree[4].joint.type" in msg and "screw" in msg
    obj = convert_tree(src, ImportOptions(screw="prismatic"))
    assert obj.part("knob_0").joint.type == "prismatic"
    assert len(convert_tree(src, ImportOptions(screw="fixed")).parts) == 3

    data = json.loads(src.read_text())
    data["diffuse_tree"][4]["joint"]["type"] = "continuous"
    src.write_text(json.dumps(data))
    knob_j = convert_tree(src).part("knob_0").joint
    assert knob_j.type == "revolute" and knob_j.upper == pytest.approx(2 * math.pi)
    with pytest.raises(ImportFormatError, match="continuous"):
        convert_tree(src, ImportOptions(continuous="error"))


def test_movable_grandchild_is_rerooted_onto_base(tmp_path: Path) -> None:
    folder = tmp_path / "obj"
    inner = _box(folder / "plys" / "5.ply", (0.2, 0.1, 0.1), (0, 0.3, 0.1))
    src = make_singapo(
        folder,
        extra=[
            _node(5, 2, "drawer", "prismatic", (0, 0.3, 0.1), (0, 0, 1), (0, 0.1), plys=[inner])
        ],
    )
    obj = convert_tree(src)
    assert [p.name for p in obj.parts] == ["base", "door_0", "drawer_0", "drawer_1"]
    assert obj.part("drawer_1").joint.parent == "base"


@pytest.mark.parametrize(
    "mutate, field",
    [
        (
            lambda d: d["diffuse_tree"][1]["plys"].__setitem__(0, "plys/nope.ply"),
            "diffuse_tree[1].plys",
        ),
        (
            lambda d: d["diffuse_tree"][2]["joint"]["axis"].__setitem__("direction", [0, 0]),
            "direction",
        ),
        (lambda d: d["diffuse_tree"][1].__setitem__("parent", 42), "diffuse_tree[1].parent"),
        (lambda d: d["diffuse_tree"][1].__setitem__("parent", -1), "exactly one root"),
        (
            lambda d: d["diffuse_tree"][1]["joint"].__setitem__("type", "ball"),
            "diffuse_tree[1].joint.type",
        ),
        (lambda d: d["diffuse_tree"][2]["joint"].__setitem__("range", "far"), "joint.range"),
        (lambda d: d.pop("diffuse_tree"), "diffuse_tree"),
    ],
)
def test_errors_name_file_and_field(tmp_path: Path, mutate, field: str) -> None:
    src = make_singapo(tmp_path / "obj")
    data = json.loads(src.read_text())
    mutate(data)
    src.write_text(json.dumps(data))
    with pytest.raises(ImportFormatError) as e:
        import_path(src, tmp_path / "out")
    assert str(src) in str(e.value) and field in str(e.value)
    assert not (tmp_path / "out").exists()  # nothing half-written


@pytest.mark.parametrize("where", ["relative", "absolute", "symlink"])
def test_meshes_outside_the_object_folder_are_refused(tmp_path: Path, where: str) -> None:
    """As for PartNet-Mobility objects (the same rule): an object reads only its own files."""
    src = make_singapo(tmp_path / "obj")
    outside = tmp_path / "elsewhere.ply"
    trimesh.creation.box(extents=(0.4, 0.5, 0.02)).export(outside)
    if where == "relative":
        path = "../elsewhere.ply"
    elif where == "absolute":
        path = str(outside)
    else:
        (tmp_path / "obj" / "plys" / "link.ply").symlink_to(outside)
        path = "plys/link.ply"
    data = json.loads(src.read_text())
    data["diffuse_tree"][1]["plys"] = [path]
    src.write_text(json.dumps(data))
    with pytest.raises(ImportFormatError) as e:
        import_path(src, tmp_path / "out")
    assert str(e.value).startswith(
        f"{src}: diffuse_tree[1].plys: mesh {path!r} lies outside the object folder"
    )
    assert not (tmp_path / "out").exists()


def _door_mesh(src: Path, mesh: trimesh.Trimesh) -> Path:
    """Replace the door's mesh of :func:`make_singapo`'s object (plys/1.ply)."""
    path = src.parent / "plys" / "1.ply"
    mesh.export(path)
    return path


#: Three corners of the door's front (source frame), in the order of its quad.
DOOR = [[-0.49, 0.55, 0.27], [-0.01, 0.55, 0.27], [-0.01, 1.15, 0.27], [-0.49, 1.15, 0.27]]


def test_a_part_mesh_with_no_surface_or_bad_numbers_is_refused_naming_it(tmp_path: Path) -> None:
    src = make_singapo(tmp_path / "obj")
    line = np.array([DOOR[0], DOOR[2], np.add(DOOR[0], DOOR[2]) / 2])  # collinear corners
    _door_mesh(src, trimesh.Trimesh(line, [[0, 1, 2]] * 4, process=False))
    with pytest.raises(ImportFormatError) as e:
        import_path(src, tmp_path / "out")
    assert str(e.value).startswith(f"{src}: door_0 (diffuse_tree[1]): mesh plys/1.ply: ")
    assert "all of its 4 faces have zero area" in str(e.value)
    (src.parent / "plys" / "1.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
        "end_header\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n"
    )
    with pytest.raises(ImportFormatError, match="1.ply has NaN or infinite vertex coordinates"):
        import_path(src, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_flat_or_degenerate_part_mesh_is_imported_with_a_warning_naming_it(
    tmp_path: Path,
) -> None:
    clean = import_path(make_singapo(tmp_path / "clean"), tmp_path / "out")
    assert clean.warnings == []  # boxes, and the fixture's other meshes: no doubt
    src = make_singapo(tmp_path / "obj")
    _door_mesh(src, trimesh.Trimesh(DOOR, [[0, 1, 2], [0, 2, 3]], process=False))  # one quad
    (written,) = result = import_path(src, tmp_path / "out")
    (warning,) = result.warnings
    assert warning.startswith(f"{src}: door_0 (diffuse_tree[1]): mesh plys/1.ply: ")
    assert "only 2 faces of non-zero area" in warning and "flat" in warning
    assert load_bundle(written).provenance["warnings"] == [warning.split(": ", 1)[1]]
    assert load_bundle(written).provenance["meshes"]["door_0"] == ["plys/1.ply"]
    box = trimesh.creation.box(extents=(0.48, 0.6, 0.02))
    box.apply_translation((-0.25, 0.85, 0.26))
    slivers = [[i, i, (i + 1) % 8] for i in range(8)] * 3  # zero-area faces
    _door_mesh(src, trimesh.Trimesh(box.vertices, np.vstack([box.faces, slivers]), process=False))
    (warning,) = import_path(src, tmp_path / "out", ImportOptions(overwrite=True)).warnings
    assert "mesh plys/1.ply: 67% of its faces have zero area" in warning


def test_a_part_mesh_the_build_cannot_close_is_refused_naming_it(tmp_path: Path, monkeypatch):
    from generator.mesh_repair import closing

    def cannot(mesh, *args, **kwargs):
        raise closing.MeshRepairError("voxel remesh did not give a closed volume")

    monkeypatch.setattr(closing, "watertight", cannot)
    src = make_singapo(tmp_path / "obj")
    _door_mesh(src, trimesh.Trimesh(DOOR, [[0, 1, 2], [0, 2, 3]], process=False))
    with pytest.raises(ImportFormatError) as e:
        import_path(src, tmp_path / "out")
    assert str(e.value).startswith(f"{src}: door_0 (diffuse_tree[1]): mesh plys/1.ply: ")
    assert "cannot be closed into a volume (voxel remesh did not" in str(e.value)
    import_path(make_singapo(tmp_path / "clean"), tmp_path / "out")  # closed meshes: no try


def test_arti_tree_key_and_own_bundles(tmp_path: Path) -> None:
    src = make_singapo(tmp_path / "obj")
    data = json.loads(src.read_text())
    data["arti_tree"] = data.pop("diffuse_tree")
    src.write_text(json.dumps(data))
    (written,) = import_path(tmp_path / "obj", tmp_path / "out")
    with pytest.raises(ImportFormatError, match="already a bundle"):
        import_path(written / "object.json", tmp_path / "again")
    with pytest.raises(ImportFormatError, match="no CAGE/SINGAPO/PAct"):
        import_path(tmp_path / "out", tmp_path / "again")


def test_cli_import_errors_keep_their_brackets_and_name_the_bad_file(tmp_path: Path) -> None:
    """The messages reach the terminal whole (rich would eat ``[lower, upper]`` as markup),
    and a folder whose object.json is broken says so, not that none was found."""
    from typer.testing import CliRunner

    from pact_cli.main import app

    src = make_singapo(tmp_path / "obj")
    data = json.loads(src.read_text())
    data["diffuse_tree"][2]["joint"]["range"] = [0, "x"]
    src.write_text(json.dumps(data))
    res = CliRunner().invoke(app, ["import", str(tmp_path / "obj"), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2
    assert "must be [lower, upper], got [0, 'x']" in " ".join(res.output.split())
    src.write_text("{ not json")
    res = CliRunner().invoke(app, ["import", str(tmp_path / "obj"), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "object.json: not readable JSON" in " ".join(res.output.split())
