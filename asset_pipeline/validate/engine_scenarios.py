"""What every engine simulates for the behaviour checks of :mod:`.engines`: the
:class:`Scenario` runs (base fixed or free, joints' start, a pull at a handle), the
:class:`Trajectory` an engine reports of each, and the drives that hold parts closed on
a free base. The engine modules (:mod:`.engine_sapien`, :mod:`.engine_mujoco`,
:mod:`.engine_newton`) read these; :mod:`.engines` judges their trajectories.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from asset_pipeline.assets.built_asset import BuiltAsset, Joint
from asset_pipeline.validate.report import Tolerances

#: Natural frequency (Hz) of the drives holding parts closed on a free base (as dynamic.py).
HOLD_HZ = 5.0
#: Fractions of the range the limit scenarios start from.
LIMIT_START = 0.9
CLOSE_START = 0.1


@dataclass(frozen=True)
class Pull:
    """A force of ``force`` newtons on ``link`` at ``point`` (3,) along ``direction`` (3,),
    both in the link frame (so the pull turns with the part)."""

    link: str
    point: tuple[float, float, float]
    direction: tuple[float, float, float]
    force: float


@dataclass(frozen=True)
class Scenario:
    """One run: joints start at ``q0`` (others at their lower limit), for ``duration`` s.

    ``free_base``: the base is free on a floor at z = 0 (lifted 2 mm) and every movable
    joint is held at its lower limit by a PD drive (``HOLD_HZ``); else the base is fixed
    and no drive acts (the asset's own joint damping does).
    """

    name: str
    duration: float
    q0: dict[str, float] = field(default_factory=dict)
    pull: Pull | None = None
    free_base: bool = False


@dataclass
class Trajectory:
    """What an engine reports of a scenario: ``q`` (n, J) of the movable joints (asset
    order) at ``times`` (n,), the final base pose (4, 4) and speeds, and whether every
    number stayed finite."""

    times: np.ndarray
    q: np.ndarray
    base_pose: np.ndarray
    base_speed: float = 0.0
    base_angular_speed: float = 0.0
    finite: bool = True


def hold_gains(asset: BuiltAsset, joint: Joint) -> tuple[float, float]:
    """(stiffness, damping) of the drive holding a part closed on a free base."""
    inertial = asset.link(joint.child).inertial
    m = max(inertial.mass if inertial is not None else 0.0, 1e-3)
    w = 2 * math.pi * HOLD_HZ
    return m * w * w, 2 * m * w


def _pull(asset: BuiltAsset, j: Joint, force: float) -> Pull | None:
    """The opening pull at a part's handle (None for a part without one)."""
    parts = {p.joint_name: p for p in asset.movable_parts()} if asset.handles else {}
    part = parts.get(j.name)
    if part is None:
        return None
    point = np.asarray(part.handle_object)
    axis = np.asarray(part.axis)
    if j.type == "prismatic":
        direction = axis
    else:
        tangent = np.cross(axis, point - np.asarray(part.origin))
        n = float(np.linalg.norm(tangent))
        direction = tangent / n if n > 1e-9 else axis
    R = asset.link_poses()[j.child][:3, :3]
    d = R.T @ direction
    return Pull(j.child, tuple(map(float, part.handle_link)), tuple(map(float, d)), float(force))


def scenarios(asset: BuiltAsset, tol: Tolerances) -> list[Scenario]:
    """Every run the checks need, in a fixed order (see the module docstring)."""
    out = [Scenario("rest", tol.settle_time)]
    for j in asset.movable_joints:
        rng = j.upper - j.lower
        lin = j.type == "prismatic"
        nudge = min(tol.touch * rng, tol.touch_max_linear if lin else tol.touch_max_angular)
        out.append(Scenario(f"touch:{j.name}", tol.settle_time, {j.name: j.lower + nudge}))
        pull = _pull(asset, j, tol.pull_force)
        if pull is None:
            continue
        push = Pull(pull.link, pull.point, tuple(-x for x in pull.direction), pull.force)
        out += [
            Scenario(f"pull:{j.name}", tol.pull_time, pull=pull),
            Scenario(f"limit:{j.name}", 1.0, {j.name: j.lower + LIMIT_START * rng}, pull),
            Scenario(f"close:{j.name}", 1.0, {j.name: j.lower + CLOSE_START * rng}, push),
        ]
    out.append(Scenario("free", tol.free_time, free_base=True))
    return out
