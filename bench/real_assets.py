"""Real artist-made objects made sim-ready: import, build, validate, open; prints JSON.

Runs the path an outside user takes with PartNet-Mobility objects:
``pact import DATA --out OUT`` (asset_pipeline.importers.partnet), then for every bundle
``build_asset`` + ``validate_asset`` (timed: the build includes the articulation-aware
collision boxes; a second build of the first ``--rebuild`` objects measures the cache
hit) and, unless ``--no-solver``, the scripted Panda on every movable part
(``tasks.solver.check_tasks``). Figures: share that validates, share of parts opened,
seconds per object (median, 90th percentile, max), per category, and every failure
with its reason. The data never enters the repository: DATA is a folder of
PartNet-Mobility object folders (``mobility.urdf`` + ``textured_objs/``), e.g. mirrored
from public repositories (see docs/input-format.md); ids listed in ``--exclude`` (one
per line, ``#`` comments) are never opened.

    .venv/bin/python bench/real_assets.py /path/to/partnet --out runs/real
    .venv/bin/python bench/real_assets.py /path/to/partnet --limit 5 --no-solver --coverage
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _ids(path: Path | None) -> set[str]:
    if path is None:
        return set()
    lines = (line.split("#")[0].strip() for line in path.read_text().splitlines())
    return {line for line in lines if line}


def _spread(xs: list[float]) -> dict[str, float]:
    if not xs:
        return {}
    s = sorted(xs)
    return {
        "median": round(statistics.median(s), 2),
        "p90": round(s[min(len(s) - 1, int(0.9 * len(s)))], 2),
        "max": round(s[-1], 2),
        "total": round(sum(s), 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", type=Path, help="Folder of PartNet-Mobility object folders.")
    ap.add_argument("--out", type=Path, default=Path("runs/real_assets"), help="Work folder.")
    ap.add_argument("--exclude", type=Path, default=None, help="Ids never to open.")
    ap.add_argument("--limit", type=int, default=None, help="Only the first N objects.")
    ap.add_argument("--rebuild", type=int, default=3, help="Objects built twice (cache hit).")
    ap.add_argument("--no-solver", action="store_true", help="Skip the scripted Panda.")
    ap.add_argument("--seed", type=int, default=0, help="Seed of the solver's episodes.")
    ap.add_argument(
        "--coverage",
        action="store_true",
        help="Also measure how each part's boxes fit its mesh (voxel_collision.coverage; "
        "up to a minute per object).",
    )
    args = ap.parse_args()

    import shutil

    from asset_pipeline.assets.build import BuildOptions, build_asset, prepare_object
    from asset_pipeline.geometry.voxel_collision import articulated_boxes, coverage
    from asset_pipeline.importers.partnet import find_objects, import_objects
    from asset_pipeline.validate import validate_asset
    from generator.bundle import load_bundle

    excluded = _ids(args.exclude)
    folders = [f for f in find_objects(args.data) if f.name not in excluded]
    folders = folders[: args.limit] if args.limit else folders
    bundles = args.out / "bundles"
    shutil.rmtree(bundles, ignore_errors=True)  # a fresh import each run
    t0 = time.perf_counter()
    imported = import_objects(folders, bundles)
    import_seconds = time.perf_counter() - t0

    # a fresh collision cache: the first build of each object is a cold one
    cache = args.out / "voxel-cache"
    shutil.rmtree(cache, ignore_errors=True)
    options = BuildOptions(cache_dir=cache)
    rows = []
    build_s: list[float] = []
    for k, d in enumerate(sorted(imported)):
        category = load_bundle(d).category
        row = {"id": d.name, "category": category}
        t = time.perf_counter()
        try:
            built = build_asset(d, options=options)
        except Exception as e:  # noqa: BLE001 - a failed object is a figure, not a crash
            row.update(status="build failed", reason=f"{type(e).__name__}: {e}")
            rows.append(row)
            continue
        row["build_s"] = round(time.perf_counter() - t, 2)
        build_s.append(row["build_s"])
        row["pieces"] = sum(built.pieces.values())
        if k < args.rebuild:
            t = time.perf_counter()
            build_asset(d, options=options)
            row["rebuild_s"] = round(time.perf_counter() - t, 2)
        if args.coverage:  # how the boxes fit the part meshes (boxes from the cache)
            obj = prepare_object(load_bundle(d), None, options)
            fit = coverage(obj, articulated_boxes(obj, options.voxel, cache / "voxel")[0])
            row["uncovered"] = round(max(f["uncovered"] for f in fit.values()), 4)
            row["overfill"] = round(max(f["overfill"] for f in fit.values()), 4)
        t = time.perf_counter()
        report = validate_asset(d, preview=False)
        row["validate_s"] = round(time.perf_counter() - t, 2)
        row["status"] = report.status
        if not report.ok:
            row["reason"] = "; ".join(report.reasons[:4])
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)

    parts: list[dict] = []
    if not args.no_solver:
        from tasks.solver import check_tasks, summarize

        t = time.perf_counter()
        results = check_tasks(bundles, seed=args.seed)
        summary = summarize(results)
        for r in results:
            parts.append(
                {"asset": r.asset_id, "part": r.part, "opened": r.success,
                 "fraction": round(r.final_fraction, 3), "stands": 1 + r.stands,
                 "reason": r.reason}
            )  # fmt: skip
        solver_seconds = time.perf_counter() - t

    by_cat: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    for r in rows:
        c = by_cat[r["category"]]
        c["objects"] += 1
        c["valid"] += r.get("status") in ("ok", "repaired")
    cat_of = {r["id"]: r["category"] for r in rows}
    for p in parts:
        c = by_cat[cat_of.get(p["asset"], "unknown")]
        c["parts"] += 1
        c["opened"] += p["opened"]
    valid = sum(r.get("status") in ("ok", "repaired") for r in rows)
    out = {
        "objects_found": len(folders),
        "imported": len(imported),
        "import_failures": [str(f) for f in imported.failures],
        "import_seconds": round(import_seconds, 1),
        "built": len(build_s),
        "validated": valid,
        "validated_share": round(valid / len(rows), 3) if rows else None,
        "build_seconds": _spread(build_s),
        "rebuild_seconds": _spread([r["rebuild_s"] for r in rows if "rebuild_s" in r]),
        "validate_seconds": _spread([r["validate_s"] for r in rows if "validate_s" in r]),
        # worst part per object: surface samples farther than max(5 mm, 1% of the part)
        # from its boxes, and box volume farther than that from its surface
        "uncovered": _spread([r["uncovered"] for r in rows if "uncovered" in r]),
        "overfill": _spread([r["overfill"] for r in rows if "overfill" in r]),
        "per_category": {k: dict(v) for k, v in sorted(by_cat.items())},
        "failures": [r for r in rows if r.get("status") not in ("ok", "repaired")],
    }
    if not args.no_solver:
        out.update(
            parts=summary["parts"],
            opened=summary["opened"],
            opened_share=round(summary["rate"], 3) if parts else None,
            # opened where the env placed the robot (no further stand)
            opened_where_placed=summary["opened_where_placed"],
            solver_seconds=round(solver_seconds, 1),
            parts_not_opened=[p for p in parts if not p["opened"]],
        )
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
