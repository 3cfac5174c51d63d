"""Generation metrics: how far a predicted articulated object is from the ground truth.

The PAct paper reports, after SINGAPO and DIPO, seven numbers per object (all lower
is better): RS-dgIoU, AS-dgIoU, RS-dcDist, AS-dcDist, RS-dCD, AS-dCD and AOR. ``RS-``
is the resting state, ``AS-`` the mean over sampled articulated states. This module
computes them from two ``ArticulatedObject`` s; ``evaluate_dirs`` does it for folders
of bundles and ``format_table`` renders the result for the CLI (``pact eval-gen``).

Definitions (the choices SINGAPO's ``metrics/`` code leaves open are fixed here)
--------------------------------------------------------------------------------
Normalization
    Each object is normalized on its own: translated so that the centre of its rest
    axis-aligned bounding box (all parts, every joint at ``lower``) is the origin and
    scaled uniformly by ``s = 1 / (largest rest extent)``, so it fits the unit cube
    [-0.5, 0.5]^3 of the generator space with its longest side exactly 1. A uniform
    scale keeps aspect ratios and makes revolute joints stay rigid rotations (SINGAPO
    stretches the prediction per axis onto the ground truth's box, which shears
    rotations); normalizing each object by itself makes the metrics independent of
    the unknown metric size of generator output (``scale is None``). Distances are in
    these normalized units; prismatic joint values are scaled by ``s`` with the
    geometry, revolute angles are unchanged.

Part boxes
    A part's box is the axis-aligned bounding box (object axes) of its normalized rest
    mesh, each side padded symmetrically to at least ``MIN_EXTENT`` = 1e-3 so that flat
    parts keep a volume. At joint fraction ``f`` the box is moved rigidly with the
    part's joint (an oriented box: the rest box under the joint's rigid motion), and
    its centre is the moved rest-box centre (as SINGAPO's ``sampling_giou`` /
    ``sampling_cDist``).

gIoU
    ``gIoU(A, B) = IoU - (|C| - |A u B|) / |C|`` (Rezatofighi et al. 2019), with the
    exact intersection volume of the two (possibly rotated) posed boxes, computed as
    a convex polytope intersection rather than SINGAPO's 10k-point Monte Carlo
    estimate, and ``C`` the convex hull of both posed boxes: the smallest enclosing
    convex set of the gIoU paper. For two axis-aligned boxes offset along one axis
    (stacked drawers) ``C`` is their enclosing box, as in SINGAPO's ``giou_aabb``; for
    other offsets it is smaller than that box. Unlike an enclosing box aligned with the
    object axes it does not depend on orientation, so two identical rotated boxes
    (an open door against an identical open door) have gIoU 1. gIoU is in [-1, 1];
    ``dgIoU = 1 - gIoU`` is in [0, 2].

dcDist
    Euclidean distance between the centres of matched posed part boxes, capped at
    ``DCDIST_UNMATCHED`` = sqrt(3) (the diagonal of the unit cube, the largest distance
    two rest-state centres can have; the cap only acts on articulated states where a
    part has left the cube, and guarantees a matched part never scores worse than a
    missing one).

Which parts, matching, and unmatched parts
    dgIoU and dcDist compare the non-base parts (SINGAPO's default
    ``iou_include_base=False``; the base of each object is matched to the other's base
    and, after normalization, nearly fills the cube in both). Non-base parts are
    matched one-to-one by the Hungarian algorithm (``scipy.optimize.linear_sum_assignment``)
    at rest on the cost ``dgIoU + dcDist`` of the rest boxes. When the part counts
    differ, each part left unmatched (in either object) counts as one more slot with
    the maximal values ``dgIoU = 2`` and ``dcDist = sqrt(3)``; the per-state score is the
    mean over ``max(n_pred, n_gt)`` slots. Every matched slot scores at most these
    values, so leaving a ground-truth part out never scores better than predicting it
    anywhere, and a part beyond the ground-truth count never lowers a score (SINGAPO
    instead maps surplus parts to their nearest part, which does not penalize them). Both objects without non-base parts score 0.

Articulated states
    ``n_states`` fractions ``f = linspace(0, 1, n_states)`` (default 5, SINGAPO's
    ``num_states``); at fraction ``f`` every movable joint is set to
    ``lower + f * (upper - lower)`` at once (all joints move together). ``RS-`` is
    ``f = 0`` (every joint at ``lower``, closed); ``AS-`` is the mean over all ``n_states``
    fractions, ``f = 0`` included (as SINGAPO). The match is fixed at rest and kept for
    every state. ``revolute_range`` (radians, default None) replaces every revolute
    joint's range by a fixed one, ``lower + f * revolute_range``, as SINGAPO's
    ``rotation_fix_range`` (pi / 2); by default each joint's own range is used.

dCD
    Chamfer distance between the whole objects' surfaces: ``n_points`` (default 10 000)
    points per object, sampled uniformly by area over all parts' triangles of the
    normalized rest meshes with ``numpy.random.default_rng(seed)`` (a fresh generator
    per object and parts visited in name order, so identical objects, whatever the
    order of their parts, get identical samples and dCD = 0), each point
    then moved with its part's joint for every state. ``CD(A, B) = mean_a min_b |a-b|^2 +
    mean_b min_a |a-b|^2``: squared L2, both directions summed, i.e. PyTorch3D's
    ``chamfer_distance`` default that SINGAPO reports (``chamfer(..., squared=False)``
    gives the plain L2 variant). Computed with ``scipy.spatial.cKDTree``. Missing or
    extra geometry shows up in dCD directly, so it needs no unmatched-part penalty.

AOR (average overlapping ratio)
    A property of the predicted object alone, lower is better (the PAct tables mark it
    with a down arrow). Following SINGAPO's ``metrics/aor.py``: for each of
    ``aor_states`` fractions ``f = linspace(0, 1, aor_states)`` (default 10, SINGAPO's
    default), the volumetric IoU of every pair of sibling parts (parts with the same
    parent; here all non-base parts, the children of ``base``) is computed between
    their posed part boxes; the pair IoUs are averaged per state and the states
    averaged. Objects with fewer than two sibling parts have no AOR: the value is NaN
    (SINGAPO returns -1 and drops the object), and aggregates skip it.

Joint types missed
    Not one of the paper's metrics: a count of the ground truth's movable joints
    (revolute, prismatic, continuous: all but fixed) whose type the prediction lacks,
    the two objects' joint types compared as multisets (a door predicted as a drawer
    counts one; an extra part counts nothing). Folders report its sum over objects with
    the number of ground-truth movable joints (``joint_types_missed``, ``movable_joints``).
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rich.table import Table
from scipy.optimize import linear_sum_assignment
from scipy.spatial import ConvexHull, QhullError, cKDTree

from generator.articulated import ArticulatedObject, Joint, ObjectModelError
from generator.bundle import find_bundles, load_bundle

log = logging.getLogger(__name__)

METRIC_KEYS = ("RS-dgIoU", "AS-dgIoU", "RS-dcDist", "AS-dcDist", "RS-dCD", "AS-dCD", "AOR")
DGIOU_UNMATCHED = 2.0
DCDIST_UNMATCHED = math.sqrt(3.0)
MIN_EXTENT = 1e-3
DEFAULT_STATES = 5
DEFAULT_AOR_STATES = 10
DEFAULT_POINTS = 10_000


class MetricError(ValueError):
    """An object cannot be evaluated (empty or degenerate geometry); the message says why."""


# --------------------------------------------------------------------------- boxes

# corner k of a box takes max along axis a when bit a of k is set
_CORNER_BITS = np.array([[(k >> a) & 1 for a in range(3)] for k in range(8)], dtype=float)  # (8, 3)
_EDGES = np.array(
    [(k, k | (1 << a)) for k in range(8) for a in range(3) if not k & (1 << a)]
)  # (12, 2)


def _as_box(box: np.ndarray) -> np.ndarray:
    box = np.asarray(box, dtype=float)
    if box.shape != (2, 3):
        raise ValueError(
            f"a box is a (2, 3) array [[xmin, ymin, zmin], [xmax, ymax, zmax]], got {box.shape}"
        )
    return box


def _is_translation(pose: np.ndarray | None) -> bool:
    return pose is None or np.allclose(pose[:3, :3], np.eye(3), rtol=0.0, atol=1e-12)


def box_corners(box: np.ndarray, pose: np.ndarray | None = None) -> np.ndarray:
    """(8, 3) corners of the axis-aligned ``box`` (2, 3) moved by the rigid 4x4 ``pose``."""
    box = _as_box(box)
    corners = box[0] + _CORNER_BITS * (box[1] - box[0])
    if pose is not None:
        corners = corners @ pose[:3, :3].T + pose[:3, 3]
    return corners


def _inside(points: np.ndarray, box: np.ndarray, pose: np.ndarray | None, tol: float) -> np.ndarray:
    """(N,) mask: which of ``points`` (N, 3) lie in ``box`` moved by the rigid ``pose``."""
    local = points if pose is None else (points - pose[:3, 3]) @ pose[:3, :3]
    return np.all((local >= box[0] - tol) & (local <= box[1] + tol), axis=1)


def _edge_face_points(
    box_a: np.ndarray, pose_a: np.ndarray | None, box_b: np.ndarray, pose_b: np.ndarray | None
) -> np.ndarray:
    """Points where the 12 edges of posed box A cross the 6 face planes of posed box B, (M, 3)."""
    ca = box_corners(box_a, pose_a)
    p0, p1 = ca[_EDGES[:, 0]], ca[_EDGES[:, 1]]  # (12, 3)
    rot = np.eye(3) if pose_b is None else pose_b[:3, :3]
    t = np.zeros(3) if pose_b is None else pose_b[:3, 3]
    normals = np.concatenate([rot.T, rot.T])  # (6, 3): B's local axes in the object frame
    offsets = np.concatenate([box_b[0], box_b[1]]) + normals @ t  # (6,)
    a0, a1 = p0 @ normals.T, p1 @ normals.T  # (12, 6)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (offsets - a0) / (a1 - a0)
    edge, face = np.nonzero(np.isfinite(s) & (s >= 0.0) & (s <= 1.0))
    return p0[edge] + s[edge, face, None] * (p1[edge] - p0[edge])


def intersection_volume(
    box_a: np.ndarray,
    box_b: np.ndarray,
    pose_a: np.ndarray | None = None,
    pose_b: np.ndarray | None = None,
) -> float:
    """Exact volume of the intersection of two boxes, each an AABB (2, 3) under a rigid pose.

    Without rotation this is the closed form; otherwise the intersection is the convex
    hull of the corners of each box inside the other and the edge/face crossings.
    """
    box_a, box_b = _as_box(box_a), _as_box(box_b)
    if _is_translation(pose_a) and _is_translation(pose_b):
        ta = np.zeros(3) if pose_a is None else pose_a[:3, 3]
        tb = np.zeros(3) if pose_b is None else pose_b[:3, 3]
        lo = np.maximum(box_a[0] + ta, box_b[0] + tb)
        hi = np.minimum(box_a[1] + ta, box_b[1] + tb)
        return float(np.prod(np.clip(hi - lo, 0.0, None)))
    ca, cb = box_corners(box_a, pose_a), box_corners(box_b, pose_b)
    if np.any(ca.max(0) < cb.min(0)) or np.any(cb.max(0) < ca.min(0)):
        return 0.0
    tol = 1e-9 * max(1.0, float(np.abs(np.concatenate([ca, cb])).max()))
    ab, ba = (
        _edge_face_points(box_a, pose_a, box_b, pose_b),
        _edge_face_points(box_b, pose_b, box_a, pose_a),
    )
    pts = np.concatenate(
        [
            ca[_inside(ca, box_b, pose_b, tol)],
            cb[_inside(cb, box_a, pose_a, tol)],
            ab[_inside(ab, box_b, pose_b, tol)],
            ba[_inside(ba, box_a, pose_a, tol)],
        ]
    )
    if len(pts) < 4:
        return 0.0
    try:
        return float(ConvexHull(pts).volume)
    except QhullError:  # all crossings coplanar: the boxes only touch
        return 0.0


def _volumes(box_a: np.ndarray, box_b: np.ndarray, pose_a, pose_b) -> tuple[float, float]:
    """(intersection, union) volumes of two posed boxes."""
    inter = intersection_volume(box_a, box_b, pose_a, pose_b)
    union = float(np.prod(box_a[1] - box_a[0]) + np.prod(box_b[1] - box_b[0])) - inter
    return inter, union


def _hull_volume(points: np.ndarray) -> float:
    try:
        return float(ConvexHull(points).volume)
    except QhullError:  # flat point set
        return 0.0


def _iou_of(inter: float, union: float, corners_a: np.ndarray, corners_b: np.ndarray) -> float:
    if union <= 0.0:  # both boxes have zero volume
        return float(np.allclose(corners_a, corners_b))
    return float(np.clip(inter / union, 0.0, 1.0))


def iou(
    box_a: np.ndarray,
    box_b: np.ndarray,
    pose_a: np.ndarray | None = None,
    pose_b: np.ndarray | None = None,
) -> float:
    """Volumetric IoU in [0, 1] of two boxes (2, 3), each optionally under a rigid 4x4 pose.

    Two identical zero-volume boxes have IoU 1, two different ones 0.
    """
    box_a, box_b = _as_box(box_a), _as_box(box_b)
    inter, union = _volumes(box_a, box_b, pose_a, pose_b)
    return _iou_of(inter, union, box_corners(box_a, pose_a), box_corners(box_b, pose_b))


def giou(
    box_a: np.ndarray,
    box_b: np.ndarray,
    pose_a: np.ndarray | None = None,
    pose_b: np.ndarray | None = None,
) -> float:
    """Generalized IoU in [-1, 1] of two boxes (2, 3), each optionally under a rigid 4x4 pose.

    ``IoU - (|C| - |A u B|) / |C|`` with ``C`` the convex hull of both posed boxes.
    Example: unit cubes at x in [0, 1] and [2, 3] have IoU 0, union 2 and ``|C|`` = 3,
    so gIoU = -1/3.
    """
    box_a, box_b = _as_box(box_a), _as_box(box_b)
    ca, cb = box_corners(box_a, pose_a), box_corners(box_b, pose_b)
    inter, union = _volumes(box_a, box_b, pose_a, pose_b)
    value = _iou_of(inter, union, ca, cb)
    enclosing = _hull_volume(np.concatenate([ca, cb]))
    if enclosing <= 0.0:
        return value
    return float(np.clip(value - (enclosing - max(union, 0.0)) / enclosing, -1.0, 1.0))


def box_centre(box: np.ndarray, pose: np.ndarray | None = None) -> np.ndarray:
    """(3,) centre of ``box`` (2, 3) moved by the rigid 4x4 ``pose``."""
    c = _as_box(box).mean(axis=0)
    return c if pose is None else pose[:3, :3] @ c + pose[:3, 3]


# --------------------------------------------------------------------------- normalized objects


def normalization(obj: ArticulatedObject) -> np.ndarray:
    """(4, 4) similarity taking ``obj``'s object frame to its normalized frame.

    Translates the centre of the rest bounding box to the origin and scales uniformly
    by 1 / (largest rest extent).
    """
    bounds = obj.bounds()
    extent = float((bounds[1] - bounds[0]).max())
    if not (math.isfinite(extent) and extent > 0.0):
        raise MetricError(f"object has degenerate rest bounds {bounds.tolist()}; cannot normalize")
    s = 1.0 / extent
    norm = np.diag([s, s, s, 1.0])
    norm[:3, 3] = -s * bounds.mean(axis=0)
    return norm


def joint_value(joint: Joint | None, f: float, revolute_range: float | None = None) -> float:
    """Joint value (m or rad, object units) at fraction ``f`` in [0, 1] of its range."""
    if joint is None or not joint.movable:
        return 0.0
    if joint.type == "revolute" and revolute_range is not None:
        return joint.lower + f * revolute_range
    return joint.lower + f * (joint.upper - joint.lower)


def part_poses(
    obj: ArticulatedObject, f: float, *, revolute_range: float | None = None
) -> np.ndarray:
    """(K, 4, 4) rigid motion of each part (``obj.parts`` order) at fraction ``f``, normalized frame.

    Every movable joint is at ``joint_value(joint, f)``; base and fixed parts get identity.
    """
    norm = normalization(obj)
    inv = np.linalg.inv(norm)
    poses = np.tile(np.eye(4), (len(obj.parts), 1, 1))
    for k, p in enumerate(obj.parts):
        if p.joint is not None and p.joint.movable:
            poses[k] = norm @ p.joint.transform(joint_value(p.joint, f, revolute_range)) @ inv
    return poses


def part_boxes(obj: ArticulatedObject) -> np.ndarray:
    """(K, 2, 3) rest AABB of each part's normalized mesh, sides padded to >= MIN_EXTENT."""
    norm = normalization(obj)
    boxes = np.empty((len(obj.parts), 2, 3))
    for k, p in enumerate(obj.parts):
        v = np.asarray(p.mesh.vertices, dtype=float) @ norm[:3, :3].T + norm[:3, 3]
        lo, hi = v.min(axis=0), v.max(axis=0)
        pad = np.clip(MIN_EXTENT - (hi - lo), 0.0, None) / 2.0
        boxes[k] = [lo - pad, hi + pad]
    return boxes


def sample_surface(
    obj: ArticulatedObject, n_points: int = DEFAULT_POINTS, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Points sampled uniformly by area over all parts of ``obj`` at rest, normalized frame.

    Returns ``points`` (n_points, 3) and ``labels`` (n_points,), the index in
    ``obj.parts`` of each point's part. Deterministic for a given ``seed``; parts are
    visited in name order, so the samples do not depend on the order of ``obj.parts``.
    """
    norm = normalization(obj)
    tris, labels = [], []
    for k in sorted(range(len(obj.parts)), key=lambda k: obj.parts[k].name):
        p = obj.parts[k]
        t = np.asarray(p.mesh.triangles, dtype=float) @ norm[:3, :3].T + norm[:3, 3]  # (F, 3, 3)
        tris.append(t)
        labels.append(np.full(len(t), k))
    tri, lab = np.concatenate(tris), np.concatenate(labels)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    total = float(area.sum())
    if not (math.isfinite(total) and total > 0.0):
        raise MetricError("object has zero surface area; cannot sample points for dCD")
    rng = np.random.default_rng(seed)
    face = rng.choice(len(tri), size=n_points, p=area / total)
    r1, r2 = rng.random(n_points), rng.random(n_points)
    sq = np.sqrt(r1)
    w = np.stack([1.0 - sq, sq * (1.0 - r2), sq * r2], axis=1)  # (n, 3) barycentric
    points = np.einsum("nk,nkd->nd", w, tri[face])
    return points, lab[face]


def pose_points(points: np.ndarray, labels: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Move each point (N, 3) by its part's pose ``poses[labels]`` (K, 4, 4); returns (N, 3)."""
    rot, t = poses[labels, :3, :3], poses[labels, :3, 3]
    return np.einsum("nij,nj->ni", rot, points) + t


def chamfer(points_a: np.ndarray, points_b: np.ndarray, *, squared: bool = True) -> float:
    """Symmetric Chamfer distance between point sets (N, 3) and (M, 3).

    ``mean_a min_b d(a, b) + mean_b min_a d(a, b)`` with ``d`` the squared Euclidean
    distance (default, PyTorch3D / SINGAPO) or the Euclidean distance (``squared=False``).
    """
    a, b = np.asarray(points_a, dtype=float), np.asarray(points_b, dtype=float)
    if len(a) == 0 or len(b) == 0:
        raise ValueError("chamfer needs two non-empty point sets")
    da, _ = cKDTree(b).query(a)
    db, _ = cKDTree(a).query(b)
    if squared:
        return float(np.mean(da**2) + np.mean(db**2))
    return float(np.mean(da) + np.mean(db))


# --------------------------------------------------------------------------- matching


def match_parts(pred_boxes: np.ndarray, gt_boxes: np.ndarray) -> list[tuple[int, int]]:
    """One-to-one Hungarian matching of predicted to ground-truth part boxes.

    ``pred_boxes`` (P, 2, 3) and ``gt_boxes`` (G, 2, 3) are rest boxes in the normalized
    frame; the cost of a pair is ``(1 - gIoU) + |centre_pred - centre_gt|``. Returns
    ``min(P, G)`` pairs ``(pred_index, gt_index)`` sorted by ``pred_index``; the other
    parts are unmatched.
    """
    if len(pred_boxes) == 0 or len(gt_boxes) == 0:
        return []
    cost = np.empty((len(pred_boxes), len(gt_boxes)))
    for i, pb in enumerate(pred_boxes):
        for j, gb in enumerate(gt_boxes):
            cost[i, j] = (1.0 - giou(pb, gb)) + float(
                np.linalg.norm(box_centre(pb) - box_centre(gb))
            )
    rows, cols = linear_sum_assignment(cost)
    return sorted((int(i), int(j)) for i, j in zip(rows, cols, strict=True))


# --------------------------------------------------------------------------- metrics


@dataclass
class _Normalized:
    """What the metrics need of one object: child part indices, rest boxes, surface samples."""

    children: list[int]  # indices in obj.parts of the non-base parts
    boxes: np.ndarray  # (K, 2, 3)
    points: np.ndarray  # (N, 3) rest, normalized
    labels: np.ndarray  # (N,)

    @classmethod
    def of(cls, obj: ArticulatedObject, n_points: int, seed: int) -> _Normalized:
        points, labels = sample_surface(obj, n_points, seed)
        children = [k for k, p in enumerate(obj.parts) if not p.is_base]
        return cls(children, part_boxes(obj), points, labels)


def state_fractions(n_states: int) -> np.ndarray:
    """(n_states,) joint-range fractions ``linspace(0, 1, n_states)``; the first is rest."""
    if n_states < 1:
        raise ValueError(f"n_states must be >= 1, got {n_states}")
    return np.linspace(0.0, 1.0, n_states)


def _box_scores(
    pred: _Normalized,
    gt: _Normalized,
    pairs: Sequence[tuple[int, int]],
    pred_poses: np.ndarray,
    gt_poses: np.ndarray,
) -> tuple[float, float]:
    """(dgIoU, dcDist) of the child parts at one state, unmatched slots penalized."""
    slots = max(len(pred.children), len(gt.children))
    if slots == 0:
        return 0.0, 0.0
    n_unmatched = slots - len(pairs)
    dg = DGIOU_UNMATCHED * n_unmatched
    dc = DCDIST_UNMATCHED * n_unmatched
    for i, j in pairs:
        a, b = pred.children[i], gt.children[j]
        g = giou(pred.boxes[a], gt.boxes[b], pred_poses[a], gt_poses[b])
        dg += float(np.clip(1.0 - g, 0.0, DGIOU_UNMATCHED))
        d = np.linalg.norm(
            box_centre(pred.boxes[a], pred_poses[a]) - box_centre(gt.boxes[b], gt_poses[b])
        )
        dc += min(float(d), DCDIST_UNMATCHED)
    return dg / slots, dc / slots


def aor(
    obj: ArticulatedObject,
    *,
    n_states: int = DEFAULT_AOR_STATES,
    revolute_range: float | None = None,
) -> float:
    """Average overlapping ratio of ``obj``: mean IoU of sibling part boxes over states.

    For each fraction in ``state_fractions(n_states)``, the IoU of every pair of parts
    sharing a parent (posed part boxes) is averaged; the state means are averaged.
    NaN when no part has a sibling. Lower is better.
    """
    boxes = part_boxes(obj)
    groups: dict[str, list[int]] = {}
    for k, p in enumerate(obj.parts):
        if p.joint is not None:
            groups.setdefault(p.joint.parent, []).append(k)
    pairs = [(a, b) for ks in groups.values() for n, a in enumerate(ks) for b in ks[n + 1 :]]
    if not pairs:
        return float("nan")
    per_state = []
    for f in state_fractions(n_states):
        poses = part_poses(obj, f, revolute_range=revolute_range)
        per_state.append(np.mean([iou(boxes[a], boxes[b], poses[a], poses[b]) for a, b in pairs]))
    return float(np.mean(per_state))


def evaluate_pair(
    pred: ArticulatedObject,
    gt: ArticulatedObject,
    *,
    n_states: int = DEFAULT_STATES,
    n_points: int = DEFAULT_POINTS,
    seed: int = 0,
    aor_states: int = DEFAULT_AOR_STATES,
    revolute_range: float | None = None,
) -> dict[str, float]:
    """The seven metrics of ``pred`` against ``gt`` (definitions in the module docstring).

    Returns a dict with keys ``METRIC_KEYS``; distances are in normalized units
    (dCD in squared units); AOR is NaN when ``pred`` has fewer than two sibling parts.
    Raises MetricError for an object with degenerate geometry.
    """
    p = _Normalized.of(pred, n_points, seed)
    g = _Normalized.of(gt, n_points, seed)
    pairs = match_parts(p.boxes[p.children], g.boxes[g.children])
    dg, dc, cd = [], [], []
    for f in state_fractions(n_states):
        pp = part_poses(pred, f, revolute_range=revolute_range)
        gp = part_poses(gt, f, revolute_range=revolute_range)
        a, b = _box_scores(p, g, pairs, pp, gp)
        dg.append(a)
        dc.append(b)
        cd.append(chamfer(pose_points(p.points, p.labels, pp), pose_points(g.points, g.labels, gp)))
    return {
        "RS-dgIoU": dg[0],
        "AS-dgIoU": float(np.mean(dg)),
        "RS-dcDist": dc[0],
        "AS-dcDist": float(np.mean(dc)),
        "RS-dCD": cd[0],
        "AS-dCD": float(np.mean(cd)),
        "AOR": aor(pred, n_states=aor_states, revolute_range=revolute_range),
    }


def joint_types_missed(pred: ArticulatedObject, gt: ArticulatedObject) -> tuple[int, int]:
    """(missed, total): how many of ``gt``'s movable joints have a type ``pred`` lacks, the
    joint types compared as multisets (module docstring), and how many it has."""

    def types(obj: ArticulatedObject) -> Counter[str]:
        return Counter(
            p.joint.type for p in obj.parts if p.joint is not None and p.joint.type != "fixed"
        )

    want, have = types(gt), types(pred)
    return sum(max(0, n - have[t]) for t, n in want.items()), sum(want.values())


def motions_match(pred: ArticulatedObject, gt: ArticulatedObject) -> tuple[bool, bool]:
    """(kinds exact, motions exact): whether ``pred``'s movable parts have exactly ``gt``'s
    joint kinds (drawer, vertical hinge, horizontal hinge: ``generator.motions.MOTION_KIND``)
    as multisets, and exactly its motions (the hinge edge too: left/right, bottom/top,
    lid). A part whose motion cannot be read counts as a wrong one."""
    from generator.motions import MOTION_KIND, motion_of

    def motions(obj: ArticulatedObject) -> Counter[str]:
        out: Counter[str] = Counter()
        for p in obj.parts:
            if p.joint is None or not p.joint.movable:
                continue
            try:
                out[motion_of(p)] += 1
            except ValueError:
                out["?"] += 1
        return out

    def kinds(c: Counter[str]) -> Counter[str]:
        return Counter(MOTION_KIND.get(m, "?") for m in c.elements())

    have, want = motions(pred), motions(gt)
    return kinds(have) == kinds(want), have == want


# --------------------------------------------------------------------------- folders


def score_row(pred: ArticulatedObject, gt: ArticulatedObject, **kwargs: Any) -> dict[str, Any]:
    """``evaluate_pair``'s metrics (NaN as None, for strict JSON) and the joint-type count
    (``joint_types_missed``, ``movable_joints``) of ``pred`` against ``gt``."""
    row: dict[str, Any] = {
        k: (None if math.isnan(v) else float(v))
        for k, v in evaluate_pair(pred, gt, **kwargs).items()
    }
    row["joint_types_missed"], row["movable_joints"] = joint_types_missed(pred, gt)
    row["kinds_exact"], row["motions_exact"] = motions_match(pred, gt)
    return row


def mean_scores(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Per-metric mean over ``rows`` skipping undefined (None) values, ``count``, and the
    sums of ``joint_types_missed`` and ``movable_joints`` (of rows that have them)."""
    out: dict[str, Any] = {}
    for key in METRIC_KEYS:
        vals = [r[key] for r in rows if r.get(key) is not None]
        out[key] = float(np.mean(vals)) if vals else None
    out["count"] = len(rows)
    for key in ("joint_types_missed", "movable_joints"):
        out[key] = int(sum(r.get(key) or 0 for r in rows))
    for key in ("kinds_exact", "motions_exact"):  # shares of the rows
        vals = [bool(r[key]) for r in rows if r.get(key) is not None]
        out[key] = float(np.mean(vals)) if vals else None
    return out


def evaluate_dirs(pred_dir: str | Path, gt_dir: str | Path, **kwargs: Any) -> dict[str, Any]:
    """Evaluate every ground-truth bundle in ``gt_dir`` against the same-named one in ``pred_dir``.

    Bundles are found with ``find_bundles`` and paired by folder name; ``kwargs`` go to
    ``evaluate_pair``. Returns::

        {"per_object":   {id: {"category": str, <metric>: float | None, ...,
                               "joint_types_missed": int, "movable_joints": int}},
         "per_category": {category: {<metric>: mean, ..., "count": n,
                                     "joint_types_missed": sum, "movable_joints": sum}},
         "mean":         {<metric>: mean over all evaluated objects, ..., "count": n,
                          "joint_types_missed": sum, "movable_joints": sum},
         "missing":      [ids in gt_dir with no prediction],
         "failed":       {id: reason}   # bundles that did not load or evaluate
         "extra":        [ids in pred_dir with no ground truth]}

    Undefined values (AOR of an object without sibling parts, a mean over no values)
    are None, so the result serializes to strict JSON. Missing and failed objects are
    not in the means; they are listed so that a caller can count them as failures.
    """
    gts = {p.name: p for p in find_bundles(gt_dir)}
    preds = {p.name: p for p in find_bundles(pred_dir)}
    per_object: dict[str, dict[str, Any]] = {}
    missing: list[str] = []
    failed: dict[str, str] = {}
    for oid in sorted(gts):
        if oid not in preds:
            missing.append(oid)
            continue
        try:
            gt = load_bundle(gts[oid])
            pred = load_bundle(preds[oid])
            scores = score_row(pred, gt, **kwargs)
        except (ObjectModelError, MetricError) as e:
            log.warning("%s: not evaluated: %s", oid, e)
            failed[oid] = str(e)
            continue
        row: dict[str, Any] = {"category": gt.category}
        row.update(scores)
        per_object[oid] = row
        log.info("%s: %s", oid, {k: row[k] for k in METRIC_KEYS})
    by_cat: dict[str, list[dict[str, Any]]] = {}
    for row in per_object.values():
        by_cat.setdefault(row["category"], []).append(row)
    return {
        "per_object": per_object,
        "per_category": {c: mean_scores(rows) for c, rows in sorted(by_cat.items())},
        "mean": mean_scores(list(per_object.values())),
        "missing": missing,
        "failed": failed,
        "extra": sorted(set(preds) - set(gts)),
    }


def format_table(results: dict[str, Any]) -> Table:
    """A rich table of ``evaluate_dirs`` results: one row per category, then all objects."""

    def cell(v: Any) -> str:
        return "-" if v is None else f"{v:.4f}"

    table = Table(title="Generation metrics (lower is better)")
    table.add_column("category")
    table.add_column("n", justify="right")
    for key in METRIC_KEYS:
        table.add_column(key, justify="right")
    table.add_column("joint types missed", justify="right")

    def missed(row: dict[str, Any]) -> str:
        return f"{row.get('joint_types_missed', 0)} of {row.get('movable_joints', 0)}"

    for cat, row in results.get("per_category", {}).items():
        table.add_row(cat, str(row["count"]), *(cell(row[k]) for k in METRIC_KEYS), missed(row))
    mean = results.get("mean", {})
    table.add_row(
        "all",
        str(mean.get("count", 0)),
        *(cell(mean.get(k)) for k in METRIC_KEYS),
        missed(mean),
        style="bold",
    )
    notes = []
    if results.get("missing"):
        notes.append(f"{len(results['missing'])} missing prediction(s)")
    if results.get("failed"):
        notes.append(f"{len(results['failed'])} failed")
    if results.get("extra"):
        notes.append(f"{len(results['extra'])} prediction(s) without ground truth")
    if notes:
        table.caption = "; ".join(notes)
    return table
