"""Build a training dataset of rendered procedural objects (`pact dataset build`).

Object ``i`` (0-based) is ``sample_object(categories[i % len(categories)], seed + i,
split)``; its views, materials and surface samples are drawn from a random stream
keyed by (object seed, category, split) only, so an object's arrays do not depend on
the shard layout. Objects are stored ``objects_per_shard`` to a shard, in order.

Building is resumable: a shard listed in the manifest whose file exists is skipped.
Each shard is written to a temporary name and renamed, and the manifest is rewritten
(atomically) after every shard. An object that cannot be generated or encoded is
logged and recorded under the shard's ``failed`` list; the build goes on.
"""

from __future__ import annotations

import logging
import time
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from generator.articulated import ArticulatedObject
from generator.data.encode import EncodeConfig, encode_object
from generator.data.render import ViewConfig, check_render_device
from generator.data.shards import (
    JOINT_TYPES,
    SCHEMA,
    SEMANTICS,
    VERSION,
    DatasetError,
    array_spec,
    read_manifest,
    remove_stale_temporaries,
    shard_name,
    stack_records,
    write_manifest,
    write_shard,
)

log = logging.getLogger(__name__)

Sampler = Callable[[str, int, str], ArticulatedObject]
SPLITS = ("train", "test")

# manifest keys that must match for a folder to be resumed
_FIXED_KEYS = (
    "seed",
    "split",
    "resolution",
    "image_size",
    "views",
    "max_parts",
    "points_per_part",
    "categories",
    "objects_per_shard",
    "semantics",
    "joint_types",
)


def default_object_id(category: str, seed: int) -> str:
    return f"{category}_s{seed:07d}"


def object_seed_sequence(category: str, seed: int, split: str) -> np.random.SeedSequence:
    """The random stream of one object's views, materials and surface samples."""
    return np.random.SeedSequence([seed, zlib.crc32(category.encode()), SPLITS.index(split)])


def _procedural() -> tuple[Sequence[str], Sampler, Callable[[str, int], str]]:
    try:
        from generator.procedural import CATEGORIES, object_id, sample_object
    except ImportError as e:  # the factory lives in generator/procedural/
        raise DatasetError(
            f"generator.procedural is not available ({e}); pass sampler= and categories="
        ) from e
    return CATEGORIES, sample_object, object_id


def build_dataset(
    out: Path,
    n: int,
    views: int,
    seed: int,
    *,
    split: str = "train",
    categories: Sequence[str] | None = None,
    resolution: int = 32,
    image_size: int = 256,
    objects_per_shard: int = 64,
    max_parts: int = 16,
    points_per_part: int = 2048,
    progress: bool = True,
    sampler: Sampler | None = None,
    view_config: ViewConfig | None = None,
) -> Path:
    """Render ``n`` procedural objects (``views`` each) into shards under ``out``.

    Returns the manifest path. Deterministic: the same arguments give identical arrays.
    ``sampler(category, seed, split) -> ArticulatedObject`` defaults to
    ``generator.procedural.sample_object`` and ``categories`` to its ``CATEGORIES``.
    Raises DatasetError when ``out`` holds a dataset built with other arguments.
    """
    if split not in SPLITS:
        raise DatasetError(f"split must be one of {SPLITS}, got {split!r}")
    if resolution % 2 or resolution < 2:
        raise DatasetError(f"resolution must be even (packbits of R^3 bits), got {resolution}")
    if n < 0 or views < 1 or objects_per_shard < 1:
        raise DatasetError(
            f"need n >= 0, views >= 1, objects_per_shard >= 1; got {n}, {views}, {objects_per_shard}"
        )
    make_id: Callable[[str, int], str] = default_object_id
    if sampler is None or categories is None:
        proc_categories, proc_sampler, proc_id = _procedural()
        if sampler is None:
            sampler, make_id = proc_sampler, proc_id
        categories = list(proc_categories) if categories is None else categories
    categories = list(categories)
    if not categories:
        raise DatasetError("categories is empty")
    check_render_device()

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(out)
    config = EncodeConfig(
        views, image_size, resolution, max_parts, points_per_part, view_config or ViewConfig()
    )
    spec = array_spec(views, image_size, max_parts, resolution, points_per_part)
    manifest: dict[str, Any] = {
        "schema": SCHEMA,
        "version": VERSION,
        "seed": seed,
        "split": split,
        "resolution": resolution,
        "image_size": image_size,
        "views": views,
        "max_parts": max_parts,
        "points_per_part": points_per_part,
        "semantics": list(SEMANTICS),
        "joint_types": list(JOINT_TYPES),
        "n": n,
        "categories": categories,
        "objects_per_shard": objects_per_shard,
        "object_seeds": "object i = sample_object(categories[i % len(categories)], seed + i, split)",
        "view_qpos_units": "prismatic: normalized units (metres / s); revolute: radians",
        "shards": [],
    }
    previous = read_manifest(out)
    done: dict[str, dict[str, Any]] = {}
    if previous is not None:
        diff = {
            k: (previous.get(k), manifest[k]) for k in _FIXED_KEYS if previous.get(k) != manifest[k]
        }
        if diff:
            raise DatasetError(
                f"{out} holds a dataset built with other arguments "
                f"(key: (existing, requested)) {diff}; use another output folder or the same arguments"
            )
        done = {s["file"]: s for s in previous.get("shards", [])}

    jobs = []  # (file, [(index, category, object seed, object id)])
    for k, start in enumerate(range(0, n, objects_per_shard)):
        members = []
        for i in range(start, min(n, start + objects_per_shard)):
            cat, s = categories[i % len(categories)], seed + i
            members.append((i, cat, s, make_id(cat, s)))
        jobs.append((shard_name(k), members))

    files = {f for f, _ in jobs}
    entries = {f: e for f, e in done.items() if f in files and (out / f).is_file()}
    bar = _Progress(n, enabled=progress)
    with bar:
        for file, members in jobs:
            entry = entries.get(file)
            if entry is not None and _listed(entry) == sorted(m[3] for m in members):
                log.info("%s: complete, skipped", file)
                bar.advance(len(members))
                continue
            records, failed = [], []
            for _, cat, s, oid in members:
                t0 = time.perf_counter()
                try:
                    obj = sampler(cat, s, split)
                    records.append(
                        encode_object(obj, oid, object_seed_sequence(cat, s, split), config)
                    )
                except Exception as e:  # a batch records the failed item and goes on
                    log.warning("%s: skipped: %s: %s", oid, type(e).__name__, e)
                    failed.append({"id": oid, "reason": f"{type(e).__name__}: {e}"})
                log.debug("%s: %.2f s", oid, time.perf_counter() - t0)
                bar.advance(1)
            if not records:
                raise DatasetError(f"{file}: every object failed; first: {failed[0]['reason']}")
            write_shard(out / file, stack_records(records, spec))
            entries[file] = {
                "file": file,
                "objects": [str(r["object_ids"]) for r in records],
                "failed": failed,
            }
            manifest["shards"] = [entries[f] for f, _ in jobs if f in entries]
            write_manifest(out, manifest)
    manifest["shards"] = [entries[f] for f, _ in jobs if f in entries]
    write_manifest(out, manifest)
    return out / "manifest.json"


def _listed(entry: dict[str, Any]) -> list[str]:
    """Object ids a manifest shard entry accounts for (stored and failed), in build order."""
    ids = list(entry.get("objects", [])) + [f["id"] for f in entry.get("failed", [])]
    return sorted(ids)


class _Progress:
    """A rich progress bar over objects (a no-op when disabled)."""

    def __init__(self, total: int, enabled: bool):
        self.enabled = enabled
        self.total = total
        self._progress = None

    def __enter__(self) -> _Progress:
        if self.enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._progress = Progress(
                TextColumn("rendering objects"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
            )
            self._progress.__enter__()
            self._task = self._progress.add_task("objects", total=self.total)
        return self

    def advance(self, k: int) -> None:
        if self._progress is not None:
            self._progress.advance(self._task, k)

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)
