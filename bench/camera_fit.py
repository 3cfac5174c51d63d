"""How well the box camera fitted to a part mask finds the real dev split's cameras. Prints JSON.

    .venv/bin/python bench/camera_fit.py [--split-dir /work/data/real_split]
        [--styles product room] [--limit N]

For every image of the real dev split (``bench/real_split.py``; its manifest records the
camera's azimuth and elevation), ``generator.pact.inference.mask_layout.fit_box_camera`` fits the
box and camera to the image's part mask, with the ground truth's depth over width given
(so the figures are about the view, not the depth), twice: from the mask alone, and with
the photo's edges (``edges=edge_map(photo, silhouette)``). Reports per style and way the mean and median absolute
azimuth and elevation errors (degrees), the number of fits off by more than 15 degrees
of azimuth, the mean silhouette IoU and the seconds per fit, and the images whose
azimuth is off by more than 15 degrees.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
from PIL import Image

from generator.bundle import load_bundle
from generator.data.real_split import DEFAULT_REAL_SPLIT, read_manifest
from generator.pact.inference.mask_layout import edge_map, fit_box_camera

OFF_DEG = 15.0


def gt_depth_ratio(gt_dir: Path) -> float:
    """Depth over width (x extent over y extent) of a ground-truth bundle at rest."""
    obj = load_bundle(gt_dir)
    b = np.array([p.mesh.bounds for p in obj.parts])
    size = b[:, 1].max(axis=0) - b[:, 0].min(axis=0)
    return float(size[0] / size[1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--split-dir", type=Path, default=DEFAULT_REAL_SPLIT)
    ap.add_argument("--styles", nargs="*", default=None)
    ap.add_argument("--limit", type=int, default=None)
    args = ap.parse_args()
    manifest = read_manifest(args.split_dir)
    if not manifest:
        raise SystemExit(f"{args.split_dir}: no real split (run bench/real_split.py first)")
    images = [im for im in manifest["images"] if not args.styles or im["style"] in args.styles][
        : args.limit
    ]
    depths: dict[str, float] = {}
    rows = []
    for im in images:
        obj = im["object"]
        if obj not in depths:
            depths[obj] = gt_depth_ratio(args.split_dir / "gt" / obj)
        folder = args.split_dir / "images"
        mask = np.asarray(Image.open(folder / f"{im['id']}.mask.png"))
        photo = np.asarray(Image.open(folder / f"{im['id']}.png").convert("RGB"))
        movable = [int(i) for i in np.unique(mask) if i >= 2]
        if not movable:
            continue
        row = {"id": im["id"], "style": im["style"]}
        for way, image in (("mask", None), ("mask+photo", photo)):
            t = time.perf_counter()
            edges = None if image is None else edge_map(image, mask > 0)
            cam = fit_box_camera(mask, movable, depths[obj], edges=edges)
            row[way] = {
                "azimuth_error": abs(float(np.degrees(cam.azimuth)) - im["azimuth_deg"]),
                "elevation_error": abs(float(np.degrees(cam.elevation)) - im["elevation_deg"]),
                "iou": cam.iou,
                "seconds": time.perf_counter() - t,
            }
        rows.append(row)
    out: dict[str, dict] = {}
    for style in sorted({r["style"] for r in rows}):
        group = [r for r in rows if r["style"] == style]
        out[style] = {"images": len(group)}
        for way in ("mask", "mask+photo"):
            az = [r[way]["azimuth_error"] for r in group]
            el = [r[way]["elevation_error"] for r in group]
            out[style][way] = {
                "azimuth_error_mean": statistics.fmean(az),
                "azimuth_error_median": statistics.median(az),
                "elevation_error_mean": statistics.fmean(el),
                "elevation_error_median": statistics.median(el),
                f"azimuth_off_{OFF_DEG:g}": sum(a > OFF_DEG for a in az),
                "iou_mean": statistics.fmean(r[way]["iou"] for r in group),
                "seconds_per_fit_median": statistics.median(r[way]["seconds"] for r in group),
                "azimuth_off_images": [r["id"] for r in group if r[way]["azimuth_error"] > OFF_DEG],
            }
    print(json.dumps({"split_dir": str(args.split_dir), "per_style": out}, indent=2))


if __name__ == "__main__":
    main()
