"""What the drawer and door tasks meet in sets of built assets, per part kind. Prints JSON.

    python bench/task_assets.py NAME=FOLDER [NAME=FOLDER ...]

For each set (read as the tasks read it: ``sim_envs.asset_sources.open_source``, failed
and unreadable assets left out) and each part kind (``MovablePart.kind``: drawer,
side_door, bottom_door, lid, top_flap): the number of parts, their categories and handle
kinds, and the median (min, max) of the joint range (metres for drawers, degrees for
hinges), the part's mass (kg), the joint's damping and friction (N or N m) and the
handle's height above the floor (m). Put a policy's training sets beside its test sets to
see what a policy trained on one never met in the other (docs/tasks.md).
"""

from __future__ import annotations

import argparse
import json
from collections import Counter, defaultdict
from typing import Any

import numpy as np


def spread(values: list[float], digits: int = 2) -> dict[str, float]:
    """Median, min and max of ``values``, rounded."""
    v = np.asarray(values, float)
    return {
        "median": round(float(np.median(v)), digits),
        "min": round(float(v.min()), digits),
        "max": round(float(v.max()), digits),
    }


def part_rows(folder: str) -> list[dict[str, Any]]:
    """One row per movable part of every usable asset in ``folder``."""
    from sim_envs.asset_sources import open_source

    rows = []
    for asset in open_source(folder).assets():
        friction = asset.joint_friction
        for part in asset.movable_parts():
            joint = asset.joint(part.joint_name)
            link = asset.link(joint.child)
            rng = part.range if part.joint_type == "prismatic" else float(np.degrees(part.range))
            rows.append(
                {
                    "asset": asset.id,
                    "category": asset.category,
                    "kind": part.kind,
                    "handle": part.handle_kind,
                    "range": rng,
                    "mass": link.inertial.mass if link.inertial is not None else float("nan"),
                    "damping": joint.physics.damping,
                    "friction": friction.get(joint.name, 0.0),
                    "handle_height": part.handle_object[2],
                }
            )
    return rows


def summarize(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per part kind: counts and spreads (module docstring)."""
    by_kind: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        by_kind[r["kind"]].append(r)
    out = {}
    for kind, group in sorted(by_kind.items()):
        out[kind] = {
            "parts": len(group),
            "assets": len({r["asset"] for r in group}),
            "categories": dict(Counter(r["category"] for r in group).most_common()),
            "handles": dict(Counter(r["handle"] for r in group).most_common()),
            "range": spread([r["range"] for r in group], 3 if kind == "drawer" else 1),
            **{k: spread([r[k] for r in group]) for k in ("mass", "damping", "friction")},
            "handle_height": spread([r["handle_height"] for r in group]),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sets", nargs="+", metavar="NAME=FOLDER", help="asset sets")
    a = ap.parse_args()
    result = {}
    for item in a.sets:
        name, _, folder = item.partition("=")
        if not folder:
            raise SystemExit(f"{item!r}: expected NAME=FOLDER")
        rows = part_rows(folder)
        result[name] = {"folder": folder, "parts": summarize(rows)}
    print(json.dumps({"bench": "task_assets", "sets": result}, indent=1))


if __name__ == "__main__":
    main()
