"""Benchmark validation over a batch of procedural assets; prints JSON.

Object k of the batch is category ``CATEGORIES[k % len(CATEGORIES)]`` with seed
``seed + k // len(CATEGORIES)`` (so ``--n 70`` is 10 seeds of every category). Each
is sampled, built into a temporary folder and validated with repairs. Figures:
seconds per asset for building and for each validation stage (summed over
repair rounds), and the pass rate before repair (first round) and after.

    .venv/bin/python bench/validate.py --n 70 --seed 0
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=14, help="How many assets.")
    ap.add_argument("--seed", type=int, default=0, help="First seed.")
    ap.add_argument("--preview", action="store_true", help="Also render preview.png (timed).")
    ap.add_argument("--keep", type=Path, default=None, help="Build into this folder and keep it.")
    args = ap.parse_args()

    from asset_pipeline.assets.build import build_asset
    from asset_pipeline.validate import STAGES, validate_asset
    from generator.bundle import save_bundle
    from generator.procedural import CATEGORIES, sample_object

    cats = list(CATEGORIES)
    stages = [*STAGES, "repair", "preview"]
    times: dict[str, list[float]] = {s: [] for s in ["build", *stages, "validate_total"]}
    before = after = 0
    statuses: Counter[str] = Counter()
    repairs: Counter[str] = Counter()
    failures = []
    per_category: dict[str, Counter[str]] = {}
    with tempfile.TemporaryDirectory(prefix="pact-bench-validate-") as tmp:
        root = args.keep or Path(tmp)
        for k in range(args.n):
            cat = cats[k % len(cats)]
            seed = args.seed + k // len(cats)
            d = root / f"{cat}_{seed:04d}"
            t = time.perf_counter()
            save_bundle(sample_object(cat, seed), d)
            build_asset(d)
            times["build"].append(time.perf_counter() - t)
            t = time.perf_counter()
            report = validate_asset(d, repair=True, preview=args.preview)
            times["validate_total"].append(time.perf_counter() - t)
            for s in stages:
                times[s].append(report.timings.get(s, 0.0))
            first_ok = not report.rounds[0]["failed"]
            before += first_ok
            after += report.ok
            statuses[report.status] += 1
            per_category.setdefault(cat, Counter())[report.status] += 1
            repairs.update(r.kind for r in report.repairs)
            if not report.ok:
                failures.append({"asset": d.name, "reasons": report.reasons[:5]})
    n = max(args.n, 1)
    out = {
        "n": args.n,
        "seed": args.seed,
        "categories": cats,
        "seconds_per_asset": {
            s: {
                "mean": round(statistics.fmean(v), 4),
                "max": round(max(v), 4),
            }
            for s, v in times.items()
            if v
        },
        "pass_rate_before_repair": round(before / n, 4),
        "pass_rate_after_repair": round(after / n, 4),
        "status": dict(statuses),
        "status_per_category": {c: dict(v) for c, v in per_category.items()},
        "repairs": dict(repairs),
        "failures": failures,
    }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
