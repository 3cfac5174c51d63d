"""Drawer tasks: open or close one drawer (prismatic part) of a built asset with a Panda."""

from __future__ import annotations

from mani_skill.utils.registration import register_env

from tasks.articulated import ArticulatedPartEnv


@register_env("OpenDrawer-v0", max_episode_steps=100)
class OpenDrawerEnv(ArticulatedPartEnv):
    """
    **Task Description:**
    Pull one drawer of a built articulated asset open with a fixed-base Panda.

    **Randomizations:**
    - the asset is sampled from the asset source (folder or catalog) among those with a
      prismatic part (per env, at reconfiguration), the drawer among its prismatic
      parts at every reset
    - the object stands at the origin, shifted by up to 3 cm and turned by up to 0.1 rad
    - the robot faces the object's front, its ready gripper about 12 cm in front of the
      handle, shifted by up to 2 cm, turned by up to 0.05 rad; joint noise 0.02 rad

    **Success Conditions:**
    - the drawer's joint is at least 75% of its range open and the drawer is nearly still
      (|v| <= 0.1 m/s, |w| <= 1 rad/s)
    """

    joint_type = "prismatic"
    closing = False


@register_env("CloseDrawer-v0", max_episode_steps=100)
class CloseDrawerEnv(ArticulatedPartEnv):
    """
    **Task Description:**
    Push one open drawer of a built articulated asset closed with a fixed-base Panda.

    **Randomizations:**
    - as OpenDrawer-v0; the target drawer starts 80-100% open, the others closed

    **Success Conditions:**
    - the drawer's joint is at most 25% of its range open and the drawer is nearly still
    """

    joint_type = "prismatic"
    closing = True
