"""PPO (stable-baselines3) on the drawer / door tasks, CleanRL-style: read it top to bottom.

CPU (default): ``num_envs`` single-env ManiSkill processes in a gymnasium
``AsyncVectorEnv`` (one physx_cpu env per process, a new asset loaded every
``reconfiguration_freq`` episodes),
adapted to SB3's VecEnv API by :func:`sb3_vec_env`. GPU: one ManiSkill env
with ``num_envs`` sub-scenes on ``physx_cuda`` behind ManiSkill's SB3 wrapper.

Logs (TensorBoard and CSV in ``out_dir``): SB3's rollout/ep_rew_mean and
rollout/success_rate, and every ``eval_every`` steps eval/success_rate and
eval/return on held-out assets (also ``eval.csv`` with wall-clock seconds).
The policy is saved as ``out_dir/policy.zip`` at every evaluation, with the learning
curve (``curve.png``) and a checkpoint to resume from (``checkpoint/``: the model with
its optimizer, the observation normalizer, the steps and wall-clock so far); the last
evaluation episodes are recorded as videos (``videos/``).

    python -m tasks.train --assets out/train --eval-assets out/test --total-timesteps 200000
"""

from __future__ import annotations

import csv
import gc
import json
import logging
import multiprocessing
import shutil
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

log = logging.getLogger(__name__)


@dataclass
class Args:
    env_id: str = "OpenDrawer-v0"
    """task id: OpenDrawer-v0, CloseDrawer-v0, OpenDoor-v0 or CloseDoor-v0"""
    assets: str = "out"
    """folder of built assets or catalog file to train on"""
    eval_assets: str | None = None
    """held-out assets for evaluation (None: the training assets)"""
    category: str | None = None
    """only assets of this category (None: every category)"""
    num_envs: int = 4
    """parallel envs: processes with vector "async", sub-scenes on physx_cuda"""
    vector: str = "async"
    """CPU: "async" (a process per env) or "sync" (envs stepped in turn in this process)"""
    total_timesteps: int = 200_000
    """environment steps to train, summed over the envs"""
    max_minutes: float | None = None
    """wall-clock limit in minutes, then evaluate and save (None: steps only)"""
    sim_backend: str = "physx_cpu"
    """physx_cpu (vector of processes) or physx_cuda (one batched GPU env)"""
    control_mode: str = "pd_ee_delta_pos"
    """controller: pd_ee_delta_pos (easiest), pd_ee_delta_pose or pd_joint_delta_pos"""
    reward_mode: str = "normalized_dense"
    """ManiSkill reward: normalized_dense (dense / 6), dense or sparse (docs/tasks.md)"""
    control_freq: int = 10
    """policy steps per simulated second, training and evaluation (physics at 100 Hz)"""
    max_episode_steps: int = 30
    """training episode length in policy steps (30: 3 s at 10 Hz)"""
    eval_max_episode_steps: int | None = None
    """evaluation episode length (None: the task's, 5 s for drawers, 7.5 s for doors)"""
    ignore_terminations: bool = True
    """training episodes run their full length past success (evaluation ends at it)"""
    reconfiguration_freq: int = 10
    """reload an asset every k episodes per env (1: every episode; 0: never)"""
    learning_rate: float = 3e-4
    """PPO's initial learning rate"""
    lr_anneal_steps: int | None = 600_000
    """env steps over which the learning rate decays linearly to 0 (None: constant)"""
    n_steps: int = 128
    """rollout length per env, in policy steps"""
    batch_size: int = 256
    """PPO minibatch size, in transitions"""
    n_epochs: int = 5
    """PPO epochs over each rollout"""
    gamma: float = 0.9
    """discount factor per policy step"""
    gae_lambda: float = 0.95
    """GAE lambda"""
    ent_coef: float = 0.0
    """entropy bonus coefficient (0: none)"""
    target_kl: float | None = None
    """stop an update's epochs once approximate KL > 1.5 x this (None: no limit)"""
    log_std_init: float = -2.0
    """initial log std of the Gaussian policy (-2: 1.4 cm per step in pd_ee_delta_pos)"""
    gripper_log_std_init: float | None = None
    """initial log std of the gripper action alone (None: log_std_init)"""
    gripper_init: float | None = None
    """initial mean gripper action, -1..1 = fingers -0.01..0.04 m (None: SB3's 0)"""
    near_start_prob: float = 0.0
    """OpenDrawer-v0: share of training episodes starting with fingers round the handle"""
    require_grasp: bool = True
    """dense reward's grasp term only for a real grasp, not a hook (False: the env's)"""
    robot_frame_obs: bool = True
    """observe the hand-to-handle vector, the joint axis and a door's hinge-to-handle vector
    along the robot base's axes too (the env's ``robot_frame_obs``; a saved run without
    it in its args.json was trained without them)"""
    demo_episodes: int = 0
    """OpenDrawer-v0, OpenDoor-v0: episodes of the scripted teacher (tasks.teacher) on the
    training assets whose actions the policy is fitted to before PPO starts (0: PPO from
    scratch)"""
    demos_from: str | None = None
    """a run's teacher_demos.npz: clone those steps instead of running the teacher (its
    episodes, demo_episodes, are then not run; the other cloning settings apply)"""
    demo_workers: int = 2
    """processes collecting the teacher's episodes"""
    bc_epochs: int = 100
    """epochs of behaviour cloning on the teacher's successful episodes"""
    bc_obs_noise: float = 0.0
    """standard deviation of Gaussian noise on the (normalized) observations while cloning"""
    clone_members: int = 1
    """with demo_episodes or demos_from: clones fitted from different initial weights whose
    mean action is the policy (tasks.teacher.clone: one MLP, the members' hidden units side
    by side, each net_arch wide; the value function stays net_arch wide)"""
    dagger_rounds: int = 0
    """with demo_episodes: rounds of DAgger after the first clone (tasks.teacher.
    collect_corrections): the clone runs dagger_episodes episodes, the teacher labels the
    states it visits, and the clone is fitted again to all steps so far"""
    dagger_episodes: int = 200
    """the clone's episodes per DAgger round"""
    anchor_batches: int = 0
    """with demo_episodes: minibatches of behaviour cloning on the teacher's successful steps
    between PPO's updates (tasks.teacher.CloneAnchor; 0: none), so that PPO improves the
    clone without trading its grasps for hooks"""
    anchor_learning_rate: float = 1e-4
    """learning rate of those minibatches"""
    critic_warmup_steps: int = 0
    """env steps at the start of PPO during which only the value function learns (the
    policy's mean and log std frozen): a cloned actor is not moved by the advantages of an
    untrained critic"""
    randomize_physics: bool = False
    """training envs scale each object's movable parts' mass, damping and friction at every
    load (tasks.articulated.PhysicsRandomization's ranges); evaluation never does"""
    normalize_obs: bool = True
    """running mean/std observation normalization, saved beside the policy (obs_norm.npz)"""
    update_obs_norm: bool = True
    """update the normalization's statistics from PPO's rollouts (False: keep those it
    starts with, with demo_episodes the teacher's: a clone's inputs then do not drift)"""
    net_arch: list[int] = field(default_factory=lambda: [256, 256])
    """hidden layer widths of the policy and value MLPs"""
    seed: int = 0
    """random seed of PPO and the envs"""
    out_dir: str = "runs/ppo"
    """run folder: policy.zip, obs_norm.npz, args.json, progress.csv, eval.csv, TensorBoard"""
    eval_every: int = 20_000
    """env steps between held-out evaluations (0: none)"""
    eval_episodes: int = 10
    """episodes per periodic evaluation"""
    device: str = "cpu"
    """torch device of the learner"""
    torch_threads: int = 1
    """torch threads per process, learner and each env worker (0: torch's default)"""
    resume: bool = False
    """continue the run in out_dir from its last checkpoint (out_dir/checkpoint), if any"""
    progress_bar: bool = True
    """show a progress bar of the env steps (SB3's, drawn with rich)"""
    video_episodes: int = 2
    """held-out episodes recorded in out_dir/videos when training ends (0: none)"""

    @property
    def clones_teacher(self) -> bool:
        """The run starts from a clone of the teacher (its episodes or a saved run's steps)."""
        return self.demo_episodes > 0 or bool(self.demos_from)


#: Training episode length of the recipe per task, in policy steps at 10 Hz: a drawer
#: is pulled in 3 s; a door's handle travels an arc, 5 s.
RECIPE_EPISODE_STEPS = {
    "OpenDrawer-v0": 30,
    "CloseDrawer-v0": 30,
    "OpenDoor-v0": 50,
    "CloseDoor-v0": 50,
}


def recipe_episode_steps(env_id: str) -> int:
    """The recipe's training episode length for ``env_id`` (:data:`RECIPE_EPISODE_STEPS`)."""
    return RECIPE_EPISODE_STEPS.get(env_id, Args.max_episode_steps)


# --------------------------------------------------------------------------- envs


class FlattenStateObs(gym.ObservationWrapper):
    """Observations as one float32 numpy vector (state obs are already flat; dicts get concatenated)."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        obs, _ = env.reset(seed=0)
        n = self.observation(obs).shape[0]
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (n,), np.float32)

    def observation(self, obs: Any) -> np.ndarray:
        if isinstance(obs, dict):
            parts = [self.observation(obs[k]) for k in sorted(obs)]
            return np.concatenate(parts).astype(np.float32) if parts else np.zeros(0, np.float32)
        return np.asarray(obs, dtype=np.float32).reshape(-1)


class SuccessInfo(gym.Wrapper):
    """Adds SB3's ``is_success`` (success at any step of the episode) and the episode
    statistics ``episode={r, l, t}`` to the infos of an episode's last step."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self._ret, self._len, self._t0, self._success = 0.0, 0, time.time(), False

    def reset(self, **kw: Any) -> tuple[Any, dict]:
        self._ret, self._len, self._success = 0.0, 0, False
        return self.env.reset(**kw)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        obs, r, term, trunc, info = self.env.step(action)
        self._ret += float(r)
        self._len += 1
        self._success |= bool(info.get("success", False))
        if term or trunc:
            info["is_success"] = self._success
            info["episode"] = {"r": self._ret, "l": self._len, "t": time.time() - self._t0}
        return obs, float(r), bool(term), bool(trunc), info


_GC_FROZEN = False


def freeze_gc() -> None:
    """Once per process: collect, then move every object alive (imports, torch, the
    first scene) out of the cyclic garbage collector's sight (``gc.freeze``).

    ManiSkill calls ``gc.collect()`` at every reconfiguration (to free GPU memory); in a
    CPU process holding torch that full collection is most of an asset reload (a
    reload took 0.29 s, a lone ``gc.collect()`` in that process 0.16 s), and reloads
    happen every few episodes. After the freeze a reload took 0.03 s, and the resident
    memory stayed flat over 150 reloads (objects created later, the later scenes among
    them, are collected as before).
    """
    global _GC_FROZEN
    if not _GC_FROZEN:
        gc.collect()
        gc.freeze()
        _GC_FROZEN = True


def make_cpu_env(
    env_id: str,
    assets: str,
    seed: int = 0,
    render_mode: str | None = None,
    ignore_terminations: bool = False,
    **kwargs: Any,
) -> gym.Env:
    """One ManiSkill env on physx_cpu as a plain gymnasium env with numpy observations
    (``ignore_terminations``: episodes end only at the time limit, not at success).
    Freezes the process's garbage collector once the env exists (:func:`freeze_gc`)."""
    from mani_skill.utils.wrappers import CPUGymWrapper

    import tasks  # noqa: F401  (registers the envs)

    kwargs.setdefault("obs_mode", "state")
    kwargs.setdefault(
        "render_backend", "none" if render_mode is None and kwargs["obs_mode"] == "state" else "cpu"
    )
    env = gym.make(
        env_id, assets=assets, sim_backend="physx_cpu", render_mode=render_mode, **kwargs
    )
    env = CPUGymWrapper(env, ignore_terminations=ignore_terminations)
    env = SuccessInfo(FlattenStateObs(env))
    env.action_space.seed(seed)
    freeze_gc()
    return env


def _env_fn(args: Args, rank: int):
    def thunk() -> gym.Env:
        set_torch_threads(args.torch_threads)
        return make_cpu_env(
            args.env_id,
            args.assets,
            seed=args.seed + rank,
            category=args.category,
            control_mode=args.control_mode,
            reward_mode=args.reward_mode,
            max_episode_steps=args.max_episode_steps,
            reconfiguration_freq=args.reconfiguration_freq,
            ignore_terminations=args.ignore_terminations,
            sim_config={"control_freq": args.control_freq},
            near_start_prob=args.near_start_prob,
            require_grasp=args.require_grasp,
            robot_frame_obs=args.robot_frame_obs,
            physics_randomization=physics_randomization(args),
        )

    return thunk


def physics_randomization(args: Args) -> Any:
    """The training envs' PhysicsRandomization (None: the assets' own physics)."""
    from tasks.articulated import PhysicsRandomization

    return PhysicsRandomization() if args.randomize_physics else None


def set_torch_threads(n: int) -> None:
    """Torch's intra-op threads for this process (``n`` <= 0: leave torch's default)."""
    if n > 0:
        import torch

        torch.set_num_threads(n)


def sb3_vec_env(venv: gym.vector.VectorEnv):
    """Wrap a gymnasium vector env (autoreset_mode=SAME_STEP) as an SB3 VecEnv."""
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv

    class _Adapter(VecEnv):
        def __init__(self) -> None:
            self.venv = venv
            super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
            self._actions: np.ndarray | None = None
            self._seed: int | None = None

        def reset(self) -> np.ndarray:
            obs, _ = self.venv.reset(seed=self._seed)
            self._seed = None
            return obs

        def step_async(self, actions: np.ndarray) -> None:
            self._actions = actions

        def step_wait(self):
            obs, rew, term, trunc, infos = self.venv.step(self._actions)
            done = term | trunc
            out = []
            for i in range(self.num_envs):
                info: dict[str, Any] = {}
                if done[i] and "final_info" in infos:
                    info.update(_index_info(infos["final_info"], i))
                    info["terminal_observation"] = infos["final_obs"][i]
                    info["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
                out.append(info)
            return obs, rew.astype(np.float32), done, out

        def close(self) -> None:
            self.venv.close()

        def terminate_workers(self) -> None:
            """End the env processes without waiting for their replies (a stopped run)."""
            self.venv.close(terminate=True)

        def seed(self, seed: int | None = None):
            self._seed = seed
            return [seed] * self.num_envs

        def get_attr(self, attr_name, indices=None):
            return [getattr(self.venv, attr_name)] * len(self._get_indices(indices))

        def set_attr(self, attr_name, value, indices=None) -> None:
            setattr(self.venv, attr_name, value)

        def env_method(self, method_name, *args, indices=None, **kwargs):
            return [None] * len(self._get_indices(indices))

        def env_is_wrapped(self, wrapper_class, indices=None):
            return [False] * len(self._get_indices(indices))

    return _Adapter()


def _index_info(infos: dict, i: int) -> dict[str, Any]:
    out = {}
    for k, v in infos.items():
        if k.startswith("_"):
            continue
        mask = infos.get("_" + k)
        if mask is not None and not mask[i]:
            continue
        out[k] = _index_info(v, i) if isinstance(v, dict) else v[i]
    return out


def make_train_env(args: Args):
    """The SB3 VecEnv for ``args`` (CPU process vector or GPU batched env)."""
    if args.sim_backend == "physx_cpu":
        fns = [_env_fn(args, i) for i in range(args.num_envs)]
        mode = gym.vector.AutoresetMode.SAME_STEP
        if args.num_envs == 1 or args.vector == "sync":
            venv = gym.vector.SyncVectorEnv(fns, autoreset_mode=mode)
        else:
            venv = gym.vector.AsyncVectorEnv(fns, autoreset_mode=mode, context="spawn")
        return sb3_vec_env(venv)
    # GPU: all envs in one process; different assets per sub-scene (untested here: no GPU)
    from mani_skill.vector.wrappers.sb3 import ManiSkillSB3VectorEnv

    import tasks  # noqa: F401

    env = gym.make(
        args.env_id,
        assets=args.assets,
        category=args.category,
        num_envs=args.num_envs,
        sim_backend=args.sim_backend,
        obs_mode="state",
        control_mode=args.control_mode,
        reward_mode=args.reward_mode,
        max_episode_steps=args.max_episode_steps,
        reconfiguration_freq=0,  # each sub-scene keeps its asset; parts are re-sampled
        near_start_prob=args.near_start_prob,
        require_grasp=args.require_grasp,
        robot_frame_obs=args.robot_frame_obs,
        physics_randomization=physics_randomization(args),
    )
    return ManiSkillSB3VectorEnv(env)


# --------------------------------------------------------------------------- evaluation


@dataclass
class ObsNorm:
    """SB3 VecNormalize's observation transform as plain arrays (saved as ``obs_norm.npz``)."""

    mean: np.ndarray
    var: np.ndarray
    clip: float = 10.0
    epsilon: float = 1e-8

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        z = (obs - self.mean) / np.sqrt(self.var + self.epsilon)
        return np.clip(z, -self.clip, self.clip).astype(np.float32)

    @classmethod
    def from_vec_normalize(cls, vn: Any) -> ObsNorm:
        return cls(vn.obs_rms.mean.copy(), vn.obs_rms.var.copy(), vn.clip_obs, vn.epsilon)

    def save(self, path: Path) -> None:
        np.savez(path, mean=self.mean, var=self.var, clip=self.clip, epsilon=self.epsilon)

    @classmethod
    def load(cls, path: Path) -> ObsNorm:
        z = np.load(path)
        return cls(z["mean"], z["var"], float(z["clip"]), float(z["epsilon"]))


def load_policy(path: str | Path) -> tuple[Any, ObsNorm | None, dict[str, Any]]:
    """A saved run's PPO policy, its observation normalization (if any) and its Args."""
    from stable_baselines3 import PPO

    path = Path(path)
    run = path.parent
    norm = ObsNorm.load(run / "obs_norm.npz") if (run / "obs_norm.npz").is_file() else None
    saved = json.loads((run / "args.json").read_text()) if (run / "args.json").is_file() else {}
    return PPO.load(str(path), device="cpu"), norm, saved


def evaluate(
    policy: Any,
    env_id: str,
    assets: str,
    episodes: int = 10,
    seed: int = 10_000,
    video_dir: str | Path | None = None,
    deterministic: bool = True,
    obs_norm: ObsNorm | None = None,
    **env_kwargs: Any,
) -> dict[str, Any]:
    """Success rate, mean return and grasp rate of ``policy`` (an SB3 model or a path to
    one) on ``assets``; an episode counts as grasped when ``is_grasped`` was true at any
    step (a policy can also open a drawer by hooking its handle).

    Episode k is seeded ``seed + k`` (each reset loads an asset sampled from ``assets``).
    A policy given by path brings its run's observation normalization and its control
    mode and episode length (``args.json``) unless ``env_kwargs`` say otherwise.
    With ``video_dir`` each episode is written as mp4 (imageio) or, failing that, PNG frames.
    """
    if isinstance(policy, (str, Path)):
        policy, saved_norm, saved = load_policy(policy)
        obs_norm = obs_norm or saved_norm
        if "control_mode" in saved:
            env_kwargs.setdefault("control_mode", saved["control_mode"])
        env_kwargs.setdefault("robot_frame_obs", bool(saved.get("robot_frame_obs", False)))
        freq = int(saved.get("control_freq", 20))
        if freq != 20:
            env_kwargs.setdefault("sim_config", {"control_freq": freq})
        for k, v in eval_episode_steps(env_id, saved.get("eval_max_episode_steps"), freq).items():
            env_kwargs.setdefault(k, v)
    env = make_cpu_env(env_id, assets, render_mode="rgb_array" if video_dir else None, **env_kwargs)
    norm = obs_norm or (lambda o: o)
    rows: list[dict[str, Any]] = []
    try:
        for k in range(episodes):
            obs, _ = env.reset(seed=seed + k)
            frames = [env.render()] if video_dir else []
            done, ret, info, held, widest = False, 0.0, {}, False, 0.0
            while not done:
                action, _ = policy.predict(norm(obs), deterministic=deterministic)
                obs, r, term, trunc, info = env.step(action)
                ret += r
                held = held or bool(info.get("is_grasped", False))
                widest = max(widest, float(info.get("open_fraction", 0.0)))
                done = term or trunc
                if video_dir:
                    frames.append(env.render())
            asset, part = env.unwrapped.episode_assets[0], env.unwrapped.episode_parts[0]
            rows.append(
                {
                    "asset": asset.id,
                    "category": asset.category or "unknown",
                    "part": part.name,
                    "part_kind": part.kind,
                    "handle_kind": part.handle_kind,
                    "success": bool(info.get("success", False)),
                    "return": float(ret),
                    "grasped": held,
                    "open_fraction": round(float(info.get("open_fraction", 0.0)), 4),
                    "max_open_fraction": round(widest, 4),
                }
            )
            if video_dir:
                write_video(frames, Path(video_dir) / f"episode_{k:03d}_{asset.id}_{part.name}")
    finally:
        env.close()

    def mean(key: str) -> float:
        return float(np.mean([r[key] for r in rows])) if rows else 0.0

    return {
        "success_rate": mean("success"),
        "mean_return": mean("return"),
        "grasp_rate": mean("grasped"),
        "by_category": success_table(rows, "category"),
        "by_part_kind": success_table(rows, "part_kind"),
        "episodes": rows,
    }


def success_table(episodes: list[dict[str, Any]], key: str) -> dict[str, dict[str, Any]]:
    """Per value of ``key`` (category, part_kind, ...): episodes, successes, success rate,
    and how far the failures opened the part (mean of the episodes' last open fraction,
    None without failures)."""
    table: dict[str, dict[str, Any]] = {}
    for value in sorted({e[key] for e in episodes}):
        group = [e for e in episodes if e[key] == value]
        failed = [e["open_fraction"] for e in group if not e["success"]]
        ok = sum(e["success"] for e in group)
        table[value] = {
            "episodes": len(group),
            "success": ok,
            "success_rate": round(ok / len(group), 4),
            "failed_open_fraction": round(float(np.mean(failed)), 4) if failed else None,
        }
    return table


def eval_episode_steps(env_id: str, n: int | None, control_freq: int) -> dict[str, int]:
    """``max_episode_steps`` for evaluation: ``n``, else the task's registered length
    (set for 20 Hz) scaled to ``control_freq``, else nothing (the registered default)."""
    if n is None and control_freq != 20:
        import tasks  # noqa: F401  (registers the envs)

        registered = gym.spec(env_id).max_episode_steps
        n = None if registered is None else max(1, round(registered * control_freq / 20))
    return {} if n is None else {"max_episode_steps": n}


def write_video(frames: list[Any], stem: Path, fps: int = 20) -> Path:
    """Write rgb frames as ``stem.mp4`` (imageio + ffmpeg), else ``stem.gif``, else PNGs."""
    stem.parent.mkdir(parents=True, exist_ok=True)
    imgs = [np.asarray(f).reshape(np.asarray(f).shape[-3:]).astype(np.uint8) for f in frames]
    try:
        import imageio.v2 as imageio

        try:
            path = stem.with_suffix(".mp4")
            imageio.mimsave(path, imgs, fps=fps)
        except Exception:  # no ffmpeg backend
            path = stem.with_suffix(".gif")
            imageio.mimsave(path, imgs, duration=1 / fps)
        return path
    except ImportError:
        from PIL import Image

        stem.mkdir(parents=True, exist_ok=True)
        for i, im in enumerate(imgs):
            Image.fromarray(im).save(stem / f"{i:04d}.png")
        return stem


# --------------------------------------------------------------------------- training


class TrainingArgsError(ValueError):
    """Training arguments that cannot run together (the message names the options)."""


class TrainingStopped(Exception):
    """A signal stopped the run (SIGTERM: ``kill``, a job scheduler; SIGINT: Ctrl-C); it
    saved its checkpoint first. ``signum``: the signal's number."""

    def __init__(self, message: str, signum: int = signal.SIGTERM) -> None:
        super().__init__(message)
        self.signum = int(signum)


@contextmanager
def stop_on_sigterm() -> Iterator[None]:
    """Within: SIGTERM raises :class:`TrainingStopped` in the main thread, so a run saves
    its checkpoint and closes its env workers instead of ending at once (SIGINT already
    raises KeyboardInterrupt, unless the shell that started the run ignores it, as a
    non-interactive shell does for a background job). Outside the main thread, nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise TrainingStopped(signal.Signals(signum).name, signum)

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def start_from_teacher(model: Any, venv: Any, args: Args) -> tuple[dict[str, Any], Any]:
    """Fit ``model``'s policy to the scripted teacher's successful episodes on the training
    assets (tasks.teacher), and start the observation normalizer from their statistics;
    then ``args.dagger_rounds`` rounds of DAgger (the clone's episodes labelled by the
    teacher, the clone fitted again to every step so far). Returns what was done (episodes,
    successful ones, cloned steps, the cloning loss at its first and last epoch, each
    DAgger round's episodes, the clone's success in them and its steps, and the seconds it
    took: they count in the run's wall-clock) and the steps cloned (``tasks.teacher.Demos``)."""
    import tempfile

    from tasks.teacher import Demos, check_task, join_demos

    check_task(args.env_id, args.control_mode)
    t0 = time.time()
    report: dict[str, Any] = {}
    if args.demos_from:
        demos = Demos.load_steps(args.demos_from)
        width = venv.observation_space.shape[0]
        if demos.obs.shape[1] != width:
            raise ValueError(
                f"{args.demos_from}: {demos.obs.shape[1]} observations a step, the task's "
                f"{width} (another task or observation set)"
            )
        report["demos_from"] = str(args.demos_from)
    else:
        collected = _in_workers(_collect_demos, args, args.demo_episodes, 50_000)
        demos = collected.successful()
        if len(demos.obs) == 0:
            raise RuntimeError(
                f"{args.assets}: the teacher opened no part in {len(collected.success)} episodes"
            )
        report.update(episodes=len(collected.success), successful=int(demos.success.sum()))
    normalize = None
    if hasattr(venv, "obs_rms"):
        venv.obs_rms.mean = demos.obs.mean(axis=0).astype(np.float64)
        venv.obs_rms.var = demos.obs.var(axis=0).astype(np.float64)
        venv.obs_rms.count = float(len(demos.obs))
        normalize = ObsNorm.from_vec_normalize(venv)
    losses = _clone(model, demos, normalize, args, args.seed)
    report.update(
        steps=len(demos.obs), bc_loss_first=round(losses[0], 5), bc_loss_last=round(losses[-1], 5)
    )
    rounds = []
    for r in range(args.dagger_rounds):
        with tempfile.TemporaryDirectory() as tmp:
            policy_zip = str(Path(tmp) / "clone.zip")
            model.save(policy_zip)
            seed = 70_000 + r * args.dagger_episodes
            fixes = _in_workers(
                _collect_corrections, args, args.dagger_episodes, seed, policy_zip, normalize
            )
        demos = join_demos(demos, fixes)
        losses = _clone(model, demos, normalize, args, args.seed + r + 1)
        rounds.append(
            {
                "episodes": len(fixes.success),
                "clone_success": round(float(fixes.success.mean()), 4),
                "steps": len(fixes.obs),
                "bc_loss_last": round(losses[-1], 5),
            }
        )
        log.info("DAgger round %d: %s", r + 1, rounds[-1])
    if rounds:
        report["dagger"] = rounds
    report["seconds"] = round(time.time() - t0, 1)
    log.info("behaviour cloning on the teacher's episodes: %s", report)
    return report, demos


def _clone(model: Any, demos: Any, normalize: Any, args: Args, seed: int) -> list[float]:
    """Fit ``model``'s policy to ``demos`` per ``args`` (``args.clone_members`` averaged)."""
    from tasks.teacher import clone

    return clone(
        model, demos, normalize, epochs=args.bc_epochs, seed=seed,
        obs_noise=args.bc_obs_noise, members=args.clone_members,
    )  # fmt: skip


def policy_net_arch(args: Args) -> list[int] | dict[str, list[int]]:
    """The PPO policy's ``net_arch``: ``args.net_arch`` for both MLPs, the policy's
    ``args.clone_members`` times as wide when that many clones are averaged in it."""
    if args.clone_members > 1:
        return {"pi": [w * args.clone_members for w in args.net_arch], "vf": list(args.net_arch)}
    return list(args.net_arch)


def _in_workers(collect: Any, args: Args, episodes: int, seed: int, *extra: Any) -> Any:
    """``collect(args, n, seed_i, *extra)`` in ``args.demo_workers`` processes, the
    ``episodes`` shared out and seeded one after another; their Demos joined."""
    from concurrent.futures import ProcessPoolExecutor

    from tasks.teacher import join_demos

    workers = max(1, min(args.demo_workers, episodes))
    share = [episodes // workers + (i < episodes % workers) for i in range(workers)]
    seeds = [seed + sum(share[:i]) for i in range(workers)]
    if workers == 1:
        return collect(args, share[0], seeds[0], *extra)
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        n = len(share)
        parts = list(pool.map(collect, [args] * n, share, seeds, *[[e] * n for e in extra]))
    return join_demos(*parts)


def set_actor_trainable(model: Any, trainable: bool) -> None:
    """Let PPO's updates move ``model``'s policy mean and log std, or not (then only the
    value function learns: the critic's warm-up)."""
    from tasks.teacher import actor_parameters

    for p in [*actor_parameters(model.policy), model.policy.log_std]:
        p.requires_grad_(trainable)


def _collect_demos(args: Args, episodes: int, seed: int) -> Any:
    """The teacher's episodes on the training assets, each loading an asset, of the task's
    own length (7.5 s for doors, 5 s for drawers)."""
    from tasks.teacher import collect_demos

    set_torch_threads(args.torch_threads)
    env = _teacher_env(args)
    try:
        return collect_demos(env, episodes, seed=seed)
    finally:
        env.close()


def _collect_corrections(
    args: Args, episodes: int, seed: int, policy_zip: str, normalize: ObsNorm | None
) -> Any:
    """The clone saved at ``policy_zip`` run on the training assets as in
    :func:`_collect_demos`, the teacher labelling its states (DAgger)."""
    from stable_baselines3 import PPO

    from tasks.teacher import collect_corrections

    set_torch_threads(args.torch_threads)
    model = PPO.load(policy_zip, device="cpu")
    norm = normalize or (lambda o: o)
    env = _teacher_env(args)
    try:
        return collect_corrections(
            env, lambda o: model.predict(norm(o), deterministic=True)[0], episodes, seed=seed
        )
    finally:
        env.close()


def _teacher_env(args: Args) -> gym.Env:
    """The env the teacher's episodes run in: the training assets, one per episode, with
    the training envs' physics randomization (so a clone also sees heavy doors' states)."""
    return make_cpu_env(
        args.env_id, args.assets, category=args.category, control_mode=args.control_mode,
        sim_config={"control_freq": args.control_freq}, reconfiguration_freq=1,
        robot_frame_obs=args.robot_frame_obs,
        physics_randomization=physics_randomization(args),
        **eval_episode_steps(args.env_id, None, args.control_freq),
    )  # fmt: skip


def learning_rate_schedule(args: Args) -> Any:
    """``args.learning_rate``, or with ``lr_anneal_steps`` SB3's schedule form (a function
    of the remaining progress, 1 at the start and 0 at ``total_timesteps``) of a linear
    decay to zero at ``lr_anneal_steps`` steps."""
    if args.lr_anneal_steps is None:
        return args.learning_rate
    lr0, total, horizon = args.learning_rate, args.total_timesteps, args.lr_anneal_steps

    def schedule(progress_remaining: float) -> float:
        steps = (1.0 - progress_remaining) * total
        return lr0 * max(0.0, 1.0 - steps / horizon)

    return schedule


def set_initial_log_std(model: Any, index: int, value: float) -> None:
    """Set an SB3 Gaussian policy's initial log std in dimension ``index`` (its
    state-independent ``log_std`` parameter)."""
    import torch

    with torch.no_grad():
        model.policy.log_std[index] = float(value)


def set_initial_action_mean(model: Any, index: int, value: float) -> None:
    """Make an SB3 Gaussian policy's mean action ``value`` in dimension ``index`` at the
    start: its action layer starts with near-zero weights (orthogonal, gain 0.01), so the
    layer's bias is the initial mean."""
    import torch

    with torch.no_grad():
        model.policy.action_net.bias[index] = float(value)


def plot_curve(rows: list[dict[str, Any]], path: Path, title: str) -> bool:
    """The held-out success rate against wall-clock minutes as a PNG (matplotlib); False
    when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, ax = plt.subplots(figsize=(6, 4))
    minutes = [float(r["wall_seconds"]) / 60 for r in rows]
    ax.plot(minutes, [float(r["success_rate"]) for r in rows], marker="o")
    ax.set_xlabel("wall-clock (min)")
    ax.set_ylabel("held-out success rate")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return True


@dataclass
class Checkpoint:
    """Where a run resumes from: ``out_dir/checkpoint/`` holds the PPO model (with its
    optimizer), the observation normalizer and ``state.json`` (env steps and wall-clock
    seconds so far)."""

    folder: Path

    @property
    def model(self) -> Path:
        return self.folder / "model.zip"

    @property
    def normalizer(self) -> Path:
        return self.folder / "vec_normalize.pkl"

    @property
    def state(self) -> Path:
        return self.folder / "state.json"

    def exists(self) -> bool:
        return self.model.is_file() and self.state.is_file()

    def seconds(self) -> float:
        return float(json.loads(self.state.read_text())["wall_seconds"])

    def save(self, model: Any, venv: Any, wall_seconds: float) -> None:
        """Model, normalizer, then the state last: a checkpoint cut off half-written
        keeps the previous state."""
        from generator.atomic_files import atomic_write_bytes

        self.folder.mkdir(parents=True, exist_ok=True)
        tmp = self.folder / "model.tmp.zip"
        model.save(tmp)
        tmp.replace(self.model)
        if hasattr(venv, "obs_rms"):
            venv.save(str(self.folder / "vec_normalize.tmp.pkl"))
            (self.folder / "vec_normalize.tmp.pkl").replace(self.normalizer)
        state = {"num_timesteps": int(model.num_timesteps), "wall_seconds": round(wall_seconds, 2)}
        atomic_write_bytes(self.state, json.dumps(state).encode())


def train(args: Args) -> dict[str, Any]:
    """Train PPO per ``args``; return paths and the last evaluation.

    With ``args.resume`` and a checkpoint in ``out_dir`` the run goes on from it (steps,
    wall-clock limit, learning-rate schedule and curve continue; the random streams
    start afresh, so a resumed run is not step-for-step the uninterrupted one).
    """
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import VecNormalize

    if args.n_steps < 1 or args.n_steps * args.num_envs < 2:
        raise TrainingArgsError(
            f"--n-steps {args.n_steps} with --num-envs {args.num_envs}: PPO's rollout needs "
            "at least 2 transitions (n_steps >= 1, n_steps x num_envs >= 2)"
        )
    if args.batch_size < 2:
        raise TrainingArgsError(
            f"--batch-size {args.batch_size}: PPO's minibatches need at least 2"
        )
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    set_torch_threads(args.torch_threads)
    ckpt = Checkpoint(out / "checkpoint")
    resuming = args.resume and ckpt.exists()
    if resuming and (out / "args.json").is_file():
        # a run started before the robot-frame observations goes on without them
        saved = json.loads((out / "args.json").read_text())
        args = replace(args, robot_frame_obs=bool(saved.get("robot_frame_obs", False)))
    needs = "it needs --demo-episodes N or --demos-from FILE"
    if args.anchor_batches > 0 and not args.clones_teacher and not resuming:
        raise TrainingArgsError(f"--anchor-batches keeps PPO near a clone: {needs}")
    if args.dagger_rounds > 0 and not args.clones_teacher and not resuming:
        raise TrainingArgsError(f"--dagger-rounds refines a clone of the teacher: {needs}")
    if args.clone_members > 1 and not args.clones_teacher and not resuming:
        raise TrainingArgsError(f"--clone-members averages clones of the teacher: {needs}")
    (out / "args.json").write_text(json.dumps(asdict(args), indent=2))
    eval_assets = args.eval_assets or args.assets
    venv = make_train_env(args)
    schedule = learning_rate_schedule(args)
    if args.normalize_obs:
        if resuming and ckpt.normalizer.is_file():
            venv = VecNormalize.load(str(ckpt.normalizer), venv)
        else:
            venv = VecNormalize(venv, norm_obs=True, norm_reward=False, gamma=args.gamma)
        # False: the statistics stay as they start (a clone's, from the teacher's episodes)
        venv.training = args.update_obs_norm
    teacher: dict[str, Any] | None = None
    if resuming:
        model = PPO.load(
            ckpt.model, env=venv, device=args.device,
            custom_objects={"learning_rate": schedule, "lr_schedule": schedule},
        )  # fmt: skip
        log.info("resuming %s at %d steps", out, model.num_timesteps)
    else:
        model = PPO(
            "MlpPolicy",
            venv,
            learning_rate=schedule,
            n_steps=args.n_steps,
            batch_size=args.batch_size,
            n_epochs=args.n_epochs,
            gamma=args.gamma,
            gae_lambda=args.gae_lambda,
            ent_coef=args.ent_coef,
            target_kl=args.target_kl,
            seed=args.seed,
            device=args.device,
            policy_kwargs={"net_arch": policy_net_arch(args), "log_std_init": args.log_std_init},
            verbose=0,
        )
        if args.gripper_init is not None:
            set_initial_action_mean(model, -1, args.gripper_init)
        if args.gripper_log_std_init is not None:
            set_initial_log_std(model, -1, args.gripper_log_std_init)
        if args.clones_teacher:
            teacher, demos = start_from_teacher(model, venv, args)
            (out / "teacher.json").write_text(json.dumps(teacher, indent=2))
            demos.save_steps(out / "teacher_demos.npz")
    model.set_logger(configure(str(out), ["csv", "tensorboard", "log"]))
    eval_csv = out / "eval.csv"
    if not resuming and eval_csv.exists():
        eval_csv.unlink()
    history: list[dict[str, Any]] = []
    if resuming and eval_csv.exists():
        with open(eval_csv, newline="") as f:
            history = list(csv.DictReader(f))
    # wall-clock of the whole run, across resumes
    t0 = time.time() - (ckpt.seconds() if resuming else teacher["seconds"] if teacher else 0.0)
    eval_kwargs: dict[str, Any] = dict(
        category=args.category,
        control_mode=args.control_mode,
        robot_frame_obs=args.robot_frame_obs,
        sim_config={"control_freq": args.control_freq},
        **eval_episode_steps(args.env_id, args.eval_max_episode_steps, args.control_freq),
    )

    def current_norm() -> ObsNorm | None:
        return ObsNorm.from_vec_normalize(venv) if args.normalize_obs else None

    def save_policy() -> None:
        ckpt.save(model, venv, time.time() - t0)
        # the latest policy, usable while training runs: the checkpoint's model
        shutil.copyfile(ckpt.model, out / "policy.zip")
        if args.normalize_obs:
            current_norm().save(out / "obs_norm.npz")

    class PeriodicEval(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            # a new run is evaluated at its start; a resumed one was at its checkpoint
            self.next_eval = model.num_timesteps + (args.eval_every if resuming else 0)

        def run_eval(self) -> None:
            res = evaluate(
                self.model, args.env_id, eval_assets, args.eval_episodes,
                obs_norm=current_norm(), **eval_kwargs,
            )  # fmt: skip
            row = {
                "timesteps": self.num_timesteps,
                "wall_seconds": round(time.time() - t0, 2),
                "success_rate": res["success_rate"],
                "mean_return": res["mean_return"],
            }
            history.append(row)
            save_policy()
            self.logger.record("eval/success_rate", res["success_rate"])
            self.logger.record("eval/return", res["mean_return"])
            new = not eval_csv.exists()
            with open(eval_csv, "a", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(row))
                if new:
                    w.writeheader()
                w.writerow(row)
            title = f"PPO {args.env_id}: {Path(args.assets).name}, {args.eval_episodes} episodes a point"
            plot_curve(history, out / "curve.png", title)
            log.info("eval at %d steps: %s", self.num_timesteps, row)

        def _on_step(self) -> bool:
            if args.eval_every > 0 and self.num_timesteps >= self.next_eval:
                self.run_eval()
                self.next_eval = self.num_timesteps + args.eval_every
            if args.max_minutes is not None and time.time() - t0 > 60 * args.max_minutes:
                log.info(
                    "stopping at %d steps: %.1f min reached", self.num_timesteps, args.max_minutes
                )
                return False
            return True

        def _on_training_end(self) -> None:
            last = int(history[-1]["timesteps"]) if history else -1
            if last != self.num_timesteps:
                self.run_eval()

    class FromClone(BaseCallback):
        """The critic's warm-up (the actor frozen until ``critic_warmup_steps``) and the
        clone's anchor (``anchor_batches`` of behaviour cloning after each PPO update)."""

        def __init__(self) -> None:
            super().__init__()
            self.frozen = False
            self.anchor = None
            if args.anchor_batches > 0:
                from tasks.teacher import CloneAnchor, Demos

                path = out / "teacher_demos.npz"
                if not path.is_file():
                    raise FileNotFoundError(
                        f"{path}: --anchor-batches needs the teacher's episodes "
                        "(--demo-episodes N on a new run)"
                    )
                demos = Demos.load_steps(path)
                self.anchor = CloneAnchor(
                    model, demos, args.anchor_batches,
                    learning_rate=args.anchor_learning_rate, seed=args.seed,
                )  # fmt: skip

        def _on_training_start(self) -> None:
            if self.num_timesteps < args.critic_warmup_steps:
                set_actor_trainable(self.model, False)
                self.frozen = True
                log.info(
                    "critic warm-up: the actor is frozen until %d steps", args.critic_warmup_steps
                )

        def _on_rollout_start(self) -> None:
            if self.frozen and self.num_timesteps >= args.critic_warmup_steps:
                set_actor_trainable(self.model, True)
                self.frozen = False
                log.info("critic warm-up over at %d steps: the actor learns", self.num_timesteps)
            if self.anchor is not None and not self.frozen and self.num_timesteps > 0:
                self.logger.record("train/anchor_loss", self.anchor.step(current_norm()))

        def _on_step(self) -> bool:
            return True

    remaining = args.total_timesteps - model.num_timesteps
    finished = False
    try:
        with stop_on_sigterm():
            if remaining > 0 and (
                args.max_minutes is None or time.time() - t0 < 60 * args.max_minutes
            ):
                model.learn(
                    total_timesteps=remaining,
                    callback=[PeriodicEval(), FromClone()],
                    reset_num_timesteps=not resuming,
                    progress_bar=args.progress_bar,
                )
            save_policy()
            finished = True
    except (KeyboardInterrupt, TrainingStopped) as stop:
        save_policy()  # resume with --resume
        signum = stop.signum if isinstance(stop, TrainingStopped) else signal.SIGINT
        raise TrainingStopped(
            f"{out}: stopped by {signal.Signals(signum).name} at {model.num_timesteps} steps; "
            "the checkpoint is saved: the same command with --resume goes on",
            signum,
        ) from None
    finally:
        close_quietly(venv, stopped=not finished)
    videos = []
    if args.video_episodes > 0:
        shutil.rmtree(out / "videos", ignore_errors=True)
        recorded = evaluate(
            out / "policy.zip", args.env_id, eval_assets, args.video_episodes,
            video_dir=out / "videos", seed=20_000, category=args.category,
        )  # fmt: skip
        videos = sorted(str(p) for p in (out / "videos").iterdir())
        log.info("videos of %d held-out episodes: %s", len(recorded["episodes"]), videos)
    return {
        "policy": str(out / "policy.zip"),
        "progress_csv": str(out / "progress.csv"),
        "eval_csv": str(eval_csv),
        "curve_png": str(out / "curve.png"),
        "videos": videos,
        "last_eval": history[-1] if history else None,
        "timesteps": int(model.num_timesteps),
        "seconds": time.time() - t0,
        "teacher": teacher,
    }


def close_quietly(venv: Any, stopped: bool = False) -> None:
    """Close the training envs; workers already ended (a SIGTERM sent to the whole process
    group reaches them too) leave broken pipes, which are only logged. ``stopped``: the run
    ended by an exception (a signal, an error), which may have landed while the main process
    read some of the workers' step replies and not others; asking such workers to close
    would wait forever for replies already read, so they are terminated instead (a GPU env,
    one process, has no workers to terminate: it is closed)."""
    try:
        if stopped:
            getattr(venv.unwrapped, "terminate_workers", venv.close)()
        else:
            venv.close()
    except (BrokenPipeError, EOFError, ConnectionError, OSError) as e:
        log.warning("closing the env workers: %s", e)


def _optional(kind: type) -> Any:
    """An argparse type: ``kind`` of the text, or None for "none"."""

    def parse(text: str) -> Any:
        return None if text.lower() == "none" else kind(text)

    return parse


def parse_args(argv: list[str] | None = None) -> Args:
    """Args from command-line flags (``--total-timesteps 1000``); defaults from :class:`Args`."""
    import argparse

    parser = argparse.ArgumentParser(description="PPO on the drawer / door tasks")
    for name, value in asdict(Args()).items():
        flag = "--" + name.replace("_", "-")
        if isinstance(value, bool):
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, default=value)
        elif isinstance(value, list):
            parser.add_argument(flag, type=int, nargs="+", default=value)
        elif "None" in (annotation := str(Args.__dataclass_fields__[name].type)):
            # optional fields: str unless their annotation says float or int; "none"
            # gives None
            kind = float if "float" in annotation else int if "int" in annotation else str
            parser.add_argument(flag, type=_optional(kind), default=value)
        else:
            parser.add_argument(flag, type=type(value), default=value)
    return Args(**vars(parser.parse_args(argv)))


def main(argv: list[str] | None = None) -> None:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    print(json.dumps(train(parse_args(argv)), indent=2))


if __name__ == "__main__":
    main()
