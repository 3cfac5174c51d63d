"""Env steps per second of the drawer task: state and rgb observations, 1 and 2 processes.

Prints JSON. Assets: ``--assets`` (a folder of built assets) or, by default, a few
procedural desks/cabinets built into a temporary folder. ``--reconfiguration-freqs``:
reload an asset every k episodes (1 = every episode; a reload costs 0.3-0.5 s on CPU).
Each figure is given including resets (wall-clock over all steps) and excluding them
(only the vector steps in which no episode ended). Every configuration runs
``--repeats`` times in fresh processes; the figures are those of the median run, and
``steps_per_s_per_process_runs`` lists every run (single short runs on these shared
cores varied by up to 1.6x).

    VK_ICD_FILENAMES=/usr/share/vulkan/icd.d/lvp_icd.json python bench/sim.py
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np


def build_procedural(
    out: Path,
    categories: tuple[str, ...] = ("desk", "cabinet"),
    n: int = 2,
    split: str = "train",
    seed0: int = 0,
) -> Path:
    from asset_pipeline.assets.build import build_asset
    from generator.bundle import save_bundle
    from generator.procedural import object_id, sample_object

    for c in categories:
        for s in range(seed0, seed0 + n):
            build_asset(save_bundle(sample_object(c, s, split=split), out / object_id(c, s, split)))
    return out


def _make(
    assets: str,
    obs_mode: str,
    control_mode: str,
    reconfiguration_freq: int = 1,
    torch_threads: int = 1,
):
    def thunk():
        from tasks.train import make_cpu_env, set_torch_threads

        set_torch_threads(torch_threads)  # as training's env workers (Args.torch_threads)

        return make_cpu_env(
            "OpenDrawer-v0",
            assets,
            obs_mode=obs_mode,
            control_mode=control_mode,
            render_backend="none" if obs_mode == "state" else "cpu",
            reconfiguration_freq=reconfiguration_freq,
        )

    return thunk


def measure(
    assets: str,
    obs_mode: str,
    procs: int,
    steps: int,
    control_mode: str,
    reconfiguration_freq: int = 1,
    torch_threads: int = 1,
) -> dict:
    fns = [
        _make(assets, obs_mode, control_mode, reconfiguration_freq, torch_threads)
        for _ in range(procs)
    ]
    mode = gym.vector.AutoresetMode.SAME_STEP
    venv = (
        gym.vector.SyncVectorEnv(fns, autoreset_mode=mode)
        if procs == 1
        else gym.vector.AsyncVectorEnv(fns, autoreset_mode=mode, context="spawn")
    )
    try:
        venv.reset(seed=0)
        rng = np.random.default_rng(0)
        for _ in range(10):  # warm-up (shader compilation for rgb)
            venv.step(rng.uniform(-1, 1, venv.action_space.shape).astype(np.float32))
        episodes, clean_steps, clean_time = 0, 0, 0.0
        t0 = time.perf_counter()
        for _ in range(steps):
            action = rng.uniform(-1, 1, venv.action_space.shape).astype(np.float32)
            t = time.perf_counter()
            _, _, term, trunc, _ = venv.step(action)
            ended = int(np.sum(term | trunc))
            if not ended:  # no autoreset inside this vector step
                clean_steps += 1
                clean_time += time.perf_counter() - t
            episodes += ended
        dt = time.perf_counter() - t0
    finally:
        venv.close()
    total = steps * procs
    clean = clean_steps * procs / clean_time if clean_time > 0 else float("nan")
    return {
        "obs_mode": obs_mode,
        "processes": procs,
        "control_mode": control_mode,
        "reconfiguration_freq": reconfiguration_freq,
        "env_steps": total,
        "seconds": round(dt, 2),
        "steps_per_s": round(total / dt, 1),
        "steps_per_s_per_process": round(total / dt / procs, 1),
        "steps_per_s_excluding_resets": round(clean, 1),
        "steps_per_s_per_process_excluding_resets": round(clean / procs, 1),
        "episodes_reset": episodes,
    }


def measure_repeated(repeats: int, *args) -> dict:
    """:func:`measure` ``repeats`` times: the median run (by steps per second), plus the
    per-process rate of every run."""
    runs = [measure(*args) for _ in range(repeats)]
    ranked = sorted(runs, key=lambda r: r["steps_per_s"])
    return {
        **ranked[len(ranked) // 2],
        "repeats": repeats,
        "steps_per_s_per_process_runs": [r["steps_per_s_per_process"] for r in runs],
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--assets", default=None)
    ap.add_argument("--steps", type=int, default=2000, help="vector steps per measurement")
    ap.add_argument("--rgb-steps", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=3, help="runs per configuration (median)")
    ap.add_argument("--procs", type=int, nargs="+", default=[1, 2])
    ap.add_argument(
        "--control-modes", nargs="+", default=["pd_joint_delta_pos", "pd_ee_delta_pose"]
    )
    ap.add_argument("--no-rgb", action="store_true")
    ap.add_argument(
        "--reconfiguration-freqs",
        type=int,
        nargs="+",
        default=[1, 10],
        help="reload an asset every k episodes (state runs); rgb runs use the first",
    )
    ap.add_argument(
        "--torch-threads",
        type=int,
        default=1,
        help="torch threads per env process, as in training (0: torch's default, one per core)",
    )
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        assets = a.assets or str(build_procedural(Path(tmp)))
        results = []
        for k in a.reconfiguration_freqs:
            for cm in a.control_modes:
                for p in a.procs:
                    results.append(
                        measure_repeated(
                            a.repeats, assets, "state", p, a.steps, cm, k, a.torch_threads
                        )
                    )
        if not a.no_rgb:
            k = a.reconfiguration_freqs[0]
            for p in a.procs:
                results.append(
                    measure_repeated(
                        a.repeats,
                        assets,
                        "rgb",
                        p,
                        a.rgb_steps,
                        a.control_modes[0],
                        k,
                        a.torch_threads,
                    )
                )
    print(
        json.dumps(
            {
                "bench": "sim",
                "task": "OpenDrawer-v0",
                "max_episode_steps": 100,
                "note": "random actions; an asset is reloaded every reconfiguration_freq episodes",
                "torch_threads_per_process": a.torch_threads,
                "results": results,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
