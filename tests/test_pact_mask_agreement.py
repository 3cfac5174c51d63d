"""Render-and-compare of stage-1 part voxels against a part mask, and the stage-1
generator's choice among samples."""

from __future__ import annotations

import numpy as np
import pytest

from generator.pact.inference.mask_agreement import (
    agreement,
    agreements,
    carve_missing,
    id_iou,
    mask_ids,
    relabel_front,
    render_ids,
    render_visible,
    sample_mask,
    sample_masks,
    surface_points,
    view_rotation,
)
from generator.pact.inference.stage1_generator import Stage1Generator

R = 16


def _two_doors(swap: bool = False) -> np.ndarray:
    """Slot 0 a base box (x < 12), slots 1 and 2 two doors on its front (x 12-13), side by
    side: slot 1 at low y, slot 2 at high y (or the other way round with ``swap``)."""
    occ = np.zeros((3, R, R, R), bool)
    occ[0, :12] = True
    a, b = (2, 1) if swap else (1, 2)
    occ[a, 12:14, :8] = True
    occ[b, 12:14, 8:] = True
    return occ


def _front_mask() -> np.ndarray:
    """A 64 x 64 part mask of ``_two_doors()`` seen from the front: the door of slot 1
    (id 2) on the image's left, slot 2's (id 3) on the right."""
    m = np.zeros((64, 64), np.uint8)
    m[8:56, 8:32] = 2
    m[8:56, 32:56] = 3
    return m


def test_view_rotation_axes_by_hand():
    np.testing.assert_allclose(
        view_rotation(0.0, 0.0), [[0, 1, 0], [0, 0, -1], [1, 0, 0]], atol=1e-12
    )
    # camera on +y: image right is -x, down is -z, towards the camera +y
    np.testing.assert_allclose(
        view_rotation(np.pi / 2, 0.0), [[-1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12
    )
    # 45 degrees up: the camera direction between +x and +z, the rows orthonormal
    v = view_rotation(0.0, np.pi / 4)
    np.testing.assert_allclose(v[2], [np.sqrt(0.5), 0, np.sqrt(0.5)], atol=1e-12)
    np.testing.assert_allclose(v @ v.T, np.eye(3), atol=1e-12)


def test_view_rotation_is_the_cross_product_definition_to_the_bit():
    """The written-out cross products give exactly what np.cross gives (the box fit and the
    sample choice compare scores, so a last-bit change could change a generated object)."""
    rng = np.random.default_rng(0)
    for az, el in rng.uniform((-2.0, 0.0), (2.0, 1.2), size=(500, 2)):
        d = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        right = np.cross(-d, (0.0, 0.0, 1.0))
        right /= np.linalg.norm(right)
        want = np.stack([right, -np.cross(right, -d), d])
        assert np.array_equal(view_rotation(az, el), want)


def test_id_iou_and_mask_ids_by_hand():
    a = np.array([[1, 1], [2, 0]])
    b = np.array([[1, 0], [2, 2]])
    np.testing.assert_allclose(id_iou(a, b, np.array([1, 2])), [0.5, 0.5])
    m = np.zeros((10, 10), np.uint8)
    m[2:6, 4:8] = 1
    m[2:4, 4:6] = 9  # a part beyond the model's slots counts as the base
    out = mask_ids(m, max_id=3, grid=4)
    assert out.shape == (4, 4) and set(np.unique(out)) == {1}  # cropped to the silhouette
    with pytest.raises(ValueError, match="empty"):
        mask_ids(np.zeros((5, 5), np.uint8), 3)


def test_render_visible_nearest_point_wins_by_hand():
    """Seen from the front (image right +y, down -z, towards the camera +x): three points
    on one pixel column at y = 0 (x 0, 2 and 2 again: the nearest wins, the later of two
    equally near), one at y = 2, one at z = 1; a 3 x 2 image, resampled to 4 x 4."""
    pts = np.array(
        [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 2.0, 0.0], [0.0, 2.0, 1.0]]
    )
    img = render_visible(pts, view_rotation(0.0, 0.0), grid=4)
    # u = y spans 0..2: ceil(2 / 0.7) = 3 columns (y = 0 in column 0, y = 2 in column 2);
    # v = -z spans -1..0: ceil(1 / 0.7) = 2 rows (z = 1 in row 0, z = 0 in row 1). The 4
    # resampled columns read columns 0, 1, 1, 2 and the 4 rows read rows 0, 0, 1, 1.
    assert img.shape == (4, 4)
    top, bottom = img[0], img[3]
    assert list(bottom) == [2, -1, -1, 3]  # y = 0: point 2 (x = 2, after 1); y = 2: point 3
    assert list(top) == [-1, -1, -1, 4]  # only point 4 is at z = 1
    assert render_visible(pts, view_rotation(np.pi, 0.0), grid=4)[3, 3] == 0  # from behind


def test_agreement_prefers_the_layout_the_mask_shows():
    mask = _front_mask()
    right = agreement(_two_doors(), mask)
    swapped = agreement(_two_doors(swap=True), mask)
    assert right > 0.9  # the front view reproduces the mask
    assert swapped < right - 0.5  # from the side one door hides the other: not zero
    missing = _two_doors()
    missing[2] = False
    assert agreement(missing, mask) < 0.6  # id 3 unmatched: at most half the mean
    assert agreement(np.zeros((3, R, R, R), bool), mask) == 0.0


def test_several_samples_scored_at_once_as_one_by_one():
    """agreements and sample_masks (threads) give what agreement and sample_mask give."""
    samples = [_two_doors(), _two_doors(swap=True), _two_doors()[:2]]
    mask = _front_mask()
    assert agreements(samples, mask) == [agreement(o, mask) for o in samples]
    assert agreements(samples, mask)[0] > agreements(samples, mask)[1]
    sil = mask > 0
    for got, o in zip(sample_masks(samples, [sil] * 3), samples, strict=True):
        np.testing.assert_array_equal(got, sample_mask(o, sil))


def test_best_candidate_realizes_the_mask_parts_then_agrees_best():
    mask = _front_mask()
    shown = [1, 2]  # the slots of ids 2 and 3, the ones the mask shows
    right, swapped, missing = _two_doors(), _two_doors(swap=True), _two_doors()
    missing[2] = False
    occ = np.stack([missing, swapped, right])
    exists = occ.reshape(3, 3, -1).any(axis=2)
    assert Stage1Generator._best_candidate(occ, exists, shown, mask) == 2
    # a lone complete candidate wins over an incomplete one without any rendering
    assert Stage1Generator._best_candidate(occ[:2], exists[:2], shown, mask) == 1
    with pytest.raises(ValueError, match="candidates"):
        Stage1Generator({}, None, candidates=0)  # type: ignore[arg-type]


def test_consensus_candidate_keeps_the_median_part_count():
    """Without a mask: of four samples, two draw the two doors, one three parts, one a
    single door; a two-door sample is kept (the median count, 1 2 2 3), the one whose silhouette matches the photo's
    (the other lacks a corner the photo's solid silhouette shows)."""
    sil = _front_mask() > 0
    three = _two_doors()
    three = np.concatenate([three, np.zeros((1, R, R, R), bool)])
    three[3, 12:14, 4:12, 4:12] = True  # a third part in front of the two doors
    three[1:3] &= ~three[3]
    one = _two_doors()
    one[1] |= one[2]
    one[2] = False
    holed = _two_doors()
    holed[:, :, 10:, 10:] = False  # a corner cut off along the whole depth
    pad = np.zeros((1, R, R, R), bool)
    occ = np.stack([three, np.concatenate([holed, pad]), np.concatenate([one, pad])])
    occ = np.concatenate([occ, np.concatenate([_two_doors(), pad])[None]])

    def keep(candidates: np.ndarray) -> int:
        own = [sample_mask(o, sil) for o in candidates]
        return Stage1Generator._consensus_candidate(candidates, own, sil)

    assert keep(occ) == 3
    # samples that show no movable part do not count while one does
    empty = np.zeros_like(occ[0])
    empty[0] = occ[3].any(axis=0)
    assert keep(np.stack([empty, empty, occ[2]])) == 2
    with pytest.raises(ValueError, match="candidates"):
        Stage1Generator({}, None, candidates_without_mask=0)  # type: ignore[arg-type]


def test_carve_missing_takes_the_base_behind_the_parts_mask_pixels():
    occ = _two_doors()
    occ[2] = False  # the sample left the right door empty; the mask shows it
    out = carve_missing(occ, _front_mask(), [1, 2])
    expected = np.zeros((R, R, R), bool)
    expected[10:12, 8:, :] = True  # the base's front face behind id 3, as deep as door 1
    assert np.array_equal(out[2], expected)
    assert np.array_equal(out[0], occ[0] & ~expected)
    assert np.array_equal(out[1], occ[1])  # other parts are never taken from
    assert not occ[2].any()  # the input is left alone
    # nothing to carve: a realized slot, or a slot the mask pixels show no base under
    assert np.array_equal(carve_missing(_two_doors(), _front_mask(), [1, 2]), _two_doors())
    no_base = occ.copy()
    no_base[0] = False
    assert not carve_missing(no_base, _front_mask(), [2])[2].any()


def _stacked_drawers(R: int = 32) -> np.ndarray:
    """A block (slot 0) with two drawer fronts 4 voxels deep: slot 1 on top, slot 2 below."""
    occ = np.zeros((3, R, R, R), bool)
    occ[0, 4:24, 2:30, 2:30] = True
    occ[1, 20:24, 4:28, 16:28] = True
    occ[2, 20:24, 4:28, 4:15] = True
    occ[0] &= ~(occ[1] | occ[2])
    return occ


def test_relabel_front_moves_parts_to_where_the_mask_puts_them():
    gt = _stacked_drawers()
    pts, labels, _ = surface_points(gt)
    sample = np.zeros_like(gt)  # the right row count, the wrong layout: side by side
    sample[0] = gt.any(axis=0)
    sample[1, 20:24, 4:16, 4:28] = True
    sample[2, 20:24, 16:28, 4:28] = True
    sample[0] &= ~(sample[1] | sample[2])
    for az, el in [(0, 0), (20, 20), (-50, 10)]:
        mask = render_ids(pts, labels, view_rotation(np.radians(az), np.radians(el)), 80)
        out = relabel_front(sample, mask, [0, 1, 2])
        assert np.array_equal(out.any(axis=0), sample.any(axis=0))  # same union
        assert out.sum(axis=0).max() == 1  # disjoint
        for k in (1, 2):  # footprints on the front: exact head-on, close when oblique
            a, b = out[k].any(axis=0), gt[k].any(axis=0)
            iou = (a & b).sum() / (a | b).sum()
            assert iou == 1.0 if (az, el) == (0, 0) else iou > 0.8
        assert out[1, 20:24].any() and not out[1, :20].any()  # as deep as the sample's part
        assert agreement(out, mask) > agreement(sample, mask) + 0.3
    assert not sample[1, 20:24, 16:28].any()  # the input is left alone


def test_relabel_front_keeps_a_sample_it_cannot_improve():
    gt = _stacked_drawers()
    pts, labels, _ = surface_points(gt)
    mask = render_ids(pts, labels, view_rotation(0.0, 0.0), 80)
    assert np.array_equal(relabel_front(gt, mask, [0, 1, 2]), gt)  # already right
    no_parts = np.zeros_like(gt)
    no_parts[0] = gt.any(axis=0)
    assert np.array_equal(relabel_front(no_parts, mask, [0]), no_parts)  # only the base
    # a mask that gives part 2 no front column would empty it: the sample is kept
    one_part = np.where(mask == 3, 1, mask)
    sample = gt.copy()
    assert np.array_equal(relabel_front(sample, one_part, [0, 1, 2]), gt)


def _desk(R: int = 32) -> np.ndarray:
    """Slot 0 a low, wide body (x 0-7, y 0-31, z 8-23: 8 deep, 32 wide, 16 tall), slot 1
    a drawer front one voxel deep on its face (x 8, y 4-11, z 18-21; 9 deep with it), slot 2 a shelf
    one voxel thick across it (z 12)."""
    occ = np.zeros((3, R, R, R), bool)
    occ[0, :8, :, 8:24] = True
    occ[1, 8, 4:12, 18:22] = True
    occ[0, :8, :, 12] = False
    occ[2, :8, :, 12] = True
    return occ


def test_height_scale_fits_the_silhouettes_aspect_by_hand():
    """Seen from the front (the only view offered), the body is 32 wide and 16 tall:
    against a square silhouette its height must double, against one 4 to 1 halve;
    against one of its own aspect it stays."""
    from generator.pact.inference.mask_agreement import height_scale

    front = (view_rotation(0.0, 0.0),)
    occ = _desk()
    square = np.zeros((64, 64), np.uint8)
    square[10:50, 10:50] = 1
    assert height_scale(occ, square, front) == pytest.approx(2.0, rel=0.03)
    wide = np.zeros((64, 64), np.uint8)
    wide[20:30, 4:44] = 1
    assert height_scale(occ, wide, front) == pytest.approx(0.5, rel=0.03)
    same = np.zeros((64, 64), np.uint8)
    same[10:30, 4:44] = 1
    assert height_scale(occ, same, front) == pytest.approx(1.0, rel=0.03)


def test_rescale_height_keeps_parts_and_thin_panels():
    """Doubled in height the desk is 32 tall and, its longest side spanning the grid
    again, still 32 wide and 9 deep; halved, it is 8 tall and the one-voxel shelf and
    drawer front survive (each source cell fills the target cells it touches). Parts stay
    disjoint, none is emptied, and a factor of 1 changes nothing. ``fit_height`` leaves a
    sample a third too low alone (within the tolerance) and doubles one half as tall as
    the silhouette says."""
    from generator.pact.inference.mask_agreement import fit_height, rescale_height

    occ = _desk()
    for factor, tall in ((2.0, 32), (0.5, 8)):
        out = rescale_height(occ, factor)
        ext = np.ptp(np.argwhere(out.any(axis=0)), axis=0) + 1
        assert ext.tolist() == [9, 32, tall]
        assert (out.sum(axis=0) <= 1).all()
        assert all(out[k].any() for k in range(3))
        shelf_z = np.unique(np.argwhere(out[2])[:, 2])
        assert len(shelf_z) == (2 if factor == 2.0 else 1)
        assert len(np.unique(np.argwhere(out[1])[:, 0])) == 1  # still one voxel deep
    assert np.array_equal(rescale_height(occ, 1.0), occ)
    front = (view_rotation(0.0, 0.0),)
    same = np.zeros((64, 64), np.uint8)
    same[10:30, 4:44] = 1
    kept, f = fit_height(occ, same, front)
    assert f == 1.0 and np.array_equal(kept, occ)
    a_third_taller = np.zeros((64, 64), np.uint8)  # 40 x 26.7: within the tolerance
    a_third_taller[10:37, 4:44] = 1
    kept, f = fit_height(occ, a_third_taller, front)
    assert f == 1.0 and np.array_equal(kept, occ)
    square = np.zeros((64, 64), np.uint8)
    square[10:50, 10:50] = 1
    fitted, f = fit_height(occ, square, front)
    assert f == pytest.approx(2.0, rel=0.03)
    assert (np.ptp(np.argwhere(fitted.any(axis=0)), axis=0) + 1).tolist() == [9, 32, 32]
