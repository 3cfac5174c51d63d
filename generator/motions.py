"""How a movable part moves, in words a photo shows: the motion classes of the project.

A part of a cabinet, desk or appliance moves in one of six ways (``MOTIONS``), named as
a person facing the object's front sees it:

=============  =====================================================================
``drawer``     slides out (prismatic, along the front's normal)
``door_left``  swings out on a vertical hinge at its left edge
``door_right`` swings out on a vertical hinge at its right edge
``flap_bottom`` swings down on a horizontal hinge at its bottom edge (an oven door)
``flap_top``   swings up on a horizontal hinge at its top edge
``lid``        on top, swings up on a horizontal hinge at its back edge
=============  =====================================================================

Frame convention (``generator.articulated``): +x is the front, +z up, so a person facing
the front has +y on their right. :func:`motion_of` reads a part's motion from its joint
and its box; :func:`joint_for_motion` makes the joint of a motion on a given box (hinge
on the named edge, opening outward: positive joint values open, as the object model
requires). The two are inverses on boxes.
"""

from __future__ import annotations

import numpy as np

from generator.articulated import Joint, Part

MOTIONS: tuple[str, ...] = ("drawer", "door_left", "door_right", "flap_bottom", "flap_top", "lid")
#: The joint type of each motion.
MOTION_JOINT = {m: ("prismatic" if m == "drawer" else "revolute") for m in MOTIONS}
#: The semantic label of a part moving so (a flap is a door hinged at an edge).
MOTION_SEMANTIC = {
    "drawer": "drawer",
    "door_left": "door",
    "door_right": "door",
    "flap_bottom": "door",
    "flap_top": "door",
    "lid": "lid",
}
#: The joint kinds the metrics compare (drawer; door on a vertical hinge; a part on a
#: horizontal hinge), per motion.
MOTION_KIND = {
    "drawer": "drawer",
    "door_left": "vertical_hinge",
    "door_right": "vertical_hinge",
    "flap_bottom": "horizontal_hinge",
    "flap_top": "horizontal_hinge",
    "lid": "horizontal_hinge",
}


class UnknownMotionError(ValueError):
    """A motion name that is not one of ``MOTIONS``."""

    def __init__(self, motion: str) -> None:
        super().__init__(f"unknown motion {motion!r}; motions: {', '.join(MOTIONS)}")
        self.motion = motion


def motion_of_joint(joint: Joint, lo: np.ndarray, hi: np.ndarray) -> str:
    """The motion of a part whose rest box is ``lo``..``hi`` (3,) and whose joint is
    ``joint`` (prismatic or revolute; object frame)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if joint.type == "prismatic":
        return "drawer"
    if joint.type != "revolute":
        raise ValueError(f"a {joint.type!r} joint has no motion")
    axis = np.asarray(joint.axis, float)
    centre = (lo + hi) / 2
    o = np.asarray(joint.origin, float)
    k = int(np.argmax(np.abs(axis)))
    if k == 2:  # vertical hinge
        return "door_left" if o[1] < centre[1] else "door_right"
    if k == 1:  # horizontal hinge along the front
        extent = hi - lo
        flat = extent[2] <= min(extent[0], extent[1])
        if o[0] < centre[0] and (flat or o[2] > centre[2]):
            return "lid"  # hinged at its back edge: a flat part's, or the top one
        return "flap_bottom" if o[2] < centre[2] else "flap_top"
    # a hinge along the front's normal (front to back) is horizontal too: a lid hinged on
    # its side edge (a top-loading washer's) or, rarely, a part turning in the front's
    # plane; the vocabulary's horizontal hinges are the nearest
    extent = hi - lo
    if extent[2] <= min(extent[0], extent[1]):
        return "lid"
    return "flap_bottom" if o[2] < centre[2] else "flap_top"


def motion_of(part: Part) -> str:
    """The motion of a movable ``part`` (its joint and its mesh's box at rest)."""
    if part.joint is None or not part.joint.movable:
        raise ValueError(f"part {part.name!r} does not move")
    lo, hi = part.mesh.bounds
    return motion_of_joint(part.joint, lo, hi)


def joint_for_motion(
    motion: str, lo: np.ndarray, hi: np.ndarray, upper: float | None = None, parent: str = "base"
) -> Joint:
    """The joint of ``motion`` for a part whose rest box is ``lo``..``hi`` (object frame):
    a drawer slides along +x from its front face's centre; a hinge lies on the named edge
    of the box's front face (a lid's on the back edge of its top face), its axis turned
    so that positive values open the part outward. ``upper``: the open limit (default a
    drawer 0.75 of its depth, a door or lid 1.57 rad)."""
    if motion not in MOTIONS:
        raise UnknownMotionError(motion)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centre = (lo + hi) / 2
    if motion == "drawer":
        origin = np.array([hi[0], centre[1], centre[2]])
        limit = 0.75 * float(hi[0] - lo[0]) if upper is None else upper
        return Joint("prismatic", origin, [1.0, 0.0, 0.0], 0.0, limit, parent)
    limit = 1.57 if upper is None else upper
    origin, axis = {
        "door_left": ([hi[0], lo[1], centre[2]], [0.0, 0.0, -1.0]),
        "door_right": ([hi[0], hi[1], centre[2]], [0.0, 0.0, 1.0]),
        "flap_bottom": ([hi[0], centre[1], lo[2]], [0.0, 1.0, 0.0]),
        "flap_top": ([hi[0], centre[1], hi[2]], [0.0, -1.0, 0.0]),
        "lid": ([lo[0], centre[1], hi[2]], [0.0, -1.0, 0.0]),
    }[motion]
    return Joint("revolute", origin, axis, 0.0, limit, parent)
