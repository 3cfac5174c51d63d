"""USD export of built assets: seconds per asset, size, USD's validators, read-back. Prints JSON.

    .venv/bin/python bench/usd_export.py OUT [OUT ...] [--engines sapien,mujoco,usd]
        [--exclude IDS.txt] [--out FILE.json]

For every built asset folder (``model.urdf``) under the given folders: the asset is read
(``load_asset``) and its stage written (``asset_pipeline.assets.usd.write_usd``) into a
temporary folder holding links to the asset's files, timed (reading the asset and
writing ``model.usdc``), and the same stage written as text (``.usda``) for its size; then the stage is opened with USD's
own Python bindings, every ``UsdValidation`` validator is run and
``UsdPhysics.LoadUsdPhysicsFromRange`` is compared with the URDF
(``asset_pipeline.validate.usd_checks``). With ``--engines`` the behaviour checks run in
those engines too and the share of parts agreeing with SAPIEN is reported
(bench/engine_parity.py does only that, with details).

Summary: assets, how many pass the validators and read back equal, export seconds
(median, max; the first export in a process also pays for importing ``pxr``, about
0.4 s, reported apart), sizes (median, max) of ``.usda`` and ``.usdc``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def linked_copy(src: Path, dst: Path) -> None:
    for f in src.rglob("*"):
        if f.is_file() and f.suffix not in (".usda", ".usdc"):
            target = dst / f.relative_to(src)
            target.parent.mkdir(parents=True, exist_ok=True)
            try:
                os.link(f, target)
            except OSError:
                target.write_bytes(f.read_bytes())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("paths", nargs="+", type=Path)
    ap.add_argument("--engines", default="")
    ap.add_argument("--exclude", type=Path)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()

    t = time.perf_counter()
    import pxr.Usd  # noqa: F401

    import_seconds = time.perf_counter() - t
    from asset_pipeline.assets.folder import asset_folders, load_asset
    from asset_pipeline.assets.usd import write_usd
    from asset_pipeline.validate.engines import engine_report
    from asset_pipeline.validate.report import DEFAULT_TOLERANCES, jsonable
    from asset_pipeline.validate.usd_checks import usd_checks

    excluded = set()
    if args.exclude and args.exclude.is_file():
        excluded = {x.strip() for x in args.exclude.read_text().split() if x.strip()}
    engines = [e for e in args.engines.split(",") if e]
    rows = []
    agree = {e: [0, 0] for e in engines if e != "sapien"}
    for folder in asset_folders(args.paths):
        if folder.name in excluded:
            continue
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp) / folder.name
            linked_copy(folder, work)
            t = time.perf_counter()
            asset = load_asset(work, metadata=(work / "asset.json").is_file())
            path = write_usd(asset, work)
            seconds = time.perf_counter() - t
            text = write_usd(asset, work, "model.usda")
            checks = {c.name: c for c in usd_checks(asset)}
            row = {
                "asset": folder.name,
                "export_s": round(seconds, 3),
                "usdc_kb": round(path.stat().st_size / 1024, 1),
                "usda_kb": round(text.stat().st_size / 1024, 1),
                "asset_kb": round(
                    sum(f.stat().st_size for f in folder.rglob("*") if f.is_file()) / 1024, 1
                ),
                "validators_clean": checks["usd_stage"].passed,
                "validator_errors": [] if checks["usd_stage"].passed else checks["usd_stage"].value,
                "reads_back_equal": checks["usd_matches_urdf"].passed,
                "differences": []
                if checks["usd_matches_urdf"].passed
                else checks["usd_matches_urdf"].value,
            }
            if engines:
                report = engine_report(asset, engines, DEFAULT_TOLERANCES)
                for e in agree:
                    for verdicts in report["parity"].values():
                        agree[e][0] += verdicts.get(e) == verdicts.get("sapien")
                        agree[e][1] += 1
                row["engines_agree"] = all(v["agree"] for v in report["parity"].values())
        rows.append(row)
        print(f"{folder.name}: {row['export_s']} s", file=sys.stderr, flush=True)
    secs = [r["export_s"] for r in rows]
    result = {
        "assets": len(rows),
        "validators_clean": sum(r["validators_clean"] for r in rows),
        "reads_back_equal": sum(r["reads_back_equal"] for r in rows),
        "export_s_median": round(statistics.median(secs), 3) if secs else None,
        "export_s_max": round(max(secs), 3) if secs else None,
        "pxr_import_s": round(import_seconds, 3),
        "usda_kb_median": statistics.median(r["usda_kb"] for r in rows) if rows else None,
        "usda_kb_max": max((r["usda_kb"] for r in rows), default=None),
        "usdc_kb_median": statistics.median(r["usdc_kb"] for r in rows) if rows else None,
        "usdc_kb_max": max((r["usdc_kb"] for r in rows), default=None),
        "asset_kb_median": statistics.median(r["asset_kb"] for r in rows) if rows else None,
        "check_agreement_with_sapien": {
            e: round(a / n, 4) if n else None for e, (a, n) in agree.items()
        },
        "per_asset": rows,
    }
    text = json.dumps(jsonable(result), indent=2)
    if args.out:
        args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
