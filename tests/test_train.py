"""tasks.train and `pact train` / `pact eval-policy`: the PPO run (logs, curve, checkpoint,
resume, videos), stopping by signal, evaluation tables, the shipped policies, and the
training helpers (observation normalization, initial action mean and spread, learning
rate, GC freeze)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from asset_fixtures import write_task_assets

import tasks  # noqa: F401  (registers the envs)


@pytest.fixture(scope="module")
def procedural_assets(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Built procedural assets: a desk with drawers, a microwave with a side-hinged door,
    an oven with a bottom-hinged door and a fridge with two side-hinged doors."""
    return write_task_assets(tmp_path_factory.mktemp("assets"))


@pytest.mark.slow
def test_ppo_smoke_run_writes_logs(procedural_assets: Path, tmp_path: Path) -> None:
    from tasks.train import Args, train

    args = Args(
        env_id="OpenDrawer-v0",
        assets=str(procedural_assets),
        num_envs=2,
        total_timesteps=50,  # one rollout (2 envs x 25 steps) and one update
        n_steps=25,
        batch_size=25,
        n_epochs=2,
        max_episode_steps=50,
        eval_max_episode_steps=5,
        eval_every=0,
        eval_episodes=1,
        video_episodes=0,
        progress_bar=False,
        out_dir=str(tmp_path / "run"),
        vector="sync",  # in-process envs: the process vector is run by the SIGTERM test
    )
    out = train(args)
    run = tmp_path / "run"
    assert (run / "policy.zip").is_file()
    assert (run / "progress.csv").stat().st_size > 0
    assert list(run.glob("events.out.tfevents*"))
    rows = (run / "eval.csv").read_text().splitlines()
    assert rows[0].startswith("timesteps,wall_seconds,success_rate") and len(rows) == 2
    assert out["last_eval"] is not None
    assert np.isfinite(out["last_eval"]["mean_return"])
    # the saved policy brings its observation normalization and control mode
    from tasks.train import ObsNorm, evaluate, load_policy

    _, norm, saved = load_policy(run / "policy.zip")
    assert isinstance(norm, ObsNorm) and norm.mean.shape == norm.var.shape
    assert saved["control_mode"] == args.control_mode
    res = evaluate(str(run / "policy.zip"), "OpenDrawer-v0", str(procedural_assets), episodes=1)
    assert len(res["episodes"]) == 1 and np.isfinite(res["mean_return"])
    assert res["grasp_rate"] == float(res["episodes"][0]["grasped"])
    # per category and part kind: the desk is the only asset with drawers
    ep = res["episodes"][0]
    assert ep["category"] == "desk" and ep["part_kind"] == "drawer"
    assert 0.0 <= ep["open_fraction"] <= ep["max_open_fraction"] + 1e-6
    assert res["by_category"]["desk"]["episodes"] == 1
    assert res["by_part_kind"]["drawer"]["success"] == int(ep["success"])
    assert (run / "curve.png").stat().st_size > 0
    state = json.loads((run / "checkpoint" / "state.json").read_text())
    assert state["num_timesteps"] == 50

    # resume: the run goes on from its checkpoint to the new total, the curve continues
    resumed = train(replace(args, total_timesteps=100, resume=True, video_episodes=1))
    assert resumed["timesteps"] == 100
    rows = (run / "eval.csv").read_text().splitlines()
    assert [int(r.split(",")[0]) for r in rows[1:]] == [50, 100]
    assert json.loads((run / "checkpoint" / "state.json").read_text())["num_timesteps"] == 100
    assert resumed["seconds"] >= float(rows[1].split(",")[1])  # wall-clock adds up
    videos = list((run / "videos").iterdir())
    assert len(videos) == 1 and videos[0].name.startswith("episode_000_desk")
    assert resumed["videos"] == [str(videos[0])]

    # pact eval-policy: tables per category and part kind, every episode as JSON
    from typer.testing import CliRunner

    from pact_cli.main import app

    out_json = tmp_path / "eval.json"
    cli = CliRunner().invoke(
        app,
        ["eval-policy", str(run / "policy.zip"), "--assets", str(procedural_assets),
         "--episodes", "2", "--out", str(out_json)],
    )  # fmt: skip
    assert cli.exit_code == 0, cli.output
    assert "success per category" in cli.output and "success per part kind" in cli.output
    result = json.loads(out_json.read_text())
    assert len(result["episodes"]) == 2 and set(result["by_category"]) == {"desk"}


@pytest.mark.slow
def test_sigterm_saves_the_checkpoint_and_closes_the_workers(
    procedural_assets: Path, tmp_path: Path
) -> None:
    """`pact train` sent SIGTERM mid-run (as `kill` or a job scheduler does): it saves the
    checkpoint, ends its env worker processes and exits 128 + 15, saying how to go on."""
    import signal
    import subprocess
    import sys
    import time

    run = tmp_path / "run"
    cmd = [
        sys.executable, "-c", "from pact_cli.main import main; main()", "train",
        "--assets", str(procedural_assets), "--steps", "1000000", "--num-envs", "2",
        "--eval-every", "0", "--video-episodes", "0", "--no-progress", "--out", str(run),
        "--n-steps", "16", "--batch-size", "32",  # a first rollout of 2 x 16 steps
    ]  # fmt: skip
    child = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.time() + 240
        progress = run / "progress.csv"  # SB3 writes a row after each rollout
        while time.time() < deadline and child.poll() is None:
            if progress.is_file() and len(progress.read_text().splitlines()) >= 2:
                break
            time.sleep(0.5)
        assert child.poll() is None, child.communicate()[0]
        children = subprocess.run(
            ["pgrep", "-P", str(child.pid)], capture_output=True, text=True
        ).stdout.split()
        workers = [  # the async vector env's processes (not multiprocessing's tracker)
            pid for pid in children if b"spawn_main" in Path(f"/proc/{pid}/cmdline").read_bytes()
        ]
        assert len(workers) == 2
        child.send_signal(signal.SIGTERM)
        output, _ = child.communicate(timeout=120)
    finally:
        if child.poll() is None:
            child.kill()
    assert child.returncode == 128 + signal.SIGTERM, output
    assert "stopped by SIGTERM" in output and "--resume" in output
    state = json.loads((run / "checkpoint" / "state.json").read_text())
    assert state["num_timesteps"] >= 32  # at least the first rollout: 2 envs x 16 steps
    assert (run / "policy.zip").is_file()
    deadline = time.time() + 10  # no worker outlives the run
    while time.time() < deadline and any(Path(f"/proc/{pid}").exists() for pid in workers):
        time.sleep(0.2)
    assert not [pid for pid in workers if Path(f"/proc/{pid}").exists()]


def test_a_stop_mid_step_closes_the_workers_without_waiting() -> None:
    """A signal can land while the main process has read some workers' step replies and
    not others. Closing then must end the workers, not wait for replies already read (the
    hang a SIGTERM sometimes caused); a normal close still shuts them down cleanly."""
    import functools
    import threading

    from tasks.train import close_quietly, sb3_vec_env

    def make() -> gym.vector.AsyncVectorEnv:
        fns = [functools.partial(gym.make, "CartPole-v1")] * 2
        return gym.vector.AsyncVectorEnv(fns, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)

    inner = make()
    venv = sb3_vec_env(inner)
    venv.reset()
    inner.step_async(np.zeros(2, dtype=np.int64))
    inner.parent_pipes[0].recv()  # the first worker's reply read, the second's not
    closing = threading.Thread(target=close_quietly, args=(venv,), kwargs={"stopped": True})
    closing.daemon = True
    closing.start()
    closing.join(timeout=60)
    assert not closing.is_alive(), "close waited on a step reply already read"
    assert not any(p.is_alive() for p in inner.processes)

    inner = make()
    venv = sb3_vec_env(inner)
    venv.reset()
    close_quietly(venv)
    assert inner.closed and not any(p.is_alive() for p in inner.processes)


def test_obs_norm_matches_vec_normalize():
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from tasks.train import ObsNorm

    venv = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]), norm_reward=False)
    venv.reset()
    for _ in range(50):
        venv.step(np.array([venv.action_space.sample()]))
    obs = np.array([[0.5, -0.2, 3.0]], dtype=np.float32)
    norm = ObsNorm.from_vec_normalize(venv)
    np.testing.assert_allclose(norm(obs), venv.normalize_obs(obs), rtol=1e-5)
    hand = np.clip((obs - venv.obs_rms.mean) / np.sqrt(venv.obs_rms.var + 1e-8), -10, 10)
    np.testing.assert_allclose(norm(obs), hand, rtol=1e-5)


def test_freeze_gc_once_per_process_and_later_garbage_still_collected():
    """The env processes' GC freeze (tasks.train.freeze_gc) happens once: objects made
    afterwards are neither frozen by a second call nor kept from collection (each asset
    reload's old scene must still be freed)."""
    import gc
    import weakref

    from tasks.train import freeze_gc

    freeze_gc()
    frozen = gc.get_freeze_count()
    assert frozen > 0

    class Node:
        pass

    a, b = Node(), Node()
    a.other, b.other = b, a  # a reference cycle: only the cyclic collector frees it
    alive = weakref.ref(a)
    freeze_gc()
    assert gc.get_freeze_count() == frozen
    del a, b
    gc.collect()
    assert alive() is None


def test_initial_action_mean_opens_the_gripper_without_changing_other_dimensions():
    """``set_initial_action_mean`` makes a fresh SB3 policy's mean gripper action +1 (open
    fingers) and leaves the other dimensions near SB3's zero-mean start."""
    from types import SimpleNamespace

    import torch
    from stable_baselines3.common.policies import ActorCriticPolicy

    from tasks.train import set_initial_action_mean

    torch.manual_seed(0)
    actions = gym.spaces.Box(-1.0, 1.0, (4,), np.float32)  # 3 position deltas + gripper
    policy = ActorCriticPolicy(gym.spaces.Box(-5.0, 5.0, (6,), np.float32), actions, lambda _: 3e-4)
    obs = torch.as_tensor(np.random.default_rng(0).normal(size=(64, 6)), dtype=torch.float32)
    with torch.no_grad():
        before = policy.get_distribution(obs).distribution.mean.numpy()
        set_initial_action_mean(SimpleNamespace(policy=policy), -1, 1.0)
        after = policy.get_distribution(obs).distribution.mean.numpy()
    assert np.abs(before[:, -1]).max() < 0.05  # SB3's start: half-closed fingers
    np.testing.assert_allclose(after[:, -1], 1.0, atol=0.05)
    np.testing.assert_array_equal(after[:, :-1], before[:, :-1])


def test_learning_rate_anneals_linearly_to_zero_at_the_given_step():
    from tasks.train import Args, learning_rate_schedule

    assert learning_rate_schedule(Args(learning_rate=3e-4, lr_anneal_steps=None)) == 3e-4
    lr = learning_rate_schedule(Args(learning_rate=3e-4, total_timesteps=1000, lr_anneal_steps=500))
    # SB3 calls it with the remaining progress 1 - steps / total_timesteps
    assert lr(1.0) == pytest.approx(3e-4)
    assert lr(1.0 - 250 / 1000) == pytest.approx(1.5e-4)
    assert lr(1.0 - 500 / 1000) == pytest.approx(0.0)
    assert lr(0.0) == 0.0
    # from the command line: the default, a number, or none for a constant rate
    from tasks.train import parse_args

    assert parse_args([]).lr_anneal_steps == Args().lr_anneal_steps
    assert parse_args(["--lr-anneal-steps", "1000"]).lr_anneal_steps == 1000
    assert parse_args(["--lr-anneal-steps", "none"]).lr_anneal_steps is None
    assert parse_args(["--gripper-init", "1"]).gripper_init == 1.0


def test_initial_log_std_widens_only_the_gripper_exploration():
    """``set_initial_log_std`` sets the gripper's std (exp of the value) and leaves the
    position dimensions at the policy's ``log_std_init``."""
    from types import SimpleNamespace

    import torch
    from stable_baselines3.common.policies import ActorCriticPolicy

    from tasks.train import set_initial_log_std

    actions = gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    policy = ActorCriticPolicy(
        gym.spaces.Box(-5.0, 5.0, (6,), np.float32), actions, lambda _: 3e-4, log_std_init=-2.0
    )
    set_initial_log_std(SimpleNamespace(policy=policy), -1, 0.0)
    with torch.no_grad():
        std = policy.get_distribution(torch.zeros(1, 6)).distribution.stddev.numpy()[0]
    np.testing.assert_allclose(std, [np.exp(-2.0)] * 3 + [1.0], rtol=1e-6)
    # the optimizer still trains it: it is the same parameter
    assert any(p is policy.log_std for g in policy.optimizer.param_groups for p in g["params"])


def test_success_table_counts_and_failure_opening() -> None:
    from tasks.train import success_table

    episodes = [
        {"category": "oven", "success": True, "open_fraction": 0.9},
        {"category": "oven", "success": False, "open_fraction": 0.2},
        {"category": "oven", "success": False, "open_fraction": 0.4},
        {"category": "desk", "success": True, "open_fraction": 0.8},
    ]
    table = success_table(episodes, "category")
    assert list(table) == ["desk", "oven"]
    assert table["oven"] == {
        "episodes": 3, "success": 1, "success_rate": 0.3333, "failed_open_fraction": 0.3,
    }  # fmt: skip
    assert table["desk"]["success_rate"] == 1.0 and table["desk"]["failed_open_fraction"] is None


@pytest.mark.parametrize("task", ["OpenDrawer-v0", "OpenDoor-v0"])
def test_shipped_policy_runs_on_built_assets(task: str, procedural_assets: Path) -> None:
    """policies/<task>/policy.zip (what `pact eval-policy` runs on a fresh clone) loads
    with its observation normalization and acts in the current task: its observation
    layout still matches the env's."""
    from tasks.train import evaluate, load_policy

    policy = Path(__file__).resolve().parents[1] / "policies" / task / "policy.zip"
    model, norm, saved = load_policy(policy)
    assert norm is not None and saved["env_id"] == task
    res = evaluate(str(policy), task, str(procedural_assets), episodes=1, max_episode_steps=3)
    ep = res["episodes"][0]
    assert ep["part_kind"] in (
        ("drawer",) if task == "OpenDrawer-v0" else ("side_door", "bottom_door")
    )
    assert np.isfinite(res["mean_return"])


def test_pact_train_passes_its_options_and_reports_a_stop(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """`pact train`'s options reach the training arguments (0 learning-rate horizon: a
    constant rate), and a stopped run exits 128 + the signal with its message."""
    import signal

    from typer.testing import CliRunner

    import tasks.train
    from pact_cli.main import app
    from tasks.train import Args

    seen = []

    def fake_train(args):  # noqa: ANN001, ANN202
        seen.append(args)
        if args.seed == 1:
            raise tasks.train.TrainingStopped("RUN: stopped by SIGTERM at 10 steps", signal.SIGTERM)
        return {"timesteps": 0}

    monkeypatch.setattr(tasks.train, "train", fake_train)
    base = ["train", "--assets", str(tmp_path), "--out", str(tmp_path / "run")]
    res = CliRunner().invoke(
        app,
        [*base, "--lr-anneal-steps", "950000", "--randomize-physics",
         "--demo-episodes", "300", "--learning-rate", "1e-4", "--log-std-init", "-3",
         "--anchor-batches", "10", "--critic-warmup-steps", "20000", "--fixed-obs-norm",
         "--dagger-rounds", "2", "--dagger-episodes", "50", "--clone-members", "3",
         "--bc-obs-noise", "0.1", "--demos-from", "RUN/teacher_demos.npz",
         "--n-steps", "64", "--batch-size", "128"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert seen[-1].n_steps == 64 and seen[-1].batch_size == 128
    assert seen[-1].clone_members == 3 and seen[-1].bc_obs_noise == pytest.approx(0.1)
    assert seen[-1].demos_from == "RUN/teacher_demos.npz" and seen[-1].clones_teacher
    assert tasks.train.policy_net_arch(seen[-1]) == {"pi": [768, 768], "vf": [256, 256]}
    assert seen[-1].dagger_rounds == 2 and seen[-1].dagger_episodes == 50
    assert seen[-1].log_std_init == pytest.approx(-3.0)
    assert seen[-1].anchor_batches == 10 and seen[-1].critic_warmup_steps == 20_000
    assert not seen[-1].update_obs_norm
    assert seen[-1].lr_anneal_steps == 950_000 and seen[-1].randomize_physics
    assert seen[-1].demo_episodes == 300 and seen[-1].learning_rate == pytest.approx(1e-4)
    res = CliRunner().invoke(app, [*base, "--lr-anneal-steps", "0", "--seed", "1"])
    assert seen[-1].lr_anneal_steps is None and not seen[-1].randomize_physics
    assert seen[-1].demo_episodes == 0 and seen[-1].learning_rate == pytest.approx(3e-4)
    assert seen[-1].log_std_init == pytest.approx(tasks.train.Args().log_std_init)
    assert seen[-1].update_obs_norm and seen[-1].anchor_batches == 0
    assert seen[-1].dagger_rounds == 0 and seen[-1].clone_members == 1
    assert (seen[-1].n_steps, seen[-1].batch_size) == (Args.n_steps, Args.batch_size)
    assert seen[-1].demos_from is None and not seen[-1].clones_teacher
    assert tasks.train.policy_net_arch(seen[-1]) == [256, 256]
    assert res.exit_code == 128 + signal.SIGTERM
    assert "stopped by SIGTERM" in res.output


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--n-steps", "0"], "--n-steps 0 with --num-envs 4"),
        (["--n-steps", "1", "--num-envs", "1"], "at least 2 transitions"),
        (["--batch-size", "1"], "--batch-size 1"),
    ],
)
def test_pact_train_refuses_a_rollout_or_minibatch_ppo_cannot_use(
    options: list[str], message: str, tmp_path: Path
) -> None:
    """A rollout of fewer than 2 transitions or a minibatch of 1 stops `pact train` with
    one line naming the option, before any env starts or the run folder is made."""
    from typer.testing import CliRunner

    from pact_cli.main import app

    run = tmp_path / "run"
    res = CliRunner().invoke(app, ["train", "--assets", str(tmp_path), "--out", str(run), *options])
    assert res.exit_code != 0
    assert message in res.output
    assert not run.exists()


def test_teacher_episodes_run_with_the_training_physics_randomization(
    procedural_assets: Path,
) -> None:
    """With --randomize-physics the teacher's episodes (what a clone learns from) load the
    parts with scaled masses too, as the PPO envs do; without it, the assets' own."""
    from tasks.train import Args, _teacher_env

    for randomize in (False, True):
        env = _teacher_env(
            Args(env_id="OpenDoor-v0", assets=str(procedural_assets), randomize_physics=randomize)
        )
        try:
            env.reset(seed=5)
            scales = env.unwrapped.physics_scales[0].cpu().numpy()
        finally:
            env.close()
        assert (not np.allclose(scales, 1.0)) == randomize, (randomize, scales)
