"""The photo parser's training data (generator.data.parser_data): format, masks, labels,
determinism, resume; and the realistic objects' left / right hinged variants."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from generator.data.parser_data import (
    CATEGORIES,
    CATEGORY_SHARES,
    ParserDataError,
    degrade,
    plan_object,
    sample_degradation,
    visible_parts,
    write_parser_data,
)
from generator.motions import MOTIONS, motion_of
from generator.procedural.realistic import sample_realistic_object

SEED = 1  # objects 0-2: a microwave (val), a washing machine, a cabinet
SIZE = 48
OBJECTS, VIEWS = 3, 2


def _render_device() -> None:
    from generator.data.render import RenderUnavailableError, check_render_device

    try:
        check_render_device()
    except RenderUnavailableError as e:
        pytest.skip(str(e))


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    _render_device()
    out = tmp_path_factory.mktemp("parser") / "data"
    write_parser_data(out, OBJECTS, VIEWS, SEED, SIZE, flush_seconds=0.0)
    return out


def _files(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


def test_manifest_lists_every_image_in_the_agreed_format(data):
    m = json.loads((data / "manifest.json").read_text())
    assert set(m) == {
        "schema",
        "version",
        "seed",
        "image_size",
        "categories",
        "motions",
        "items",
        "failed",
    }
    assert (m["schema"], m["version"], m["seed"], m["image_size"]) == (
        "pact.parser_data",
        1,
        SEED,
        SIZE,
    )
    assert m["categories"] == list(CATEGORIES) and len(m["categories"]) == 8
    assert "other" in m["categories"] and m["motions"] == list(MOTIONS)
    assert m["failed"] == []
    assert len(m["items"]) == OBJECTS * VIEWS
    plans = [plan_object(SEED, i) for i in range(OBJECTS)]
    expected_ids = [f"{p.id}_{k}" for p in plans for k in range(VIEWS)]
    assert [it["id"] for it in m["items"]] == expected_ids
    for it in m["items"]:
        assert set(it) == {"id", "object", "category", "style", "split"}
        plan = next(p for p in plans if p.id == it["object"])
        assert it["category"] == plan.category and it["split"] == plan.split
        assert it["style"] in ("product", "room", "plain") and it["split"] in ("train", "val")
    # the split is by object: every view of an object has its object's split
    assert {it["object"]: it["split"] for it in m["items"]}[plans[0].id] == "val"


def test_images_masks_and_hints_agree(data):
    m = json.loads((data / "manifest.json").read_text())
    seen_parts = 0
    for it in m["items"]:
        rgb = Image.open(data / "images" / f"{it['id']}.png")
        mask_img = Image.open(data / "images" / f"{it['id']}.mask.png")
        hints = json.loads((data / "images" / f"{it['id']}.json").read_text())
        assert rgb.mode == "RGB" and rgb.size == (SIZE, SIZE)
        assert mask_img.mode == "L" and mask_img.size == (SIZE, SIZE)
        mask = np.asarray(mask_img)
        ids = sorted(int(v) for v in np.unique(mask))
        assert 1 in ids, "the base is visible"
        movable = [i for i in ids if i >= 2]
        assert movable == list(range(2, 2 + len(movable))), "part ids are consecutive"
        assert hints["category"] == it["category"]
        assert sorted(int(k) for k in hints["parts"]) == movable, "a hint for every visible part"
        for part in hints["parts"].values():
            assert set(part) == {"motion"} and part["motion"] in MOTIONS
        seen_parts += len(movable)
        # the object covers a sensible share of the photo and the background is not masked
        assert 0.03 < (mask > 0).mean() < 0.95
    assert seen_parts > 0


def test_labels_are_the_objects_motions(data):
    """The hints name the motions of the rendered object's visible parts (in slot order)."""
    m = json.loads((data / "manifest.json").read_text())
    for plan in (plan_object(SEED, i) for i in range(OBJECTS)):
        obj = sample_realistic_object(plan.category, plan.seed)
        motions = [motion_of(p) for p in obj.parts if not p.is_base]
        for it in (it for it in m["items"] if it["object"] == plan.id):
            hints = json.loads((data / "images" / f"{it['id']}.json").read_text())
            labelled = [hints["parts"][k]["motion"] for k in sorted(hints["parts"], key=int)]
            # visible parts are a subsequence of the object's parts, in order
            rest = iter(motions)
            assert all(any(x == y for y in rest) for x in labelled), (labelled, motions)


def test_same_seed_gives_the_same_bytes(data, tmp_path):
    again = tmp_path / "again"
    write_parser_data(again, OBJECTS, VIEWS, SEED, SIZE, flush_seconds=0.0)
    assert _files(again) == _files(data)


def test_resume_after_an_interruption(data, tmp_path):
    out = tmp_path / "resumed"

    class Stop(Exception):
        pass

    def stop_after_first(done: int, _total: int) -> None:
        if done == 1:
            raise Stop

    with pytest.raises(Stop):
        write_parser_data(
            out, OBJECTS, VIEWS, SEED, SIZE, progress=stop_after_first, flush_seconds=0.0
        )
    half = json.loads((out / "manifest.json").read_text())
    assert [it["object"] for it in half["items"]] == [plan_object(SEED, 0).id] * VIEWS
    first = out / "images" / f"{half['items'][0]['id']}.png"
    stamp = first.stat().st_mtime_ns
    write_parser_data(out, OBJECTS, VIEWS, SEED, SIZE, flush_seconds=0.0)
    assert first.stat().st_mtime_ns == stamp, "a finished object is kept, not rendered again"
    assert _files(out) == _files(data)
    with pytest.raises(ParserDataError, match="seed"):
        write_parser_data(out, OBJECTS, VIEWS, SEED + 1, SIZE)


def test_hidden_and_tiny_parts_are_left_out_and_ids_renumbered():
    obj = next(
        o
        for o in (sample_realistic_object("cabinet", k) for k in range(50))
        if len(o.movable_parts) >= 3
    )
    n = len(obj.movable_parts)
    mask = np.zeros((40, 40), np.uint8)
    mask[:, :10] = 1
    mask[:, 10:20] = 2  # slot 1 visible
    mask[0, 20:23] = 3  # slot 2: a 3-pixel sliver -> hidden, its pixels become the base
    mask[:, 30:40] = n + 1  # the last slot visible; the slots between are not rendered
    out, parts = visible_parts(obj, mask)
    movable = [p for p in obj.parts if not p.is_base]
    assert sorted(np.unique(out).tolist()) == [0, 1, 2, 3]
    assert (out[:, 10:20] == 2).all() and (out[0, 20:23] == 1).all() and (out[:, 30:] == 3).all()
    assert parts == {
        "2": {"motion": motion_of(movable[0])},
        "3": {"motion": motion_of(movable[n - 1])},
    }


@pytest.mark.parametrize(
    "category,seed", [("microwave", 0), ("washing_machine", 3), ("refrigerator", 2), ("cabinet", 2)]
)
def test_left_and_right_hinged_variants(category, seed):
    plain = sample_realistic_object(category, seed, mirror=False)
    mirrored = sample_realistic_object(category, seed, mirror=True)
    assert plain.provenance["params"]["mirror"] is False
    assert mirrored.provenance["params"]["mirror"] is True
    swap = {"door_left": "door_right", "door_right": "door_left"}
    assert len(plain.movable_parts) == len(mirrored.movable_parts)
    for a in plain.movable_parts:
        # its mirror image: the same box reflected through y = 0, the other hinge side
        lo, hi = a.mesh.bounds
        reflected = [[lo[0], -hi[1], lo[2]], [hi[0], -lo[1], hi[2]]]
        (b,) = [
            b for b in mirrored.movable_parts if np.allclose(b.mesh.bounds, reflected, atol=1e-5)
        ]
        assert b.semantic == a.semantic
        assert motion_of(b) == swap.get(motion_of(a), motion_of(a))
    for obj in (plain, mirrored):
        assert {"door_left", "door_right"} & {motion_of(p) for p in obj.movable_parts}
        for p in obj.movable_parts:
            motion = motion_of(p)
            if motion not in ("door_left", "door_right"):
                continue
            # a left-hinged door swings out to the viewer's left (-y), a right-hinged one right
            rest, opened = p.mesh.centroid, p.posed_mesh(0.5 * p.joint.upper).centroid
            assert opened[0] > rest[0] + 0.02, "it opens outward"
            assert (opened[1] < rest[1]) == (motion == "door_left"), (p.name, motion)


def test_the_plan_keeps_category_shares_and_a_val_split():
    plans = [plan_object(0, i) for i in range(400)]
    counts = Counter(p.category for p in plans)
    assert counts == {c: 4 * n for c, n in CATEGORY_SHARES.items()}
    assert sum(CATEGORY_SHARES.values()) == 100
    assert counts["cabinet"] + counts["desk"] == 160 and counts["other"] == 16
    val = sum(p.split == "val" for p in plans)
    assert 8 <= val <= 36, val  # about 5 %
    assert plan_object(0, 7) == plans[7] and plan_object(1, 7) != plans[7]


def test_degradations_are_deterministic_and_keep_the_picture():
    rng = np.random.default_rng(0)
    img = (rng.random((64, 64, 3)) * 255).astype(np.uint8)
    for k in range(10):
        p = sample_degradation(np.random.default_rng(k))
        a, b = degrade(img, p), degrade(img, p)
        assert a.shape == img.shape and a.dtype == np.uint8
        assert np.array_equal(a, b)
        assert abs(float(a.mean()) - float(img.mean())) < 40


def test_bundles_are_rendered_as_parser_data(tmp_path):
    """Built or imported objects (here: project-made bundles, one of a category the parser
    does not know) become parser data like the procedural ones: every image "train", the
    bundle's name as the object id, its motions as the labels."""
    from generator.bundle import save_bundle
    from generator.data.parser_data import write_parser_data_from_bundles

    _render_device()
    fridge = sample_realistic_object("refrigerator", 5)
    lamp = sample_realistic_object("oven", 6)
    lamp.category = "lamp"
    b1 = save_bundle(fridge, tmp_path / "bundles" / "fridge_a")
    b2 = save_bundle(lamp, tmp_path / "bundles" / "lamp_b")
    out = tmp_path / "data"
    m = write_parser_data_from_bundles(out, [b1, b2], views=2, seed=3, image_size=SIZE)
    assert m["failed"] == []
    assert [(it["id"], it["category"], it["split"]) for it in m["items"]] == [
        ("fridge_a_0", "refrigerator", "train"),
        ("fridge_a_1", "refrigerator", "train"),
        ("lamp_b_0", "other", "train"),
        ("lamp_b_1", "other", "train"),
    ]
    motions = {motion_of(p) for p in fridge.parts if not p.is_base}
    for it in m["items"][:2]:
        hints = json.loads((out / "images" / f"{it['id']}.json").read_text())
        mask = np.asarray(Image.open(out / "images" / f"{it['id']}.mask.png"))
        assert hints["category"] == "refrigerator"
        assert {p["motion"] for p in hints["parts"].values()} <= motions
        assert set(np.unique(mask)) - {0, 1} == {int(k) for k in hints["parts"]}
    with pytest.raises(ParserDataError, match="not an object bundle"):
        write_parser_data_from_bundles(out, [tmp_path / "bundles"], views=1, seed=3)
