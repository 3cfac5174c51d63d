"""Benchmark dataset building on these CPUs; prints JSON.

    python bench/dataset.py --n 14 --views 8

Figures: rendered views per second (SAPIEN camera only: pose, render, read back,
composite), objects per minute for the whole build (generation, rendering,
occupancy, surface samples, compressed shards), and the bytes stored per object.
The first render of a process compiles shaders (10-20 s on lavapipe); it is done
before timing and reported separately as ``warmup_s``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=14, help="objects to build")
    ap.add_argument("--views", type=int, default=8, help="views per object")
    ap.add_argument("--image-size", type=int, default=256)
    ap.add_argument("--resolution", type=int, default=32)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    from generator.data import build_dataset
    from generator.data.render import ObjectRenderer, sample_view
    from generator.procedural import CATEGORIES, sample_object

    t0 = time.perf_counter()
    warm = sample_object(CATEGORIES[0], 10**6, "train")
    with ObjectRenderer(warm, args.image_size, np.random.default_rng(0)) as r:
        r.render(sample_view(warm, np.random.default_rng(0), args.image_size))
    warmup = time.perf_counter() - t0

    # rendering alone
    objects = [
        sample_object(CATEGORIES[i % len(CATEGORIES)], args.seed + i, "train")
        for i in range(args.n)
    ]
    rng = np.random.default_rng(args.seed)
    views = [[sample_view(o, rng, args.image_size) for _ in range(args.views)] for o in objects]
    t0 = time.perf_counter()
    for obj, vs in zip(objects, views, strict=True):
        with ObjectRenderer(obj, args.image_size, rng) as r:
            for v in vs:
                r.render(v)
    render_s = time.perf_counter() - t0

    # the whole build
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "ds"
        t0 = time.perf_counter()
        build_dataset(
            out,
            args.n,
            args.views,
            args.seed,
            resolution=args.resolution,
            image_size=args.image_size,
            progress=False,
        )
        build_s = time.perf_counter() - t0
        stored = sum(p.stat().st_size for p in out.glob("shard_*.npz"))

    print(
        json.dumps(
            {
                "n": args.n,
                "views": args.views,
                "image_size": args.image_size,
                "resolution": args.resolution,
                "warmup_s": round(warmup, 2),
                "render_views_per_s": round(args.n * args.views / render_s, 1),
                "build_objects_per_min": round(args.n / build_s * 60, 1),
                "build_views_per_s": round(args.n * args.views / build_s, 1),
                "build_s": round(build_s, 2),
                "bytes_per_object": int(stored / max(args.n, 1)),
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
