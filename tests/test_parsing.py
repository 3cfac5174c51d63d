"""asset_pipeline.inputs.parsing: what a photo lacks read by the photo parser, the user's
word winning, and where each field came from; and convert with a parser."""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image

from asset_pipeline.inputs.folder import discover_inputs, load_input
from asset_pipeline.inputs.parsing import complete_input, given_sources

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "images"


@dataclass
class Part:
    id: int
    motion: str
    confidence: float


@dataclass
class Reading:
    category: str
    category_confidence: float
    mask: np.ndarray
    parts: list[Part]
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)


@dataclass
class FakeParser:
    """Reads every photo as an oven: base 1, a bottom-hinged door 2 and a drawer 3 (boxes
    of the object's bounding box); records what it was asked."""

    version: str = "fake-parser-1"
    calls: list[str] = field(default_factory=list)

    def _mask(self, shape) -> np.ndarray:
        h, w = shape[:2]
        m = np.zeros((h, w), np.uint8)
        m[h // 8 : 7 * h // 8, w // 8 : 7 * w // 8] = 1
        m[h // 4 : h // 2, w // 4 : 3 * w // 4] = 2
        m[5 * h // 8 : 3 * h // 4, w // 4 : 3 * w // 4] = 3
        return m

    def parse(self, image, alpha=None, category=None) -> Reading:
        self.calls.append("parse" if category is None else f"parse:{category}")
        parts = [Part(2, "flap_bottom", 0.9), Part(3, "drawer", 0.8)]
        return Reading("oven", 0.95, self._mask(image.shape), parts)

    def label(self, image, mask, category=None) -> Reading:
        self.calls.append("label" if category is None else f"label:{category}")
        ids = [int(v) for v in np.unique(mask) if v >= 2]
        return Reading("oven", 0.7, mask, [Part(k, "door_right", 0.6) for k in ids])


def _photo(tmp_path: Path, name: str = "p") -> Path:
    rng = np.random.default_rng(0)
    img = np.full((96, 128, 3), 240, np.uint8)
    img[12:84, 16:112] = rng.integers(40, 90, (72, 96, 3))
    Image.fromarray(img).save(tmp_path / f"{name}.png")
    return tmp_path / f"{name}.png"


def _load(folder: Path):
    (item,) = discover_inputs(folder)
    return load_input(item)


def test_a_bare_photo_gets_the_parsers_mask_category_and_motions(tmp_path):
    _photo(tmp_path)
    parser = FakeParser()
    done, sources = complete_input(_load(tmp_path), parser)
    assert parser.calls == ["parse"]
    assert sorted(np.unique(done.mask).tolist()) == [0, 1, 2, 3]
    assert done.hints["category"] == "oven"
    assert done.hints["parts"] == {"2": {"motion": "flap_bottom"}, "3": {"motion": "drawer"}}
    s = sources.to_json()
    assert s["category"] == {"source": "parser", "confidence": 0.95, "by": "fake-parser-1"}
    assert s["mask"]["source"] == "parser"
    assert s["parts"]["2"] == {"motion": "flap_bottom", "source": "parser", "confidence": 0.9,
                               "by": "fake-parser-1"}  # fmt: skip


def test_the_users_mask_category_and_motions_win(tmp_path):
    photo = _photo(tmp_path)
    mask = FakeParser()._mask((96, 128))
    Image.fromarray(mask).save(tmp_path / "p.mask.png")
    (tmp_path / "p.json").write_text(json.dumps(
        {"category": "cabinet", "parts": {"2": {"motion": "door_left"}}}))  # fmt: skip
    parser = FakeParser()
    done, sources = complete_input(_load(tmp_path), parser)
    # part 3 has no motion: the parser labels the regions, knowing the user's category
    assert parser.calls == ["label:cabinet"]
    assert np.array_equal(done.mask, mask) and done.hints["category"] == "cabinet"
    assert done.hints["parts"] == {"2": {"motion": "door_left"}, "3": {"motion": "door_right"}}
    s = sources.to_json()
    assert s["category"] == {"source": "user"} and s["mask"] == {"source": "user"}
    assert s["parts"]["2"] == {"motion": "door_left", "source": "user"}
    assert s["parts"]["3"]["source"] == "parser" and s["parts"]["3"]["confidence"] == 0.6
    # all given: the parser is not asked
    (tmp_path / "p.json").write_text(json.dumps({"category": "cabinet", "parts": {
        "2": {"motion": "door_left"}, "3": {"motion": "drawer"}}}))  # fmt: skip
    parser = FakeParser()
    complete_input(_load(tmp_path), parser)
    assert parser.calls == [] and photo.is_file()


def test_what_pact_parse_wrote_stays_the_parsers_with_its_confidence(tmp_path):
    _photo(tmp_path)
    Image.fromarray(FakeParser()._mask((96, 128))).save(tmp_path / "p.mask.png")
    hints = {"category": "oven", "parts": {"2": {"motion": "flap_bottom"}, "3": {"motion": "drawer"}},
             "parsed": {"by": "fake-parser-0", "category": 0.9, "mask": 0.8, "parts": {"3": 0.7}}}  # fmt: skip
    (tmp_path / "p.json").write_text(json.dumps(hints))
    s = given_sources(_load(tmp_path)).to_json()
    assert s["category"] == {"source": "parser", "confidence": 0.9, "by": "fake-parser-0"}
    assert s["mask"]["source"] == "parser"
    assert s["parts"]["2"]["source"] == "user"  # a person set it: parsed.parts has no "2"
    assert s["parts"]["3"] == {"motion": "drawer", "source": "parser", "confidence": 0.7,
                               "by": "fake-parser-0"}  # fmt: skip


def test_a_parser_that_finds_nothing_leaves_the_item_without_a_mask(tmp_path):
    _photo(tmp_path)

    class Blind(FakeParser):
        def parse(self, image, alpha=None, category=None):
            return Reading("other", 0.4, np.zeros(image.shape[:2], np.uint8), [])

    done, sources = complete_input(_load(tmp_path), Blind())
    assert done.mask is None and any("found no object" in w for w in done.warnings)
    assert done.hints["category"] == "other" and sources.mask.source == "none"


def test_what_the_parser_asks_a_person_to_check_is_the_items_warning(tmp_path):
    photo = _photo(tmp_path)

    class Unsure(FakeParser):
        def parse(self, image, alpha=None, category=None):
            reading = super().parse(image, alpha, category)
            reading.notes.append("the parser was sure of no moving part: check the mask")
            return reading

    done, _ = complete_input(_load(tmp_path), Unsure())
    assert done.mask is not None
    assert done.warnings == [f"{photo}: the parser was sure of no moving part: check the mask"]
    done, _ = complete_input(_load(tmp_path), FakeParser())  # a sure reading: no warning
    assert done.warnings == []


def test_convert_parses_a_bare_photo_and_records_where_each_field_came_from(tmp_path, monkeypatch):
    """pact convert with a parser (a stand-in): the asset is made from the parser's mask
    and motions, its folder keeps that mask, and asset.json, the catalog and pact ls say
    the fields came from the parser with its confidence."""
    from typer.testing import CliRunner

    from asset_pipeline.catalog import batch
    from asset_pipeline.catalog.batch import ConvertSettings, run_convert
    from asset_pipeline.catalog.registry import Catalog
    from pact_cli.main import app

    images = tmp_path / "in"
    images.mkdir()
    shutil.copy(EXAMPLES / "oven_t0000001.png", images / "oven.png")  # no mask, no hints
    monkeypatch.setitem(batch._PARSER_CACHE, "parser", FakeParser())
    out = tmp_path / "out"
    settings = ConvertSettings(generator="retrieval", validate=False, preview=False,
                               texture=False, fidelity=False)  # fmt: skip
    summary = run_convert(images, out, settings)
    assert [r.status for r in summary.results] == ["ok"], summary.results
    asset = out / "oven"
    mask = np.asarray(Image.open(asset / "input.mask.png"))
    assert sorted(np.unique(mask).tolist()) == [0, 1, 2, 3]
    inputs = json.loads((asset / "asset.json").read_text())["provenance"]["inputs"]
    assert (
        inputs["category"]["source"] == "parser" and inputs["parts"]["2"]["motion"] == "flap_bottom"
    )
    with Catalog(out, readonly=True) as cat:
        row = cat.get("oven")
        assert row.category == "oven" and row.inputs == inputs
    r = CliRunner().invoke(app, ["ls", str(out)])
    assert "parser 0.95" in r.output and "flap_bottom" in r.output


def test_pact_parse_writes_the_parsers_mask_and_hints_beside_the_photo(tmp_path, monkeypatch):
    """pact parse: a bare photo gets <name>.mask.png and <name>.json (category, motions and
    a 'parsed' record with the confidences); a photo with the user's mask and hints keeps
    them and gets only the motions its hints lack; the hints load as valid input."""
    from typer.testing import CliRunner

    from asset_pipeline.catalog import batch
    from pact_cli.main import app

    monkeypatch.setitem(batch._PARSER_CACHE, "parser", FakeParser())
    _photo(tmp_path, "bare")
    _photo(tmp_path, "given")
    user_mask = FakeParser()._mask((96, 128))
    Image.fromarray(user_mask).save(tmp_path / "given.mask.png")
    (tmp_path / "given.json").write_text(
        json.dumps({"height": 0.9, "parts": {"2": {"motion": "door_left"}}})
    )
    r = CliRunner().invoke(app, ["parse", str(tmp_path)])
    assert r.exit_code == 0, r.output
    bare = json.loads((tmp_path / "bare.json").read_text())
    assert bare["category"] == "oven" and bare["parts"]["3"] == {"motion": "drawer"}
    assert bare["parsed"] == {"by": "fake-parser-1", "category": 0.95, "mask": 0.0,
                              "parts": {"2": 0.9, "3": 0.8}}  # fmt: skip
    assert (tmp_path / "bare.mask.png").is_file()
    given = json.loads((tmp_path / "given.json").read_text())
    assert given["height"] == 0.9 and given["parts"]["2"] == {"motion": "door_left"}
    assert given["parts"]["3"] == {"motion": "door_right"}
    assert given["parsed"] == {"by": "fake-parser-1", "category": 0.7, "parts": {"3": 0.6}}
    assert np.array_equal(np.asarray(Image.open(tmp_path / "given.mask.png")), user_mask)
    for name in ("bare", "given"):  # valid input for pact convert, the parser's fields named
        (item,) = discover_inputs(tmp_path / f"{name}.png")
        assert given_sources(load_input(item)).category.source == "parser"


def test_the_gallery_says_what_the_parser_read(tmp_path, monkeypatch):
    from asset_pipeline.catalog import batch
    from asset_pipeline.catalog.batch import ConvertSettings, run_convert
    from asset_pipeline.gallery.page import write_gallery

    images = tmp_path / "in"
    images.mkdir()
    shutil.copy(EXAMPLES / "oven_t0000001.png", images / "oven.png")
    monkeypatch.setitem(batch._PARSER_CACHE, "parser", FakeParser())
    out = tmp_path / "out"
    settings = ConvertSettings(generator="retrieval", validate=False, preview=False,
                               texture=False, fidelity=False)  # fmt: skip
    run_convert(images, out, settings)
    page = write_gallery(out).read_text()
    assert "category oven (parser 0.95)" in page
    assert "2: flap_bottom (parser 0.90)" in page and "read by the parser: check it" in page


def test_convert_with_a_bad_sam2_checkpoint_stops_with_one_error_line(tmp_path):
    from typer.testing import CliRunner

    from pact_cli.main import app

    images = tmp_path / "in"
    images.mkdir()
    shutil.copy(EXAMPLES / "oven_t0000001.png", images / "oven.png")
    bad = tmp_path / "sam2.1_hiera_tiny.pt"
    bad.write_bytes(b"not a checkpoint")
    args = ["convert", str(images), "--out", str(tmp_path / "out"), "--segmenter", "sam2"]
    r = CliRunner().invoke(app, [*args, "--sam2-checkpoint", str(bad)])
    assert r.exit_code == 2 and str(bad) in r.output and "Traceback" not in r.output
    assert not (tmp_path / "out" / "oven").exists()
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 2 and "--sam2-checkpoint" in r.output


def test_pact_parse_reads_with_the_weights_it_is_given(tmp_path):
    """--parser-weights FOLDER: the parser of that folder writes the hints (its version,
    named after the folder's weights, is in the 'parsed' record); a folder that holds no
    weights stops pact parse and pact convert with one line naming it."""
    import hashlib

    import torch
    from typer.testing import CliRunner

    from generator.parser import ParserConfig, ParserNet
    from generator.parser.model import save_weights
    from pact_cli.main import app

    torch.manual_seed(0)
    tiny = ParserConfig(image_size=64, channels=(8, 8, 16, 16, 16), blocks=(0, 0, 1, 0, 0),
                        decoder_channels=(8, 8, 16, 16))  # fmt: skip
    weights = tmp_path / "w"
    save_weights(ParserNet(tiny).eval(), weights, {"step": 7})
    digest = hashlib.sha256((weights / "model.safetensors").read_bytes()).hexdigest()
    photos = tmp_path / "photos"
    photos.mkdir()
    _photo(photos, "bare")
    r = CliRunner().invoke(app, ["parse", str(photos), "--parser-weights", str(weights)])
    assert r.exit_code == 0, r.output
    hints = json.loads((photos / "bare.json").read_text())
    assert hints["parsed"]["by"] == f"parser-7-{digest[:8]}"
    for cmd in (["parse", str(photos)], ["convert", str(photos), "--out", str(tmp_path / "o")]):
        r = CliRunner().invoke(app, [*cmd, "--parser-weights", str(tmp_path / "photos")])
        assert r.exit_code == 2 and "no config.json" in r.output and "Traceback" not in r.output
        assert str(tmp_path / "photos") in r.output
    assert not (tmp_path / "o").exists()
