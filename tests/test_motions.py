"""generator.motions: a part's motion from its joint, and the joint of a motion."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from generator.articulated import Joint, Part
from generator.motions import MOTIONS, UnknownMotionError, joint_for_motion, motion_of

# a door-sized panel on the front (+x) of a cabinet, and a lid lying on top
FRONT = (np.array([0.38, -0.3, 0.1]), np.array([0.4, 0.3, 0.8]))
TOP = (np.array([-0.4, -0.3, 0.88]), np.array([0.4, 0.3, 0.9]))


def _part(lo, hi, joint) -> Part:
    box = trimesh.creation.box(np.subtract(hi, lo))
    box.apply_translation((np.asarray(lo) + np.asarray(hi)) / 2)
    return Part("p", "door", box, joint)


@pytest.mark.parametrize("motion", MOTIONS)
def test_motion_of_reads_back_joint_for_motion(motion):
    lo, hi = TOP if motion == "lid" else FRONT
    assert motion_of(_part(lo, hi, joint_for_motion(motion, lo, hi))) == motion


@pytest.mark.parametrize("motion", [m for m in MOTIONS if m != "drawer"])
def test_every_hinge_opens_outward_and_on_its_named_edge(motion):
    """Opened a little, the part's free edge leaves the front (or, for a lid, rises)."""
    lo, hi = TOP if motion == "lid" else FRONT
    j = joint_for_motion(motion, lo, hi)
    part = _part(lo, hi, j)
    moved = part.posed_mesh(0.5).vertices - part.mesh.vertices
    if motion == "lid":
        assert moved[:, 2].max() > 0.2 and j.origin[0] == lo[0]  # up, hinge at the back
        return
    assert moved[:, 0].max() > 0.1 and moved[:, 0].min() >= -1e-6  # out of the front
    still = np.linalg.norm(moved, axis=1) < 1e-6  # the hinge edge stays put
    edge = part.mesh.vertices[still]
    expect = {"door_left": (1, lo[1]), "door_right": (1, hi[1]),
              "flap_bottom": (2, lo[2]), "flap_top": (2, hi[2])}[motion]  # fmt: skip
    assert len(edge) and np.allclose(edge[:, expect[0]], expect[1])


def test_a_drawer_slides_out_along_x_by_three_quarters_of_its_depth():
    lo, hi = np.array([-0.3, -0.2, 0.1]), np.array([0.3, 0.2, 0.3])
    j = joint_for_motion("drawer", lo, hi)
    assert (
        j.type == "prismatic" and np.allclose(j.axis, [1, 0, 0]) and j.upper == pytest.approx(0.45)
    )


def test_a_left_hinged_door_of_partnet_convention_reads_as_left():
    """A hinge given by its axis pointing down (-z) or up (+z), at the viewer's left
    (-y) edge: the side decides, not the axis sign."""
    lo, hi = FRONT
    for axis in ([0, 0, 1], [0, 0, -1]):
        j = Joint("revolute", [0.4, -0.3, 0.45], axis, 0.0, 1.5)
        assert motion_of(_part(lo, hi, j)) == "door_left"


def test_a_hinge_from_front_to_back_is_a_horizontal_hinge():
    """A top-loading washer's lid hinged on its left edge (axis along x, PartNet-Mobility
    103508's) is a lid, not a side door; a front panel turning about the front's normal
    reads as a flap (both horizontal hinges, as their axes are)."""
    lo, hi = TOP
    j = Joint("revolute", [0.0, -0.3, 0.9], [1, 0, 0], 0.0, 1.7)
    assert motion_of(_part(lo, hi, j)) == "lid"
    lo, hi = FRONT
    j = Joint("revolute", [0.4, 0.0, 0.1], [1, 0, 0], 0.0, 1.0)
    assert motion_of(_part(lo, hi, j)) == "flap_bottom"


def test_unknown_motion_names_the_known_ones():
    with pytest.raises(UnknownMotionError, match="door_left"):
        joint_for_motion("slide_up", *FRONT)
