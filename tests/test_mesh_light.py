"""generator.mesh_repair: light meshes (decimation, budgets, edge splits) and clean pieces
(slivers dropped, a movable part's visual as its panel and its handle)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from PIL import Image

from generator.articulated import ArticulatedObject, Joint, Part
from generator.mesh_repair.cleaning import (
    drop_slivers,
    panel_and_handle,
    strict_pieces,
    union_solids,
)
from generator.mesh_repair.closing import is_closed_volume
from generator.mesh_repair.decimation import (
    MIN_PART_FACES,
    decimate,
    light_object,
    part_budgets,
    split_long_edges,
)


def _pieces(mesh: trimesh.Trimesh) -> int:
    return len(np.unique(strict_pieces(mesh)))


def _coloured_sphere(subdivisions: int = 5) -> trimesh.Trimesh:
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.3)
    rgba = np.zeros((len(m.vertices), 4), np.uint8)
    rgba[:, 0] = np.where(m.vertices[:, 2] > 0, 200, 20)  # red on top, dark below
    rgba[:, 3] = 255
    m.visual = trimesh.visual.ColorVisuals(m, vertex_colors=rgba)
    return m


# --------------------------------------------------------------------------- decimation


def test_budgets_share_by_area_and_leave_small_parts_alone():
    big = trimesh.creation.icosphere(subdivisions=5, radius=1.0)  # 20480 faces, area 4 pi
    mid = trimesh.creation.icosphere(subdivisions=5, radius=0.5)  # 20480 faces, area pi
    small = trimesh.creation.box([0.1, 0.1, 0.1])  # 12 faces
    b = part_budgets({"big": big, "mid": mid, "small": small}, 10_012)
    assert b["small"] == 12  # within its share: kept, its rest goes to the others
    # the other 10000 shared by area, 4 : 1
    assert b["big"] == pytest.approx(8000, abs=2) and b["mid"] == pytest.approx(2000, abs=2)
    assert part_budgets({"big": big}, 0) == {"big": 20480}  # 0 keeps everything
    assert part_budgets({"big": big, "mid": mid}, 100)["mid"] == MIN_PART_FACES


def test_decimate_keeps_a_closed_coloured_mesh_closed_and_coloured():
    m = _coloured_sphere()
    out = decimate(m, 2000)
    assert len(out.faces) <= 2000
    assert is_closed_volume(out) and _pieces(out) == 1
    assert out.volume == pytest.approx(m.volume, rel=0.02)
    rgba = np.asarray(out.visual.vertex_colors)
    top = out.vertices[:, 2] > 0.05
    assert (rgba[top, 0] > 150).all() and (rgba[out.vertices[:, 2] < -0.05, 0] < 60).all()
    assert decimate(m, len(m.faces)) is m  # within the target: the mesh itself


def test_a_heavy_closed_mesh_is_presimplified_and_stays_closed(monkeypatch):
    import generator.mesh_repair.decimation as decimation

    m = _coloured_sphere(6)  # 81920 faces
    seen = []
    real = decimation._presimplify
    monkeypatch.setattr(decimation, "_presimplify", lambda mesh, t: seen.append(t) or real(mesh, t))
    out = decimate(m, 4000)
    assert seen == [int(decimation.PRESIMPLIFY_FACTOR * 4000)]
    assert len(out.faces) <= 4000 and is_closed_volume(out) and _pieces(out) == 1
    assert (out.area_faces > 0).all()  # no zero-area face: dropping it would open a hole
    assert out.volume == pytest.approx(m.volume, rel=0.02)
    rgba = np.asarray(out.visual.vertex_colors)
    assert (rgba[out.vertices[:, 2] > 0.05, 0] > 150).all()
    # a pre-pass that breaks the mesh is dropped: MeshLab alone
    monkeypatch.setattr(decimation, "_presimplify", lambda mesh, t: seen.append(t) and None)
    seen.clear()
    alone = decimate(m, 4000)
    assert seen and len(alone.faces) <= 4000 and is_closed_volume(alone)
    # an open mesh is not pre-simplified (the pre-pass keeps no boundary)
    seen.clear()
    opened = m.copy()
    opened.update_faces(np.arange(len(m.faces)) > 0)
    decimate(opened, 4000)
    assert seen == []


def _meshlab_calls(monkeypatch) -> list[tuple[int, dict]]:
    """(faces in, keyword arguments) of each MeshLab collapse the decimation runs."""
    import generator.mesh_repair.decimation as decimation

    calls: list[tuple[int, dict]] = []
    real = decimation._meshlab_collapse
    monkeypatch.setattr(
        decimation,
        "_meshlab_collapse",
        lambda mesh, target, **kw: calls.append((len(mesh.faces), kw)) or real(mesh, target, **kw),
    )
    return calls


def test_a_marching_cubes_shell_stays_closed_through_the_presimplified_collapse(monkeypatch):
    # a cabinet's shell as a generator's marching cubes draws it: thin walls round a cavity
    grid = np.zeros((70, 50, 90), bool)
    grid[5:65, 5:45, 5:85] = True
    grid[8:62, 8:60, 8:82] = False  # open at the front
    shell = trimesh.voxel.VoxelGrid(grid).marching_cubes
    assert is_closed_volume(shell) and len(shell.faces) > 40_000
    calls = _meshlab_calls(monkeypatch)
    out = decimate(shell, 3000)
    # the fast path held: MeshLab ran once, on the pre-simplified mesh (1.5 x 3000 faces)
    assert len(calls) == 1 and calls[0][1] == {"flip_t_vertices": True}
    assert calls[0][0] <= 4500
    assert len(out.faces) <= 3000 and is_closed_volume(out) and (out.area_faces > 0).all()
    assert out.volume == pytest.approx(shell.volume, rel=0.03)
    near = trimesh.proximity.closest_point(shell, out.vertices)[1]
    assert near.max() < 1.0  # within a voxel of the surface


def test_a_wall_folded_flat_by_the_pre_pass_keeps_the_fast_path(monkeypatch):
    from scipy import ndimage

    import generator.mesh_repair.decimation as decimation

    # a lumpy closed solid (a smoothed noise field, its largest piece): meshoptimizer's
    # collapse to 9,000 faces folds a thin wall flat into two faces on the same three
    # vertices, which leaves the surface open until the pair is dropped
    noise = ndimage.gaussian_filter(np.random.default_rng(1).normal(size=(48, 48, 48)), 3)
    grid = noise > 0.02
    grid[[0, 1, -2, -1]] = grid[:, [0, 1, -2, -1]] = grid[:, :, [0, 1, -2, -1]] = False
    labels, _ = ndimage.label(grid)
    solid = ndimage.binary_fill_holes(labels == np.argmax(np.bincount(labels.ravel())[1:]) + 1)
    lumpy = trimesh.voxel.VoxelGrid(solid).marching_cubes
    assert is_closed_volume(lumpy)
    pairs = np.array([[0, 1, 2], [3, 4, 5], [2, 1, 0], [1, 2, 0], [5, 4, 3]])
    assert decimation._drop_folded_pairs(pairs).tolist() == []
    assert decimation._drop_folded_pairs(pairs[:2]).tolist() == [[0, 1, 2], [3, 4, 5]]
    calls = _meshlab_calls(monkeypatch)
    out = decimate(lumpy, 6000)
    # MeshLab ran once, on the pre-simplified mesh: no fall-back to MeshLab alone
    assert len(calls) == 1 and calls[0][1] == {"flip_t_vertices": True} and calls[0][0] <= 9000
    assert len(out.faces) <= 6000 and is_closed_volume(out) and (out.area_faces > 0).all()
    assert out.volume == pytest.approx(lumpy.volume, rel=0.01)


def test_decimate_keeps_a_texture_and_its_mapping():
    m = trimesh.creation.icosphere(subdivisions=5, radius=0.3)
    # texture: left half (y < 0) red, right half blue, mapped by the y coordinate
    uv = np.stack([(m.vertices[:, 1] / 0.6) + 0.5, np.full(len(m.vertices), 0.5)], axis=1)
    img = np.zeros((8, 64, 3), np.uint8)
    img[:, :32, 0] = 255
    img[:, 32:, 2] = 255
    material = trimesh.visual.material.PBRMaterial(baseColorTexture=Image.fromarray(img))
    m.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    out = decimate(m, 1500)
    assert len(out.faces) <= 1500 and out.visual.kind == "texture"
    assert len(out.visual.uv) == len(out.vertices)
    # each vertex still maps to the side of the texture its position says
    u = np.asarray(out.visual.uv)[:, 0]
    far = np.abs(out.vertices[:, 1]) > 0.05
    assert np.all((u[far] < 0.5) == (out.vertices[far, 1] < 0))


def test_light_object_meets_the_budget_and_keeps_joints():
    base = _coloured_sphere(5)
    door = _coloured_sphere(4)
    door.apply_translation([0.5, 0, 0])
    joint = Joint("revolute", [0.5, 0.3, 0], [0, 0, 1], 0.0, 1.5)
    obj = ArticulatedObject([Part("base", "base", base), Part("door_0", "door", door, joint)])
    light = light_object(obj, 6000)
    assert sum(len(p.mesh.faces) for p in light.parts) <= 6000
    assert light.parts[1].joint is joint and light.category == obj.category
    assert light_object(obj, 0) is obj


def test_split_long_edges_is_conforming_and_keeps_a_box_closed():
    box = trimesh.creation.box([1.0, 0.5, 0.2])
    v, f, parents, origin = split_long_edges(box.vertices, box.faces, max_edge=0.2)
    out = trimesh.Trimesh(v, f, process=False)
    assert is_closed_volume(out) and out.volume == pytest.approx(0.1)
    edges = out.edges_unique_length
    assert edges.max() <= 0.2 + 1e-9
    assert len(origin) == len(f) and origin.max() == len(box.faces) - 1
    # every new vertex is the middle of its two parents
    new = np.arange(len(box.vertices), len(v))
    np.testing.assert_allclose(v[new], 0.5 * (v[parents[new, 0]] + v[parents[new, 1]]))
    # a bound on faces stops the splitting before it passes it
    _, f2, _, _ = split_long_edges(box.vertices, box.faces, max_edge=0.05, max_faces=200)
    assert 12 < len(f2) <= 200


# --------------------------------------------------------------------------- clean pieces


def test_drop_slivers_drops_flecks_and_zero_area_faces_but_keeps_a_handle():
    panel = trimesh.creation.box([0.02, 0.6, 0.4])
    bar = trimesh.creation.box([0.02, 0.3, 0.02])
    bar.apply_translation([0.03, 0, 0.1])  # apart from the panel, 50 % of its extent
    fleck = trimesh.creation.box([0.003, 0.003, 0.003])
    fleck.apply_translation([0.0, 0.35, 0.0])
    flat = trimesh.Trimesh([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]], [[0, 1, 2]])  # zero area
    mesh = trimesh.util.concatenate([panel, bar, fleck, flat])
    assert _pieces(mesh) == 4
    out = drop_slivers(mesh)
    assert _pieces(out) == 2 and len(out.faces) == 24
    assert drop_slivers(panel) is panel


def test_union_solids_joins_touching_solids_and_keeps_colours():
    a = trimesh.creation.box([0.4, 0.4, 0.1])
    b = trimesh.creation.box([0.1, 0.1, 0.3])
    b.apply_translation([0, 0, 0.15])  # overlaps a
    a.visual.vertex_colors = [200, 0, 0, 255]
    b.visual.vertex_colors = [0, 0, 200, 255]
    u = union_solids([a, b])
    assert u is not None and _pieces(u) == 1 and is_closed_volume(u)
    assert u.volume == pytest.approx(0.4 * 0.4 * 0.1 + 0.1 * 0.1 * 0.25, rel=1e-4)
    rgba = np.asarray(u.visual.vertex_colors)
    assert (rgba[u.vertices[:, 2] > 0.2, 2] == 200).all()
    open_box = trimesh.creation.box([0.2, 0.2, 0.2])
    open_box.update_faces(np.arange(10))
    assert union_solids([a, open_box]) is None  # not closed: nothing joined


def test_panel_and_handle_leaves_a_drawer_its_front_tray_and_bar():
    front = trimesh.creation.box([0.02, 0.6, 0.3])
    walls = []
    for size, at in (
        ([0.4, 0.6, 0.01], [-0.2, 0, -0.145]),  # floor
        ([0.4, 0.01, 0.3], [-0.2, 0.295, 0]),  # side walls
        ([0.4, 0.01, 0.3], [-0.2, -0.295, 0]),
        ([0.01, 0.6, 0.3], [-0.395, 0, 0]),  # back wall
    ):
        w = trimesh.creation.box(size)
        w.apply_translation(at)
        walls.append(w)
    bar = trimesh.creation.cylinder(radius=0.008, height=0.3)
    bar.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    bar.apply_translation([0.05, 0, 0.05])
    stray = trimesh.creation.box([0.05, 0.05, 0.05])  # a blob of the network, not a handle
    stray.apply_translation([0.3, 0.0, 0.4])
    mesh = trimesh.util.concatenate([front, *walls, stray])
    assert _pieces(mesh) == 6
    out = panel_and_handle(mesh, handle=bar)
    assert _pieces(out) == 2
    panel_volume = 0.02 * 0.6 * 0.3 + sum(w.volume for w in walls)
    assert out.volume == pytest.approx(panel_volume + bar.volume, rel=0.05)  # overlaps counted once
    assert out.bounds[1, 2] < 0.2  # the stray blob is gone
