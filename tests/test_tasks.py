"""tasks: env checker, determinism, success flag, dense reward, scripted solver, PPO smoke run."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

import tasks  # noqa: F401  (registers the envs)
from asset_pipeline.assets.built_asset import MovablePart


@pytest.fixture(scope="module")
def procedural_assets(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Built procedural assets: a desk with drawers, a microwave with a side-hinged door,
    an oven with a bottom-hinged door and a fridge with two side-hinged doors."""
    from asset_pipeline.assets.build import build_asset
    from generator.bundle import save_bundle
    from generator.procedural import object_id, sample_object

    root = tmp_path_factory.mktemp("assets")
    for category, seed in (("desk", 0), ("microwave", 1), ("oven", 0), ("refrigerator", 0)):
        build_asset(save_bundle(sample_object(category, seed), root / object_id(category, seed)))
    return root


def _make(env_id: str, assets: Path, **kw):
    kw.setdefault("render_backend", "none")
    return gym.make(env_id, assets=assets, sim_backend="physx_cpu", **kw)


def test_env_ids_registered() -> None:
    for env_id in tasks.ENV_IDS:
        assert env_id in gym.registry


def test_check_env(procedural_assets: Path) -> None:
    from gymnasium.utils.env_checker import check_env
    from mani_skill.utils.wrappers import CPUGymWrapper

    from tasks.drawer import OpenDrawerEnv

    # constructed directly: the TimeLimitWrapper gym.make adds cannot be re-created
    # from its spec, which the checker tries
    env = CPUGymWrapper(
        OpenDrawerEnv(
            assets=procedural_assets,
            obs_mode="state",
            sim_backend="physx_cpu",
            render_backend="none",
        )
    )
    try:
        check_env(env, skip_render_check=True)
    finally:
        env.close()


def test_seeded_reset_is_deterministic(procedural_assets: Path) -> None:
    env = _make("OpenDoor-v0", procedural_assets)
    try:
        o1, _ = env.reset(seed=3)
        a1 = env.unwrapped.episode_assets[0].id
        env.reset(seed=4)
        o2, _ = env.reset(seed=3)
        assert env.unwrapped.episode_assets[0].id == a1
        torch.testing.assert_close(o1, o2)
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["OpenDrawer-v0", "CloseDrawer-v0"])
def test_success_flag_follows_the_target_joint(procedural_assets: Path, env_id: str) -> None:
    env = _make(env_id, procedural_assets)
    try:
        env.reset(seed=0)
        u = env.unwrapped
        opening = not u.closing
        start = float(u.open_fraction()[0])
        assert (start == pytest.approx(0.0, abs=1e-4)) if opening else start >= 0.8
        assert not bool(u.evaluate()["success"][0])

        def set_fraction(frac: float) -> bool:
            q = u.object.get_qpos().clone()
            q[0, u.target_dof_idx[0]] = u.qlow[0] + frac * u.qrange[0]
            u.object.set_qpos(q)
            u.object.set_qvel(torch.zeros_like(q))
            return bool(u.evaluate()["success"][0])

        assert set_fraction(0.9) is opening
        assert set_fraction(0.0) is not opening
    finally:
        env.close()


def test_is_grasped_only_while_the_fingers_hold_the_handle(procedural_assets: Path) -> None:
    from tasks.solver import ScriptedSolver

    env = _make("OpenDrawer-v0", procedural_assets, control_mode="pd_ee_delta_pose")
    try:
        env.reset(seed=1)
        u = env.unwrapped
        assert not bool(u.evaluate()["is_grasped"][0])  # 12 cm in front of the handle
        res = ScriptedSolver(env).solve()
        assert res.success
        assert bool(u.evaluate()["is_grasped"][0])  # still pinching the pulled handle
        obs = u.get_obs()
        assert obs.shape[0] == 1 and torch.isfinite(obs).all()
    finally:
        env.close()


def test_dense_reward_rises_as_gripper_approaches(procedural_assets: Path) -> None:
    from tasks.solver import ScriptedSolver

    env = _make(
        "OpenDrawer-v0", procedural_assets, control_mode="pd_ee_delta_pose", reward_mode="dense"
    )
    try:
        env.reset(seed=1)
        u = env.unwrapped
        solver = ScriptedSolver(env)
        info = u.evaluate()
        handle = info["handle_pos"][0].numpy()
        goal = solver._tcp()
        goal[:3, 3] = handle
        dists, rewards = [], []
        for _ in range(8):
            _, r, _, _, info = env.step(torch.as_tensor(solver._action(goal, 1.0))[None])
            dists.append(float(info["tcp_to_handle_dist"][0]))
            rewards.append(float(r[0]))
        assert dists[-1] < dists[0] - 0.02
        assert rewards[-1] > rewards[0]
        assert all(0.0 <= x <= u.max_reward for x in rewards)
    finally:
        env.close()


def test_resets_between_reconfigurations_resample_part_and_poses(
    procedural_assets: Path,
) -> None:
    """With reconfiguration_freq=k the asset stays loaded for k episodes; each reset
    still draws the target part (among the loaded asset's drawers) and the poses."""
    env = _make("OpenDrawer-v0", procedural_assets, category="desk", reconfiguration_freq=4)
    try:
        env.reset(seed=0, options={"reconfigure": True})  # starts a cycle of 4 episodes
        u = env.unwrapped
        loaded = u.object._objs[0]
        parts, bases = set(), set()
        for _ in range(3):
            env.reset()
            assert u.object._objs[0] is loaded  # no reload
            part = u.episode_parts[0]
            parts.add(part.name)
            bases.add(tuple(np.round(u.agent.robot.pose.p[0].numpy(), 4)))
            # the tables follow the part: its joint, closed, and its handle where the link is
            joints = u.object._objs[0].get_active_joints()
            assert joints[int(u.target_dof_idx[0])].name.endswith(part.joint_name)
            assert float(u.open_fraction()[0]) == pytest.approx(0.0, abs=1e-4)
            assert u.target_link._objs[0].name.endswith(part.name)
        assert len(bases) == 3
        env.reset()  # the 4th reset after the reload: a new scene
        assert u.object._objs[0] is not loaded
        # over a few seeds every drawer of the desk gets picked
        for seed in range(1, 12):
            env.reset(seed=seed)
            parts.add(u.episode_parts[0].name)
        assert len(parts) > 1
    finally:
        env.close()


def test_state_obs_carries_the_target_handle_kind(procedural_assets: Path) -> None:
    """``handle_kind`` in the state observation is the one-hot of the episode's part."""
    from asset_pipeline.assets.built_asset import HANDLE_KINDS

    env = _make("OpenDoor-v0", procedural_assets, obs_mode="state_dict")
    try:
        for seed in range(6):
            obs, _ = env.reset(seed=seed)
            kind = env.unwrapped.episode_parts[0].handle_kind
            onehot = obs["extra"]["handle_kind"][0].numpy()
            assert onehot.tolist() == [float(kind == k) for k in HANDLE_KINDS]
            assert onehot.sum() == 1.0
    finally:
        env.close()


def test_robot_placement_keeps_door_path_in_reach(procedural_assets: Path) -> None:
    from sim_envs import FolderSource
    from tasks.placement import REACH, SHOULDER_HEIGHT, handle_path, robot_base_for_part

    fridge = next(r for r in FolderSource(procedural_assets) if r.category == "refrigerator")
    lo, hi = np.asarray(fridge.bounds[0]), np.asarray(fridge.bounds[1])
    for part in fridge.movable_parts():
        base, _, start = robot_base_for_part(part, fridge.bounds)
        assert start is None  # no kinematics given: the ready pose
        # outside the fridge's footprint
        assert not ((base[:2] > lo[:2]) & (base[:2] < hi[:2])).all()
        path = handle_path(part)
        assert np.allclose(path[0], part.handle_object)
        dist = np.linalg.norm(path - (base + [0, 0, SHOULDER_HEIGHT]), axis=1)
        assert dist.max() < REACH[1] + 0.1


@pytest.mark.slow
def test_scripted_solver_opens_drawer_and_doors(procedural_assets: Path) -> None:
    """The solver opens a drawer, a side-hinged microwave door, a bottom-hinged oven door
    and a side-hinged fridge door in CPU simulation."""
    from sim_envs import FolderSource
    from tasks.solver import solve_part

    src = {r.category: r for r in FolderSource(procedural_assets)}
    for category, part, env_id in (
        ("desk", "drawer_0", "OpenDrawer-v0"),
        ("microwave", "door_0", "OpenDoor-v0"),
        ("oven", "door_0", "OpenDoor-v0"),
        ("refrigerator", "door_1", "OpenDoor-v0"),
    ):
        res, used = solve_part(src[category], part, seed=0)
        assert used == env_id and res.success, (category, part, res)


@pytest.mark.slow
def test_ppo_smoke_run_writes_logs(procedural_assets: Path, tmp_path: Path) -> None:
    from tasks.train import Args, train

    args = Args(
        env_id="OpenDrawer-v0",
        assets=str(procedural_assets),
        num_envs=2,
        total_timesteps=500,
        n_steps=125,
        batch_size=125,
        n_epochs=2,
        max_episode_steps=50,
        eval_max_episode_steps=5,
        eval_every=0,
        eval_episodes=1,
        video_episodes=0,
        progress_bar=False,
        out_dir=str(tmp_path / "run"),
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
    assert state["num_timesteps"] == 500

    # resume: the run goes on from its checkpoint to the new total, the curve continues
    resumed = train(
        replace(args, total_timesteps=750, resume=True, video_episodes=1, vector="sync")
    )
    assert resumed["timesteps"] == 750
    rows = (run / "eval.csv").read_text().splitlines()
    assert [int(r.split(",")[0]) for r in rows[1:]] == [500, 750]
    assert json.loads((run / "checkpoint" / "state.json").read_text())["num_timesteps"] == 750
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
    assert state["num_timesteps"] >= 256  # at least the first rollout: 2 envs x 128 steps
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


def test_near_start_curriculum_puts_the_fingers_round_the_handle(procedural_assets: Path) -> None:
    """``near_start_prob=1`` starts every drawer episode with the TCP a few cm from the
    handle (about 12 cm without it); the option is refused for door and closing tasks."""

    def reset_distances(prob: float) -> list[float]:
        env = _make("OpenDrawer-v0", procedural_assets, near_start_prob=prob)
        try:
            dists = []
            for seed in range(8):
                env.reset(seed=seed)
                dists.append(float(env.unwrapped.evaluate()["tcp_to_handle_dist"][0]))
            return dists
        finally:
            env.close()

    far, near = reset_distances(0.0), reset_distances(1.0)
    assert min(far) > 0.08
    assert max(near) < 0.08 and np.mean(near) < np.mean(far) - 0.06
    with pytest.raises(ValueError, match="drawer opening"):
        _make("OpenDoor-v0", procedural_assets, near_start_prob=0.5)


def test_require_grasp_withholds_the_grasp_term_from_a_hook(procedural_assets: Path) -> None:
    """A drawer moved 30 % open with the gripper 12 cm away (no grasp): the default dense
    reward counts the grasp term as earned (reach 1 + grasp 1 + 3 x progress, progress
    = 0.3 / 0.75 of the goal: 3.2); ``require_grasp=True`` does not (2.2)."""
    rewards = {}
    for require in (False, True):
        env = _make("OpenDrawer-v0", procedural_assets, reward_mode="dense", require_grasp=require)
        try:
            env.reset(seed=0)
            u = env.unwrapped
            q = u.object.get_qpos().clone()
            q[0, u.target_dof_idx[0]] = u.qlow[0] + 0.3 * u.qrange[0]
            u.object.set_qpos(q)
            u.object.set_qvel(torch.zeros_like(q))
            info = u.evaluate()
            assert not bool(info["is_grasped"][0]) and not bool(info["success"][0])
            r = u.compute_dense_reward(obs=None, action=None, info=info)
            rewards[require] = float(r[0])
        finally:
            env.close()
    assert rewards[False] == pytest.approx(3.2, abs=1e-3)
    assert rewards[True] == pytest.approx(2.2, abs=1e-3)


def _part(joint_type: str, axis, origin, handle) -> MovablePart:
    return MovablePart(
        name="p", joint_name="j", joint_type=joint_type, lower=0.0, upper=1.0, axis=axis,
        origin=origin, handle_link=(0.0, 0.0, 0.0), handle_object=handle,
        handle_axis=(0.0, 1.0, 0.0), handle_kind="bar",
    )  # fmt: skip


def test_part_kind_from_joint_and_handle() -> None:
    """The part kinds the policy evaluation reports, on hand-placed hinges (object frame:
    +x front, +z up)."""
    assert _part("prismatic", (1, 0, 0), (0.3, 0, 0.5), (0.32, 0, 0.5)).kind == "drawer"
    # a fridge door hinged on its left edge, handle at the right
    assert _part("revolute", (0, 0, -1), (0.3, -0.3, 1.0), (0.33, 0.25, 1.0)).kind == "side_door"
    # an oven door: hinge along y at the bottom of the front, handle 0.4 m above it
    assert _part("revolute", (0, 1, 0), (0.3, 0, 0.2), (0.35, 0, 0.6)).kind == "bottom_door"
    # a top-loader lid hinged at its back edge, handle at the front, level with the hinge
    assert _part("revolute", (0, -1, 0), (-0.25, 0, 0.9), (0.25, 0, 0.92)).kind == "lid"
    # a lid hinged at its left edge (axis along the front's normal), handle at the right
    assert _part("revolute", (1, 0, 0), (0.0, -0.3, 0.9), (0.0, 0.25, 0.92)).kind == "lid"
    # a flap hinged at its top edge
    assert _part("revolute", (0, -1, 0), (0.3, 0, 1.0), (0.33, 0, 0.7)).kind == "top_flap"


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


def test_task_assets_bench_counts_parts_per_kind(procedural_assets: Path) -> None:
    """bench/task_assets.py: per part kind, the parts the tasks see, ranges in degrees for
    hinges and metres for drawers, checked against the assets' own joints."""
    import importlib.util

    from sim_envs.asset_sources import open_source

    spec = importlib.util.spec_from_file_location(
        "task_assets", Path(__file__).parents[1] / "bench" / "task_assets.py"
    )
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    summary = bench.summarize(bench.part_rows(str(procedural_assets)))
    parts = [p for a in open_source(procedural_assets).assets() for p in a.movable_parts()]
    want = {}
    for p in parts:
        want.setdefault(p.kind, []).append(p)
    assert set(summary) == set(want) >= {"drawer", "side_door", "bottom_door"}
    for kind, group in want.items():
        assert summary[kind]["parts"] == len(group)
        assert sum(summary[kind]["handles"].values()) == len(group)
        ranges = [p.range if kind == "drawer" else np.degrees(p.range) for p in group]
        assert summary[kind]["range"]["max"] == pytest.approx(max(ranges), abs=0.06)
    assert summary["drawer"]["categories"] == {"desk": len(want["drawer"])}
    assert 60 <= summary["side_door"]["range"]["median"] <= 180  # degrees, not radians


def test_physics_randomization_scales_the_parts_within_its_ranges(procedural_assets: Path) -> None:
    """Each load scales the object's movable parts by factors drawn in the ranges: masses
    and inertias, joint damping and friction against the same object loaded plainly; the
    same seed draws the same factors; the base is left alone."""
    from tasks.articulated import PhysicsRandomization

    def loaded(**kw):  # noqa: ANN003, ANN202
        env = _make("OpenDrawer-v0", procedural_assets, **kw)
        env.reset(seed=3)
        u = env.unwrapped
        obj = u.object._objs[0]
        joints = {
            j.name: (j.damping, j.friction, j.child_link.mass) for j in obj.get_active_joints()
        }
        base = obj.get_links()[0].mass
        inertia = {j.name: np.asarray(j.child_link.inertia) for j in obj.get_active_joints()}
        scales = u.physics_scales[0].cpu().numpy()
        env.close()
        return joints, base, inertia, scales

    plain, base0, inertia0, scales0 = loaded()
    np.testing.assert_array_equal(scales0, [1.0, 1.0, 1.0])
    ranges = PhysicsRandomization(mass=(2.0, 3.0), damping=(0.5, 0.6), friction=(1.5, 1.6))
    joints, base, inertia, scales = loaded(physics_randomization=ranges)
    m, d, f = scales
    assert 2.0 <= m <= 3.0 and 0.5 <= d <= 0.6 and 1.5 <= f <= 1.6
    assert base == pytest.approx(base0)
    assert set(joints) == set(plain) and plain
    for name, (damping, friction, mass) in joints.items():
        assert damping == pytest.approx(plain[name][0] * d, rel=1e-5)
        assert friction == pytest.approx(plain[name][1] * f, rel=1e-5)
        assert mass == pytest.approx(plain[name][2] * m, rel=1e-5)
        np.testing.assert_allclose(inertia[name], inertia0[name] * m, rtol=1e-5)
    assert plain[next(iter(plain))][0] > 0  # the asset's damping is there to be scaled
    _, _, _, again = loaded(physics_randomization=ranges)
    np.testing.assert_array_equal(again, scales)
    with pytest.raises(ValueError, match="0 < low <= high"):
        PhysicsRandomization(mass=(0.0, 1.0)).draw(np.random.RandomState(0))


def test_pact_train_passes_its_options_and_reports_a_stop(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """`pact train`'s options reach the training arguments (0 learning-rate horizon: a
    constant rate), and a stopped run exits 128 + the signal with its message."""
    import signal

    from typer.testing import CliRunner

    import tasks.train
    from pact_cli.main import app

    seen = []

    def fake_train(args):  # noqa: ANN001, ANN202
        seen.append(args)
        if args.seed == 1:
            raise tasks.train.TrainingStopped("RUN: stopped by SIGTERM at 10 steps", signal.SIGTERM)
        return {"timesteps": 0}

    monkeypatch.setattr(tasks.train, "train", fake_train)
    base = ["train", "--assets", str(tmp_path), "--out", str(tmp_path / "run")]
    res = CliRunner().invoke(app, [*base, "--lr-anneal-steps", "950000", "--randomize-physics"])
    assert res.exit_code == 0, res.output
    assert seen[-1].lr_anneal_steps == 950_000 and seen[-1].randomize_physics
    res = CliRunner().invoke(app, [*base, "--lr-anneal-steps", "0", "--seed", "1"])
    assert seen[-1].lr_anneal_steps is None and not seen[-1].randomize_physics
    assert res.exit_code == 128 + signal.SIGTERM
    assert "stopped by SIGTERM" in res.output
