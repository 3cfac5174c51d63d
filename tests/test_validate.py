"""Validation, repair and report of built assets (asset_pipeline.validate / repair / sim_options).

Broken assets are made by building a procedural asset and then editing its URDF or
collision OBJ files; each must be caught by the check named in the test, and the
repairable ones must come out repaired and passing. Validation runs without the
preview here (tests/test_preview.py renders).
"""

from __future__ import annotations

import json
import math
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from asset_pipeline.assets.build import build_asset
from asset_pipeline.assets.folder import load_asset
from asset_pipeline.assets.mesh_files import piece_vertices, read_obj_vertices
from asset_pipeline.simulation.sapien_scenes import load_articulation, physics_scene
from asset_pipeline.simulation.sim_options import (
    DEFAULT_SIM_OPTIONS,
    OBJECT_IGNORE_BIT,
    SimOptions,
    apply_sim_options,
)
from asset_pipeline.validate import Report, validate_asset
from asset_pipeline.validate.static import hinge_offset, hull_thickness
from generator.bundle import save_bundle
from generator.procedural import CATEGORIES, sample_object

#: Seeds of every category validated by the default test run (the 10-seed batch of
#: every category runs in bench/validate.py; see the module docstring there).
DEFAULT_SEEDS = (0, 1, 2)


def _build(root: Path, category: str, seed: int) -> Path:
    d = save_bundle(sample_object(category, seed), root / f"{category}_{seed:04d}")
    build_asset(d)
    return d


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> dict[str, Path]:
    """Built procedural assets, never edited: a cabinet with drawers and a door, an oven."""
    root = tmp_path_factory.mktemp("pristine")
    return {"cabinet": _build(root, "cabinet", 0), "oven": _build(root, "oven", 0)}


@pytest.fixture
def copy_of(pristine, tmp_path):
    def make(kind: str) -> Path:
        dst = tmp_path / pristine[kind].name
        shutil.copytree(pristine[kind], dst)
        return dst

    return make


def _edit_urdf(asset: Path, fn) -> None:
    path = asset / "model.urdf"
    tree = ET.parse(path)
    fn(tree.getroot())
    tree.write(path, encoding="utf-8", xml_declaration=True)


def _joint(root: ET.Element, name: str) -> ET.Element:
    el = root.find(f"joint[@name='{name}']")
    assert el is not None, name
    return el


def _invert_axis(root: ET.Element, name: str) -> None:
    axis = _joint(root, name).find("axis")
    axis.set("xyz", " ".join(str(-float(v)) for v in axis.get("xyz").split()))


def _kinds(report: Report) -> set[tuple[str, str]]:
    return {(r.kind, r.target) for r in report.repairs}


def _first_failed(report: Report) -> set[str]:
    return set(report.rounds[0]["failed"])


def _shift_obj(path: Path, delta: np.ndarray) -> None:
    lines = []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            p = np.array([float(x) for x in line.split()[1:4]]) + delta
            line = "v " + " ".join(f"{x:.9g}" for x in p)
        lines.append(line)
    path.write_text("\n".join(lines) + "\n")


# --------------------------------------------------------------------------- pure helpers


def test_hull_thickness_flat_and_solid():
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 2) for z in (0, 3)], float)
    assert hull_thickness(flat) < 1e-12
    assert hull_thickness(cube) == pytest.approx(1.0)


def test_hinge_offset_projects_onto_aabb_surface():
    lo, hi = np.array([-0.02, 0.0, -0.3]), np.array([0.0, 0.5, 0.3])
    # hinge line along z through the origin: on the box's edge
    d, _ = hinge_offset(np.array([0, 0, 1.0]), lo, hi)
    assert d == pytest.approx(0.0)
    # box shifted 0.1 m away in +y: the line is outside, closest surface point at y = 0.1
    d, target = hinge_offset(np.array([0, 0, 1.0]), lo + [0, 0.1, 0], hi + [0, 0.1, 0])
    assert d == pytest.approx(0.1)
    assert target[1] == pytest.approx(0.1)


# --------------------------------------------------------------------------- sim options


def test_apply_sim_options_sets_material_groups_and_solver(pristine):
    opts = SimOptions(static_friction=0.9, dynamic_friction=0.7, self_collisions=False)
    scene = physics_scene(opts)
    art = load_articulation(scene, load_asset(pristine["cabinet"]), opts, visuals=False)
    assert art.get_solver_position_iterations() == opts.solver_position_iterations
    for link in art.links:
        for shape in link.collision_shapes:
            mat = shape.get_physical_material()
            assert mat.static_friction == pytest.approx(0.9)
            assert mat.dynamic_friction == pytest.approx(0.7)
            assert shape.get_collision_groups()[2] & (1 << OBJECT_IGNORE_BIT)
    apply_sim_options(art, DEFAULT_SIM_OPTIONS)  # siblings collide again
    for link in art.links:
        for shape in link.collision_shapes:
            assert not shape.get_collision_groups()[2] & (1 << OBJECT_IGNORE_BIT)


# --------------------------------------------------------------------------- report


def test_pristine_asset_passes_and_report_is_complete(copy_of):
    d = copy_of("cabinet")
    report = validate_asset(d, preview=False)
    assert report.status == "ok", report.reasons
    data = json.loads((d / "report.json").read_text())
    assert data["schema"] == "pact.validation" and data["status"] == "ok"
    assert data["repairs"] == [] and data["reasons"] == []
    names = {c["name"] for c in data["checks"]}
    for must in (
        "single_root",
        "axis_unit",
        "limits_ordered",
        "mass_positive",
        "inertia_valid",
        "collision_hulls",
        "hinge_on_part",
        "sapien_load",
        "collision_shapes",
        "joint_matches_urdf",
        "rest_penetration",
        "sweep_penetration",
        "drawer_engaged",
        "opens_outward",
        "rest_drift",
        "drive_reach",
        "free_base_stable",
        "finite",
    ):
        assert must in names, must
    for c in data["checks"]:
        assert set(c) >= {"name", "stage", "subject", "passed", "value", "tolerance"}
    assert set(data["timings"]) >= {"static", "load", "kinematic", "dynamic"}
    assert not list(d.glob(".report.json.*"))  # atomic write leaves no temporaries


# --------------------------------------------------------------------------- broken assets


def test_inverted_door_axis_is_flipped(copy_of):
    d = copy_of("cabinet")
    _edit_urdf(d, lambda r: _invert_axis(r, "joint_door_0"))
    report = validate_asset(d, preview=False)
    assert "opens_outward[joint_door_0]" in _first_failed(report)
    assert "sweep_penetration[joint_door_0]" in _first_failed(report)
    assert ("flip_axis", "joint_door_0") in _kinds(report)
    assert report.status == "repaired", report.reasons
    meta = json.loads((d / "asset.json").read_text())
    door = next(j for j in meta["joints"] if j["name"] == "joint_door_0")
    np.testing.assert_allclose(door["axis"], load_asset(d).joint("joint_door_0").axis)


def test_reversed_limits_fail(copy_of):
    d = copy_of("cabinet")

    def reverse(root):
        lim = _joint(root, "joint_drawer_0").find("limit")
        lo, hi = lim.get("lower"), lim.get("upper")
        lim.set("lower", hi)
        lim.set("upper", lo)

    _edit_urdf(d, reverse)
    report = validate_asset(d, preview=False)
    assert report.status == "failed"
    assert not report.check("limits_ordered", "joint_drawer_0")[0].passed
    assert any("limits_ordered[joint_drawer_0]" in r for r in report.reasons)
    assert json.loads((d / "report.json").read_text())["status"] == "failed"


def test_zero_mass_fails(copy_of):
    d = copy_of("cabinet")
    _edit_urdf(d, lambda r: r.find("link[@name='drawer_0']/inertial/mass").set("value", "0"))
    report = validate_asset(d, preview=False)
    assert report.status == "failed"
    assert not report.check("mass_positive", "drawer_0")[0].passed


def test_single_link_object_fails_with_a_clear_reason(tmp_path):
    from generator.articulated import ArticulatedObject

    obj = sample_object("microwave", 0)
    base_only = ArticulatedObject(
        [obj.parts[0]], category=obj.category, scale=obj.scale, provenance=obj.provenance
    )
    d = save_bundle(base_only, tmp_path / "microwave_base_only")
    build_asset(d)
    report = validate_asset(d, preview=False)
    assert report.status == "failed"
    check = report.check("has_movable_part", "asset")[0]
    assert not check.passed and "nothing to articulate" in check.message
    assert not report.check("sapien_load", "asset")  # stopped before SAPIEN


def test_overlapping_siblings_are_shrunk(copy_of):
    d = copy_of("cabinet")
    asset = load_asset(d)
    # the drawer_0 piece with the largest y*z face (its front panel), grown 12 mm up and down
    paths = [asset.path_of(p.filename) for p in asset.link("drawer_0").collisions]
    sizes = [np.ptp(read_obj_vertices(p), axis=0) for p in paths]
    k = int(np.argmax([s[1] * s[2] for s in sizes]))
    v = read_obj_vertices(paths[k])
    c = v.mean(0)
    grown = c + (v - c) * np.array([1.0, 1.0, (sizes[k][2] + 0.024) / sizes[k][2]])
    lines, it = [], iter(grown)
    for line in paths[k].read_text().splitlines():
        lines.append(
            "v " + " ".join(f"{x:.9g}" for x in next(it)) if line.startswith("v ") else line
        )
    paths[k].write_text("\n".join(lines) + "\n")
    report = validate_asset(d, preview=False)
    assert "rest_penetration[asset]" in _first_failed(report)
    first = report.rounds[0]
    assert first["failed"]
    assert any(
        kind == "shrink_piece" and target.startswith("drawer_0#") for kind, target in _kinds(report)
    )
    assert report.status == "repaired", report.reasons


def test_drawer_range_longer_than_depth_is_shortened(copy_of):
    d = copy_of("cabinet")
    asset = load_asset(d)
    depth = float(
        np.ptp(
            np.concatenate([piece_vertices(asset, p) for p in asset.link("drawer_0").collisions])[
                :, 0
            ]
        )
    )
    _edit_urdf(
        d, lambda r: _joint(r, "joint_drawer_0").find("limit").set("upper", f"{1.1 * depth:.6f}")
    )
    report = validate_asset(d, preview=False)
    assert "drawer_engaged[joint_drawer_0]" in _first_failed(report)
    rec = next(r for r in report.repairs if r.kind == "shorten_prismatic_range")
    assert rec.target == "joint_drawer_0" and rec.after[1] < rec.before[1]
    assert report.status == "repaired", report.reasons
    new_upper = load_asset(d).joint("joint_drawer_0").upper
    assert new_upper == pytest.approx(rec.after[1], rel=1e-6) and new_upper < depth
    meta = json.loads((d / "asset.json").read_text())
    assert next(j for j in meta["joints"] if j["name"] == "joint_drawer_0")[
        "upper"
    ] == pytest.approx(new_upper)


def test_flat_collision_piece_fails(copy_of):
    d = copy_of("cabinet")
    path = d / "collision" / "door_0_0.obj"
    path.write_text("v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0.1 0.1 0\nf 1 2 3\nf 2 4 3\n")
    report = validate_asset(d, preview=False)
    assert report.status == "failed"
    hulls = report.check("collision_hulls", "door_0")[0]
    assert not hulls.passed and "flat" in hulls.message


def test_uncookable_collision_piece_is_counted(copy_of):
    d = copy_of("cabinet")
    (d / "collision" / "door_0_0.obj").write_text("# nothing SAPIEN can cook\nv 0 0 0\n")
    report = validate_asset(d, preview=False)
    assert report.status == "failed"
    shapes = report.check("collision_shapes", "door_0")[0]
    assert not shapes.passed and shapes.value == shapes.tolerance - 1


def test_drifting_joint_gets_damping(copy_of):
    d = copy_of("oven")
    tilt = math.radians(15.0)

    def loosen(root):
        j = _joint(root, "joint_door_0")
        j.find("dynamics").set("damping", "0")
        j.find("dynamics").set("friction", "0")
        # lean the bottom-hinged door forward: gravity now pulls it open
        j.find("origin").set("rpy", f"0 {tilt:.6f} 0")

    _edit_urdf(d, loosen)
    report = validate_asset(d, preview=False)
    assert "rest_drift[joint_door_0]" in _first_failed(report)
    assert ("add_damping", "joint_door_0") in _kinds(report)
    assert report.status == "repaired", report.reasons
    dyn = load_asset(d).joint("joint_door_0").physics
    assert dyn.damping > 0 and dyn.friction > 0


def test_hinge_off_the_part_is_projected(copy_of):
    d = copy_of("cabinet")
    asset = load_asset(d)
    door = asset.joint("joint_door_0")
    paths = [asset.path_of(p.filename) for p in asset.link("door_0").collisions]
    centre = np.concatenate([read_obj_vertices(p) for p in paths]).mean(0)
    off = np.array([0.0, 0.08 if centre[1] < 0 else -0.08, 0.0])  # away from the door
    # move the hinge 8 cm away in y while the door's collision geometry stays put
    _edit_urdf(
        d,
        lambda r: (
            _joint(r, "joint_door_0")
            .find("origin")
            .set("xyz", " ".join(f"{x:.9g}" for x in door.origin[:3, 3] + off))
        ),
    )
    for p in paths:
        _shift_obj(p, -off)

    def world_pieces(a):
        pose = a.link_poses()["door_0"]
        return [
            piece_vertices(a, p) @ pose[:3, :3].T + pose[:3, 3] for p in a.link("door_0").collisions
        ]

    before = world_pieces(load_asset(d))
    report = validate_asset(d, preview=False)
    assert "hinge_on_part[joint_door_0]" in _first_failed(report)
    rec = next(r for r in report.repairs if r.kind == "project_hinge_origin")
    np.testing.assert_allclose(rec.after, door.origin[:3, 3], atol=1e-6)
    assert report.status == "repaired", report.reasons
    # the part did not move: only its link frame did (geometry origins compensate)
    repaired = load_asset(d)
    for a, b in zip(before, world_pieces(repaired), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-6)
    np.testing.assert_allclose(repaired.link("door_0").collisions[0].origin[:3, 3], off, atol=1e-6)


def test_no_repair_mode_reports_failure_without_editing(copy_of):
    d = copy_of("cabinet")
    _edit_urdf(d, lambda r: _joint(r, "joint_door_0").find("axis").set("xyz", "0 0 -1"))
    before = (d / "model.urdf").read_bytes()
    report = validate_asset(d, repair=False, preview=False)
    assert report.status == "failed" and not report.repairs
    assert (d / "model.urdf").read_bytes() == before


# --------------------------------------------------------------------------- hostile files


def _bytes(d: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(d)): p.read_bytes()
        for p in sorted(d.rglob("*"))
        if p.is_file() and p.name != "report.json"
    }


@pytest.mark.parametrize("where", ["../../../etc/passwd", "/etc/passwd", "elsewhere"])
def test_mesh_paths_outside_the_asset_fail_by_name(copy_of, tmp_path, where):
    d = copy_of("cabinet")
    if where == "elsewhere":  # a perfectly valid mesh, but not the asset's own
        outside = tmp_path / "other" / "piece.obj"
        outside.parent.mkdir()
        shutil.copy(d / "collision" / "door_0_0.obj", outside)
        where = str(outside)
    _edit_urdf(
        d, lambda r: r.find("link[@name='door_0']/collision/geometry/mesh").set("filename", where)
    )
    report = validate_asset(d, preview=False)
    assert report.status == "failed" and not report.repairs
    (urdf,) = report.check("urdf", "asset")
    assert not urdf.passed and where in urdf.message and "model.urdf" in urdf.message
    assert "leaves the asset folder" in urdf.message or "absolute" in urdf.message
    assert not report.check("sapien_load")  # SAPIEN never saw it


def test_nan_joint_origin_fails_statically_and_nothing_is_rewritten(copy_of):
    d = copy_of("cabinet")
    _edit_urdf(d, lambda r: _joint(r, "joint_door_0").find("origin").set("xyz", "nan 0 0.5"))
    before = _bytes(d)
    report = validate_asset(d, preview=False)
    assert report.status == "failed" and not report.repairs
    (urdf,) = report.check("urdf", "asset")
    assert "joint[joint_door_0]/origin@xyz" in urdf.message and "not finite" in urdf.message
    assert [c.stage for c in report.checks] == ["static"]
    assert _bytes(d) == before


def test_repairs_that_do_not_fix_the_asset_leave_its_files_alone(copy_of):
    """The inverted door axis is repairable, a flat collision piece of the drawer is not:
    the flip is made and checked, the asset still fails, so none of its edits may land."""
    d = copy_of("cabinet")
    axis = _joint(ET.parse(d / "model.urdf").getroot(), "joint_door_0").find("axis").get("xyz")
    flipped = " ".join(str(-float(v)) for v in axis.split())
    _edit_urdf(d, lambda r: _joint(r, "joint_door_0").find("axis").set("xyz", flipped))
    (d / "collision" / "drawer_0_0.obj").write_text(
        "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0.1 0.1 0\nf 1 2 3\nf 2 4 3\n"
    )
    before = _bytes(d)
    report = validate_asset(d, preview=False)
    assert report.status == "failed"
    assert ("flip_axis", "joint_door_0") in _kinds(report)  # tried, and checked again
    assert (
        len(report.rounds) == 2 and "opens_outward[joint_door_0]" not in report.rounds[1]["failed"]
    )
    assert _bytes(d) == before
    assert not (d / ".repair").exists()


def test_xml_that_is_not_a_urdf_is_called_that(copy_of):
    d = copy_of("cabinet")
    (d / "model.urdf").write_text('<?xml version="1.0"?>\n<svg><rect/></svg>\n')
    report = validate_asset(d, preview=False)
    (urdf,) = report.check("urdf", "asset")
    assert report.status == "failed" and "not a URDF" in urdf.message and "<svg>" in urdf.message


# --------------------------------------------------------------------------- procedural batch


@pytest.mark.parametrize("seed", DEFAULT_SEEDS)
@pytest.mark.parametrize("category", CATEGORIES)
def test_procedural_assets_pass(tmp_path, category, seed):
    d = _build(tmp_path, category, seed)
    report = validate_asset(d, preview=False)
    assert report.ok, report.reasons


def test_base_on_uneven_feet_gets_a_levelling_plate(tmp_path):
    """A cabinet standing on two front feet and a rear foot 2 cm short (an artist's base
    that rests on what it touches) tips back when free on the floor; the repair puts a
    3 mm plate under its feet and it then stands level."""
    import trimesh

    from generator.articulated import ArticulatedObject, Joint, Part
    from generator.procedural.solids import box

    def part(name, semantic, prims, joint=None):
        mesh = trimesh.util.concatenate([q.to_mesh() for q in prims])
        return Part(name, semantic, mesh, joint, prims)

    body = [
        box((-0.25, -0.3, 0.05), (0.25, 0.3, 0.08)),  # bottom panel, walls and top
        box((-0.25, -0.3, 0.08), (0.25, -0.28, 0.8)),
        box((-0.25, 0.28, 0.08), (0.25, 0.3, 0.8)),
        box((-0.25, -0.28, 0.08), (-0.23, 0.28, 0.8)),
        box((-0.25, -0.3, 0.8), (0.25, 0.3, 0.82)),
        box((0.17, -0.3, 0.0), (0.25, -0.22, 0.05)),  # two front feet
        box((0.17, 0.22, 0.0), (0.25, 0.3, 0.05)),
        box((-0.25, -0.04, 0.025), (-0.17, 0.04, 0.05)),  # a rear foot, 2.5 cm short
    ]
    door = [box((0.25, -0.28, 0.09), (0.27, 0.28, 0.79))]
    obj = ArticulatedObject(
        [
            part("base", "base", body),
            part("door_0", "door", door, Joint("revolute", (0.26, -0.28, 0.4), (0, 0, -1), 0, 1.5)),
        ],
        category="cabinet",
        scale=1.0,
    )
    folder = save_bundle(obj, tmp_path / "cabinet_feet")
    build_asset(folder)
    report = validate_asset(folder, preview=False, repair=False)
    assert _first_failed(report) == {"free_base_stable[asset]"}
    report = validate_asset(folder, preview=False)
    assert report.status == "repaired", report.reasons
    assert [r.kind for r in report.repairs] == ["level_base"]
    plate = load_asset(folder).link("base").collisions[-1]
    assert plate.name == "base_levelling"
    z = piece_vertices(load_asset(folder), plate)[:, 2]
    assert z.max() - z.min() == pytest.approx(0.003, abs=1e-4)


def test_a_deep_narrow_door_hinged_at_the_side_opens_outward(tmp_path):
    """A door 9 cm deep and 12 cm wide, hinged at the object's side (what a generator
    makes of a narrow panel): opening first moves its centroid sideways, toward the
    base's centre, but its free edge leaves the front. It passes ``opens_outward`` (also
    with a range past a half turn); the same door with its axis inverted still fails."""
    import trimesh

    from generator.articulated import ArticulatedObject, Joint, Part
    from generator.box_layout import fit_box_layout

    def box(lo, hi):
        m = trimesh.creation.box(np.subtract(hi, lo))
        m.apply_translation(np.add(lo, hi) / 2)
        return m

    base = Part("base", "base", box((-0.2, -0.4, -0.45), (0.2, 0.4, 0.45)))
    door = Part(
        "door_1",
        "door",
        box((0.11, -0.4, -0.15), (0.2, -0.28, 0.15)),
        Joint("revolute", (0.2, -0.4, 0.0), (0, 0, -1), 0.0, 1.2),
    )
    obj = fit_box_layout(ArticulatedObject([base, door], category="cabinet", scale=1.0))
    d = save_bundle(obj, tmp_path / "side_door")
    build_asset(d)
    report = validate_asset(d, repair=False, preview=False)
    assert "opens_outward[joint_door_1]" not in _first_failed(report), report.reasons
    # a range past a half turn (PartNet refrigerators: up to 180 degrees and more),
    # where opened and swung back by the range meet: judged at a quarter turn
    _edit_urdf(d, lambda r: _joint(r, "joint_door_1").find("limit").set("upper", "3.14159265"))
    report = validate_asset(d, repair=False, preview=False)
    assert "opens_outward[joint_door_1]" not in _first_failed(report), report.reasons
    _edit_urdf(d, lambda r: _joint(r, "joint_door_1").find("limit").set("upper", "1.2"))
    _edit_urdf(d, lambda r: _invert_axis(r, "joint_door_1"))
    report = validate_asset(d, repair=False, preview=False)
    assert "opens_outward[joint_door_1]" in _first_failed(report)
