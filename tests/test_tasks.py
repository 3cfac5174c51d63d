"""tasks: env checker, determinism, success flag, dense reward, curriculum, robot placement,
scripted solver, physics randomization (training and evaluation: tests/test_train.py)."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from asset_fixtures import write_task_assets

import tasks  # noqa: F401  (registers the envs)
from asset_pipeline.assets.built_asset import MovablePart


@pytest.fixture(scope="module")
def procedural_assets(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Built procedural assets: a desk with drawers, a microwave with a side-hinged door,
    an oven with a bottom-hinged door and a fridge with two side-hinged doors."""
    return write_task_assets(tmp_path_factory.mktemp("assets"))


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


def test_robot_frame_obs_are_the_world_vectors_along_the_robot_base_axes(
    procedural_assets: Path,
) -> None:
    """``robot_frame_obs=True``: the hand-to-handle vector and the joint axis turned into
    the robot base's frame, and for a door the vector from its hinge line to its handle
    (square to the hinge, ending on it); off by default."""
    env = _make("OpenDoor-v0", procedural_assets, obs_mode="state_dict", robot_frame_obs=True)
    try:
        for seed in range(4):
            obs, _ = env.reset(seed=seed)
            u, extra = env.unwrapped, {k: v[0].numpy() for k, v in obs["extra"].items()}
            base = u.agent.robot.pose.to_transformation_matrix()[0, :3, :3].numpy()
            np.testing.assert_allclose(
                base @ extra["tcp_to_handle_robot"], extra["tcp_to_handle"], atol=1e-5
            )
            axis = extra["joint_axis"]
            np.testing.assert_allclose(base @ extra["joint_axis_robot"], axis, atol=1e-5)
            arm = base @ extra["hinge_to_handle_robot"]
            assert abs(arm @ axis) < 1e-5 and np.linalg.norm(arm) > 0.05
            on_hinge = extra["handle_pos"] - arm - u.target_link.pose.p[0].numpy()
            assert np.linalg.norm(np.cross(on_hinge, axis)) < 1e-4
    finally:
        env.close()
    env = _make("OpenDrawer-v0", procedural_assets, obs_mode="state_dict", robot_frame_obs=True)
    try:
        obs, _ = env.reset(seed=0)
        assert "tcp_to_handle_robot" in obs["extra"] and "hinge_to_handle_robot" not in obs["extra"]
    finally:
        env.close()
    env = _make("OpenDoor-v0", procedural_assets, obs_mode="state_dict")
    try:
        obs, _ = env.reset(seed=0)
        assert not [k for k in obs["extra"] if k.endswith("_robot")]
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


def test_near_start_curriculum_puts_the_fingers_round_the_handle(procedural_assets: Path) -> None:
    """``near_start_prob=1`` starts every drawer episode with the TCP a few cm from the
    handle (about 12 cm without it); the option is refused for door and closing tasks."""

    def reset_distances(prob: float) -> list[float]:
        env = _make("OpenDrawer-v0", procedural_assets, near_start_prob=prob)
        try:
            dists = []
            for seed in range(4):
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
