"""Generation quality on the fixed test split (issue 5) or the real dev split. Prints JSON, then a table.

    .venv/bin/python bench/gen_quality.py --generator retrieval [--per-category 6]
        [--split-dir runs/test_split] [--no-mask [--one-sample-without-mask]]
    .venv/bin/python bench/gen_quality.py --split real --generator pact retrieval
        [--split-dir /work/data/real_split] [--no-mask] [--category-hint] [--limit N]
        [--categories microwave oven ...] [--styles product room] [--views N] [--weights FOLDER]
        [--dev-half A|B] [--parser [--parser-weights FOLDER]]
        [--seed N] [--candidates N] [--stage1-steps N] [--stage1-cfg-interval LO HI]
        [--stage2-cfg-interval LO HI]

Test split (the default): writes the split once (``generator.data.test_split``), runs
the generator on every image (with its mask unless ``--no-mask``; the category hint is
passed only with ``--category-hint``; without a mask PAct lays its sample out on the
silhouette unless ``--one-sample-without-mask``), saves the predictions as bundles in
SPLIT/pred-<generator>/, and prints the paper's metrics per category (generator.metrics)
as JSON and a rich table.

Real split (``--split real``): the split must have been written (``bench/real_split.py``;
default folder ``generator.data.real_split.DEFAULT_REAL_SPLIT``, /work/data/real_split).
Every image (``<object>_<style>_<k>``, product photos and rooms) is generated
from, the prediction saved in SPLIT/pred-<generator>[-nomask]/<image id>/ and compared
with its object's ground truth SPLIT/gt/<object>/; the JSON adds the means per style
and per category and style. Every group also counts the ground truth's movable joints
whose type the predictions lack (``joint_types_missed`` of ``movable_joints``:
``generator.metrics.joint_types_missed``).

Several ``--generator`` s run one after the other on the same images; the JSON is then
``{"runs": [<one run's JSON>, ...], "comparison": {category: {metric: {generator:
value}}}}`` and the table compares them per category. CLIP similarity, the paper's
eighth column, needs CLIP weights, which cannot be downloaded here; it is not reported.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from rich.console import Console
from rich.table import Table

from generator.bundle import load_bundle, save_bundle
from generator.data.real_split import DEFAULT_REAL_SPLIT, dev_half, read_manifest
from generator.data.test_split import write_test_split
from generator.metrics import (
    METRIC_KEYS,
    MetricError,
    evaluate_dirs,
    format_table,
    mean_scores,
    score_row,
)

GENERATORS = ("pact", "retrieval")


def load_generator(  # noqa: ANN201
    name: str, weights: Path | None = None, one_sample: bool = False, sampling: dict | None = None
):
    """The generator ``name``; PAct from ``weights`` (a folder laid out as
    generator/pact/weights/small) when given, else the shipped small model; with
    ``one_sample``, PAct without a mask keeps one stage-1 sample as drawn
    (``Stage1Generator(layout_without_mask=False)``). ``sampling`` (:func:`sampling_options`)
    changes PAct's sampling: the seed, stage-1 candidates and steps, each stage's guidance
    interval."""
    if name == "retrieval":
        from generator.retrieval import RetrievalGenerator

        return RetrievalGenerator.default()
    from generator.pact.inference.generate import WEIGHTS_DIR, PActGenerator

    sampling = sampling or {}
    gen = PActGenerator.load(
        WEIGHTS_DIR / "small" if weights is None else weights,
        layout_without_mask=not one_sample,
        seed=sampling.get("seed", 0),
        **({"candidates": sampling["candidates"]} if "candidates" in sampling else {}),
    )
    s1, s2 = gen.stage1.sampler, gen.sampler
    gen.stage1.sampler = dataclasses.replace(
        s1,
        steps=sampling.get("stage1_steps", s1.steps),
        cfg_interval=tuple(sampling.get("stage1_cfg_interval", s1.cfg_interval)),
    )
    gen.sampler = dataclasses.replace(
        s2, cfg_interval=tuple(sampling.get("stage2_cfg_interval", s2.cfg_interval))
    )
    return gen


def sampling_options(args: argparse.Namespace) -> dict:
    """PAct sampling changes asked on the command line (none: the shipped settings)."""
    out: dict = {}
    if args.seed:
        out["seed"] = args.seed
    if args.candidates is not None:
        out["candidates"] = args.candidates
    if args.stage1_steps is not None:
        out["stage1_steps"] = args.stage1_steps
    for stage in ("stage1", "stage2"):
        interval = getattr(args, f"{stage}_cfg_interval")
        if interval is not None:
            out[f"{stage}_cfg_interval"] = tuple(interval)
    return out


def sampling_tag(sampling: dict) -> str:
    """The predictions folder's suffix for changed sampling, e.g. ``-cand4-s1cfg0.5-1``."""
    tag = ""
    if "seed" in sampling:
        tag += f"-seed{sampling['seed']}"
    if "candidates" in sampling:
        tag += f"-cand{sampling['candidates']}"
    if "stage1_steps" in sampling:
        tag += f"-s1steps{sampling['stage1_steps']}"
    for stage, short in (("stage1", "s1"), ("stage2", "s2")):
        if f"{stage}_cfg_interval" in sampling:
            tag += "-{}cfg{:g}-{:g}".format(short, *sampling[f"{stage}_cfg_interval"])
    return tag


def _inputs(split_dir: Path, iid: str, no_mask: bool, category_hint: bool, parser=None):  # noqa: ANN001, ANN202
    """The photo, mask and hints of image ``iid``; with ``parser``, what the photo lacks
    (the mask when ``no_mask``, the category without ``category_hint``, every part's
    motion) read by the photo parser as ``pact convert`` reads it
    (``asset_pipeline.inputs.parsing.complete_input``)."""
    img = np.asarray(Image.open(split_dir / "images" / f"{iid}.png").convert("RGB"))
    mask = None if no_mask else np.asarray(Image.open(split_dir / "images" / f"{iid}.mask.png"))
    hints = json.loads((split_dir / "images" / f"{iid}.json").read_text())
    if not category_hint:
        hints.pop("category", None)
    if parser is not None:
        from asset_pipeline.inputs.folder import InputItem, LoadedInput
        from asset_pipeline.inputs.parsing import complete_input

        item = InputItem(iid, split_dir / "images" / f"{iid}.png", None, None, "")
        loaded = LoadedInput(item=item, image=img, alpha=None, mask=mask, hints=hints)
        done, _ = complete_input(loaded, parser)
        mask, hints = done.mask, done.hints
    return img, mask, hints


def evaluate_images(
    pred_dir: Path, split_dir: Path, images: list[dict[str, Any]]
) -> dict[str, Any]:
    """``evaluate_dirs`` for a split whose images share ground truth: every prediction
    ``pred_dir/<image id>`` against ``split_dir/gt/<object>``; also means per style."""
    gts: dict[str, Any] = {}
    per_image: dict[str, dict[str, Any]] = {}
    missing, failed = [], {}
    for im in images:
        iid = im["id"]
        if not (pred_dir / iid / "object.json").is_file():
            missing.append(iid)
            continue
        try:
            if im["object"] not in gts:
                gts[im["object"]] = load_bundle(split_dir / "gt" / im["object"])
            scores = score_row(load_bundle(pred_dir / iid), gts[im["object"]])
        except (ValueError, MetricError) as e:  # ObjectModelError is a ValueError
            failed[iid] = str(e)
            continue
        row: dict[str, Any] = {"category": im["category"], "style": im["style"]}
        row.update(scores)
        per_image[iid] = row
    rows = list(per_image.values())

    def group(key) -> dict[str, Any]:  # noqa: ANN001
        by: dict[str, list[dict[str, Any]]] = {}
        for r in rows:
            by.setdefault(key(r), []).append(r)
        return {k: mean_scores(v) for k, v in sorted(by.items())}

    return {
        "per_object": per_image,
        "per_category": group(lambda r: r["category"]),
        "per_style": group(lambda r: r["style"]),
        "per_category_style": group(lambda r: f"{r['category']}/{r['style']}"),
        "mean": mean_scores(rows),
        "missing": missing,
        "failed": failed,
    }


def run(args: argparse.Namespace, name: str, split_dir: Path) -> dict[str, Any]:
    """Generate from every image of the split with generator ``name``; the run's JSON."""
    weights = args.weights if name == "pact" else None
    one_sample = args.one_sample_without_mask and name == "pact"
    sampling = sampling_options(args) if name == "pact" else {}
    gen = load_generator(name, weights, one_sample, sampling)
    tag = (
        f"pred-{name}"
        + (f"-{weights.name}" if weights is not None else "")
        + sampling_tag(sampling)
        + ("-nomask" if args.no_mask else "")
        + ("-onesample" if one_sample else "")
        + ("-hint" if args.category_hint else "")
        + ("-parser" if args.parser else "")
        + (f"-{args.parser_weights.name}" if args.parser and args.parser_weights else "")
    )
    pred_dir = split_dir / tag
    seconds = []
    if args.split == "real":
        manifest = read_manifest(split_dir) or {}
        half = set(dev_half(args.dev_half)) if args.dev_half else None
        images = [
            im
            for im in manifest.get("images", [])
            if (not args.categories or im["category"] in args.categories)
            and (not args.styles or im["style"] in args.styles)
            and (args.views is None or int(im["id"].rsplit("_", 1)[1]) < args.views)
            and (half is None or im["object"] in half)
        ][: args.limit]
        ids = [im["id"] for im in images]
    else:
        ids = write_test_split(split_dir, args.per_category)
    parser = None
    if args.parser:
        from generator.parser import PhotoParser

        parser = (
            PhotoParser.default()
            if args.parser_weights is None
            else PhotoParser.from_dir(args.parser_weights)
        )
    for oid in ids:
        img, mask, hints = _inputs(split_dir, oid, args.no_mask, args.category_hint, parser)
        t0 = time.perf_counter()
        obj = gen.generate(img, mask, hints)
        seconds.append(time.perf_counter() - t0)
        save_bundle(obj, pred_dir / oid)
    if args.split == "real":
        results = evaluate_images(pred_dir, split_dir, images)
        out = {
            "generator": name,
            "weights": None if weights is None else str(weights),
            "split": "real",
            "split_dir": str(split_dir),
            "mask": not args.no_mask,
            "category_hint": bool(args.category_hint),
            "parser": bool(args.parser),
            "images": len(ids),
            "objects": len({im["object"] for im in images}),
            "seconds_per_image_median": statistics.median(seconds) if seconds else None,
            "per_category": results["per_category"],
            "per_style": results["per_style"],
            "per_category_style": results["per_category_style"],
            "mean": results["mean"],
            "missing": results["missing"],
            "failed": results["failed"],
        }
    else:
        results = evaluate_dirs(pred_dir, split_dir / "gt")
        out = {
            "generator": name,
            "weights": None if weights is None else str(weights),
            "mask": not args.no_mask,
            "objects": len(ids),
            "seconds_per_object_median": statistics.median(seconds),
            "per_category": results["per_category"],
            "mean": results["mean"],
            "failed": results.get("failed", {}),
        }
    table = format_table(results)
    if args.split == "real":
        table.title = f"{name}, real split{', no mask' if args.no_mask else ''}: {table.title}"
    Console(stderr=True).print(table)
    return out


def comparison(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """{category (and "all"): {metric: {generator: value}, "count": n}} over ``runs``
    (metrics: the seven and ``joint_types_missed``)."""
    cats = sorted({c for r in runs for c in r["per_category"]}) + ["all"]
    out: dict[str, Any] = {}
    for c in cats:
        row: dict[str, Any] = {}
        for key in (*METRIC_KEYS, "joint_types_missed"):
            row[key] = {
                r["generator"]: (r["mean"] if c == "all" else r["per_category"].get(c, {})).get(key)
                for r in runs
            }
        row["count"] = (runs[0]["mean"] if c == "all" else runs[0]["per_category"].get(c, {})).get(
            "count", 0
        )
        out[c] = row
    return out


def comparison_table(comp: dict[str, Any], names: list[str]) -> Table:
    table = Table(
        title="Generation metrics per category: " + " / ".join(names) + " (lower is better)"
    )
    table.add_column("category")
    table.add_column("n", justify="right")
    for key in METRIC_KEYS:
        table.add_column(key, justify="right")
    table.add_column("joint types missed", justify="right")
    for cat, row in comp.items():
        cells = [
            " / ".join("-" if row[k][n] is None else f"{row[k][n]:.3f}" for n in names)
            for k in METRIC_KEYS
        ]
        cells.append(" / ".join(str(row["joint_types_missed"][n]) for n in names))
        table.add_row(cat, str(row["count"]), *cells, style="bold" if cat == "all" else None)
    return table


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--generator", nargs="+", default=["retrieval"], choices=GENERATORS)
    ap.add_argument("--split", choices=("test", "real"), default="test")
    ap.add_argument("--per-category", type=int, default=6, help="Test split objects per category.")
    ap.add_argument(
        "--split-dir",
        type=Path,
        default=None,
        help="Default: runs/test_split; real: " + str(DEFAULT_REAL_SPLIT),
    )
    ap.add_argument("--limit", type=int, default=None, help="Real split: only the first N images.")
    ap.add_argument("--categories", nargs="+", default=None, help="Real split: only these.")
    ap.add_argument(
        "--dev-half",
        choices=("A", "B"),
        default=None,
        help="Real split: only the objects of this half (generator.data.real_split.dev_half)",
    )
    ap.add_argument(
        "--views",
        type=int,
        default=None,
        help="Real split: only each object's first N photos per style (every object kept).",
    )
    ap.add_argument("--styles", nargs="+", default=None, help="Real split: product and/or room.")
    ap.add_argument("--no-mask", action="store_true")
    ap.add_argument("--category-hint", action="store_true")
    ap.add_argument(
        "--parser",
        action="store_true",
        help="read what each photo lacks with the photo parser, as pact convert does: the "
        "mask with --no-mask, the category without --category-hint, every part's motion",
    )
    ap.add_argument("--parser-weights", type=Path, default=None, help="parser weights folder")
    ap.add_argument(
        "--one-sample-without-mask",
        action="store_true",
        help="PAct without a mask: one stage-1 sample kept as drawn, not laid out on a box "
        "fitted to the silhouette (predictions go to pred-pact-nomask-onesample)",
    )
    ap.add_argument(
        "--weights",
        type=Path,
        default=None,
        help="PAct weights folder (laid out as generator/pact/weights/small); predictions "
        "go to pred-pact-<folder name>",
    )
    ap.add_argument(
        "--candidates", type=int, default=None, help="PAct: stage-1 samples per masked photo"
    )
    ap.add_argument("--stage1-steps", type=int, default=None, help="PAct: stage-1 Euler steps")
    ap.add_argument("--seed", type=int, default=0, help="PAct: the sampling seed")
    for stage in ("stage1", "stage2"):
        ap.add_argument(
            f"--{stage}-cfg-interval",
            type=float,
            nargs=2,
            default=None,
            metavar=("LO", "HI"),
            help=f"PAct {stage}: guidance only at the steps with t in [LO, HI]",
        )
    args = ap.parse_args()

    split_dir = args.split_dir or (
        DEFAULT_REAL_SPLIT if args.split == "real" else Path("runs/test_split")
    )
    if args.split == "real" and not (read_manifest(split_dir) or {}).get("images"):
        sys.exit(
            f"{split_dir} holds no real split; write it with: .venv/bin/python bench/real_split.py --out {split_dir}"
        )
    runs = [run(args, name, split_dir) for name in args.generator]
    if len(runs) == 1:
        print(json.dumps(runs[0], indent=2))
        return
    comp = comparison(runs)
    print(json.dumps({"runs": runs, "comparison": comp}, indent=2))
    Console(stderr=True).print(comparison_table(comp, list(args.generator)))


if __name__ == "__main__":
    main()
