"""generator.parser.sam2_segmenter: SAM2's automatic masks as the parser's regions.

No downloaded weights: the model is SAM 2.1 hiera-tiny built from the package's config
with random weights at a 128 px input (the released configs use 1024), saved to a
temporary checkpoint by the test. A random model segments nothing meaningful: these tests
check the contract (shapes, order, cleaning, errors), not quality.
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import pytest

from generator.parser.sam2_segmenter import (
    INSTALL_HINT,
    Sam2CheckpointError,
    Sam2NotInstalledError,
    Sam2Segmenter,
    Sam2SegmenterError,
    Sam2Settings,
    clean_regions,
    config_file,
    config_for_checkpoint,
)

try:
    from generator.parser import ParsedPart, ParsedPhoto
except ImportError:  # the parser package without its inference module
    from dataclasses import dataclass

    @dataclass
    class ParsedPart:  # type: ignore[no-redef]
        id: int
        motion: str
        confidence: float

    @dataclass
    class ParsedPhoto:  # type: ignore[no-redef]
        category: str
        category_confidence: float
        mask: np.ndarray
        parts: list
        seconds: float


IMAGE_SIZE = 128  # the test model's input side (the released configs: 1024)
# Every mask the random model makes passes SAM2's quality filters; a 4 x 4 prompt grid.
TEST_SETTINGS = Sam2Settings(points_per_side=4, pred_iou_thresh=0.0, stability_score_thresh=0.0)


def cabinet_photo(h: int = 96, w: int = 128) -> np.ndarray:
    """A two-door cabinet on a light wall: carcass, two doors with a seam, two handles."""
    img = np.full((h, w, 3), (228, 226, 220), np.uint8)
    img[int(0.88 * h) :, :] = (150, 140, 130)  # floor
    top, bottom, left, right = int(0.12 * h), int(0.85 * h), int(0.18 * w), int(0.82 * w)
    img[top:bottom, left:right] = (120, 84, 52)  # carcass
    mid = (left + right) // 2
    for x0, x1 in ((left + 3, mid - 1), (mid + 1, right - 3)):
        img[top + 3 : bottom - 3, x0:x1] = (158, 116, 76)  # door
    for x in (mid - 5, mid + 3):
        img[h // 2 - 6 : h // 2 + 6, x : x + 2] = (40, 40, 44)  # handle
    return img


# --------------------------------------------------------------------------- cleaning


def box(h: int, w: int, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
    m = np.zeros((h, w), bool)
    m[r0:r1, c0:c1] = True
    return m


def test_clean_regions_sorts_by_area_and_drops_tiny_and_duplicates():
    door = box(60, 80, 10, 50, 10, 40)
    door_again = door.copy()
    door_again[10, 10] = False  # IoU ~0.999 with door
    carcass = box(60, 80, 5, 55, 5, 75)
    handle = box(60, 80, 28, 34, 35, 37)  # 12 px
    speck = box(60, 80, 0, 2, 0, 2)  # 4 px
    empty = np.zeros((60, 80), bool)
    masks = [handle, door_again, speck, carcass, door, empty]
    scores = [0.9, 0.5, 0.99, 0.8, 0.95, 0.9]
    out = clean_regions(masks, scores, min_area=10, duplicate_iou=0.9)
    assert len(out) == 3
    assert [int(m.sum()) for m in out] == sorted((int(m.sum()) for m in out), reverse=True)
    assert np.array_equal(out[0], carcass) and np.array_equal(out[2], handle)
    assert np.array_equal(out[1], door)  # the better-scored of the two duplicates
    assert all(m.dtype == bool and m.shape == (60, 80) and m.flags.c_contiguous for m in out)


def test_clean_regions_removes_specks_inside_a_mask():
    door = box(40, 40, 5, 35, 5, 20)
    with_speck = door | box(40, 40, 0, 2, 30, 32)  # a 4 px island far from the door
    (out,) = clean_regions([with_speck], [1.0], min_area=10, duplicate_iou=0.9)
    assert np.array_equal(out, door)


def test_clean_regions_keeps_overlapping_regions_that_are_not_duplicates():
    door = box(40, 40, 5, 35, 5, 20)
    door_with_handle = door | box(40, 40, 15, 25, 20, 24)  # IoU 450/490 = 0.92
    top_half = box(40, 40, 5, 20, 5, 20)  # IoU 0.5 with door
    out = clean_regions(
        [door, door_with_handle, top_half], [0.9, 0.8, 0.7], min_area=10, duplicate_iou=0.95
    )
    assert len(out) == 3
    out = clean_regions(
        [door, door_with_handle, top_half], [0.9, 0.8, 0.7], min_area=10, duplicate_iou=0.9
    )
    assert len(out) == 2


def test_config_names():
    assert config_file("sam2.1_hiera_t") == "configs/sam2.1/sam2.1_hiera_t.yaml"
    assert config_file("sam2_hiera_b+") == "configs/sam2/sam2_hiera_b+.yaml"
    assert config_for_checkpoint("/x/sam2.1_hiera_base_plus.pt") == "sam2.1_hiera_b+"
    assert config_for_checkpoint("sam2_hiera_large.pt") == "sam2_hiera_l"
    assert config_for_checkpoint("my_finetune.pt") is None
    with pytest.raises(Sam2SegmenterError, match="sam2.1_hiera_t"):
        config_file("hiera_tiny")


# --------------------------------------------------------------------------- errors


def test_missing_sam2_package_says_how_to_install(monkeypatch, tmp_path):
    for name in ("sam2", "sam2.build_sam", "sam2.automatic_mask_generator"):
        monkeypatch.setitem(sys.modules, name, None)  # import raises ImportError
    with pytest.raises(Sam2NotInstalledError) as err:
        Sam2Segmenter.from_checkpoint(tmp_path / "sam2.1_hiera_tiny.pt")
    assert "pip install sam2==1.1.0" in str(err.value) and "optional" in str(err.value)
    assert isinstance(err.value, ImportError) and INSTALL_HINT in str(err.value)


def test_missing_checkpoint_names_the_file(tmp_path):
    pytest.importorskip("sam2", reason="the optional sam2 package is not installed")
    path = tmp_path / "nowhere" / "sam2.1_hiera_tiny.pt"
    with pytest.raises(Sam2CheckpointError, match="does not exist") as err:
        Sam2Segmenter.from_checkpoint(path)
    assert str(path) in str(err.value) and "docs/segmenters.md" in str(err.value)


@pytest.mark.parametrize("content", [b"not a checkpoint\n", b"PK\x03\x04 truncated zip"])
def test_unreadable_checkpoint_names_the_file(tmp_path, content):
    pytest.importorskip("sam2", reason="the optional sam2 package is not installed")
    path = tmp_path / "sam2.1_hiera_tiny.pt"
    path.write_bytes(content)
    with pytest.raises(Sam2CheckpointError, match="cannot be read as a PyTorch checkpoint") as err:
        Sam2Segmenter.from_checkpoint(path)
    assert str(path) in str(err.value)


def test_checkpoint_without_weights_names_the_file(tmp_path):
    torch = pytest.importorskip("torch")
    pytest.importorskip("sam2", reason="the optional sam2 package is not installed")
    path = tmp_path / "sam2.1_hiera_tiny.pt"
    torch.save({"model": {}, "epoch": 3}, path)
    with pytest.raises(Sam2CheckpointError, match="holds no model weights") as err:
        Sam2Segmenter.from_checkpoint(path)
    assert str(path) in str(err.value)


@pytest.mark.slow
def test_checkpoint_of_another_model_names_the_file_and_the_config(tmp_path):
    torch = pytest.importorskip("torch")
    pytest.importorskip("sam2", reason="the optional sam2 package is not installed")
    path = tmp_path / "sam2.1_hiera_small.pt"
    torch.save({"model": torch.nn.Linear(3, 2).state_dict()}, path)
    with pytest.raises(Sam2CheckpointError) as err:
        Sam2Segmenter.from_checkpoint(path, config="sam2.1_hiera_t", image_size=IMAGE_SIZE)
    msg = str(err.value)
    assert str(path) in msg and "does not match config 'sam2.1_hiera_t'" in msg
    assert "weights missing" in msg and "2 weights unexpected (e.g. weight, bias)" in msg
    assert "goes with config 'sam2.1_hiera_s'" in msg


# --------------------------------------------------------------------------- the model


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory):
    """SAM 2.1 hiera-tiny at a 128 px input with random weights (seed 0), as a checkpoint
    file in Meta's layout ({"model": state_dict})."""
    torch = pytest.importorskip("torch")
    pytest.importorskip("sam2", reason="the optional sam2 package is not installed")
    from sam2.build_sam import build_sam2

    torch.manual_seed(0)
    model = build_sam2(
        config_file("sam2.1_hiera_t"),
        ckpt_path=None,
        device="cpu",
        hydra_overrides_extra=[f"++model.image_size={IMAGE_SIZE}"],
    )
    path = tmp_path_factory.mktemp("sam2") / "random_hiera_t.pt"
    torch.save({"model": model.state_dict()}, path)
    return path


@pytest.fixture(scope="module")
def segmenter(tiny_checkpoint):
    return Sam2Segmenter.from_checkpoint(
        tiny_checkpoint, "sam2.1_hiera_t", "cpu", settings=TEST_SETTINGS, image_size=IMAGE_SIZE
    )


@pytest.fixture(scope="module")
def photo_regions(segmenter):
    image = cabinet_photo()
    return image, segmenter.regions(image)


@pytest.mark.slow
def test_regions_on_cpu_keep_the_contract(segmenter, photo_regions):
    assert segmenter.config == "sam2.1_hiera_t" and segmenter.model.device.type == "cpu"
    image, regions = photo_regions
    assert len(regions) >= 1
    areas = [int(r.sum()) for r in regions]
    assert areas == sorted(areas, reverse=True) and min(areas) > 0
    for r in regions:
        assert isinstance(r, np.ndarray) and r.dtype == bool and r.shape == image.shape[:2]
    with pytest.raises(ValueError, match=r"\(H, W, 3\) uint8"):
        segmenter.regions(image.astype(np.float32))


@pytest.mark.slow
def test_a_photo_larger_than_max_side_gets_regions_of_its_own_size(segmenter):
    shrinking = Sam2Segmenter(segmenter.model, replace(TEST_SETTINGS, max_side=64))
    image = cabinet_photo(96, 128)  # SAM2 sees it at 48 x 64
    regions = shrinking.regions(image)
    assert len(regions) >= 1
    assert all(r.shape == (96, 128) and r.dtype == bool and r.any() for r in regions)
    areas = [int(r.sum()) for r in regions]
    assert areas == sorted(areas, reverse=True)


class RecordingParser:
    """Stands in for PhotoParser: records what merge_regions got, returns a ParsedPhoto
    whose mask is the first region as the base and the second as part 2."""

    def __init__(self) -> None:
        self.calls: list[tuple[np.ndarray, list[np.ndarray]]] = []

    def merge_regions(self, image: np.ndarray, regions: list[np.ndarray]) -> ParsedPhoto:
        self.calls.append((image, regions))
        mask = np.zeros(image.shape[:2], np.uint8)
        for label, region in zip((1, 2), regions, strict=False):
            mask[region] = label
        parts = [ParsedPart(id=2, motion="door_left", confidence=0.5)] if (mask == 2).any() else []
        return ParsedPhoto(
            category="cabinet", category_confidence=0.9, mask=mask, parts=parts, seconds=0.0
        )


@pytest.mark.slow
def test_segment_hands_the_regions_to_the_parser(segmenter, photo_regions):
    image, expected = photo_regions
    image = image.copy()
    parser = RecordingParser()
    parsed = segmenter.segment(image, parser)
    assert len(parser.calls) == 1
    got_image, got_regions = parser.calls[0]
    assert got_image is image
    # the same regions as regions() gave for this photo (SAM2 on CPU is deterministic)
    assert len(got_regions) == len(expected)
    assert all(np.array_equal(a, b) for a, b in zip(got_regions, expected, strict=True))
    assert isinstance(parsed, ParsedPhoto) and parsed.mask.shape == image.shape[:2]
    assert parsed.category == "cabinet"
