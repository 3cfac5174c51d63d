"""Clean part geometry: occupancy-constrained SLAT decoding and the generic part cleaning."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from generator.articulated import ArticulatedObject, Joint, Part
from generator.mesh_repair.cleaning import clean_mesh, clean_parts, pieces
from generator.mesh_repair.closing import is_closed
from generator.pact.model.slat_vae import RESOLUTION, SUB, decode_part_mesh, shell_voxels
from generator.pact.training.stage2_data import TRUNCATION, subsample_points

R = RESOLUTION
VOXEL = 1.0 / R


def _box_sdf(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Exact signed distance to an axis-aligned box (normalized units, negative inside)."""
    c, h = (lo + hi) / 2, (hi - lo) / 2
    d = np.abs(points - c) - h
    return np.linalg.norm(np.maximum(d, 0), axis=-1) + np.minimum(d.max(axis=-1), 0)


def _decoded(occ: np.ndarray, boxes: list[tuple[np.ndarray, np.ndarray]]):
    """Token voxels of ``occ`` and their truncated SDF of the union of ``boxes`` (what a
    perfect stage 2 would decode), rgb grey."""
    coords = np.argwhere(shell_voxels(occ))
    pts = subsample_points(coords)  # (N, 64, 3) normalized
    d = np.min([_box_sdf(pts, np.asarray(lo), np.asarray(hi)) for lo, hi in boxes], axis=0)
    sdf = np.clip(d / TRUNCATION, -1, 1).astype(np.float32)
    return coords, sdf, np.full((len(coords), 3), 128, np.uint8)


def _frame(i: float) -> float:
    """Voxel coordinate -> normalized frame."""
    return -0.5 + i * VOXEL


def _assert_clean(mesh: trimesh.Trimesh, n_pieces: int) -> None:
    ps = pieces(mesh)
    assert len(ps) == n_pieces
    assert all(is_closed(p) for p in ps)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0


def test_noise_islands_around_a_blob_decode_to_one_piece():
    occ = np.zeros((R, R, R), bool)
    occ[8:20, 8:20, 8:20] = True
    lo, hi = np.full(3, _frame(8.5)), np.full(3, _frame(19.5))  # surface mid-shell
    coords, sdf, rgb = _decoded(occ, [(lo, hi)])
    rng = np.random.default_rng(0)
    sdf = sdf + rng.normal(0, 0.05, sdf.shape).astype(np.float32)
    # islands: isolated negative sub-samples on the outer side of shell voxels
    outer = np.flatnonzero(sdf.max(axis=1) > 0.3)
    for i in rng.choice(outer, 40, replace=False):
        j = int(np.argmax(sdf[i]))
        sdf[i, j] = -0.6
    raw = decode_part_mesh(coords, sdf, rgb, occ, constrain=False)
    assert len(pieces(raw)) > 10  # the debris the issue shows
    mesh = decode_part_mesh(coords, sdf, rgb, occ)
    _assert_clean(mesh, 1)
    # the surface stays within about a voxel of the true box
    assert np.allclose(mesh.bounds, [lo, hi], atol=1.0 * VOXEL)
    assert mesh.visual.vertex_colors.shape == (len(mesh.vertices), 4)


def test_cracked_panel_decodes_to_one_piece():
    """A thin panel whose decoded SDF misses a whole band of voxels (stage 2 decoded
    nothing there): the raw mesh falls in two, the constrained one does not."""
    occ = np.zeros((R, R, R), bool)
    occ[20, 6:26, 4:28] = True
    x0 = _frame(20.5)
    lo, hi = (
        np.array([x0 - 0.008, _frame(6.2), _frame(4.2)]),
        np.array([x0 + 0.008, _frame(25.8), _frame(27.8)]),
    )
    coords, sdf, rgb = _decoded(occ, [(lo, hi)])
    crack = (coords[:, 2] >= 14) & (coords[:, 2] < 16)
    sdf[crack] = 1.0
    assert len(pieces(decode_part_mesh(coords, sdf, rgb, occ, constrain=False))) == 2
    mesh = decode_part_mesh(coords, sdf, rgb, occ)
    _assert_clean(mesh, 1)
    assert mesh.extents[2] > 0.9 * (hi - lo)[2]


@pytest.mark.parametrize("x", [20, R - 1])  # in the middle, on the grid's face
@pytest.mark.parametrize("decoded", ["slab", "nothing"])
def test_one_voxel_thick_panel_survives(x, decoded):
    """A 1.5 cm panel of a 1 m object (half a voxel at R = 32) is one voxel thick in the
    occupancy, with no interior voxels: it survives as one thin closed plate, whether
    stage 2 decoded the slab or nothing at all."""
    occ = np.zeros((R, R, R), bool)
    occ[x, 6:26, 4:28] = True
    x0 = _frame(x + 0.5)
    lo = np.array([x0 - 0.0075, _frame(6.1), _frame(4.1)])
    hi = np.array([x0 + 0.0075, _frame(25.9), _frame(27.9)])
    coords, sdf, rgb = _decoded(occ, [(lo, hi)])
    if decoded == "nothing":
        sdf[:] = 1.0
    mesh = decode_part_mesh(coords, sdf, rgb, occ)
    _assert_clean(mesh, 1)
    ext = mesh.extents
    assert ext[0] < VOXEL  # a plate, not a voxel slab
    assert ext[1] > 0.85 * (hi - lo)[1] and ext[2] > 0.85 * (hi - lo)[2]
    # no holes: the plate covers its face (area of both sides ~ 2 x the face)
    assert mesh.area > 1.6 * (hi - lo)[1] * (hi - lo)[2]
    if decoded == "slab":  # thickness near the decoded slab's, not the voxel's
        assert abs(ext[0] - 0.015) < 0.5 * VOXEL


def test_base_of_two_occupancy_blobs_gives_two_pieces():
    occ = np.zeros((R, R, R), bool)
    occ[4:12, 4:28, 2:10] = True
    occ[4:12, 4:28, 20:30] = True
    boxes = [
        (
            np.array([_frame(4.3), _frame(4.3), _frame(2.3)]),
            np.array([_frame(11.7), _frame(27.7), _frame(9.7)]),
        ),
        (
            np.array([_frame(4.3), _frame(4.3), _frame(20.3)]),
            np.array([_frame(11.7), _frame(27.7), _frame(29.7)]),
        ),
    ]
    coords, sdf, rgb = _decoded(occ, boxes)
    mesh = decode_part_mesh(coords, sdf, rgb, occ)
    _assert_clean(mesh, 2)
    assert len(pieces(clean_mesh(mesh, movable=False))) == 2  # the base keeps both


def test_diagonal_contact_stays_one_piece():
    """Two blocks of a movable part's occupancy that touch only along an edge (one
    26-connected piece): one piece, not two."""
    occ = np.zeros((R, R, R), bool)
    occ[10:14, 10:14, 10:20] = True
    occ[14:18, 14:18, 10:20] = True
    coords = np.argwhere(shell_voxels(occ))
    sdf = np.ones((len(coords), SUB**3), np.float32)  # nothing decoded
    mesh = decode_part_mesh(coords, sdf, np.zeros((len(coords), 3), np.uint8), occ)
    _assert_clean(mesh, 1)


# --------------------------------------------------------------------------- cleaning


def _coloured(mesh: trimesh.Trimesh, rgb) -> trimesh.Trimesh:  # noqa: ANN001
    mesh.visual.vertex_colors = np.tile([*rgb, 255], (len(mesh.vertices), 1)).astype(np.uint8)
    return mesh


def _door() -> trimesh.Trimesh:
    return _coloured(trimesh.creation.box((0.02, 0.5, 0.8)), (150, 100, 50))


def test_handle_kept_fleck_dropped():
    door = _door()
    handle = trimesh.creation.cylinder(0.01, 0.12)  # along z, 3 cm in front of the door
    handle.apply_translation([0.01 + 0.03, 0.18, 0.0])
    fleck = trimesh.creation.box((0.006, 0.006, 0.006))
    fleck.apply_translation([0.05, -0.1, 0.3])
    chunk = trimesh.creation.box((0.1, 0.1, 0.1))  # far off: stray debris
    chunk.apply_translation([0.6, 0.0, 0.0])
    mesh = trimesh.util.concatenate([door, _coloured(handle, (20, 20, 20)), fleck, chunk])
    out = clean_mesh(mesh, movable=True)
    ps = sorted(pieces(out), key=lambda p: -p.area)
    assert len(ps) == 2
    assert np.allclose(ps[0].bounds, door.bounds) and np.allclose(ps[1].bounds, handle.bounds)
    assert all(is_closed(p) for p in ps)
    # the base keeps every piece but the fleck
    assert len(pieces(clean_mesh(mesh, movable=False))) == 3


def test_open_and_inverted_pieces_are_closed():
    door = _door()
    open_box = trimesh.Trimesh(door.vertices, door.faces[:-2], process=False)  # a hole
    out = clean_mesh(open_box, movable=True)
    assert len(pieces(out)) == 1 and is_closed(out)
    inverted = _door()
    inverted.invert()
    out = clean_mesh(inverted, movable=False)
    assert is_closed(out) and np.isclose(out.volume, door.volume)


def test_clean_parts_leaves_procedural_objects_unchanged():
    from generator.procedural import sample_object

    for cat, seed in (("cabinet", 1), ("oven", 0), ("microwave", 2), ("washing_machine", 1)):
        obj = sample_object(cat, seed, split="test")
        assert clean_parts(obj) is obj, cat


def test_clean_parts_on_a_debris_object():
    base = _coloured(trimesh.creation.box((0.5, 0.6, 0.8)), (200, 200, 200))
    base.apply_translation([-0.26, 0, 0])
    debris = trimesh.creation.icosphere(1, 0.02)
    debris.apply_translation([0.3, 0.2, 0.3])
    door = trimesh.util.concatenate([_door(), debris])
    obj = ArticulatedObject(
        [
            Part("base", "base", base),
            Part("door_1", "door", door, Joint("revolute", [0.01, 0.25, 0], [0, 0, 1], 0, 1.5)),
        ],
        scale=None,
    )
    out = clean_parts(obj)
    assert out is not obj and out.parts[0] is obj.parts[0]
    assert len(pieces(out.parts[1].mesh)) == 1 and is_closed(out.parts[1].mesh)
    out.validate()


def test_layout_from_raw_meshes_visuals_from_clean_ones():
    """generate's box layout comes from the raw decoded meshes and its visuals from the
    clean ones: a drawer's visual is its clean mesh plus the layout's bar, the base's the
    clean base plus the clean mesh of a part merged into it; collisions and joints are
    the raw layout's."""
    import trimesh as tm

    from generator.articulated import ArticulatedObject, Joint, Part
    from generator.box_layout import fit_box_layout
    from generator.pact.inference.generate import with_visuals

    def box(lo, hi):
        m = tm.creation.box(np.subtract(hi, lo))
        m.apply_translation(np.add(lo, hi) / 2)
        return m

    def obj(extra):
        base = box((-0.3, -0.4, -0.5), (0.3, 0.4, 0.5))
        drawer = box((-0.2, -0.3, 0.1), (0.3, 0.3, 0.4))
        if extra:  # the raw mesh's stray fragment
            drawer = tm.util.concatenate([drawer, box((0.0, 0.0, -0.3), (0.02, 0.02, -0.28))])
        sliver = box((0.29, -0.3, -0.45), (0.3, -0.29, -0.44))  # too small: merged
        return ArticulatedObject(
            [
                Part("base", "base", base),
                Part(
                    "drawer_1",
                    "drawer",
                    drawer,
                    Joint("prismatic", (0.3, 0, 0.25), (1, 0, 0), 0, 0.3),
                ),
                Part(
                    "drawer_2",
                    "drawer",
                    sliver,
                    Joint("prismatic", (0.3, 0, -0.44), (1, 0, 0), 0, 0.3),
                ),
            ]
        )

    raw, clean = obj(True), obj(False)
    laid = fit_box_layout(raw)
    out = with_visuals(laid, raw, clean)
    assert [p.name for p in out.parts] == [p.name for p in laid.parts] == ["base", "drawer_1"]
    drawer, laid_drawer = out.part("drawer_1"), laid.part("drawer_1")
    assert drawer.primitives is laid_drawer.primitives and drawer.joint is laid_drawer.joint
    bar_faces = len(laid_drawer.mesh.faces) - len(raw.part("drawer_1").mesh.faces)
    assert bar_faces > 0
    assert len(drawer.mesh.faces) == len(clean.part("drawer_1").mesh.faces) + bar_faces
    assert len(drawer.mesh.split(only_watertight=False)) == 2  # panel and bar
    # the part the layout merged into the base is a sliver of it (under 2 % of its size):
    # the base's visual drops it (mesh_repair.cleaning.drop_slivers)
    assert len(out.part("base").mesh.faces) == len(clean.part("base").mesh.faces)
    # a clean base reaching 2 cm below the raw one: the base's boxes reach down with it
    # (the build stands the object on its meshes' lowest point)
    clean.part("base").mesh.vertices[:, 2] -= (
        clean.part("base").mesh.vertices[:, 2] < -0.49
    ) * 0.02
    out = with_visuals(fit_box_layout(raw), raw, clean)
    low = min(q.transform[2, 3] - q.size[2] / 2 for q in out.part("base").primitives)
    assert low == pytest.approx(-0.52) and out.bounds()[0][2] == pytest.approx(-0.52)


def test_a_raw_mesh_that_lost_the_face_is_replaced_by_the_clean_one():
    """A drawer front two voxels deep whose raw SDF decodes to a sliver of its face (a
    quarter of it here) would be merged into the base by the box layout: generate lays
    out the clean mesh instead. A raw mesh about as large as the clean one (a little
    trimmed, a stray fragment) is kept; a missing raw mesh is replaced."""
    import trimesh as tm

    from generator.pact.inference.generate import _raw_face_lost

    def box(lo, hi):
        m = tm.creation.box(np.subtract(hi, lo))
        m.apply_translation(np.add(lo, hi) / 2)
        return m

    clean = box((0.45, -0.3, 0.1), (0.5, 0.3, 0.3))  # face 0.6 x 0.2
    sliver = box((0.46, -0.15, 0.15), (0.48, 0.15, 0.25))  # face 0.3 x 0.1: a quarter
    trimmed = box((0.46, -0.28, 0.11), (0.49, 0.28, 0.29))
    stray = tm.util.concatenate([trimmed, box((0.0, 0.0, -0.3), (0.01, 0.01, -0.29))])
    assert _raw_face_lost(sliver, clean)
    assert not _raw_face_lost(trimmed, clean)
    assert not _raw_face_lost(stray, clean)
    assert _raw_face_lost(None, clean) and _raw_face_lost(tm.Trimesh(), clean)
    assert not _raw_face_lost(sliver, None)


def test_visuals_are_cut_where_they_reach_into_a_neighbour():
    """Two stacked drawers whose collision boxes the layout left 4 mm apart, their clean
    meshes each reaching 1 cm past their box toward the other: cut at the middle of the
    gap, their meshes' boxes no longer overlap (the metrics' AOR) and each stays one
    closed piece with its vertex colours. A side without a neighbour (the bottom drawer's
    bottom, the drawers' fronts and -y sides) keeps the mesh's extent. A door beside the
    drawers (boxes 1 cm apart along y): the drawers' meshes reaching toward it are cut at
    the middle of that gap, its own mesh, short of it, is left as it is."""
    import trimesh as tm

    from generator.articulated import Joint, Part, Primitive
    from generator.metrics import iou
    from generator.pact.inference.generate import _primitive_box, clip_from_neighbours

    def box(lo, hi):
        m = tm.creation.box(np.subtract(hi, lo))
        m.apply_translation(np.add(lo, hi) / 2)
        m.visual.vertex_colors = np.tile([200, 120, 40, 255], (len(m.vertices), 1))
        return m

    def part(name, prim_lo, prim_hi, mesh, joint):
        lo, hi = np.asarray(prim_lo, float), np.asarray(prim_hi, float)
        prim = Primitive("box", hi - lo, tm.transformations.translation_matrix((lo + hi) / 2))
        return Part(name, "drawer", mesh, joint, [prim])

    slide = Joint("prismatic", (0.3, 0, 0), (1, 0, 0), 0, 0.3)
    low = part(
        "drawer_1",
        (-0.2, -0.3, 0.0),
        (0.3, 0.3, 0.2),
        box((-0.2, -0.31, -0.01), (0.31, 0.31, 0.21)),
        slide,
    )
    high = part(
        "drawer_2",
        (-0.2, -0.3, 0.204),
        (0.3, 0.3, 0.4),
        box((-0.2, -0.31, 0.194), (0.31, 0.31, 0.41)),
        slide,
    )
    door = part(
        "door_3",
        (0.28, 0.31, 0.0),
        (0.3, 0.6, 0.4),
        box((0.28, 0.312, 0.0), (0.3, 0.6, 0.4)),
        Joint("revolute", (0.3, 0.6, 0), (0, 0, 1), 0, 1.5),
    )
    boxes = np.array([low.mesh.bounds, high.mesh.bounds])
    assert iou(boxes[0], boxes[1]) > 0.03  # overlapping before
    parts = [low, high, door]

    def cut(part):  # noqa: ANN001, ANN202
        others = [_primitive_box(q) for q in parts if q is not part]
        return clip_from_neighbours(part.mesh, _primitive_box(part), others)

    a, b = cut(low), cut(high)
    assert a.bounds[1][2] == pytest.approx(0.202) and b.bounds[0][2] == pytest.approx(0.202)
    assert iou(a.bounds, b.bounds) == pytest.approx(0.0, abs=1e-9)
    assert a.bounds[0][2] == pytest.approx(-0.01) and b.bounds[1][2] == pytest.approx(0.41)
    assert a.bounds[0][1] == pytest.approx(-0.31) and a.bounds[1][0] == pytest.approx(0.31)
    assert a.bounds[1][1] == pytest.approx(0.305) and b.bounds[1][1] == pytest.approx(0.305)
    for m in (a, b):
        assert m.is_watertight and len(m.split(only_watertight=False)) == 1
        assert np.all(m.visual.vertex_colors[:, :3] == [200, 120, 40])
    assert cut(door) is door.mesh


def test_a_drawer_drawn_as_its_front_gets_the_body_of_its_collision_box() -> None:
    """A drawer whose visual is a 3 cm front on a collision box 40 cm deep gets an
    open-top tray behind the front, inside that box: its visual now reaches the box's
    back, keeps the front's colour, and a drawer whose visual is already deep, or one
    sliding along -y, is handled alike (the latter: along y)."""
    import trimesh as tm

    from generator.pact.inference.generate import DRAWER_WALL, drawer_body

    def box(lo, hi):
        m = tm.creation.box(np.subtract(hi, lo))
        m.apply_translation(np.add(lo, hi) / 2)
        m.visual.vertex_colors = np.tile([200, 120, 40, 255], (len(m.vertices), 1))
        return m

    collision = np.array([[-0.1, -0.3, 0.0], [0.3, 0.3, 0.2]])
    front = box((0.27, -0.3, 0.0), (0.3, 0.3, 0.2))
    body = drawer_body(front, collision, np.array([1.0, 0.0, 0.0]))
    assert body is not None
    lo, hi = body.bounds
    assert lo == pytest.approx([-0.1, -0.3, 0.0]) and hi[0] == pytest.approx(0.27 + DRAWER_WALL)
    assert hi[1:] == pytest.approx([0.3, 0.2])
    # open at the top: a point in the middle of the tray, above its floor, is not inside
    assert not body.contains([[0.1, 0.0, 0.1]])[0]
    assert body.contains([[0.1, 0.0, DRAWER_WALL / 2]])[0]  # the floor
    assert body.contains([[-0.1 + DRAWER_WALL / 2, 0.0, 0.1]])[0]  # the back wall
    assert np.all(body.visual.vertex_colors[:, :3] == [200, 120, 40])
    # already as deep as its box: nothing added
    assert (
        drawer_body(box((-0.05, -0.3, 0.0), (0.3, 0.3, 0.2)), collision, np.array([1.0, 0, 0]))
        is None
    )
    # a drawer sliding out along -y: the tray runs along +y behind its front
    side = np.array([[-0.3, -0.3, 0.0], [0.3, 0.1, 0.2]])
    body = drawer_body(box((-0.3, -0.3, 0.0), (0.3, -0.27, 0.2)), side, np.array([0.0, -1.0, 0.0]))
    assert body is not None
    lo, hi = body.bounds
    assert hi[1] == pytest.approx(0.1) and lo[1] == pytest.approx(-0.27 - DRAWER_WALL)
    assert lo[0] == pytest.approx(-0.3) and hi[0] == pytest.approx(0.3)


def test_visuals_of_two_doors_opening_together_are_cut_apart():
    """A fridge's two side-by-side doors, hinged at their outer front edges, their visuals
    6 cm deep behind the hinge line and 4 mm apart: swinging open, each one's back inner
    corner sweeps ``hypot(0.06, 0.248) - 0.248`` = 7 mm past its free edge into the
    other (AOR > 0). Cut apart, their swept boxes and the posed boxes the metrics read
    stay apart (AOR 0), each visual is cut on its facing side only and by little, stays
    closed and keeps its colours; the bar handle is not cut. Two drawers stacked with
    room between them are left as they are."""
    import trimesh as tm

    from generator.metrics import aor
    from generator.pact.inference.sweep_clearance import keep_sweeps_apart, swept_bounds

    def box(lo, hi):
        m = tm.creation.box(np.subtract(hi, lo))
        m.apply_translation(np.add(lo, hi) / 2)
        m.visual.vertex_colors = np.tile([200, 120, 40, 255], (len(m.vertices), 1))
        return m

    visuals = {
        "door_1": box((0.24, -0.25, -0.5), (0.3, -0.002, 0.5)),
        "door_2": box((0.24, 0.002, -0.5), (0.3, 0.25, 0.5)),
    }
    joints = {
        "door_1": Joint("revolute", (0.3, -0.25, 0), (0, 0, -1), 0, np.pi / 2),
        "door_2": Joint("revolute", (0.3, 0.25, 0), (0, 0, 1), 0, np.pi / 2),
    }
    bar = np.array([[0.3, -0.06, -0.1], [0.33, -0.04, 0.1]])

    def as_object(v):  # noqa: ANN001, ANN202
        base = Part("base", "base", box((-0.3, -0.25, -0.5), (0.24, 0.25, 0.5)))
        return ArticulatedObject([base, *(Part(n, "door", v[n], joints[n]) for n in v)])

    assert aor(as_object(visuals)) > 1e-5
    out = keep_sweeps_apart(visuals, {"door_1": bar}, joints)
    a, b = out["door_1"].bounds, out["door_2"].bounds
    swept_a = swept_bounds(
        np.r_[np.minimum(a[:1], bar[:1]), np.maximum(a[1:], bar[1:])], joints["door_1"]
    )
    swept_b = swept_bounds(b, joints["door_2"])
    assert swept_a[1, 1] <= swept_b[0, 1]
    assert aor(as_object(out)) == 0.0
    assert -0.02 < a[1, 1] < -0.002 and 0.002 < b[0, 1] < 0.02  # cut on the facing sides
    np.testing.assert_allclose(a[0], [0.24, -0.25, -0.5])  # the rest kept
    np.testing.assert_allclose(b[1], [0.3, 0.25, 0.5])
    for m in (out["door_1"], out["door_2"]):
        assert m.is_watertight
        assert np.all(m.visual.vertex_colors[:, :3] == [200, 120, 40])

    drawers = {
        "drawer_1": box((-0.2, -0.3, 0.0), (0.3, 0.3, 0.2)),
        "drawer_2": box((-0.2, -0.3, 0.21), (0.3, 0.3, 0.4)),
    }
    slide = Joint("prismatic", (0.3, 0, 0), (1, 0, 0), 0, 0.3)
    kept = keep_sweeps_apart(drawers, {}, {"drawer_1": slide, "drawer_2": slide})
    assert all(kept[n] is drawers[n] for n in drawers)
