"""The scripted opening teacher (tasks.teacher) run as a policy on sets of assets: what a
clone of it could reach at best. Success per set, category and part kind, as
bench/policy_eval.py prints them for a trained policy.

    python bench/teacher.py --task OpenDoor-v0 \
        --assets generated=HELD_OUT_GENERATED realA=REAL_DEV --episodes 60

Episodes as `pact eval-policy` runs them for the shipped policies: 10 Hz
``pd_ee_delta_pos``, the task's length (7.5 s doors, 5 s drawers), episode k seeded
``--seed + k``, no action noise.
"""

from __future__ import annotations

import argparse
import json
import time


def run_teacher(task: str, assets: str, episodes: int, seed: int) -> dict:
    import numpy as np

    from tasks.teacher import OpeningTeacher
    from tasks.train import eval_episode_steps, make_cpu_env, success_table

    env = make_cpu_env(
        task, assets, control_mode="pd_ee_delta_pos", sim_config={"control_freq": 10},
        **eval_episode_steps(task, None, 10),
    )  # fmt: skip
    rows = []
    try:
        for k in range(episodes):
            env.reset(seed=seed + k)
            teacher, done, info = OpeningTeacher(), False, {}
            while not done:
                _, _, term, trunc, info = env.step(teacher(env))
                done = term or trunc
            asset, part = env.unwrapped.episode_assets[0], env.unwrapped.episode_parts[0]
            rows.append(
                {
                    "asset": asset.id,
                    "category": asset.category or "unknown",
                    "part_kind": part.kind,
                    "success": bool(info.get("success", False)),
                    "open_fraction": round(float(info.get("open_fraction", 0.0)), 4),
                }
            )
    finally:
        env.close()
    return {
        "success_rate": round(float(np.mean([r["success"] for r in rows])), 4),
        "by_category": success_table(rows, "category"),
        "by_part_kind": success_table(rows, "part_kind"),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--task", default="OpenDoor-v0")
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
        sets[name] = {
            "assets": folder,
            "episodes": a.episodes,
            **run_teacher(a.task, folder, a.episodes, a.seed),
            "seconds": round(time.time() - t0, 1),
        }
    print(json.dumps({"bench": "teacher", "task": a.task, "sets": sets}, indent=2))


if __name__ == "__main__":
    main()
