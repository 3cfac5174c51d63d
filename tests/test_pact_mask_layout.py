"""The box and camera fitted to a part mask, and the part grids laid out from them.

The masks here are ray-cast independently of the module: a pinhole camera at a known
azimuth, elevation and field of view looks at an axis-aligned box (or a table: a top on
four legs) whose front carries the movable parts."""

from __future__ import annotations

import numpy as np

from generator.pact.inference.mask_agreement import view_rotation
from generator.pact.inference.mask_layout import (
    BOX_IOU,
    MIN_FIT_IOU,
    BoxCamera,
    edge_map,
    edge_score,
    fit_box_camera,
    layout_from_mask,
)

SIZE = 128


def _raycast(boxes, azimuth_deg, elevation_deg, fovy_deg=40.0, size=SIZE, shaded=False):
    """Part-id image (size, size) of axis-aligned boxes [(lo, hi, id), ...] (the nearest
    hit wins) seen by a pinhole camera at the given azimuth and elevation, looking at the
    origin from 2.2 units away. With ``shaded``, also an RGB image: faces facing x, y and
    z lit differently (170, 110, 230 grey), the background dark."""
    R = view_rotation(np.radians(azimuth_deg), np.radians(elevation_deg))
    eye = 2.2 * R[2]
    f = 0.5 * size / np.tan(np.radians(fovy_deg) / 2)
    u, v = np.meshgrid(np.arange(size) + 0.5 - size / 2, np.arange(size) + 0.5 - size / 2)
    dirs = u[..., None] / f * R[0] + v[..., None] / f * R[1] - R[2]  # right, down, forward
    dirs = dirs.reshape(-1, 3)
    best = np.full(len(dirs), np.inf)
    out = np.zeros(len(dirs), np.uint8)
    face = np.zeros(len(dirs), np.int64)  # the axis of the face hit
    for lo, hi, pid in boxes:
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (np.asarray(lo) - eye) / dirs
            t2 = (np.asarray(hi) - eye) / dirs
        entry = np.minimum(t1, t2)
        near = np.nanmax(entry, axis=1)
        far = np.nanmin(np.maximum(t1, t2), axis=1)
        hit = (near <= far) & (near > 0) & (near < best)
        best[hit] = near[hit]
        out[hit] = pid
        face[hit] = np.nanargmax(entry[hit], axis=1)
    ids = out.reshape(size, size)
    if not shaded:
        return ids
    grey = np.where(out > 0, np.array([170, 110, 230])[face], 40).astype(np.uint8)
    return ids, np.repeat(grey.reshape(size, size, 1), 3, axis=2)


def _chest(top_id=2, bottom_id=3):
    """A chest 0.5 deep, 1 wide, 0.8 tall (x, y, z), two drawer fronts on its face."""
    return [
        ((-0.25, -0.5, -0.4), (0.25, 0.5, 0.4), 1),
        ((0.25, -0.45, 0.02), (0.27, 0.45, 0.35), top_id),
        ((0.25, -0.45, -0.35), (0.27, 0.45, -0.02), bottom_id),
    ]


def _table():
    """A table 0.5 deep, 1 wide, 0.8 tall: a top on four legs, a drawer front (id 2) under
    the top."""
    legs = [
        ((sx * 0.2 - 0.04, sy * 0.45 - 0.04, -0.4), (sx * 0.2 + 0.04, sy * 0.45 + 0.04, 0.25), 1)
        for sx in (-1, 1)
        for sy in (-1, 1)
    ]
    return [
        ((-0.25, -0.5, 0.25), (0.25, 0.5, 0.4), 1),
        *legs,
        ((0.25, 0.1, 0.27), (0.27, 0.4, 0.38), 2),
    ]


def test_fit_box_camera_recovers_view_and_proportions():
    mask = _raycast(_chest(), azimuth_deg=35.0, elevation_deg=20.0)
    cam = fit_box_camera(mask, [2, 3])
    assert cam.iou > 0.9
    assert abs(np.degrees(cam.azimuth) - 35.0) < 6.0
    assert abs(np.degrees(cam.elevation) - 20.0) < 6.0
    assert abs(np.log(cam.height / 0.8)) < 0.12  # height over width
    assert abs(np.log(cam.depth / 0.52)) < 0.3  # depth over width (the fronts stand out)
    # seen from the other side, the front (where the parts are) is on the other side
    mirrored = fit_box_camera(_raycast(_chest(), azimuth_deg=-35.0, elevation_deg=20.0), [2, 3])
    assert abs(np.degrees(mirrored.azimuth) + 35.0) < 6.0


def _chest_camera(ids, azimuth_deg, elevation_deg):
    """The chest's box (0.52 deep with its fronts, 0.8 tall) seen as ``_raycast`` sees it,
    mapped onto the silhouette of ``ids``."""
    rows, cols = np.nonzero(ids)
    return BoxCamera(
        np.radians(azimuth_deg),
        np.radians(elevation_deg),
        0.52,
        0.8,
        np.radians(40.0),
        1.0,
        ((cols.min() + cols.max() + 1) / 2, (rows.min() + rows.max() + 1) / 2),
        float(max(np.ptp(rows), np.ptp(cols)) + 1),
    )


def test_scores_of_a_box_seen_from_the_front_are_its_front_rectangle():
    """Seen head-on (azimuth and elevation 0) a box's silhouette is its front face (the
    back is further away, so smaller and hidden): a box as high as half its width fills
    the middle half of the rows of its bounding square, all columns. Against that
    silhouette its IoU is 1, a box as high as wide (the whole square) 0.5, and movable
    pixels inside the front count fully (score = IoU + CONTAINMENT_WEIGHT)."""
    from generator.pact.inference.mask_layout import CONTAINMENT_WEIGHT, FOVY, _scores

    G = 40
    sil = np.zeros((G, G), bool)
    sil[G // 4 : 3 * G // 4] = True  # rows 10-29: centres (r + 0.5) / G in (0.25, 0.75)
    parts = np.zeros((G, G), bool)
    parts[12:18, 5:11] = True
    half = np.array([[0.3, 0.5, 0.25], [0.3, 0.5, 0.5]])  # heights 0.5 and 1, width 1
    score, iou = _scores(sil, parts, 0.0, 0.0, half, FOVY)
    np.testing.assert_allclose(iou, [1.0, 0.5])
    np.testing.assert_allclose(score, iou + CONTAINMENT_WEIGHT)
    # no movable pixel on the front: the containment term is 0
    outside = np.zeros((G, G), bool)
    outside[:5] = True
    score, _ = _scores(sil, outside, 0.0, 0.0, half[:1], FOVY)
    np.testing.assert_allclose(score, [1.0])


def test_edge_score_is_high_where_the_photo_shows_the_box_edges():
    """The photo of a chest whose faces are lit differently: the edge term is high at the
    true view and low at views 12 degrees off (the front/side edge then falls on a face),
    alike whatever the photo's resolution; a photo of another size than the mask, or one
    with no gradient, gives no edge map."""
    for size in (128, 512):
        ids, photo = _raycast(_chest(), 35.0, 20.0, size=size, shaded=True)
        edges = edge_map(photo, ids > 0)
        assert edges is not None
        true = edge_score(_chest_camera(ids, 35.0, 20.0), edges)
        assert true > 2.0
        for off in (-12.0, 12.0):
            assert edge_score(_chest_camera(ids, 35.0 + off, 20.0), edges) < 0.5 * true
    assert edge_map(photo[:100], ids > 0) is None
    assert edge_map(np.full_like(photo, 90), ids > 0) is None


def test_the_photos_edges_turn_the_fit_to_the_true_view():
    """A cabinet 0.5 deep, 1 wide and 0.8 tall with one door across its front, seen from
    45 degrees: a view of 34 degrees explains its silhouette about as well (the mask
    alone picks that); the edge between its front and its side, which the photo shows,
    puts the fit back within 3 degrees of the true view."""
    cabinet = [
        ((-0.25, -0.5, -0.4), (0.25, 0.5, 0.4), 1),
        ((0.25, -0.48, -0.38), (0.27, 0.48, 0.38), 2),
    ]
    ids, photo = _raycast(cabinet, -45.0, 12.0, shaded=True)
    alone = fit_box_camera(ids, [2], 0.52)
    with_photo = fit_box_camera(ids, [2], 0.52, edges=edge_map(photo, ids > 0))
    assert abs(np.degrees(alone.azimuth) + 45.0) > 8.0
    assert abs(np.degrees(with_photo.azimuth) + 45.0) < 3.0
    assert with_photo.iou > alone.iou - 0.02


def test_a_legged_tables_fit_ignores_the_photo(monkeypatch):
    """A table (a top on four legs, a drawer under the top) is no box to the silhouette
    (IoU below ``BOX_IOU``): where its front/side edge would be there is only background
    between the legs, so the photo is not read (no edge score taken) and the fit is the
    mask's; a box's fit reads it."""
    import generator.pact.inference.mask_layout as mask_layout

    calls = []
    score = mask_layout.edge_score
    monkeypatch.setattr(mask_layout, "edge_score", lambda c, e: calls.append(c) or score(c, e))
    table = _table()
    ids, photo = _raycast(table, 35.0, 15.0, shaded=True)
    alone = fit_box_camera(ids, [2], 0.5)
    assert alone.iou < BOX_IOU
    assert fit_box_camera(ids, [2], 0.5, edges=edge_map(photo, ids > 0)) == alone
    assert not calls
    ids, photo = _raycast(_chest(), 35.0, 20.0, shaded=True)
    fit_box_camera(ids, [2, 3], 0.52, edges=edge_map(photo, ids > 0))
    assert calls


def test_fit_box_camera_maps_the_box_onto_the_mask():
    mask = _raycast(_chest(), azimuth_deg=30.0, elevation_deg=15.0)
    cam = fit_box_camera(mask, [2, 3], depth=0.52)
    h = cam.half_extents
    # the front face's centres of the upper and lower halves land on the two drawers
    upper = cam.to_pixels(np.array([[h[0], 0.0, 0.5 * h[2]]]))[0]
    lower = cam.to_pixels(np.array([[h[0], 0.0, -0.5 * h[2]]]))[0]
    assert mask[int(upper[1]), int(upper[0])] == 2
    assert mask[int(lower[1]), int(lower[0])] == 3
    # the box's projected corners span the silhouette's bounding box
    rows, cols = np.nonzero(mask)
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    px = cam.to_pixels(corners * h)
    assert np.allclose(px.min(axis=0), [cols.min(), rows.min()], atol=3)
    assert np.allclose(px.max(axis=0), [cols.max() + 1, rows.max() + 1], atol=3)


def _sample(depth: int, R=32):
    """A stage-1 sample of the chest with its drawers swapped round and the base full of
    holes: slot 1 low on the front, slot 2 high, ``depth`` cells deep (of 16)."""
    occ = np.zeros((4, R, R, R), bool)
    occ[0, 8:24, 0:32, 6:26] = True
    occ[0, 10:20:3, 4:28:3, 8:24:3] = False  # holes
    occ[0, 24 - depth : 24] = False
    occ[1, 24 - depth : 24, 1:31, 7:15] = True
    occ[2, 24 - depth : 24, 1:31, 17:25] = True
    return occ


def test_layout_puts_parts_where_the_mask_shows_them():
    from scipy import ndimage

    mask = _raycast(_chest(top_id=2, bottom_id=3), azimuth_deg=30.0, elevation_deg=15.0)
    out, cam = layout_from_mask(_sample(depth=10), mask, [0, 1, 2])
    assert cam.iou > 0.9
    # slot 1 (mask id 2) is now on top, slot 2 (id 3) at the bottom
    z1 = np.argwhere(out[1])[:, 2].mean()
    z2 = np.argwhere(out[2])[:, 2].mean()
    assert z1 > z2 + 4
    # both sit on the front face, as deep as in the sample (10 of the box's 16 cells)
    union = out.any(axis=0)
    front = np.argwhere(union)[:, 0].max()
    assert np.ptp(np.argwhere(union)[:, 0]) + 1 == 16
    for k in (1, 2):
        xs = np.unique(np.argwhere(out[k])[:, 0])
        assert xs.max() == front
        assert len(xs) == 10
    # parts are disjoint; the base is one closed block round the drawers: its holes are gone
    assert (
        not (out[0] & out[1]).any() and not (out[0] & out[2]).any() and not (out[1] & out[2]).any()
    )
    assert ndimage.label(out[0])[1] == 1
    assert not (ndimage.binary_fill_holes(union) & ~union).any()


def test_layout_leaves_a_cavity_behind_a_panel():
    from scipy import ndimage

    mask = _raycast(_chest(top_id=2, bottom_id=3), azimuth_deg=30.0, elevation_deg=15.0)
    out, _ = layout_from_mask(_sample(depth=2), mask, [0, 1, 2])
    union = out.any(axis=0)
    for k in (1, 2):
        assert len(np.unique(np.argwhere(out[k])[:, 0])) == 2
    cavity = ndimage.binary_fill_holes(union) & ~union
    assert cavity.sum() > 0.3 * union.sum()  # the space behind the doors, closed by walls
    assert ndimage.label(out[0])[1] == 1


def test_layout_fits_the_depth_when_the_sample_has_it_clearly_wrong():
    # the sample's chest is as deep as it is wide (the chest is half as deep)
    deep = np.zeros((3, 32, 32, 32), bool)
    deep[0, 0:28, 0:32, 6:26] = True
    deep[1, 28:32, 1:31, 16:25] = True
    deep[2, 28:32, 1:31, 7:15] = True
    # seen from above, the top face says otherwise: the box takes the fitted depth
    mask = _raycast(_chest(top_id=2, bottom_id=3), azimuth_deg=30.0, elevation_deg=30.0)
    out, cam = layout_from_mask(deep, mask, [0, 1, 2])
    assert abs(np.log(cam.depth / 0.52)) < 0.2
    union = out.any(axis=0)
    assert abs(np.ptp(np.argwhere(union)[:, 0]) + 1 - 16) <= 3  # 0.52 of the 32-cell width
    # unless told to keep the sample's (a mask drawn from the sample, without a user's)
    assert layout_from_mask(deep, mask, [0, 1, 2], fit_depth=False)[1].depth == 1.0
    # a sample with the chest's own depth keeps it (see the tests above: 16 cells of 32)
    _, kept = layout_from_mask(_sample(depth=10), mask, [0, 1, 2])
    assert kept.depth == 0.5
    # seen nearly level, depth trades against azimuth: the sample's depth stays
    level = _raycast(_chest(top_id=2, bottom_id=3), azimuth_deg=35.0, elevation_deg=5.0)
    _, cam = layout_from_mask(deep, level, [0, 1, 2])
    assert cam.depth == 1.0


def test_layout_takes_the_candidate_depth_that_explains_the_silhouette():
    deep = np.zeros((3, 32, 32, 32), bool)  # the kept sample: as deep as it is wide
    deep[0, 0:28, 0:32, 6:26] = True
    deep[1, 28:32, 1:31, 16:25] = True
    deep[2, 28:32, 1:31, 7:15] = True
    # seen nearly level the free fit is not trusted, but of the samples' depths the chest's
    # own (0.5) explains the silhouette clearly better than 1.0 or 2.0
    level = _raycast(_chest(top_id=2, bottom_id=3), azimuth_deg=35.0, elevation_deg=5.0)
    _, cam = layout_from_mask(deep, level, [0, 1, 2], depths=[2.0, 0.5, 1.0])
    assert cam.depth == 0.5
    assert fit_box_camera(level, [2, 3], depth=[2.0, 0.5, 1.0]).depth == 0.5
    # the same from the other side
    mirrored = _raycast(_chest(top_id=2, bottom_id=3), azimuth_deg=-40.0, elevation_deg=10.0)
    assert fit_box_camera(mirrored, [2, 3], depth=[0.25, 0.5, 1.0, 2.0]).depth == 0.5
    # two depths that explain the silhouette as well (0.5 and 0.6 for the chest's 0.52): the
    # deeper is taken
    assert fit_box_camera(level, [2, 3], depth=[0.25, 0.5, 0.6, 1.0]).depth == 0.6


def test_layout_carves_a_table_between_its_legs():
    table = _table()
    mask = _raycast(table, azimuth_deg=35.0, elevation_deg=15.0)
    R = 32
    occ = np.zeros((3, R, R, R), bool)
    occ[0, 8:24, :, 21:26] = True  # the sample: a top on four rough legs
    for x in (8, 20):
        for y in (0, 28):
            occ[0, x : x + 4, y : y + 4, 6:21] = True
    occ[1, 22:24, 18:28, 20:25] = True
    out, _ = layout_from_mask(occ, mask, [0, 1])
    base = out[0]
    zs = np.argwhere(base)[:, 2]
    feet = base[:, :, zs.min() : zs.min() + 4].sum() / 4  # cells per layer
    top = base[:, :, zs.max() - 1 : zs.max() + 1].sum() / 2
    assert feet < 0.4 * top  # between the feet mostly empty
    xs, ys = np.argwhere(base)[:, 0], np.argwhere(base)[:, 1]
    middle = base[(xs.min() + xs.max()) // 2, (ys.min() + ys.max()) // 2, zs.min() : zs.min() + 6]
    assert not middle.any()
    assert out[1].any()


def test_layout_declines_what_is_no_box():
    R = 16
    occ = np.zeros((2, R, R, R), bool)
    occ[0, 4:12, 4:12, 4:12] = True
    occ[1, 12, 6:10, 6:10] = True
    # an empty sample, a mask without movable parts
    assert layout_from_mask(np.zeros_like(occ), np.ones((8, 8), np.uint8), [0, 1]) is None
    assert layout_from_mask(occ, np.ones((8, 8), np.uint8), [0]) is None
    # a thin diagonal stroke: no box explains it
    mask = np.zeros((64, 64), np.uint8)
    for i in range(64):
        mask[i, max(0, i - 1) : i + 1] = 1
    mask[30:33, 29:32] = 2
    cam = fit_box_camera(mask, [2])
    assert cam.iou < MIN_FIT_IOU
    assert layout_from_mask(occ, mask, [0, 1]) is None


def test_a_chest_of_ten_drawers_keeps_all_ten_past_the_flows_slots():
    """The shipped model has 8 part slots (the base and 7 parts); a mask with 10 drawers
    (ids 2-11, two columns of five) gets slots past the flow's, laid out from the mask:
    stage 1 returns 11 slots, each drawer's cells where its mask puts it (its column and
    row), and the assembled object has ten movable parts, the three the heads never read
    typed by their shape (wide fronts: drawers)."""
    from generator.pact.inference.generate import PActGenerator

    boxes = [((-0.25, -0.5, -0.6), (0.25, 0.5, 0.6), 1)]
    rows = np.linspace(-0.58, 0.58, 6)
    for i in range(10):
        col, row = divmod(i, 5)
        y0, y1 = (-0.48, -0.02) if col == 0 else (0.02, 0.48)
        boxes.append(((0.25, y0, rows[row] + 0.01), (0.27, y1, rows[row + 1] - 0.01), i + 2))
    mask = _raycast(boxes, azimuth_deg=30.0, elevation_deg=15.0)
    shade = np.array([0, 150, *range(60, 260, 20)], np.uint8)  # a grey per id
    image = np.repeat(np.where(mask > 0, shade[mask], 255)[..., None], 3, axis=2).astype(np.uint8)
    gen = PActGenerator.default(device="cpu")
    occ, _ = gen.stage1_parts(image, mask)
    assert occ.shape[0] == 11 and all(occ[k].any() for k in range(1, 11))
    z = [np.argwhere(occ[k])[:, 2].mean() for k in range(1, 11)]
    y = [np.argwhere(occ[k])[:, 1].mean() for k in range(1, 11)]
    for c in (0, 5):  # rows from the bottom up in each column; the columns side by side
        assert all(a < b for a, b in zip(z[c : c + 4], z[c + 1 : c + 5], strict=True))
    assert max(y[:5]) < min(y[5:])
    obj = gen.assemble(gen.run(image, mask, occupancy=occ))
    movable = [p for p in obj.parts if not p.is_base]
    assert len(movable) == 10
    extra = [p for p in movable if int(p.name.rsplit("_", 1)[1]) >= 8]
    assert len(extra) == 3 and all(p.joint.type == "prismatic" for p in extra)


def test_sample_mask_shows_the_samples_parts_where_the_silhouette_is():
    """Without a part mask, the sample's own parts seen in the view that matches the
    photo's silhouette stand in for one: on a chest whose sample has its drawers right,
    each drawer's pixels land on that drawer in the (independently ray-cast) picture."""
    from generator.pact.inference.mask_agreement import sample_mask

    truth = _raycast(_chest(top_id=2, bottom_id=3), azimuth_deg=30.0, elevation_deg=15.0)
    occ = np.zeros((3, 32, 32, 32), bool)
    occ[0, 8:24, 0:32, 6:26] = True  # 16 deep, 32 wide, 20 tall: the chest's proportions
    occ[0, 22:24, 1:31, 7:25] = False
    occ[1, 22:24, 1:31, 16:25] = True  # slot 1 (id 2) the upper drawer
    occ[2, 22:24, 1:31, 7:15] = True  # slot 2 (id 3) the lower one
    own = sample_mask(occ, truth > 0)
    assert ((own > 0) == (truth > 0)).all()  # exactly the silhouette
    for pid in (2, 3):
        a, b = own == pid, truth == pid
        assert (a & b).sum() / (a | b).sum() > 0.6
    # a speck of a part (one voxel across the front) is no part: it counts as the base
    occ[0] |= occ[2]
    occ[2] = False
    occ[2, 22:24, 15:16, 10:11] = True
    occ[0] &= ~occ[2]
    own = sample_mask(occ, truth > 0)
    assert set(np.unique(own)) == {0, 1, 2}


def test_sample_mask_keeps_a_parts_largest_piece():
    """A sample that also draws a corner of the upper drawer as the lower drawer's: that
    stray piece is the base in the sample's mask, the lower drawer one piece where the
    picture has it."""
    from scipy import ndimage

    from generator.pact.inference.mask_agreement import sample_mask

    truth = _raycast(_chest(top_id=2, bottom_id=3), azimuth_deg=30.0, elevation_deg=15.0)
    occ = np.zeros((3, 32, 32, 32), bool)
    occ[0, 8:24, 0:32, 6:26] = True
    occ[0, 22:24, 1:31, 7:25] = False
    occ[1, 22:24, 1:31, 16:25] = True
    occ[2, 22:24, 1:31, 7:15] = True
    occ[1, 22:24, 1:6, 20:25] = False  # the upper drawer's corner drawn as slot 2
    occ[2, 22:24, 1:6, 20:25] = True
    own = sample_mask(occ, truth > 0)
    assert ndimage.label(own == 3, structure=np.ones((3, 3), bool))[1] == 1
    assert ((own == 3) & (truth == 2)).sum() <= 0.02 * (own == 3).sum()
    a, b = own == 3, truth == 3
    assert (a & b).sum() / (a | b).sum() > 0.6


def test_sample_mask_of_an_empty_sample_or_silhouette_is_empty():
    from generator.pact.inference.mask_agreement import sample_mask

    occ = np.zeros((2, 8, 8, 8), bool)
    sil = np.ones((16, 16), bool)
    assert not sample_mask(occ, sil).any()
    occ[0, 2:6, 2:6, 2:6] = True
    assert not sample_mask(occ, np.zeros((16, 16), bool)).any()
