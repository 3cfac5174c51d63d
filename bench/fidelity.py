"""Likeness of converted assets to their photos (camera, photo texture, fidelity). Prints JSON.

    .venv/bin/python bench/fidelity.py --generator pact|retrieval [--set test|examples|both]
        [--no-texture] [--split-dir runs/test_split] [--out runs/fidelity]
        [--gen-cache runs/fidelity/gen-cache] [--per-category 6] [--limit N]

Converts the fixed test split (``generator.data.test_split``, written on first use) and/or
the bundled examples (``examples/images``) with ``asset_pipeline.catalog.batch.run_convert``
(validation and previews on, one worker) into ``OUT/<generator>-<texture|baseline>-<set>/``
and prints, per set: mean and median silhouette IoU, part-mask IoU, PSNR and SSIM inside
the photo's silhouette (and PSNR where both silhouettes overlap), the fidelity score, the
share of assets flagged ``low_fidelity``, and the seconds per object (wall clock and CPU)
of the camera fit, the texture bake, the ``texture`` and ``fidelity`` stages and their sum.

``--no-texture`` is the baseline: the same camera fit and scoring on assets whose
colours are the generator's own (no photo texture baked).

Generated objects are cached by input (``--gen-cache``): the baseline and the textured
run score the same generated geometry, and a rerun does not pay PAct's ~50 s per photo
again. The cache is keyed by the generator's version and the photo, mask and hints.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from asset_pipeline.catalog import batch  # noqa: E402
from asset_pipeline.catalog.batch import ConvertSettings, run_convert  # noqa: E402
from asset_pipeline.validate import read_report  # noqa: E402
from generator.articulated import ArticulatedObject  # noqa: E402
from generator.bundle import load_bundle, save_bundle  # noqa: E402


class CachedGenerator:
    """A generator whose outputs are kept on disk by input (benchmarks only)."""

    def __init__(self, inner: Any, cache: Path) -> None:
        self.inner = inner
        self.cache = Path(cache)
        self.name = getattr(inner, "name", "generator")
        self.version = str(getattr(inner, "version", "0"))
        self.hits = 0

    def key(self, image: np.ndarray, mask: np.ndarray | None, hints: dict[str, Any]) -> str:
        h = hashlib.sha256(self.version.encode())
        for a in (image, mask, hints.get("alpha")):
            h.update(b"-" if a is None else np.ascontiguousarray(a).tobytes())
        plain = {k: v for k, v in hints.items() if k != "alpha"}
        h.update(json.dumps(plain, sort_keys=True, default=str).encode())
        return h.hexdigest()[:24]

    def generate(
        self, image: np.ndarray, mask: np.ndarray | None = None, hints: dict | None = None
    ) -> ArticulatedObject:
        hints = dict(hints or {})
        folder = self.cache / self.key(image, mask, hints)
        if (folder / "object.json").is_file():
            self.hits += 1
            return load_bundle(folder)
        obj = self.inner.generate(image, mask, hints)
        tmp = Path(tempfile.mkdtemp(dir=self.cache.parent if self.cache.parent.exists() else None))
        save_bundle(obj, tmp / "b")
        self.cache.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(folder, ignore_errors=True)
        (tmp / "b").rename(folder)
        shutil.rmtree(tmp, ignore_errors=True)
        return load_bundle(folder)


def use_cache(generator: str, cache: Path) -> CachedGenerator:
    """Make ``asset_pipeline.catalog.batch`` use a cached ``generator`` in this process."""
    inner = batch.load_generator(generator)
    cached = CachedGenerator(inner, cache / generator)
    batch._GENERATOR_CACHE[generator] = cached
    return cached


def _stats(values: list[float]) -> dict[str, float | int | None]:
    v = [float(x) for x in values if x is not None and np.isfinite(x)]
    if not v:
        return {"mean": None, "median": None, "n": 0}
    return {"mean": statistics.fmean(v), "median": statistics.median(v), "n": len(v)}


def summarize(out: Path, results: list) -> dict[str, Any]:
    """The figures of one converted set."""
    keys = ("silhouette_iou", "part_iou", "psnr", "ssim", "score", "psnr_overlap")
    rows: dict[str, list[float]] = {k: [] for k in keys}
    low, scored, per_object = 0, 0, []
    # wall and CPU seconds of the stages this benchmark is about (the machine is shared:
    # CPU seconds are the steadier figure)
    seconds: dict[str, list[float]] = {
        k: [] for k in ("camera_fit", "bake", "texture_stage", "fidelity_stage", "added")
    }
    cpu: dict[str, list[float]] = {k: [] for k in ("camera_fit", "bake", "fidelity")}
    for r in results:
        if r.status == "failed" and r.path is None:
            per_object.append({"id": r.id, "status": r.status, "reason": r.reason})
            continue
        folder = out / r.id
        report = read_report(folder) if (folder / "report.json").is_file() else None
        fid = getattr(report, "fidelity", None) or {}
        cam = {}
        if (folder / "camera.json").is_file():
            cam = json.loads((folder / "camera.json").read_text())
        fit, bake = cam.get("fit") or {}, cam.get("texture") or {}
        for store, key, value in (
            (seconds, "camera_fit", fit.get("seconds")),
            (cpu, "camera_fit", fit.get("cpu_seconds")),
            (seconds, "bake", bake.get("seconds")),
            (cpu, "bake", bake.get("cpu_seconds")),
            (cpu, "fidelity", fid.get("cpu_seconds")),
            (seconds, "texture_stage", r.stage_seconds.get("texture")),
            (seconds, "fidelity_stage", r.stage_seconds.get("fidelity")),
        ):
            if value is not None:
                store[key].append(value)
        seconds["added"].append(
            r.stage_seconds.get("texture", 0.0) + r.stage_seconds.get("fidelity", 0.0)
        )
        if fid.get("score") is not None:
            scored += 1
            low += bool(fid.get("low_fidelity"))
            for k in keys:
                rows[k].append(fid.get(k))
        per_object.append(
            {
                "id": r.id,
                "status": r.status,
                **{k: fid.get(k) for k in keys},
                "low_fidelity": fid.get("low_fidelity"),
                "reasons": fid.get("reasons"),
                "skipped": fid.get("skipped"),
            }
        )
    return {
        "objects": len(results),
        "scored": scored,
        **{k: _stats(v) for k, v in rows.items()},
        "low_fidelity_share": (low / scored) if scored else None,
        "seconds_per_object": {k: _stats(v) for k, v in seconds.items()},
        "cpu_seconds_per_object": {k: _stats(v) for k, v in cpu.items()},
        "per_object": per_object,
    }


def rescore(out: Path) -> list[Any]:
    """Score every catalogued asset of ``out`` again; results as ``run_convert`` gives them
    (the fidelity stage's seconds are the new ones)."""
    from asset_pipeline.catalog.registry import Catalog

    results = []
    with Catalog(out, readonly=True) as cat:
        rows = cat.query()
    for row in rows:
        r = batch.ItemResult(id=row.id, name=row.id, status=row.status, path=row.path)
        r.stage_seconds = dict(row.stage_seconds)
        if (out / row.id / "report.json").is_file():
            t = time.perf_counter()
            batch.fidelity_stage(out / row.id, r.warnings)
            r.stage_seconds["fidelity"] = time.perf_counter() - t
        results.append(r)
    return results


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--generator", default="retrieval", choices=("pact", "retrieval"))
    ap.add_argument("--set", default="both", choices=("test", "examples", "both"))
    ap.add_argument("--no-texture", action="store_true", help="baseline: no photo texture")
    ap.add_argument("--split-dir", type=Path, default=ROOT / "runs" / "test_split")
    ap.add_argument("--per-category", type=int, default=6)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "fidelity")
    ap.add_argument("--gen-cache", type=Path, default=None)
    ap.add_argument("--limit", type=int, default=None, help="first N photos of each set")
    ap.add_argument("--objects", action="store_true", help="also print per-object figures")
    ap.add_argument(
        "--visual-faces",
        type=int,
        default=None,
        help="pact convert --visual-faces (default its own)",
    )
    ap.add_argument(
        "--rescore",
        action="store_true",
        help="do not convert: score the assets of an earlier run again (same --out, same "
        "generator and mode) with the current fidelity code",
    )
    args = ap.parse_args()

    from generator.data.test_split import write_test_split

    cached = use_cache(args.generator, args.gen_cache or args.out / "gen-cache")
    sets: dict[str, Path] = {}
    if args.set in ("test", "both"):
        ids = write_test_split(args.split_dir, args.per_category)
        chosen = Path(tempfile.mkdtemp()) / "images"
        chosen.mkdir(parents=True)
        for oid in ids:
            for p in (args.split_dir / "images").glob(f"{oid}.*"):
                shutil.copy(p, chosen / p.name)
        sets["test"] = chosen
    if args.set in ("examples", "both"):
        sets["examples"] = ROOT / "examples" / "images"
    settings = ConvertSettings(generator=args.generator, texture=not args.no_texture)
    if args.visual_faces is not None:
        settings = replace(settings, visual_faces=args.visual_faces)
    mode = "baseline" if args.no_texture else "texture"
    report: dict[str, Any] = {"generator": args.generator, "texture": not args.no_texture}
    for name, images in sets.items():
        if args.limit is not None:
            src, images = images, Path(tempfile.mkdtemp()) / "images"
            images.mkdir(parents=True)
            stems = sorted({p.name.split(".")[0] for p in src.glob("*.png")})[: args.limit]
            for p in src.iterdir():
                if p.name.split(".")[0] in stems:
                    shutil.copy(p, images / p.name)
        out = args.out / f"{args.generator}-{mode}-{name}"
        t0 = time.perf_counter()
        if args.rescore:
            results = rescore(out)
        else:
            results = run_convert(images, out, settings, force=True).results
        figures = summarize(out, results)
        figures["wall_seconds"] = time.perf_counter() - t0
        figures["failed"] = sum(r.status == "failed" for r in results)
        figures["out"] = str(out)
        if not args.objects:
            figures.pop("per_object")
        report[name] = figures
    report["generator_cache_hits"] = cached.hits
    print(json.dumps(report, indent=2, default=float))


if __name__ == "__main__":
    main()
