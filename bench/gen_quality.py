"""Generation quality on the fixed test split (issue 5). Prints JSON, then a table.

    .venv/bin/python bench/gen_quality.py --generator retrieval [--per-category 6]
        [--split-dir runs/test_split] [--no-mask]

Writes the split once (``generator.data.test_split``), runs the generator on every
image (with its mask unless ``--no-mask``; the category hint is passed only with
``--category-hint``), saves the predictions as bundles in SPLIT/pred-<generator>/, and
prints the paper's metrics per category (generator.metrics) as JSON and a rich table.
CLIP similarity, the paper's eighth column, needs CLIP weights, which cannot be
downloaded here; it is not reported.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
from PIL import Image
from rich.console import Console

from generator.articulated import save_bundle
from generator.data.test_split import write_test_split
from generator.metrics import evaluate_dirs, format_table


def load_generator(name: str):  # noqa: ANN201
    if name == "retrieval":
        from generator.retrieval import RetrievalGenerator

        return RetrievalGenerator.default()
    from generator.pact.generate import PActGenerator

    return PActGenerator.default()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--generator", default="retrieval")
    ap.add_argument("--per-category", type=int, default=6)
    ap.add_argument("--split-dir", type=Path, default=Path("runs/test_split"))
    ap.add_argument("--no-mask", action="store_true")
    ap.add_argument("--category-hint", action="store_true")
    args = ap.parse_args()

    ids = write_test_split(args.split_dir, args.per_category)
    gen = load_generator(args.generator)
    tag = f"pred-{args.generator}" + ("-nomask" if args.no_mask else "")
    pred_dir = args.split_dir / tag
    seconds = []
    for oid in ids:
        img = np.asarray(Image.open(args.split_dir / "images" / f"{oid}.png").convert("RGB"))
        mask = (
            None
            if args.no_mask
            else np.asarray(Image.open(args.split_dir / "images" / f"{oid}.mask.png"))
        )
        hints = json.loads((args.split_dir / "images" / f"{oid}.json").read_text())
        if not args.category_hint:
            hints.pop("category", None)
        t0 = time.perf_counter()
        obj = gen.generate(img, mask, hints)
        seconds.append(time.perf_counter() - t0)
        save_bundle(obj, pred_dir / oid)
    results = evaluate_dirs(pred_dir, args.split_dir / "gt")
    out = {
        "generator": args.generator,
        "mask": not args.no_mask,
        "objects": len(ids),
        "seconds_per_object_median": statistics.median(seconds),
        "per_category": results["per_category"],
        "mean": results["mean"],
        "failed": results.get("failed", {}),
    }
    print(json.dumps(out, indent=2))
    Console(stderr=True).print(format_table(results))


if __name__ == "__main__":
    main()
