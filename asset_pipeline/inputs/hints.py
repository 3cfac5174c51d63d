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
from generator.procedural import CATEGORIES as PROCEDURAL_CATEGORIES

#: Categories a hint may name ("unknown" lets the generator decide).
CATEGORIES = (*PROCEDURAL_CATEGORIES, "unknown")

HINT_KEYS = ("id", "category", "height", "seed", "notes")


# --------------------------------------------------------------------------- hints


def check_hints(hints: Any, source: str = "<hints>") -> dict[str, Any]:
    """Return checked hints or raise InputError naming ``source`` and the key.

    Keys (all optional): ``id`` (asset id: letters, digits, ``_ . -``; starts with a
    letter or digit; at most 128 characters; not one of :data:`RESERVED_IDS`, case
    ignored), ``category`` (one of :data:`CATEGORIES`), ``height`` (the object's rest
    height in metres, 0 < h <= 5), ``seed`` (int >= 0, the generator's sampling
    seed), ``notes`` (free text).
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
    return out


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
