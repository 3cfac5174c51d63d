"""The gallery's mask editor, server side (docs/gallery.md, "Mask editor").

A person opens an asset's photo with its part mask in the served gallery, draws what
the photo parser (or an earlier user) got wrong, chooses each movable part's motion and
the category, and saves. This module is everything the server does for that, with no
HTTP in it (:mod:`asset_pipeline.gallery.server` routes requests here):

- :meth:`MaskEditor.state`, :meth:`MaskEditor.photo_png`, :meth:`MaskEditor.mask_png`:
  what the editor opens for a catalogued asset: its input photo (the catalog's
  ``source_image``), the current part mask (the asset folder's ``input.mask.png``, else
  the photo's own ``<name>.mask.png``) and the hints file beside the photo.
- :meth:`MaskEditor.save`: checks a save (the mask: a PNG of part ids at the photo's
  size, :func:`asset_pipeline.inputs.mask.check_mask` and the rest of what ``pact
  convert`` would refuse; the hints: :func:`asset_pipeline.inputs.hints.check_hints`)
  and only then writes exactly two files beside the photo, ``<name>.mask.png`` and
  ``<name>.json``, each atomically; then queues the re-conversion of that one item.
- :class:`Reconverter`: one background thread converting the saved items one at a
  time into OUT (:func:`asset_pipeline.catalog.batch.run_convert` with the photo as
  IMAGES, ``force=True``, the generator the catalog recorded for the asset and default
  settings otherwise), then rewriting the gallery page.

No path from a request is ever used: an asset is named by its id, which must be a
catalog row, and every file comes from that row. The hints keep every key of the file
as it was except ``category`` (when the person set or confirmed it), ``parts`` (the
motions of the saved mask's movable parts) and ``parsed`` (what the photo parser
wrote: an entry the person set or confirmed, or that the edit changed, is removed so
that the catalog says it came from the user; :func:`edited_hints`).
"""

from __future__ import annotations

import base64
import binascii
import io
import json
import logging
import queue
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from asset_pipeline.catalog.batch import ConvertSettings, run_convert
from asset_pipeline.catalog.registry import AssetRecord, Catalog, CatalogError, catalog_path
from asset_pipeline.inputs.asset_ids import asset_id_for
from asset_pipeline.inputs.errors import InputError
from asset_pipeline.inputs.folder import (
    HINTS_SUFFIX,
    IMAGE_SUFFIXES,
    MASK_SUFFIX,
    discover_inputs,
)
from asset_pipeline.inputs.hints import CATEGORIES, check_hints, check_part_ids, renumber_parts
from asset_pipeline.inputs.mask import (
    MAX_PART_ID,
    check_mask,
    check_mask_edges,
    check_mask_matches_photo,
    clean_mask,
    mask_png,
    read_mask,
)
from asset_pipeline.inputs.photo import read_image
from generator.atomic_files import atomic_write_bytes
from generator.motions import MOTIONS

log = logging.getLogger(__name__)

#: The six motions of :data:`generator.motions.MOTIONS` in words a person understands,
#: as the editor's motion selectors show them (same order).
MOTION_LABELS: dict[str, str] = {
    "drawer": "drawer (slides out)",
    "door_left": "door hinged left (swings out)",
    "door_right": "door hinged right (swings out)",
    "flap_bottom": "flap hinged at the bottom (folds down, as an oven door)",
    "flap_top": "flap hinged at the top (swings up)",
    "lid": "lid on top (lifts, hinged at the back)",
}
#: Mask colours by part id: 0 background (dark), 1 base (grey), 2.. movable parts (the
#: gallery's mask thumbnails and the editor's overlay).
MASK_PALETTE = np.array(
    [
        (30, 30, 30), (170, 170, 170), (228, 26, 28), (55, 126, 184), (77, 175, 74),
        (152, 78, 163), (255, 127, 0), (255, 255, 51), (166, 86, 40), (247, 129, 191),
        (102, 194, 165), (252, 141, 98), (141, 160, 203), (231, 138, 195), (166, 216, 84),
        (255, 217, 47), (229, 196, 148),
    ],
    dtype=np.uint8,
)  # fmt: skip
#: Largest request body the server reads (a PNG of part ids compresses well).
MAX_REQUEST_BYTES = 64 << 20
#: Keys a save request may have (docs/gallery.md, "What the page sends").
REQUEST_KEYS = ("id", "mask", "category", "parts", "confirmed", "mask_confirmed", "from")


class EditRefused(Exception):
    """A request the editor refuses; ``status`` is the HTTP status to answer with and the
    message says what is wrong and what to do."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


# --------------------------------------------------------------------------- the asset


@dataclass(frozen=True)
class EditTarget:
    """A catalogued asset converted from a photo, and the files an edit writes."""

    id: str
    photo: Path  # the input photo: the catalog's source_image
    mask_path: Path  # <name>.mask.png beside it (the existing one, whatever its case)
    hints_path: Path  # <name>.json beside it
    asset_dir: Path | None
    record: AssetRecord

    @property
    def generator(self) -> str:
        return self.record.generator or ConvertSettings().generator


def find_target(out: Path, asset_id: Any) -> EditTarget:
    """The asset ``asset_id`` of OUT's catalog, with the paths an edit reads and writes.

    Raises EditRefused (404) for an id the catalog does not hold, and (409) for an asset
    without a photo (imported) or whose photo is gone.
    """
    if not isinstance(asset_id, str) or not asset_id:
        raise EditRefused("give the asset's id (a string)")
    if not catalog_path(out).is_file():
        raise EditRefused(f"{out}: no catalog (registry.sqlite); nothing can be edited", 404)
    try:
        with Catalog(out, readonly=True) as cat:
            row = cat.get(asset_id)
            asset_dir = None if row is None else cat.asset_dir(row)
    except CatalogError as e:
        raise EditRefused(str(e), 500) from e
    if row is None:
        raise EditRefused(f"no asset {asset_id!r} in the catalog {catalog_path(out)}", 404)
    src = row.source_image
    if not src:
        raise EditRefused(
            f"{asset_id}: the catalog records no photo for this asset (an imported asset?); "
            "only assets converted from a photo can be edited",
            409,
        )
    photo = Path(src)
    if not photo.is_absolute():
        raise EditRefused(
            f"{asset_id}: the catalog stores its photo as the relative path {src!r} (an older "
            "run); convert it once more with pact convert so that the catalog knows where it is",
            409,
        )
    if not photo.is_file() or photo.suffix.lower() not in IMAGE_SUFFIXES:
        raise EditRefused(
            f"{asset_id}: its photo {photo} is no longer there; the editor writes the mask and "
            "hints beside the photo",
            409,
        )
    try:
        (item,) = discover_inputs(photo).items
    except (InputError, ValueError) as e:
        raise EditRefused(f"{asset_id}: {e}", 409) from e
    stem = photo.name[: -len(photo.suffix)]
    mask_path = item.mask_path or photo.with_name(stem + MASK_SUFFIX)
    hints_path = item.hints_path or photo.with_name(stem + HINTS_SUFFIX)
    return EditTarget(asset_id, photo, mask_path, hints_path, asset_dir, row)


def read_photo(target: EditTarget) -> tuple[np.ndarray, np.ndarray | None]:
    """The photo as ``pact convert`` reads it: ((H, W, 3) RGB, (H, W) alpha or None)."""
    try:
        return read_image(target.photo)
    except InputError as e:
        raise EditRefused(str(e), 409) from e


def photo_size(target: EditTarget) -> tuple[int, int]:
    """The photo's (width, height) after its EXIF orientation, as a mask must be."""
    image, _ = read_photo(target)
    return image.shape[1], image.shape[0]


@dataclass
class OpenedMask:
    """The part mask the editor opens: ids (H, W) or None, the file, the ids cleaning
    renumbered (old -> new, for the hints' parts) and why a mask file was not used."""

    ids: np.ndarray | None
    path: Path | None = None
    renumbered: dict[int, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def opened_mask(target: EditTarget, size: tuple[int, int]) -> OpenedMask:
    """The current part mask: the asset folder's ``input.mask.png`` (what the asset was
    built from), else the photo's own mask; read as ``pact convert`` reads it."""
    candidates = []
    if target.asset_dir is not None:
        candidates.append(target.asset_dir / f"input{MASK_SUFFIX}")
    candidates.append(target.mask_path)
    notes = []
    for path in candidates:
        if not path.is_file():
            continue
        renumbered: dict[int, int] = {}
        try:
            ids = read_mask(path, size, renumbered=renumbered)
        except InputError as e:
            notes.append(str(e))
            continue
        return OpenedMask(ids, path, renumbered, notes)
    return OpenedMask(None, None, {}, notes)


def read_raw_hints(target: EditTarget) -> dict[str, Any]:
    """The hints file beside the photo as it is (unchecked), {} without one."""
    if not target.hints_path.is_file():
        return {}
    try:
        data = json.loads(target.hints_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise EditRefused(
            f"{target.hints_path}: cannot read the hints beside the photo ({e}); fix or delete "
            "that file, then edit again",
            409,
        ) from e
    if not isinstance(data, dict):
        raise EditRefused(f"{target.hints_path}: hints must be a JSON object; fix it", 409)
    return data


def decode_mask(data: bytes, size: tuple[int, int], source: str) -> np.ndarray:
    """The (H, W) uint8 ids of a PNG the page sent: grey, or RGB(A) with equal colour
    channels (a canvas's PNG); refused unless it is a PNG of the photo's ``size``."""
    try:
        img = Image.open(io.BytesIO(data))
    except (OSError, ValueError, Image.DecompressionBombError) as e:
        raise EditRefused(f"{source}: the mask is not a readable image: {e}") from e
    if img.format != "PNG":
        raise EditRefused(f"{source}: the mask must be a PNG, got {img.format}")
    if img.size != tuple(size):
        raise EditRefused(
            f"{source}: the mask is {img.size[0]}x{img.size[1]} but the photo is "
            f"{size[0]}x{size[1]}; they must be the same size"
        )
    try:
        img.load()
    except (OSError, ValueError) as e:
        raise EditRefused(f"{source}: the mask PNG is damaged: {e}") from e
    a = np.asarray(img)
    if img.mode in ("L", "P"):
        return np.ascontiguousarray(a, dtype=np.uint8)
    if img.mode in ("RGB", "RGBA"):
        if not (np.array_equal(a[..., 0], a[..., 1]) and np.array_equal(a[..., 0], a[..., 2])):
            raise EditRefused(
                f"{source}: the mask's colour channels differ; send the part ids as grey values"
            )
        if img.mode == "RGBA" and not (a[..., 3] == 255).all():
            raise EditRefused(f"{source}: the mask has transparent pixels; send it opaque")
        return np.ascontiguousarray(a[..., 0], dtype=np.uint8)
    raise EditRefused(f"{source}: mask mode {img.mode} is not supported; send 8-bit grey ids")


# --------------------------------------------------------------------------- the hints


def _part_key(k: Any, what: str) -> str:
    if not (isinstance(k, str) and k.isdigit() and 2 <= int(k) <= MAX_PART_ID):
        raise EditRefused(f'{what}: {k!r} is not a movable part\'s mask id ("2" .. "16")')
    return str(int(k))


def _origins(movable_ids: set[int], origin_in: Any) -> dict[str, str | None]:
    """Saved part id -> its id in the opened mask (None: drawn anew), from the request's
    ``from``; without one, every id is taken to be unchanged."""
    if origin_in is not None and not isinstance(origin_in, dict):
        raise EditRefused('from: must be an object like {"2": 2, "3": null}')
    origin: dict[str, str | None] = {}
    for k in sorted(movable_ids):
        key = str(k)
        if origin_in is None:
            origin[key] = key
            continue
        v = origin_in.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int)):
            raise EditRefused(f"from.{key}: must be a mask id or null, got {v!r}")
        origin[key] = None if v is None else str(v)
    return origin


def edited_hints(
    existing: Mapping[str, Any],
    movable_ids: set[int],
    mask_changed: bool,
    request: Mapping[str, Any],
) -> dict[str, Any]:
    """The hints to write after an edit (unchecked; :func:`check_hints` comes next).

    ``existing``: the hints file as it is (its ids already those of the opened mask);
    ``movable_ids``: the saved mask's ids >= 2; ``mask_changed``: whether the saved mask
    differs from the opened one. From ``request``: ``category`` (present when the person
    set or confirmed it), ``parts`` (``{"3": {"motion": "drawer"}}``: the motion of each
    movable part of the saved mask; a part left out, or with an empty motion, is left to
    the generator; without ``parts`` each part keeps the motion the file gives its
    opened id), ``confirmed`` (the part ids whose motion the person set or
    confirmed), ``mask_confirmed``, ``from`` (saved part id -> its id in the opened mask,
    null for a part drawn anew; without it, ids are taken to be unchanged).

    Every other key keeps its value. ``parsed`` loses ``category`` when the category
    was set or confirmed, ``mask`` when the mask changed or was confirmed, and a part's
    confidence unless the part kept its opened id's motion without being set or
    confirmed (its confidence then moves to the saved id); what is left empty goes.
    """
    hints = dict(existing)
    old_parts = existing.get("parts") if isinstance(existing.get("parts"), dict) else {}
    old_parsed = existing.get("parsed") if isinstance(existing.get("parsed"), dict) else None
    parsed = dict(old_parsed) if old_parsed is not None else None

    if "category" in request:
        hints["category"] = request["category"]
        if parsed is not None:
            parsed.pop("category", None)
    if parsed is not None and (mask_changed or request.get("mask_confirmed") is True):
        parsed.pop("mask", None)

    parts_in = request.get("parts")
    if parts_in is None:  # not sent: each part keeps the motion of the file, through `from`
        parts_in = {}
        for key, was in _origins(movable_ids, request.get("from")).items():
            entry = old_parts.get(was) if was is not None else None
            if isinstance(entry, dict):
                parts_in[key] = entry
    if not isinstance(parts_in, dict):
        raise EditRefused('parts: must be an object like {"2": {"motion": "drawer"}}')
    confirmed = request.get("confirmed") or []
    if not isinstance(confirmed, list):
        raise EditRefused('confirmed: must be a list of part ids, e.g. ["2"]')
    confirmed_ids = {_part_key(str(k), "confirmed") for k in confirmed}
    origin = _origins(movable_ids, request.get("from"))

    parts: dict[str, Any] = {}
    for key, entry in parts_in.items():
        key = _part_key(key, "parts")
        if int(key) not in movable_ids:
            raise EditRefused(
                f"parts: the saved mask has no part {key} (its movable parts: "
                f"{sorted(movable_ids)})"
            )
        if not isinstance(entry, dict):
            raise EditRefused(f'parts.{key}: must be an object like {{"motion": "drawer"}}')
        if entry.get("motion") in (None, ""):
            continue
        parts[key] = dict(entry)
    parts = {k: parts[k] for k in sorted(parts, key=int)}
    if parts:
        hints["parts"] = parts
    else:
        hints.pop("parts", None)

    if parsed is not None and isinstance(parsed.get("parts"), dict):
        kept = {}
        for key in sorted(movable_ids):
            key = str(key)
            was = origin.get(key)
            if key in confirmed_ids or was is None or was not in parsed["parts"]:
                continue
            old_entry = old_parts.get(was)
            old_motion = old_entry.get("motion") if isinstance(old_entry, dict) else None
            if (parts.get(key) or {}).get("motion") == old_motion:
                kept[key] = parsed["parts"][was]
        if kept:
            parsed["parts"] = kept
        else:
            parsed.pop("parts", None)
    if parsed is not None:
        if parsed:
            hints["parsed"] = parsed
        else:
            hints.pop("parsed", None)
    return hints


# --------------------------------------------------------------------------- saving


@dataclass(frozen=True)
class PreparedSave:
    """A checked edit: the two files' bytes, ready to write beside the photo."""

    target: EditTarget
    mask: bytes
    hints: dict[str, Any]
    hints_bytes: bytes
    warnings: list[str]
    parts: int  # parts of the mask, base included

    def write(self) -> None:
        """Write ``<name>.mask.png`` then ``<name>.json`` beside the photo, each atomically."""
        atomic_write_bytes(self.target.mask_path, self.mask)
        atomic_write_bytes(self.target.hints_path, self.hints_bytes)


def prepare_save(out: Path, request: Any) -> PreparedSave:
    """Check a save request (docs/gallery.md) against the catalog, the photo and the
    rules ``pact convert`` applies; return the files to write. Writes nothing; raises
    EditRefused with a message naming what is wrong."""
    if not isinstance(request, dict):
        raise EditRefused("the request must be a JSON object")
    unknown = sorted(set(request) - set(REQUEST_KEYS))
    if unknown:
        raise EditRefused(f"unknown keys {unknown}; known: {list(REQUEST_KEYS)}")
    target = find_target(out, request.get("id"))
    image, alpha = read_photo(target)
    size = (image.shape[1], image.shape[0])
    mask_field = request.get("mask")
    if not isinstance(mask_field, str) or not mask_field:
        raise EditRefused("mask: give the part mask as a base64 PNG")
    if mask_field.startswith("data:"):
        mask_field = mask_field.partition(",")[2]
    try:
        data = base64.b64decode(mask_field, validate=True)
    except (binascii.Error, ValueError) as e:
        raise EditRefused(f"mask: not valid base64: {e}") from e
    source = str(target.mask_path)
    ids = decode_mask(data, size, source)
    try:
        check_mask(ids, source)
    except InputError as e:
        raise EditRefused(str(e)) from e
    present = {int(v) for v in np.unique(ids)}
    try:
        cleaned, _, renumbered = clean_mask(ids, source)
    except InputError as e:
        raise EditRefused(str(e)) from e
    lost = sorted(present - {int(v) for v in np.unique(cleaned)} - {0})
    if lost or renumbered:
        gone = lost or sorted(renumbered)
        raise EditRefused(
            f"{source}: part {', '.join(map(str, gone))} would be lost: it is only specks or "
            "lines a pixel or two thin, which pact convert cleans away; draw it larger or "
            "erase it"
        )
    warnings: list[str] = []
    try:
        check_mask_matches_photo(ids, image, alpha, source)
        warnings += check_mask_edges(ids, image, source)
    except InputError as e:
        raise EditRefused(str(e)) from e

    opened = opened_mask(target, size)
    existing = read_raw_hints(target)
    if opened.renumbered:  # the file names parts by the ids the mask was saved with
        existing = renumber_parts(existing, opened.renumbered)
    mask_changed = opened.ids is None or not np.array_equal(opened.ids, ids)
    movable = {i for i in present if i >= 2}
    hints = edited_hints(existing, movable, mask_changed, request)
    try:
        check_hints(hints, str(target.hints_path))
        check_part_ids(hints, present, str(target.hints_path))
    except InputError as e:
        raise EditRefused(str(e)) from e
    stem = target.photo.name[: -len(target.photo.suffix)]
    new_id = hints.get("id") or asset_id_for(stem)[0]
    if new_id != target.id:
        raise EditRefused(
            f"{target.hints_path}: the photo would now convert into asset {new_id!r}, not "
            f"{target.id!r}; the editor keeps the id (fix the 'id' hint by hand)",
            409,
        )
    hints_bytes = (json.dumps(hints, indent=2, ensure_ascii=False) + "\n").encode("utf-8")
    return PreparedSave(target, mask_png(ids), hints, hints_bytes, warnings, len(present - {0}))


# --------------------------------------------------------------------------- re-converting


@dataclass
class Job:
    """One re-conversion: ``state`` queued -> running -> done | failed."""

    number: int
    asset_id: str
    photo: Path
    generator: str
    state: str = "queued"
    stage: str | None = None
    message: str | None = None
    #: The converted asset: status, reason, part_count, category (catalog row).
    result: dict[str, Any] | None = None
    #: Parts (base included) of the saved mask: what the asset should have.
    mask_parts: int | None = None
    #: Doubts about the saved mask that did not refuse it (weak edges on its boundaries).
    warnings: list[str] = field(default_factory=list)
    started: float | None = None
    finished: float | None = None

    def public(self) -> dict[str, Any]:
        """What the status endpoint answers (no paths)."""
        return {
            "job": self.number,
            "id": self.asset_id,
            "state": self.state,
            "stage": self.stage,
            "message": self.message,
            "result": self.result,
            "warnings": self.warnings,
            "seconds": None
            if self.started is None
            else round((self.finished or time.monotonic()) - self.started, 1),
        }


def reconvert_settings(
    generator: str, overrides: Mapping[str, Any] | None = None
) -> ConvertSettings:
    """The settings of a re-conversion: the generator the catalog recorded for the asset
    and the defaults of ``pact convert`` otherwise (``overrides`` replace some: tests)."""
    return replace(ConvertSettings(generator=generator), **dict(overrides or {}))


class Reconverter:
    """Re-converts saved items into OUT, one at a time, in one background thread.

    ``after`` runs once a job's conversion is over (the server rewrites the gallery
    page there); ``overrides`` replace default convert settings (:func:`reconvert_settings`).
    """

    def __init__(
        self,
        out: Path,
        overrides: Mapping[str, Any] | None = None,
        after: Callable[[], None] | None = None,
    ) -> None:
        self.out = Path(out)
        self.overrides = dict(overrides or {})
        self.after = after
        self.lock = threading.Lock()
        self.jobs: dict[int, Job] = {}
        self._queue: queue.Queue[Job] = queue.Queue()
        self._thread: threading.Thread | None = None

    def pending(self, asset_id: str) -> Job | None:
        """The queued or running job of ``asset_id``, if any."""
        with self.lock:
            for job in self.jobs.values():
                if job.asset_id == asset_id and job.state in ("queued", "running"):
                    return job
        return None

    def submit(
        self, target: EditTarget, warnings: list[str] | None = None, mask_parts: int | None = None
    ) -> Job:
        with self.lock:
            job = Job(len(self.jobs) + 1, target.id, target.photo, target.generator)
            job.warnings, job.mask_parts = list(warnings or []), mask_parts
            self.jobs[job.number] = job
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(
                    target=self._run, name="gallery-reconvert", daemon=True
                )
                self._thread.start()
        self._queue.put(job)
        return job

    def get(self, number: int) -> Job | None:
        with self.lock:
            return self.jobs.get(number)

    def _run(self) -> None:
        while True:
            job = self._queue.get()
            try:
                self._convert(job)
            except Exception as e:  # a worker thread must not die with a job half-told
                log.exception("%s: re-conversion failed", job.asset_id)
                job.state, job.message = "failed", f"{type(e).__name__}: {e}"
            finally:
                job.finished = time.monotonic()
                self._queue.task_done()

    def _convert(self, job: Job) -> None:
        job.state, job.started = "running", time.monotonic()
        settings = reconvert_settings(job.generator, self.overrides)
        log.info("%s: re-converting %s (%s)", job.asset_id, job.photo, settings.generator)

        def on_stage(_name: str, stage: str) -> None:
            job.stage = stage

        try:
            summary = run_convert(job.photo, self.out, settings, force=True, on_stage=on_stage)
        except Exception as e:  # InputError, OutputLockedError, CatalogError, ...
            job.state = "failed"
            job.message = (
                f"{e} (the mask and hints are saved beside the photo; convert it again with "
                "pact convert --force, or save again)"
            )
            return
        results = [r for r in summary.results if r.id == job.asset_id] or summary.results
        r = results[0] if results else None
        row = None
        try:
            with Catalog(self.out, readonly=True) as cat:
                row = cat.get(job.asset_id)
        except CatalogError as e:
            log.warning("%s", e)
        job.result = {
            "status": None if r is None else r.status,
            "reason": None if r is None else r.reason,
            "part_count": None if row is None else row.part_count,
            "mask_parts": job.mask_parts,
            "category": None if row is None else row.category,
        }
        if self.after is not None:
            job.stage = "gallery"
            try:
                self.after()
            except Exception as e:
                job.state, job.message = "failed", f"converted, but the page was not rewritten: {e}"
                return
        failed = r is None or r.status == "failed"
        job.state = "failed" if failed else "done"
        job.stage = None
        if failed:
            job.message = (r.reason if r is not None else None) or "nothing was converted"


# --------------------------------------------------------------------------- the editor


class MaskEditor:
    """The editor of OUT's assets as the server offers it (see the module docstring).

    ``enabled`` False (a server not bound to 127.0.0.1) refuses every request with
    ``reason``.
    """

    def __init__(
        self,
        out: str | Path,
        *,
        enabled: bool = True,
        reason: str = "",
        overrides: Mapping[str, Any] | None = None,
        after: Callable[[], None] | None = None,
    ) -> None:
        self.out = Path(out)
        self.enabled = enabled
        self.reason = reason
        self.jobs = Reconverter(self.out, overrides, after)
        self._save_lock = threading.Lock()

    def _check_enabled(self) -> None:
        if not self.enabled:
            raise EditRefused(self.reason or "the mask editor is off", 403)

    def info(self) -> dict[str, Any]:
        """What the page needs before opening the editor."""
        return {
            "enabled": self.enabled,
            "reason": None if self.enabled else self.reason,
            "motions": [[m, MOTION_LABELS[m]] for m in MOTIONS],
            "categories": [[c, c.replace("_", " ")] for c in CATEGORIES],
            "max_part_id": MAX_PART_ID,
            "palette": MASK_PALETTE.tolist(),
        }

    def state(self, asset_id: Any) -> dict[str, Any]:
        """The asset as the editor opens it: photo size, the current mask's ids, the
        hints beside the photo (ids as in the opened mask), category, parser's record."""
        self._check_enabled()
        target = find_target(self.out, asset_id)
        size = photo_size(target)
        opened = opened_mask(target, size)
        hints = read_raw_hints(target)
        if opened.renumbered:
            hints = renumber_parts(hints, opened.renumbered)
        try:
            check_hints(hints, str(target.hints_path))
            hints_error = None
        except InputError as e:
            hints_error = str(e)
        ids = [] if opened.ids is None else sorted(int(v) for v in np.unique(opened.ids) if v)
        pending = self.jobs.pending(target.id)
        return {
            "id": target.id,
            "photo_name": target.photo.name,
            "width": size[0],
            "height": size[1],
            "has_mask": opened.ids is not None,
            "mask_from": None
            if opened.path is None
            else ("asset" if opened.path.parent == target.asset_dir else "photo"),
            "mask_notes": opened.notes,
            "ids": ids,
            "hints": hints,
            "hints_error": hints_error,
            "category": hints.get("category", target.record.category or "unknown"),
            "generator": target.generator,
            "part_count": target.record.part_count,
            "status": target.record.status,
            "pending_job": None if pending is None else pending.number,
            **self.info(),
        }

    def photo_png(self, asset_id: Any) -> bytes:
        """The photo as the editor draws it: PNG, EXIF orientation applied."""
        self._check_enabled()
        image, alpha = read_photo(find_target(self.out, asset_id))
        rgba = image if alpha is None else np.dstack([image, alpha])
        buf = io.BytesIO()
        Image.fromarray(rgba).save(buf, format="PNG", compress_level=1)
        return buf.getvalue()

    def mask_png(self, asset_id: Any) -> bytes:
        """The opened mask's ids as an 8-bit grey PNG; EditRefused (404) without one."""
        self._check_enabled()
        target = find_target(self.out, asset_id)
        opened = opened_mask(target, photo_size(target))
        if opened.ids is None:
            raise EditRefused(
                f"{target.id}: no usable part mask"
                + (f" ({'; '.join(opened.notes)})" if opened.notes else ""),
                404,
            )
        return mask_png(opened.ids)

    def save(self, request: Any) -> Job:
        """Check, write the two files beside the photo, queue the re-conversion."""
        self._check_enabled()
        with self._save_lock:
            asset_id = request.get("id") if isinstance(request, dict) else None
            if isinstance(asset_id, str):
                busy = self.jobs.pending(asset_id)
                if busy is not None:
                    raise EditRefused(
                        f"{asset_id}: its re-conversion (job {busy.number}) is still under way; "
                        "wait until it is done, then save again",
                        409,
                    )
            prepared = prepare_save(self.out, request)
            try:
                prepared.write()
            except OSError as e:
                raise EditRefused(
                    f"{prepared.target.photo.parent}: cannot write the mask and hints beside the "
                    f"photo: {e.strerror or e}",
                    500,
                ) from e
            for w in prepared.warnings:
                log.warning("%s", w)
            log.info(
                "%s: wrote %s and %s", prepared.target.id, prepared.target.mask_path,
                prepared.target.hints_path,
            )  # fmt: skip
            return self.jobs.submit(prepared.target, prepared.warnings, prepared.parts)

    def status(self, number: Any) -> dict[str, Any]:
        try:
            n = int(number)
        except (TypeError, ValueError) as e:
            raise EditRefused("job: give the job number the save answered") from e
        job = self.jobs.get(n)
        if job is None:
            raise EditRefused(f"no job {n}", 404)
        return job.public()
