"""Benchmark PAct stage 1 on the held-out test split against the retrieval baseline.

    python bench/stage1.py [--weights generator/pact/weights/small] [--split runs/test_split]

Writes the test split first when missing (``generator.data.test_split``, 6 objects per
category, deterministic). Ground-truth part occupancies are the GT bundles' rest part
meshes voxelized in the normalized frame exactly as the training set does
(``generator.data.geometry.occupancy``, slot order base first). Prints JSON:

- ``vae``: reconstruction IoU of the GT part grids through the VAE (posterior mean),
  pooled over voxels (``iou``) and the mean per part (``part_iou``);
- per method (``stage1_mask``: stage 1 with the GT part mask; ``stage1_nomask``: image
  only; ``retrieval``: ``RetrievalGenerator.default()`` with the mask):
  ``part_iou`` mean voxel IoU of matched parts (Hungarian on voxel IoU, base included),
  ``part_iou_penalized`` the same with every unmatched part (either side) scoring 0,
  ``object_iou`` IoU of the union of all parts, ``part_count_acc`` share of objects with
  the GT number of parts, RS-dgIoU / AS-dgIoU / RS-dCD (``generator.metrics``), and
  ``seconds`` per object (retrieval), ``seconds_batched`` (stage 1: sampling time of a
  batch of ``--batch`` objects / batch size, 2 threads), and
  ``stage1_seconds_per_object_batch1``: sampling one object alone.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np
import torch
from PIL import Image
from scipy.optimize import linear_sum_assignment

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from generator.articulated import ArticulatedObject  # noqa: E402
from generator.bundle import load_bundle  # noqa: E402
from generator.data.geometry import occupancy  # noqa: E402
from generator.data.render import part_slots  # noqa: E402
from generator.metrics import evaluate_pair, normalization  # noqa: E402

R = 32


def part_grids(obj: ArticulatedObject) -> np.ndarray:
    """(K, R, R, R) rest occupancy of each part (slot order) in the normalized frame."""
    norm = normalization(obj)
    grids = []
    for p in part_slots(obj):
        m = p.posed_mesh(p.joint.lower if p.joint is not None else 0.0)
        m.apply_transform(norm)
        grids.append(occupancy(m, R))
    return np.stack(grids)


def voxel_iou(a: np.ndarray, b: np.ndarray) -> float:
    union = (a | b).sum()
    return float((a & b).sum() / union) if union else 1.0


def part_scores(pred: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    """pred (P, R, R, R), gt (G, R, R, R) bool part grids -> matched voxel IoUs."""
    if len(pred) == 0:
        return {"part_iou": 0.0, "part_iou_penalized": 0.0, "object_iou": 0.0}
    ious = np.array([[voxel_iou(p, g) for g in gt] for p in pred])  # (P, G)
    rows, cols = linear_sum_assignment(-ious)
    matched = ious[rows, cols]
    return {
        "part_iou": float(matched.mean()),
        "part_iou_penalized": float(matched.sum() / max(len(pred), len(gt))),
        "object_iou": voxel_iou(pred.any(0), gt.any(0)),
    }


def _mean(rows: list[dict[str, float]]) -> dict[str, float]:
    keys = [k for k in rows[0] if isinstance(rows[0][k], (int, float))]
    return {k: float(np.nanmean([r[k] for r in rows])) for k in keys} | {"count": len(rows)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--weights", default=str(ROOT / "generator/pact/weights/small"))
    ap.add_argument("--split", default=str(ROOT / "runs/test_split"))
    ap.add_argument("--per-category", type=int, default=6)
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-retrieval", action="store_true")
    ap.add_argument("--batch", type=int, default=14, help="objects sampled together")
    ap.add_argument("--latency-objects", type=int, default=2, help="timed alone (batch 1)")
    ap.add_argument("--cfg-scale", type=float, default=None, help="default: the checkpoint's")
    ap.add_argument("--steps", type=int, default=None, help="default: the checkpoint's")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    torch.set_num_threads(args.threads)

    from generator.data.test_split import write_test_split
    from generator.pact.inference.stage1_generator import Stage1Generator

    split = Path(args.split)
    ids = write_test_split(split, per_category=args.per_category)[: args.limit]
    gen = Stage1Generator.load(args.weights)
    gen.sampler = dataclasses.replace(
        gen.sampler,
        **{
            k: v for k, v in (("cfg_scale", args.cfg_scale), ("steps", args.steps)) if v is not None
        },
    )
    methods = {"stage1_mask": [], "stage1_nomask": []}
    retrieval = None
    if not args.no_retrieval:
        from generator.retrieval import RetrievalGenerator

        retrieval = RetrievalGenerator.default()
        methods["retrieval"] = []
    vae_inter = vae_union = 0
    vae_parts = []
    vae = gen.models["vae"]
    gts, gt_grids, images, masks, hints = [], [], [], [], []
    for oid in ids:
        gt = load_bundle(split / "gt" / oid)
        gts.append(gt)
        gt_grids.append(part_grids(gt))  # (G, R, R, R)
        images.append(np.asarray(Image.open(split / "images" / f"{oid}.png").convert("RGB")))
        masks.append(np.asarray(Image.open(split / "images" / f"{oid}.mask.png")))
        hints.append(json.loads((split / "images" / f"{oid}.json").read_text()))
        with torch.no_grad():  # VAE reconstruction of the GT parts
            occ = torch.from_numpy(gt_grids[-1])[:, None].float()
            rec = (vae.decode(vae.encode(occ)[1]) > 0)[:, 0].numpy()
        vae_inter += int((rec & gt_grids[-1]).sum())
        vae_union += int((rec | gt_grids[-1]).sum())
        vae_parts += [voxel_iou(a, b) for a, b in zip(rec, gt_grids[-1], strict=True)]

    # latency of one object (batch 1), then the whole split in batches
    latency = []
    for i in range(min(args.latency_objects, len(ids))):
        t0 = time.perf_counter()
        gen.predict_parts(images[i], masks[i])
        latency.append(time.perf_counter() - t0)
    for name, use_mask in (("stage1_mask", True), ("stage1_nomask", False)):
        for b0 in range(0, len(ids), args.batch):
            sl = slice(b0, b0 + args.batch)
            t0 = time.perf_counter()
            occ_b, _ = gen.predict_parts_batch(images[sl], masks[sl] if use_mask else None)
            per_object = (time.perf_counter() - t0) / len(occ_b)
            for k, occ_pred in enumerate(occ_b):
                i = b0 + k
                used = occ_pred.reshape(len(occ_pred), -1).any(1)
                pred = occ_pred[used]
                obj = gen.assemble(occ_pred, images[i], masks[i] if use_mask else None, hints[i])
                metrics = evaluate_pair(obj, gts[i])
                row = part_scores(pred, gt_grids[i]) | {
                    "seconds_batched": per_object,
                    "part_count_acc": float(len(pred) == len(gt_grids[i])),
                }
                row |= {k: metrics[k] for k in ("RS-dgIoU", "AS-dgIoU", "RS-dCD")}
                methods[name].append(row)
            print(f"{name}: {min(b0 + args.batch, len(ids))}/{len(ids)}", file=sys.stderr)
    if retrieval is not None:
        for i in range(len(ids)):
            t0 = time.perf_counter()
            obj = retrieval.generate(images[i], masks[i], hints[i])
            seconds = time.perf_counter() - t0
            pred = part_grids(obj)
            metrics = evaluate_pair(obj, gts[i])
            row = part_scores(pred, gt_grids[i]) | {
                "seconds": seconds,
                "part_count_acc": float(len(pred) == len(gt_grids[i])),
            }
            row |= {k: metrics[k] for k in ("RS-dgIoU", "AS-dgIoU", "RS-dCD")}
            methods["retrieval"].append(row)

    out = {
        "split": str(split),
        "objects": len(ids),
        "weights": args.weights,
        "generator_version": gen.version,
        "threads": args.threads,
        "sampler": {"steps": gen.sampler.steps, "cfg_scale": gen.sampler.cfg_scale},
        "vae": {"iou": vae_inter / max(1, vae_union), "part_iou": float(np.mean(vae_parts))},
        "stage1_seconds_per_object_batch1": float(np.mean(latency)) if latency else None,
        **{k: _mean(v) for k, v in methods.items()},
    }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
