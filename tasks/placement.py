"""Where the Panda stands for a target part: pure numpy geometry in the object frame.

A drawer's handle moves straight out, so the robot stands in front of it (its ready
gripper ``standoff`` metres in front of the handle). A door's or lid's handle moves on
a circle about the hinge, up to a metre across for a fridge door, so the base is chosen
by a small grid search: every handle point on the opening path (``lower`` to
``lower + 0.9 * range``) within comfortable reach of the shoulder, the gripper able to
face the handle along the path, and the base column clear of the object and of the
volume the part sweeps. With the robot's kinematics (:class:`PandaReach`, SAPIEN's
Pinocchio model) the best candidates are re-ranked by how far along the path the
grasp stays reachable within the joint limits, and the arm starts at the pre-grasp
joint positions found on the way.

A fixed Panda cannot follow the handle of a wide fridge door round its whole arc (up
to 0.9 m radius, 70-90 degrees to the goal). When no base lets it, bases are also
ranked for a pull-then-push plan (:func:`push_plan_poses`): pull the door a third of
the way or so, let go, go round the free edge and push the inner face on
(:func:`push_waypoints_link`), the robot standing where the door, swept only as far
as the push takes it, keeps clear of its base.

Where the arm runs out of reach on the push, the solver moves the base, as a mobile
base would: :func:`push_stand` ranks stands in front of the opening (behind the door's
plane, clear of what the door sweeps from where it is) for pushing it on, and
:func:`base_route` finds the base's way there round the object and the open door.
"""

from __future__ import annotations

import heapq
from typing import Any

import numpy as np

from asset_pipeline.assets.built_asset import MovablePart

READY_TCP = np.array([0.615, 0.0, 0.818])  # tcp in the robot base frame at READY_QPOS (FK)
SHOULDER_HEIGHT = 0.333  # panda_link2 above the base
REACH = (0.35, 0.68)  # comfortable shoulder-to-tcp distances (m)
# the closed handle is grasped first: a base whose shoulder is further from it than
# this (m) cannot start the task at all, however well it suits the rest of the path
FIRST_GRASP_REACH = 0.8
BASE_CLEARANCE = 0.2  # base column radius plus margin (m)
PATH_FRACTIONS = np.linspace(0.0, 0.9, 10)  # of the joint range
FOLLOW_FRACTIONS = np.linspace(0.0, 0.85, 9)


def _yaw_matrix(yaw: float) -> np.ndarray:
    """(3, 3) rotation by ``yaw`` about +z (the robot base's frame in the object's)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about the unit ``axis`` by ``angle`` (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def handle_path(part: MovablePart, fractions: np.ndarray = PATH_FRACTIONS) -> np.ndarray:
    """(K, 3) object-frame handle positions at ``lower + f * range`` for each fraction f."""
    h0 = np.asarray(part.handle_object, dtype=float)
    axis = np.asarray(part.axis, dtype=float)
    if part.joint_type == "prismatic":
        return h0 + np.outer(np.asarray(fractions) * part.range, axis)
    origin = np.asarray(part.origin, dtype=float)
    out = []
    for f in fractions:
        # the rest pose is q = lower; rotate by the travel from there
        out.append(origin + _rot(axis, f * part.range) @ (h0 - origin))
    return np.asarray(out)


def opening_normals(part: MovablePart, fractions: np.ndarray = PATH_FRACTIONS) -> np.ndarray:
    """(K, 3) unit directions in which the handle moves as the part opens (its face normal)."""
    axis = np.asarray(part.axis, dtype=float)
    if part.joint_type == "prismatic":
        return np.tile(axis / np.linalg.norm(axis), (len(fractions), 1))
    path = handle_path(part, fractions)
    r = path - np.asarray(part.origin, dtype=float)
    t = np.cross(axis, r)
    return t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-9)


def face_normal_link(part: MovablePart) -> np.ndarray:
    """(3,) unit outward normal of the face carrying the handle, in the link frame (closed pose)."""
    return opening_normals(part, np.array([0.0]))[0]


PUSH_RADIUS = 0.85  # fraction of the handle's distance from the hinge where the pusher presses


def hinge_frame_link(part: MovablePart) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Joint axis ``a``, radial ``r`` (hinge toward handle, in the face plane) and face
    normal ``n`` unit vectors and the handle's radius (m), in the link frame, closed pose.

    ``n`` is the object axis nearest to the handle's opening direction (the parts'
    faces are axis-aligned), so a bar's standoff does not tilt the frame.
    """
    a = np.asarray(part.axis, dtype=float)
    a = a / np.linalg.norm(a)
    h = np.asarray(part.handle_link, dtype=float)
    t = np.cross(a, h - a * (h @ a))
    n = np.zeros(3)
    k = int(np.argmax(np.abs(t)))
    n[k] = np.sign(t[k])
    r_vec = h - a * (h @ a) - n * (h @ n)
    radius = float(np.linalg.norm(r_vec))
    return a, r_vec / max(radius, 1e-9), n, radius


def push_point_link(part: MovablePart, radial: float, depth: float) -> np.ndarray:
    """(3,) link-frame point ``radial`` x handle radius from the hinge, at the handle's
    height along the axis, ``depth`` metres behind the hinge plane (negative: in front)."""
    a, r, n, radius = hinge_frame_link(part)
    h = np.asarray(part.handle_link, dtype=float)
    return a * (h @ a) + r * (radial * radius) - n * depth


PUSH_DEPTH = 0.05  # m behind the hinge plane assumed for the inner face when planning
PUSH_EDGE_CLEARANCE = 0.08  # m beyond the free edge when going round it
PUSH_SWITCHES = (0.35, 0.45)  # open fractions at which a planned push takes over
PUSH_TILTS = (0.0, 0.25 * np.pi, 0.5 * np.pi)  # pusher orientations, see push_waypoints_link
PUSH_END = 0.9  # of the range: how far a planned push must reach
# a push is less sure than a grasp (the arm may knock the door going round its edge): a
# plan's followed fraction must beat the grasp's by this much
PUSH_MARGIN = 0.35
PUSH_FREE_EDGE = 1.12  # the free edge's distance from the hinge, guessed from the handle's
PUSH_INSIDE_APPROACH = 0.12  # m behind the pressing point a hand coming from inside stops
PUSH_STAND_BACK = 0.35  # m another stand keeps behind the door's plane (room for the hand)


def push_waypoints_link(
    part: MovablePart,
    tilt: float,
    depth: float = PUSH_DEPTH,
    clearance: float = 0.025,
    edge_clearance: float = PUSH_EDGE_CLEARANCE,
    edge: float | None = None,
    press_radial: float = PUSH_RADIUS,
    inside: bool = False,
) -> list[tuple[str, list[np.ndarray]]]:
    """Link-frame tcp poses (two finger orientations each) going from a let-go handle
    round the free edge to the pushing pose on the door's inner face: ``edge`` (beyond
    the free edge, in front of the face), ``behind`` (beyond it, behind the inner face)
    and ``press`` (``press_radial`` x the handle's radius from the hinge, behind the
    inner face ``depth`` metres behind the hinge plane). ``inside``: for a hand that
    comes from the inner side (a robot standing in front of the opening), ``inside``
    (``PUSH_INSIDE_APPROACH`` further behind the pressing point) then ``press``.

    The closed fingers point along ``cos(tilt) * -radial + sin(tilt) * normal``: at 0
    a paddle lying along the inner face, pointing at the hinge (fingers closing along
    the axis, the arm reaching round from beyond the free edge); at pi/2 fingertips
    poking the inner face in the direction it opens (a robot standing behind the door
    pushes it away from itself); in between, slanted. ``clearance`` is kept between
    the inner face and the tcp for the paddle (a finger's half width), 1 cm for a poke.
    The hand's width (0.2 m across the fingers) lies along the hinge, clear of the free
    edge, ``edge`` metres from the hinge (default: ``PUSH_FREE_EDGE`` x the handle's).
    """
    a, r, n, radius = hinge_frame_link(part)
    z = np.cos(tilt) * -r + np.sin(tilt) * n
    behind = depth + clearance * np.cos(tilt) + 0.01 * np.sin(tilt)
    edge = PUSH_FREE_EDGE * radius if edge is None else edge
    beyond = (edge + edge_clearance) / radius
    frames = []
    for y in (a, -a):
        R = np.eye(4)
        R[:3, :3] = np.stack([np.cross(y, z), y, z], axis=1)
        frames.append(R)
    out = []
    stops = [("edge", beyond, -0.1), ("behind", beyond, behind)]
    if inside:
        stops = [("inside", press_radial, behind + PUSH_INSIDE_APPROACH)]
    for name, radial, dep in stops + [("press", press_radial, behind)]:
        p = push_point_link(part, radial, dep)
        poses = []
        for R in frames:
            T = R.copy()
            T[:3, 3] = p
            poses.append(T)
        out.append((name, poses))
    return out


def link_pose(part: MovablePart, fraction: float) -> np.ndarray:
    """(4, 4) the part's link frame in the object frame at ``lower + fraction * range``
    (the link frame is the object frame moved to the joint origin when closed)."""
    T = np.eye(4)
    axis = np.asarray(part.axis, dtype=float)
    origin = np.asarray(part.origin, dtype=float)
    if part.joint_type == "prismatic":
        T[:3, 3] = origin + axis / np.linalg.norm(axis) * fraction * part.range
    else:
        T[:3, :3] = _rot(axis, fraction * part.range)
        T[:3, 3] = origin
    return T


def _interpolate(a: list, b: list, n: int) -> list:
    """``n`` candidate lists stepping from the poses ``a`` to ``b`` (matched by index,
    the last of the shorter list repeated): straight moves, rotations slerped (the
    shortest rotation from each pose of ``a`` to its pose of ``b``, in equal angles)."""
    from scipy.spatial.transform import Rotation

    m = max(len(a), len(b))
    A = np.stack([a[min(i, len(a) - 1)] for i in range(m)])
    B = np.stack([b[min(i, len(b) - 1)] for i in range(m)])
    ra = Rotation.from_matrix(A[:, :3, :3])
    turn = (ra.inv() * Rotation.from_matrix(B[:, :3, :3])).as_rotvec()
    out = []
    for k in range(1, n + 1):
        t = k / n
        T = np.tile(np.eye(4), (m, 1, 1))
        T[:, :3, :3] = (ra * Rotation.from_rotvec(t * turn)).as_matrix()
        T[:, :3, 3] = (1 - t) * A[:, :3, 3] + t * B[:, :3, 3]
        out.append(list(T))
    return out


def push_plan_poses(
    part: MovablePart,
    switch: float,
    tilt: float,
    depth: float = PUSH_DEPTH,
    standoff: float = 0.12,
) -> tuple[list, np.ndarray]:
    """Candidate tcp poses (object frame), step by step, of the pull-then-push plan:
    the grasp from closed to ``switch`` of the range, then :func:`push_steps`; and the
    part's open fraction at each step. For :meth:`PandaReach.follow`."""
    pulled_f = np.linspace(0.0, switch, 4)
    steps, fractions = push_steps(part, switch, tilt, depth, standoff)
    return grasp_poses(part, pulled_f) + steps[1:], np.concatenate([pulled_f, fractions[1:]])


def push_steps(
    part: MovablePart,
    fraction: float,
    tilt: float,
    depth: float = PUSH_DEPTH,
    standoff: float = 0.12,
) -> tuple[list, np.ndarray]:
    """Candidate tcp poses (object frame), step by step, of a push from ``fraction``
    of the range: the grasp there, backing ``standoff`` out of the face, round the
    free edge (:func:`push_waypoints_link`, tilt ``tilt``) and pushing the inner face
    on to ``PUSH_END`` of the range; and the part's open fraction at each step."""
    held = grasp_poses(part, np.array([fraction]))[0]
    steps = [held]
    back = []
    for T in held:
        B = T.copy()
        B[:3, 3] -= T[:3, 2] * standoff
        back.append(B)
    steps += _interpolate(held, back, 2)
    return _round_and_press(part, fraction, tilt, depth, steps, back)


def _round_and_press(
    part: MovablePart,
    fraction: float,
    tilt: float,
    depth: float,
    steps: list,
    prev: list | None,
    inside: bool = False,
    end: float = PUSH_END,
) -> tuple[list, np.ndarray]:
    """``steps`` followed by the hand's way from ``prev`` (None: no way there, the
    first waypoint is the first step) round the free edge of the part ``fraction``
    open (``inside``: from the inner side, see :func:`push_waypoints_link`) and the
    push on to ``end``; and the part's open fraction at each step."""
    L = link_pose(part, fraction)
    waypoints = push_waypoints_link(part, tilt, depth, inside=inside)
    for _, poses in waypoints:
        cur = [L @ T for T in poses]
        steps += [cur] if prev is None else _interpolate(prev, cur, 3)
        prev = cur
    press = waypoints[-1][1]
    pushed_f = np.linspace(fraction, max(end, fraction), 6)[1:]
    steps += [[link_pose(part, f) @ T for T in press] for f in pushed_f]
    fractions = np.concatenate([np.full(len(steps) - len(pushed_f), fraction), pushed_f])
    return steps, fractions


def _swept_points(
    part: MovablePart, bounds: tuple | None = None, end: float = 1.0, start: float = 0.0
) -> np.ndarray:
    """(M, 3) points of the volume a door sweeps (from ``start`` up to ``end`` of its
    range): hinge-to-handle segments along the path.

    With the object's ``bounds``, a door on a horizontal hinge (bottom-hinged, a lid)
    also spans the object's extent along its hinge: it comes down over its full width,
    onto a robot standing beside the handle.
    """
    origin = np.asarray(part.origin, dtype=float)
    path = handle_path(part, np.linspace(start, end, 12))
    s = np.linspace(0.0, 1.15, 8)[:, None, None]
    pts = (origin + s * (path - origin)[None]).reshape(-1, 3)
    axis = np.asarray(part.axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    if bounds is None or abs(axis[2]) > 0.7:
        return pts
    lo, hi = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (0, 1)])
    span = corners @ axis
    flat = pts - np.outer(pts @ axis, axis)
    along = np.linspace(span.min(), span.max(), 9)
    return (flat[None] + along[:, None, None] * axis).reshape(-1, 3)


ARM_CLEARANCE = 0.08  # m kept between the arm's link axes and the door or the object


def _arm_clearance(part: MovablePart, bounds: tuple, fractions: np.ndarray):
    """``clear(k, points)``: whether arm points (object frame) keep off the door at
    ``lower + fractions[k] * range`` (a slab from the hinge out past the handle, over
    the object's extent along the hinge) and off the object's closed box."""
    lo, hi = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    axis = np.asarray(part.axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    origin = np.asarray(part.origin, dtype=float)
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    span = (corners - origin) @ axis
    a0, a1 = span.min() - ARM_CLEARANCE, span.max() + ARM_CLEARANCE
    path = handle_path(part, fractions)
    normals = opening_normals(part, fractions)
    m = ARM_CLEARANCE

    def clear(k: int, pts: np.ndarray) -> bool:
        d = pts - origin
        r_vec = path[k] - origin
        r_vec = r_vec - axis * (r_vec @ axis)
        radius = np.linalg.norm(r_vec)
        radial = d @ (r_vec / radius)
        normal = d @ normals[k]
        along = d @ axis
        in_door = (
            (radial > -m)
            & (radial < radius + 0.1 + m)
            & (normal > -0.08 - m)
            & (normal < m)
            & (along > a0)
            & (along < a1)
        )
        in_body = ((pts > lo - m) & (pts < hi + m)).all(1)
        return not (in_door.any() or in_body.any())

    return clear


def _box_distance_xy(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(C,) horizontal distance from points (C, 2) to the rectangle lo..hi (0 inside)."""
    d = np.maximum(np.maximum(lo - p, p - hi), 0.0)
    return np.linalg.norm(d, axis=1)


def grasp_poses(part: MovablePart, fractions: np.ndarray = FOLLOW_FRACTIONS) -> list:
    """Per fraction, the candidate tcp poses (4, 4) grasping the handle (object frame):
    z into the handle's face, fingers (y) closing across the bar, either way round."""
    path = handle_path(part, fractions)
    normals = opening_normals(part, fractions)
    axis = np.asarray(part.axis, dtype=float)
    bar0 = np.asarray(part.handle_axis, dtype=float)
    out = []
    for f, p, n in zip(fractions, path, normals, strict=True):
        bar = bar0 if part.joint_type == "prismatic" else _rot(axis, f * part.range) @ bar0
        a = -n
        if part.handle_kind == "knob" and abs(a[2]) < 0.7:  # pinched sideways (the solver)
            bar = np.array([0.0, 0.0, 1.0])
        c = np.cross(a, bar)
        if np.linalg.norm(c) < 1e-3:
            c = np.cross(a, np.cross(np.array([0.0, 0.0, 1.0]), a))
        c /= np.linalg.norm(c)
        poses = []
        for sign in (1.0, -1.0):
            T = np.eye(4)
            T[:3, :3] = np.stack([np.cross(sign * c, a), sign * c, a], axis=1)
            T[:3, 3] = p
            poses.append(T)
        out.append(poses)
    return out


class PandaReach:
    """Inverse kinematics of the task's Panda (SAPIEN's Pinocchio model) for placement.

    ``follow(base, yaw, grasps, standoff)`` -> (the fraction of the consecutive grasp
    poses, from the closed pose on, the arm reaches within its joint limits, each
    seeded by the last; the joint positions at the pre-grasp ``standoff`` metres out).
    """

    margin = 0.12  # rad kept from every joint limit

    def __init__(self, articulation: Any, tcp_link: str, ready_qpos: np.ndarray) -> None:
        self.model = articulation.create_pinocchio_model()
        names = [link.name for link in articulation.links]
        self.tcp = next(i for i, n in enumerate(names) if n.endswith(tcp_link))
        self.limits = np.asarray(articulation.get_qlimits(), dtype=float)[:7]
        self.ready = np.asarray(ready_qpos, dtype=float)
        self.mask = [1] * 7 + [0] * (len(self.ready) - 7)
        # shoulder, upper arm, elbow and forearm: the links that must keep off the door
        arm = [f"panda_link{k}" for k in (2, 3, 4, 5)]
        self.arm_links = [i for i, n in enumerate(names) if any(n.endswith(a) for a in arm)]

    def arm_points(self, q: np.ndarray) -> np.ndarray:
        """(M, 3) points along the shoulder, upper arm, elbow and forearm (root frame)."""
        self.model.compute_forward_kinematics(np.asarray(q, dtype=float))
        pts = np.array([self.model.get_link_pose(i).p for i in self.arm_links], dtype=float)
        if len(pts) < 2:
            return pts
        mids = 0.5 * (pts[1:] + pts[:-1])
        return np.concatenate([pts, mids])

    def _ik(self, T: np.ndarray, q0: np.ndarray) -> np.ndarray | None:
        import sapien
        from scipy.spatial.transform import Rotation

        xyzw = Rotation.from_matrix(T[:3, :3]).as_quat()
        pose = sapien.Pose(T[:3, 3], [xyzw[3], xyzw[0], xyzw[1], xyzw[2]])
        q, ok, _ = self.model.compute_inverse_kinematics(
            self.tcp, pose, initial_qpos=q0, active_qmask=self.mask, max_iterations=100
        )
        q = np.asarray(q, dtype=float)
        lo, hi = self.limits[:, 0] + self.margin, self.limits[:, 1] - self.margin
        if not ok or (q[:7] < lo).any() or (q[:7] > hi).any():
            return None
        return q

    def follow(
        self,
        base: np.ndarray,
        yaw: float,
        grasps: list,
        standoff: float = 0.12,
        clear: Any = None,
        q0: np.ndarray | None = None,
    ) -> tuple[float, np.ndarray | None]:
        """``clear(k, points)``: optional check that the arm's points (object frame) at
        grasp ``k`` keep off the door and the object; grasps where they do not count in
        ``self.last_hits`` (a fraction of the grasps), clear solutions are preferred.
        ``q0``: the joints to start from (default: the ready pose).

        A hand holding a bar cannot turn over on it: when every step offers the same
        number of poses (the fingers closing either way round), the i-th pose of every
        step is followed as one plan. From the ready pose every such plan is tried and the
        one followed furthest wins (its pre-grasp joints start the arm, so the solver grasps
        that way round); from ``q0`` (a hand already holding) only the plan whose first
        pose is nearest the hand's orientation now."""
        counts = {len(poses) for poses in grasps}
        if len(counts) != 1 or counts == {1}:
            return self._follow(base, yaw, grasps, standoff, clear, q0)
        n = counts.pop()
        plans = [[[poses[i]] for poses in grasps] for i in range(n)]
        if q0 is not None:
            self.model.compute_forward_kinematics(np.asarray(q0, dtype=float))
            hand = self.model.get_link_pose(self.tcp)
            from scipy.spatial.transform import Rotation

            w, x, y, z = hand.q
            R_now = _yaw_matrix(yaw) @ Rotation.from_quat([x, y, z, w]).as_matrix()
            i = int(np.argmax([np.trace(T[:3, :3].T @ R_now) for T in grasps[0]]))
            return self._follow(base, yaw, plans[i], standoff, clear, q0)
        best: tuple | None = None
        for plan in plans:
            frac, start = self._follow(base, yaw, plan, standoff, clear, q0)
            key = (frac, -self.last_hits)
            if best is None or key > best[0]:
                best = (key, frac, start, self.last_hits)
        assert best is not None
        self.last_hits = best[3]
        return best[1], best[2]

    def _follow(
        self,
        base: np.ndarray,
        yaw: float,
        grasps: list,
        standoff: float,
        clear: Any,
        q0: np.ndarray | None,
    ) -> tuple[float, np.ndarray | None]:
        """:meth:`follow` with any of a step's poses allowed (the nearest clear one)."""
        to_root = np.eye(4)
        to_root[:3, :3] = _yaw_matrix(yaw).T
        to_root[:3, 3] = -to_root[:3, :3] @ base
        from_root = np.linalg.inv(to_root)
        q = self.ready.copy() if q0 is None else np.asarray(q0, dtype=float).copy()
        reached, start, hits = 0, None, 0
        for k, poses in enumerate(grasps):
            best = None
            for T in poses:
                q_pre = None
                if k == 0:  # the pre-grasp, ``standoff`` out, must be reachable too
                    pre = T.copy()
                    pre[:3, 3] -= T[:3, 2] * standoff
                    q_pre = self._ik(to_root @ pre, q)
                    if q_pre is None:
                        continue
                    cand = self._ik(to_root @ T, q_pre)
                else:
                    cand = self._ik(to_root @ T, q)
                if cand is None:
                    continue
                hit = False
                if clear is not None:
                    pts = self.arm_points(cand)
                    hit = not clear(k, pts @ from_root[:3, :3].T + from_root[:3, 3])
                key = (hit, float(np.abs(cand - q).sum()))
                if best is None or key < best[2]:
                    best = (cand, q_pre, key)
            if best is None:
                break
            q = best[0]
            hits += int(best[2][0])
            if k == 0:
                start = best[1]
            reached += 1
        self.last_hits = hits / len(grasps)
        return reached / len(grasps), start


def _candidate_bases(
    part: MovablePart,
    bounds: tuple,
    path: np.ndarray,
    approach: np.ndarray,
    swept_end: float = 1.0,
    high: bool = False,
    swept_start: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid of bases (C, 3) in the object frame, their yaws (C,) toward the middle of
    ``path`` and heuristic costs (C,; inf: the base column hits the object or the door
    swept from ``swept_start`` up to ``swept_end`` of its range): ``path`` points (K, 3)
    within comfortable reach of the shoulder, the gripper, pointing along ``approach``
    (K, 3) at each, reaching away from the body. ``high``: also bases up to 0.8 m above the path,
    standing over the volume the door sweeps (a bottom-hinged door or a lid comes down
    in front of the object, under them)."""
    lo, hi = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    swept = _swept_points(part, bounds, swept_end, swept_start)
    centre = path.mean(axis=0)
    xs = np.arange(lo[0] + 0.1, hi[0] + 1.4, 0.05)
    ys = np.arange(lo[1] - 1.0, hi[1] + 1.0, 0.05)
    zs = centre[2] - SHOULDER_HEIGHT + np.arange(-0.4, 0.81 if high else 0.41, 0.1)
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    base = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)  # (C, 3)
    shoulder = base + np.array([0.0, 0.0, SHOULDER_HEIGHT])
    d = path[None] - shoulder[:, None]  # (C, K, 3)
    dist = np.linalg.norm(d, axis=2)
    dh = np.linalg.norm(d[..., :2], axis=2)
    cost = (np.maximum(dist - REACH[1], 0) ** 2 + np.maximum(REACH[0] - dist, 0) ** 2).sum(1)
    cost += (np.maximum(0.3 - dh, 0) ** 2).sum(1)
    # the gripper reaches away from the body more easily than back toward it
    u = d[..., :2] / np.maximum(dh[..., None], 1e-6)
    facing = (approach[None, :, :2] * u).sum(2)
    cost += 0.3 * (np.maximum(0.3 - facing, 0) ** 2).sum(1)
    # prefer standing near the middle of the comfortable range
    cost += 0.01 * ((dist - 0.55) ** 2).sum(1)
    # the base column must stay clear of the object and of the swept volume
    clear_obj = _box_distance_xy(base[:, :2], lo[:2], hi[:2])
    bad = clear_obj < BASE_CLEARANCE
    bad |= dist[:, 0] > FIRST_GRASP_REACH
    # (the arm rises above its base: any height of the swept volume counts; ``high``:
    # only the swept volume above the base's bottom, under a robot standing high)
    # (computed on the horizontal grid once: the bases differ in height only along zs)
    xy = np.stack([X[:, :, 0].ravel(), Y[:, :, 0].ravel()], axis=1)  # (nx * ny, 2)
    gap2 = ((swept[None, :, :2] - xy[:, None]) ** 2).sum(2)  # (nx * ny, M)
    near = gap2 < BASE_CLEARANCE**2
    if high:
        under = swept[None, :, 2] > zs[:, None] - 0.05  # (nz, M)
        hit = (near[:, None, :] & under[None]).any(2)  # (nx * ny, nz)
    else:
        hit = np.repeat(near.any(1)[:, None], len(zs), axis=1)
    bad |= hit.ravel()
    # the ready gripper must not start inside the object
    yaw = np.arctan2(centre[1] - base[:, 1], centre[0] - base[:, 0])
    tcp = base + np.stack(
        [np.cos(yaw) * READY_TCP[0], np.sin(yaw) * READY_TCP[0], np.full_like(yaw, READY_TCP[2])],
        axis=1,
    )
    inside = (tcp > lo - 0.08).all(1) & (tcp < hi + 0.08).all(1)
    cost += np.where(inside, 1.0, 0.0)
    return base, yaw, np.where(bad, np.inf, cost)


def _shortlist(cost: np.ndarray, n_checked: tuple[int, int]) -> list[int]:
    """The ``n_checked[0]`` cheapest finite candidates and ``n_checked[1]`` others (seeded)."""
    ranked = [int(i) for i in np.argsort(cost) if np.isfinite(cost[i])]
    rng = np.random.default_rng(0)
    rest = ranked[n_checked[0] :]
    extra = rng.choice(rest, size=min(n_checked[1], len(rest)), replace=False) if rest else []
    return ranked[: n_checked[0]] + [int(i) for i in extra]


def push_plan_points(part: MovablePart, switch: float) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) object-frame points the tcp visits in a pull-then-push plan switching at
    ``switch`` (the handle up to it, then the pressing point on to ``PUSH_END``) and
    (K, 3) the directions the gripper points there (a slanted pusher's for the push)."""
    grasp_f = np.linspace(0.0, switch, 4)
    push_f = np.linspace(switch, PUSH_END, 6)
    a, r, n, _ = hinge_frame_link(part)
    press = push_point_link(part, PUSH_RADIUS, PUSH_DEPTH)
    slant = (n - r) / np.sqrt(2.0)
    points = [link_pose(part, f)[:3] @ np.append(press, 1.0) for f in push_f]
    dirs = [link_pose(part, f)[:3, :3] @ slant for f in push_f]
    return (
        np.concatenate([handle_path(part, grasp_f), np.asarray(points)]),
        np.concatenate([-opening_normals(part, grasp_f), np.asarray(dirs)]),
    )


def grasp_score(
    reach: PandaReach,
    part: MovablePart,
    bounds: tuple,
    base: np.ndarray,
    yaw: float,
    standoff: float = 0.12,
    q0: np.ndarray | None = None,
    start: float = 0.0,
) -> tuple[float, float, np.ndarray | None]:
    """How well a robot at ``base``, ``yaw`` (object frame) follows the grasped handle
    from ``start`` of the range to the end of ``FOLLOW_FRACTIONS``: (the score: the
    fraction of the path followed less half the fraction where the arm is in the door's
    way, which knocks it back or jams as badly as half the path; the fraction followed;
    the pre-grasp joints)."""
    fractions = np.linspace(start, FOLLOW_FRACTIONS[-1], len(FOLLOW_FRACTIONS))
    clear = _arm_clearance(part, bounds, fractions)
    frac, q = reach.follow(base, yaw, grasp_poses(part, fractions), standoff, clear, q0=q0)
    return frac - 0.5 * reach.last_hits, frac, q


def best_push_plan(
    reach: PandaReach,
    part: MovablePart,
    base: np.ndarray,
    yaw: float,
    standoff: float = 0.12,
    q0: np.ndarray | None = None,
    depth: float = PUSH_DEPTH,
    plans: dict | None = None,
) -> tuple[float, float, float, np.ndarray | None]:
    """The best pull-then-push plan (:func:`push_plan_poses`) for a robot at ``base``,
    ``yaw`` (object frame): (the fraction of its steps the arm follows, the switch
    fraction, the tilt, the pre-grasp joints), over ``PUSH_SWITCHES`` x ``PUSH_TILTS``.
    ``plans``: a dict the plans' poses are kept in between calls for the same part,
    ``depth`` and ``standoff`` (they do not depend on the robot's stand)."""
    best = (-1.0, PUSH_SWITCHES[0], PUSH_TILTS[0], None)
    plans = {} if plans is None else plans
    for switch in PUSH_SWITCHES:
        for tilt in PUSH_TILTS:
            if (switch, tilt) not in plans:
                plans[switch, tilt] = push_plan_poses(part, switch, tilt, depth, standoff)[0]
            steps = plans[switch, tilt]
            frac, q = reach.follow(base, yaw, steps, standoff, q0=q0)
            if frac > best[0]:
                best = (frac, switch, tilt, q)
            if frac == 1.0:
                return best
    return best


def robot_base_for_part(
    part: MovablePart,
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]],
    standoff: float = 0.12,
    reach: PandaReach | None = None,
    n_checked: tuple[int, int] = (25, 50),
) -> tuple[np.ndarray, float, np.ndarray | None]:
    """Robot base position (3,), yaw (rad) in the object frame and arm joint positions
    (or None: the ready pose) at the start, for opening ``part``.

    Prismatic parts: facing the front (yaw pi), ready gripper ``standoff`` in front of
    the handle. Revolute parts: grid search (see the module docstring); with ``reach``
    the ``n_checked[0]`` best candidates and ``n_checked[1]`` others drawn at random
    (seeded) are ranked by inverse kinematics along the grasped path, and the arm
    starts at the pre-grasp ``standoff`` in front of the handle. When no base lets the
    grasp follow the whole path (a wide fridge door swings its handle round a metre-wide
    arc), bases are also ranked for pulling part of the way and pushing the door's inner
    face on from there (:func:`best_push_plan`; the solver switches the same way).
    """
    if part.joint_type == "prismatic":
        handle = np.asarray(part.handle_object, dtype=float)
        base = handle + np.array([standoff + READY_TCP[0], 0.0, -READY_TCP[2]])
        return base, float(np.pi), None
    hi = np.asarray(bounds[1], dtype=float)
    path = handle_path(part, PATH_FRACTIONS)  # (K, 3)
    approach = -opening_normals(part, PATH_FRACTIONS)
    base, yaw, cost = _candidate_bases(part, bounds, path, approach)
    best = int(np.argmin(cost))
    if not np.isfinite(cost[best]):  # nothing clear: fall back to the front
        centre = path.mean(axis=0)
        return np.array([hi[0] + 0.8, centre[1], centre[2] - 0.6]), float(np.pi), None
    if reach is None:
        return base[best], float(yaw[best]), None
    # the heuristic's best few and some others, ranked by how far along the path the
    # grasp stays kinematically feasible (inverse kinematics, seeded step by step)
    best_score, picked, full = -np.inf, (base[best], float(yaw[best]), None), False
    axis = np.asarray(part.axis, dtype=float)
    for high in (False, True):
        if high:  # a door on a horizontal hinge out of reach: try standing over it
            if best_score > 0.0 or abs(axis[2]) > 0.7 * np.linalg.norm(axis):
                break
            base, yaw, cost = _candidate_bases(part, bounds, path, approach, high=True)
        for i in _shortlist(cost, n_checked):
            score, _, q = grasp_score(reach, part, bounds, base[i], float(yaw[i]), standoff)
            if score - 0.01 * cost[i] > best_score:
                best_score, picked = score - 0.01 * cost[i], (base[i], float(yaw[i]), q)
                full = score == 1.0
    if full:
        return picked
    # pull part of the way, then push: bases for that plan, ranked the same way
    plans: dict = {}
    for switch in PUSH_SWITCHES:
        pts, dirs = push_plan_points(part, switch)
        # (the push stops short of the door's stop: a robot may stand beyond that)
        base, yaw, cost = _candidate_bases(part, bounds, pts, dirs, PUSH_END)
        for i in _shortlist(cost, (n_checked[0] // 2, n_checked[1] // 2)):
            frac, _, _, q = best_push_plan(
                reach, part, base[i], float(yaw[i]), standoff, plans=plans
            )
            score = frac - PUSH_MARGIN - 0.01 * cost[i]
            if score > best_score:
                best_score, picked = score, (base[i], float(yaw[i]), q)
    return picked


def push_stand(
    reach: PandaReach,
    part: MovablePart,
    bounds: tuple,
    fraction: float,
    depth: float = PUSH_DEPTH,
    standoff: float = 0.12,
    n_checked: tuple[int, int] = (12, 24),
    end: float = PUSH_END,
) -> tuple[np.ndarray, float, float, float] | None:
    """Another stand for pushing on a door left ``fraction`` open (the arm ran out of
    reach where it stands): (base (3,), yaw in the object frame, the open fraction up to
    which the arm follows the push from its ready pose, the pusher's tilt), or None when
    no base is clear.

    The push presses the inner face ``PUSH_RADIUS`` x the handle's radius from the
    hinge from ``fraction`` on to ``end``, or, where no base lets the arm follow that far,
    part of the way (a door swinging round to lie along the object's side takes the
    pressing point round the corner: a second push from a third stand goes on from
    there). The base stands clear of the object and of the volume the door sweeps over
    the stretch pushed only: the space it swept on its way to ``fraction`` (in front of
    where it was closed) is free now, and a robot standing there, at least
    ``PUSH_STAND_BACK`` behind the door's plane, faces the inner face. Candidates are
    ranked as in :func:`robot_base_for_part`. Only for a door on a vertical hinge.
    """
    axis = np.asarray(part.axis, dtype=float)
    if abs(axis[2]) < 0.7 * np.linalg.norm(axis) or end <= fraction:
        return None  # a lid or a bottom-hinged door: its inner side is under it
    _, r, n, _ = hinge_frame_link(part)
    press = np.append(push_point_link(part, PUSH_RADIUS, depth), 1.0)
    slant = (n - r) / np.sqrt(2.0)
    L = link_pose(part, fraction)
    best: tuple | None = None
    for stop in np.linspace(end, fraction + (end - fraction) / 3, 3):
        push_f = np.linspace(fraction, stop, 6)
        pts = np.array([link_pose(part, f)[:3] @ press for f in push_f])
        dirs = np.array([link_pose(part, f)[:3, :3] @ slant for f in push_f])
        base, yaw, cost = _candidate_bases(part, bounds, pts, dirs, stop, swept_start=fraction)
        # on the inner side of the door (an arm reaching round from the outer side
        # would sweep it shut)
        inner = (base - L[:3, 3]) @ (L[:3, :3] @ n)
        cost = np.where(inner < -PUSH_STAND_BACK, cost, np.inf)
        for tilt in PUSH_TILTS:
            steps, fractions = _round_and_press(part, fraction, tilt, depth, [], None, True, stop)
            for i in _shortlist(cost, n_checked):
                followed, _ = reach.follow(base[i], float(yaw[i]), steps, standoff)
                k = int(round(followed * len(steps)))
                reached = float(fractions[k - 1]) if k else fraction
                key = (reached, -cost[i])
                if best is None or key > best[0]:
                    best = (key, base[i], float(yaw[i]), reached, tilt)
        if best is not None and best[3] >= stop - 1e-9:
            break  # the whole stretch: no need for a shorter one
    if best is None:
        return None
    return best[1], best[2], best[3], best[4]


ROUTE_CELL = 0.05  # m: the grid a base's route between two stands is planned on
ROUTE_BERTH = 0.5  # m a driving base keeps from the object and the door where it can


def base_route(
    part: MovablePart,
    bounds: tuple,
    fraction: float,
    start: np.ndarray,
    goal: np.ndarray,
    clearance: float = BASE_CLEARANCE,
    berth: float = ROUTE_BERTH,
) -> np.ndarray | None:
    """(W, 2) object-frame xy waypoints of a route for the robot's base from ``start``
    to ``goal`` (xy) that keeps ``clearance`` from the object's box and from the door
    standing ``fraction`` open, and ``berth`` where it can (the arm, drawn in over the
    base, reaches out past the base column): the cheapest path on a ``ROUTE_CELL`` grid
    (8-connected; a cell within the berth costs more the nearer it is), then straight
    legs wherever they keep as far off as the path they replace. None: no such route.

    The start may lie within the clearance (the arm was just pushing there): the route
    then leaves it only by cells that get further from the object and the door.
    """
    lo, hi = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    start, goal = np.asarray(start, dtype=float)[:2], np.asarray(goal, dtype=float)[:2]
    door = _swept_points(part, bounds, fraction, fraction)[:, :2]

    def gap_at(q: np.ndarray) -> np.ndarray:  # distance to the object's box or the door
        near = np.min(np.linalg.norm(q[:, None] - door[None], axis=2), axis=1)
        return np.minimum(_box_distance_xy(q, lo[:2], hi[:2]), near)

    corner = np.minimum(np.minimum(start, goal), lo[:2]) - 1.0
    far = np.maximum(np.maximum(start, goal), hi[:2]) + 1.0
    shape = np.ceil((far - corner) / ROUTE_CELL).astype(int) + 1
    axes = [corner[k] + ROUTE_CELL * np.arange(shape[k]) for k in (0, 1)]
    gx, gy = np.meshgrid(*axes, indexing="ij")
    cells = np.stack([gx.ravel(), gy.ravel()], axis=1)
    gap = gap_at(cells).reshape(shape)
    free = gap >= clearance
    # a cell inside the berth costs up to 20 cells more, the nearer the more
    toll = 1.0 + 20.0 * np.clip((berth - gap) / max(berth - clearance, 1e-6), 0.0, 1.0) ** 2

    def cell(p: np.ndarray) -> tuple[int, int]:
        i, j = np.clip(np.round((p - corner) / ROUTE_CELL).astype(int), 0, shape - 1)
        return int(i), int(j)

    s, g = cell(start), cell(goal)
    if not free[g]:
        return None
    dist = {s: 0.0}
    prev = {s: s}
    heap = [(0.0, s)]
    moves = [
        (di, dj, float(np.hypot(di, dj))) for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj
    ]
    while heap:
        d, c = heapq.heappop(heap)
        if c == g:
            break
        if d > dist[c]:
            continue
        for di, dj, step in moves:
            n = (c[0] + di, c[1] + dj)
            if not (0 <= n[0] < shape[0] and 0 <= n[1] < shape[1]):
                continue
            if not free[n] and gap[n] <= gap[c]:
                continue
            nd = d + step * toll[n]
            if nd < dist.get(n, np.inf):
                dist[n], prev[n] = nd, c
                heapq.heappush(heap, (nd, n))
    if g not in prev:
        return None
    path = [g]
    while path[-1] != s:
        path.append(prev[path[-1]])
    pts = corner + ROUTE_CELL * np.asarray(path[::-1], dtype=float)
    pts[0], pts[-1] = start, goal

    # shortcuts: from each waypoint straight to the furthest later one the straight
    # leg reaches no nearer the object or the door than the path it replaces
    along = gap_at(pts)
    keep, k = [0], 0
    while k < len(pts) - 1:
        for m in range(len(pts) - 1, k, -1):
            n = max(2, int(np.ceil(np.linalg.norm(pts[m] - pts[k]) / (ROUTE_CELL / 2))))
            leg = pts[k] + np.linspace(0.0, 1.0, n)[:, None] * (pts[m] - pts[k])
            if m == k + 1 or gap_at(leg).min() >= min(berth, along[k : m + 1].min()) - 1e-9:
                keep.append(m)
                k = m
                break
    return pts[keep]
