"""Tests of the procedural factory (generator/procedural): geometry, joints, splits, I/O."""

from __future__ import annotations

import itertools
from functools import cache

import manifold3d
import numpy as np
import pytest
import trimesh

from generator.articulated import ArticulatedObject
from generator.bundle import load_bundle, save_bundle
from generator.procedural import (
    CATEGORIES,
    HELD_OUT,
    UnknownCategoryError,
    object_id,
    sample_object,
)
from generator.procedural.sampling import SplitChoice, SplitRange

SEEDS = (0, 1, 2, 3)
CASES = [(c, s, split) for c in CATEGORIES for s in SEEDS for split in ("train", "test")]
OVERLAP_TOL = 1e-7  # m^3

# (min, max) number of movable parts per semantic, per category
COUNTS = {
    "cabinet": {"total": (1, 8)},
    "desk": {"drawer": (1, 4), "door": (0, 0), "lid": (0, 0)},
    "microwave": {"door": (1, 1), "drawer": (0, 0), "lid": (0, 0)},
    "oven": {"door": (1, 1), "drawer": (0, 1), "lid": (0, 0)},
    "dishwasher": {"door": (1, 1), "drawer": (0, 0), "lid": (0, 0)},
    "refrigerator": {"door": (1, 2), "drawer": (0, 0), "lid": (0, 0)},
    "washing_machine": {"total": (1, 1), "drawer": (0, 0)},
}


@cache
def _obj(category: str, seed: int, split: str) -> ArticulatedObject:
    return sample_object(category, seed, split)


def _manifold(mesh: trimesh.Trimesh) -> manifold3d.Manifold:
    return manifold3d.Manifold(
        mesh=manifold3d.Mesh(
            vert_properties=np.asarray(mesh.vertices, dtype=np.float32),
            tri_verts=np.asarray(mesh.faces, dtype=np.uint32),
        )
    )


def _overlap(a: trimesh.Trimesh, b: trimesh.Trimesh) -> float:
    """Volume (m^3) of the boolean intersection of two closed meshes."""
    return (_manifold(a) ^ _manifold(b)).volume()


@pytest.mark.parametrize("category,seed,split", CASES)
def test_object_is_valid_metric_and_watertight(category: str, seed: int, split: str) -> None:
    obj = _obj(category, seed, split)
    obj.validate()
    assert obj.scale == 1.0 and obj.category == category
    base = obj.base
    lo, hi = base.mesh.bounds
    assert abs(lo[2]) < 1e-6, "the base stands on the floor (min z = 0)"
    # footprint centred; control knobs may stand up to 2.5 cm proud of an appliance front
    assert abs(lo[1] + hi[1]) / 2 < 1e-3, "footprint centred in y"
    assert abs(lo[0] + hi[0]) / 2 < 0.0126, "footprint centred in x"
    assert 0.2 < hi[2] < 2.2 and 0.2 < hi[1] - lo[1] < 2.0, "realistic metric size"
    for part in obj.parts:
        assert part.primitives, part.name
        assert part.material in {"wood", "metal", "plastic", "glass"}
        assert part.mesh.is_watertight, part.name
        union = trimesh.boolean.union([p.to_mesh() for p in part.primitives], engine="manifold")
        assert part.mesh.volume == pytest.approx(union.volume, rel=1e-5, abs=1e-9), part.name
        assert part.mesh.volume > 0


@pytest.mark.parametrize("category,seed,split", CASES)
def test_part_names_and_counts(category: str, seed: int, split: str) -> None:
    obj = _obj(category, seed, split)
    assert obj.parts[0].name == "base"
    by_sem: dict[str, list[str]] = {}
    for p in obj.movable_parts:
        assert p.semantic in {"drawer", "door", "lid"}
        by_sem.setdefault(p.semantic, []).append(p.name)
    for sem, names in by_sem.items():
        assert names == [f"{sem}_{k}" for k in range(len(names))]
    limits = COUNTS[category]
    if "total" in limits:
        lo, hi = limits["total"]
        assert lo <= len(obj.movable_parts) <= hi
    for sem, (lo, hi) in limits.items():
        if sem != "total":
            assert lo <= len(by_sem.get(sem, [])) <= hi, (sem, by_sem)
    # stable order: top to bottom, then left to right (ascending y), per semantic
    for names in by_sem.values():
        centres = [obj.part(n).mesh.bounds[:, 1:].mean(axis=0) for n in names]  # (y, z)
        for (ya, za), (yb, zb) in itertools.pairwise(centres):
            assert za > zb + 1e-3 or (abs(za - zb) <= 1e-3 and ya < yb), names


@pytest.mark.parametrize("category,seed,split", CASES)
def test_no_overlap_at_rest(category: str, seed: int, split: str) -> None:
    obj = _obj(category, seed, split)
    for a, b in itertools.combinations(obj.parts, 2):
        assert _overlap(a.mesh, b.mesh) < OVERLAP_TOL, (a.name, b.name)


@pytest.mark.parametrize("category,seed,split", CASES)
def test_joints_open_outward_without_collisions(category: str, seed: int, split: str) -> None:
    obj = _obj(category, seed, split)
    base = obj.base
    for p in obj.movable_parts:
        j = p.joint
        assert j.lower == 0.0
        assert np.linalg.norm(j.axis) == pytest.approx(1.0)
        rest = p.mesh
        opened = p.posed_mesh(j.upper)
        if p.semantic == "drawer":
            assert j.type == "prismatic" and np.allclose(j.axis, [1, 0, 0])
            depth = j.origin[0] - rest.bounds[0, 0]
            assert 0.7 - 1e-6 <= j.upper / depth <= 0.9 + 1e-6
            assert np.allclose(opened.vertices - rest.vertices, [j.upper, 0, 0], atol=1e-6)
            # still engaged: the drawer's back stays inside the carcass by >= 10 % of depth
            assert opened.bounds[0, 0] < j.origin[0] - 0.09 * depth
            assert _overlap(opened, base.mesh) < OVERLAP_TOL
        else:
            assert j.type == "revolute"
            if p.semantic == "door":
                assert 1.4 - 1e-6 <= j.upper <= 2.0 + 1e-6
                if abs(j.axis[1]) > 0.5:  # bottom/top hinged
                    assert j.upper <= 1.5708
                assert opened.centroid[0] > rest.centroid[0] + 0.05
                handle = p.handle.position
                moved = trimesh.transform_points([handle], j.transform(j.upper))[0]
                assert moved[0] > handle[0] + 0.05, "the free edge swings toward +x"
            else:  # lid
                assert opened.centroid[2] > rest.centroid[2] + 0.05
            # the hinge lies on the edge of the part's bounding box
            lo, hi = rest.bounds
            on_face = np.isclose(j.origin, lo, atol=1e-4) | np.isclose(j.origin, hi, atol=1e-4)
            assert on_face.sum() >= 1
        # sweeping the range never passes through the base or a sibling at rest
        for frac in (0.3, 0.7, 1.0):
            posed = p.posed_mesh(frac * j.upper)
            for q in obj.parts:
                if q is not p:
                    assert _overlap(posed, q.mesh) < OVERLAP_TOL, (p.name, frac, q.name)


@pytest.mark.parametrize("category,seed,split", CASES)
def test_handles_belong_to_their_parts(category: str, seed: int, split: str) -> None:
    obj = _obj(category, seed, split)
    for p in obj.movable_parts:
        h = p.handle
        assert h is not None and h.kind in {"bar", "knob", "recessed"}
        assert np.linalg.norm(h.axis) == pytest.approx(1.0)
        _, dist, _ = trimesh.proximity.closest_point(p.mesh, [h.position])
        assert dist[0] < 0.01, (p.name, h.kind, dist[0])
        assert h.position[0] > p.mesh.centroid[0], (p.name, h.kind)


def test_same_seed_identical_and_seeds_differ() -> None:
    for category in CATEGORIES:
        a, b = sample_object(category, 7), sample_object(category, 7)
        assert [p.name for p in a.parts] == [p.name for p in b.parts]
        for pa, pb in zip(a.parts, b.parts, strict=True):
            assert np.array_equal(pa.mesh.vertices, pb.mesh.vertices)
            assert np.array_equal(pa.mesh.faces, pb.mesh.faces)
            if pa.joint is not None:
                assert pa.joint.to_json() == pb.joint.to_json()
        assert a.provenance == b.provenance
        c = sample_object(category, 8)
        assert a.provenance["params"] != c.provenance["params"]
        assert not np.array_equal(a.base.mesh.bounds, c.base.mesh.bounds)


def test_splits_use_disjoint_held_out_ranges() -> None:
    assert set(HELD_OUT) == set(CATEGORIES)
    for category in CATEGORIES:
        assert HELD_OUT[category], category
        for seed in range(6):
            train = (
                _obj(category, seed, "train") if seed in SEEDS else sample_object(category, seed)
            )
            test = (
                _obj(category, seed, "test")
                if seed in SEEDS
                else sample_object(category, seed, "test")
            )
            assert train.provenance["split"] == "train" and test.provenance["split"] == "test"
            assert train.provenance["params"] != test.provenance["params"]
            for name, spec in HELD_OUT[category].items():
                assert isinstance(spec, SplitRange | SplitChoice)
                assert spec.held_out(test.provenance["params"][name]), (category, name)
                assert not spec.held_out(train.provenance["params"][name]), (category, name)


def test_provenance_and_object_id() -> None:
    obj = _obj("cabinet", 1, "train")
    prov = obj.provenance
    assert prov["generator"] == "procedural" and prov["category"] == "cabinet"
    assert prov["seed"] == 1 and prov["split"] == "train"
    assert {"width", "height", "depth", "panel_t", "gap"} <= set(prov["params"])
    assert 0.012 <= prov["params"]["panel_t"] <= 0.025
    assert 0.001 <= prov["params"]["gap"] <= 0.003
    assert object_id("cabinet", 12) == "cabinet_s0000012"
    assert object_id("cabinet", 12, "test") == "cabinet_t0000012"


def test_errors() -> None:
    with pytest.raises(UnknownCategoryError) as e:
        sample_object("sofa", 0)
    for c in CATEGORIES:
        assert c in str(e.value)
    assert isinstance(e.value, ValueError)
    with pytest.raises(ValueError, match="split"):
        sample_object("cabinet", 0, split="bogus")
    with pytest.raises(UnknownCategoryError):
        object_id("sofa", 0)


def test_appearance_colours_and_textures() -> None:
    textured = coloured = 0
    for category in ("cabinet", "desk"):
        for seed in SEEDS:
            for p in _obj(category, seed, "train").parts:
                vis = p.mesh.visual
                if isinstance(vis, trimesh.visual.TextureVisuals):
                    textured += 1
                    assert vis.uv.shape == (len(p.mesh.vertices), 2)
                    assert np.all((vis.uv >= 0) & (vis.uv <= 1))
                    assert vis.material.image.size == (64, 64)
                else:
                    coloured += 1
                    assert vis.vertex_colors.shape == (len(p.mesh.vertices), 4)
    assert textured > 0 and coloured > 0
    # bar/knob handles are painted in the accent colour, not the panel's colour
    checked = 0
    for category, seed in itertools.product(CATEGORIES, SEEDS):
        for p in _obj(category, seed, "train").movable_parts:
            vis = p.mesh.visual
            if p.handle.kind in {"bar", "knob"} and isinstance(vis, trimesh.visual.ColorVisuals):
                _, _, tri = trimesh.proximity.closest_point(p.mesh, [p.handle.position])
                grip_colors = vis.vertex_colors[p.mesh.faces[tri[0]]]  # (3, 4)
                back_color = vis.vertex_colors[np.argmin(p.mesh.vertices[:, 0])]
                assert not np.all(grip_colors == back_color), (category, seed, p.name)
                checked += 1
    assert checked > 0


def test_bundle_round_trip(tmp_path) -> None:
    for category in CATEGORIES:
        obj = _obj(category, 2, "train")  # cabinet 2 is wood-textured
        back = load_bundle(save_bundle(obj, tmp_path / object_id(category, 2)))
        assert [p.name for p in back.parts] == [p.name for p in obj.parts]
        assert back.provenance == obj.provenance
        for a, b in zip(obj.parts, back.parts, strict=True):
            assert np.array_equal(a.mesh.vertices, b.mesh.vertices), a.name
            assert np.array_equal(a.mesh.faces, b.mesh.faces), a.name
            assert b.mesh.is_watertight
            va, vb = a.mesh.visual, b.mesh.visual
            if isinstance(va, trimesh.visual.TextureVisuals):
                assert np.array_equal(va.uv, vb.uv), a.name
            else:
                assert np.array_equal(va.vertex_colors, vb.vertex_colors), a.name
            assert (a.joint is None) == (b.joint is None)
            if a.joint is not None:
                assert a.joint.to_json() == b.joint.to_json()
                assert a.handle.to_json() == b.handle.to_json()
            assert [q.to_json() for q in a.primitives] == [q.to_json() for q in b.primitives]


def test_sampling_prints_nothing(capsys) -> None:
    sample_object("refrigerator", 3)
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""


def _object_digest(obj: ArticulatedObject) -> str:
    """SHA-256 of everything a procedural object holds (meshes, colours, textures, joints,
    handles, primitives, provenance)."""
    import hashlib
    import json

    h = hashlib.sha256(json.dumps(obj.provenance, sort_keys=True).encode())
    for p in obj.parts:
        h.update(f"{p.name}|{p.semantic}|{p.material}".encode())
        h.update(np.asarray(p.mesh.vertices, np.float64).tobytes())
        h.update(np.asarray(p.mesh.faces, np.int64).tobytes())
        vis = p.mesh.visual
        if isinstance(vis, trimesh.visual.TextureVisuals):
            h.update(np.asarray(vis.uv, np.float64).tobytes())
            h.update(np.asarray(vis.material.image).tobytes())
        else:
            h.update(np.asarray(vis.vertex_colors, np.uint8).tobytes())
        for record in (p.joint, p.handle, *p.primitives):
            if record is not None:
                h.update(json.dumps(record.to_json(), sort_keys=True).encode())
    return h.hexdigest()


#: Digests of sample_object(category, seed, split) for seeds 0-4 and both splits, recorded
#: before the realistic variety (generator/procedural/realistic/) extended the shared
#: builders: the factory's output for existing calls must never change.
SAMPLE_OBJECT_DIGESTS = {
    "cabinet": "a2d157e515d4d3829fb8ab2956b3165e631dcc384ab69bc8bc29ae3d548cf631",
    "desk": "426d3e2fb6cd0d631e9c4e4a10dd3bdc3fcebee36e2612658669b5e98ed93075",
    "microwave": "c60203621befd6c0695e5bca55b1d77ad9b7ac207d2e58b91c3f1b2f99f7d0d7",
    "oven": "6607c6a00695047e23937af839ac92ee17d2cae28f65e20bd1ce4bb350e70d15",
    "dishwasher": "bb3a1e8607d79e3cbba15cb599a8fe249a538dcd91b7de113e9afa68923a92cb",
    "refrigerator": "4ce0da8fa70ab34b9849b13a46fb78e68a78a2c79612cf61a4392eea62993f4d",
    "washing_machine": "c9d2fdee14a247e5d365c7ecc61d5617910dd041348fc5d6f6e317b4b2d6dc54",
}


def test_sample_object_output_is_unchanged() -> None:
    import hashlib

    for category in CATEGORIES:
        h = hashlib.sha256()
        for split in ("train", "test"):
            for seed in range(5):
                h.update(_object_digest(sample_object(category, seed, split)).encode())
        assert h.hexdigest() == SAMPLE_OBJECT_DIGESTS[category], category


# --------------------------------------------------------------------------- realistic variety

REAL_SEEDS = (0, 1, 2)


@cache
def _real(category: str, seed: int) -> ArticulatedObject:
    from generator.procedural.realistic import sample_realistic_object

    return sample_realistic_object(category, seed)


def test_realistic_objects_are_valid_metric_and_labelled() -> None:
    from generator.motions import MOTIONS, motion_of
    from generator.procedural.realistic import REALISTIC_CATEGORIES

    assert REALISTIC_CATEGORIES == (*CATEGORIES, "other")
    for category in REALISTIC_CATEGORIES:
        for seed in REAL_SEEDS:
            obj = _real(category, seed)
            obj.validate()
            assert obj.scale == 1.0 and obj.category == category
            assert obj.provenance["generator"] == "procedural_realistic"
            lo, hi = obj.bounds()
            assert abs(lo[2]) < 1e-6 and 0.15 < hi[2] < 2.3, (category, seed, hi[2])
            for part in obj.parts:
                assert part.mesh.is_watertight and part.mesh.volume > 0, (category, part.name)
            if category == "other":
                assert obj.movable_parts == []
                continue
            assert obj.movable_parts, (category, seed)
            for part in obj.movable_parts:
                assert motion_of(part) in MOTIONS
                assert part.handle is not None and part.handle.kind in {"bar", "knob", "recessed"}
            for a, b in itertools.combinations(obj.parts, 2):
                assert _overlap(a.mesh, b.mesh) < 1e-6, (category, seed, a.name, b.name)


def test_realistic_objects_are_deterministic_and_varied() -> None:
    from generator.procedural.realistic import sample_realistic_object

    for category in ("cabinet", "refrigerator", "other"):
        a, b = _real(category, 1), sample_realistic_object(category, 1)
        assert a.provenance == b.provenance
        for pa, pb in zip(a.parts, b.parts, strict=True):
            assert np.array_equal(pa.mesh.vertices, pb.mesh.vertices)
        assert a.provenance["params"] != _real(category, 2).provenance["params"]
    kinds = {_real("cabinet", s).provenance["params"]["kind"] for s in REAL_SEEDS}
    kinds |= {
        sample_realistic_object("cabinet", s).provenance["params"]["kind"] for s in range(3, 12)
    }
    assert len(kinds) >= 4, kinds


def test_realistic_looks_have_metric_textures_and_tones() -> None:
    """Wood grain, brushed steel and paint are metric textures; windows, displays and
    countertops are further tones of their part's look."""
    from generator.procedural.appearance import METRIC_TEXTURE_SIZE

    textured = toned = 0
    for category in ("cabinet", "oven", "microwave"):
        for seed in REAL_SEEDS:
            for p in _real(category, seed).parts:
                vis = p.mesh.visual
                if isinstance(vis, trimesh.visual.TextureVisuals):
                    textured += 1
                    assert vis.material.image.size == (METRIC_TEXTURE_SIZE, METRIC_TEXTURE_SIZE)
                    assert np.all((vis.uv >= 0) & (vis.uv <= 1))
                    colours = np.unique(np.asarray(vis.material.image).reshape(-1, 3), axis=0)
                else:
                    colours = np.unique(vis.vertex_colors[:, :3], axis=0)
                toned += len(colours) > 2
    assert textured > 0 and toned > 0


def test_realistic_sampling_leaves_sample_object_alone() -> None:
    from generator.procedural.realistic import realistic_object_id, sample_realistic_object

    before = _object_digest(sample_object("oven", 4))
    sample_realistic_object("oven", 4)
    assert _object_digest(sample_object("oven", 4)) == before
    assert realistic_object_id("oven", 4) == "oven_r0000004"
    assert realistic_object_id("oven", 4, "test") == "oven_q0000004"
    with pytest.raises(UnknownCategoryError):
        sample_realistic_object("sofa", 0)


def test_realistic_thin_vent_grille_builds() -> None:
    """An over-the-range microwave whose vent strip is too thin for slats still builds
    (it failed with a degenerate box before)."""
    from generator.procedural.realistic import sample_realistic_object
    from generator.procedural.realistic.shapes import slots

    assert slots(0.0, 0.5, 0.3, 0.29, 0.2, 10, True) == []
    for seed in (89, 372):
        obj = sample_realistic_object("microwave", seed)
        assert obj.provenance["params"]["kind"] == "over_range" and len(obj.movable_parts) == 1


def test_realistic_double_fridge_doors_clear_each_other_as_they_start_to_open() -> None:
    """A side-by-side or French-door fridge's doors are 4-7 cm thick: as one starts to
    open, its free edge's back corner swings toward the other door by up to
    thickness^2 / (2 width), 2-7 mm, before it moves away. The gap between them leaves
    room for it: no overlap with the other door at the small angles where that happens."""
    from generator.procedural.realistic import sample_realistic_object

    found = set()
    for seed in range(40):
        obj = sample_realistic_object("refrigerator", seed)
        kind = obj.provenance["params"]["kind"]
        if kind not in ("side_by_side", "french") or kind in found:
            continue
        found.add(kind)
        doors = [p for p in obj.movable_parts if p.semantic == "door"]
        assert len(doors) == 2, (seed, kind)
        for door, other in (doors, doors[::-1]):
            for angle in (0.03, 0.06, 0.1, 0.15, 0.2):
                posed = door.posed_mesh(angle)
                assert _overlap(posed, other.mesh) < OVERLAP_TOL, (seed, kind, door.name, angle)
        if found == {"side_by_side", "french"}:
            break
    assert found == {"side_by_side", "french"}


def test_a_realistic_side_by_side_fridge_validates_in_sapien(tmp_path) -> None:
    """Built and validated in SAPIEN, each door of a side-by-side fridge opens to 90 %
    and closes again under its drive while the other is held closed (drive_reach): with
    too little room between the doors' free edges the closing one jammed 0.13 rad short."""
    from asset_pipeline.assets.build import build_asset
    from asset_pipeline.validate import validate_asset
    from generator.bundle import save_bundle
    from generator.procedural.realistic import sample_realistic_object

    obj = sample_realistic_object("refrigerator", 1)
    assert obj.provenance["params"]["kind"] == "side_by_side"
    folder = save_bundle(obj, tmp_path / "fridge")
    build_asset(folder)
    report = validate_asset(folder, preview=False, repair=False)
    drives = report.check("drive_reach")
    assert len(drives) == 2 and all(c.passed for c in drives), [c.message for c in drives]
    assert report.ok, report.reasons


def test_a_realistic_french_door_fridges_freezer_drawer_closes_in_sapien(tmp_path) -> None:
    """A French-door fridge's freezer drawer, driven open and shut in SAPIEN
    (drive_reach), closes: with the 2-4 mm gap of the other fronts between it and the
    doors above, the closing front met the doors' bottom edge and jammed 6 cm out."""
    from asset_pipeline.assets.build import build_asset
    from asset_pipeline.validate import validate_asset
    from generator.bundle import save_bundle
    from generator.procedural.realistic import sample_realistic_object
    from generator.procedural.realistic.appliances import FRIDGE_DRAWER_GAP

    obj = sample_realistic_object("refrigerator", 4)
    assert obj.provenance["params"]["kind"] == "french"
    doors = [p for p in obj.movable_parts if p.semantic == "door"]
    drawer = next(p for p in obj.movable_parts if p.semantic == "drawer")
    gap = min(d.mesh.bounds[0][2] for d in doors) - drawer.mesh.bounds[1][2]
    assert gap >= FRIDGE_DRAWER_GAP - 1e-6, gap
    folder = save_bundle(obj, tmp_path / "fridge")
    build_asset(folder)
    report = validate_asset(folder, preview=False, repair=False)
    drive = next(c for c in report.check("drive_reach") if "drawer" in c.subject)
    assert drive.passed, drive.message


def _first_hit_x(mesh: trimesh.Trimesh, y: float, z: float) -> float | None:
    """x of the first surface a ray from the front (+x) at (y, z) meets, going -x."""
    hits, _, _ = mesh.ray.intersects_location([[5.0, y, z]], [[-1.0, 0.0, 0.0]])
    return float(hits[:, 0].max()) if len(hits) else None


def test_realistic_pedestal_desk_can_stand_on_open_shelves() -> None:
    """A pedestal of open shelves under a shallow drawer (a real desk's look the parser
    read as drawers): the shelves stay part of the base, a ray into them from the front
    reaches the back of the pedestal, and the drawer is the only movable part."""
    from generator.procedural.realistic import sample_realistic_object

    obj = sample_realistic_object("desk", 76)
    p = obj.provenance["params"]
    assert p["kind"] == "pedestal" and p["left_layout"] == "shelves" and "right_layout" not in p
    assert [m.semantic for m in obj.movable_parts] == ["drawer"]
    cy = -(p["width"] / 2 - p["overhang_side"] - p["pedestal_w"] / 2)
    cy = -cy if p["mirror"] else cy
    base = obj.parts[0].mesh
    front = p["depth"] / 2 - p["overhang_front"]
    drawer_lo = obj.movable_parts[0].mesh.bounds[0][2]
    for z in (0.25 * drawer_lo, 0.7 * drawer_lo):  # the two cubbies under the drawer
        x = _first_hit_x(base, cy, z)
        assert x is not None and x < front - 0.3, (z, x, front)


def test_realistic_fridge_can_have_a_tall_fixed_grille_panel() -> None:
    """Some fridges stand on a 10-20 cm grille panel across their width (a real fridge's
    look the parser read as a drawer): it is the base's, flush with the carcass front,
    and every door starts above it."""
    from generator.procedural.realistic import sample_realistic_object

    obj = sample_realistic_object("refrigerator", 2)
    p = obj.provenance["params"]
    assert p["grille_panel"] and 0.1 <= p["grille_panel_h"] <= 0.2
    h, front = p["grille_panel_h"], p["depth"] / 2
    for y in (-0.2, 0.0, 0.2):
        x = _first_hit_x(obj.parts[0].mesh, y, h / 2)
        assert x is not None and abs(x - front) < 0.005, (y, x, front)
    assert min(m.mesh.bounds[0][2] for m in obj.movable_parts) >= h - 0.005
    assert not _real("refrigerator", 0).provenance["params"]["grille_panel"]
