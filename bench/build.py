"""Sample and build timings (issue 2). Prints JSON.

    .venv/bin/python bench/build.py [--repeats 10]

- sample_seconds / build_seconds: median over ``repeats`` objects per category
  (build without validation: mesh, collision, URDF, MJCF, asset.json);
- decomposition: exact boxes versus CoACD (threshold 0.05) for the same part (the
  carcass of a cabinet), and the cached CoACD re-run.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

from asset_pipeline.assets.build import build_asset
from asset_pipeline.geometry.coacd_collision import CoacdParams, coacd_pieces, primitive_pieces
from asset_pipeline.geometry.metric import to_metric
from generator.bundle import save_bundle
from generator.procedural import CATEGORIES, object_id, sample_object


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=10)
    args = ap.parse_args()
    out: dict = {"repeats": args.repeats, "per_category": {}}
    with tempfile.TemporaryDirectory() as tmp:
        sample_all, build_all = [], []
        for cat in CATEGORIES:
            s_times, b_times = [], []
            for seed in range(args.repeats):
                t0 = time.perf_counter()
                obj = sample_object(cat, 1000 + seed)
                s_times.append(time.perf_counter() - t0)
                d = save_bundle(obj, Path(tmp) / object_id(cat, 1000 + seed))
                t0 = time.perf_counter()
                build_asset(d)
                b_times.append(time.perf_counter() - t0)
            out["per_category"][cat] = {
                "sample_seconds_median": statistics.median(s_times),
                "build_seconds_median": statistics.median(b_times),
            }
            sample_all += s_times
            build_all += b_times
        out["sample_seconds_median"] = statistics.median(sample_all)
        out["build_seconds_median"] = statistics.median(build_all)

        base = to_metric(sample_object("cabinet", 7)).base
        t0 = time.perf_counter()
        boxes = primitive_pieces(base.primitives)
        exact = time.perf_counter() - t0
        cache = Path(tmp) / "coacd-cache"
        params = CoacdParams(threshold=0.05)
        t0 = time.perf_counter()
        hulls = coacd_pieces(base.mesh, params, cache_dir=cache)
        coacd_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        coacd_pieces(base.mesh, params, cache_dir=cache)
        cached = time.perf_counter() - t0
        out["decomposition"] = {
            "part": "cabinet seed 7 base carcass",
            "exact_boxes_seconds": exact,
            "exact_boxes_pieces": len(boxes),
            "coacd_seconds": coacd_s,
            "coacd_pieces": len(hulls),
            "coacd_cached_rerun_seconds": cached,
        }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
