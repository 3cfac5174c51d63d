"""PPO on 20 training drawers, success on 10 held-out drawers against wall-clock.

Writes ``OUT/curve.csv`` (timesteps, wall_seconds, success_rate, mean_return) and
``OUT/curve.png`` (matplotlib), prints JSON, including the final policy's success on
``--final-episodes`` held-out episodes (the curve's points use fewer, so they are
noisy). Train assets: procedural desks and cabinets of the train split; held-out: the
test split.

    python bench/rl.py --minutes 60 --num-envs 4 --out runs/bench_rl
    python bench/rl.py --total-timesteps 2000 --eval-every 1000 --n-train 2 --n-test 1   # smoke
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def by_kind(episodes: list[dict]) -> dict[str, str]:
    """Successes / episodes and grasped episodes per handle kind."""
    out: dict[str, list[int]] = {}
    for e in episodes:
        c = out.setdefault(e["handle_kind"], [0, 0, 0])
        c[0] += int(e["success"])
        c[1] += 1
        c[2] += int(e["grasped"])
    return {k: f"{s}/{n} opened, {g} grasped" for k, (s, n, g) in sorted(out.items())}


def _overrides(items: list[str]) -> dict:
    """``FIELD=VALUE`` strings as typed ``tasks.train.Args`` overrides, parsed by
    ``tasks.train.parse_args`` (booleans take true/false, lists comma-separated values,
    optional fields "none")."""
    from tasks.train import Args, parse_args

    argv, names = [], []
    for item in items:
        name, _, value = item.partition("=")
        if name not in Args.__dataclass_fields__ or not value:
            known = sorted(Args.__dataclass_fields__)
            raise SystemExit(f"--set {item!r}: expected FIELD=VALUE with FIELD one of {known}")
        flag = "--" + name.replace("_", "-")
        if isinstance(getattr(Args(), name), bool):
            on = value.lower() in ("1", "true", "yes", "on")
            argv.append(flag if on else "--no-" + flag[2:])
        else:
            argv += [flag, *value.split(",")]
        names.append(name)
    parsed = parse_args(argv)
    return {name: getattr(parsed, name) for name in names}


def main() -> None:
    from sim import build_procedural

    from tasks.train import Args, evaluate, plot_curve, train

    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="runs/bench_rl")
    ap.add_argument(
        "--n-train", type=int, default=10, help="per category (desk, cabinet): 2 x 10 = 20"
    )
    ap.add_argument("--n-test", type=int, default=5, help="per category: 2 x 5 = 10 held out")
    ap.add_argument("--total-timesteps", type=int, default=2_000_000)
    ap.add_argument(
        "--minutes", type=float, default=60.0, help="stop training after this wall-clock"
    )
    ap.add_argument("--num-envs", type=int, default=4)
    ap.add_argument("--vector", default="async", help="async (processes) or sync")
    ap.add_argument("--control-mode", default="pd_ee_delta_pos")
    ap.add_argument(
        "--near-start-prob",
        type=float,
        default=0.0,
        help="fraction of training episodes starting with the fingers around the handle",
    )
    ap.add_argument(
        "--require-grasp",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="dense reward: the grasp term only for a real grasp, not for a hook "
        "(default: tasks.train.Args, on)",
    )
    ap.add_argument(
        "--log-std-init",
        type=float,
        default=None,
        help="initial log std of the Gaussian policy (default: tasks.train.Args)",
    )
    ap.add_argument(
        "--set",
        nargs="+",
        default=[],
        metavar="FIELD=VALUE",
        help="override tasks.train.Args fields, e.g. --set learning_rate=1e-4 target_kl=0.05",
    )
    ap.add_argument("--eval-every", type=int, default=15_000)
    ap.add_argument("--eval-episodes", type=int, default=20)
    ap.add_argument(
        "--final-episodes",
        type=int,
        default=50,
        help="held-out episodes for the final policy (the curve's points use --eval-episodes)",
    )
    a = ap.parse_args()
    out = Path(a.out)
    train_dir = build_procedural(out / "assets" / "train", n=a.n_train, split="train")
    test_dir = build_procedural(out / "assets" / "test", n=a.n_test, split="test")
    extra = {} if a.log_std_init is None else {"log_std_init": a.log_std_init}
    if a.require_grasp is not None:
        extra["require_grasp"] = a.require_grasp
    extra.update(_overrides(a.set))
    args = Args(
        env_id="OpenDrawer-v0",
        assets=str(train_dir),
        eval_assets=str(test_dir),
        num_envs=a.num_envs,
        vector=a.vector,
        control_mode=a.control_mode,
        near_start_prob=a.near_start_prob,
        total_timesteps=a.total_timesteps,
        max_minutes=a.minutes,
        eval_every=a.eval_every,
        eval_episodes=a.eval_episodes,
        out_dir=str(out / "ppo"),
        **extra,
    )
    result = train(args)
    with open(result["eval_csv"]) as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    final = evaluate(result["policy"], "OpenDrawer-v0", str(test_dir), a.final_episodes)
    curve = out / "curve.csv"
    curve.write_text(Path(result["eval_csv"]).read_text())
    png = out / "curve.png"
    print(
        json.dumps(
            {
                "bench": "rl",
                "curve_csv": str(curve),
                "curve_png": str(png)
                if plot_curve(rows, png, "PPO OpenDrawer-v0: 20 train / 10 held-out drawers")
                else None,
                "last_curve_point": rows[-1] if rows else None,
                "final_policy_held_out": {
                    "episodes": a.final_episodes,
                    "success_rate": final["success_rate"],
                    "grasp_rate": final["grasp_rate"],
                    "mean_return": round(final["mean_return"], 3),
                    "by_handle_kind": by_kind(final["episodes"]),
                },
                "train_seconds": round(result["seconds"], 1),
                "policy": result["policy"],
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
