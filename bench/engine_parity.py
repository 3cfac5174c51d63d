"""The same behaviour in SAPIEN, MuJoCo and Newton: per part, each engine's verdict. Prints JSON.

    .venv/bin/python bench/engine_parity.py OUT [OUT ...] [--engines sapien,mujoco,usd]
        [--exclude IDS.txt] [--limit N] [--out FILE.json]

For every built asset folder (``model.urdf``) under the given folders, the behaviour checks
of ``asset_pipeline.validate.engines`` (rest, touch, pull at the handle, upper and lower
limit stops, free base on the floor, finite) run in each engine: SAPIEN on the URDF,
MuJoCo on the MJCF, Newton (XPBD on Warp's CPU device) on the USD (exported into a
temporary folder when the asset has none). A part agrees when each of its checks has
SAPIEN's verdict in the engine; the asset-level checks count as one more "part".

Summary per engine: parts (and checks) with SAPIEN's verdict, their share, the
disagreements by check name, seconds per asset; per asset the disagreeing checks.
``--exclude`` names asset ids (one per line) to leave out.
"""

from __future__ import annotations

import argparse
import json
import logging
import statistics
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def part_of(key: str) -> str:
    return key[key.index("[") + 1 : -1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("paths", nargs="+", type=Path)
    ap.add_argument("--engines", default="sapien,mujoco,usd")
    ap.add_argument("--exclude", type=Path)
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)

    from asset_pipeline.assets.folder import asset_folders, load_asset
    from asset_pipeline.validate.engines import engine_report
    from asset_pipeline.validate.report import DEFAULT_TOLERANCES, jsonable

    engines = [e.strip() for e in args.engines.split(",")]
    excluded = set()
    if args.exclude and args.exclude.is_file():
        excluded = {x.strip() for x in args.exclude.read_text().split() if x.strip()}
    folders = [f for f in asset_folders(args.paths) if f.name not in excluded]
    if args.limit:
        folders = folders[: args.limit]
    per_asset = []
    parts = Counter()
    parts_agree = Counter()
    checks = Counter()
    checks_agree = Counter()
    disagree_by_check: dict[str, Counter] = {e: Counter() for e in engines}
    seconds: dict[str, list[float]] = {e: [] for e in engines}
    for folder in folders:
        asset = load_asset(folder, metadata=(folder / "asset.json").is_file())
        report = engine_report(asset, engines, DEFAULT_TOLERANCES)
        row = {"asset": folder.name, "disagree": {}, "errors": {}}
        for e in engines:
            seconds[e].append(report[e]["seconds"])
            if report[e].get("error"):
                row["errors"][e] = report[e]["error"]
        by_part: dict[str, dict[str, bool]] = {}
        for key, verdicts in report["parity"].items():
            for e in engines:
                if e == "sapien":
                    continue
                ok = verdicts.get(e) is not None and verdicts[e] == verdicts.get("sapien")
                checks[e] += 1
                checks_agree[e] += ok
                by_part.setdefault(part_of(key), {}).setdefault(e, True)
                if not ok:
                    by_part[part_of(key)][e] = False
                    disagree_by_check[e][key.split("[")[0]] += 1
                    row["disagree"].setdefault(e, []).append(
                        {"check": key, "sapien": verdicts.get("sapien"), e: verdicts.get(e)}
                    )
        for verdict in by_part.values():
            for e, ok in verdict.items():
                parts[e] += 1
                parts_agree[e] += ok
        per_asset.append(row)
        print(f"{folder.name}: {row['disagree'] or 'all agree'}", file=sys.stderr, flush=True)
    summary = {}
    for e in engines:
        if e == "sapien":
            continue
        summary[e] = {
            "parts": parts[e],
            "parts_agreeing": parts_agree[e],
            "part_agreement": round(parts_agree[e] / parts[e], 4) if parts[e] else None,
            "checks": checks[e],
            "checks_agreeing": checks_agree[e],
            "disagreements_by_check": dict(disagree_by_check[e]),
        }
    result = {
        "assets": len(folders),
        "engines": engines,
        "summary": summary,
        "seconds_per_asset_median": {
            e: round(statistics.median(v), 2) if v else None for e, v in seconds.items()
        },
        "per_asset": per_asset,
        "when": time.strftime("%Y-%m-%d"),
    }
    text = json.dumps(jsonable(result), indent=2)
    if args.out:
        args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
