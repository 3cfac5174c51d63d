"""SAM2's automatic masks on CPU: seconds per photo and regions per photo.

    .venv/bin/python bench/sam2_segmenter.py [--checkpoint FILE [--config NAME]]
        [--photos DIR] [--limit N] [--long-side 1024] [--points-per-side 32] [--max-side 1024]
        [--no-filter] [--image-size N] [--threads N] [--out result.json]

Runs ``generator.parser.sam2_segmenter.Sam2Segmenter.regions`` on the photos of a folder
(default: the bundled examples, ``examples/images``, resized so that their long side is
``--long-side`` px) and prints JSON: the model, the settings, the seconds to load it, and
per photo the seconds (wall clock, and CPU time summed over torch's threads: on a shared
machine the second is the steadier figure) and the number of regions, with their means.

Without ``--checkpoint`` the model is SAM 2.1 hiera-tiny (``sam2.1_hiera_t``) with random
weights (seed 0), saved to a temporary checkpoint first: its masks mean nothing, its
seconds are the cost of the tiny model. A random model's masks mostly fail SAM2's quality
filters, which skips the work on kept masks; ``--no-filter`` sets both thresholds to 0 so
that every mask is kept (an upper bound on that work). Needs the optional ``sam2``
package (``pip install sam2==1.1.0``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from generator.parser.sam2_segmenter import (  # noqa: E402
    DEFAULT_CONFIG,
    Sam2Segmenter,
    Sam2Settings,
    config_file,
    import_sam2,
)

PHOTO_SUFFIXES = {".png", ".jpg", ".jpeg", ".webp", ".bmp", ".tif", ".tiff"}


def load_photos(folder: Path, limit: int, long_side: int | None) -> list[tuple[str, np.ndarray]]:
    paths = sorted(
        p
        for p in folder.iterdir()
        if p.suffix.lower() in PHOTO_SUFFIXES and not p.name.endswith(".mask.png")
    )[:limit]
    photos = []
    for p in paths:
        im = Image.open(p).convert("RGB")
        if long_side:
            scale = long_side / max(im.size)
            im = im.resize((round(im.width * scale), round(im.height * scale)), Image.BICUBIC)
        photos.append((p.name, np.asarray(im)))
    return photos


def random_checkpoint(config: str, image_size: int | None, folder: Path) -> Path:
    """A checkpoint of ``config`` with random weights (seed 0), in Meta's layout."""
    import torch

    sam2 = import_sam2()
    torch.manual_seed(0)
    overrides = [] if image_size is None else [f"++model.image_size={image_size}"]
    model = sam2.build_sam.build_sam2(
        config_file(config), ckpt_path=None, device="cpu", hydra_overrides_extra=overrides
    )
    path = folder / f"random_{config}.pt"
    torch.save({"model": model.state_dict()}, path)
    return path


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checkpoint", type=Path, help="default: a random sam2.1_hiera_t")
    ap.add_argument("--config", help="default: from the checkpoint's name, else sam2.1_hiera_t")
    ap.add_argument("--photos", type=Path, default=ROOT / "examples" / "images")
    ap.add_argument("--limit", type=int, default=8)
    ap.add_argument("--long-side", type=int, default=1024, help="0 keeps the photos' size")
    ap.add_argument("--points-per-side", type=int, default=Sam2Settings.points_per_side)
    ap.add_argument("--max-side", type=int, default=Sam2Settings.max_side)
    ap.add_argument("--no-filter", action="store_true", help="keep every mask SAM2 makes")
    ap.add_argument("--image-size", type=int, help="the model's input side (default 1024)")
    ap.add_argument("--threads", type=int, help="torch threads (default: torch's choice)")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)

    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    settings = Sam2Settings(points_per_side=args.points_per_side, max_side=args.max_side)
    if args.no_filter:
        settings.pred_iou_thresh = settings.stability_score_thresh = 0.0
    photos = load_photos(args.photos, args.limit, args.long_side or None)
    if not photos:
        sys.exit(f"no photos in {args.photos}")

    with tempfile.TemporaryDirectory() as tmp:
        checkpoint = args.checkpoint
        random_model = checkpoint is None
        config = args.config or (DEFAULT_CONFIG if random_model else None)
        if random_model:
            checkpoint = random_checkpoint(config, args.image_size, Path(tmp))
        t0 = time.perf_counter()
        seg = Sam2Segmenter.from_checkpoint(
            checkpoint, config, "cpu", settings=settings, image_size=args.image_size
        )
        load_seconds = time.perf_counter() - t0
        seg.regions(photos[0][1][:64, :64].copy())  # warm-up (first-call allocations)
        per_photo = []
        for name, image in photos:
            t, c = time.perf_counter(), time.process_time()
            regions = seg.regions(image)
            per_photo.append(
                {
                    "photo": name,
                    "size": list(image.shape[:2]),
                    "seconds": round(time.perf_counter() - t, 3),
                    "cpu_seconds": round(time.process_time() - c, 3),
                    "regions": len(regions),
                }
            )

    seconds = [p["seconds"] for p in per_photo]
    result = {
        "model": f"random {config} (seed 0)" if random_model else str(checkpoint),
        "config": seg.config,
        "image_size": int(seg.model.image_size),
        "device": "cpu",
        "torch_threads": torch.get_num_threads(),
        "settings": dataclasses.asdict(settings),
        "load_seconds": round(load_seconds, 2),
        "photos": len(per_photo),
        "seconds_per_photo": round(float(np.mean(seconds)), 3),
        "seconds_per_photo_max": round(float(np.max(seconds)), 3),
        "cpu_seconds_per_photo": round(float(np.mean([p["cpu_seconds"] for p in per_photo])), 3),
        "regions_per_photo": round(float(np.mean([p["regions"] for p in per_photo])), 2),
        "per_photo": per_photo,
    }
    text = json.dumps(result, indent=1)
    if args.out:
        args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
