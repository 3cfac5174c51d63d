"""Dataset rendering and shards (generator/data): format, masks, occupancy, determinism.

Objects are hand-built boxes (a cabinet with a drawer and a door, each part in its own
colour) so these tests do not depend on the procedural factory.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from generator.articulated import ArticulatedObject, Joint, Part
from generator.data import Dataset, DatasetError, build_dataset, load_shard, unpack_occupancy
from generator.data.geometry import occupancy, sample_surface, voxel_centres
from generator.data.shards import array_spec, pack_occupancy, stack_records, write_shard

BASE_RGB, DRAWER_RGB, DOOR_RGB = (200, 30, 30), (30, 200, 30), (30, 30, 200)


def _box(extents, centre, rgb) -> trimesh.Trimesh:
    T = np.eye(4)
    T[:3, 3] = centre
    m = trimesh.creation.box(extents=extents, transform=T)
    m.visual.face_colors = np.tile([*rgb, 255], (len(m.faces), 1))
    return m


def toy_cabinet(seed: int = 0) -> ArticulatedObject:
    """Open-front carcass (red), drawer on top (green), door below (blue), metric."""
    rng = np.random.default_rng(seed)
    w, h, d = rng.uniform(0.6, 1.0), rng.uniform(0.7, 1.1), rng.uniform(0.45, 0.6)
    t = 0.02
    x0 = d / 2
    carcass = [
        _box([d, w, t], [0, 0, t / 2], BASE_RGB),
        _box([d, w, t], [0, 0, h - t / 2], BASE_RGB),
        _box([d, t, h], [0, w / 2 - t / 2, h / 2], BASE_RGB),
        _box([d, t, h], [0, -w / 2 + t / 2, h / 2], BASE_RGB),
        _box([t, w, h], [-x0 + t / 2, 0, h / 2], BASE_RGB),
    ]
    zd = 0.74 * h
    drawer = _box([d - 2 * t, w - 2 * t - 0.004, 0.44 * h], [t / 2, 0, zd], DRAWER_RGB)
    door = _box([t, w - 2 * t - 0.004, 0.48 * h], [x0 + t / 2, 0, 0.26 * h], DOOR_RGB)
    hinge = [x0 + t, -w / 2 + t, 0.26 * h]
    obj = ArticulatedObject(
        [
            Part("base", "base", trimesh.util.concatenate(carcass)),
            Part(
                "drawer_0",
                "drawer",
                drawer,
                joint=Joint("prismatic", [x0, 0, zd], [1, 0, 0], 0, 0.8 * d),
            ),
            Part("door_0", "door", door, joint=Joint("revolute", hinge, [0, 0, -1], 0, 1.6)),
        ],
        category="cabinet",
        scale=1.0,
    )
    obj.validate()
    return obj


def toy_sampler(category: str, seed: int, split: str) -> ArticulatedObject:
    return toy_cabinet(seed)


# --------------------------------------------------------------------------- no rendering


def test_shard_round_trip(tmp_path):
    spec = array_spec(views=2, image_size=8, max_parts=4, resolution=4, points_per_part=5)
    rng = np.random.default_rng(0)
    records = []
    for i in range(3):
        rec = {}
        for key, (shape, dtype) in spec.items():
            if dtype == "U":
                rec[key] = np.array(f"{key}_{i}")
            elif dtype.startswith("float"):
                rec[key] = rng.normal(size=shape).astype(dtype)
            else:
                rec[key] = rng.integers(0, 100, size=shape).astype(dtype)
        records.append(rec)
    arrays = stack_records(records, spec)
    write_shard(tmp_path / "shard_00000.npz", arrays)
    back = load_shard(tmp_path / "shard_00000.npz")
    assert set(back) == set(arrays)
    for key in arrays:
        assert back[key].dtype == arrays[key].dtype, key
        np.testing.assert_array_equal(back[key], arrays[key], err_msg=key)
    assert not list(tmp_path.glob(".*.tmp"))

    grid = rng.random((3, 4, 6, 6, 6)) > 0.5
    np.testing.assert_array_equal(unpack_occupancy(pack_occupancy(grid), 6), grid)


def test_occupancy_agrees_with_meshes():
    R = 32
    box = trimesh.creation.box(extents=[0.5, 0.3, 0.7])
    grid = occupancy(box, R)
    c = voxel_centres(R)
    X, Y, Z = np.meshgrid(c, c, c, indexing="ij")
    inside = (np.abs(X) < 0.25) & (np.abs(Y) < 0.15) & (np.abs(Z) < 0.35)
    assert grid[inside].all()
    # nothing far from the box is occupied
    far = (np.abs(X) > 0.25 + 1 / R) | (np.abs(Y) > 0.15 + 1 / R) | (np.abs(Z) > 0.35 + 1 / R)
    assert not grid[far].any()

    # a panel thinner than a voxel keeps a full sheet of voxels
    panel = trimesh.creation.box(extents=[0.01, 0.8, 0.6])
    sheet = occupancy(panel, R)
    assert sheet.any(axis=0).sum() >= (0.8 * R - 1) * (0.6 * R - 1)

    # overlapping closed pieces (a non-manifold union) are filled, not cancelled
    cross = trimesh.util.concatenate(
        [
            trimesh.creation.box(extents=[0.6, 0.2, 0.2]),
            trimesh.creation.box(extents=[0.2, 0.6, 0.2]),
        ]
    )
    centre = np.searchsorted(c, 0.0)
    assert occupancy(cross, R)[centre, centre, centre]

    for mesh in (box, panel, trimesh.creation.cylinder(radius=0.3, height=0.4, sections=24)):
        points, colors = sample_surface(mesh, 2000, np.random.default_rng(1))
        idx = np.clip(np.floor((points + 0.5) * R).astype(int), 0, R - 1)
        g = occupancy(mesh, R)
        assert g[idx[:, 0], idx[:, 1], idx[:, 2]].mean() >= 0.999
        assert colors.shape == (2000, 3) and colors.dtype == np.uint8


# --------------------------------------------------------------------------- rendering


@pytest.fixture(scope="module")
def render_device():
    from generator.data.render import RenderUnavailableError, check_render_device

    try:
        check_render_device()
    except RenderUnavailableError as e:
        pytest.skip(str(e))


@pytest.fixture(scope="module")
def built(tmp_path_factory, render_device):
    out = tmp_path_factory.mktemp("ds") / "a"
    kwargs = dict(categories=["cabinet"], sampler=toy_sampler, image_size=96, objects_per_shard=2)
    build_dataset(out, 5, 6, seed=3, progress=False, **kwargs)
    return out, kwargs


def _visible(mesh: trimesh.Trimesh, eye: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points on ``mesh`` seen from ``eye``: facing it (not at a grazing angle) and hit
    first by the ray from ``eye`` (nothing in front of them)."""
    d = points - eye
    dist = np.linalg.norm(d, axis=1)
    _, _, tri = mesh.nearest.on_surface(points)
    facing = (mesh.face_normals[tri] * -d).sum(axis=1) / dist > 0.25
    locs, ray_idx, _ = mesh.ray.intersects_location(
        np.repeat(eye[None], len(points), 0), d / dist[:, None], multiple_hits=True
    )
    first = np.full(len(points), np.inf)
    np.minimum.at(first, ray_idx, np.linalg.norm(locs - eye, axis=1))
    return facing & (first >= dist - 2e-3)


@pytest.mark.render
def test_masks_land_on_the_right_parts(built):
    out, _ = built
    ds = Dataset(out)
    assert len(ds) == 5
    item = ds[0]
    assert int(item["part_count"]) == 3
    expected = {1: 0, 2: 1, 3: 2}  # mask id -> dominant colour channel (red, green, blue)
    for v in range(item["images"].shape[0]):
        rgb, mask = item["images"][v].astype(int), item["masks"][v]
        assert set(np.unique(mask)) <= {0, 1, 2, 3}
        for mid, channel in expected.items():
            pixels = rgb[mask == mid]
            if len(pixels) < 10:
                continue
            assert (pixels.argmax(axis=1) == channel).mean() > 0.95, (v, mid)


@pytest.mark.render
def test_surface_points_project_onto_their_mask(built):
    out, _ = built
    ds = Dataset(out)
    checked = 0
    for i in range(len(ds)):
        item = ds[i]
        obj = toy_cabinet(3 + i)
        c, s = item["normalization"][:3], float(item["normalization"][3])
        H = item["masks"].shape[1]
        for v in range(item["masks"].shape[0]):
            if np.any(item["view_qpos"][v] != 0):
                continue  # stored surface points are at rest
            K, E = item["intrinsics"][v].astype(float), item["extrinsics"][v].astype(float)
            eye = -E[:3, :3].T @ E[:3, 3]
            scene = trimesh.util.concatenate(list(obj.posed_meshes().values()))
            for k in range(int(item["part_count"])):
                pts = item["surface_points"][k][:300].astype(float) * s + c
                cam = pts @ E[:3, :3].T + E[:3, 3]
                uv = cam @ K.T
                px = np.floor(uv[:, :2] / uv[:, 2:3]).astype(int)
                ok = ((px >= 0) & (px < H)).all(axis=1) & _visible(scene, eye, pts)
                if ok.sum() < 20:
                    continue
                # a point may fall one pixel across a silhouette edge (rasterization)
                mask = np.pad(item["masks"][v], 1)
                near = np.zeros(int(ok.sum()), bool)
                for dy, dx in ((0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)):
                    near |= mask[px[ok, 1] + 1 + dy, px[ok, 0] + 1 + dx] == k + 1
                exact = item["masks"][v][px[ok, 1], px[ok, 0]] == k + 1
                assert near.mean() > 0.97 and exact.mean() > 0.75, (
                    i,
                    v,
                    k,
                    near.mean(),
                    exact.mean(),
                )
                checked += 1
    assert checked >= 5


@pytest.mark.render
def test_targets_in_normalized_frame(built):
    out, _ = built
    item = Dataset(out)[1]
    R = int(Dataset(out).manifest["resolution"])
    grid = item["occupancy_grid"]
    for k in range(int(item["part_count"])):
        pts = item["surface_points"][k]
        assert np.abs(pts).max() <= 0.5 + 1e-5
        idx = np.clip(np.floor((pts + 0.5) * R).astype(int), 0, R - 1)
        assert grid[k][idx[:, 0], idx[:, 1], idx[:, 2]].mean() >= 0.999
    assert not grid[int(item["part_count"]) :].any()
    assert list(item["joint_type"][:3]) == [0, 2, 3]  # none, prismatic, revolute
    assert list(item["semantic"][:3]) == [0, 1, 2]  # base, drawer, door
    obj = toy_cabinet(4)
    s = float(item["normalization"][3])
    np.testing.assert_allclose(item["joint_range"][1, 1], obj.parts[1].joint.upper / s, rtol=1e-5)
    np.testing.assert_allclose(item["joint_range"][2, 1], 1.6, rtol=1e-6)


@pytest.mark.render
@pytest.mark.slow
def test_build_is_deterministic_and_resumable(built, tmp_path):
    out, kwargs = built
    again = tmp_path / "b"
    build_dataset(again, 5, 6, seed=3, progress=False, **kwargs)
    files = sorted(p.name for p in out.glob("shard_*.npz"))
    assert files == ["shard_00000.npz", "shard_00001.npz", "shard_00002.npz"]
    reference = {f: load_shard(out / f) for f in files}
    for f in files:
        other = load_shard(again / f)
        for key, value in reference[f].items():
            np.testing.assert_array_equal(other[key], value, err_msg=f"{f}:{key}")

    # resume: delete one shard; the others are not rewritten, the result is identical
    stats = {f: (again / f).stat() for f in files}
    (again / "shard_00001.npz").unlink()
    build_dataset(again, 5, 6, seed=3, progress=False, **kwargs)
    for f in ("shard_00000.npz", "shard_00002.npz"):
        st = (again / f).stat()
        assert (st.st_ino, st.st_mtime_ns) == (stats[f].st_ino, stats[f].st_mtime_ns)
    for f in files:
        other = load_shard(again / f)
        for key, value in reference[f].items():
            np.testing.assert_array_equal(other[key], value, err_msg=f"{f}:{key}")
    assert Dataset(again).object_ids == Dataset(out).object_ids

    with pytest.raises(DatasetError, match="other arguments"):
        build_dataset(again, 5, 6, seed=4, progress=False, **kwargs)


def test_cameras_render_segmentation_after_maniskill_changed_the_shader(render_device) -> None:
    """ManiSkill sets the process-wide camera shader to its minimal pack (no Segmentation
    picture, 8-bit colour) when it makes a camera; the project's scenes put SAPIEN's
    own pack back, so a render after a task's video still has both pictures."""
    import sapien

    from asset_pipeline.simulation.sapien_scenes import make_scene

    sapien.render.set_camera_shader_dir("minimal")  # what ManiSkill's set_shader_pack does
    sapien.render.set_picture_format("Color", "r8g8b8a8unorm")
    scene = make_scene(render=True)
    camera = scene.add_camera("probe", 16, 16, 1.0, 0.01, 10.0)
    scene.update_render()
    camera.take_picture()
    assert camera.get_picture("Color").dtype == np.float32
    assert camera.get_picture("Segmentation").shape[:2] == (16, 16)
