"""The photo parser (generator/parser): network shapes, targets, augmentation, instance
extraction, weights, and the shipped weights on a bundled example photo."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from generator.motions import MOTIONS
from generator.parser import (
    CATEGORIES,
    ParsedPhoto,
    ParserConfig,
    ParserNet,
    PhotoParser,
    instances,
)
from generator.parser.data import (
    AugmentConfig,
    ParserDataset,
    StepBatches,
    box_targets,
    mixed_items,
    motion_lut,
    targets,
)
from generator.parser.inference import box_groups
from generator.parser.model import load_weights, save_weights

REPO = Path(__file__).resolve().parents[1]
TINY = ParserConfig(
    image_size=64,
    channels=(8, 8, 16, 16, 16),
    blocks=(0, 0, 1, 0, 0),
    decoder_channels=(8, 8, 16, 16),
)


def _check_photo(p: ParsedPhoto, h: int, w: int) -> None:
    assert p.category in CATEGORIES
    assert 0.0 <= p.category_confidence <= 1.0
    assert p.mask.shape == (h, w) and p.mask.dtype == np.uint8
    ids = sorted(int(v) for v in np.unique(p.mask) if v >= 2)
    assert ids == list(range(2, 2 + len(ids)))  # consecutive
    assert [q.id for q in p.parts] == ids
    for q in p.parts:
        assert q.motion in MOTIONS and 0.0 <= q.confidence <= 1.0
    assert p.seconds >= 0


def test_untrained_model_shapes() -> None:
    model = ParserNet(TINY).eval()
    with torch.no_grad():
        out = model(torch.rand(2, 3, 64, 64))
    assert out.seg.shape == (2, 3, 32, 32)
    assert out.boundary.shape == (2, 1, 32, 32)
    assert out.motion.shape == (2, len(MOTIONS), 32, 32)
    assert out.category.shape == (2, len(CATEGORIES))
    assert out.box is None
    boxed = ParserNet(dataclasses.replace(TINY, box=True)).eval()
    with torch.no_grad():
        box = boxed(torch.rand(2, 3, 64, 64)).box
    assert box.shape == (2, 4, 32, 32) and (box >= 0).all()


def test_box_targets_and_loss_by_hand() -> None:
    """A part's pixels point to its box; the IoU loss is 0 on the truth and 1 - IoU off it."""
    from generator.parser.train import box_loss

    mask = np.zeros((8, 8), np.uint8)
    mask[1:7, 1:7] = 1
    mask[2:4, 2:6] = 2  # a 4 x 2 drawer front
    box = box_targets(mask, 8)
    # pixel (row 2, col 3): centre (3.5, 2.5); box x 2..6, y 2..4 -> l 1.5, t 0.5, r 2.5, b 1.5
    assert np.allclose(box[:, 2, 3] * 8, [1.5, 0.5, 2.5, 1.5])
    assert not box[:, mask != 2].any()
    t = torch.from_numpy(box)[None]
    on = torch.from_numpy(mask == 2)[None]
    assert box_loss(t, t, on).item() == pytest.approx(0.0, abs=1e-6)
    wider = t.clone()
    wider[:, 2] += 4 / 8  # every box 4 px wider to the right: IoU 8 / 16
    assert box_loss(wider, t, on).item() == pytest.approx(1 - 8 / 16, abs=1e-5)


def test_box_groups_separate_touching_parts() -> None:
    """Two drawers touching without an edge between them: their pixels' boxes part them."""
    movable = np.zeros((40, 40), bool)
    movable[8:32, 8:32] = True
    box = np.zeros((4, 40, 40), np.float32)
    ys, xs = np.indices((40, 40)) + 0.5
    top = ys < 20
    box[0], box[2] = xs - 8, 32 - xs
    box[1] = np.where(top, ys - 8, ys - 20)
    box[3] = np.where(top, 20 - ys, 32 - ys)
    parts = box_groups(movable, box, min_px=20)
    assert parts.max() == 2
    assert len(np.unique(parts[8:20, 8:32])) == 1 and len(np.unique(parts[20:32, 8:32])) == 1
    assert parts[10, 10] != parts[30, 10] and parts[0, 0] == 0
    mask = instances(_seg_probs(np.where(movable, 2, 1), np.zeros((40, 40))), box=box)
    assert mask[10, 10] == 2 and mask[30, 10] == 3


def test_targets_band_and_motion() -> None:
    mask = np.zeros((32, 32), np.uint8)
    mask[4:28, 4:28] = 1
    mask[8:24, 8:16] = 2
    mask[8:24, 16:24] = 3  # touching part 2: a band on both sides
    lut = motion_lut({"parts": {"2": {"motion": "door_left"}, "3": {"motion": "door_right"}}})
    seg, boundary, motion = targets(mask, lut, 32)
    assert boundary[16, 15] == 1 and boundary[16, 16] == 1  # both sides where the parts meet
    assert boundary[16, 7] == 1 and boundary[16, 8] == 1  # where a part meets the base
    assert boundary[16, 11] == 0 and boundary[5, 5] == 0  # inside a part, inside the base
    assert boundary[4, 16] == 0  # the object's outline is no part edge
    assert seg[16, 10] == 2 and seg[16, 20] == 2
    assert seg[5, 5] == 1 and seg[0, 0] == 0
    assert motion[16, 10] == MOTIONS.index("door_left")
    assert motion[16, 20] == MOTIONS.index("door_right")
    assert motion[5, 5] == -1


def _tiny_dataset(root: Path) -> None:
    (root / "images").mkdir(parents=True)
    img = np.full((64, 64, 3), 200, np.uint8)
    mask = np.zeros((64, 64), np.uint8)
    mask[10:54, 10:54] = 1
    mask[14:50, 14:30] = 2  # a door on the left half of the front
    img[mask == 1] = (120, 90, 60)
    img[mask == 2] = (60, 60, 160)
    Image.fromarray(img).save(root / "images" / "a.png")
    Image.fromarray(mask).save(root / "images" / "a.mask.png")
    hints = {"category": "cabinet", "parts": {"2": {"motion": "door_left"}}}
    (root / "images" / "a.json").write_text(json.dumps(hints))
    manifest = {
        "schema": "pact.parser_data",
        "version": 1,
        "image_size": 64,
        "categories": list(CATEGORIES),
        "motions": list(MOTIONS),
        "items": [
            {"id": "a", "object": "a", "category": "cabinet", "style": "product", "split": "train"}
        ],
    }
    (root / "manifest.json").write_text(json.dumps(manifest))


@pytest.mark.parametrize("flip", [0.0, 1.0])
def test_flip_swaps_left_and_right_doors(tmp_path: Path, flip: float) -> None:
    _tiny_dataset(tmp_path)
    cfg = AugmentConfig(
        fill=(0.9, 0.9),
        stretch=0.0,
        rotate=0.0,
        flip=flip,
        color=0,
        retint=0,
        gray=0,
        blur=0,
        noise=0,
        lowres=0,
        jpeg=0,
    )
    ds = ParserDataset(tmp_path, "train", size=64, augment=True, cfg=cfg)
    s = ds[(0, 3)]
    motion = s["motion"].numpy()
    found = set(np.unique(motion[motion >= 0]).tolist())
    door_cols = np.nonzero((motion >= 0).any(0))[0]
    if flip:
        assert found == {MOTIONS.index("door_right")}
        assert door_cols.mean() > 16  # the door moved to the right half
    else:
        assert found == {MOTIONS.index("door_left")}
        assert door_cols.mean() < 16
    assert s["image"].shape == (3, 64, 64) and int(s["category"]) == CATEGORIES.index("cabinet")


def test_other_folders_join_the_training_items_from_their_own_roots(tmp_path: Path) -> None:
    """--extra-data: the other folders' train items, repeated, read from their folders."""
    _tiny_dataset(tmp_path / "procedural")
    _tiny_dataset(tmp_path / "real")
    real_img = tmp_path / "real" / "images" / "a.png"
    Image.fromarray(np.zeros((64, 64, 3), np.uint8)).save(real_img)  # tell the two apart
    items = mixed_items(tmp_path / "procedural", tmp_path / "real", repeat=3)
    assert [it.get("root") for it in items] == [None] + [str(tmp_path / "real")] * 3
    ds = ParserDataset(tmp_path / "procedural", "train", size=64, augment=False, items=items)
    assert len(ds) == 4
    assert float(ds[0]["image"].mean()) > 0.3  # the procedural photo
    assert all(float(ds[i]["image"][:, 20:44, 20:44].max()) == 0.0 for i in (1, 2, 3))
    # several folders (other seeds' data): each one's items, each from its own root
    _tiny_dataset(tmp_path / "seed2")
    items = mixed_items(tmp_path / "procedural", [tmp_path / "real", tmp_path / "seed2"], 1)
    assert [it.get("root") for it in items] == [
        None,
        str(tmp_path / "real"),
        str(tmp_path / "seed2"),
    ]


def test_training_stopped_by_its_time_limit_leaves_weights_and_resumes(tmp_path: Path) -> None:
    """The trainer on a one-photo folder: --max-minutes stops it after its first
    checkpoint with the weights of that step written; the same command then resumes and
    finishes, its curve one row per checkpoint."""
    from generator.parser.train import Args, train

    data = tmp_path / "data"
    _tiny_dataset(data)
    manifest = json.loads((data / "manifest.json").read_text())
    manifest["items"].append(dict(manifest["items"][0], split="val"))  # the same photo
    (data / "manifest.json").write_text(json.dumps(manifest))
    args = Args(
        data=str(data),
        out=str(tmp_path / "run"),
        steps=3,
        batch=2,
        warmup=1,
        size=64,
        small_fraction=0.0,
        channels="8,8,16,16,16",
        blocks="0,0,1,0,0",
        decoder_channels="8,8,16,16",
        bf16=False,
        workers=0,
        ckpt_every=1,
        eval_every=2,
        max_minutes=1e-9,
    )
    out = train(args)
    step_of = lambda w: json.loads((w / "config.json").read_text())["extra"]["step"]  # noqa: E731
    assert step_of(out / "weights") == 1  # stopped by the limit, weights still written
    train(dataclasses.replace(args, max_minutes=0.0))
    assert step_of(out / "weights") == 3
    rows = (out / "log.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["1", "2", "3"]
    assert (out / "weights_000002").is_dir()  # the evaluation step's weights
    model, _ = load_weights(out / "weights")
    assert model.cfg.image_size == 64


def test_step_batches_are_reproducible() -> None:
    a = list(StepBatches(10, 4, seed=1, start=0, stop=5))
    b = list(StepBatches(10, 4, seed=1, start=3, stop=5))
    assert a[3:] == b


def _seg_probs(cls: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """Class map (0 bg, 1 base, 2 part) + edge map -> the (4, H, W) maps ``instances`` reads."""
    return np.concatenate([np.eye(3, dtype=np.float32)[cls].transpose(2, 0, 1), edge[None]])


def test_instances_from_a_hand_made_map() -> None:
    cls = np.zeros((40, 40), int)
    cls[5:35, 5:35] = 1  # base
    cls[8:20, 8:32] = 2  # top part
    cls[20:32, 8:32] = 2  # bottom part, touching the top one
    cls[34, 5] = 2  # a speck far from the parts: dropped, stays base
    edge = np.zeros((40, 40), np.float32)
    edge[18:22, 6:34] = 0.9  # the seam between the two parts
    edge[6:34, 7:10] = 0.8  # the parts' left edges
    mask = instances(_seg_probs(cls, edge))
    assert mask.dtype == np.uint8
    assert mask[0, 0] == 0 and mask[6, 6] == 1
    assert mask[14, 20] == 2 and mask[26, 20] == 3  # reading order: top first
    assert mask[19, 20] == 2 and mask[20, 20] == 3  # edge pixels joined their nearest part
    assert mask[10, 8] == 2 and mask[30, 8] == 3
    assert mask[34, 5] == 1
    assert sorted(np.unique(mask).tolist()) == [0, 1, 2, 3]
    alpha = np.zeros((40, 40), bool)
    alpha[5:35, 5:20] = True
    cut = instances(_seg_probs(cls, edge), alpha=alpha)
    assert not cut[:, 20:].any() and cut[6, 6] == 1


def test_instances_keep_a_part_that_is_all_edge() -> None:
    cls = np.zeros((40, 40), int)
    cls[5:35, 5:35] = 1
    cls[10:14, 8:32] = 2  # a thin drawer front the edge map covers entirely
    edge = np.zeros((40, 40), np.float32)
    edge[9:15, 7:33] = 0.9
    mask = instances(_seg_probs(cls, edge))
    assert mask[12, 20] == 2 and (mask == 2).sum() == 4 * 24


def test_weights_round_trip(tmp_path: Path) -> None:
    torch.manual_seed(0)
    model = ParserNet(TINY).eval()
    save_weights(model, tmp_path / "w", {"note": "tiny"})
    again, meta = load_weights(tmp_path / "w")
    assert meta["extra"] == {"note": "tiny"} and again.cfg == model.cfg
    x = torch.rand(1, 3, 64, 64)
    with torch.no_grad():
        a, b = model(x), again(x)
    assert torch.allclose(a.seg, b.seg, atol=0.05)


def test_tiny_parser_api_on_any_photo() -> None:
    parser = PhotoParser(ParserNet(TINY), flip=True)
    img = np.random.default_rng(0).integers(0, 255, (50, 70, 3), dtype=np.uint8)
    _check_photo(parser.parse(img), 50, 70)
    mask = np.zeros((50, 70), np.uint8)
    mask[10:40, 10:60] = 1
    mask[15:35, 15:30] = 2
    mask[15:35, 35:55] = 3
    labelled = parser.label(img, mask)
    assert np.array_equal(labelled.mask, mask) and [p.id for p in labelled.parts] == [2, 3]
    regions = [mask == 1, mask == 2, mask == 3, mask == 0]
    merged = parser.merge_regions(img, regions)
    _check_photo(merged, 50, 70)
    for v in np.unique(merged.mask):  # every output label is a union of whole regions
        assert all((merged.mask[r] == v).all() or not (merged.mask[r] == v).any() for r in regions)


def test_bf16_only_where_the_cpu_computes_it(monkeypatch: pytest.MonkeyPatch) -> None:
    import generator.parser.model as parser_model

    def cpuinfo(flags: str | None):
        def read_text(self: Path, *a, **k) -> str:
            if flags is None:
                raise OSError("no /proc here")
            return f"processor\t: 0\nflags\t\t: fpu sse2 {flags}\n"

        return read_text

    for flags, native in [("avx2 fma", False), ("avx512f avx512_bf16", True), ("amx_bf16", True)]:
        monkeypatch.setattr(Path, "read_text", cpuinfo(flags))
        assert parser_model.cpu_has_native_bf16() is native
        assert PhotoParser(ParserNet(TINY)).bf16 is native  # the default follows the CPU
        assert PhotoParser(ParserNet(TINY), bf16=False).bf16 is False  # the caller's wins
    monkeypatch.setattr(Path, "read_text", cpuinfo(None))
    assert parser_model.cpu_has_native_bf16() is False


def test_shipped_weights_parse_an_example_photo() -> None:
    parser = PhotoParser.default()
    assert PhotoParser.default() is parser  # cached per process
    assert parser.version.startswith("parser-") and parser.motion_prior
    path = REPO / "examples" / "images" / "desk_t0000001.png"
    img = np.asarray(Image.open(path).convert("RGB"))
    truth = np.asarray(Image.open(path.with_suffix(".mask.png")))
    parsed = parser.parse(img)
    _check_photo(parsed, *img.shape[:2])
    # the desk is found (its silhouette), read as a desk, its parts as drawers
    found, real = parsed.mask > 0, truth > 0
    assert (found & real).sum() / (found | real).sum() > 0.9
    assert parsed.category == "desk"
    assert parsed.parts and {p.motion for p in parsed.parts} == {"drawer"}
    # with the user's mask and category: every drawer labelled, the oven's door a flap
    labelled = parser.label(img, truth, category="desk")
    assert [p.motion for p in labelled.parts] == ["drawer"] * len(np.unique(truth[truth >= 2]))
    oven = REPO / "examples" / "images" / "oven_t0000001.png"
    door = parser.label(
        np.asarray(Image.open(oven).convert("RGB")),
        np.asarray(Image.open(oven.with_suffix(".mask.png"))),
        category="oven",
    ).parts
    assert [p.motion for p in door] == ["flap_bottom"]


def test_the_partnet_variant_is_named_weights_that_read_an_example_photo() -> None:
    """--parser-weights partnet: the fine-tuned variant ships beside the default weights,
    is other weights (another version), and reads the example desk as a desk of drawers."""
    from generator.parser import weights_dir

    assert weights_dir("partnet") == REPO / "generator" / "parser" / "weights_partnet"
    assert weights_dir("shipped") == REPO / "generator" / "parser" / "weights"
    assert weights_dir("/some/folder") == Path("/some/folder")
    variant = PhotoParser.from_dir(weights_dir("partnet"))
    assert variant.version != PhotoParser.default().version and variant.motion_prior
    path = REPO / "examples" / "images" / "desk_t0000001.png"
    parsed = variant.parse(np.asarray(Image.open(path).convert("RGB")))
    assert parsed.category == "desk" and {p.motion for p in parsed.parts} == {"drawer"}


def test_a_known_category_weighs_the_motions_by_what_its_parts_do() -> None:
    """p(m | photo, category) ~ p(m | photo) p(m | category) / p(m), hand-computed."""
    from generator.motions import MOTIONS
    from generator.parser.inference import _motion_prior

    counts = {"refrigerator": {"door_left": 8}, "dishwasher": {"flap_bottom": 8}}
    prior = _motion_prior(counts)
    # +1 per motion: fridge (9, 1, 1, 1, 1, 1)/14 by MOTIONS order, marginal
    fridge = np.array([9.0 if m == "door_left" else 1.0 for m in MOTIONS])
    dish = np.array([9.0 if m == "flap_bottom" else 1.0 for m in MOTIONS])
    marginal = (fridge + dish) / 28
    np.testing.assert_allclose(prior["refrigerator"], fridge / 14 / marginal)
    torch.manual_seed(0)  # an untrained network: near-even motion probabilities
    parser = PhotoParser(ParserNet(ParserConfig(image_size=64, channels=(8, 8, 8, 8, 8),
                         decoder_channels=(8, 8, 8, 8))), motion_counts=counts)  # fmt: skip
    img = np.full((64, 64, 3), 128, np.uint8)
    mask = np.zeros((64, 64), np.uint8)
    mask[8:56, 8:56] = 1
    mask[16:48, 16:48] = 2
    free = parser.label(img, mask)
    fridge_part = parser.label(img, mask, category="refrigerator").parts[0]
    dish_part = parser.label(img, mask, category="dishwasher").parts[0]
    assert fridge_part.motion == "door_left" and dish_part.motion == "flap_bottom"
    p0 = np.array([free.parts[0].motion_probs[m] for m in MOTIONS])
    want = p0 * prior["refrigerator"] / (p0 * prior["refrigerator"]).sum()
    got = np.array([fridge_part.motion_probs[m] for m in MOTIONS])
    np.testing.assert_allclose(got, want, rtol=1e-5)
    assert parser.label(img, mask, category="desk").parts[0].motion == free.parts[0].motion


@pytest.mark.parametrize(
    ("other_prob", "given", "parts"),
    [(0.9, None, 1), (0.4, None, 2), (0.9, "cabinet", 2), (0.9, "other", 2)],
)
def test_an_object_the_parser_reads_as_other_has_no_moving_parts(
    monkeypatch: pytest.MonkeyPatch, other_prob: float, given: str | None, parts: int
) -> None:
    """Only the parser's own confident "other" empties the parts; a given category wins."""
    from generator.parser.inference import PixelMaps

    cls = np.zeros((40, 40), int)
    cls[5:35, 5:35] = 1
    cls[10:30, 10:30] = 2  # one movable part
    category = np.full(len(CATEGORIES), (1 - other_prob) / (len(CATEGORIES) - 1))
    category[CATEGORIES.index("other")] = other_prob
    maps = PixelMaps(
        _seg_probs(cls, np.zeros((40, 40), np.float32)),
        np.full((len(MOTIONS), 40, 40), 1 / len(MOTIONS), np.float32),
        category,
    )
    parser = PhotoParser(ParserNet(TINY))
    monkeypatch.setattr(parser, "pixel_maps", lambda image, alpha=None: maps)
    parsed = parser.parse(np.zeros((40, 40, 3), np.uint8), category=given)
    assert len(np.unique(parsed.mask)) == parts + 1  # background, base[, the part]
    assert len(parsed.parts) == parts - 1 and (parsed.mask[5:35, 5:35] > 0).all()


@pytest.mark.parametrize(
    ("movable_prob", "other_prob", "fallback", "parts"),
    [
        (0.35, 0.05, 0.25, 1),  # unsure of the drawer front: it becomes the part
        (0.2, 0.05, 0.25, 0),  # below the fallback's share: no part
        (0.35, 0.05, 0.0, 0),  # the fallback off
        (0.35, 0.9, 0.25, 0),  # read as "other": no moving part wanted
    ],
)
def test_an_object_of_the_seven_without_a_found_part_gets_its_likeliest_one(
    monkeypatch: pytest.MonkeyPatch,
    movable_prob: float,
    other_prob: float,
    fallback: float,
    parts: int,
) -> None:
    """Every object of the seven categories has a moving part: where no pixel is more
    likely movable than base, the region whose movable share passes ``fallback_movable``
    is the part, with the motion its pixels vote for; the silhouette is unchanged."""
    from generator.parser.inference import PixelMaps

    seg = np.zeros((4, 40, 40), np.float32)
    seg[0] = 1.0
    seg[:, 5:35, 5:35] = np.array([0.0, 1.0, 0.0, 0.0])[:, None, None]  # the object: base
    seg[1:3, 10:20, 10:30] = np.array([1 - movable_prob, movable_prob])[:, None, None]
    motion = np.full((len(MOTIONS), 40, 40), 0.05, np.float32)
    motion[MOTIONS.index("drawer")] = 0.75
    category = np.full(len(CATEGORIES), (1 - other_prob) / (len(CATEGORIES) - 1))
    category[CATEGORIES.index("other")] = other_prob
    parser = PhotoParser(ParserNet(TINY), fallback_movable=fallback)
    maps = PixelMaps(seg, motion, category)
    monkeypatch.setattr(parser, "pixel_maps", lambda image, alpha=None: maps)
    parsed = parser.parse(np.zeros((40, 40, 3), np.uint8))
    assert len(parsed.parts) == parts
    assert (parsed.mask > 0).sum() == 30 * 30 and (parsed.mask[5:35, 5:35] > 0).all()
    if parts:
        assert (parsed.mask == 2).sum() == 10 * 20 and (parsed.mask[10:20, 10:30] == 2).all()
        assert parsed.parts[0].motion == "drawer"
    # a person is asked to check the likeliest region (the item's warning in convert)
    assert bool(parsed.notes) is bool(parts)
