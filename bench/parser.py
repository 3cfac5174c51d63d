"""The photo parser on real renders: category, part count, part-mask IoU, joint kinds.

    .venv/bin/python bench/parser.py [--split-dir /work/data/real_split] [--weights DIR]
        [--threads 1] [--limit N] [--given-mask] [--dev-half B] [--out result.json]
    .venv/bin/python bench/parser.py --split-dir /work/data/parser_data   # its val items

It runs ``generator.parser.PhotoParser`` on every image of a real split
(``generator.data.real_split`` layout) and prints JSON: per image-set (all, per
category, per style) the share of photos whose category is right, whose movable-part
count is right, the mean part IoU (predicted and true parts, base included, matched by
Hungarian on IoU; unmatched parts count 0), the share whose multiset of joint kinds of
the matched movable parts equals the truth's (``generator.motions.MOTION_KIND``), the
same with exact motions (left/right/bottom/top), and the parser's seconds per photo.
The truth's motions come from the ground-truth bundles (``generator.bundle.load_bundle``
then ``generator.motions.motion_of``); a true part is one whose id is in the image's
mask. ``--given-mask`` also measures ``PhotoParser.label`` on the true masks. Given
parser data (``docs/dataset.md``) it measures the ``val`` items: procedural objects
held out of training, where the parser's inference settings are chosen (never on the
real renders). ``--dev-half A|B`` keeps the objects of one half of the dev objects
(``policies/partnet_split.json``; half A may be trained on, half B never is).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from generator.motions import MOTION_KIND  # noqa: E402

# --------------------------------------------------------------------------- metrics


def truth(split_dir: Path, image: dict, cache: dict) -> tuple[np.ndarray, dict[int, str]]:
    """The true mask of an image and the motion of each movable id in it."""
    if "gt_motions" in image:  # a parser-data item: its hints hold the motions
        mask = np.asarray(Image.open(split_dir / "images" / f"{image['id']}.mask.png"))
        return mask, image["gt_motions"]
    from generator.bundle import load_bundle
    from generator.data.render import part_slots
    from generator.motions import motion_of

    oid = image["object"]
    if oid not in cache:
        obj = load_bundle(split_dir / "gt" / oid)
        cache[oid] = [motion_of(p) for p in part_slots(obj)[1:]]
    mask = np.asarray(Image.open(split_dir / "images" / f"{image['id']}.mask.png"))
    motions = {int(v): cache[oid][int(v) - 2] for v in np.unique(mask) if v >= 2}
    return mask, motions


def match(gt: np.ndarray, pred: np.ndarray) -> tuple[list[tuple[int, int, float]], int, int]:
    """Hungarian matching on IoU of the ids >= 1 of two masks: (gt id, pred id, IoU)
    pairs, and the numbers of gt and pred ids."""
    from scipy.optimize import linear_sum_assignment

    g_ids = [int(v) for v in np.unique(gt) if v >= 1]
    p_ids = [int(v) for v in np.unique(pred) if v >= 1]
    iou = np.zeros((len(g_ids), len(p_ids)))
    for i, g in enumerate(g_ids):
        gm = gt == g
        for j, p in enumerate(p_ids):
            pm = pred == p
            inter = np.logical_and(gm, pm).sum()
            if inter:
                iou[i, j] = inter / np.logical_or(gm, pm).sum()
    rows, cols = linear_sum_assignment(-iou) if iou.size else ([], [])
    pairs = [(g_ids[r], p_ids[c], float(iou[r, c])) for r, c in zip(rows, cols, strict=True)]
    return pairs, len(g_ids), len(p_ids)


def score_image(gt_mask, gt_motion, gt_cat, parsed) -> dict:  # noqa: ANN001
    pred_motion = {p.id: p.motion for p in parsed.parts}
    pairs, ng, npred = match(gt_mask, parsed.mask)
    matched = {g: p for g, p, iou in pairs if iou > 0}
    mean_iou = sum(iou for _, _, iou in pairs) / max(ng, npred, 1)

    def multisets(name_of):  # noqa: ANN001, ANN202
        want = Counter(name_of(m) for m in gt_motion.values())
        got = Counter(
            name_of(pred_motion[matched[g]]) if matched.get(g) in pred_motion else "none"
            for g in gt_motion
        )
        extra = len(pred_motion) - sum(1 for g in gt_motion if matched.get(g) in pred_motion)
        return want == got, want == got and extra == 0

    kinds, kinds_strict = multisets(lambda m: MOTION_KIND[m])
    motions, motions_strict = multisets(lambda m: m)
    return {
        "category": parsed.category == gt_cat,
        "count": len(pred_motion) == len(gt_motion),
        "iou": mean_iou,
        "kinds": kinds,
        "kinds_strict": kinds_strict,
        "motions": motions,
        "motions_strict": motions_strict,
        "seconds": parsed.seconds,
        "pred_category": parsed.category,
        "pred_parts": len(pred_motion),
        "true_parts": len(gt_motion),
    }


def label_score(gt_mask, gt_motion, gt_cat, labelled) -> dict:  # noqa: ANN001
    got = {p.id: p.motion for p in labelled.parts}
    ok = [got.get(g) == m for g, m in gt_motion.items()]
    ok_kind = [MOTION_KIND.get(got.get(g, ""), "") == MOTION_KIND[m] for g, m in gt_motion.items()]
    return {
        "category": labelled.category == gt_cat,
        "part_motion": ok,
        "part_kind": ok_kind,
        "motions": all(ok),
        "kinds": all(ok_kind),
    }


def _colour(mask: np.ndarray) -> np.ndarray:
    palette = np.array(
        [
            [0, 0, 0],
            [70, 110, 170],
            [120, 220, 90],
            [180, 80, 250],
            [240, 190, 170],
            [50, 40, 90],
            [110, 160, 250],
            [250, 120, 60],
            [250, 230, 60],
            [60, 200, 200],
        ],
        np.uint8,
    )
    return palette[np.minimum(mask, len(palette) - 1)]


def dump(folder: Path, image_id: str, rgb: np.ndarray, gt: np.ndarray, pred: np.ndarray) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    row = np.concatenate([rgb, _colour(gt), _colour(pred)], 1)
    Image.fromarray(row).save(folder / f"{image_id}.png")


def summarize(rows: list[dict]) -> dict:
    keys = ("category", "count", "iou", "kinds", "kinds_strict", "motions", "motions_strict")
    out = {"images": len(rows)}
    for k in keys:
        if rows and k in rows[0]:
            out[k] = round(float(np.mean([r[k] for r in rows])), 4)
    by_obj = defaultdict(list)
    for r in rows:
        by_obj[r["object"]].append(r)
    out["objects"] = len(by_obj)
    if rows and "kinds" in rows[0]:
        out["objects_kinds_all_views"] = round(
            float(np.mean([all(r["kinds"] for r in v) for v in by_obj.values()])), 4
        )
    if rows and "part_motion" in rows[0]:
        pm = [x for r in rows for x in r["part_motion"]]
        pk = [x for r in rows for x in r["part_kind"]]
        out["part_motion"] = round(float(np.mean(pm)), 4) if pm else None
        out["part_kind"] = round(float(np.mean(pk)), 4) if pk else None
    return out


def groups(rows: list[dict]) -> dict:
    res = {"all": summarize(rows)}
    for key in ("category", "style"):
        vals = sorted({r["true_" + key] for r in rows})
        res["by_" + key] = {v: summarize([r for r in rows if r["true_" + key] == v]) for v in vals}
    return res


def split_images(split_dir: Path) -> list[dict]:
    """The images of a real split (``manifest.json`` ``images``), or the ``val`` items of
    parser data (``pact.parser_data``: procedural objects the parser never trained on),
    each with ``id``, ``object``, ``category``, ``style``."""
    manifest = json.loads((split_dir / "manifest.json").read_text())
    if manifest.get("schema") != "pact.parser_data":
        return manifest["images"]
    out = []
    for item in manifest["items"]:
        if item["split"] != "val":
            continue
        hints = json.loads((split_dir / "images" / f"{item['id']}.json").read_text())
        motions = {int(k): v["motion"] for k, v in hints["parts"].items()}
        out.append({**item, "gt_motions": motions})
    return out


def run(args: argparse.Namespace) -> dict:
    import torch

    from generator.parser import PhotoParser

    torch.set_num_threads(args.threads)
    parser = PhotoParser.from_dir(args.weights) if args.weights else PhotoParser.default()
    images = split_images(args.split_dir)
    if args.dev_half:
        from generator.data.real_split import dev_half

        keep = set(dev_half(args.dev_half))
        images = [im for im in images if im["object"] in keep]
    images = images[: args.limit] if args.limit else images
    cache: dict = {}
    rows, label_rows, confusion = [], [], Counter()
    parser.parse(np.zeros((64, 64, 3), np.uint8))  # warm-up
    for im in images:
        rgb = np.asarray(Image.open(args.split_dir / "images" / f"{im['id']}.png").convert("RGB"))
        gt_mask, gt_motion = truth(args.split_dir, im, cache)
        meta = {
            "id": im["id"],
            "object": im["object"],
            "true_category": im["category"],
            "true_style": im["style"],
        }
        parsed = parser.parse(rgb)
        r = {**meta, **score_image(gt_mask, gt_motion, im["category"], parsed)}
        r["pred_motions"] = sorted(p.motion for p in parsed.parts)
        r["true_motions"] = sorted(gt_motion.values())
        rows.append(r)
        if args.dump:
            dump(args.dump, im["id"], rgb, gt_mask, parsed.mask)
        confusion[(im["category"], parsed.category)] += 1
        if args.given_mask:
            label_rows.append(
                {
                    **meta,
                    **label_score(gt_mask, gt_motion, im["category"], parser.label(rgb, gt_mask)),
                }
            )
    secs = [r["seconds"] for r in rows]
    result = {
        "split_dir": str(args.split_dir),
        "weights": str(args.weights or "shipped"),
        "dev_half": args.dev_half,
        "photos": len(rows),
        "threads": args.threads,
        "parse": groups(rows),
        "seconds_per_photo": {
            "mean": round(float(np.mean(secs)), 4),
            "median": round(float(np.median(secs)), 4),
            "max": round(float(np.max(secs)), 4),
        },
        "category_confusion": {f"{a}->{b}": n for (a, b), n in sorted(confusion.items())},
    }
    if label_rows:
        result["label_given_mask"] = groups(label_rows)
    if args.per_image:
        result["images"] = [{k: v for k, v in r.items() if k != "seconds"} for r in rows]
    return result


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--split-dir", type=Path, default=Path("/work/data/real_split"))
    ap.add_argument(
        "--weights", type=Path, default=None, help="a weights folder (default: shipped)"
    )
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument(
        "--given-mask", action="store_true", help="also PhotoParser.label on the true masks"
    )
    ap.add_argument("--dev-half", choices=["A", "B"], default=None, help="only this half's objects")
    ap.add_argument("--per-image", action="store_true")
    ap.add_argument("--dump", type=Path, default=None, help="write photo | truth | parse PNGs here")
    ap.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    a = ap.parse_args(argv)
    result = run(a)
    text = json.dumps(result, indent=1)
    if a.out:
        a.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
