"""Door tasks: open or close one door (revolute part) of a built asset with a Panda."""

from __future__ import annotations

from mani_skill.utils.registration import register_env

from tasks.articulated import ArticulatedPartEnv


@register_env("OpenDoor-v0", max_episode_steps=150)
class OpenDoorEnv(ArticulatedPartEnv):
    """
    **Task Description:**
    Swing one door (or lid) of a built articulated asset open with a fixed-base Panda.

    **Randomizations:**
    - the asset is sampled from the asset source among those with a revolute part (per
      env, at reconfiguration), the door among its revolute parts at every reset
    - the object's pose as in OpenDrawer-v0; the robot stands where the handle's whole
      opening path is in reach and clear of the swinging door (beside a side-hinged
      door, in front of and beside a bottom-hinged one; ``tasks.placement``), its arm
      at the pre-grasp 12 cm in front of the handle; 2 cm, 0.05 rad and 0.02 rad noise

    **Success Conditions:**
    - the door's joint is at least 75% of its range open and the door is nearly still
      (|v| <= 0.1 m/s, |w| <= 1 rad/s)
    """

    joint_type = "revolute"
    closing = False


@register_env("CloseDoor-v0", max_episode_steps=150)
class CloseDoorEnv(ArticulatedPartEnv):
    """
    **Task Description:**
    Push one open door of a built articulated asset closed with a fixed-base Panda.

    **Randomizations:**
    - as OpenDoor-v0; the target door starts 80-100% open, the others closed

    **Success Conditions:**
    - the door's joint is at most 25% of its range open and the door is nearly still
    """

    joint_type = "revolute"
    closing = True
