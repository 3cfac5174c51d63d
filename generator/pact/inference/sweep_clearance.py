"""Movable parts' visuals kept out of each other's way while they open.

The box layout (:mod:`generator.box_layout`) places collision boxes and hinges so that
no two parts' collision geometry meets over their ranges. The visuals are the clean
decoded meshes, which reach a little past those boxes (``generate.clip_from_neighbours``
cuts them at the middle of the gap between two neighbours' boxes, which is enough at
rest). While a door swings, though, the part of its visual behind its hinge line
sweeps sideways past its free edge (by ``sqrt(t^2 + w^2) - w`` for a visual ``t`` deep
behind the hinge and ``w`` wide), and a bottom-hinged door's visual reaching below its
hinge swings down past it: on the real dev split 9 of 160 generated objects had two
doors (or a door and a drawer) whose visuals passed through each other when opened
together (AOR 0.00003 against 0 for retrieval).

:func:`keep_sweeps_apart` checks every two parts with the same parent: the box
holding each one's visual over its whole range (:func:`swept_bounds`) against the
other's. Where the two meet, the visuals are cut on their facing sides (the axis along
which their rest boxes are furthest apart) at the planes that part their swept boxes
while cutting least, at most ``MAX_CUT`` of a part's extent. Swept boxes that stay apart
mean the visuals cannot meet in any pair of joint states.
"""

from __future__ import annotations

import numpy as np
import trimesh

from generator.articulated import Joint
from generator.mesh_repair.closing import slice_closed

#: States sampled over a joint's range for its swept box (a quarter turn in 16 steps:
#: the bulge's maximum lies between two samples within 0.1 % of the width).
SWEEP_STATES = 17
#: A part's visual is cut by at most this share of its extent along the cut's axis.
MAX_CUT = 0.25
#: Candidate cut planes per part, from none to ``MAX_CUT``.
CUT_STEPS = 26
#: Rest boxes overlapping by more than this (object units) along every axis are not two
#: neighbours but one part inside another: nothing to cut between them.
REST_OVERLAP = 1e-3

_SIGNS = np.array([[sx, sy, sz] for sx in (0, 1) for sy in (0, 1) for sz in (0, 1)])


def swept_bounds(bounds: np.ndarray, joint: Joint | None, states: int = SWEEP_STATES) -> np.ndarray:
    """(2, 3) box holding the box ``bounds`` (2, 3) moved by ``joint`` over its whole
    range (``states`` samples); the box itself for a fixed joint or none."""
    bounds = np.asarray(bounds, float)
    if joint is None or not joint.movable:
        return bounds.copy()
    corners = np.where(_SIGNS == 1, bounds[1], bounds[0])  # (8, 3)
    homog = np.c_[corners, np.ones(8)]
    moved = [homog @ joint.transform(q).T for q in np.linspace(joint.lower, joint.upper, states)]
    pts = np.concatenate(moved)[:, :3]
    return np.array([pts.min(axis=0), pts.max(axis=0)])


def _overlap(a: np.ndarray, b: np.ndarray, tol: float = 1e-9) -> bool:
    return bool(np.all(np.minimum(a[1], b[1]) - np.maximum(a[0], b[0]) > tol))


def _cut_planes(
    low: tuple[np.ndarray, np.ndarray, Joint | None],
    high: tuple[np.ndarray, np.ndarray, Joint | None],
    axis: int,
) -> tuple[float, float] | None:
    """The cut planes (low part's upper face, high part's lower face along ``axis``)
    that part the two swept boxes while cutting least; each part is (cuttable bounds,
    bounds of what stays uncut (or empty), joint). None when no pair of cuts within
    ``MAX_CUT`` parts them."""

    def swept(
        part: tuple[np.ndarray, np.ndarray, Joint | None], face: int, at: float
    ) -> np.ndarray:
        cut, keep, joint = part
        b = cut.copy()
        b[face, axis] = at
        if keep.size:
            b = np.array([np.minimum(b[0], keep[0]), np.maximum(b[1], keep[1])])
        return swept_bounds(b, joint)

    lo_a, lo_b = low[0], high[0]
    reach_a = np.linspace(lo_a[1, axis], lo_a[1, axis] - MAX_CUT * np.ptp(lo_a[:, axis]), CUT_STEPS)
    reach_b = np.linspace(lo_b[0, axis], lo_b[0, axis] + MAX_CUT * np.ptp(lo_b[:, axis]), CUT_STEPS)
    top_a = [swept(low, 1, c) for c in reach_a]  # the low part's swept boxes per cut
    bottom_b = [swept(high, 0, c) for c in reach_b]
    best: tuple[float, float, float] | None = None
    for i, ca in enumerate(reach_a):
        for j, cb in enumerate(reach_b):
            if _overlap(top_a[i], bottom_b[j]):
                continue
            cost = (reach_a[0] - ca) + (cb - reach_b[0])
            if best is None or cost < best[0]:
                best = (cost, float(ca), float(cb))
            break  # larger cuts of the high part only cost more
    return None if best is None else (best[1], best[2])


def _cut(mesh: trimesh.Trimesh, axis: int, at: float, keep_below: bool) -> trimesh.Trimesh:
    """``mesh`` cut by the plane ``x[axis] = at``, the side below (or above) kept
    (:func:`generator.mesh_repair.closing.slice_closed`: capped when closed, coloured as
    the nearest old vertex); ``mesh`` when the cut leaves nothing or is not needed."""
    lo, hi = mesh.bounds
    if (hi[axis] <= at) if keep_below else (lo[axis] >= at):
        return mesh
    normal = np.zeros(3)
    normal[axis] = -1.0 if keep_below else 1.0
    origin = np.zeros(3)
    origin[axis] = at
    out = slice_closed(mesh, normal, origin)
    return mesh if out is None else out


def keep_sweeps_apart(
    visuals: dict[str, trimesh.Trimesh],
    fixed: dict[str, np.ndarray],
    joints: dict[str, Joint | None],
) -> dict[str, trimesh.Trimesh]:
    """The parts' ``visuals`` (name -> the mesh that may be cut) cut so that no two
    parts with the same parent sweep into each other (module docstring). ``fixed``
    (name -> (2, 3) bounds, may be absent) is geometry moving with a part that must not
    be cut (a bar handle); ``joints`` the parts' joints (all parts in ``visuals``).
    Returns the new visuals (the same meshes where nothing was cut)."""
    out = dict(visuals)
    names = [n for n in visuals if joints.get(n) is not None and len(visuals[n].faces)]
    empty = np.zeros((0, 3))

    def part(n: str) -> tuple[np.ndarray, np.ndarray, Joint | None]:
        return np.asarray(out[n].bounds, float), fixed.get(n, empty), joints[n]

    def whole(n: str) -> np.ndarray:
        b, keep, _ = part(n)
        if keep.size:
            b = np.array([np.minimum(b[0], keep[0]), np.maximum(b[1], keep[1])])
        return b

    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            ja, jb = joints[a], joints[b]
            assert ja is not None and jb is not None
            if ja.parent != jb.parent or not (ja.movable or jb.movable):
                continue
            if not _overlap(swept_bounds(whole(a), ja), swept_bounds(whole(b), jb)):
                continue
            ra, rb = whole(a), whole(b)
            gaps = np.maximum(rb[0] - ra[1], ra[0] - rb[1])
            axis = int(np.argmax(gaps))
            if gaps[axis] < -REST_OVERLAP:
                continue  # one inside the other
            low, high = (a, b) if ra[0, axis] + ra[1, axis] <= rb[0, axis] + rb[1, axis] else (b, a)
            planes = _cut_planes(part(low), part(high), axis)
            if planes is None:
                continue
            out[low] = _cut(out[low], axis, planes[0], keep_below=True)
            out[high] = _cut(out[high], axis, planes[1], keep_below=False)
    return out
