"""An image folder as ``pact convert`` reads it (docs/input-format.md).

A folder holds one item per photo::

    cab01.png          the photo (.png, .jpg, .jpeg, .webp, .bmp, .tif, .tiff;
                       RGB or RGBA, alpha = silhouette)
    cab01.mask.png     optional part mask: 8-bit part ids, 0 background, 1 base, 2.. parts
    cab01.json         optional hints: {"category": "cabinet", "height": 0.9, "id": "..."}

:func:`discover_inputs` lists the items of a folder and the files it skipped (cheap:
it reads bytes only to hash them and to read the hints' ``id``); :func:`load_input`
decodes and checks one item. Every problem raises :class:`InputError` with a message
that names the file, says what is wrong and what to do.
"""

from __future__ import annotations

import errno
import hashlib
import json
import logging
import os
import stat
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, overload

import numpy as np

from asset_pipeline.inputs.asset_ids import ID_PATTERN, asset_id_for, is_reserved_id
from asset_pipeline.inputs.errors import InputError
from asset_pipeline.inputs.hints import check_part_ids, read_hints, renumber_parts
from asset_pipeline.inputs.mask import check_mask_edges, check_mask_matches_photo, read_mask
from asset_pipeline.inputs.photo import read_image

log = logging.getLogger(__name__)

#: Photo suffixes (case-insensitive); every one is a format Pillow decodes.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".webp", ".bmp", ".tif", ".tiff")
MASK_SUFFIX = ".mask.png"
HINTS_SUFFIX = ".json"


def _hinted_id(hints_path: Path | None) -> str | None:
    """The valid ``id`` of a hints file, or None (no file, no id, unreadable or invalid).

    Never raises: :func:`read_hints` reports a bad hints file when the item is loaded.
    """
    if hints_path is None:
        return None
    try:
        hints = json.loads(hints_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):  # ValueError covers JSON and UTF-8 decoding errors
        return None
    v = hints.get("id") if isinstance(hints, dict) else None
    if isinstance(v, str) and ID_PATTERN.match(v) and not is_reserved_id(v):
        return v
    return None


# --------------------------------------------------------------------------- data


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

    def resolve_asset_id(self) -> tuple[str, str | None]:
        """``(asset id, note)``: the hints' valid ``id`` (note None), else
        :func:`asset_id_for` of the name. Reads the hints file; never raises."""
        hinted = _hinted_id(self.hints_path)
        if hinted is not None:
            return hinted, None
        return asset_id_for(self.name)

    @property
    def asset_id(self) -> str:
        """The id of the asset built from this item (see :meth:`resolve_asset_id`)."""
        return self.resolve_asset_id()[0]


@dataclass(frozen=True)
class SkippedFile:
    """A file of an input folder that is not part of any item, and why."""

    path: Path
    reason: str


@dataclass
class InputListing(Sequence[InputItem]):
    """What :func:`discover_inputs` found: the items and the files it skipped.

    Indexing, iterating and ``len()`` act on ``items``, so code written for the
    former ``list[InputItem]`` return keeps working (but does not see ``skipped``).
    """

    items: list[InputItem] = field(default_factory=list)
    skipped: list[SkippedFile] = field(default_factory=list)

    @overload
    def __getitem__(self, index: int) -> InputItem: ...

    @overload
    def __getitem__(self, index: slice) -> list[InputItem]: ...

    def __getitem__(self, index: int | slice) -> InputItem | list[InputItem]:
        return self.items[index]

    def __iter__(self) -> Iterator[InputItem]:
        return iter(self.items)

    def __len__(self) -> int:
        return len(self.items)


@dataclass
class LoadedInput:
    """A decoded, checked input item.

    image: (H, W, 3) uint8 RGB. alpha: (H, W) uint8 silhouette (255 = object) or
    None when the photo has no alpha channel or a fully opaque one. mask: (H, W)
    uint8 part ids or None. hints: the checked hints (empty when there is no file).
    warnings: doubts about the item that did not refuse it (each naming the file).
    """

    item: InputItem
    image: np.ndarray
    alpha: np.ndarray | None
    mask: np.ndarray | None
    hints: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def asset_id(self) -> str:
        """The id of the asset built from this item: the ``id`` hint, else
        :func:`asset_id_for` of the name."""
        if "id" in self.hints:
            return str(self.hints["id"])
        return asset_id_for(self.item.name)[0]

    @property
    def asset_id_note(self) -> str | None:
        """Why :attr:`asset_id` differs from the photo's name, or None when it does not
        (or when the hints give the id)."""
        if "id" in self.hints:
            return None
        return asset_id_for(self.item.name)[1]

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


def _is_hints(p: Path) -> bool:
    return p.suffix.lower() == HINTS_SUFFIX


def _is_image(p: Path) -> bool:
    return p.suffix.lower() in IMAGE_SUFFIXES and not _is_mask(p) and not p.name.startswith(".")


def _stem(p: Path) -> str:
    return p.name[: -len(p.suffix)]


def _companion_stem(p: Path) -> str:
    """The photo name a mask or hints file belongs to (``cab01`` for ``cab01.mask.png``)."""
    return p.name[: -len(MASK_SUFFIX)] if _is_mask(p) else _stem(p)


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


def _unusable_reason(p: Path) -> str | None:
    """Why ``p`` (symlinks followed) cannot be an input file, or None for a regular file."""
    try:
        st = os.stat(p)
    except FileNotFoundError:
        if p.is_symlink():
            return "broken symlink (its target does not exist); fix or delete the link"
        return "vanished while the folder was listed"
    except OSError as e:
        if e.errno == errno.ELOOP:
            return "symlink loop (the link resolves to itself); fix or delete the link"
        return f"cannot be inspected: {e.strerror or e}"
    if stat.S_ISDIR(st.st_mode):
        return "subfolder (folders are not searched recursively); convert it separately"
    if not stat.S_ISREG(st.st_mode):
        return "not a regular file (a device, pipe or socket)"
    return None


class _Companions:
    """The mask or hints files of a folder, found by photo name in O(1)."""

    def __init__(self, files: list[Path], suffix: str) -> None:
        self.suffix = suffix
        self.exact = {p.name: p for p in files}
        self.folded: dict[str, Path] = {}
        for p in sorted(files):
            self.folded.setdefault(p.name.lower(), p)

    def find(self, name: str) -> Path | None:
        """The companion of photo ``name``: the exact file name first, else one whose
        name matches ignoring case (``cab01.MASK.PNG``, ``CAB01.json``)."""
        wanted = f"{name}{self.suffix}"
        return self.exact.get(wanted) or self.folded.get(wanted.lower())


def _make_item(image_path: Path, masks: _Companions, hints: _Companions) -> InputItem:
    name = _stem(image_path)
    mask_path, hints_path = masks.find(name), hints.find(name)
    try:
        digest = hash_files(image_path, mask_path, hints_path)
    except OSError as e:
        raise InputError(
            f"{e.filename or image_path}: cannot read: {e.strerror or e}; check its permissions"
        ) from e
    return InputItem(name, image_path, mask_path, hints_path, digest)


def _regular_companions(folder: Path) -> tuple[list[Path], list[Path]]:
    """The regular mask and hints files of ``folder``, sorted by file name."""
    masks, hints = [], []
    for p in sorted(folder.iterdir()):
        if (_is_mask(p) or _is_hints(p)) and _unusable_reason(p) is None:
            (masks if _is_mask(p) else hints).append(p)
    return masks, hints


def discover_inputs(folder: str | Path) -> InputListing:
    """The items of an input folder (not recursive), sorted by name, and what was skipped.

    ``folder`` may also be a single photo (its companions are looked up beside it;
    nothing is listed as skipped). ``*.mask.png`` files are masks, never photos.
    Listed in ``skipped``: files of an unsupported type, masks and hints without a
    photo (or beside the one that is used), subfolders, broken symlinks and symlink
    loops, and other non-regular files; hidden files (``.name``) are skipped without
    a listing. Raises InputError when ``folder`` does not exist or is a file that is
    not a photo, when two photos share a name (``a.png`` and ``a.jpg``) or two items
    would get the same asset id, or when a file of an item cannot be read.
    """
    folder = Path(folder)
    if folder.is_file():
        if not _is_image(folder):
            raise InputError(
                f"{folder}: not a photo (expected {', '.join(IMAGE_SUFFIXES)}, not a "
                f"*{MASK_SUFFIX}); give a folder or a photo"
            )
        masks, hints = _regular_companions(folder.parent)
        item = _make_item(folder, _Companions(masks, MASK_SUFFIX), _Companions(hints, HINTS_SUFFIX))
        return InputListing(items=[item])
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder; give a folder of photos or one photo")

    photos: list[Path] = []
    masks: list[Path] = []
    hints: list[Path] = []
    skipped: list[SkippedFile] = []
    for p in sorted(folder.iterdir()):
        if p.name.startswith("."):
            continue
        reason = _unusable_reason(p)
        if reason is not None:
            skipped.append(SkippedFile(p, reason))
        elif _is_mask(p):
            masks.append(p)
        elif _is_hints(p):
            hints.append(p)
        elif _is_image(p):
            photos.append(p)
        else:
            kind = f"'{p.suffix.lower()}'" if p.suffix else "without a suffix"
            skipped.append(
                SkippedFile(
                    p,
                    f"unsupported file type {kind} (photos are {', '.join(IMAGE_SUFFIXES)}); "
                    "convert it to .png to include it",
                )
            )

    photos.sort(key=_stem)
    seen: dict[str, Path] = {}
    for p in photos:
        other = seen.get(_stem(p))
        if other is not None:
            raise InputError(
                f"{p}: two photos share the name {_stem(p)!r} ({other.name} and {p.name}); rename one"
            )
        seen[_stem(p)] = p
    mask_index, hints_index = _Companions(masks, MASK_SUFFIX), _Companions(hints, HINTS_SUFFIX)
    items = [_make_item(p, mask_index, hints_index) for p in photos]
    used = {p for item in items for p in (item.mask_path, item.hints_path) if p is not None}
    photo_names = {name.lower() for name in seen}
    for p in [*masks, *hints]:
        if p in used:
            continue
        what = "mask" if _is_mask(p) else "hints file"
        if _companion_stem(p).lower() in photo_names:
            reason = f"another {what} of the same photo is used (names differ only in case)"
        else:
            reason = (
                f"{what} without a photo (no {_companion_stem(p)} with a suffix of "
                f"{', '.join(IMAGE_SUFFIXES)})"
            )
        skipped.append(SkippedFile(p, reason))
    skipped.sort(key=lambda s: s.path.name)
    for s in skipped:
        log.debug("%s: skipped: %s", s.path, s.reason)
    return InputListing(items=items, skipped=skipped)


# --------------------------------------------------------------------------- loading


# --------------------------------------------------------------------------- one item


def load_input(item: InputItem) -> LoadedInput:
    """Decode and check one item (image, mask, hints); raise InputError on any fault.

    Beyond the checks of :func:`read_image`, :func:`read_mask` and
    :func:`read_hints`, the mask must match the photo (:func:`check_mask_matches_photo`,
    :func:`check_mask_edges`: refused on strong evidence, else a warning).
    """
    image, alpha = read_image(item.image_path)
    h, w = image.shape[:2]
    warnings: list[str] = []
    renumbered: dict[int, int] = {}
    mask = (
        None if item.mask_path is None else read_mask(item.mask_path, (w, h), warnings, renumbered)
    )
    hints = {} if item.hints_path is None else read_hints(item.hints_path)
    if renumbered:  # the hints name the parts by the ids as the mask was saved
        hints = renumber_parts(hints, renumbered)
    check_part_ids(
        hints, None if mask is None else {int(v) for v in np.unique(mask)}, str(item.hints_path)
    )
    if mask is not None:
        check_mask_matches_photo(mask, image, alpha, str(item.mask_path))
        warnings += check_mask_edges(mask, image, str(item.mask_path))
        if alpha is not None:
            outside = int(np.count_nonzero((mask > 0) & (alpha == 0)))
            if outside > 0.01 * mask.size:
                log.warning(
                    "%s: %d mask pixels lie outside the photo's alpha silhouette",
                    item.mask_path,
                    outside,
                )
    return LoadedInput(
        item=item, image=image, alpha=alpha, mask=mask, hints=hints, warnings=warnings
    )
