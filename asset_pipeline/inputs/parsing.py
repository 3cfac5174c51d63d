"""An input item completed by the photo parser: the part mask, the category, each part's motion.

A photo may come with a part mask and hints, or alone (what users mostly have). What it
lacks the project's photo parser reads from the photo (:mod:`generator.parser`: a
network trained on the project's renders), and what the user gives always wins:

- no mask: the parser's mask (or, with ``segmenter="sam2"``, SAM2's automatic masks merged
  into parts by the parser, as the PAct paper merges them with a vision-language model);
- no category (or ``"unknown"``): the parser's category;
- a movable part of the mask without a motion in the hints' ``parts``: the parser's motion
  for that region.

:func:`complete_input` returns the completed item and where each field came from
(:class:`InputSources`): ``user`` (the mask and hints files), ``parser`` with its
confidence (read now, or written earlier by ``pact parse`` or the gallery's editor: the
hints' ``parsed`` record names those fields), or ``none`` (nobody gave it). The
sources go into the asset's provenance (``asset.json``), its catalog row (``pact ls``)
and the gallery.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from asset_pipeline.inputs.errors import InputError
from asset_pipeline.inputs.folder import LoadedInput
from asset_pipeline.inputs.mask import check_mask

log = logging.getLogger(__name__)

#: How a missing mask is made: the parser alone, or SAM2's fragments merged by the parser.
SEGMENTERS = ("parser", "sam2")


class Parser(Protocol):
    """What this module needs of :class:`generator.parser.PhotoParser`."""

    version: str

    def parse(
        self, image: np.ndarray, alpha: np.ndarray | None = None, category: str | None = None
    ) -> Any: ...

    def label(self, image: np.ndarray, mask: np.ndarray, category: str | None = None) -> Any: ...


class Segmenter(Protocol):
    """What this module needs of :class:`generator.parser.sam2_segmenter.Sam2Segmenter`."""

    def segment(self, image: np.ndarray, parser: Any) -> Any: ...


@dataclass
class FieldSource:
    """Where one field came from: ``user``, ``parser`` (``confidence`` in 0..1, ``by`` the
    parser's version) or ``none``."""

    source: str
    confidence: float | None = None
    by: str | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"source": self.source}
        if self.confidence is not None:
            out["confidence"] = round(float(self.confidence), 4)
        if self.by:
            out["by"] = self.by
        return out


@dataclass
class InputSources:
    """Where an item's category, part mask and each movable part's motion came from."""

    category: FieldSource = field(default_factory=lambda: FieldSource("none"))
    mask: FieldSource = field(default_factory=lambda: FieldSource("none"))
    #: mask id -> (motion, its source)
    parts: dict[int, tuple[str, FieldSource]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            "category": self.category.to_json(),
            "mask": self.mask.to_json(),
            "parts": {
                str(k): {"motion": m, **s.to_json()} for k, (m, s) in sorted(self.parts.items())
            },
        }


def _given(hints: dict[str, Any], key: str, parsed: dict[str, Any]) -> FieldSource:
    """The source of a hint the file gives: the parser's when its ``parsed`` record names
    the key (with the confidence it wrote), else the user's."""
    if key in parsed:
        return FieldSource("parser", parsed[key], parsed.get("by"))
    return FieldSource("user")


def _parsed_part_confidence(parsed: dict[str, Any], mask_id: int) -> float | None:
    return (parsed.get("parts") or {}).get(str(mask_id))


def complete_input(
    loaded: LoadedInput, parser: Parser, segmenter: Segmenter | None = None
) -> tuple[LoadedInput, InputSources]:
    """``loaded`` with what it lacks read by ``parser`` (the module docstring), and the
    sources of its fields. The parser's mask must pass the mask rules
    (:func:`~asset_pipeline.inputs.mask.check_mask`); one that does not, or that finds no
    object, is left out with a warning, and the item goes on without a mask."""
    hints = dict(loaded.hints)
    parsed_record = dict(hints.get("parsed") or {})
    sources = InputSources()
    image, mask = loaded.image, loaded.mask
    warnings = list(loaded.warnings)
    where = str(loaded.item.image_path)
    version = getattr(parser, "version", None)
    # a category the user gives also steers the parser's motions (a fridge's doors swing)
    has_category = hints.get("category") not in (None, "unknown")
    category = hints["category"] if has_category else None
    reading = None
    if mask is None:
        reading = (
            segmenter.segment(image, parser)
            if segmenter is not None
            else parser.parse(image, loaded.alpha, category)
        )
        try:
            if not (reading.mask > 0).any():
                raise InputError(f"{where}: the parser found no object in the photo")
            check_mask(reading.mask, f"{where} (the parser's mask)")
        except InputError as e:
            warnings.append(f"{e}; converted without a part mask")
            log.warning("%s", warnings[-1])
        else:
            mask = np.ascontiguousarray(reading.mask, dtype=np.uint8)
            for note in getattr(reading, "notes", []):
                warnings.append(f"{where}: {note}")
                log.warning("%s", warnings[-1])
            how = "sam2+parser" if segmenter is not None else "parser"
            sources.mask = FieldSource("parser", None, f"{version} ({how})" if version else how)
    else:
        sources.mask = _given(hints, "mask", parsed_record)
    movable = [] if mask is None else [int(v) for v in np.unique(mask) if v >= 2]
    given_parts = {
        int(k): v["motion"] for k, v in (hints.get("parts") or {}).items() if v.get("motion")
    }
    if (
        reading is None
        and mask is not None
        and (not has_category or set(movable) - set(given_parts))
    ):
        reading = parser.label(image, mask, category)
    if has_category:
        sources.category = _given(hints, "category", parsed_record)
    elif reading is not None:
        hints["category"] = reading.category
        sources.category = FieldSource("parser", reading.category_confidence, version)
    read_parts = {} if reading is None else {p.id: p for p in reading.parts}
    parts = dict(hints.get("parts") or {})
    for k in movable:
        if k in given_parts:
            conf = _parsed_part_confidence(parsed_record, k)
            src = (
                FieldSource("user")
                if conf is None
                else FieldSource("parser", conf, parsed_record.get("by"))
            )
            sources.parts[k] = (given_parts[k], src)
        elif k in read_parts:
            p = read_parts[k]
            parts[str(k)] = {"motion": p.motion}
            sources.parts[k] = (p.motion, FieldSource("parser", p.confidence, version))
    if parts:
        hints["parts"] = parts
    completed = dataclasses.replace(loaded, mask=mask, hints=hints, warnings=warnings)
    return completed, sources


def given_sources(loaded: LoadedInput) -> InputSources:
    """The sources of what ``loaded``'s files give, when no parser runs."""
    hints = loaded.hints
    parsed = dict(hints.get("parsed") or {})
    sources = InputSources()
    if loaded.mask is not None:
        sources.mask = _given(hints, "mask", parsed)
    if hints.get("category") not in (None, "unknown"):
        sources.category = _given(hints, "category", parsed)
    for key, entry in (hints.get("parts") or {}).items():
        if entry.get("motion"):
            conf = _parsed_part_confidence(parsed, int(key))
            src = (
                FieldSource("user")
                if conf is None
                else FieldSource("parser", conf, parsed.get("by"))
            )
            sources.parts[int(key)] = (entry["motion"], src)
    return sources


@dataclass
class ParseWritten:
    """What :func:`write_parsed` wrote for one photo (paths) and what it read."""

    mask: Path | None
    hints: Path | None
    sources: InputSources


def parsed_hints(hints: dict[str, Any], sources: InputSources) -> dict[str, Any]:
    """``hints`` with a ``parsed`` record naming the fields the parser gave (with its
    confidences), for a hints file a person checks before converting."""
    out = {k: v for k, v in hints.items() if k != "parsed"}
    record: dict[str, Any] = {}
    by = None
    if sources.category.source == "parser":
        record["category"] = sources.category.confidence
        by = sources.category.by or by
    if sources.mask.source == "parser":
        record["mask"] = sources.mask.confidence if sources.mask.confidence is not None else 0.0
        by = by or sources.mask.by
    parts = {str(k): s.confidence for k, (_, s) in sources.parts.items() if s.source == "parser"}
    if parts:
        record["parts"] = parts
        by = by or next(s.by for _, s in sources.parts.values() if s.source == "parser")
    if record:
        record["by"] = by
        out["parsed"] = {k: v for k, v in record.items() if v is not None}
    return out


def write_parsed(
    loaded: LoadedInput, parser: Parser, segmenter: Segmenter | None = None, overwrite: bool = False
) -> ParseWritten:
    """``pact parse`` for one item: read what it lacks (:func:`complete_input`) and write
    the parser's mask (``<name>.mask.png``) and hints (``<name>.json``, the user's keys
    kept, a ``parsed`` record naming the parser's fields) beside the photo, for a person
    to check before converting. A user's mask is never replaced unless ``overwrite``
    (then the parser reads the photo afresh)."""
    import json

    from asset_pipeline.inputs.mask import write_mask
    from generator.atomic_files import atomic_write_bytes

    item = loaded.item
    if overwrite and loaded.mask is not None:  # the parser reads the photo afresh
        hints = {k: v for k, v in loaded.hints.items() if k not in ("parts", "parsed")}
        loaded = dataclasses.replace(loaded, mask=None, hints=hints)
    done, sources = complete_input(loaded, parser, segmenter)
    photo = Path(item.image_path)
    mask_path = hints_path = None
    if sources.mask.source == "parser" and done.mask is not None:
        mask_path = write_mask(
            done.mask,
            item.mask_path if item.mask_path else photo.with_name(photo.stem + ".mask.png"),
        )
    hints = parsed_hints(done.hints, sources)
    if hints != loaded.hints:
        hints_path = Path(item.hints_path) if item.hints_path else photo.with_suffix(".json")
        atomic_write_bytes(hints_path, (json.dumps(hints, indent=2) + "\n").encode())
    return ParseWritten(mask_path, hints_path, sources)
