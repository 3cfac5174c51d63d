"""ManiSkill3 tasks on built articulated assets.

Importing this package registers ``OpenDrawer-v0``, ``CloseDrawer-v0``, ``OpenDoor-v0``
and ``CloseDoor-v0`` with ManiSkill and Gymnasium::

    import gymnasium as gym
    import tasks  # noqa: F401
    env = gym.make("OpenDrawer-v0", assets="out/", obs_mode="state", sim_backend="physx_cpu")

``assets`` is a folder of built assets, one asset folder, a catalog file
(``registry.sqlite``) or an :class:`sim_envs.AssetSource`; ``category`` filters it.
"""

from tasks.door import CloseDoorEnv, OpenDoorEnv
from tasks.drawer import CloseDrawerEnv, OpenDrawerEnv

ENV_IDS = ("OpenDrawer-v0", "CloseDrawer-v0", "OpenDoor-v0", "CloseDoor-v0")

__all__ = ["ENV_IDS", "CloseDoorEnv", "CloseDrawerEnv", "OpenDoorEnv", "OpenDrawerEnv"]
