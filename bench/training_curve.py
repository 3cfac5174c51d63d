"""A stage-1 training run's curve: samples seen against the generation metrics on the
real dev split (or the test split). Prints JSON, then a table.

    .venv/bin/python bench/training_curve.py --run RUN [--init generator/pact/weights/small/stage1]
        [--split real] [--styles product] [--limit N] [--work runs/curve]

``RUN`` is a ``generator.pact.training.train_stage1`` run folder trained with ``--snapshot-every K``: every
``RUN/flow/snapshots/step_<k>/stage1`` is scored. Each snapshot becomes a weights folder
``WORK/<run name>_<split>[_<styles>][_first<N>]_samples_<n>/`` laid out as generator/pact/weights/small: the shipped
networks (``--base``) with the snapshot's stage 1 in place of the shipped one, and is
run through ``bench/gen_quality.py``'s chain (``PActGenerator.load``, the mask given,
the paper's metrics). ``--init`` (the stage-1 folder the run started from) adds the point
at 0 samples. A snapshot already scored (its JSON in WORK) is not scored again.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from rich.console import Console
from rich.table import Table

sys.path.insert(0, str(Path(__file__).resolve().parent))
from gen_quality import run as run_gen_quality  # noqa: E402

from generator.data.real_split import DEFAULT_REAL_SPLIT  # noqa: E402
from generator.metrics import METRIC_KEYS  # noqa: E402
from generator.pact.inference.generate import WEIGHTS_DIR  # noqa: E402

NETWORKS = ("ss_vae", "slat_vae", "stage2", "foreground", "stage1_head")


def snapshots(run: Path) -> list[tuple[int, Path]]:
    """(samples seen, stage-1 folder) of every finished snapshot of ``run``, in order."""
    out = []
    for folder in sorted((run / "flow" / "snapshots").glob("step_*")):
        if not (folder / "stage1" / "config.json").is_file():  # being written
            continue
        meta = json.loads((folder / "stage1" / "config.json").read_text())
        out.append((int(meta["extra"]["samples_seen"]), folder / "stage1"))
    return out


def weights_folder(work: Path, name: str, stage1: Path, base: Path) -> Path:
    """``work/name``: the ``base`` networks with ``stage1`` as stage 1 (symlinks)."""
    folder = work / name
    folder.mkdir(parents=True, exist_ok=True)
    for net in (*NETWORKS, "stage1"):
        link, target = folder / net, (stage1 if net == "stage1" else base / net)
        if not target.exists():
            continue
        if link.is_symlink() or link.exists():
            link.unlink()
        link.symlink_to(target.resolve(), target_is_directory=True)
    return folder


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True)
    ap.add_argument("--init", type=Path, default=None, help="the run's --init-from folder")
    ap.add_argument("--base", type=Path, default=WEIGHTS_DIR / "small")
    ap.add_argument("--split", choices=("test", "real"), default="real")
    ap.add_argument("--split-dir", type=Path, default=None)
    ap.add_argument("--styles", nargs="+", default=["product"])
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--work", type=Path, default=Path("runs/curve"))
    args = ap.parse_args()

    split_dir = args.split_dir or (
        Path(DEFAULT_REAL_SPLIT) if args.split == "real" else Path("runs/test_split")
    )
    points = ([(0, args.init)] if args.init is not None else []) + snapshots(args.run)
    if not points:
        sys.exit(f"{args.run}: no snapshots (train with --snapshot-every K)")
    scope = (  # what a scored point was measured on: part of its name
        args.split
        + ("_" + "_".join(args.styles) if args.split == "real" else "")
        + (f"_first{args.limit}" if args.limit else "")
    )
    curve: list[dict[str, Any]] = []
    for samples, stage1 in points:
        name = f"{args.run.name}_{scope}_samples_{samples:08d}"
        scored = args.work / f"{name}.json"
        if scored.is_file():
            curve.append(json.loads(scored.read_text()))
            continue
        weights = weights_folder(args.work, name, stage1, args.base)
        gq = SimpleNamespace(
            weights=weights,
            no_mask=False,
            category_hint=False,
            split=args.split,
            categories=None,
            styles=args.styles if args.split == "real" else None,
            limit=args.limit,
            per_category=6,
        )
        result = run_gen_quality(gq, "pact", split_dir)
        point = {"samples_seen": samples, "stage1": str(stage1), "mean": result["mean"]}
        point["per_category"] = result["per_category"]
        scored.write_text(json.dumps(point, indent=1))
        curve.append(point)
    print(json.dumps({"run": str(args.run), "split": args.split, "curve": curve}, indent=1))
    table = Table(title=f"{args.run.name}: {args.split} split, lower is better")
    table.add_column("samples seen", justify="right")
    for key in METRIC_KEYS:
        table.add_column(key, justify="right")
    for point in curve:
        cells = [f"{point['mean'].get(k, float('nan')):.4f}" for k in METRIC_KEYS]
        table.add_row(f"{point['samples_seen']:,}", *cells)
    Console(stderr=True).print(table)


if __name__ == "__main__":
    main()
