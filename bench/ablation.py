"""PAct's ablations on the fixed test split (paper sec. 5.3). Prints JSON, then a table.

    .venv/bin/python bench/ablation.py [--voxels stage1|gt] [--per-category 6]
        [--split-dir runs/test_split] [--limit N] [--weights FOLDER] [--candidates N]

Variants (one generation per object; the variants share its geometry and differ only in
the articulation read-out):

* ``S=1``, ``S=15``, ``S=20``: the articulation head on stage-2 last-block features
  averaged over the last S of the 25 sampling steps (the paper's default is S = 20);
* ``stage1-S=20``: a head of the same shape on stage 1's last-block features (needs the
  stage-1 checkpoints and ``weights/small/stage1_head``), only with ``--voxels stage1``.

``--voxels stage1`` runs the full chain (stage-1 part voxels from image + mask);
``--voxels gt`` conditions stage 2 on the ground-truth part voxels (teacher forcing:
stage 2 and the head measured on their own). Metrics: ``generator.metrics`` against the
split's ground-truth bundles, predictions saved under SPLIT/pred-pact-<voxels>-<variant>/.
"""

from __future__ import annotations

import argparse
import json
import logging
import shutil
import time
from pathlib import Path

import numpy as np
from PIL import Image
from rich.console import Console
from rich.table import Table

from generator.bundle import save_bundle
from generator.data.test_split import write_test_split
from generator.metrics import evaluate_dirs

KEYS = ("RS-dgIoU", "AS-dgIoU", "RS-dcDist", "AS-dcDist", "RS-dCD", "AS-dCD", "AOR")


def gt_occupancy(oid: str, max_parts: int) -> np.ndarray:
    """(max_parts, 32, 32, 32) ground-truth part occupancies in the normalized frame."""
    from generator.data.encode import normalization
    from generator.data.geometry import occupancy
    from generator.data.render import part_slots
    from generator.pact.training.stage2_data import object_from_id

    obj = object_from_id(oid)
    norm = normalization(obj)
    out = np.zeros((max_parts, 32, 32, 32), bool)
    for k, part in enumerate(part_slots(obj)[:max_parts]):
        j = part.joint
        rest = part.posed_mesh(j.lower if j is not None else 0.0)
        rest.apply_translation(-norm[:3])
        rest.apply_scale(1.0 / norm[3])
        out[k] = occupancy(rest, 32)
    return out


def main() -> None:
    logging.basicConfig(level=logging.WARNING)
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--voxels", choices=["stage1", "gt"], default="stage1")
    ap.add_argument("--per-category", type=int, default=6)
    ap.add_argument("--split-dir", type=Path, default=Path("runs/test_split"))
    ap.add_argument("--limit", type=int, default=0, help="only the first N objects")
    ap.add_argument("--no-mask", action="store_true")
    ap.add_argument(
        "--weights", type=Path, default=None, help="weights folder (default: the shipped small)"
    )
    ap.add_argument(
        "--threads", type=int, default=1, help="torch threads (1 is fastest on 2 busy cores)"
    )
    ap.add_argument(
        "--candidates", type=int, default=8, help="stage-1 samples per image (with a mask)"
    )
    args = ap.parse_args()
    import torch

    torch.set_num_threads(args.threads)

    from generator.pact.inference.generate import PActGenerator

    ids = write_test_split(args.split_dir, args.per_category)
    if args.limit:
        ids = ids[: args.limit]
    kw = {"candidates": args.candidates}
    gen = PActGenerator.load(args.weights, **kw) if args.weights else PActGenerator.default(**kw)
    variants: list[tuple[str, int, str]] = [("S=1", 1, "stage2"), ("S=15", 15, "stage2"),
                                            ("S=20", 20, "stage2")]  # fmt: skip
    if args.voxels == "stage1" and gen.stage1_head is not None:
        variants.append(("stage1-S=20", 20, "stage1"))
    dirs = {name: args.split_dir / f"pred-pact-{args.voxels}-{name}" for name, _, _ in variants}
    for d in dirs.values():  # no stale predictions from an earlier run in the means
        shutil.rmtree(d, ignore_errors=True)
    seconds, failed = [], {}
    for oid in ids:
        img = np.asarray(Image.open(args.split_dir / "images" / f"{oid}.png").convert("RGB"))
        mask = None
        if not args.no_mask:
            mask = np.asarray(Image.open(args.split_dir / "images" / f"{oid}.mask.png"))
        t0 = time.perf_counter()
        try:
            if args.voxels == "gt":
                run = gen.run(img, None, gt_occupancy(oid, gen.cfg.flow.max_parts))
            else:
                run = gen.run(img, mask)
            for name, S, source in variants:
                save_bundle(gen.assemble(run, {}, S, source), dirs[name] / oid)
        except Exception as e:  # record and go on
            failed[oid] = f"{type(e).__name__}: {e}"
            continue
        seconds.append(time.perf_counter() - t0)
    results = {}
    for name, _, _ in variants:
        res = evaluate_dirs(dirs[name], args.split_dir / "gt")
        results[name] = {k: res["mean"].get(k) for k in KEYS}
    out = {
        "voxels": args.voxels,
        "mask": not args.no_mask,
        "objects": len(ids),
        "generated": len(seconds),
        "seconds_per_object_median": float(np.median(seconds)) if seconds else None,
        "generator_version": gen.version,
        "stage1_candidates": args.candidates,
        "variants": results,
        "failed": failed,
    }
    print(json.dumps(out, indent=2))
    table = Table(title=f"PAct ablation ({args.voxels} voxels, {len(seconds)} objects)")
    table.add_column("variant")
    for k in KEYS:
        table.add_column(k, justify="right")
    for name, row in results.items():
        table.add_row(name, *(f"{row[k]:.4f}" if row[k] is not None else "-" for k in KEYS))
    Console(stderr=True).print(table)


if __name__ == "__main__":
    main()
