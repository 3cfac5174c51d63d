"""A trained policy, or the scripted teacher, on sets of held-out assets: success per set,
category and part kind, and the seconds an evaluation takes.

For each ``--assets NAME=FOLDER`` runs ``tasks.train.evaluate`` (what ``pact eval-policy``
runs) for ``--episodes`` episodes and prints JSON: per set the success rate, the grasp
rate, the tables per category and part kind (with how far the failures opened the part)
and the wall-clock seconds of the evaluation.

    python bench/policy_eval.py policies/OpenDrawer-v0/policy.zip --task OpenDrawer-v0 \
        --assets generated=HELD_OUT_GENERATED real=IMPORTED_PARTNET --episodes 50

With ``teacher`` in place of the policy, the scripted opening teacher (tasks.teacher)
runs as the policy, in the episodes the shipped policies are measured in (10 Hz
``pd_ee_delta_pos``, the task's length, episode k seeded ``--seed + k``, no action
noise): what a clone of it could reach at best.

    python bench/policy_eval.py teacher --task OpenDoor-v0 --assets realA=REAL_DEV \
        [--teacher-set door_pull=0.02]     # OpeningTeacher's fields set otherwise
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any


def run_teacher(
    task: str, assets: str, episodes: int, seed: int, settings: dict[str, float] | None = None
) -> dict[str, Any]:
    """``tasks.train.evaluate``'s figures for the scripted teacher (``settings``: fields of
    ``OpeningTeacher`` set otherwise than their defaults)."""
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
            teacher, done, info, held = OpeningTeacher(**(settings or {})), False, {}, False
            while not done:
                _, _, term, trunc, info = env.step(teacher(env))
                held = held or bool(info.get("is_grasped", False))
                done = term or trunc
            asset, part = env.unwrapped.episode_assets[0], env.unwrapped.episode_parts[0]
            rows.append(
                {
                    "category": asset.category or "unknown",
                    "part_kind": part.kind,
                    "success": bool(info.get("success", False)),
                    "grasped": held,
                    "open_fraction": round(float(info.get("open_fraction", 0.0)), 4),
                }
            )
    finally:
        env.close()
    return {
        "success_rate": float(np.mean([r["success"] for r in rows])),
        "grasp_rate": float(np.mean([r["grasped"] for r in rows])),
        "by_category": success_table(rows, "category"),
        "by_part_kind": success_table(rows, "part_kind"),
    }


def main() -> None:
    from tasks.teacher import OpeningTeacher
    from tasks.train import evaluate

    ap = argparse.ArgumentParser()
    ap.add_argument("policy", help="policy.zip written by pact train, or 'teacher'")
    ap.add_argument("--task", default="OpenDrawer-v0")
    ap.add_argument(
        "--assets", nargs="+", required=True, metavar="NAME=FOLDER", help="asset sets to run on"
    )
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--seed", type=int, default=10_000)
    ap.add_argument(
        "--teacher-set",
        nargs="+",
        default=[],
        metavar="FIELD=VALUE",
        help="with 'teacher': OpeningTeacher fields to set (e.g. door_pull=0.02)",
    )
    a = ap.parse_args()
    settings = {}
    for item in a.teacher_set:
        field, _, value = item.partition("=")
        try:
            if a.policy != "teacher" or field not in OpeningTeacher.__dataclass_fields__:
                raise ValueError
            settings[field] = type(getattr(OpeningTeacher, field))(value)
        except ValueError:
            raise SystemExit(
                f"--teacher-set {item!r}: expected FIELD=VALUE of OpeningTeacher"
            ) from None
    sets = {}
    for item in a.assets:
        name, _, folder = item.partition("=")
        if not folder:
            raise SystemExit(f"--assets {item!r}: expected NAME=FOLDER")
        t0 = time.time()
        if a.policy == "teacher":
            r = run_teacher(a.task, folder, a.episodes, a.seed, settings)
        else:
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
            {
                "bench": "policy_eval",
                "policy": a.policy,
                "task": a.task,
                **({"teacher_settings": settings} if settings else {}),
                "sets": sets,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
