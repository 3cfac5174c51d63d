"""Scripted-solver success on fresh procedural assets: which parts a Panda really opens.

Builds ``--n`` procedural objects of every category starting at each seed in
``--seeds`` (test-split parameter ranges by default: seeds and shapes nobody tuned the
solver on), runs ``tasks.solver.check_tasks`` on every movable part and prints JSON:
opened / parts overall, per category and per joint type, seconds per part, and the
failed parts with their final open fraction.

    python bench/solver.py                       # seeds 100-104 and 200-204, all categories
    python bench/solver.py --seeds 300 --n 2 --categories cabinet oven
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    from sim import build_procedural

    from generator.procedural import CATEGORIES
    from tasks.solver import check_tasks, summarize

    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="runs/bench_solver")
    ap.add_argument("--seeds", type=int, nargs="+", default=[100, 200])
    ap.add_argument("--n", type=int, default=5, help="objects per category and seed start")
    ap.add_argument("--categories", nargs="+", default=list(CATEGORIES))
    ap.add_argument("--split", default="train", help="parameter ranges: train or test")
    a = ap.parse_args()
    out = Path(a.out) / "assets"
    t0 = time.perf_counter()
    for s in a.seeds:
        build_procedural(out, tuple(a.categories), n=a.n, split=a.split, seed0=s)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    results = check_tasks(out)
    t_check = time.perf_counter() - t0
    by: dict[str, list[int]] = defaultdict(lambda: [0, 0])
    for r in results:
        category = r.asset_id.rsplit("_", 1)[0]
        for key in (category, r.joint_type):
            by[key][0] += int(r.success)
            by[key][1] += 1
    summary = summarize(results)
    print(
        json.dumps(
            {
                "bench": "solver",
                "seeds": a.seeds,
                "per_category_and_seed": a.n,
                "split": a.split,
                "parts": len(results),
                "opened": summary["opened"],
                "rate": round(summary["rate"], 4),
                # opened where the env placed the robot (no further stand)
                "opened_where_placed": summary["opened_where_placed"],
                "by": {k: f"{v[0]}/{v[1]}" for k, v in sorted(by.items())},
                "seconds_per_part": round(t_check / max(1, len(results)), 2),
                "build_seconds": round(t_build, 1),
                "failed": [
                    {
                        "asset": r.asset_id,
                        "part": r.part,
                        "final_fraction": round(r.final_fraction, 3),
                        "reason": r.reason,
                    }
                    for r in results
                    if not r.success
                ],
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
