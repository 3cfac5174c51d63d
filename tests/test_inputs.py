"""The image-folder input format (docs/input-format.md)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from asset_pipeline.inputs import InputError, check_hints, discover_inputs, load_input


def _rgba(path: Path, w: int = 8, h: int = 6, opaque: bool = False) -> None:
    a = np.zeros((h, w, 4), np.uint8)
    a[..., :3] = 120
    a[1:5, 2:6, 3] = 255
    if opaque:
        a[..., 3] = 255
    Image.fromarray(a, "RGBA").save(path)


def _mask(path: Path, ids: np.ndarray, mode: str = "L") -> None:
    img = Image.fromarray(ids.astype(np.uint8), "L")
    if mode != "L":
        img = img.convert(mode)
    img.save(path)


def _good_mask(w: int = 8, h: int = 6) -> np.ndarray:
    m = np.zeros((h, w), np.uint8)
    m[1:5, 2:6] = 1
    m[2:4, 3:5] = 2
    return m


def test_discover_and_load(tmp_path: Path) -> None:
    _rgba(tmp_path / "b.png")
    _mask(tmp_path / "b.mask.png", _good_mask())
    (tmp_path / "b.json").write_text(
        json.dumps({"category": "cabinet", "height": 0.9, "id": "cab-b"})
    )
    Image.new("RGB", (5, 4), (10, 20, 30)).save(tmp_path / "a.jpg")
    _mask(tmp_path / "orphan.mask.png", _good_mask())
    items = discover_inputs(tmp_path)
    assert [i.name for i in items] == ["a", "b"]
    a, b = items
    assert a.mask_path is None and a.hints_path is None
    assert b.mask_path == tmp_path / "b.mask.png" and b.hints_path == tmp_path / "b.json"

    la = load_input(a)
    assert la.image.shape == (4, 5, 3) and la.image.dtype == np.uint8
    assert la.alpha is None and la.mask is None and la.hints == {}
    assert la.asset_id == "a" and la.category == "unknown" and la.height is None

    lb = load_input(b)
    assert lb.image.shape == (6, 8, 3) and lb.alpha.shape == (6, 8)
    assert lb.alpha[2, 3] == 255 and lb.alpha[0, 0] == 0
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
    assert discover_inputs(tmp_path / "x.png")[0].input_hash == h2  # a single photo works too


def test_opaque_alpha_and_grey_rgb_mask(tmp_path: Path) -> None:
    _rgba(tmp_path / "o.png", opaque=True)
    _mask(tmp_path / "o.mask.png", _good_mask(), mode="RGB")
    li = load_input(discover_inputs(tmp_path)[0])
    assert li.alpha is None
    assert np.array_equal(li.mask, _good_mask())


def _expect(tmp_path: Path, match: str, file: str) -> None:
    (item,) = discover_inputs(tmp_path)
    with pytest.raises(InputError, match=match) as e:
        load_input(item)
    assert str(tmp_path / file) in str(e.value)


def test_corrupt_image(tmp_path: Path) -> None:
    (tmp_path / "c.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    _expect(tmp_path, "unreadable or corrupt image", "c.png")


def test_mask_size_mismatch(tmp_path: Path) -> None:
    _rgba(tmp_path / "c.png")
    _mask(tmp_path / "c.mask.png", _good_mask(w=9))
    _expect(tmp_path, "mask is 9x6 but the image is 8x6", "c.mask.png")


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda m: m.__setitem__((0, 0), 17), "above 16"),
        (lambda m: m.__setitem__(m == 1, 0), "no base"),
        (lambda m: m.__setitem__(m == 2, 3), "consecutive"),
    ],
)
def test_mask_ids(tmp_path: Path, edit, match: str) -> None:
    _rgba(tmp_path / "c.png")
    m = _good_mask()
    edit(m)
    _mask(tmp_path / "c.mask.png", m)
    _expect(tmp_path, match, "c.mask.png")


def test_colour_mask_refused(tmp_path: Path) -> None:
    _rgba(tmp_path / "c.png")
    a = np.zeros((6, 8, 3), np.uint8)
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
        ("[1, 2]", "JSON object"),
    ],
)
def test_bad_hints(tmp_path: Path, text: str, match: str) -> None:
    _rgba(tmp_path / "c.png")
    (tmp_path / "c.json").write_text(text)
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
