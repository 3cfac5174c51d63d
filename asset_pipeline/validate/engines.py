"""The same behaviour checks in several physics engines: SAPIEN (the URDF), MuJoCo (the
MJCF) and Newton (the USD).

Validation proves an asset in SAPIEN (:mod:`.dynamic`); this module asks whether the
asset's other files behave the same elsewhere. The checks are written once, over
:class:`Scenario` runs that each engine module simulates (:mod:`.engine_sapien`,
:mod:`.engine_mujoco`, :mod:`.engine_newton`: ``simulate(asset, scenarios)`` returns one
:class:`Trajectory` per scenario), so every engine is judged by the same code:

``rest_drift[joint]``   base fixed, gravity, no drive, everything closed: the joint moves
                        at most 1 mm / 1 deg in 2 s (the part rests)
``touch_hold[joint]``   nudged 2 % open (at most 1 cm / 3 deg): opens no further
``handle_pull[joint]``  pulled at its handle with 40 N along its opening direction (the
                        direction turns with the part): opens 30 % of its range in 2 s
                        (a drawer slides out, a door swings)
``limit_stop[joint]``   from 90 % open, pulled on: stays within its upper limit
                        (``limit_linear`` / ``limit_angular``)
``closed_stop[joint]``  from 10 % open, pushed shut with 40 N: stops at its lower limit
                        (it does not pass into the carcass; engines, like PhysX, filter
                        contacts between a part and its parent, so the limit is what stops it)
``free_base_stable``    base free on the floor for 1.5 s, its parts held closed by drives:
                        it rests (tilt 2 deg, 1 cm), it does not sink through the floor
``finite``              no NaN or inf anywhere

:func:`engine_checks` runs them in one engine; :func:`engine_report` in several, with the
parity of each against SAPIEN (the ``engines`` section of ``report.json``).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from asset_pipeline.assets.built_asset import BuiltAsset, Joint
from asset_pipeline.validate.engine_scenarios import (
    Scenario,
    Trajectory,
    scenarios,
)
from asset_pipeline.validate.report import Check, Tolerances

log = logging.getLogger(__name__)

#: The engines, by the name ``pact validate --engines`` takes, and the file each reads.
ENGINES = ("sapien", "mujoco", "usd")
ENGINE_FILES = {"sapien": "model.urdf", "mujoco": "model.xml", "usd": "model.usdc"}
Simulate = Callable[[BuiltAsset, Sequence[Scenario]], list[Trajectory]]


def simulator(engine: str) -> Simulate:
    """The ``simulate`` function of an engine (imported on demand: each needs its library)."""
    if engine == "sapien":
        from asset_pipeline.validate.engine_sapien import simulate
    elif engine == "mujoco":
        from asset_pipeline.validate.engine_mujoco import simulate
    elif engine == "usd":
        from asset_pipeline.validate.engine_newton import simulate
    else:
        raise ValueError(f"unknown engine {engine!r}; engines: {', '.join(ENGINES)}")
    return simulate


def _unit(j: Joint) -> str:
    return "m" if j.type == "prismatic" else "rad"


def evaluate(
    asset: BuiltAsset, runs: dict[str, Trajectory], tol: Tolerances, engine: str
) -> list[Check]:
    """The checks of the module docstring from the trajectories of :func:`scenarios`."""
    checks: list[Check] = []
    stage = f"engine:{engine}"
    joints = asset.movable_joints
    rest = runs["rest"]
    for i, j in enumerate(joints):
        lin = j.type == "prismatic"
        lim = tol.drift_linear if lin else tol.drift_angular
        drift = float(np.max(np.abs(rest.q[:, i] - rest.q[0, i]))) if len(rest.q) else math.nan
        ok = bool(math.isfinite(drift) and drift <= lim)
        checks.append(
            Check("rest_drift", stage, j.name, ok, drift, lim,
                  "" if ok else f"drifts {drift:.4f} {_unit(j)} in {tol.settle_time:g} s at rest")
        )  # fmt: skip
    for i, j in enumerate(joints):
        lin = j.type == "prismatic"
        rng = j.upper - j.lower
        touch = runs[f"touch:{j.name}"]
        lim = tol.drift_linear if lin else tol.drift_angular
        moved = max(0.0, float(np.max(touch.q[:, i]) - touch.q[0, i])) if len(touch.q) else math.nan
        ok = bool(math.isfinite(moved) and moved <= lim)
        checks.append(
            Check("touch_hold", stage, j.name, ok, moved, lim,
                  "" if ok else f"nudged open it opens {moved:.4f} {_unit(j)} further")
        )  # fmt: skip
        if f"pull:{j.name}" not in runs:
            continue
        pull = runs[f"pull:{j.name}"]
        best = float(np.max((pull.q[:, i] - j.lower) / rng)) if len(pull.q) else math.nan
        ok = bool(math.isfinite(best) and best >= tol.pull_fraction)
        checks.append(
            Check("handle_pull", stage, j.name, ok, best, tol.pull_fraction,
                  "" if ok else f"pulled with {tol.pull_force:g} N it opens {best:.0%} of its range")
        )  # fmt: skip
        stop = tol.limit_linear if lin else tol.limit_angular
        over = float(np.max(runs[f"limit:{j.name}"].q[:, i]) - j.upper)
        ok = bool(math.isfinite(over) and over <= stop)
        checks.append(
            Check("limit_stop", stage, j.name, ok, over, stop,
                  "" if ok else f"pulled on, it passes its upper limit by {over:.4f} {_unit(j)}")
        )  # fmt: skip
        under = float(j.lower - np.min(runs[f"close:{j.name}"].q[:, i]))
        ok = bool(math.isfinite(under) and under <= stop)
        checks.append(
            Check("closed_stop", stage, j.name, ok, under, stop,
                  "" if ok else f"pushed shut, it passes its lower limit by {under:.4f} {_unit(j)}")
        )  # fmt: skip
    free = runs["free"]
    T = free.base_pose
    if np.isfinite(T).all():
        tilt = float(math.acos(float(np.clip(T[2, 2], -1, 1))))
        disp = float(np.linalg.norm(T[:3, 3] - np.array([0.0, 0.0, 0.002])))
    else:
        tilt = disp = math.nan
    ok = bool(
        math.isfinite(tilt)
        and tilt <= tol.free_tilt
        and disp <= tol.free_displacement
        and free.base_speed <= tol.max_linear_velocity
        and free.base_angular_speed <= tol.max_angular_velocity
    )
    checks.append(
        Check("free_base_stable", stage, "asset", ok,
              {"tilt": tilt, "displacement": disp, "speed": free.base_speed,
               "angular_speed": free.base_angular_speed},
              {"tilt": tol.free_tilt, "displacement": tol.free_displacement},
              "" if ok else f"free on the floor the base tilts {math.degrees(tilt):.1f} deg "
              f"and moves {disp * 1000:.0f} mm")
    )  # fmt: skip
    bad = [name for name, r in runs.items() if not r.finite]
    checks.append(
        Check("finite", stage, "asset", not bad, bad or None, "no NaN/inf",
              "" if not bad else f"non-finite state in {bad}")
    )  # fmt: skip
    return checks


def engine_checks(
    asset: BuiltAsset, engine: str, tol: Tolerances, simulate: Simulate | None = None
) -> list[Check]:
    """Run every scenario of ``asset`` in ``engine`` and judge it (module docstring)."""
    plan = scenarios(asset, tol)
    trajectories = (simulate or simulator(engine))(asset, plan)
    return evaluate(
        asset, {s.name: t for s, t in zip(plan, trajectories, strict=True)}, tol, engine
    )


def engine_report(asset: BuiltAsset, engines: Sequence[str], tol: Tolerances) -> dict[str, Any]:
    """The ``engines`` section of ``report.json``: per engine its checks (or the error
    that stopped it), its verdict and seconds; ``parity``: per check key, each engine's
    verdict, and whether every engine agrees with SAPIEN."""
    out: dict[str, Any] = {}
    verdicts: dict[str, dict[str, bool]] = {}
    for engine in engines:
        t = time.perf_counter()
        try:
            checks = engine_checks(asset, engine, tol)
        except Exception as e:  # noqa: BLE001 - one engine failing never stops the others
            log.warning("%s: engine %s failed: %s", asset.id, engine, e, exc_info=True)
            out[engine] = {
                "file": ENGINE_FILES[engine],
                "passed": False,
                "error": f"{type(e).__name__}: {e}",
                "checks": [],
                "seconds": round(time.perf_counter() - t, 2),
            }
            verdicts[engine] = {}
            continue
        verdicts[engine] = {c.key: c.passed for c in checks}
        out[engine] = {
            "file": ENGINE_FILES[engine],
            "passed": all(c.passed for c in checks),
            "checks": checks,
            "seconds": round(time.perf_counter() - t, 2),
        }
    keys = list(dict.fromkeys(k for v in verdicts.values() for k in v))
    parity = {}
    for key in keys:
        row = {e: verdicts[e].get(key) for e in engines}
        ref = row.get("sapien")
        row["agree"] = ref is None or all(v == ref for v in row.values() if v is not None)
        parity[key] = row
    out["parity"] = parity
    return out
