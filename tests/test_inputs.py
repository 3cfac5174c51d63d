"""The image-folder input format (docs/input-format.md)."""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from asset_pipeline.inputs.asset_ids import ID_PATTERN, asset_id_for, is_reserved_id
from asset_pipeline.inputs.errors import InputError
from asset_pipeline.inputs.folder import (
    IMAGE_SUFFIXES,
    MASK_SUFFIX,
    InputItem,
    InputListing,
    SkippedFile,
    discover_inputs,
    load_input,
)
from asset_pipeline.inputs.hints import check_hints
from asset_pipeline.inputs.mask import (
    MASK_EDGE_REFUSE,
    MASK_FLOOR_IOU,
    MASK_MIN_IOU,
    MASK_OUTLINE_COVERED,
    check_mask_edges,
    check_mask_matches_photo,
    mask_edge_support,
    mask_outline_coverage,
)
from asset_pipeline.inputs.photo import MIN_PHOTO_SIZE, estimate_silhouette

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "images"

# The object of the synthetic photos: rows 8..40, columns 16..48 of a 64x48 (w x h) image.
OBJ = (slice(8, 40), slice(16, 48))


def _rgba(path: Path, w: int = 64, h: int = 48, opaque: bool = False) -> None:
    """An RGBA photo whose alpha silhouette is the OBJ box, a darker door inside it."""
    a = np.zeros((h, w, 4), np.uint8)
    a[..., :3] = 120
    a[(*OBJ, slice(0, 3))] = 180
    a[12:36, 20:44, :3] = 90
    a[(*OBJ, 3)] = 255
    if opaque:
        a[..., 3] = 255
    Image.fromarray(a, "RGBA").save(path)


def _mask(path: Path, ids: np.ndarray, mode: str = "L") -> None:
    img = Image.fromarray(ids.astype(np.uint8), "L")
    if mode != "L":
        img = img.convert(mode)
    img.save(path)


def _good_mask(w: int = 64, h: int = 48) -> np.ndarray:
    """Base over the OBJ box, a door (id 2) inside it."""
    m = np.zeros((h, w), np.uint8)
    m[OBJ] = 1
    m[12:36, 20:44] = 2
    return m


def _on_plain_background(w: int = 128, h: int = 96, box=(slice(20, 80), slice(10, 60))):
    """(h, w, 3) uint8: a textured dark box on a white background (a product photo)."""
    rng = np.random.default_rng(0)
    img = np.full((h, w, 3), 245, np.uint8)
    img[box] = rng.integers(30, 90, (box[0].stop - box[0].start, box[1].stop - box[1].start, 3))
    return img


def _box_mask(w: int, h: int, box) -> np.ndarray:
    m = np.zeros((h, w), np.uint8)
    m[box] = 1
    return m


def _expect(tmp_path: Path, match: str, file: str) -> InputError:
    (item,) = discover_inputs(tmp_path)
    with pytest.raises(InputError, match=match) as e:
        load_input(item)
    assert str(e.value).startswith(str(tmp_path / file) + ": ")
    return e.value


# --------------------------------------------------------------------------- basics


def test_discover_and_load(tmp_path: Path) -> None:
    _rgba(tmp_path / "b.png")
    _mask(tmp_path / "b.mask.png", _good_mask())
    (tmp_path / "b.json").write_text(
        json.dumps({"category": "cabinet", "height": 0.9, "id": "cab-b"})
    )
    jpg = Image.new("RGB", (40, 36), (10, 20, 30))
    jpg.paste((200, 180, 160), (8, 6, 30, 28))  # an object on a dark background
    jpg.save(tmp_path / "a.jpg")
    _mask(tmp_path / "orphan.mask.png", _good_mask())
    listing = discover_inputs(tmp_path)
    assert isinstance(listing, InputListing)
    assert [i.name for i in listing.items] == ["a", "b"]
    assert [i.name for i in listing] == ["a", "b"] and len(listing) == 2  # acts as the items
    a, b = listing
    assert a.mask_path is None and a.hints_path is None
    assert b.mask_path == tmp_path / "b.mask.png" and b.hints_path == tmp_path / "b.json"
    assert (a.asset_id, b.asset_id) == ("a", "cab-b")

    la = load_input(a)
    assert la.image.shape == (36, 40, 3) and la.image.dtype == np.uint8
    assert la.alpha is None and la.mask is None and la.hints == {}
    assert la.asset_id == "a" and la.category == "unknown" and la.height is None

    lb = load_input(b)
    assert lb.image.shape == (48, 64, 3) and lb.alpha.shape == (48, 64)
    assert lb.alpha[10, 20] == 255 and lb.alpha[0, 0] == 0
    assert lb.mask.dtype == np.uint8 and lb.part_count == 2
    assert (lb.asset_id, lb.category, lb.height) == ("cab-b", "cabinet", 0.9)


def test_input_hash_tracks_every_file(tmp_path: Path) -> None:
    _rgba(tmp_path / "x.png")
    h0 = discover_inputs(tmp_path)[0].input_hash
    assert discover_inputs(tmp_path)[0].input_hash == h0
    _mask(tmp_path / "x.mask.png", _good_mask())
    h1 = discover_inputs(tmp_path)[0].input_hash
    (tmp_path / "x.json").write_text("{}")
    h2 = discover_inputs(tmp_path)[0].input_hash
    assert len({h0, h1, h2}) == 3
    single = discover_inputs(tmp_path / "x.png")  # a single photo works too
    assert single[0].input_hash == h2 and single.skipped == []


def test_opaque_alpha_and_grey_rgb_mask(tmp_path: Path) -> None:
    _rgba(tmp_path / "o.png", opaque=True)
    _mask(tmp_path / "o.mask.png", _good_mask(), mode="RGB")
    li = load_input(discover_inputs(tmp_path)[0])
    assert li.alpha is None
    assert np.array_equal(li.mask, _good_mask())


def test_corrupt_image(tmp_path: Path) -> None:
    (tmp_path / "c.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    _expect(tmp_path, "unreadable or corrupt image", "c.png")


def test_mask_size_mismatch(tmp_path: Path) -> None:
    _rgba(tmp_path / "c.png")
    _mask(tmp_path / "c.mask.png", _good_mask(w=65))
    _expect(tmp_path, "mask is 65x48 but the image is 64x48", "c.mask.png")


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda m: m.__setitem__(m == 1, 0), "no base"),
        (lambda m: m.__setitem__(slice(None), 40), "above 16"),  # all of it: not ids
    ],
)
def test_mask_ids(tmp_path: Path, edit, match: str) -> None:
    _rgba(tmp_path / "c.png")
    m = _good_mask()
    edit(m)
    _mask(tmp_path / "c.mask.png", m)
    _expect(tmp_path, match, "c.mask.png")


def test_part_ids_that_skip_a_number_are_renumbered_with_a_warning(tmp_path: Path) -> None:
    _rgba(tmp_path / "c.png")
    m = _good_mask()
    m[14:20, 22:30] = 4  # parts 1, 2, 4: part 3 is hidden in this view
    _mask(tmp_path / "c.mask.png", m)
    loaded = load_input(discover_inputs(tmp_path)[0])
    assert sorted(np.unique(loaded.mask)) == [0, 1, 2, 3] and loaded.part_count == 3
    assert (loaded.mask[14:20, 22:30] == 3).all() and (loaded.mask == 2).sum() == (m == 2).sum()
    (warning,) = loaded.warnings
    assert warning.startswith(f"{tmp_path / 'c.mask.png'}: mask part ids [1, 2, 4] skip [3]")
    assert "renumbered 4 -> 3" in warning


def _soft_mask() -> tuple[np.ndarray, np.ndarray]:
    """(ids as an anti-aliasing tool saves them, the exact ids): a cabinet (base 1) with
    a tilted door (3) and a drawer (2), drawn at 4x and scaled down smoothly, so that its
    slanted edges carry in-between values."""
    from PIL import ImageDraw

    big = Image.new("L", (512, 384), 0)
    draw = ImageDraw.Draw(big)
    draw.rectangle([64, 64, 448, 320], fill=1)
    draw.polygon([(96, 96), (240, 112), (228, 296), (84, 280)], fill=3)
    draw.rectangle([272, 96, 416, 200], fill=2)
    soft = np.asarray(big.resize((128, 96), Image.BILINEAR))
    exact = np.asarray(big.resize((128, 96), Image.NEAREST))
    return soft.copy(), exact


def test_soft_edges_specks_and_holes_are_cleaned_with_a_warning(tmp_path: Path) -> None:
    soft, exact = _soft_mask()
    assert (soft != exact).sum() > 20  # in-between values along the door's slanted edges
    soft[60:62, 100:102] = 3  # a speck of the door on the base
    soft[70:72, 90:92] = 0  # a small hole in the base
    soft[[17, 40, 77], [20, 110, 50]] = 200  # stray values that are no id
    img = _on_plain_background(box=(slice(16, 80), slice(16, 112)))
    Image.fromarray(img).save(tmp_path / "cab.png")
    _mask(tmp_path / "cab.mask.png", soft)
    loaded = load_input(discover_inputs(tmp_path)[0])
    assert loaded.part_count == 3  # no part made of in-between values
    assert (loaded.mask[60:62, 100:102] == 1).all() and (loaded.mask[70:72, 90:92] == 1).all()
    assert (loaded.mask[[17, 40, 77], [20, 110, 50]] == 1).all()
    assert (loaded.mask != exact).sum() < (soft != exact).sum() / 2
    (warning,) = [w for w in loaded.warnings if "mask cleaned" in w]
    assert warning.startswith(f"{tmp_path / 'cab.mask.png'}: mask cleaned: 3 px of values above")
    assert "specks" in warning and "small holes" in warning


def test_a_movable_part_seen_edge_on_is_kept_when_it_is_the_only_one(tmp_path: Path) -> None:
    """A top-loader's lid seen from the front is a 3 px strip along the top: thin as the
    in-between values of an edge, which go when other movable parts remain, but the
    mask's only movable part, so it stays (with a warning) and the item keeps its part."""
    box = (slice(20, 80), slice(10, 60))
    img = _on_plain_background(box=box)
    Image.fromarray(img).save(tmp_path / "w.png")
    ids = _box_mask(128, 96, box)
    ids[20:23, 14:56] = 2  # the lid's front edge
    _mask(tmp_path / "w.mask.png", ids)
    loaded = load_input(discover_inputs(tmp_path)[0])
    assert loaded.part_count == 2 and (loaded.mask[20:23, 14:56] == 2).all()
    (warning,) = [w for w in loaded.warnings if "sliver" in w]
    assert warning.startswith(f"{tmp_path / 'w.mask.png'}: part 2 is a sliver of 126 px")
    ids[40:70, 20:50] = 3  # with a door beside it, the strip is an edge's in-between values
    _mask(tmp_path / "w.mask.png", ids)
    loaded = load_input(discover_inputs(tmp_path)[0])
    assert loaded.part_count == 2 and (loaded.mask[40:70, 20:50] == 2).all()  # 3 -> 2
    assert not (loaded.mask[20:23, 14:56] == 2).any()  # the strip went to its neighbours
    assert not any("sliver" in w for w in loaded.warnings)


@pytest.mark.parametrize(
    "picture, match",
    [
        ("photo", "above 16 in 100% of its pixels.*is this a photo"),
        ("random ids", "this is not a mask of part ids"),
    ],
)
def test_a_picture_saved_as_a_mask_is_still_refused(tmp_path: Path, picture, match) -> None:
    img = _on_plain_background()
    Image.fromarray(img).save(tmp_path / "p.png")
    if picture == "photo":
        ids = np.asarray(Image.fromarray(img).convert("L"))
    else:  # a picture of few levels: every pixel its own speck
        ids = np.random.default_rng(5).integers(0, 4, img.shape[:2]).astype(np.uint8)
    _mask(tmp_path / "p.mask.png", ids)
    _expect(tmp_path, match, "p.mask.png")


def test_colour_mask_refused(tmp_path: Path) -> None:
    _rgba(tmp_path / "c.png")
    a = np.zeros((48, 64, 3), np.uint8)
    a[2, 2] = (255, 0, 0)
    Image.fromarray(a, "RGB").save(tmp_path / "c.mask.png")
    _expect(tmp_path, "colour channels that differ", "c.mask.png")


@pytest.mark.parametrize(
    "text, match",
    [
        ("{not json", "not valid JSON"),
        ('{"colour": "red"}', "unknown hint keys"),
        ('{"height": -1}', "height"),
        ('{"height": "tall"}', "height"),
        ('{"category": "sofa"}', "category"),
        ('{"id": "../evil"}', "id"),
        ('{"id": "registry.sqlite"}', "reserved"),
        ("[1, 2]", "JSON object"),
        ('{"parts": {"2": {"motion": "slide_up"}}}', "parts.2.motion"),
        ('{"parts": {"1": {"motion": "drawer"}}}', "movable part's mask id"),
        ('{"parts": {"2": {"hinge": "left"}}}', "unknown keys"),
        ('{"parsed": {"category": 1.5}}', "confidence"),
    ],
)
def test_bad_hints(tmp_path: Path, text: str, match: str) -> None:
    _rgba(tmp_path / "c.png")
    (tmp_path / "c.json").write_text(text)
    (item,) = discover_inputs(tmp_path)
    assert item.asset_id == "c"  # bad hints do not raise here: the id falls back to the name
    _expect(tmp_path, match, "c.json")


def test_duplicate_names_and_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such folder"):
        discover_inputs(tmp_path / "nope")
    _rgba(tmp_path / "d.png")
    Image.new("RGB", (2, 2)).save(tmp_path / "d.jpg")
    with pytest.raises(InputError, match="share the name"):
        discover_inputs(tmp_path)


def test_check_hints_accepts_all_keys() -> None:
    h = {"id": "x_1", "category": "washing_machine", "height": 1, "seed": 3, "notes": "n"}
    assert check_hints(h) == {**h, "height": 1.0}
    parsed = {"by": "parser-1", "category": 0.9, "mask": 0.75, "parts": {"2": 0.5}}
    h = {"parts": {"2": {"motion": "door_left"}, "3": {"motion": "lid"}}, "parsed": parsed}
    assert check_hints(h) == h


def test_motions_follow_a_mask_renumbered_for_a_hidden_part(tmp_path: Path) -> None:
    """A mask whose ids skip 3 (a part hidden in this view) is renumbered 4 -> 3; the
    hints' motions and parser confidences, given by the ids as saved, follow."""
    _rgba(tmp_path / "r.png")
    ids = _good_mask()
    ids[14:20, 22:30] = 4
    _mask(tmp_path / "r.mask.png", ids)
    hints = {"parts": {"2": {"motion": "door_left"}, "4": {"motion": "drawer"}},
             "parsed": {"parts": {"4": 0.8}}}  # fmt: skip
    (tmp_path / "r.json").write_text(json.dumps(hints))
    (item,) = discover_inputs(tmp_path)
    loaded = load_input(item)
    assert sorted(np.unique(loaded.mask).tolist()) == [0, 1, 2, 3]
    assert loaded.hints["parts"] == {"2": {"motion": "door_left"}, "3": {"motion": "drawer"}}
    assert loaded.hints["parsed"]["parts"] == {"3": 0.8}
    assert any("renumbered" in w for w in loaded.warnings)


def test_motions_for_a_part_the_mask_lacks_are_refused(tmp_path: Path) -> None:
    _rgba(tmp_path / "m.png")
    _mask(tmp_path / "m.mask.png", _good_mask())
    (tmp_path / "m.json").write_text('{"parts": {"3": {"motion": "drawer"}}}')
    _expect(tmp_path, r"no part with id \[3\]", "m.json")


def test_motions_without_a_mask_are_refused(tmp_path: Path) -> None:
    _rgba(tmp_path / "n.png")
    (tmp_path / "n.json").write_text('{"parts": {"2": {"motion": "drawer"}}}')
    _expect(tmp_path, "has no mask", "n.json")


def test_bundled_examples_all_load() -> None:
    listing = discover_inputs(EXAMPLES)
    assert len(listing) == 8 and listing.skipped == []
    for item in listing:
        assert item.mask_path is not None and item.hints_path is not None
        loaded = load_input(item)
        assert loaded.part_count >= 2 and loaded.asset_id == item.name


# --------------------------------------------------------------------------- 1. tiny photos


@pytest.mark.parametrize("size", [(1, 1), (31, 200), (200, 31)])
def test_tiny_photo_refused(tmp_path: Path, size: tuple[int, int]) -> None:
    Image.new("RGB", size, (200, 10, 10)).save(tmp_path / "t.png")
    err = _expect(tmp_path, "needed to see an object", "t.png")
    w, h = size
    assert f"photo is {w}x{h} px; at least 32x32 px are needed to see an object" in str(err)


def test_plain_photo_refused(tmp_path: Path) -> None:
    """A photo of one colour holds no object (an all-grey or all-white picture)."""
    Image.new("RGB", (128, 96), (200, 200, 200)).save(tmp_path / "grey.png")
    with pytest.raises(InputError, match=r"grey.png: the photo is one plain colour"):
        load_input(discover_inputs(tmp_path)[0])


def test_smallest_photo_accepted(tmp_path: Path) -> None:
    img = Image.new("RGB", (MIN_PHOTO_SIZE, MIN_PHOTO_SIZE))
    img.paste((200, 180, 160), (8, 8, 24, 24))
    img.save(tmp_path / "t.png")
    assert load_input(discover_inputs(tmp_path)[0]).image.shape == (32, 32, 3)


# --------------------------------------------------------------------------- 2. empty alpha


def test_empty_alpha_refused(tmp_path: Path) -> None:
    Image.new("RGBA", (64, 64), (120, 120, 120, 0)).save(tmp_path / "e.png")
    err = _expect(tmp_path, "silhouette is empty", "e.png")
    assert "remove the alpha channel" in str(err) and "paint the object opaque" in str(err)


@pytest.mark.parametrize("opaque_pixels, ok", [(63, False), (64, True)])
def test_alpha_silhouette_minimum(tmp_path: Path, opaque_pixels: int, ok: bool) -> None:
    a = np.zeros((64, 64, 4), np.uint8)
    a.reshape(-1, 4)[:opaque_pixels, 3] = 128  # 128 counts as foreground; 64 px is the minimum
    a[-1, -1, 3] = 127  # semi-transparent background does not count
    Image.fromarray(a, "RGBA").save(tmp_path / "s.png")
    if ok:
        assert load_input(discover_inputs(tmp_path)[0]).alpha is not None
    else:
        _expect(tmp_path, "silhouette is empty", "s.png")


# --------------------------------------------------------------------------- 3. empty mask


def test_empty_mask_refused(tmp_path: Path) -> None:
    _rgba(tmp_path / "m.png")
    _mask(tmp_path / "m.mask.png", np.zeros((48, 64), np.uint8))
    err = _expect(tmp_path, "mask is empty", "m.mask.png")
    assert "(no pixel has a part id > 0)" in str(err)


def test_small_mask_on_busy_photo_kept(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    Image.fromarray(rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)).save(tmp_path / "m.png")
    m = np.zeros((48, 64), np.uint8)
    m[20:22, 30:32] = 1  # four pixels of base: small, but a mask
    _mask(tmp_path / "m.mask.png", m)
    assert load_input(discover_inputs(tmp_path)[0]).part_count == 1


# --------------------------------------------------------------------------- 4. mask vs photo


def test_mask_of_another_photo_refused_alpha(tmp_path: Path) -> None:
    _rgba(tmp_path / "p.png")  # silhouette: rows 8..40, columns 16..48
    m = np.zeros((48, 64), np.uint8)
    m[8:40, 40:64] = 1  # IoU 256 / 1536 with the silhouette
    _mask(tmp_path / "p.mask.png", m)
    err = _expect(tmp_path, "the mask does not match the photo", "p.mask.png")
    msg = str(err)
    assert "IoU 0.17 with the photo's silhouette" in msg and "alpha channel" in msg
    assert "is it the mask of another photo?" in msg


def test_mask_of_another_photo_refused_plain_background(tmp_path: Path) -> None:
    img = _on_plain_background()  # the object: rows 20..80, columns 10..60
    Image.fromarray(img).save(tmp_path / "p.jpg", quality=80)
    _mask(tmp_path / "p.mask.png", _box_mask(128, 96, (slice(10, 90), slice(70, 120))))
    err = _expect(tmp_path, "the mask does not match the photo", "p.mask.png")
    assert "IoU 0.00" in str(err) and "plain background" in str(err)


def test_matching_mask_on_plain_background_accepted(tmp_path: Path) -> None:
    box = (slice(20, 80), slice(10, 60))
    img = _on_plain_background(box=box)
    img[40:60, 25:45] = 245  # a white panel inside the object is still the object
    Image.fromarray(img).save(tmp_path / "p.jpg", quality=60)
    m = _box_mask(128, 96, box)
    m[40:60, 25:45] = 2  # the panel is the movable part: its outline is an edge
    _mask(tmp_path / "p.mask.png", m)
    assert load_input(discover_inputs(tmp_path)[0]).part_count == 2


def _table_with_shadow() -> tuple[np.ndarray, np.ndarray]:
    """(photo, its own mask): a thin-legged table on a white floor with its grey cast
    shadow under it. The estimated silhouette takes in the shadow, so the table's own
    mask overlaps it with an IoU below MASK_MIN_IOU, as PartNet's desks do."""
    rng = np.random.default_rng(3)
    img = np.full((128, 128, 3), 245, np.uint8)
    img[96:118, 30:122] = 200  # the shadow on the floor, cast to the right
    wood = rng.integers(60, 90, (128, 128, 1)) + np.array([40, 10, 0])
    table = np.zeros((128, 128), np.uint8)
    table[30:40, 20:108] = 1  # the top
    table[40:110, 22:26] = 1  # the legs
    table[40:110, 102:106] = 1
    img[table > 0] = wood[table > 0]
    return img, table


def test_own_mask_of_a_table_with_a_cast_shadow_is_accepted(tmp_path: Path) -> None:
    img, own = _table_with_shadow()
    silhouette = estimate_silhouette(img)
    iou = np.count_nonzero((own > 0) & silhouette) / np.count_nonzero((own > 0) | silhouette)
    assert MASK_FLOOR_IOU <= iou < MASK_MIN_IOU  # the shadow is in the silhouette
    assert mask_outline_coverage(own, img) >= MASK_OUTLINE_COVERED
    Image.fromarray(img).save(tmp_path / "t.png")
    _mask(tmp_path / "t.mask.png", own)
    assert load_input(discover_inputs(tmp_path)[0]).part_count == 1


def test_mask_inside_the_silhouette_but_off_its_edges_is_refused(tmp_path: Path) -> None:
    """Another photo's mask that falls inside this photo's silhouette (the lower part of
    the shadow): its top edge runs over flat grey, so its outline is not the photo's."""
    img, _ = _table_with_shadow()
    other = np.zeros((128, 128), np.uint8)
    other[104:118, 30:122] = 1
    assert mask_outline_coverage(other, img) < MASK_OUTLINE_COVERED
    Image.fromarray(img).save(tmp_path / "t.png")
    _mask(tmp_path / "t.mask.png", other)
    err = _expect(tmp_path, "the mask does not match the photo", "t.mask.png")
    assert "is it the mask of another photo?" in str(err)


def test_mismatch_not_judged_without_a_silhouette(tmp_path: Path) -> None:
    """A busy background or a thin plain frame round a busy picture gives no silhouette:
    nothing is refused."""
    rng = np.random.default_rng(2)
    busy = rng.integers(0, 256, (96, 128, 3), dtype=np.uint8)
    framed = busy.copy()
    framed[:3], framed[-3:], framed[:, :3], framed[:, -3:] = 255, 255, 255, 255
    m = _box_mask(128, 96, (slice(10, 30), slice(100, 120)))
    for name, img in (("busy", busy), ("framed", framed)):
        Image.fromarray(img).save(tmp_path / f"{name}.png")
        _mask(tmp_path / f"{name}{MASK_SUFFIX}", m)
    assert [load_input(i).part_count for i in discover_inputs(tmp_path)] == [1, 1]


def _dark_appliance() -> tuple[np.ndarray, np.ndarray]:
    """(photo, its own mask): a microwave, a dark body on a light plain background with
    a panel of bright buttons, whose dark glass door (id 2) shows no edge against its
    frame: the door's outline is no edge at all, the body's outline is one."""
    img = np.full((96, 128, 3), 235, np.uint8)
    img[16:80, 16:112] = 25  # the body and the door: the same dark
    for row in range(28, 72, 10):  # the control panel's buttons
        img[row : row + 5, 94:104] = 220
    mask = np.zeros((96, 128), np.uint8)
    mask[16:80, 16:112] = 1
    mask[24:72, 24:84] = 2
    return img, mask


def test_a_dark_door_in_a_dark_frame_with_its_own_mask_is_accepted(tmp_path: Path) -> None:
    img, mask = _dark_appliance()
    assert mask_edge_support(mask, img) < MASK_EDGE_REFUSE  # no edge round the door
    Image.fromarray(img).save(tmp_path / "mw.png")
    _mask(tmp_path / "mw.mask.png", mask)
    loaded = load_input(discover_inputs(tmp_path)[0])
    assert loaded.part_count == 2
    (warning,) = loaded.warnings  # a doubt, named, but no refusal
    assert warning.startswith(f"{tmp_path / 'mw.mask.png'}: the boundaries between")


def test_a_mask_whose_outline_and_parts_miss_the_photos_edges_is_refused(tmp_path: Path) -> None:
    """Another object's mask: its outline and its part boundary run over flat bands of a
    textured object, where the photo has no edges (its silhouette still overlaps)."""
    rng = np.random.default_rng(4)
    img = np.full((96, 128, 3), 235, np.uint8)
    img[8:88, 8:120] = rng.integers(0, 256, (80, 112, 3))  # a busy, textured object
    for flat in (np.s_[14:26, 14:114], np.s_[70:82, 14:114], np.s_[14:82, 14:26],
                 np.s_[14:82, 102:114], np.s_[14:82, 58:70]):  # fmt: skip
        img[flat] = 128
    other = np.zeros((96, 128), np.uint8)
    other[20:76, 20:108] = 1  # the outline on the flat ring
    other[20:76, 64:108] = 2  # the boundary between the parts on the flat band
    assert check_mask_edges(_dark_appliance()[1], _dark_appliance()[0], "own") != []
    with pytest.raises(InputError, match="it looks like the mask of another photo"):
        check_mask_edges(other, img, "other.mask.png")
    Image.fromarray(img).save(tmp_path / "p.png")
    _mask(tmp_path / "p.mask.png", other)
    err = _expect(tmp_path, "neither the mask's outline nor the boundaries", "p.mask.png")
    assert "outline support" in str(err) and "part-boundary support" in str(err)


def test_mask_check_compares_on_a_small_grid_at_1024px(monkeypatch) -> None:
    """The check costs a few ms at any photo size because the silhouette is estimated,
    and compared with the mask, on a grid of at most SILHOUETTE_GRID px a side (the
    load stage's seconds in bench/convert.py measure it)."""
    import asset_pipeline.inputs.mask as mask_module

    grids = []

    def estimate(image, stride=1):
        out = estimate_silhouette(image, stride)
        grids.append(out.shape)
        return out

    monkeypatch.setattr(mask_module, "estimate_silhouette", estimate)
    box = (slice(200, 900), slice(150, 700))
    img = _on_plain_background(1024, 1024, box)
    check_mask_matches_photo(_box_mask(1024, 1024, box), img, None, "m.mask.png")
    assert grids == [(256, 256)]
    shifted = _box_mask(1024, 1024, (slice(200, 900), slice(450, 1000)))
    with pytest.raises(InputError, match="the mask does not match the photo"):
        check_mask_matches_photo(shifted, img, None, "m.mask.png")  # the grid still tells


# --------------------------------------------------------------------------- 5. formats


@pytest.mark.parametrize("suffix", [".webp", ".bmp", ".tif", ".tiff", ".WEBP"])
def test_more_photo_formats(tmp_path: Path, suffix: str) -> None:
    assert suffix.lower() in IMAGE_SUFFIXES
    img = _on_plain_background()
    Image.fromarray(img).save(
        tmp_path / f"p{suffix}", **({"lossless": True} if "webp" in suffix.lower() else {})
    )
    _mask(tmp_path / "p.mask.png", _box_mask(128, 96, (slice(20, 80), slice(10, 60))))
    listing = discover_inputs(tmp_path)
    assert [i.image_path.name for i in listing] == [f"p{suffix}"] and listing.skipped == []
    loaded = load_input(listing[0])
    assert np.array_equal(loaded.image, img) and loaded.part_count == 1


def test_webp_with_alpha(tmp_path: Path) -> None:
    a = np.zeros((48, 64, 4), np.uint8)
    a[(*OBJ, 3)] = 255
    buf = io.BytesIO()
    Image.fromarray(a, "RGBA").save(buf, "WEBP", lossless=True)
    (tmp_path / "w.webp").write_bytes(buf.getvalue())
    assert load_input(discover_inputs(tmp_path)[0]).alpha[10, 20] == 255


# --------------------------------------------------------------------------- 6. skipped files


def test_skipped_files_are_reported(tmp_path: Path) -> None:
    _rgba(tmp_path / "ok.png")
    (tmp_path / "loop.png").symlink_to("loop.png")
    (tmp_path / "broken.jpg").symlink_to("missing.jpg")
    (tmp_path / "notes.txt").write_text("n")
    Image.new("RGB", (40, 40)).save(tmp_path / "photo.gif")
    _mask(tmp_path / "orphan.mask.png", _good_mask())
    (tmp_path / "orphan.json").write_text("{}")
    (tmp_path / "sub").mkdir()
    (tmp_path / "README").write_text("x")
    (tmp_path / ".DS_Store").write_bytes(b"\0")
    os.mkfifo(tmp_path / "pipe.png")  # must not be read (it would block)
    listing = discover_inputs(tmp_path)
    assert [i.name for i in listing.items] == ["ok"]
    reasons = {s.path.name: s.reason for s in listing.skipped}
    assert all(isinstance(s, SkippedFile) and s.path.parent == tmp_path for s in listing.skipped)
    assert sorted(reasons) == [
        "README",
        "broken.jpg",
        "loop.png",
        "notes.txt",
        "orphan.json",
        "orphan.mask.png",
        "photo.gif",
        "pipe.png",
        "sub",
    ]
    assert reasons["loop.png"].startswith("symlink loop")
    assert reasons["broken.jpg"].startswith("broken symlink")
    assert reasons["notes.txt"].startswith("unsupported file type '.txt'")
    assert reasons["photo.gif"].startswith("unsupported file type '.gif'")
    assert reasons["README"].startswith("unsupported file type without a suffix")
    assert reasons["orphan.mask.png"].startswith("mask without a photo")
    assert reasons["orphan.json"].startswith("hints file without a photo")
    assert reasons["sub"].startswith("subfolder")
    assert reasons["pipe.png"].startswith("not a regular file")


def test_second_companion_differing_in_case_is_reported(tmp_path: Path) -> None:
    _rgba(tmp_path / "c.png")
    (tmp_path / "c.json").write_text("{}")
    (tmp_path / "C.JSON").write_text('{"id": "other"}')
    listing = discover_inputs(tmp_path)
    assert listing[0].hints_path == tmp_path / "c.json"
    assert [(s.path.name, s.reason.split(" (")[0]) for s in listing.skipped] == [
        ("C.JSON", "another hints file of the same photo is used")
    ]


def test_discover_refuses_a_file_that_is_not_a_photo(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("n")
    with pytest.raises(InputError, match="not a photo") as e:
        discover_inputs(tmp_path / "notes.txt")
    assert str(e.value).startswith(str(tmp_path / "notes.txt"))


# --------------------------------------------------------------------------- 7. asset ids


@pytest.mark.parametrize(
    "asset_id",
    [
        "registry.sqlite",
        "Registry.SQLite",
        "registry.sqlite-wal",
        "registry.sqlite-shm",
        "registry.sqlite-journal",
        "index.html",
        "INDEX.HTML",
        "gallery",
        "Gallery",
        "gallery_web",
        "Gallery_Web",
    ],
)
def test_reserved_ids_refused(asset_id: str) -> None:
    assert is_reserved_id(asset_id)
    with pytest.raises(InputError, match="reserved") as e:
        check_hints({"id": asset_id}, "photos/c.json")
    assert str(e.value).startswith("photos/c.json: id: ")
    assert is_reserved_id(".staging")


def test_every_name_the_output_folder_uses_is_reserved() -> None:
    """An asset folder must never take the place of the catalog, the gallery's files or
    the run's own folders (the gallery copies its viewer into OUT/gallery_web/)."""
    from asset_pipeline.catalog import batch
    from asset_pipeline.catalog.registry import CATALOG_NAME
    from asset_pipeline.gallery import page

    used = [CATALOG_NAME, batch.STAGING, batch.PREVIOUS, batch.LOCK_NAME]
    used += ["index.html", "gallery", page.WEB_DIR_NAME]
    assert [name for name in used if not is_reserved_id(name)] == []
    assert asset_id_for(page.WEB_DIR_NAME)[0] == f"{page.WEB_DIR_NAME}_photo"


@pytest.mark.parametrize(
    "name, expected, note",
    [
        ("cab01", "cab01", None),
        ("kitchen-cab_01.v2", "kitchen-cab_01.v2", None),
        ("my cabinet (1)", "my_cabinet_1", "id slugified from 'my cabinet (1)'"),
        ("Küche Schrank", "Kuche_Schrank", "id slugified from 'Küche Schrank'"),
        ("__draft__ cab", "draft_cab", "id slugified from '__draft__ cab'"),
        ("a  &  b", "a_b", "id slugified from 'a  &  b'"),
        ("gallery", "gallery_photo", "id 'gallery_photo' made from 'gallery'"),
        ("Registry.sqlite", "Registry.sqlite_photo", "id 'Registry.sqlite_photo' made from"),
        ("x" * 130, "x" * 128, "id slugified from"),
    ],
)
def test_asset_id_for(name: str, expected: str, note: str | None) -> None:
    got, got_note = asset_id_for(name)
    assert got == expected
    if note is None:
        assert got_note is None
    else:
        assert got_note is not None and got_note.startswith(note)


@pytest.mark.parametrize("name", ["柜子", "()", "-._", "é" * 200, "index.html", "a" + "é" * 200])
def test_asset_id_for_always_gives_a_valid_id(name: str) -> None:
    got, note = asset_id_for(name)
    assert ID_PATTERN.match(got) and not is_reserved_id(got) and note is not None
    assert asset_id_for(got) == (got, None)
    if name == "柜子":
        assert got.startswith("photo_") and got != asset_id_for("椅子")[0]


def test_item_and_loaded_asset_ids_use_the_slug(tmp_path: Path) -> None:
    _rgba(tmp_path / "my cabinet (1).png")
    _rgba(tmp_path / "gallery.png")
    _rgba(tmp_path / "named.png")
    (tmp_path / "named.json").write_text('{"id": "kitchen_01"}')
    items = {i.name: i for i in discover_inputs(tmp_path)}
    assert {n: i.asset_id for n, i in items.items()} == {
        "gallery": "gallery_photo",
        "my cabinet (1)": "my_cabinet_1",
        "named": "kitchen_01",
    }
    assert isinstance(items["gallery"], InputItem)
    loaded = load_input(items["my cabinet (1)"])
    assert loaded.asset_id == "my_cabinet_1"
    assert loaded.asset_id_note == "id slugified from 'my cabinet (1)'"
    named = load_input(items["named"])
    assert (named.asset_id, named.asset_id_note) == ("kitchen_01", None)
