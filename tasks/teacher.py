"""A scripted opening teacher in the policy's own action space, and behaviour cloning.

PPO from scratch on the drawer task learns to hook handles, not to grasp them, and on
the door task mostly to pull bottom-hinged doors down (docs/tasks.md, "Training"). The
teacher here grasps. It drives ``pd_ee_delta_pos`` (the PPO recipe's controller) from the
env's state: line the open fingers up in front of the handle, move in to it, close, then
move the hand the way the handle opens (a drawer's axis; for a door the tangent of the
handle's circle about the hinge, the hand keeping its orientation: a bar parallel to the
hinge turns between the fingers); when the fingers close on nothing or lose the handle,
open, back off and come in again. Recessed pulls get the fingers opened only a little, so
that one finger goes into the pocket (``recessed_open``).

:func:`collect_demos` records the teacher in a task env (what the policy observes and
what the teacher did); :func:`clone` fits an SB3 policy's mean action to them, the start
of PPO with ``pact train --demo-episodes N`` (``tasks.train.start_from_teacher``, which
makes the envs: this module imports nothing of the project); :class:`CloneAnchor` keeps
fitting it between PPO's updates (``--anchor-batches``).

The teacher reads the simulator's state (the handle point, the joint's axis and the
finger opening, which are also in the observation; a door's hinge position and the
robot base's orientation, which are not); the policy cloned from it sees only the
observation.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

log = logging.getLogger(__name__)

#: ``pd_ee_delta_pos``: an action of 1 moves the hand 0.1 m (ManiSkill's Panda config).
POS_ACTION_SCALE = 0.1


#: The tasks the teacher opens (opening tasks: the part starts closed).
TEACHER_TASKS = ("OpenDrawer-v0", "OpenDoor-v0")


@dataclass
class OpeningTeacher:
    """Grasp-and-pull for ``OpenDrawer-v0`` and ``OpenDoor-v0`` in ``pd_ee_delta_pos``.

    Lengths in metres; ``pull`` is the hand's travel per control step while pulling.
    Chosen on the procedural training objects (``pact sample --split train``).
    """

    standoff: float = 0.06
    """line up this far in front of the handle before moving in"""
    depth: float = 0.0
    """the hand's centre this far behind the handle point when closing (bars, knobs)"""
    recessed_depth: float = 0.01
    """as ``depth``, recessed pulls"""
    recessed_open: float = -0.2
    """gripper action while reaching a recessed pull (-1..1 = fingers -0.01..0.04 m):
    opened 1.5 cm a finger, so that one finger goes into the pocket"""
    step: float = 0.05
    """largest hand move per control step while reaching"""
    pull: float = 0.02
    """hand travel per control step while pulling a drawer"""
    door_pull: float = 0.05
    """as ``pull``, doors: a door resists more, and the controller's force grows with the
    commanded step"""
    close_steps: int = 3
    """control steps the fingers get to close before pulling"""
    overshoot: float = 0.08
    """pull on to this fraction of the range past the goal, then hold still"""
    stall_steps: int = 5
    """a door whose opening grew less than 0.01 of its range over this many steps of
    pulling has stalled (the arm, its orientation fixed, can follow the handle no further)"""
    push_from: float = 0.15
    """a stalled door opened at least this fraction of its range is let go and pushed on
    from inside, the hand going round its free edge"""
    regrasp_below: float = 0.25
    """a door whose handle the fingers lost below this fraction is grasped again (and
    pushed on from inside above it)"""
    round_clear: float = 0.1
    """how far in front of the handle the hand backs off before going round the free edge"""
    edge_clear: float = 0.11
    """how far past the door's free edge the hand goes round it (the Panda hand is about
    0.2 m across its fingers' travel)"""
    face_clear: float = 0.04
    """how far behind the door's inner face the hand goes to push it from inside"""
    inside_past_edge: float = 0.02
    """where the hand goes behind the door and pushes from: this far past its free edge (the
    hand's side pushes the edge; further in, the hand's body, fixed in orientation, would
    catch the edge from the front and shut the door)"""
    door_step: float = 0.07
    """as ``step``, doors: reaching and going round"""
    round_steps: int = 5
    """control steps each leg of the way round gets (out of reach, the hand goes on)"""
    door_push: float = 0.09
    """hand travel per control step pushing a door from inside"""

    def __post_init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.phase, self.t, self.opening = "approach", 0, []
        self.extent: tuple[float, float] | None = None  # the door's, :func:`door_extent`

    def __call__(self, env: Any) -> np.ndarray:
        """The action for ``env`` (a ManiSkill ``ArticulatedPartEnv``, one sub-scene)."""
        u = env.unwrapped
        tcp = u.agent.tcp.pose.p[0].cpu().numpy()
        handle = u.handle_positions()[0].cpu().numpy()
        axis = opening_direction(u, handle)
        width = float(u.agent.robot.get_qpos()[0, 7:9].sum())
        frac, goal = float(u.open_fraction()[0]), float(u.open_goal)
        recessed = u.episode_parts[0].handle_kind == "recessed"
        to_handle = handle - tcp
        along = float(to_handle @ axis)
        lateral = to_handle - along * axis
        pre = handle + axis * self.standoff
        grasp = handle - axis * (self.recessed_depth if recessed else self.depth)
        gripper, move = (self.recessed_open if recessed else 1.0), np.zeros(3)
        door = u.episode_parts[0].joint_type == "revolute"
        # a door's round trip to its inner face, in the door's current frame: ``out`` points
        # from the hinge line to the handle, the free edge is ``edge`` past the handle that
        # way and the inner face ``face`` behind the handle point
        out = _radial(u) if door else axis
        if door and self.extent is None:
            self.extent = door_extent(u, handle, axis, out)
        edge, face = self.extent if door else (0.0, 0.0)
        past = edge + self.edge_clear
        behind = face + self.face_clear
        round_path = {
            "back_off": handle + axis * self.round_clear,
            "past_edge": handle + axis * self.round_clear + out * past,
            "behind": handle - axis * behind + out * past,
            "inside": handle - axis * behind + out * (edge + self.inside_past_edge),
        }
        self.t += 1
        if self.phase == "approach":
            lined_up = np.linalg.norm(lateral) <= 0.01 or along >= -0.02
            move = (grasp if lined_up else pre) - tcp
            gap = float(np.linalg.norm(grasp - tcp))
            # a door's recessed pull may be shallower than recessed_depth: the hand stops
            # at the door short of the grasp point, and closes there
            near = 0.008 + (self.recessed_depth if door and recessed else 0.0)
            if gap < near or (self.t > 12 and gap < 0.02):
                self.phase, self.t = "close", 0
        elif self.phase == "close":
            gripper = -1.0
            if self.t >= self.close_steps:
                self.phase, self.t = "pull", 0
        elif self.phase == "pull":
            gripper = -1.0
            if frac < goal + self.overshoot:
                # back onto the path; a door's hand also waits for a lagging handle
                back = to_handle if door else lateral
                move = axis * (self.door_pull if door else self.pull) + 0.5 * back
            lost = width < 0.004 or np.linalg.norm(to_handle) > 0.05
            self.opening.append(frac)
            stalled = len(self.opening) > self.stall_steps and (
                frac - self.opening[-1 - self.stall_steps] < 0.01
            )
            if (
                door
                and frac < goal
                and ((stalled and frac >= self.push_from) or (lost and frac >= self.regrasp_below))
            ):
                self.phase, self.t = "back_off", 0
            elif frac < goal and lost:
                self.phase, self.t = "retreat", 0
        elif self.phase in round_path:
            move = round_path[self.phase] - tcp
            if np.linalg.norm(move) < 0.02 or self.t > self.round_steps:
                order = list(round_path)
                nxt = order.index(self.phase) + 1
                self.phase, self.t = (order[nxt] if nxt < len(order) else "push"), 0
        elif self.phase == "push":
            # stay just behind the inner face at the free edge and move the way it opens
            if frac < goal + self.overshoot:
                target = handle - axis * (face + 0.02) + out * (edge + self.inside_past_edge)
                move = axis * self.door_push + 0.5 * (target - tcp)
        elif self.phase == "retreat":
            gripper = 1.0
            move = pre - tcp
            if np.linalg.norm(move) < 0.01 or self.t > 6:
                self.phase, self.t = "approach", 0
        if self.phase == "push":
            step = self.door_push
        else:
            step = max(self.door_step, self.door_pull) if door else self.step
        norm = float(np.linalg.norm(move))
        if norm > step:
            move = move * step / norm
        return (
            np.concatenate([_world_to_base(move, u) / POS_ACTION_SCALE, [gripper]])
            .clip(-1.0, 1.0)
            .astype(np.float32)
        )


def opening_direction(u: Any, handle: np.ndarray) -> np.ndarray:
    """(3,) unit world direction in which the target part's handle moves as it opens: the
    drawer's axis, or for a revolute part the tangent of the handle's circle (the
    target link's origin lies on the hinge, and the joint opens toward its upper limit,
    turning the right-handed way about its axis)."""
    axis = u.joint_axis_world()[0].cpu().numpy()
    if u.episode_parts[0].joint_type != "revolute":
        return axis
    arm = handle - u.target_link.pose.p[0].cpu().numpy()
    arm = arm - (arm @ axis) * axis
    tangent = np.cross(axis, arm)
    return tangent / max(float(np.linalg.norm(tangent)), 1e-9)


def _radial(u: Any) -> np.ndarray:
    """(3,) unit world direction from a revolute target part's hinge line to its handle,
    square to the hinge (the env's ``hinge_to_handle``)."""
    arm = u.hinge_to_handle()[0].cpu().numpy().astype(float)
    return arm / max(float(np.linalg.norm(arm)), 1e-9)


def door_extent(
    u: Any, handle: np.ndarray, axis: np.ndarray, out: np.ndarray
) -> tuple[float, float]:
    """How far the target part's collision geometry reaches past its handle point: along
    ``out`` (the free edge, away from the hinge) and against ``axis`` (the inner face,
    behind the handle), in metres, each at least 0. Rigid with the part, so one reading
    holds for the episode. Without collision shapes to read: 0.05 and 0.08 m (a handle
    near the edge of a panel with a bar's standoff)."""
    points = _link_points(u.target_link)
    if len(points) == 0:
        return 0.05, 0.08
    rel = points - handle
    return max(float((rel @ out).max()), 0.0), max(float(-(rel @ axis).min()), 0.0)


def _link_points(link: Any) -> np.ndarray:
    """(N, 3) world corners of a ManiSkill link's convex and box collision shapes (its first
    sub-scene's)."""
    world = link.pose.to_transformation_matrix()[0].cpu().numpy()
    rows = []
    for shape in link._bodies[0].get_collision_shapes():
        if hasattr(shape, "get_vertices"):
            local = np.asarray(shape.get_vertices(), float) * np.asarray(shape.get_scale(), float)
        elif hasattr(shape, "get_half_size"):
            half = np.asarray(shape.get_half_size(), float)
            local = half * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        else:
            continue
        pose = shape.get_local_pose().to_transformation_matrix()
        rows.append(local @ pose[:3, :3].T + pose[:3, 3])
    if not rows:
        return np.zeros((0, 3))
    pts = np.concatenate(rows)
    return pts @ world[:3, :3].T + world[:3, 3]


def _world_to_base(v: np.ndarray, u: Any) -> np.ndarray:
    """A world-frame translation in the robot base's frame (``pd_ee_delta_pos`` moves the
    hand along the base's axes)."""
    rotation = u.agent.robot.pose.to_transformation_matrix()[0, :3, :3].cpu().numpy()
    return rotation.T @ v


@dataclass
class Demos:
    """Observations and the teacher's actions, step by step, with each step's episode."""

    obs: np.ndarray
    actions: np.ndarray
    episode: np.ndarray
    success: np.ndarray
    """(episodes,) whether each episode succeeded"""

    @classmethod
    def from_rows(cls, obs: list, actions: list, episode: list, success: list) -> Demos:
        """From per-step lists (observation, action, episode) and per-episode success."""
        return cls(
            np.asarray(obs, np.float32),
            np.asarray(actions, np.float32),
            np.asarray(episode, np.int64),
            np.asarray(success, bool),
        )

    def successful(self) -> Demos:
        keep = self.success[self.episode]
        return Demos(self.obs[keep], self.actions[keep], self.episode[keep], self.success)

    def save_steps(self, path: str | Path) -> None:
        """The steps' observations and actions (a run's ``teacher_demos.npz``)."""
        np.savez_compressed(path, obs=self.obs, actions=self.actions)

    @classmethod
    def load_steps(cls, path: str | Path) -> Demos:
        """Steps written by :meth:`save_steps`, as one successful episode."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such file of the teacher's steps")
        with np.load(path) as d:
            if "obs" not in d.files or "actions" not in d.files:
                raise ValueError(f"{path}: not a file of the teacher's steps (obs, actions)")
            obs, actions = d["obs"].astype(np.float32), d["actions"].astype(np.float32)
        if obs.ndim != 2 or actions.ndim != 2 or len(obs) != len(actions) or len(obs) == 0:
            raise ValueError(
                f"{path}: {obs.shape} observations and {actions.shape} actions are not steps"
            )
        return cls(obs, actions, np.zeros(len(obs), np.int64), np.ones(1, bool))


def check_task(env_id: str, control_mode: str) -> None:
    """Raise ValueError unless the teacher can demonstrate ``env_id`` with ``control_mode``."""
    if env_id not in TEACHER_TASKS:
        raise ValueError(
            f"{env_id}: the scripted teacher opens parts only ({', '.join(TEACHER_TASKS)})"
        )
    if control_mode != "pd_ee_delta_pos":
        raise ValueError(f"the teacher drives pd_ee_delta_pos, not {control_mode}")


def collect_demos(env: Any, episodes: int, seed: int = 50_000, action_noise: float = 0.05) -> Demos:
    """Run :class:`OpeningTeacher` on ``env`` (an opening task in ``pd_ee_delta_pos`` with
    flat observations, ``tasks.train.make_cpu_env``) for ``episodes`` episodes (episode k
    seeded ``seed + k``) and record each step's observation and the teacher's action. The
    env is stepped with the teacher's action plus Gaussian noise of ``action_noise`` on the
    hand's move (the recorded label stays the clean action), so that the demos also show
    the way back from where a clone's errors lead (DART)."""
    rng = np.random.default_rng(seed)
    obs_rows, act_rows, ep_rows, success = [], [], [], []
    for k in range(episodes):
        obs, _ = env.reset(seed=seed + k)
        teacher, done, info = OpeningTeacher(), False, {}
        while not done:
            action = teacher(env)
            obs_rows.append(obs)
            act_rows.append(action)
            ep_rows.append(k)
            noisy = action.copy()
            noisy[:3] += rng.normal(0.0, action_noise, 3)
            obs, _, term, trunc, info = env.step(np.clip(noisy, -1.0, 1.0))
            done = term or trunc
        success.append(bool(info.get("success", False)))
    log.info("teacher: %d of %d episodes succeeded", sum(success), episodes)
    return Demos.from_rows(obs_rows, act_rows, ep_rows, success)


def collect_corrections(
    env: Any, act: Callable[[np.ndarray], np.ndarray], episodes: int, seed: int = 70_000
) -> Demos:
    """DAgger (Ross, Gordon and Bagnell, 2011): run a policy ``act`` (raw observation ->
    action; the clone) on ``env`` for ``episodes`` episodes (episode k seeded ``seed + k``)
    and label every state it visits with the teacher's action there. The teacher's phase
    follows the states the policy leads it to (it reads the simulator at each step), so
    the labels say how to go on from the clone's own mistakes, which the teacher's
    episodes never reach. ``success`` is the policy's."""
    obs_rows, act_rows, ep_rows, success = [], [], [], []
    for k in range(episodes):
        obs, _ = env.reset(seed=seed + k)
        teacher, done, info = OpeningTeacher(), False, {}
        while not done:
            obs_rows.append(obs)
            act_rows.append(teacher(env))
            ep_rows.append(k)
            obs, _, term, trunc, info = env.step(np.clip(act(obs), -1.0, 1.0))
            done = term or trunc
        success.append(bool(info.get("success", False)))
    log.info("corrections: the policy succeeded in %d of %d episodes", sum(success), episodes)
    return Demos.from_rows(obs_rows, act_rows, ep_rows, success)


def join_demos(*parts: Demos) -> Demos:
    """Demos one after another, episode numbers made distinct."""
    offset, pieces = 0, []
    for d in parts:
        pieces.append(Demos(d.obs, d.actions, d.episode + offset, d.success))
        offset += len(d.success)
    return Demos(
        np.concatenate([d.obs for d in pieces]),
        np.concatenate([d.actions for d in pieces]),
        np.concatenate([d.episode for d in pieces]),
        np.concatenate([d.success for d in pieces]),
    )


def actor_parameters(policy: Any) -> list[Any]:
    """The parameters of an SB3 Gaussian MlpPolicy's mean action (not the value function's,
    not the log std)."""
    return [
        *policy.features_extractor.parameters(),
        *policy.mlp_extractor.policy_net.parameters(),
        *policy.action_net.parameters(),
    ]


def _mean_action(policy: Any, x: Any) -> Any:
    features = policy.extract_features(x, policy.pi_features_extractor)
    return policy.action_net(policy.mlp_extractor.forward_actor(features))


def clone(
    model: Any,
    demos: Demos,
    normalize: Any = None,
    epochs: int = 200,
    batch_size: int = 256,
    learning_rate: float = 1e-3,
    seed: int = 0,
    obs_noise: float = 0.0,
    members: int = 1,
) -> list[float]:
    """Fit the mean action of ``model`` (an SB3 PPO model, Gaussian MlpPolicy) to the
    demos' actions (mean squared error; the log std stays); ``normalize`` maps raw
    observations to what the policy sees; ``obs_noise``: the standard deviation of
    Gaussian noise added to those (normalized) observations in every batch, so that
    nearby states get nearby actions. Returns the loss of each epoch (with ``members``,
    the members' mean).

    ``members`` > 1 fits that many clones from different initial weights, each ``1 /
    members`` of the width of ``model``'s policy MLP, and writes them into ``model``'s
    policy so that its mean action is theirs averaged (:func:`set_ensemble`): clones of
    one teacher differ on objects they never saw as much as recipes do, their mean
    less."""
    import torch

    fit = dict(epochs=epochs, batch_size=batch_size, learning_rate=learning_rate)
    policy = model.policy
    if members == 1:
        return _fit_mean_action(policy, demos, normalize, seed=seed, obs_noise=obs_noise, **fit)
    widths = list(policy.net_arch["pi"] if isinstance(policy.net_arch, dict) else policy.net_arch)
    if members < 1 or any(w % members for w in widths):
        raise ValueError(f"{members} members do not share the policy's widths {widths}")
    kwargs = dict(model.policy_kwargs, net_arch=[w // members for w in widths])
    fitted, losses = [], []
    for i in range(members):
        with torch.random.fork_rng():
            torch.manual_seed(seed * 1000 + i)
            member = model.policy_class(
                model.observation_space, model.action_space, model.lr_schedule, **kwargs
            ).to(policy.device)
        losses.append(
            _fit_mean_action(member, demos, normalize, seed=seed + i, obs_noise=obs_noise, **fit)
        )
        fitted.append(member)
    set_ensemble(policy, fitted)
    return [float(x) for x in np.mean(losses, axis=0)]


def set_ensemble(policy: Any, members: list[Any]) -> None:
    """Write same-shaped SB3 MlpPolicies into ``policy``, whose policy MLP is
    ``len(members)`` times as wide, so that its mean action is exactly their mean: the
    first layer stacks the members' rows, the deeper ones are block-diagonal (a member's
    units see only its own), the action layer averages. The log std is the members' mean;
    the value function stays ``policy``'s."""
    import torch

    k = len(members)
    layers = [m for m in policy.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)]
    parts = [
        [m for m in p.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)] for p in members
    ]
    for i, layer in enumerate(layers):
        want = sum(p[i].out_features for p in parts)
        if layer.out_features != want:
            raise ValueError(
                f"policy layer {i} has {layer.out_features} units, the members {want} together"
            )
    with torch.no_grad():
        for i, layer in enumerate(layers):
            weights = [p[i].weight for p in parts]
            layer.weight.copy_(torch.cat(weights, 0) if i == 0 else torch.block_diag(*weights))
            layer.bias.copy_(torch.cat([p[i].bias for p in parts], 0))
        policy.action_net.weight.copy_(torch.cat([p.action_net.weight for p in members], 1) / k)
        policy.action_net.bias.copy_(torch.stack([p.action_net.bias for p in members]).mean(0))
        policy.log_std.copy_(torch.stack([p.log_std for p in members]).mean(0))


def _fit_mean_action(
    policy: Any,
    demos: Demos,
    normalize: Any,
    *,
    epochs: int,
    batch_size: int,
    learning_rate: float,
    seed: int,
    obs_noise: float,
) -> list[float]:
    import torch

    obs = normalize(demos.obs) if normalize is not None else demos.obs
    x = torch.as_tensor(obs, dtype=torch.float32, device=policy.device)
    y = torch.as_tensor(demos.actions, dtype=torch.float32, device=policy.device)
    opt = torch.optim.Adam(actor_parameters(policy), lr=learning_rate)
    gen = torch.Generator().manual_seed(seed)
    losses = []
    policy.set_training_mode(True)
    for _ in range(epochs):
        order = torch.randperm(len(x), generator=gen)
        total = 0.0
        for i in range(0, len(x), batch_size):
            idx = order[i : i + batch_size]
            xb = x[idx]
            if obs_noise > 0:
                xb = xb + obs_noise * torch.randn(xb.shape, generator=gen).to(xb.device)
            loss = torch.nn.functional.mse_loss(_mean_action(policy, xb), y[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        losses.append(total / len(x))
    policy.set_training_mode(False)
    return losses


class CloneAnchor:
    """Behaviour cloning kept up while PPO trains the clone: each :meth:`step` runs
    ``batches`` minibatches of the mean-squared-error fit of :func:`clone` on random demo
    steps (its own Adam at ``learning_rate``), pulling the policy's mean action back toward
    the teacher's where PPO has moved it, so that PPO improves the clone without trading
    its grasps for hooks (the auxiliary behaviour-cloning term of DAPG, here as separate
    steps between PPO's updates)."""

    def __init__(
        self,
        model: Any,
        demos: Demos,
        batches: int,
        batch_size: int = 256,
        learning_rate: float = 1e-4,
        seed: int = 0,
    ) -> None:
        import torch

        if batches < 1 or len(demos.obs) == 0:
            raise ValueError(
                f"need batches >= 1 and demo steps, got {batches} and {len(demos.obs)}"
            )
        self.model, self.demos = model, demos
        self.batches, self.batch_size = int(batches), int(batch_size)
        self.opt = torch.optim.Adam(actor_parameters(model.policy), lr=learning_rate)
        self.gen = torch.Generator().manual_seed(seed)

    def step(self, normalize: Any = None) -> float:
        """``batches`` minibatches; ``normalize`` (the observation normalizer as it is now)
        maps raw observations to what the policy sees. Returns the mean loss."""
        import torch

        policy = self.model.policy
        policy.set_training_mode(True)
        total = 0.0
        for _ in range(self.batches):
            idx = torch.randint(len(self.demos.obs), (self.batch_size,), generator=self.gen)
            idx = idx.numpy()
            obs = self.demos.obs[idx]
            x = torch.as_tensor(
                normalize(obs) if normalize is not None else obs,
                dtype=torch.float32,
                device=self.model.device,
            )
            y = torch.as_tensor(
                self.demos.actions[idx], dtype=torch.float32, device=self.model.device
            )
            loss = torch.nn.functional.mse_loss(_mean_action(policy, x), y)
            self.opt.zero_grad()
            loss.backward()
            self.opt.step()
            total += loss.item()
        policy.set_training_mode(False)
        return total / self.batches
