"""A trained policy on sets of held-out assets: success per set, category and part kind,
and the seconds an evaluation takes.

For each ``--assets NAME=FOLDER`` runs ``tasks.train.evaluate`` (what ``pact eval-policy``
runs) for ``--episodes`` episodes and prints JSON: per set the success rate, the grasp
rate, the tables per category and part kind (with how far the failures opened the part)
and the wall-clock seconds of the evaluation.

    python bench/policy_eval.py policies/OpenDrawer-v0/policy.zip --task OpenDrawer-v0 \
        --assets generated=HELD_OUT_GENERATED real=IMPORTED_PARTNET --episodes 50
"""

from __future__ import annotations

import argparse
import json
import time


def main() -> None:
    from tasks.train import evaluate

    ap = argparse.ArgumentParser()
    ap.add_argument("policy", help="policy.zip written by pact train")
    ap.add_argument("--task", default="OpenDrawer-v0")
    ap.add_argument(
        "--assets", nargs="+", required=True, metavar="NAME=FOLDER", help="asset sets to run on"
    )
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--seed", type=int, default=10_000)
    a = ap.parse_args()
    sets = {}
    for item in a.assets:
        name, _, folder = item.partition("=")
        if not folder:
            raise SystemExit(f"--assets {item!r}: expected NAME=FOLDER")
        t0 = time.time()
        r = evaluate(a.policy, a.task, folder, episodes=a.episodes, seed=a.seed)
        sets[name] = {
            "assets": folder,
            "episodes": a.episodes,
            "success_rate": round(r["success_rate"], 4),
            "grasp_rate": round(r["grasp_rate"], 4),
            "by_category": r["by_category"],
            "by_part_kind": r["by_part_kind"],
            "seconds": round(time.time() - t0, 1),
        }
    print(
        json.dumps(
            {"bench": "policy_eval", "policy": a.policy, "task": a.task, "sets": sets}, indent=2
        )
    )


if __name__ == "__main__":
    main()
