"""Batch conversion of an image folder: generate, build, validate, register (``pact convert``).

Each input item (docs/input-format.md) goes through the stages ``load`` ->
``generate`` -> ``build`` (mesh, collision, rig) -> ``validate`` (checks, repairs,
preview) in a worker; the driver alone writes the catalog (``OUT/registry.sqlite``).

Guarantees
----------
- Atomic items: a worker assembles the asset in ``OUT/.staging/<id>.<pid>/`` and
  renames it to ``OUT/<id>`` only when it is complete; an older version is moved
  aside first and deleted after. A run killed at any moment leaves finished items
  intact and no half-made ``OUT/<id>``; stale staging folders are removed by the next
  run.
- Resumable and idempotent: an item whose id, input hash and settings hash match a
  catalogued, not-failed asset whose folder exists is skipped (``force`` redoes it).
- One failed item never stops the batch; its reason is catalogued.
- Executors: a local process pool (default; ``workers`` processes) or a Ray cluster
  (``executor="ray"``, each item one Ray task, the catalog written by the driver).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import time
import traceback
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from asset_pipeline.inputs import InputError, InputItem, discover_inputs, load_input
from asset_pipeline.registry import Catalog, register_asset_dir

log = logging.getLogger(__name__)

STAGES = ("load", "generate", "build", "validate")
GENERATORS = ("pact", "retrieval")
STAGING = ".staging"


@dataclass(frozen=True)
class ConvertSettings:
    """What an item's result depends on besides its input files (hashed for resume)."""

    generator: str = "pact"
    validate: bool = True
    repair: bool = True
    preview: bool = True
    seed: int = 0

    def digest(self, generator_version: str = "") -> str:
        text = json.dumps({**asdict(self), "generator_version": generator_version}, sort_keys=True)
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
            from generator.pact.generate import PActGenerator

            _GENERATOR_CACHE[name] = PActGenerator.default()
    return _GENERATOR_CACHE[name]


def generator_version(name: str) -> str:
    return str(getattr(load_generator(name), "version", "0"))


# --------------------------------------------------------------------------- one item


def _replace_dir(staging: Path, final: Path) -> None:
    """Move ``staging`` to ``final``, replacing an older ``final`` without a half-made state."""
    old = None
    if final.exists():
        old = final.parent / STAGING / f"{final.name}.old.{os.getpid()}.{time.time_ns()}"
        os.replace(final, old)
    os.replace(staging, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def convert_item(
    item: InputItem,
    out: str | Path,
    settings: ConvertSettings,
    report_stage: Callable[[str, str], None] | None = None,
) -> ItemResult:
    """Run every stage for one input item; never raises (failures come back as results)."""
    from asset_pipeline.build import build_asset
    from generator.articulated import save_bundle

    out = Path(out)
    result = ItemResult(
        id=item.name,
        name=item.name,
        status="failed",
        source_image=str(item.image_path),
        source_hash=item.input_hash,
        generator=settings.generator,
    )
    # The build names the asset after its folder, so stage in a private parent folder.
    private = out / STAGING / f"{os.getpid()}.{time.time_ns()}"
    staging = private / item.name
    stage = "load"

    def enter(name: str) -> float:
        nonlocal stage
        stage = name
        if report_stage:
            report_stage(item.name, name)
        return time.perf_counter()

    try:
        t = enter("load")
        loaded = load_input(item)
        result.id = loaded.asset_id
        staging = private / result.id
        result.category = loaded.category
        result.stage_seconds["load"] = time.perf_counter() - t

        t = enter("generate")
        gen = load_generator(settings.generator)
        result.generator_version = str(getattr(gen, "version", "0"))
        hints = dict(loaded.hints)
        hints.setdefault("seed", settings.seed)
        if loaded.alpha is not None:
            hints["alpha"] = loaded.alpha
        obj = gen.generate(loaded.image, loaded.mask, hints)
        obj.provenance.setdefault("source_image", str(item.image_path))
        obj.provenance["source_hash"] = item.input_hash
        if obj.category in ("unknown", "") and loaded.category != "unknown":
            obj.category = loaded.category
        result.category = obj.category
        result.stage_seconds["generate"] = time.perf_counter() - t

        t = enter("build")
        save_bundle(obj, staging)
        shutil.copyfile(item.image_path, staging / f"input{item.image_path.suffix.lower()}")
        if item.mask_path is not None:
            shutil.copyfile(item.mask_path, staging / "input.mask.png")
        build_asset(staging, height=loaded.height)
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
            result.stage_seconds["validate"] = time.perf_counter() - t
        final = out / result.id
        _replace_dir(staging, final)
        shutil.rmtree(private, ignore_errors=True)
        result.path = str(final)
        result.status = status
        if status == "failed":
            result.stage = "validate"
    except Exception as e:  # a failed item is a result, not a crash
        result.status = "failed"
        result.stage = stage
        result.reason = (
            f"{stage}: {e}" if isinstance(e, InputError) else f"{stage}: {type(e).__name__}: {e}"
        )
        log.debug("item %s failed in %s:\n%s", item.name, stage, traceback.format_exc())
        shutil.rmtree(private, ignore_errors=True)
    return result


# --------------------------------------------------------------------------- the batch


@dataclass
class BatchSummary:
    results: list[ItemResult]
    skipped: list[str]

    @property
    def failed(self) -> list[ItemResult]:
        return [r for r in self.results if r.status == "failed"]


def clean_staging(out: Path) -> None:
    """Remove what a killed run left in ``OUT/.staging``."""
    shutil.rmtree(out / STAGING, ignore_errors=True)


def _register(catalog: Catalog, r: ItemResult, settings_hash: str) -> None:
    provenance = dict(
        source_image=r.source_image,
        source_hash=r.source_hash,
        settings_hash=settings_hash,
        generator=r.generator,
        generator_version=r.generator_version,
        stage_seconds=r.stage_seconds,
    )
    if r.path is not None:
        rec = register_asset_dir(catalog, r.path, **provenance)
        if r.status == "failed" and rec.status != "failed":
            catalog.upsert_asset(
                type(rec)(**{**asdict(rec), "status": "failed", "failure_reason": r.reason})
            )
    else:
        catalog.record_failure(
            r.id, r.reason or "unknown failure", category=r.category, **provenance
        )


def _local_results(
    todo: list[InputItem], out: Path, settings: ConvertSettings, workers: int, on_stage
) -> Iterator[ItemResult]:
    if workers <= 1:
        for item in todo:
            yield convert_item(item, out, settings, on_stage)
        return
    import multiprocessing as mp

    ctx = mp.get_context("spawn")  # SAPIEN and torch do not survive fork reliably
    with mp.Manager() as manager:
        stages = manager.dict()
        reporter = _DictReporter(stages)
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            pending = {pool.submit(convert_item, it, out, settings, reporter): it for it in todo}
            while pending:
                done, _ = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
                if on_stage:
                    for name, stage in list(stages.items()):
                        on_stage(name, stage)
                for fut in done:
                    item = pending.pop(fut)
                    try:
                        yield fut.result()
                    except Exception as e:  # a worker process died
                        yield _lost(item, settings, f"worker crashed: {type(e).__name__}: {e}")


def _lost(item: InputItem, settings: ConvertSettings, reason: str) -> ItemResult:
    """The result of an item whose worker died before it could report."""
    return ItemResult(
        id=_asset_id(item),
        name=item.name,
        status="failed",
        reason=reason,
        source_image=str(item.image_path),
        source_hash=item.input_hash,
        generator=settings.generator,
    )


class _DictReporter:
    """Picklable stage reporter writing into a multiprocessing Manager dict."""

    def __init__(self, shared: Any) -> None:
        self.shared = shared

    def __call__(self, name: str, stage: str) -> None:
        self.shared[name] = stage


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
                yield _lost(item, settings, f"ray task failed: {type(e).__name__}: {e}")


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
    """Convert every item of ``images`` into ``out``; see the module docstring."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    clean_staging(out)
    items = discover_inputs(images)
    version = generator_version(settings.generator)
    settings_hash = settings.digest(version)
    results: list[ItemResult] = []
    skipped: list[str] = []
    with Catalog(out) as catalog:
        todo = []
        for item in items:
            # The id is the hints' "id" or the file name; cheap to read again here.
            asset_id = _asset_id(item)
            if not force and catalog.is_done(asset_id, item.input_hash, settings_hash):
                skipped.append(asset_id)
            else:
                todo.append(item)
        if on_start:
            on_start(len(todo), len(skipped))
        if executor == "ray":
            stream = _ray_results(todo, out, settings, ray_address)
        elif executor == "local":
            stream = _local_results(todo, out, settings, workers, on_stage)
        else:
            raise ValueError(f"executor must be 'local' or 'ray', got {executor!r}")
        for r in stream:
            _register(catalog, r, settings_hash)
            results.append(r)
            if on_result:
                on_result(r)
    clean_staging(out)
    return BatchSummary(results=results, skipped=skipped)


def _asset_id(item: InputItem) -> str:
    if item.hints_path is not None:
        try:
            hints = json.loads(item.hints_path.read_text())
            if isinstance(hints, dict) and isinstance(hints.get("id"), str):
                return hints["id"]
        except (OSError, ValueError):
            pass
    return item.name
