"""The hints file of an input item (docs/input-format.md, "Hints"): a JSON object of
optional keys, unknown keys refused.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from asset_pipeline.inputs.asset_ids import ID_PATTERN, RESERVED_IDS, is_reserved_id
from asset_pipeline.inputs.errors import InputError
from asset_pipeline.inputs.mask import MAX_PART_ID
from generator.motions import MOTIONS
from generator.procedural import CATEGORIES as PROCEDURAL_CATEGORIES

#: Categories a hint may name: the seven the project makes, "other" (something else: the
#: photo parser says so), and "unknown" (let the parser or the generator decide).
CATEGORIES = (*PROCEDURAL_CATEGORIES, "other", "unknown")

HINT_KEYS = ("id", "category", "height", "seed", "notes", "parts", "parsed")
#: Keys of one part's entry under ``parts``.
PART_KEYS = ("motion",)
#: Keys of the ``parsed`` record (what the photo parser wrote, with its confidences).
PARSED_KEYS = ("by", "category", "mask", "parts")


# --------------------------------------------------------------------------- hints


def check_hints(hints: Any, source: str = "<hints>") -> dict[str, Any]:
    """Return checked hints or raise InputError naming ``source`` and the key.

    Keys (all optional): ``id`` (asset id: letters, digits, ``_ . -``; starts with a
    letter or digit; at most 128 characters; not one of :data:`RESERVED_IDS`, case
    ignored), ``category`` (one of :data:`CATEGORIES`), ``height`` (the object's rest
    height in metres, 0 < h <= 5), ``seed`` (int >= 0, the generator's sampling
    seed), ``notes`` (free text), ``parts`` (per movable part of the mask, keyed by its
    mask id "2".."16": ``{"motion": m}`` with ``m`` one of
    :data:`generator.motions.MOTIONS`), ``parsed`` (which of the other keys the photo
    parser wrote, and its confidence in each: ``{"by": version, "category": c, "mask": c,
    "parts": {"2": c}}``, confidences in 0..1; a key the record does not name is the
    user's). Whether the ids of ``parts`` are in the mask is checked with the mask
    (:func:`check_part_ids`).
    """
    if not isinstance(hints, dict):
        raise InputError(f"{source}: hints must be a JSON object, got {type(hints).__name__}")
    unknown = sorted(set(hints) - set(HINT_KEYS))
    if unknown:
        raise InputError(f"{source}: unknown hint keys {unknown}; known keys: {list(HINT_KEYS)}")
    out: dict[str, Any] = {}
    if "id" in hints:
        v = hints["id"]
        if not isinstance(v, str) or not ID_PATTERN.match(v):
            raise InputError(
                f"{source}: id: {v!r} is not a valid asset id (letters, digits, '_', '.', '-'; "
                "starting with a letter or digit; at most 128 characters)"
            )
        if is_reserved_id(v):
            raise InputError(
                f"{source}: id: {v!r} is reserved: the output folder keeps that name for its "
                f"catalog or gallery ({', '.join(sorted(RESERVED_IDS))}, case ignored); "
                "choose another id"
            )
        out["id"] = v
    if "category" in hints:
        v = hints["category"]
        if not isinstance(v, str) or v not in CATEGORIES:
            raise InputError(f"{source}: category: {v!r} is not one of {list(CATEGORIES)}")
        out["category"] = v
    if "height" in hints:
        v = hints["height"]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"{source}: height: must be a number of metres, got {v!r}")
        if not (math.isfinite(v) and 0 < v <= 5.0):
            raise InputError(f"{source}: height: must be within (0, 5] metres, got {v}")
        out["height"] = float(v)
    if "seed" in hints:
        v = hints["seed"]
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise InputError(f"{source}: seed: must be an integer >= 0, got {v!r}")
        out["seed"] = v
    if "notes" in hints:
        v = hints["notes"]
        if not isinstance(v, str):
            raise InputError(f"{source}: notes: must be a string, got {type(v).__name__}")
        out["notes"] = v
    if "parts" in hints:
        out["parts"] = _check_parts(hints["parts"], source)
    if "parsed" in hints:
        out["parsed"] = _check_parsed(hints["parsed"], source)
    return out


def _part_id(key: Any, source: str, where: str) -> int:
    if not (isinstance(key, str) and key.isdigit() and 2 <= int(key) <= MAX_PART_ID):
        raise InputError(
            f'{source}: {where}: {key!r} is not a movable part\'s mask id ("2" .. '
            f'"{MAX_PART_ID}"; 1 is the base)'
        )
    return int(key)


def _check_parts(parts: Any, source: str) -> dict[str, dict[str, str]]:
    if not isinstance(parts, dict):
        raise InputError(f"{source}: parts: must be an object keyed by mask id, e.g. "
                         '{"2": {"motion": "door_left"}}')  # fmt: skip
    out = {}
    for key, entry in parts.items():
        _part_id(key, source, "parts")
        where = f"parts.{key}"
        if not isinstance(entry, dict):
            raise InputError(f'{source}: {where}: must be an object like {{"motion": "drawer"}}')
        unknown = sorted(set(entry) - set(PART_KEYS))
        if unknown:
            raise InputError(f"{source}: {where}: unknown keys {unknown}; known: {list(PART_KEYS)}")
        if "motion" in entry and entry["motion"] not in MOTIONS:
            raise InputError(
                f"{source}: {where}.motion: {entry['motion']!r} is not one of {list(MOTIONS)}"
            )
        out[key] = {k: str(v) for k, v in entry.items()}
    return out


def _confidence(v: Any, source: str, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
        raise InputError(f"{source}: {where}: a confidence must be a number in 0..1, got {v!r}")
    return float(v)


def _check_parsed(parsed: Any, source: str) -> dict[str, Any]:
    if not isinstance(parsed, dict):
        raise InputError(f"{source}: parsed: must be an object (what the photo parser wrote)")
    unknown = sorted(set(parsed) - set(PARSED_KEYS))
    if unknown:
        raise InputError(f"{source}: parsed: unknown keys {unknown}; known: {list(PARSED_KEYS)}")
    out: dict[str, Any] = {}
    if "by" in parsed:
        out["by"] = str(parsed["by"])
    for key in ("category", "mask"):
        if key in parsed:
            out[key] = _confidence(parsed[key], source, f"parsed.{key}")
    if "parts" in parsed:
        if not isinstance(parsed["parts"], dict):
            raise InputError(f"{source}: parsed.parts: must be an object keyed by mask id")
        out["parts"] = {
            k: _confidence(v, source, f"parsed.parts.{_part_id(k, source, 'parsed.parts')}")
            for k, v in parsed["parts"].items()
        }
    return out


def check_part_ids(hints: dict[str, Any], mask_ids: set[int] | None, source: str) -> None:
    """Refuse ``parts`` entries for ids the mask does not hold (or any, without a mask)."""
    ids = {int(k) for k in hints.get("parts", {})}
    if not ids:
        return
    if mask_ids is None:
        raise InputError(
            f"{source}: parts: motions are given for mask ids {sorted(ids)} but the photo has "
            "no mask; add the part mask or remove 'parts'"
        )
    missing = sorted(ids - mask_ids)
    if missing:
        raise InputError(
            f"{source}: parts: the mask has no part with id {missing} "
            f"(its movable parts: {sorted(i for i in mask_ids if i >= 2)})"
        )


def read_hints(path: str | Path) -> dict[str, Any]:
    """Read and check a hints file (see :func:`check_hints`)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as e:
        raise InputError(f"{path}: hints file not found") from e
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: hints are not valid JSON: {e}") from e
    return check_hints(data, str(path))


def renumber_parts(hints: dict[str, Any], renumbered: dict[int, int]) -> dict[str, Any]:
    """``hints`` with the mask ids of ``parts`` and ``parsed.parts`` renumbered as the mask
    was (old -> new; ids not named keep theirs)."""

    def move(entries: dict[str, Any]) -> dict[str, Any]:
        return {str(renumbered.get(int(k), int(k))): v for k, v in entries.items()}

    out = dict(hints)
    if "parts" in out:
        out["parts"] = move(out["parts"])
    if "parts" in out.get("parsed", {}):
        out["parsed"] = {**out["parsed"], "parts": move(out["parsed"]["parts"])}
    return out
