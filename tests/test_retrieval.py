"""The retrieval baseline: embeddings, layout matching, fitting to the mask."""

from __future__ import annotations

import numpy as np
import pytest

from generator.interface import Generator
from generator.procedural import sample_object
from generator.retrieval import (
    RetrievalGenerator,
    RetrievalLibrary,
    embed_image,
    keep_parts,
    layout_cost,
    mask_layout,
    object_crop_box,
    scale_object,
)


def test_crop_box_and_layout_are_hand_computable():
    mask = np.zeros((10, 20), np.uint8)
    mask[2:8, 4:14] = 1  # base: rows 2..7, cols 4..13
    mask[2:5, 4:9] = 2  # part id 2: top-left quarter-ish
    mask[5:8, 9:14] = 3
    box = object_crop_box(mask.shape, mask, None)
    assert box == (2, 8, 4, 14)
    lay = mask_layout(mask, box)
    # id 2: cols 4..8 -> x in [0, 0.5], rows 2..4 -> y in [0, 0.5]
    assert np.allclose(lay[0], [0.25, 0.25, 0.5, 0.5])
    assert np.allclose(lay[1], [0.75, 0.75, 0.5, 0.5])
    cost, match = layout_cost(lay[::-1], lay)
    assert cost == pytest.approx(0.0)
    assert list(match) == [1, 0]


def test_embedding_is_unit_and_discriminative():
    rng = np.random.default_rng(0)
    a = rng.integers(0, 255, (64, 64, 3), dtype=np.uint8)
    b = rng.integers(0, 255, (64, 64, 3), dtype=np.uint8)
    ea, eb = embed_image(a, (0, 64, 0, 64)), embed_image(b, (0, 64, 0, 64))
    assert np.linalg.norm(ea) == pytest.approx(1.0, abs=1e-5)
    assert np.linalg.norm(ea - embed_image(a, (0, 64, 0, 64))) == 0
    assert np.linalg.norm(ea - eb) > 0.1


def test_scale_object_scales_prismatic_ranges_not_revolute():
    obj = sample_object("cabinet", 3)
    scaled = scale_object(obj, np.array([2.0, 1.0, 1.0]))
    for p, q in zip(obj.parts, scaled.parts, strict=True):
        assert np.allclose(q.mesh.vertices, p.mesh.vertices * [2, 1, 1], atol=1e-6)
        if p.joint is not None and p.joint.type == "prismatic" and abs(p.joint.axis[0]) > 0.99:
            assert q.joint.upper == pytest.approx(2 * p.joint.upper, rel=1e-6)
        if p.joint is not None and p.joint.type == "revolute":
            assert q.joint.upper == pytest.approx(p.joint.upper)
    scaled.validate()


def test_keep_parts_merges_the_rest_into_the_base():
    obj = sample_object("cabinet", 3)
    movable = obj.movable_parts
    assert len(movable) >= 2
    kept = keep_parts(obj, [movable[1].name])
    kept.validate()
    assert len(kept.movable_parts) == 1
    total = sum(len(p.mesh.faces) for p in obj.parts)
    assert sum(len(p.mesh.faces) for p in kept.parts) == total


@pytest.fixture(scope="module")
def generator() -> RetrievalGenerator:
    return RetrievalGenerator.default()  # the shipped library


def test_generator_keeps_the_interface_and_follows_the_mask(generator):
    from PIL import Image

    assert isinstance(generator, Generator)
    img = np.asarray(Image.open("examples/images/cabinet_t0000001.png").convert("RGB"))
    mask = np.asarray(Image.open("examples/images/cabinet_t0000001.mask.png"))
    obj = generator.generate(img, mask, {"category": "cabinet", "height": 1.1})
    obj.validate()
    assert obj.category == "cabinet"
    assert len(obj.movable_parts) == int(mask.max()) - 1  # one movable part per mask id
    assert obj.bounds()[1, 2] - obj.bounds()[0, 2] == pytest.approx(1.1, rel=1e-6)
    assert set(generator.timings) == {"retrieve", "fit"}


def _library(embeds, counts, layouts) -> RetrievalLibrary:
    n = len(embeds)
    lay = np.full((n, 15, 4), np.nan, np.float32)
    for i, lo in enumerate(layouts):
        lay[i, : len(lo)] = lo
    return RetrievalLibrary(
        categories=np.array(["cabinet"] * n),
        seeds=np.arange(n),
        splits=np.array(["train"] * n),
        embed_crop=np.stack(embeds),
        embed_full=np.stack(embeds),
        layouts=lay,
        part_counts=np.array(counts, np.int16),
        aspects=np.ones(n, np.float32),
    )


def test_retrieve_picks_nearest_embedding_with_the_mask_part_count():
    rng = np.random.default_rng(1)
    img = rng.integers(0, 255, (32, 32, 3), dtype=np.uint8)
    mask = np.ones((32, 32), np.uint8)
    mask[:16] = 2
    mask[16:, :16] = 3
    q = embed_image(img, object_crop_box(img.shape, mask, None))
    other = embed_image(rng.integers(0, 255, (32, 32, 3), dtype=np.uint8), (0, 32, 0, 32))
    layout = mask_layout(mask, (0, 32, 0, 32))
    # Entry 0 has the same embedding but 3 parts; entry 2 the same embedding and 2 parts.
    lib = _library([q, other, q], [3, 2, 2], [np.zeros((3, 4)), layout, layout[::-1]])
    best, match = RetrievalGenerator(lib).retrieve(img, mask)
    assert best == 2
    assert list(match) == [1, 0]  # the library's layout is reversed
    best, _ = RetrievalGenerator(lib).retrieve(img, None)  # no mask: embedding alone
    assert best in (0, 2)


def test_retrieved_parts_follow_the_given_motions():
    """A procedural cabinet's parts made to move as given: a door hinged on the other side
    is mirrored (its handle with it), a door given as a drawer becomes a panel that
    slides, with a bar handle on its front."""
    from generator.motions import motion_of
    from generator.procedural import sample_object
    from generator.retrieval import follow_motions

    obj = next(
        o for o in (sample_object("cabinet", s) for s in range(40))
        if sum(p.semantic == "door" for p in o.movable_parts) >= 2
    )  # fmt: skip
    movable = obj.movable_parts
    doors = [t for t, p in enumerate(movable) if p.semantic == "door"]
    flipped = {"door_left": "door_right", "door_right": "door_left"}
    first, second = doors[:2]
    want = {first: flipped[motion_of(movable[first])], second: "drawer"}
    out = follow_motions(obj, want)
    moved = out.movable_parts
    for t, m in want.items():
        assert motion_of(moved[t]) == m
    assert moved[first].handle is not None and moved[second].handle is not None
    # the mirrored door's handle sits at its new free edge: opposite its hinge
    hinge_y = moved[first].joint.origin[1]
    assert abs(moved[first].handle.position[1] - hinge_y) > 0.5 * (moved[first].mesh.extents[1])
    assert moved[second].primitives and moved[second].joint.type == "prismatic"
    # untouched parts keep their geometry and joints; every part is named for what it is
    others = [t for t in range(len(movable)) if t not in want]
    assert all(moved[t].mesh is movable[t].mesh and moved[t].joint is movable[t].joint
               for t in others)  # fmt: skip
    assert all(p.name.startswith(p.semantic + "_") for p in moved)
    assert len({p.name for p in out.parts}) == len(out.parts)


def test_a_retrieved_drawer_given_as_a_door_is_a_panel_that_swings_clear():
    """A drawer box swung on a hinge would sweep through the carcass: given a door's
    motion, a retrieved drawer keeps only its front slab (tests/test_cli.py validates such
    assets: the examples converted by retrieval with the parser's motions)."""
    from generator.motions import motion_of
    from generator.procedural import sample_object
    from generator.retrieval import PANEL_SHARE, follow_motions

    obj = next(
        o for o in (sample_object("cabinet", s) for s in range(40))
        if any(p.semantic == "drawer" for p in o.movable_parts)
    )  # fmt: skip
    t = next(t for t, p in enumerate(obj.movable_parts) if p.semantic == "drawer")
    drawer = obj.movable_parts[t]
    assert drawer.mesh.extents[0] > 2 * PANEL_SHARE * float(np.ptp(obj.bounds(), axis=0).max())
    out = follow_motions(obj, {t: "door_left"})
    door = out.movable_parts[t]
    assert motion_of(door) == "door_left" and door.name.startswith("door_")
    size = float(np.ptp(out.bounds(), axis=0).max())
    front = drawer.mesh.bounds[1][0]
    # nothing of the door reaches back into the carcass past a panel's thickness (its bar
    # handle stands in front of the old drawer's front)
    assert door.mesh.bounds[0][0] >= front - PANEL_SHARE * size - 1e-6
    assert door.mesh.bounds[1][0] > front
