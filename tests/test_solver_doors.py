"""The scripted solver on wide doors: pull part of the way, then push the inner face."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import tasks  # noqa: F401  (registers the envs)

# a fridge whose 0.62 m wide door swings its handle further than the Panda can follow
WIDE_FRIDGE = ("refrigerator", 201, "door_0")


def _build(tmp_path_factory: pytest.TempPathFactory, category: str, seed: int):
    """One procedural object built into a fresh folder: its asset record."""
    from asset_pipeline.assets.build import build_asset
    from generator.bundle import save_bundle
    from generator.procedural import object_id, sample_object
    from sim_envs import FolderSource

    root = tmp_path_factory.mktemp(f"{category}_{seed}")
    build_asset(save_bundle(sample_object(category, seed), root / object_id(category, seed)))
    return next(iter(FolderSource(root)))


@pytest.fixture(scope="module")
def wide_fridge(tmp_path_factory: pytest.TempPathFactory):
    return _build(tmp_path_factory, *WIDE_FRIDGE[:2])


def _solve_door(record, part: str, **config):
    """The solver on one door of ``record`` (CPU, seed 0): its result and per-step trace."""
    from tasks.solver import SolverConfig, solve_part

    torch.set_num_threads(1)
    res, _ = solve_part(record, part, config=SolverConfig(trace=True, **config))
    return res, res.trace


def test_push_waypoints_go_round_the_free_edge(wide_fridge) -> None:
    """The pusher passes beyond the free edge, then presses behind the inner face, the
    hand's width along the hinge; a pull-then-push plan ends pushing at PUSH_END."""
    from tasks.placement import (
        PUSH_END,
        PUSH_RADIUS,
        PUSH_TILTS,
        hinge_frame_link,
        link_pose,
        push_plan_poses,
        push_waypoints_link,
    )

    part = next(p for p in wide_fridge.movable_parts() if p.name == WIDE_FRIDGE[2])
    a, r, n, radius = hinge_frame_link(part)
    assert radius > 0.6  # the case the push is for
    for tilt in PUSH_TILTS:
        named = dict(push_waypoints_link(part, tilt, depth=0.04))
        assert set(named) == {"edge", "behind", "press"}
        for T in named["edge"] + named["behind"]:
            assert T[:3, 3] @ r > radius  # beyond the free edge
        assert all(T[:3, 3] @ n > 0 for T in named["edge"])  # in front of the face
        for T in named["behind"] + named["press"]:
            assert T[:3, 3] @ n < -0.04  # behind the inner face
            assert abs(T[:3, 1] @ a) > 0.99  # fingers (hand width) along the hinge
        for T in named["press"]:
            assert T[:3, 3] @ r == pytest.approx(PUSH_RADIUS * radius)
    steps, fractions = push_plan_poses(part, 0.35, PUSH_TILTS[-1])
    assert len(steps) == len(fractions) and fractions[0] == 0.0 and fractions[-1] == PUSH_END
    press = dict(push_waypoints_link(part, PUSH_TILTS[-1]))["press"][0]
    assert np.allclose(steps[-1][0], link_pose(part, PUSH_END) @ press)


@pytest.mark.slow
def test_solver_pulls_then_pushes_a_wide_fridge_door(wide_fridge) -> None:
    """The robot cannot follow the handle round the whole arc: it pulls the door ajar,
    lets go and pushes the inner face on to the goal, in CPU simulation."""
    res, trace = _solve_door(wide_fridge, WIDE_FRIDGE[2])
    phases = [t["phase"] for t in trace]
    assert "push:press" in phases and "push:abort" not in phases, sorted(set(phases))
    assert res.success, res


def test_candidate_bases_must_reach_the_closed_handle(wide_fridge) -> None:
    """Every base the placement may pick has its shoulder within FIRST_GRASP_REACH of
    the closed handle (the first grasp), and the grid does hold bases beyond it that
    only this rule excludes (a cost that merely penalized them once picked a base 0.83 m
    from a cabinet door's handle, where no grasp was possible)."""
    from tasks.placement import (
        FIRST_GRASP_REACH,
        PATH_FRACTIONS,
        SHOULDER_HEIGHT,
        _candidate_bases,
        handle_path,
        opening_normals,
    )

    part = next(p for p in wide_fridge.movable_parts() if p.name == WIDE_FRIDGE[2])
    path = handle_path(part, PATH_FRACTIONS)
    base, _, cost = _candidate_bases(part, wide_fridge.bounds, path, -opening_normals(part))
    shoulder = base + np.array([0.0, 0.0, SHOULDER_HEIGHT])
    first = np.linalg.norm(shoulder - path[0], axis=1)
    ok = np.isfinite(cost)
    assert ok.any()
    assert (first[ok] <= FIRST_GRASP_REACH + 1e-9).all()
    assert (first > FIRST_GRASP_REACH).sum() > 0


def _reach_for(record, part: str):
    """The task's Panda kinematics (:class:`tasks.placement.PandaReach`) from an env."""
    import gymnasium as gym

    from sim_envs.asset_sources import ListSource
    from tasks.articulated import READY_QPOS
    from tasks.placement import PandaReach

    env = gym.make(
        "OpenDoor-v0",
        assets=ListSource([record.folder]),
        target_part=part,
        obs_mode="state",
        control_mode="pd_ee_delta_pose",
        sim_backend="physx_cpu",
        render_backend="none",
    )
    try:
        env.reset(seed=0)
        u = env.unwrapped
        return PandaReach(u.agent.robot._objs[0], u.agent.ee_link_name, READY_QPOS)
    finally:
        env.close()


def test_follow_keeps_the_hand_the_same_way_round(wide_fridge) -> None:
    """A hand holding a bar cannot turn over on it: a path whose first step is reachable
    only with the fingers one way round and whose second only the other way round is
    followed one step (half), not both by flipping the hand between them; with the hand
    already holding (``q0``) the way round it holds is followed."""
    from tasks.articulated import READY_QPOS

    reach = _reach_for(wide_fridge, WIDE_FRIDGE[2])
    reach.model.compute_forward_kinematics(np.asarray(READY_QPOS, dtype=float))
    pose = reach.model.get_link_pose(reach.tcp)
    from scipy.spatial.transform import Rotation

    ready = np.eye(4)  # the ready tcp in the root frame (= object frame: base 0, yaw 0)
    w, x, y, z = pose.q
    ready[:3, :3] = Rotation.from_quat([x, y, z, w]).as_matrix()
    ready[:3, 3] = pose.p
    near = ready.copy()
    near[:3, 3] += [0.02, 0.0, 0.0]
    far = ready.copy()
    far[:3, 3] += [5.0, 0.0, 0.0]  # out of reach
    base, yaw = np.zeros(3), 0.0
    fraction, start = reach.follow(base, yaw, [[ready, far], [far, near]], standoff=0.05)
    assert fraction == 0.5 and start is not None
    assert reach.follow(base, yaw, [[ready, far], [near, far]], standoff=0.05)[0] == 1.0
    # holding already, the ready hand's way round: its plan, whatever the other would do
    q = np.asarray(READY_QPOS, dtype=float)
    assert reach.follow(base, yaw, [[ready, far], [near, far]], q0=q)[0] == 1.0
    flipped = ready.copy()
    flipped[:3, :2] *= -1  # the fingers the other way round (a half turn about z)
    assert reach.follow(base, yaw, [[flipped, ready], [near, far]], q0=q)[0] == 0.5


def _polyline(route: np.ndarray, step: float = 0.01) -> np.ndarray:
    """Points every ``step`` metres along a route's legs."""
    pts = [route[0]]
    for a, b in zip(route[:-1], route[1:], strict=True):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        pts += [a + (b - a) * k / n for k in range(1, n + 1)]
    return np.asarray(pts)


def test_base_route_goes_round_the_open_door(wide_fridge) -> None:
    """From in front of the opening (the door's inner side) to its outer side, the
    straight way crosses the door: the route goes round its free edge, keeping the base
    column's clearance from the door and the object all the way; with nothing between,
    it is the straight line; a goal inside the object has no route."""
    from tasks.placement import (
        BASE_CLEARANCE,
        _box_distance_xy,
        _swept_points,
        base_route,
        hinge_frame_link,
        link_pose,
    )

    part = next(p for p in wide_fridge.movable_parts() if p.name == WIDE_FRIDGE[2])
    lo, hi = (np.asarray(b, dtype=float) for b in wide_fridge.bounds)
    fraction = 0.6
    _, r, n, radius = hinge_frame_link(part)
    L = link_pose(part, fraction)
    hinge, r_w, n_w = L[:3, 3], L[:3, :3] @ r, L[:3, :3] @ n
    mid = hinge + r_w * 0.9 * radius
    start, goal = (mid - n_w * 0.5)[:2], (mid + n_w * 0.5)[:2]
    door = _swept_points(part, wide_fridge.bounds, fraction, fraction)[:, :2]
    assert _box_distance_xy(start[None], lo[:2], hi[:2])[0] >= BASE_CLEARANCE  # the case
    route = base_route(part, wide_fridge.bounds, fraction, start, goal)
    assert route is not None and np.allclose(route[0], start) and np.allclose(route[-1], goal)
    pts = _polyline(route)
    gap_door = np.linalg.norm(pts[:, None] - door[None], axis=2).min(axis=1)
    gap_box = _box_distance_xy(pts, lo[:2], hi[:2])
    assert gap_door.min() >= BASE_CLEARANCE - 0.04  # (the grid's half diagonal)
    assert gap_box.min() >= BASE_CLEARANCE - 0.04
    assert ((pts - hinge[:2]) @ r_w[:2]).max() > radius  # round the free edge
    # nothing between: straight
    ahead = np.array([hi[0] + 2.0, lo[1] - 0.5]), np.array([hi[0] + 2.0, hi[1] + 0.5])
    straight = base_route(part, wide_fridge.bounds, 0.0, *ahead)
    assert straight is not None and len(straight) == 2
    inside = 0.5 * (lo[:2] + hi[:2])
    assert base_route(part, wide_fridge.bounds, fraction, start, inside) is None


def test_push_stand_faces_the_inner_face(wide_fridge) -> None:
    """A further stand for a door half open stands behind the door's plane, clear of
    what the door sweeps while pushed, and its arm follows the push on past where the
    door is, to the goal; a door on a horizontal hinge (its inner side is under it) gets none."""
    import dataclasses

    from tasks.placement import (
        BASE_CLEARANCE,
        PUSH_STAND_BACK,
        _swept_points,
        hinge_frame_link,
        link_pose,
        push_stand,
    )

    part = next(p for p in wide_fridge.movable_parts() if p.name == WIDE_FRIDGE[2])
    reach = _reach_for(wide_fridge, WIDE_FRIDGE[2])
    fraction = 0.45
    stand = push_stand(reach, part, wide_fridge.bounds, fraction, depth=0.04, end=0.85)
    assert stand is not None
    base, _, reached, _ = stand
    assert reached >= 0.75  # the task's goal, from less than half open
    _, _, n, _ = hinge_frame_link(part)
    L = link_pose(part, fraction)
    assert (base - L[:3, 3]) @ (L[:3, :3] @ n) < -PUSH_STAND_BACK
    swept = _swept_points(part, wide_fridge.bounds, reached, fraction)
    assert np.linalg.norm(swept[:, :2] - base[:2], axis=1).min() >= BASE_CLEARANCE
    lid = dataclasses.replace(part, axis=(0.0, 1.0, 0.0))
    assert push_stand(reach, lid, wide_fridge.bounds, fraction) is None


@pytest.mark.slow
def test_solver_pushes_a_wide_door_from_a_second_stand(wide_fridge) -> None:
    """With the second stand taken before any push from the first (``restand_first``),
    the robot pulls the wide door ajar, lets go, its base drives to a stand in front of
    the opening without touching the door, and the arm pushes the inner face on to the
    goal from there, in CPU simulation."""
    res, trace = _solve_door(wide_fridge, WIDE_FRIDGE[2], restand_first=True)
    phases = [t["phase"] for t in trace]
    assert "restand:drive" in phases and "push:edge" not in phases, sorted(set(phases))
    drive = [t["fraction"] for t in trace if t["phase"] == "restand:drive"]
    assert max(drive) - min(drive) < 0.01  # the base drove clear of the door
    assert res.success and res.stands >= 1, res


# a fridge door whose pull passes a wrist singularity (joint 5 through 0) at 0.75 open
SINGULAR_FRIDGE = ("refrigerator", 303, "door_0")


@pytest.fixture(scope="module")
def singular_fridge(tmp_path_factory: pytest.TempPathFactory):
    return _build(tmp_path_factory, *SINGULAR_FRIDGE[:2])


def test_twist_escape_pulls_through_a_wrist_singularity(singular_fridge) -> None:
    """Without the escape the arm, holding the handle, stalls at the singularity just
    short of the goal (the controller's IK converges for no shortened step); with it the
    hand turns a little about the bar and the pull alone opens the door."""
    part = SINGULAR_FRIDGE[2]
    # (without moving the base: from another stand the push gets there too)
    stuck, stuck_trace = _solve_door(singular_fridge, part, twist_escape=False, restand=False)
    assert not stuck.success and stuck_trace[-1]["twists"] == 0, stuck
    res, trace = _solve_door(singular_fridge, part)
    assert res.success, res
    assert trace[-1]["twists"] > 0
    phases = {t["phase"] for t in trace}
    assert not any(p.startswith("push") for p in phases), sorted(phases)


def _drawer_under_a_worktop(root, long_pull: bool = False) -> object:
    """A desk whose top drawer has a 5 cm pull 3 cm under a worktop that overhangs the
    drawer front by 3 cm: a vertical pinch meets the overhang, one along the pull fits.

    ``long_pull``: the pull is 11 cm long, held by posts at its ends (fingers along it
    meet the posts), and the worktop is 2 cm thick with a 1 cm lip along its front edge
    3 cm above the pull's axis, 3.5 cm in front of it: a wide vertical pinch stops on
    the lip less than ``approach_blocked`` short of the pull and never holds it."""
    import trimesh

    from asset_pipeline.assets.build import build_asset
    from generator.articulated import ArticulatedObject, Handle, Joint, Part
    from generator.bundle import save_bundle
    from generator.procedural.solids import box, cylinder
    from sim_envs import FolderSource

    def part(name, semantic, prims, joint=None, handle=None):
        mesh = trimesh.util.concatenate([q.to_mesh() for q in prims])
        return Part(name, semantic, mesh, joint, prims, handle)

    base = [
        box((-0.25, -0.3, 0.0), (0.25, -0.28, 0.7)),  # side walls
        box((-0.25, 0.28, 0.0), (0.25, 0.3, 0.7)),
        box((-0.25, -0.28, 0.0), (-0.23, 0.28, 0.7)),  # back
        box((-0.23, -0.28, 0.0), (0.25, 0.28, 0.5)),  # the lower body
        box((-0.25, -0.32, 0.7), (0.28, 0.32, 0.73)),  # worktop, 3 cm over the front
    ]
    pull = np.array([0.27, 0.0, 0.67])
    length, post = 0.05, (0.012, 0.02)  # the pull's length, its posts' span from the middle
    if long_pull:
        base[-1] = box((-0.25, -0.32, 0.71), (0.305, 0.32, 0.73))  # worktop, 5.5 cm over
        base.append(box((0.295, -0.32, 0.70), (0.305, 0.32, 0.71)))  # its lip
        length, post = 0.11, (0.047, 0.055)
    drawer = [
        box((0.23, -0.275, 0.505), (0.25, 0.275, 0.695)),  # front
        box((-0.2, -0.26, 0.51), (0.23, 0.26, 0.525)),  # bottom
        box((-0.2, -0.26, 0.525), (-0.185, 0.26, 0.67)),  # back
        box((-0.185, -0.26, 0.525), (0.23, -0.245, 0.67)),  # sides
        box((-0.185, 0.245, 0.525), (0.23, 0.26, 0.67)),
        cylinder(pull, 0.006, length, 1),  # the pull and its posts
        box((0.249, -post[1], 0.664), (0.265, -post[0], 0.676)),
        box((0.249, post[0], 0.664), (0.265, post[1], 0.676)),
    ]
    obj = ArticulatedObject(
        [
            part("base", "base", base),
            part(
                "drawer_0",
                "drawer",
                drawer,
                Joint("prismatic", (0.24, 0.0, 0.6), (1.0, 0.0, 0.0), 0.0, 0.3),
                Handle(pull, np.array([0.0, 1.0, 0.0]), "bar"),
            ),
        ],
        category="desk",
        scale=1.0,
    )
    build_asset(save_bundle(obj, root / ("desk_lip" if long_pull else "desk_worktop")))
    return next(iter(FolderSource(root)))


@pytest.mark.slow
def test_a_pull_under_a_worktop_is_pinched_along_its_length(tmp_path) -> None:
    """The fingers closing across the pull cannot get round it (the worktop overhangs
    it); the solver backs off and pinches it along its length, and the drawer opens.
    Without that second try it stays shut."""
    record = _drawer_under_a_worktop(tmp_path)
    res, trace = _solve_door(record, "drawer_0")
    assert res.success, res.reason
    assert any(t["phase"].endswith(":across") for t in trace)
    res, _ = _solve_door(record, "drawer_0", pinch_retry=False)
    assert not res.success


@pytest.mark.slow
def test_a_pull_the_wide_pinch_cannot_hold_is_pinched_again_narrow(tmp_path) -> None:
    """Under a worktop's lip the fingers opened wide across the pull stop on the lip
    and the pull does not move the drawer; the solver backs off and comes in again with
    the fingers opened just past the pull, pitched up under the lip, and the drawer
    opens. Without that second grasp it stays shut."""
    record = _drawer_under_a_worktop(tmp_path, long_pull=True)
    res, trace = _solve_door(record, "drawer_0")
    assert res.success, res.reason
    assert any(t["phase"] == "regrasp" for t in trace)
    assert trace[-1]["phase"] == "hold"
    pulled = [t for t in trace if t["phase"].startswith("move")]
    assert any(t["phase"] == "approach:narrow" for t in trace)
    # the drawer moved only on the narrow grasp, after the regrasp
    regrasp = min(t["step"] for t in trace if t["phase"] == "regrasp")
    assert max(t["fraction"] for t in pulled if t["step"] < regrasp) < 0.01
    res, trace = _solve_door(record, "drawer_0", pinch_retry=False)
    assert not res.success
    assert res.final_fraction < 0.01
