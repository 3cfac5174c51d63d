"""Batch conversion throughput (issue 6). Prints JSON.

    .venv/bin/python bench/convert.py [--images examples/images] [--generator retrieval]
        [--workers 1 2] [--repeat 2]

For each worker count, converts the image folder (its items repeated ``--repeat``
times under new names) into a fresh output folder with validation and previews on,
and reports objects per minute (wall clock, including worker start-up), the mean and
median seconds per stage, each item's seconds from photo to validated asset (the sum of
its stages: median, min, max), and peak resident memory of the driver and of the
largest worker, and each failed item with its reason. A folder of bare photos (no masks, no
hints) measures the photo parser's path: ``--images FOLDER --generator pact --workers 1
--repeat 1``. The real renders with their masks but not their hints, as a user's folder
of photos and masks (the parser gives the category and motions), measure how many
assets validate with a mask::

    .venv/bin/python bench/convert.py --images REAL/images --pattern '*_product_*' \
        --dev-half B --no-hints --generator pact --workers 2 --repeat 1
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from asset_pipeline.catalog.batch import STAGES, ConvertSettings, run_convert


def replicate(
    src: Path,
    dst: Path,
    repeat: int,
    pattern: str = "*.png",
    hints: bool = True,
    objects: set[str] | None = None,
) -> int:
    """Copy every item of ``src`` whose photo matches ``pattern`` ``repeat`` times as
    ``<name>_r<k>`` (its mask, and its hints when ``hints``); with ``objects``, only
    photos whose name starts with one of them and ``_`` (the real split's
    ``<object>_<style>_<view>``). Returns the item count."""
    dst.mkdir(parents=True)
    n = 0
    for img in sorted(src.glob(pattern)):
        if img.name.endswith(".mask.png") or img.suffix != ".png":
            continue
        stem = img.stem
        if objects is not None and stem.split("_")[0] not in objects:
            continue
        for k in range(repeat):
            name = f"{stem}_r{k}"
            shutil.copy(img, dst / f"{name}.png")
            for suffix in (".mask.png", ".json") if hints else (".mask.png",):
                if (src / f"{stem}{suffix}").is_file():
                    shutil.copy(src / f"{stem}{suffix}", dst / f"{name}{suffix}")
            n += 1
    return n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--images", type=Path, default=Path("examples/images"))
    ap.add_argument("--generator", default="retrieval")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--pattern", default="*.png", help="Photos of --images to convert (a glob)")
    ap.add_argument("--no-hints", action="store_true", help="Leave the items' hints files out")
    ap.add_argument(
        "--dev-half",
        choices=["A", "B"],
        help="Real split: only the objects of this half (generator.data.real_split.dev_half)",
    )
    args = ap.parse_args()
    settings = ConvertSettings(generator=args.generator)
    out: dict = {"generator": args.generator, "runs": []}
    with tempfile.TemporaryDirectory() as tmp:
        images = Path(tmp) / "images"
        objects = None
        if args.dev_half:
            from generator.data.real_split import dev_half

            objects = set(dev_half(args.dev_half))
        n = replicate(args.images, images, args.repeat, args.pattern, not args.no_hints, objects)
        out["items"] = n
        for w in args.workers:
            t0 = time.perf_counter()
            summary = run_convert(images, Path(tmp) / f"out{w}", settings, workers=w)
            wall = time.perf_counter() - t0
            stage = {
                s: statistics.mean(r.stage_seconds.get(s, 0.0) for r in summary.results)
                for s in STAGES
            }
            median_stage = {
                s: statistics.median(r.stage_seconds.get(s, 0.0) for r in summary.results)
                for s in STAGES
            }
            item = [sum(r.stage_seconds.values()) for r in summary.results]
            out["runs"].append(
                {
                    "workers": w,
                    "objects": len(summary.results),
                    "failed": len(summary.failed),
                    "failures": {r.name: f"{r.stage}: {r.reason}" for r in summary.failed},
                    "wall_seconds": wall,
                    "objects_per_minute": 60.0 * len(summary.results) / wall,
                    "mean_stage_seconds": stage,
                    "median_stage_seconds": median_stage,
                    # one photo to a validated asset: the sum of its stages
                    "item_seconds": {
                        "median": statistics.median(item) if item else None,
                        "min": min(item, default=None),
                        "max": max(item, default=None),
                    },
                }
            )
    self_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    child_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    out["peak_rss_mb"] = {"driver": self_kb / 1024, "largest_worker": child_kb / 1024}
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
