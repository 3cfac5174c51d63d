"""Batch conversion of an image folder: generate, build, validate, register (``pact convert``).

Each input item (docs/input-format.md) goes through the stages ``load`` ->
``generate`` -> ``texture`` (the photo's camera, the photo baked into the part meshes:
:mod:`asset_pipeline.photo.camera`, :mod:`asset_pipeline.photo.texture`) -> ``build``
(mesh, collision, rig) -> ``validate`` (checks, repairs, preview) -> ``fidelity`` (the
asset rendered from the photo's camera and compared with the photo, into
``report.json``: :mod:`asset_pipeline.photo.fidelity`) in a worker; the driver alone writes
the catalog (``OUT/registry.sqlite``). The ``texture`` and ``fidelity`` stages never fail
an item: a problem there is a warning and the asset goes on without a texture or score
(docs/fidelity.md).

Guarantees
----------
- One run per output folder: the driver holds an exclusive ``flock`` on ``OUT`` itself
  and on ``OUT/.lock`` (which names its pid) for the whole run (:func:`output_lock`);
  a second run on the same folder stops at once with :class:`OutputLockedError` naming
  the process that holds it, also when ``OUT/.lock`` was deleted meanwhile. An output folder that
  cannot be written (a read-only file system, no write permission) stops the run
  before anything is converted with :class:`OutputFolderError` naming it.
- Unique ids: an item's id is its hints' ``id`` or its photo's name (slugified when
  needed, :func:`asset_pipeline.inputs.asset_id_for`). Two items of a batch with the
  same id both fail, and so does an item whose id the catalog gives to another photo;
  the catalog's own files and hidden names are never ids.
- Atomic items: a worker assembles the asset in ``OUT/.staging/<pid>.<time>/<id>/`` and
  renames it to ``OUT/<id>`` only when it is complete. A run killed at any moment
  leaves finished items intact and no half-made ``OUT/<id>``; the next run removes
  what it left in ``OUT/.staging`` (never the folder of a process still alive:
  :func:`clean_staging`).
- Nothing done is lost: when an item that had a good asset fails (its photo became
  unreadable, validation now fails), the old asset is moved to ``OUT/.previous/<id>/``
  and the failure's reason says where it is (a later failure says where it is still
  kept). ``OUT/.previous/<id>/`` only ever holds the last good asset: an asset that
  failed validation is installed as ``OUT/<id>`` (catalogued failed, to be looked at)
  and deleted, never set aside, when the item runs again (:func:`set_aside`). The
  catalog never calls a folder ok that is not.
- The catalog agrees with the disk: at the start of a run every catalogued asset is
  checked (:func:`asset_pipeline.catalog.registry.folder_problem`); a damaged one (a deleted
  ``model.urdf``, ``collision/`` gone, a report that disagrees) is marked failed with
  the reason, and rebuilt when its photo is in the batch.
- Resumable and idempotent: an item whose id, input hash and settings hash match a
  catalogued, complete, not-failed asset is skipped (``force`` redoes it).
- One failed item never stops the batch; its reason is catalogued. A worker process
  that dies (a native crash, ``kill -9``) fails only the item it held, named.
- Executors: local worker processes (default; :mod:`asset_pipeline.catalog.workers`) or a
  Ray cluster (``executor="ray"``, each item one Ray task, the catalog written by the
  driver).
"""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import fcntl
import hashlib
import json
import logging
import os
import shutil
import tempfile
import time
import traceback
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from asset_pipeline.catalog.registry import (
    CATALOG_NAME,
    Catalog,
    CatalogError,
    folder_problem,
    register_asset_dir,
)
from asset_pipeline.catalog.workers import WorkerDied, WorkerPool
from asset_pipeline.inputs.errors import InputError
from asset_pipeline.inputs.folder import InputItem, SkippedFile, discover_inputs, load_input
from asset_pipeline.inputs.mask import write_mask
from asset_pipeline.inputs.parsing import SEGMENTERS, complete_input, given_sources
from asset_pipeline.validate import ReportFormatError, read_report
from generator.bundle import remove_bundle
from generator.mesh_repair.decimation import DEFAULT_VISUAL_FACES

log = logging.getLogger(__name__)

STAGES = ("load", "parse", "generate", "texture", "build", "validate", "fidelity")
GENERATORS = ("pact", "retrieval")
STAGING = ".staging"
PREVIOUS = ".previous"
LOCK_NAME = ".lock"


class OutputLockedError(RuntimeError):
    """Another run holds the output folder's lock; the message names the folder and pid."""


class OutputFolderError(ValueError):
    """``--out`` cannot be used as an output folder; the message says why."""


@dataclass(frozen=True)
class ConvertSettings:
    """What an item's result depends on besides its input files (hashed for resume)."""

    generator: str = "pact"
    validate: bool = True
    repair: bool = True
    preview: bool = True
    seed: int = 0
    #: How parts collide (asset_pipeline.assets.build.COLLISION_METHODS): "auto" keeps a
    #: generated object's box layout, "voxel" decomposes its meshes instead.
    collision: str = "auto"
    #: Bake the photo into the part meshes' textures (the camera is estimated whenever
    #: ``texture`` or ``fidelity`` is on and writes camera.json).
    texture: bool = True
    #: Render the asset from the photo's camera and score it (needs ``validate``: the
    #: score goes into report.json).
    fidelity: bool = True
    #: Visual triangles per asset (``--visual-faces``; 0 keeps every triangle).
    visual_faces: int = DEFAULT_VISUAL_FACES
    #: Read what a photo lacks (part mask, category, each part's motion) with the photo
    #: parser (asset_pipeline.inputs.parsing); what the user gives always wins.
    parse: bool = True
    #: How a missing mask is made: "parser" or "sam2" (SAM2's automatic masks merged by the
    #: parser; needs ``sam2_checkpoint``).
    segmenter: str = "parser"
    sam2_checkpoint: str | None = None
    #: The photo parser's weights folder (``--parser-weights``); None: the shipped ones.
    parser_weights: str | None = None
    #: Keep the generator's bundle (``object.json`` + ``parts/``) in the asset folder, so
    #: that ``pact build`` can rebuild it (``--keep-intermediate``); off, the folder holds
    #: the asset alone.
    keep_intermediate: bool = False
    #: The model files written (``--formats``; asset_pipeline.assets.folder.FORMATS).
    formats: tuple[str, ...] = ("urdf", "mjcf", "usd")

    def digest(self, generator_version: str = "") -> str:
        fields = asdict(self)
        if fields["collision"] == "auto":  # the default: digests of older runs still match
            del fields["collision"]
        if tuple(fields["formats"]) == ("urdf", "mjcf", "usd"):  # the default, as above
            del fields["formats"]
        if fields["parser_weights"] is None:  # the default, as above
            del fields["parser_weights"]
        text = json.dumps({**fields, "generator_version": generator_version}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass
class ItemResult:
    """The outcome of one item, sent from a worker back to the driver."""

    id: str
    name: str
    status: str  # ok | repaired | failed
    reason: str | None = None
    stage: str | None = None  # the stage that failed
    stage_seconds: dict[str, float] = field(default_factory=dict)
    path: str | None = None
    source_image: str | None = None
    source_hash: str | None = None
    category: str = "unknown"
    generator: str = ""
    generator_version: str = ""
    #: How the id was made when it is not the photo's name or hint (slugified).
    id_note: str | None = None
    #: Doubts about the item that did not fail it (each naming the file).
    warnings: list[str] = field(default_factory=list)
    #: Where its category, part mask and motions came from (parsing.InputSources.to_json).
    inputs: dict[str, Any] = field(default_factory=dict)


# --------------------------------------------------------------------------- generators

_GENERATOR_CACHE: dict[str, Any] = {}


def load_generator(name: str) -> Any:
    """The generator called ``name`` (cached per process: models load once per worker)."""
    if name not in GENERATORS:
        raise ValueError(f"unknown generator {name!r}; choose one of {GENERATORS}")
    if name not in _GENERATOR_CACHE:
        if name == "retrieval":
            from generator.retrieval import RetrievalGenerator

            _GENERATOR_CACHE[name] = RetrievalGenerator.default()
        else:
            from generator.pact.inference.generate import PActGenerator

            _GENERATOR_CACHE[name] = PActGenerator.default()
    return _GENERATOR_CACHE[name]


def generator_version(name: str) -> str:
    return str(getattr(load_generator(name), "version", "0"))


# --------------------------------------------------------------------------- one item


def _result_for(item: InputItem, settings: ConvertSettings) -> ItemResult:
    asset_id, note = item.resolve_asset_id()
    return ItemResult(
        id=asset_id,
        name=item.name,
        status="failed",
        source_image=str(item.image_path.resolve()),  # the same from any working directory
        source_hash=item.input_hash,
        generator=settings.generator,
        id_note=note,
    )


def convert_item(
    item: InputItem,
    out: str | Path,
    settings: ConvertSettings,
    report_stage: Callable[[str], None] | None = None,
) -> ItemResult:
    """Run every stage for one input item into ``OUT/.staging``; never raises.

    Returns the result with ``path`` set to the complete staged asset folder (the
    driver moves it into place) or a failure with its stage and reason.
    """
    from asset_pipeline.assets.build import BuildOptions, build_asset
    from generator.bundle import save_bundle

    out = Path(out)
    result = _result_for(item, settings)
    # The build names the asset after its folder, so stage in a private parent folder.
    private = out / STAGING / f"{os.getpid()}.{time.time_ns()}"
    stage = "load"

    def enter(name: str) -> float:
        nonlocal stage
        stage = name
        if report_stage:
            report_stage(name)
        return time.perf_counter()

    try:
        t = enter("load")
        loaded = load_input(item)
        result.warnings = list(loaded.warnings)
        staging = private / result.id
        result.category = loaded.category
        result.stage_seconds["load"] = time.perf_counter() - t

        if settings.parse:
            t = enter("parse")
            loaded, sources = parse_stage(loaded, settings)
            result.warnings = list(loaded.warnings)
            result.stage_seconds["parse"] = time.perf_counter() - t
        else:
            sources = given_sources(loaded)
        result.inputs = sources.to_json()
        result.category = loaded.category

        t = enter("generate")
        gen = load_generator(settings.generator)
        result.generator_version = str(getattr(gen, "version", "0"))
        hints = dict(loaded.hints)
        hints.setdefault("seed", settings.seed)
        hints["visual_faces"] = settings.visual_faces
        if loaded.alpha is not None:
            hints["alpha"] = loaded.alpha
        obj = gen.generate(loaded.image, loaded.mask, hints)
        obj.provenance.setdefault("source_image", str(item.image_path))
        obj.provenance["source_hash"] = item.input_hash
        obj.provenance["inputs"] = result.inputs
        if obj.category in ("unknown", "") and loaded.category != "unknown":
            obj.category = loaded.category
        result.category = obj.category
        result.stage_seconds["generate"] = time.perf_counter() - t

        if settings.texture or (settings.fidelity and settings.validate):
            t = enter("texture")
            obj = photo_stage(obj, loaded, staging, settings, result.warnings)
            result.stage_seconds["texture"] = time.perf_counter() - t

        t = enter("build")
        save_bundle(obj, staging)
        shutil.copyfile(item.image_path, staging / f"input{item.image_path.suffix.lower()}")
        if item.mask_path is not None:
            shutil.copyfile(item.mask_path, staging / "input.mask.png")
        elif loaded.mask is not None:  # the parser's mask: what the asset was made from
            write_mask(loaded.mask, staging / "input.mask.png")
        build_asset(
            staging,
            height=loaded.height,
            options=BuildOptions(
                collision=settings.collision,
                visual_faces=settings.visual_faces,
                formats=settings.formats,
            ),
        )
        if not settings.keep_intermediate:
            remove_bundle(staging)
        result.stage_seconds["build"] = time.perf_counter() - t

        status = "ok"
        if settings.validate:
            t = enter("validate")
            from asset_pipeline.validate import validate_asset

            report = validate_asset(staging, repair=settings.repair, preview=settings.preview)
            status = report.status
            if not report.ok:
                result.reason = "validation failed: " + ", ".join(
                    c.key for c in report.failed_checks[:6]
                )
                result.stage = "validate"
            result.stage_seconds["validate"] = time.perf_counter() - t
            if settings.fidelity:
                t = enter("fidelity")
                fidelity_stage(staging, result.warnings)
                result.stage_seconds["fidelity"] = time.perf_counter() - t
        result.path = str(staging)
        result.status = status
    except Exception as e:  # a failed item is a result, not a crash
        result.status = "failed"
        result.stage = stage
        result.path = None
        result.reason = (
            f"{stage}: {e}" if isinstance(e, InputError) else f"{stage}: {type(e).__name__}: {e}"
        )
        log.debug("item %s failed in %s:\n%s", item.name, stage, traceback.format_exc())
        shutil.rmtree(private, ignore_errors=True)
    return result


_PARSER_CACHE: dict[str, Any] = {}


def load_parser(weights: str | None = None) -> Any:
    """The photo parser with the shipped weights, or ``weights``: a name of shipped
    weights ("partnet") or a weights folder (cached per process)."""
    key = f"parser:{weights}" if weights else "parser"
    if key not in _PARSER_CACHE:
        from generator.parser import PhotoParser, weights_dir

        _PARSER_CACHE[key] = (
            PhotoParser.from_dir(weights_dir(weights)) if weights else PhotoParser.default()
        )
    return _PARSER_CACHE[key]


def load_segmenter(settings: ConvertSettings) -> Any:
    """None for the parser's own masks; the SAM2 segmenter (cached per checkpoint)."""
    if settings.segmenter == "parser":
        return None
    if settings.segmenter != "sam2":
        raise ValueError(f"unknown segmenter {settings.segmenter!r}; choose one of {SEGMENTERS}")
    if not settings.sam2_checkpoint:
        raise ValueError("--segmenter sam2 needs --sam2-checkpoint FILE (docs/segmenters.md)")
    key = f"sam2:{settings.sam2_checkpoint}"
    if key not in _PARSER_CACHE:
        from generator.parser.sam2_segmenter import Sam2Segmenter

        _PARSER_CACHE[key] = Sam2Segmenter.from_checkpoint(settings.sam2_checkpoint)
    return _PARSER_CACHE[key]


def parse_stage(loaded: Any, settings: ConvertSettings) -> tuple[Any, Any]:
    """The ``parse`` stage: what the photo lacks read by the photo parser
    (:func:`asset_pipeline.inputs.parsing.complete_input`). A parser that cannot run
    (its weights or SAM2 missing) leaves the item as the user gave it, with a warning."""
    try:
        parser, segmenter = load_parser(settings.parser_weights), load_segmenter(settings)
    except (ImportError, OSError, ValueError, RuntimeError) as e:
        log.debug("no photo parser:\n%s", traceback.format_exc())
        note = f"{loaded.item.image_path}: not parsed (no photo parser: {type(e).__name__}: {e})"
        loaded = dataclasses.replace(loaded, warnings=[*loaded.warnings, note])
        return loaded, given_sources(loaded)
    return complete_input(loaded, parser, segmenter)


def photo_stage(
    obj: Any,
    loaded: Any,
    staging: Path,
    settings: ConvertSettings,
    warnings: list[str],
) -> Any:
    """The ``texture`` stage: fit the photo's camera to ``obj`` (generator frame), write
    ``camera.json`` (in the built asset's metric frame) and, with ``settings.texture``,
    return ``obj`` with the photo baked into its part meshes (closed first, as the build
    would close them; the build writes each texture into its visual). Never raises: a
    problem is appended to ``warnings`` and ``obj`` comes back unchanged."""
    from asset_pipeline.assets.build import BuildOptions, voxel_parts
    from asset_pipeline.geometry.metric import frame_offset, metric_factor
    from asset_pipeline.photo.camera import fit_camera, photo_silhouette, write_camera
    from asset_pipeline.photo.texture import bake_photo_texture
    from generator.mesh_repair.closing import watertight_object

    where = f"{loaded.item.image_path}"
    silhouette = photo_silhouette(loaded.image, loaded.mask, loaded.alpha)
    if silhouette is None:
        warnings.append(
            f"{where}: no photo camera or texture: the photo has no silhouette (no mask, no "
            "alpha channel, no plain background)"
        )
        return obj
    try:
        options = BuildOptions(collision=settings.collision)
        closed = watertight_object(obj, options.remesh_resolution, keep=voxel_parts(obj, options))
        camera = fit_camera(closed, silhouette, loaded.mask)
        result, extra = obj, {}
        if settings.texture:
            part_ids = {name: int(k) for k, name in camera.fit.get("part_match", {}).items()}
            result, info = bake_photo_texture(
                closed, loaded.image, camera, silhouette, loaded.mask, part_ids
            )
            info.pop("images")  # the build writes them with the visuals
            extra["texture"] = info
        # the build makes the object metric with the same functions (mesh.to_metric)
        scale = metric_factor(closed, loaded.height, options.default_heights)
        metric = camera.transformed(scale, frame_offset(closed, scale))
        staging.mkdir(parents=True, exist_ok=True)
        write_camera(metric, staging, **extra)
        return result
    except Exception as e:  # noqa: BLE001 - the asset goes on without a texture
        log.debug("photo stage of %s failed:\n%s", where, traceback.format_exc())
        warnings.append(f"{where}: no photo texture: {type(e).__name__}: {e}")
        return obj


def fidelity_stage(staging: Path, warnings: list[str]) -> None:
    """The ``fidelity`` stage: render, score and write the score into ``report.json``
    (:func:`asset_pipeline.photo.fidelity.measure_fidelity`); a score it cannot measure is
    recorded as skipped with the reason. Never raises."""
    from asset_pipeline.photo.fidelity import (
        FidelityUnavailable,
        measure_fidelity,
        record_fidelity,
        skipped_record,
    )

    try:
        record = measure_fidelity(staging)
    except FidelityUnavailable as e:
        record = skipped_record(str(e))
        warnings.append(f"{staging.name}: fidelity not measured: {e}")
    except Exception as e:  # noqa: BLE001 - a score is not worth the asset
        log.debug("fidelity of %s failed:\n%s", staging.name, traceback.format_exc())
        record = skipped_record(f"{type(e).__name__}: {e}")
        warnings.append(f"{staging.name}: fidelity not measured: {type(e).__name__}: {e}")
    if record.get("low_fidelity"):
        warnings.append(
            f"{staging.name}: low fidelity (score {record['score']:.2f}): "
            + "; ".join(record["reasons"])
        )
    try:
        record_fidelity(staging, record)
    except Exception as e:  # noqa: BLE001
        warnings.append(f"{staging.name}: fidelity not recorded: {type(e).__name__}: {e}")


def _convert_in_worker(job: tuple[InputItem, str, ConvertSettings], report: Callable) -> ItemResult:
    """:func:`convert_item` for :class:`~asset_pipeline.catalog.workers.WorkerPool`."""
    item, out, settings = job
    return convert_item(item, out, settings, report)


# --------------------------------------------------------------------------- the output folder


def unwritable_output(out: Path, e: OSError) -> OutputFolderError:
    """The error for an output folder that cannot be written: it names the folder, says
    why (in the system's words when there is no plainer one) and what to do."""
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        why = "the disk is full (no space left, or the quota is used up); free some space or choose another --out"
    elif e.errno == errno.EROFS:
        why = "it is on a read-only file system; choose a writable --out"
    elif e.errno in (errno.EACCES, errno.EPERM):
        why = "no permission to write there; make it writable for you or choose another --out"
    else:
        why = f"{e.strerror or e}; check the folder and its disk, or choose another --out"
    return OutputFolderError(f"{out}: cannot write to the output folder: {why}")


def check_writable(out: Path) -> None:
    """Raise OutputFolderError (:func:`unwritable_output`) unless a file can be created
    in ``out`` (a read-only mount, a folder without write permission)."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".write-test.", dir=out)
    except OSError as e:
        raise unwritable_output(out, e) from e
    os.close(fd)
    os.unlink(probe)


#: Attempts at locking ``OUT/.lock`` when another process replaces the file meanwhile.
LOCK_ATTEMPTS = 5


def _locked_error(out: Path, holder: str | None) -> OutputLockedError:
    return OutputLockedError(
        f"{out}: another pact run (pid {holder or 'unknown'}) is writing to this folder; "
        "wait for it to finish or choose another --out"
    )


def _lock_holder(path: Path) -> str | None:
    """The pid written in the lock file ``path``, or None (no file, nothing written)."""
    try:
        return path.read_text(errors="replace").strip()[:64] or None
    except OSError:
        return None


def _flock(fd: int, path: Path) -> bool:
    """Take an exclusive flock on ``fd`` without waiting: False when another holds it."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError as e:
        raise OutputFolderError(
            f"{path}: cannot be locked ({e.strerror or e}); the output folder must be on a "
            "file system that supports flock (some network file systems do not)"
        ) from e
    return True


def _lock_folder(out: Path) -> int | None:
    """An flock on the output folder itself (which a run's files can be deleted from, but
    not the folder): the fd holding it, or None where the file system cannot lock a
    folder (then ``OUT/.lock`` alone guards the run). OutputLockedError when taken."""
    try:
        fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY)
    except OSError as e:
        raise unwritable_output(out, e) from e
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError as e:
        os.close(fd)
        raise _locked_error(out, _lock_holder(out / LOCK_NAME)) from e
    except OSError as e:
        os.close(fd)
        log.debug("%s: the folder cannot be flocked (%s); OUT/.lock alone guards it", out, e)
        return None
    return fd


def _lock_file(out: Path) -> int:
    """The fd of ``OUT/.lock`` holding an exclusive flock, the pid written in it.

    A lock on a file that was deleted or replaced after it was opened guards nothing:
    after the flock the file at ``OUT/.lock`` must still be the one locked (same device
    and inode), else it is opened again (up to :data:`LOCK_ATTEMPTS` times).
    """
    path = out / LOCK_NAME
    for _attempt in range(LOCK_ATTEMPTS):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            raise unwritable_output(out, e) from e
        try:
            if not _flock(fd, path):
                raise _locked_error(out, _lock_holder(path))
            held = os.fstat(fd)
            try:
                now = os.stat(path)
            except FileNotFoundError:
                now = None
            if now is None or (now.st_dev, now.st_ino) != (held.st_dev, held.st_ino):
                log.debug("%s was replaced while it was being locked; locking it again", path)
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            os.pwrite(fd, str(os.getpid()).encode(), 0)
        except OSError as e:
            os.close(fd)
            raise unwritable_output(out, e) from e
        except BaseException:
            os.close(fd)
            raise
        return fd
    raise OutputLockedError(
        f"{path}: the lock file keeps being replaced by another process; stop the other "
        "program writing to this folder, or choose another --out"
    )


@contextlib.contextmanager
def output_lock(out: Path) -> Iterator[None]:
    """Hold the output folder for the block: raise OutputLockedError when another run
    holds it and OutputFolderError when the folder cannot be written.

    Two flocks, both dropped by the kernel with the process: on the folder itself (so
    deleting ``OUT/.lock`` during a run lets no second run in) and on ``OUT/.lock``
    (which names the holder's pid, and guards the folder alone on a file system that
    cannot lock folders).
    """
    folder_fd = _lock_folder(out)
    try:
        file_fd = _lock_file(out)
        try:
            yield
        finally:
            os.close(file_fd)  # closing releases the lock
    finally:
        if folder_fd is not None:
            os.close(folder_fd)


def prepare_output(out: str | Path) -> Path:
    """``out`` as an existing folder (created when missing); OutputFolderError otherwise."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputFolderError(f"{out}: exists and is not a folder; choose a folder for --out")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputFolderError(f"{out}: cannot create the output folder: {e.strerror}") from e
    return out


def _staging_owner(name: str) -> tuple[int, int] | None:
    """(pid, time in ns) of an ``OUT/.staging`` entry (``<pid>.<time>``,
    ``<id>.old.<pid>.<time>``, ``<id>.discard.<pid>.<time>``), None for another name."""
    parts = name.split(".")
    if len(parts) < 2 or not (parts[-2].isdigit() and parts[-1].isdigit()):
        return None
    return int(parts[-2]), int(parts[-1])


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def clean_staging(out: Path, since: int | None = None) -> None:
    """Remove what killed runs left in ``OUT/.staging``, never what a live process works on.

    An entry goes when the process named in it (``<pid>.<time>``: the worker that made
    it) is not alive or is this one; with ``since`` (this run's start, ``time.time_ns()``)
    also every entry made since (this run's workers' leftovers). The folder goes when
    empty. A live process's older entry stays: another run may be working in it.
    """
    staging = out / STAGING
    if not staging.is_dir():
        return
    me = os.getpid()
    for entry in sorted(staging.iterdir()):
        owner = _staging_owner(entry.name)
        if owner is not None:
            pid, made = owner
            if pid != me and _alive(pid) and (since is None or made < since):
                log.warning("%s: kept: process %d that made it is still running", entry, pid)
                continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                entry.unlink()
    with contextlib.suppress(OSError):
        staging.rmdir()


def holds_good_asset(folder: Path) -> bool:
    """True when ``folder`` holds a complete asset that did not fail: every file there
    (:func:`~asset_pipeline.catalog.registry.folder_problem`) and a report, if any, that
    says ok or repaired (an asset built without validation has none)."""
    if folder_problem(folder, validated=False) is not None:
        return False
    try:
        report = read_report(folder)
    except ReportFormatError:
        return False
    return report is None or report.ok


def _discard(out: Path, folder: Path) -> None:
    """Remove ``folder`` (renamed into ``OUT/.staging`` first, so it goes at once)."""
    trash = out / STAGING / f"{folder.name}.discard.{os.getpid()}.{time.time_ns()}"
    trash.parent.mkdir(parents=True, exist_ok=True)
    os.replace(folder, trash)
    shutil.rmtree(trash, ignore_errors=True)


def set_aside(out: Path, asset_id: str) -> Path | None:
    """Clear ``OUT/<id>`` for a failed item; return where its good asset went, if any.

    ``OUT/.previous/<id>`` keeps the last good asset and nothing else: a good asset
    (:func:`holds_good_asset`) at ``OUT/<id>`` is moved there (replacing an older good
    one); a failed or damaged folder at ``OUT/<id>`` (an earlier failure of the same
    item) is deleted and never replaces the good copy.
    """
    folder = out / asset_id
    if not folder.exists() and not folder.is_symlink():
        return None
    if not holds_good_asset(folder):
        log.info("%s: removing the failed or damaged folder of an earlier run", folder)
        _discard(out, folder)
        return None
    dest = out / PREVIOUS / asset_id
    if dest.exists():
        _discard(out, dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    os.replace(folder, dest)
    return dest


def previous_note(out: Path, asset_id: str, moved: Path | None) -> str | None:
    """What a failure of ``asset_id`` says about its last good asset: where it was just
    moved (``moved``) or where it is still kept from an earlier failure."""
    if moved is not None:
        return f"the previous good asset was moved to {moved}"
    kept = out / PREVIOUS / asset_id
    if kept.is_dir():
        return f"the last good asset is kept in {kept}"
    return None


def _install(staged: Path, out: Path, asset_id: str, failed: bool) -> tuple[Path, Path | None]:
    """Move a complete staged asset to ``OUT/<id>``; return it and where the older asset
    went (None when it was deleted or there was none). An older asset there is deleted
    when the new one passed, else cleared by :func:`set_aside` (a good one kept in
    ``OUT/.previous/<id>``)."""
    final = out / asset_id
    old = moved = None
    if final.exists() or final.is_symlink():
        if failed:
            moved = set_aside(out, asset_id)
        else:
            old = out / STAGING / f"{asset_id}.old.{os.getpid()}.{time.time_ns()}"
            os.replace(final, old)
    os.replace(staged, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return final, moved


def reconcile(catalog: Catalog, out: Path) -> list[str]:
    """Make every catalog row agree with its folder; return what was changed.

    A row that says ok or repaired whose folder is incomplete or disagrees
    (:func:`~asset_pipeline.catalog.registry.folder_problem`) becomes failed with the reason; a
    failed row whose folder holds a passing asset (left by an older pact) has that
    folder moved to ``OUT/.previous/``.
    """
    notes = []
    for row in catalog.query(details=True):
        folder = catalog.asset_dir(row)
        if row.status in ("ok", "repaired"):
            problem = (
                folder_problem(folder, row.status, validated=bool(row.checks))
                if folder
                else "no asset folder"
            )
            if problem is not None:
                reason = f"the asset's files are damaged ({problem}); convert its photo again"
                catalog.upsert_asset(replace(row, status="failed", failure_reason=reason))
                notes.append(f"{row.id}: marked failed: {reason}")
        elif folder is not None and folder.is_dir() and folder.parent == out:
            try:
                report = read_report(folder)
            except ReportFormatError:
                report = None
            if report is not None and report.ok:
                dest = set_aside(out, row.id)
                catalog.upsert_asset(replace(row, path=None))
                notes.append(f"{row.id}: failed in the catalog; its old asset moved to {dest}")
    return notes


# --------------------------------------------------------------------------- the batch


@dataclass
class BatchSummary:
    results: list[ItemResult]
    skipped: list[str]
    #: Files of the input folder that are not items (with why).
    ignored: list[SkippedFile] = field(default_factory=list)
    #: Catalog rows changed to agree with the disk before the run.
    reconciled: list[str] = field(default_factory=list)

    @property
    def failed(self) -> list[ItemResult]:
        return [r for r in self.results if r.status == "failed"]


def _register(catalog: Catalog, out: Path, r: ItemResult, settings_hash: str) -> None:
    """Install a finished item's folder and write its catalog row (driver only)."""
    provenance = dict(
        source_image=r.source_image,
        source_hash=r.source_hash,
        settings_hash=settings_hash,
        generator=r.generator,
        generator_version=r.generator_version,
        stage_seconds=r.stage_seconds,
        warnings=tuple(r.warnings),
        inputs=r.inputs,
    )
    if r.path is not None:
        failed = r.status == "failed"
        final, moved = _install(Path(r.path), out, r.id, failed=failed)
        r.path = str(final)
        if failed:
            note = previous_note(out, r.id, moved)
            if note is not None:
                r.reason = f"{r.reason} ({note})"
            provenance["failure_reason"] = r.reason
        rec = register_asset_dir(catalog, final, **provenance)
        if failed and rec.status != "failed":
            catalog.upsert_asset(replace(rec, status="failed", failure_reason=r.reason))
        return
    note = previous_note(out, r.id, set_aside(out, r.id))
    if note is not None:
        r.reason = f"{r.reason} ({note})"
    catalog.record_failure(r.id, r.reason or "unknown failure", category=r.category, **provenance)


def _local_results(
    todo: list[InputItem],
    out: Path,
    settings: ConvertSettings,
    workers: int,
    on_stage: Callable[[str, str], None] | None,
    work: Callable[[tuple, Callable[[str], None]], ItemResult] = _convert_in_worker,
) -> Iterator[ItemResult]:
    """Results of ``todo`` from ``workers`` local processes (in this process for 1).

    ``work`` is what a worker runs per item (a module-level function).
    """
    if workers <= 1:
        for item in todo:
            yield convert_item(
                item, out, settings, lambda s, n=item.name: on_stage and on_stage(n, s)
            )
        return
    pool = WorkerPool(work, workers)
    jobs = [(item, str(out), settings) for item in todo]

    def stage_of(job: tuple, stage: str) -> None:
        if on_stage:
            on_stage(job[0].name, stage)

    for (item, _, _), result in pool.run(jobs, on_stage=stage_of):
        if isinstance(result, WorkerDied):
            yield _lost(item, settings, f"{item.name}: {result.reason}", result.stage)
        else:
            yield result


def _lost(
    item: InputItem, settings: ConvertSettings, reason: str, stage: str | None = None
) -> ItemResult:
    """The result of an item whose worker died before it could report."""
    result = _result_for(item, settings)
    result.reason, result.stage = reason, stage
    return result


def _ray_results(
    todo: list[InputItem], out: Path, settings: ConvertSettings, address: str | None
) -> Iterator[ItemResult]:
    import ray

    ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    remote = ray.remote(convert_item)
    refs = {remote.remote(it, str(out), settings): it for it in todo}
    while refs:
        done, _ = ray.wait(list(refs), num_returns=1)
        for ref in done:
            item = refs.pop(ref)
            try:
                yield ray.get(ref)
            except Exception as e:  # the task or its worker died
                yield _lost(
                    item, settings, f"{item.name}: ray task failed: {type(e).__name__}: {e}"
                )


def same_photo(stored: str, image_path: Path) -> bool:
    """Whether a catalog row's ``source_image`` names the photo ``image_path``.

    Rows store the photo's absolute, resolved path: same when both resolve to one
    file. Rows of older runs may hold a path relative to that run's working directory,
    which is not known: such a path also names the photo when the photo's absolute path
    ends with it. And a stored path that names no file any more (a relative one seen
    from another directory, a moved photo folder) names the photo when its file name is
    the photo's: there is no other photo to protect, and an edited photo converted again
    from elsewhere must not be refused. Only a path to another existing file, or to a
    file of another name, makes the id another photo's.
    """
    stored_path, photo = Path(stored), image_path.resolve()
    if stored_path.resolve() == photo:
        return True
    tail = stored_path.parts
    if not stored_path.is_absolute() and ".." not in tail and photo.parts[-len(tail) :] == tail:
        return True
    return stored_path.name == photo.name and not stored_path.resolve().is_file()


def _plan(
    items: list[InputItem],
    catalog: Catalog,
    settings: ConvertSettings,
    settings_hash: str,
    force: bool,
) -> tuple[list[InputItem], list[str], list[ItemResult]]:
    """Split items into (to convert, ids skipped as done, refused results)."""
    todo, skipped, refused = [], [], []
    first_of: dict[str, InputItem] = {}
    for item in items:
        asset_id = item.asset_id
        key = asset_id.lower()  # ids name folders: a case-insensitive disk must not merge two
        if key in first_of:
            other = first_of[key]
            r = _result_for(item, settings)
            r.stage, r.reason = (
                "load",
                (
                    f"{item.image_path}: id {asset_id!r} is also the id of {other.image_path} in "
                    "this batch; give one of them another id in its hints"
                ),
            )
            refused.append(r)
            continue
        first_of[key] = item
        row = catalog.get(asset_id)
        if (
            row is not None
            and row.source_image is not None
            and row.source_hash != item.input_hash
            and not same_photo(row.source_image, item.image_path)
        ):
            r = _result_for(item, settings)
            r.stage, r.reason = (
                "load",
                (
                    f"{item.image_path}: id {asset_id!r} already belongs to {row.source_image} in "
                    f"{catalog.path}; give this photo another id in its hints"
                ),
            )
            refused.append(r)
            continue
        if not force and catalog.is_done(asset_id, item.input_hash, settings_hash):
            skipped.append(asset_id)
        else:
            todo.append(item)
    # a later item refused for a duplicate id makes the first one ambiguous too
    dup = {r.id.lower() for r in refused if "in this batch" in (r.reason or "")}
    for item in [it for it in todo if it.asset_id.lower() in dup]:
        todo.remove(item)
        r = _result_for(item, settings)
        r.stage, r.reason = (
            "load",
            (
                f"{item.image_path}: id {item.asset_id!r} is shared with another photo of this "
                "batch; give each photo its own id"
            ),
        )
        refused.append(r)
    skipped = [s for s in skipped if s.lower() not in dup]
    return todo, skipped, refused


def run_convert(
    images: str | Path,
    out: str | Path,
    settings: ConvertSettings = ConvertSettings(),
    *,
    workers: int = 1,
    executor: str = "local",
    ray_address: str | None = None,
    force: bool = False,
    on_start: Callable[[int, int], None] | None = None,
    on_stage: Callable[[str, str], None] | None = None,
    on_result: Callable[[ItemResult], None] | None = None,
) -> BatchSummary:
    """Convert every item of ``images`` into ``out``; see the module docstring.

    Raises InputError (the input folder), OutputFolderError, OutputLockedError or
    CatalogError (each naming the path) before any item is converted.
    """
    if executor not in ("local", "ray"):
        raise ValueError(f"executor must be 'local' or 'ray', got {executor!r}")
    listing = discover_inputs(images)  # before --out is created: a wrong folder makes nothing
    out = prepare_output(out)
    if (out / CATALOG_NAME).exists() and not (out / CATALOG_NAME).is_file():
        raise OutputFolderError(f"{out / CATALOG_NAME}: is not a file; move it away")
    with output_lock(out):
        started = time.time_ns()
        check_writable(out)
        clean_staging(out)
        version = generator_version(settings.generator)
        settings_hash = settings.digest(version)
        results: list[ItemResult] = []
        with Catalog(out) as catalog:
            reconciled = reconcile(catalog, out)
            for note in reconciled:
                log.warning("%s", note)
            todo, skipped, refused = _plan(listing.items, catalog, settings, settings_hash, force)
            if on_start:
                on_start(len(todo) + len(refused), len(skipped))
            for r in refused:
                results.append(r)
                if on_result:
                    on_result(r)
            if executor == "ray":
                stream = _ray_results(todo, out, settings, ray_address)
            else:
                stream = _local_results(todo, out, settings, workers, on_stage)
            for r in stream:
                try:
                    _register(catalog, out, r, settings_hash)
                except (CatalogError, OSError) as e:
                    r.status, r.stage = "failed", "register"
                    r.reason = f"register: {e}"
                    log.error("%s: cannot register: %s", r.id, e)
                results.append(r)
                if on_result:
                    on_result(r)
        clean_staging(out, since=started)
    return BatchSummary(
        results=results, skipped=skipped, ignored=list(listing.skipped), reconciled=reconciled
    )
