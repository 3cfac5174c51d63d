"""The image-folder input format that ``pact convert`` reads (docs/input-format.md).

A folder holds one item per photo::

    cab01.png          the photo (.png, .jpg or .jpeg; RGB or RGBA, alpha = silhouette)
    cab01.mask.png     optional part mask: 8-bit part ids, 0 background, 1 base, 2.. parts
    cab01.json         optional hints: {"category": "cabinet", "height": 0.9, "id": "..."}

:func:`discover_inputs` lists the items of a folder (cheap: it reads bytes only to
hash them); :func:`load_input` decodes and checks one item. Every problem raises
:class:`InputError` with a message that names the file and says what is wrong.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageOps

from generator.procedural import CATEGORIES as PROCEDURAL_CATEGORIES

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
MASK_SUFFIX = ".mask.png"
HINTS_SUFFIX = ".json"

#: Categories a hint may name ("unknown" lets the generator decide).
CATEGORIES = (*PROCEDURAL_CATEGORIES, "unknown")

#: Largest part id a mask may hold: ids are slot + 1 and there are at most 16 slots
#: (docs/dataset.md, ``max_parts``), so ids run 0 (background), 1 (base), 2..16.
MAX_PART_ID = 16

#: Asset ids become folder names and catalog keys.
ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,127}$")

#: Hint keys, their meaning and checks live in :func:`check_hints`; this is the set.
HINT_KEYS = ("id", "category", "height", "seed", "notes")


class InputError(ValueError):
    """An input item is unusable; the message names the file and what is wrong."""


@dataclass(frozen=True)
class InputItem:
    """One photo of an input folder and its optional companions.

    ``name`` is the photo's file name without its suffix (``cab01`` for
    ``cab01.png``). ``input_hash`` is the sha256 (hex) of the image, mask and hints
    bytes, so that a batch rerun can tell whether an item changed.
    """

    name: str
    image_path: Path
    mask_path: Path | None
    hints_path: Path | None
    input_hash: str


@dataclass
class LoadedInput:
    """A decoded, checked input item.

    image: (H, W, 3) uint8 RGB. alpha: (H, W) uint8 silhouette (255 = object) or
    None when the photo has no alpha channel or a fully opaque one. mask: (H, W)
    uint8 part ids or None. hints: the checked hints (empty when there is no file).
    """

    item: InputItem
    image: np.ndarray
    alpha: np.ndarray | None
    mask: np.ndarray | None
    hints: dict[str, Any] = field(default_factory=dict)

    @property
    def asset_id(self) -> str:
        """The id of the asset built from this item: the ``id`` hint, else the name."""
        return str(self.hints.get("id", self.item.name))

    @property
    def category(self) -> str:
        return str(self.hints.get("category", "unknown"))

    @property
    def height(self) -> float | None:
        h = self.hints.get("height")
        return None if h is None else float(h)

    @property
    def part_count(self) -> int | None:
        """Number of parts (base included) the mask shows, or None without a mask."""
        if self.mask is None:
            return None
        return int(self.mask.max())


# --------------------------------------------------------------------------- discovery


def _is_mask(p: Path) -> bool:
    return p.name.lower().endswith(MASK_SUFFIX)


def _is_image(p: Path) -> bool:
    return p.suffix.lower() in IMAGE_SUFFIXES and not _is_mask(p) and not p.name.startswith(".")


def _stem(p: Path) -> str:
    return p.name[: -len(p.suffix)]


def hash_files(*paths: Path | None) -> str:
    """sha256 (hex) over the bytes of ``paths``; a missing slot (None) hashes differently."""
    h = hashlib.sha256()
    for slot, p in enumerate(paths):
        if p is None:
            h.update(f"{slot}:none;".encode())
            continue
        data = p.read_bytes()
        h.update(f"{slot}:{len(data)};".encode())
        h.update(data)
    return h.hexdigest()


def _find_companion(folder: Path, name: str, suffix: str) -> Path | None:
    exact = folder / f"{name}{suffix}"
    if exact.is_file():
        return exact
    # case-insensitive suffix (cab01.MASK.PNG, cab01.JSON)
    for p in folder.iterdir():
        if p.is_file() and p.name.lower() == f"{name}{suffix}".lower():
            return p
    return None


def _make_item(image_path: Path) -> InputItem:
    folder, name = image_path.parent, _stem(image_path)
    mask = _find_companion(folder, name, MASK_SUFFIX)
    hints = _find_companion(folder, name, HINTS_SUFFIX)
    try:
        digest = hash_files(image_path, mask, hints)
    except OSError as e:
        raise InputError(f"{e.filename or image_path}: cannot read: {e.strerror or e}") from e
    return InputItem(name, image_path, mask, hints, digest)


def discover_inputs(folder: str | Path) -> list[InputItem]:
    """The items of an input folder (not recursive), sorted by name.

    ``folder`` may also be a single photo. ``*.mask.png`` files are masks, never
    photos; masks and hints without a photo are logged and ignored. Two photos with
    the same name (``a.png`` and ``a.jpg``) are an error.
    """
    folder = Path(folder)
    if folder.is_file():
        if not _is_image(folder):
            raise InputError(
                f"{folder}: not a photo (expected {', '.join(IMAGE_SUFFIXES)}, not a *{MASK_SUFFIX})"
            )
        return [_make_item(folder)]
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder")
    images = sorted((p for p in folder.iterdir() if p.is_file() and _is_image(p)), key=_stem)
    seen: dict[str, Path] = {}
    for p in images:
        other = seen.get(_stem(p))
        if other is not None:
            raise InputError(
                f"{p}: two photos share the name {_stem(p)!r} ({other.name} and {p.name}); rename one"
            )
        seen[_stem(p)] = p
    for p in sorted(folder.iterdir()):
        if _is_mask(p) and p.name[: -len(MASK_SUFFIX)] not in seen:
            log.warning("%s: mask without a photo; ignored", p)
        elif p.suffix.lower() == HINTS_SUFFIX and _stem(p) not in seen:
            log.debug("%s: JSON file without a photo; ignored", p)
    return [_make_item(p) for p in images]


# --------------------------------------------------------------------------- loading


def _open_image(path: Path, what: str) -> Image.Image:
    try:
        img = Image.open(path)
        img.load()
    except FileNotFoundError as e:
        raise InputError(f"{path}: {what} not found") from e
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError) as e:
        raise InputError(f"{path}: unreadable or corrupt {what}: {e}") from e
    return img


def read_image(path: str | Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Decode a photo: ((H, W, 3) uint8 RGB, (H, W) uint8 alpha or None).

    The EXIF orientation of camera photos is applied. Grey and palette images are
    expanded to RGB; an alpha channel that is fully opaque carries no silhouette and
    is returned as None.
    """
    path = Path(path)
    img = _open_image(path, "image")
    try:
        img = ImageOps.exif_transpose(img)
    except Exception as e:  # malformed EXIF must not sink a usable photo
        log.warning("%s: ignoring unreadable EXIF orientation: %s", path, e)
    if img.mode in ("I", "I;16", "I;16B", "I;16L", "F"):
        raise InputError(
            f"{path}: {img.mode} images are not supported; save the photo as 8-bit RGB"
        )
    has_alpha = img.mode in ("RGBA", "LA", "PA") or (img.mode == "P" and "transparency" in img.info)
    if has_alpha:
        rgba = np.asarray(img.convert("RGBA"))
        rgb, alpha = np.ascontiguousarray(rgba[..., :3]), np.ascontiguousarray(rgba[..., 3])
        if bool((alpha == 255).all()):
            alpha = None
    else:
        rgb, alpha = np.asarray(img.convert("RGB")), None
    if rgb.shape[0] == 0 or rgb.shape[1] == 0:
        raise InputError(f"{path}: image is empty ({rgb.shape[1]}x{rgb.shape[0]})")
    return rgb.astype(np.uint8, copy=False), alpha


def read_mask(path: str | Path, size: tuple[int, int] | None = None) -> np.ndarray:
    """Decode and check a part mask; returns (H, W) uint8 ids.

    ``size`` is the photo's (width, height); the mask must match it. Accepted
    encodings: 8-bit grey (``L``), palette (``P``: the palette indices are the ids),
    grey with alpha (alpha ignored), and RGB/RGBA whose three colour channels are
    equal (a grey image saved as colour). See :func:`check_mask` for the id rules.
    """
    path = Path(path)
    img = _open_image(path, "mask")
    if size is not None and img.size != tuple(size):
        raise InputError(
            f"{path}: mask is {img.size[0]}x{img.size[1]} but the image is {size[0]}x{size[1]}; "
            "they must be the same size"
        )
    if img.mode in ("L", "P"):
        ids = np.asarray(img)
    elif img.mode == "LA":
        ids = np.asarray(img)[..., 0]
    elif img.mode in ("RGB", "RGBA"):
        a = np.asarray(img)
        if not (np.array_equal(a[..., 0], a[..., 1]) and np.array_equal(a[..., 0], a[..., 2])):
            raise InputError(
                f"{path}: mask has colour channels that differ; a mask must be a single-channel "
                "8-bit image of part ids (0 background, 1 base, 2.. movable parts)"
            )
        ids = a[..., 0]
    elif img.mode in ("I", "I;16", "I;16B", "I;16L"):
        a = np.asarray(img).astype(np.int64)
        if a.min() < 0 or a.max() > 255:
            raise InputError(
                f"{path}: 16-bit mask holds values outside 0..255; save it as 8-bit ids"
            )
        ids = a
    elif img.mode == "1":
        raise InputError(
            f"{path}: mask is 1-bit; part ids need an 8-bit single-channel image "
            "(0 background, 1 base, 2.. movable parts)"
        )
    else:
        raise InputError(f"{path}: mask mode {img.mode} is not supported; save an 8-bit grey PNG")
    ids = np.ascontiguousarray(ids, dtype=np.uint8)
    check_mask(ids, str(path))
    return ids


def check_mask(ids: np.ndarray, source: str = "<mask>") -> None:
    """Raise InputError unless ``ids`` is a valid part-id mask.

    Rules: every id is within 0..MAX_PART_ID; when any id is above 0 the base (id 1)
    is present; the ids present above 0 are consecutive (1..K, no gaps), so the
    mask shows K parts in object order.
    """
    present = np.unique(ids)
    too_big = present[present > MAX_PART_ID]
    if too_big.size:
        raise InputError(
            f"{source}: mask holds part ids {too_big.tolist()[:8]} above {MAX_PART_ID} "
            f"(at most {MAX_PART_ID} parts: 0 background, 1 base, 2..{MAX_PART_ID} movable parts); "
            "is this a colour image or an anti-aliased mask?"
        )
    fg = [int(v) for v in present if v > 0]
    if not fg:
        return
    if 1 not in fg:
        raise InputError(
            f"{source}: mask has part ids {fg} but no base (id 1); the base must be visible"
        )
    missing = sorted(set(range(1, max(fg) + 1)) - set(fg))
    if missing:
        raise InputError(
            f"{source}: mask part ids must be consecutive 1..K; ids {missing} are missing "
            f"(present: {fg}); renumber the movable parts 2, 3, ..."
        )


def check_hints(hints: Any, source: str = "<hints>") -> dict[str, Any]:
    """Return checked hints or raise InputError naming ``source`` and the key.

    Keys (all optional): ``id`` (asset id: letters, digits, ``_ . -``; starts with a
    letter or digit; at most 128 characters), ``category`` (one of
    :data:`CATEGORIES`), ``height`` (the object's rest height in metres, 0 < h <= 5),
    ``seed`` (int >= 0, the generator's sampling seed), ``notes`` (free text).
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
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as e:
        raise InputError(f"{path}: hints file not found") from e
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: hints are not valid JSON: {e}") from e
    return check_hints(data, str(path))


def load_input(item: InputItem) -> LoadedInput:
    """Decode and check one item (image, mask, hints); raise InputError on any fault."""
    image, alpha = read_image(item.image_path)
    h, w = image.shape[:2]
    mask = None if item.mask_path is None else read_mask(item.mask_path, size=(w, h))
    hints = {} if item.hints_path is None else read_hints(item.hints_path)
    if mask is not None and alpha is not None:
        outside = int(((mask > 0) & (alpha == 0)).sum())
        if outside > 0.01 * mask.size:
            log.warning(
                "%s: %d mask pixels lie outside the photo's alpha silhouette",
                item.mask_path,
                outside,
            )
    return LoadedInput(item=item, image=image, alpha=alpha, mask=mask, hints=hints)
