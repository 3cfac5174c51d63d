"""The scripted drawer teacher (tasks.teacher) and PPO started from its demonstrations."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from asset_fixtures import write_task_assets


@pytest.fixture(scope="module")
def procedural_assets(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_task_assets(tmp_path_factory.mktemp("assets"))


def test_teacher_grasps_the_handle_and_opens_the_drawer(procedural_assets: Path) -> None:
    from tasks.teacher import OpeningTeacher
    from tasks.train import make_cpu_env

    env = make_cpu_env(
        "OpenDrawer-v0", str(procedural_assets), control_mode="pd_ee_delta_pos",
        sim_config={"control_freq": 10}, max_episode_steps=50,
    )  # fmt: skip
    try:
        opened = []
        for seed in (10_000, 10_001):
            env.reset(seed=seed)
            teacher, done, grasped, info = OpeningTeacher(), False, False, {}
            while not done:
                _, _, term, trunc, info = env.step(teacher(env))
                grasped |= bool(info["is_grasped"])
                done = term or trunc
            # a grasp, not a hook: both fingers pressed on the drawer at some step
            opened.append(bool(info["success"]) and grasped)
    finally:
        env.close()
    assert any(opened)


def test_teacher_opens_side_and_bottom_hinged_doors(procedural_assets: Path) -> None:
    from tasks.teacher import OpeningTeacher
    from tasks.train import eval_episode_steps, make_cpu_env

    opened: dict[str, bool] = {}
    for category in ("microwave", "oven"):
        env = make_cpu_env(
            "OpenDoor-v0", str(procedural_assets), category=category,
            control_mode="pd_ee_delta_pos", sim_config={"control_freq": 10},
            **eval_episode_steps("OpenDoor-v0", None, 10),
        )  # fmt: skip
        try:
            env.reset(seed=10_000)
            kind = env.unwrapped.episode_parts[0].kind
            teacher, done, info = OpeningTeacher(), False, {}
            while not done:
                _, _, term, trunc, info = env.step(teacher(env))
                done = term or trunc
            opened[kind] = bool(info["success"])
        finally:
            env.close()
    assert opened == {"side_door": True, "bottom_door": True}


def test_teacher_grasps_a_dishwashers_recessed_pull_and_opens_it(tmp_path: Path) -> None:
    """A dishwasher door's pull recessed less deep than the teacher's grasp point: the hand
    stops at the door short of that point, closes there and opens the door (it used to
    wait in front of it for the whole episode)."""
    from asset_pipeline.assets.build import build_asset
    from generator.bundle import save_bundle
    from generator.procedural import object_id, sample_object
    from tasks.teacher import OpeningTeacher
    from tasks.train import eval_episode_steps, make_cpu_env

    build_asset(save_bundle(sample_object("dishwasher", 0), tmp_path / object_id("dishwasher", 0)))
    env = make_cpu_env(
        "OpenDoor-v0", str(tmp_path), control_mode="pd_ee_delta_pos",
        sim_config={"control_freq": 10}, **eval_episode_steps("OpenDoor-v0", None, 10),
    )  # fmt: skip
    try:
        env.reset(seed=10_000)
        assert env.unwrapped.episode_parts[0].handle_kind == "recessed"
        teacher, done, info, phases = OpeningTeacher(), False, {}, set()
        while not done:
            _, _, term, trunc, info = env.step(teacher(env))
            phases.add(teacher.phase)
            done = term or trunc
    finally:
        env.close()
    assert "pull" in phases and info["success"]


def test_door_extent_of_a_panel_matches_the_hand_computed_edge_and_face() -> None:
    """A door panel 2 cm thick and 0.6 m wide, hinged on the world z axis at the origin
    (box collision shape, link frame on the hinge), its handle 4 cm in front of the panel's
    outer face and 5 cm from its free edge: the free edge is 0.05 m past the handle, the
    inner face 0.06 m behind it."""
    from types import SimpleNamespace

    import sapien
    import torch

    from tasks.teacher import door_extent

    class Box:  # a collision box as SAPIEN's, by duck typing: half size and local pose
        def get_half_size(self):
            return np.array([0.01, 0.3, 0.5])

        def get_local_pose(self):
            return sapien.Pose([-0.01, 0.3, 0.0])

    pose = SimpleNamespace(to_transformation_matrix=lambda: torch.eye(4)[None])
    link = SimpleNamespace(
        pose=pose, _bodies=[SimpleNamespace(get_collision_shapes=lambda: [Box()])]
    )
    u = SimpleNamespace(target_link=link)
    handle = np.array([0.04, 0.55, 0.0])
    edge, face = door_extent(u, handle, axis=np.array([1.0, 0, 0]), out=np.array([0, 1.0, 0]))
    assert edge == pytest.approx(0.05) and face == pytest.approx(0.06)


def test_clone_fits_the_policy_mean_to_the_demonstrated_actions() -> None:
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    from tasks.teacher import Demos, clone

    class Flat(gym.Env):
        observation_space = gym.spaces.Box(-np.inf, np.inf, (6,), np.float32)
        action_space = gym.spaces.Box(-1.0, 1.0, (4,), np.float32)

        def reset(self, *, seed=None, options=None):
            return np.zeros(6, np.float32), {}

        def step(self, action):
            return np.zeros(6, np.float32), 0.0, True, False, {}

    model = PPO("MlpPolicy", make_vec_env(Flat, 1), seed=0, policy_kwargs={"net_arch": [64, 64]})
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(512, 6)).astype(np.float32)
    actions = np.tanh(obs[:, :4] - 0.5 * obs[:, 2:]).astype(np.float32)
    demos = Demos(obs, actions, np.arange(512) // 32, np.ones(16, bool))
    before = np.mean((model.predict(obs, deterministic=True)[0] - actions) ** 2)
    losses = clone(model, demos, epochs=150)
    after = np.mean((model.predict(obs, deterministic=True)[0] - actions) ** 2)
    assert losses[-1] < 0.1 * losses[0]
    assert after < 0.02 < before


def _flat_ppo():
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    class Flat(gym.Env):
        observation_space = gym.spaces.Box(-np.inf, np.inf, (6,), np.float32)
        action_space = gym.spaces.Box(-1.0, 1.0, (4,), np.float32)

        def reset(self, *, seed=None, options=None):
            return self.observation_space.sample(), {}

        def step(self, action):
            reward = -float(np.sum(np.square(action)))  # something for the critic to learn
            return self.observation_space.sample(), reward, False, False, {}

    env = make_vec_env(Flat, 1, seed=0)
    return PPO("MlpPolicy", env, n_steps=64, batch_size=32, n_epochs=2, seed=0,
               policy_kwargs={"net_arch": [64, 64]})  # fmt: skip


def test_the_anchor_pulls_a_drifted_clone_back_to_the_teacher() -> None:
    import torch

    from tasks.teacher import CloneAnchor, Demos, clone

    model = _flat_ppo()
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(512, 6)).astype(np.float32)
    actions = np.tanh(obs[:, :4] - 0.5 * obs[:, 2:]).astype(np.float32)
    demos = Demos(obs, actions, np.arange(512) // 32, np.ones(16, bool))
    clone(model, demos, epochs=150)

    def error() -> float:
        return float(np.mean((model.predict(obs, deterministic=True)[0] - actions) ** 2))

    cloned = error()
    with torch.no_grad():  # what PPO's drift might do to the mean action
        model.policy.action_net.weight.add_(0.3 * torch.randn_like(model.policy.action_net.weight))
    drifted = error()
    value = [p.detach().clone() for p in model.policy.mlp_extractor.value_net.parameters()]
    log_std = model.policy.log_std.detach().clone()
    anchor = CloneAnchor(model, demos, batches=40, learning_rate=1e-3)
    losses = [anchor.step() for _ in range(3)]
    assert drifted > 5 * cloned and error() < 0.3 * drifted
    assert losses[-1] < losses[0]
    # only the mean action moves
    assert torch.equal(model.policy.log_std, log_std)
    for p, q in zip(model.policy.mlp_extractor.value_net.parameters(), value, strict=True):
        assert torch.equal(p, q)
    with pytest.raises(ValueError, match="batches"):
        CloneAnchor(model, demos, batches=0)


def _flat_demos() -> tuple[np.ndarray, np.ndarray, object]:
    from tasks.teacher import Demos

    rng = np.random.default_rng(0)
    obs = rng.normal(size=(512, 6)).astype(np.float32)
    actions = np.tanh(obs[:, :4] - 0.5 * obs[:, 2:]).astype(np.float32)
    return obs, actions, Demos(obs, actions, np.arange(512) // 32, np.ones(16, bool))


def _flat_wide_ppo(members: int):
    """_flat_ppo's model with the policy MLP ``members`` times 32 wide."""
    model = _flat_ppo()
    from stable_baselines3 import PPO

    return PPO("MlpPolicy", model.get_env(), n_steps=64, batch_size=32, n_epochs=2, seed=0,
               policy_kwargs={"net_arch": {"pi": [32 * members] * 2, "vf": [64, 64]}})  # fmt: skip


def test_an_ensemble_policy_acts_as_the_mean_of_its_members_after_a_save(tmp_path) -> None:
    import torch
    from stable_baselines3 import PPO

    from tasks.teacher import set_ensemble

    wide = _flat_wide_ppo(3)
    kwargs = dict(wide.policy_kwargs, net_arch=[32, 32])
    members = []
    for i in range(3):
        torch.manual_seed(i)
        members.append(wide.policy_class(wide.observation_space, wide.action_space,
                                         wide.lr_schedule, **kwargs))  # fmt: skip
    x = torch.randn(9, 6)
    mean = torch.stack([m.get_distribution(x).distribution.mean for m in members]).mean(0)
    assert not torch.allclose(wide.policy.get_distribution(x).distribution.mean, mean, atol=1e-3)
    set_ensemble(wide.policy, members)
    wide.save(tmp_path / "policy.zip")
    loaded = PPO.load(tmp_path / "policy.zip", device="cpu")
    with torch.no_grad():
        got = loaded.policy.get_distribution(x).distribution.mean
    assert torch.allclose(got, mean.detach(), atol=1e-5)
    with pytest.raises(ValueError, match="units"):
        set_ensemble(wide.policy, members[:2])


def test_an_ensemble_of_clones_fits_the_teacher_and_its_members_differ() -> None:
    import torch

    from tasks.teacher import clone

    obs, actions, demos = _flat_demos()
    model = _flat_wide_ppo(3)
    losses = clone(model, demos, epochs=150, obs_noise=0.02, members=3)
    error = np.mean((model.predict(obs, deterministic=True)[0] - actions) ** 2)
    assert losses[-1] < 0.1 * losses[0] and error < 0.02
    first = model.policy.mlp_extractor.policy_net[0].weight.detach()
    assert not torch.allclose(first[:32], first[32:64])  # members from different weights
    off = model.policy.mlp_extractor.policy_net[2].weight.detach()[:32, 32:]
    assert torch.count_nonzero(off) == 0  # a member's units see only its own
    with pytest.raises(ValueError, match="widths"):
        clone(model, demos, epochs=1, members=5)


def test_a_frozen_actor_leaves_ppo_only_the_critic_to_train() -> None:
    import torch

    from tasks.teacher import actor_parameters
    from tasks.train import set_actor_trainable

    model = _flat_ppo()
    policy = model.policy
    actor = [p.detach().clone() for p in [*actor_parameters(policy), policy.log_std]]
    critic = [p.detach().clone() for p in policy.mlp_extractor.value_net.parameters()]
    set_actor_trainable(model, False)
    model.learn(128)
    after = [*actor_parameters(policy), policy.log_std]
    assert all(torch.equal(p, q) for p, q in zip(after, actor, strict=True))
    assert any(
        not torch.equal(p, q)
        for p, q in zip(policy.mlp_extractor.value_net.parameters(), critic, strict=True)
    )
    set_actor_trainable(model, True)
    model.learn(128)
    assert any(not torch.equal(p, q) for p, q in zip(after, actor, strict=True))


def test_demos_keep_only_successful_episodes() -> None:
    from tasks.teacher import Demos

    demos = Demos(
        obs=np.arange(10, dtype=np.float32)[:, None],
        actions=np.zeros((10, 4), np.float32),
        episode=np.array([0, 0, 0, 1, 1, 2, 2, 2, 2, 2]),
        success=np.array([True, False, True]),
    )
    kept = demos.successful()
    assert kept.obs[:, 0].tolist() == [0, 1, 2, 5, 6, 7, 8, 9]
    assert kept.episode.tolist() == [0, 0, 0, 2, 2, 2, 2, 2]


@pytest.mark.slow
def test_ppo_starts_from_the_teachers_demonstrations(
    procedural_assets: Path, tmp_path: Path
) -> None:
    from tasks.train import Args, ObsNorm, train

    args = Args(
        env_id="OpenDrawer-v0", assets=str(procedural_assets), num_envs=1, vector="sync",
        total_timesteps=256, n_steps=128, batch_size=128, eval_every=0, eval_episodes=1,
        eval_max_episode_steps=5, video_episodes=0, progress_bar=False,
        out_dir=str(tmp_path / "run"), demo_episodes=2, demo_workers=1, bc_epochs=20,
        critic_warmup_steps=128, anchor_batches=2, update_obs_norm=False,
    )  # fmt: skip
    out = train(args)
    teacher = out["teacher"]
    assert teacher["episodes"] == 2 and teacher["successful"] >= 1
    assert teacher["bc_loss_last"] < teacher["bc_loss_first"]
    # the normalizer starts from the demonstrations' statistics: the drawer's joint axis
    # (world +x, the object turned by at most 0.1 rad) has a mean near 1 and little spread
    norm = ObsNorm.load(tmp_path / "run" / "obs_norm.npz")
    assert norm.mean[37] > 0.95 and norm.var[37] < 0.01
    assert (tmp_path / "run" / "teacher.json").is_file()
    # the clone's anchor runs once the critic's warm-up is over (128 steps: before the
    # second update), between updates, on the demos kept beside the run
    with open(tmp_path / "run" / "progress.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 and out["timesteps"] == 256
    assert rows[0]["train/anchor_loss"] == "" and float(rows[1]["train/anchor_loss"]) >= 0
    with np.load(tmp_path / "run" / "teacher_demos.npz") as d:
        assert len(d["obs"]) == teacher["steps"] == len(d["actions"])
        # the normalizer kept the teacher's statistics through PPO's 256 steps
        assert np.allclose(norm.mean, d["obs"].mean(axis=0), atol=1e-5)


def test_corrections_label_the_policys_own_states_with_the_teachers_actions(
    procedural_assets: Path,
) -> None:
    """DAgger's data: a policy that never moves leaves the hand where it starts, and every
    state it visits is labelled with what the teacher would do there (reach for the
    handle), not with what the policy did."""
    from tasks.teacher import OpeningTeacher, collect_corrections
    from tasks.train import make_cpu_env

    env = make_cpu_env(
        "OpenDrawer-v0", str(procedural_assets), control_mode="pd_ee_delta_pos",
        sim_config={"control_freq": 10}, max_episode_steps=12,
    )  # fmt: skip
    try:
        still = collect_corrections(env, lambda o: np.zeros(4, np.float32), 1, seed=10_000)
        env.reset(seed=10_000)
        first = OpeningTeacher()(env)
    finally:
        env.close()
    assert len(still.obs) == 12 and not still.success[0]
    assert np.allclose(still.actions[0], first)
    # the teacher keeps asking for the same reach: the hand never got nearer
    reach = np.linalg.norm(still.actions[:, :3], axis=1)
    assert reach.min() > 0.1 and np.allclose(still.actions[-1, :3], first[:3], atol=0.05)


def test_dagger_rounds_add_the_clones_labelled_states_to_what_it_is_fitted_to(
    procedural_assets: Path, tmp_path: Path
) -> None:
    from dataclasses import replace

    from tasks.train import Args, load_policy, train

    args = Args(
        env_id="OpenDrawer-v0", assets=str(procedural_assets), num_envs=1, vector="sync",
        total_timesteps=0, eval_every=0, eval_episodes=1, eval_max_episode_steps=5,
        video_episodes=0, progress_bar=False, out_dir=str(tmp_path / "run"), demo_episodes=2,
        demo_workers=1, bc_epochs=5, dagger_rounds=1, dagger_episodes=1,
    )  # fmt: skip
    teacher = train(args)["teacher"]
    (fixes,) = teacher["dagger"]
    assert fixes["episodes"] == 1 and fixes["steps"] == 50  # one 5-s drawer episode
    with np.load(tmp_path / "run" / "teacher_demos.npz") as d:
        assert len(d["obs"]) == teacher["steps"] + fixes["steps"]
    # another clone of the same steps, without the teacher: two members averaged
    saved = tmp_path / "run" / "teacher_demos.npz"
    again = replace(args, out_dir=str(tmp_path / "again"), demo_episodes=0, dagger_rounds=0,
                    demos_from=str(saved), clone_members=2)  # fmt: skip
    teacher = train(again)["teacher"]
    assert teacher["demos_from"] == str(saved) and "episodes" not in teacher
    assert teacher["steps"] == len(np.load(saved)["obs"])
    model, _, _ = load_policy(tmp_path / "again" / "policy.zip")
    assert model.policy.mlp_extractor.policy_net[0].out_features == 2 * args.net_arch[0]
    np.savez(tmp_path / "narrow.npz", obs=np.zeros((4, 3)), actions=np.zeros((4, 4)))
    narrow = replace(
        again, out_dir=str(tmp_path / "narrow"), demos_from=str(tmp_path / "narrow.npz")
    )
    with pytest.raises(ValueError, match="3 observations a step"):
        train(narrow)


def test_an_anchor_or_dagger_without_a_teacher_is_refused_before_any_env_starts(
    tmp_path: Path,
) -> None:
    from tasks.train import Args, train

    with pytest.raises(ValueError, match="demo-episodes"):
        train(Args(assets=str(tmp_path), out_dir=str(tmp_path / "run"), anchor_batches=4))
    with pytest.raises(ValueError, match="demo-episodes"):
        train(Args(assets=str(tmp_path), out_dir=str(tmp_path / "run"), dagger_rounds=1))
    with pytest.raises(ValueError, match="demos-from"):
        train(Args(assets=str(tmp_path), out_dir=str(tmp_path / "run"), clone_members=3))


def test_the_teachers_steps_are_saved_and_read_back_and_bad_files_are_named(tmp_path) -> None:
    from tasks.teacher import Demos

    obs = np.arange(12, dtype=np.float32).reshape(4, 3)
    actions = np.ones((4, 2), np.float32)
    Demos(obs, actions, np.zeros(4, np.int64), np.ones(1, bool)).save_steps(tmp_path / "d.npz")
    back = Demos.load_steps(tmp_path / "d.npz")
    assert np.array_equal(back.obs, obs) and np.array_equal(back.actions, actions)
    assert len(back.successful().obs) == 4  # one successful episode of all the steps
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        Demos.load_steps(tmp_path / "missing.npz")
    np.savez(tmp_path / "other.npz", x=obs)
    with pytest.raises(ValueError, match="other.npz: not a file of the teacher's steps"):
        Demos.load_steps(tmp_path / "other.npz")
    np.savez(tmp_path / "short.npz", obs=obs, actions=actions[:3])
    with pytest.raises(ValueError, match="short.npz: .* are not steps"):
        Demos.load_steps(tmp_path / "short.npz")


def test_the_teacher_refuses_other_tasks_and_controllers() -> None:
    from tasks.teacher import check_task

    check_task("OpenDoor-v0", "pd_ee_delta_pos")
    with pytest.raises(ValueError, match="opens parts only"):
        check_task("CloseDoor-v0", "pd_ee_delta_pos")
    with pytest.raises(ValueError, match="pd_ee_delta_pos"):
        check_task("OpenDrawer-v0", "pd_joint_delta_pos")


def test_opening_direction_is_the_drawer_axis_or_the_door_handles_tangent() -> None:
    """A hand-computed case: a door hinged on the world z axis through (1, 0, 0) with its
    handle 0.5 m along +y from the hinge opens (right-handed about +z) toward -x; with the
    hinge axis flipped it opens toward +x; a drawer's handle moves along its axis."""
    from types import SimpleNamespace

    import torch

    from tasks.teacher import opening_direction

    def env(joint_type: str, axis: tuple[float, float, float]) -> SimpleNamespace:
        return SimpleNamespace(
            joint_axis_world=lambda: torch.tensor([axis]),
            episode_parts=[SimpleNamespace(joint_type=joint_type)],
            target_link=SimpleNamespace(pose=SimpleNamespace(p=torch.tensor([[1.0, 0.0, 0.3]]))),
        )

    handle = np.array([1.0, 0.5, 0.9])
    assert np.allclose(opening_direction(env("revolute", (0, 0, 1)), handle), [-1, 0, 0])
    assert np.allclose(opening_direction(env("revolute", (0, 0, -1)), handle), [1, 0, 0])
    assert np.allclose(opening_direction(env("prismatic", (1, 0, 0)), handle), [1, 0, 0])
