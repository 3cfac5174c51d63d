"""Benchmark the photo parser's training data on these CPUs; prints JSON, writes a montage.

    python bench/parser_data.py --objects 24 --views 4 [--montage parser_data_montage.png]

Figures: images per second and objects per minute for the whole writer (objects,
scenery, rendering, degradations, PNG files, manifest), bytes per image (photo, mask
and hints), and the counts per category, motion (visible parts), style and split of
the run. The first render of a process compiles shaders (10-20 s on lavapipe); it is
done before timing and reported as ``warmup_s``.

The montage (not committed) puts the run's photos (left) beside renders of real
PartNet-Mobility objects of the real dev split (right, ``generator.data.real_split``,
product and room styles), to judge by eye whether the procedural photos look alike.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw


def _montage(
    left: list[Path], right: list[Path], path: Path, cols: int = 6, tile: int = 192
) -> None:
    """Two panels of ``cols`` columns: ``left`` images beside ``right`` images."""
    rows = max((len(left) + cols - 1) // cols, (len(right) + cols - 1) // cols, 1)
    pad, head = 24, 28
    width = 2 * cols * tile + pad
    canvas = Image.new("RGB", (width, head + rows * tile), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    draw.text((8, 8), "procedural parser data (this run)", fill=(0, 0, 0))
    draw.text((cols * tile + pad + 8, 8), "real split: PartNet-Mobility renders", fill=(0, 0, 0))
    for panel, files in enumerate((left, right)):
        x0 = panel * (cols * tile + pad)
        for k, f in enumerate(files[: rows * cols]):
            img = Image.open(f).convert("RGB").resize((tile, tile), Image.BILINEAR)
            canvas.paste(img, (x0 + (k % cols) * tile, head + (k // cols) * tile))
    canvas.save(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=24, help="objects to write")
    ap.add_argument("--views", type=int, default=4, help="photos per object")
    ap.add_argument("--image-size", type=int, default=256)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument(
        "--out", type=Path, default=None, help="keep the data here (default: a temp dir)"
    )
    ap.add_argument("--montage", type=Path, default=Path("parser_data_montage.png"))
    ap.add_argument(
        "--real", type=Path, default=None, help="real split folder (default: PACT_REAL_SPLIT)"
    )
    args = ap.parse_args()

    from generator.data.parser_data import plan_object, render_parser_views, write_parser_data
    from generator.data.real_split import DEFAULT_REAL_SPLIT
    from generator.procedural.realistic import sample_realistic_object

    t0 = time.perf_counter()
    warm = plan_object(args.seed + 1, 0)
    list(
        render_parser_views(
            sample_realistic_object(warm.category, warm.seed), warm.id, 1, args.image_size, 0
        )
    )
    warmup = time.perf_counter() - t0

    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp) / "parser_data"
        t0 = time.perf_counter()
        manifest = write_parser_data(out, args.objects, args.views, args.seed, args.image_size)
        seconds = time.perf_counter() - t0
        items = manifest["items"]
        files = [
            out / "images" / f"{it['id']}{ext}"
            for it in items
            for ext in (".png", ".mask.png", ".json")
        ]
        stored = sum(f.stat().st_size for f in files)
        motions: Counter[str] = Counter()
        for it in items:
            hints = json.loads((out / "images" / f"{it['id']}.json").read_text())
            motions.update(p["motion"] for p in hints["parts"].values())
        real_dir = args.real or DEFAULT_REAL_SPLIT
        real = sorted((real_dir / "images").glob("*_product_*.png")) + sorted(
            (real_dir / "images").glob("*_room_*.png")
        )
        real = [f for f in real if not f.name.endswith(".mask.png")]
        rng = np.random.default_rng(0)
        # one photo per object (view k = object number mod views), up to 36
        by_object: dict[str, list[dict]] = {}
        for it in items:
            by_object.setdefault(it["object"], []).append(it)
        picks = [views[i % len(views)] for i, views in enumerate(by_object.values())][:36]
        shown = [out / "images" / f"{it['id']}.png" for it in picks]
        real_shown = [real[i] for i in rng.permutation(len(real))[: len(shown)]] if real else []
        _montage(shown, real_shown, args.montage)

    n_img = len(items)
    print(
        json.dumps(
            {
                "objects": args.objects,
                "views": args.views,
                "image_size": args.image_size,
                "warmup_s": round(warmup, 2),
                "seconds": round(seconds, 1),
                "images_per_s": round(n_img / seconds, 2),
                "objects_per_min": round(60 * args.objects / seconds, 1),
                "bytes_per_image": int(stored / max(n_img, 1)),
                "images": n_img,
                "failed": len(manifest["failed"]),
                "categories": dict(Counter(it["category"] for it in items)),
                "motions": dict(motions),
                "styles": dict(Counter(it["style"] for it in items)),
                "splits": dict(Counter(it["split"] for it in items)),
                "montage": str(args.montage),
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
