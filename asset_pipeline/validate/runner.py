"""Run the validation stages on a built asset, repair, re-check, write the report.

:func:`check_asset` runs every stage once on an asset folder; a stage runs only when
the stages it needs passed. :func:`validate_asset` adds the repair loop: each round
edits the asset's model (:func:`~asset_pipeline.validate.repair.plan_repairs`), writes
it into a private working copy of the folder (``<asset>/.repair/``, files hard-linked)
and checks that copy again, up to ``max_rounds`` rounds. Only when the repaired asset
passes are the changed files copied back (each atomically, ``asset.json`` last); an
asset that still fails keeps the files it had. Then ``report.json`` and
``preview.png`` are written.
"""

from __future__ import annotations

import logging
import os
import shutil
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.assets.folder import (
    FORMAT_FILES,
    formats_in,
    load_asset,
    missing_files,
    save_asset,
)
from asset_pipeline.assets.layout import ASSET_JSON_NAME, URDF_NAME, AssetFormatError
from asset_pipeline.simulation.sim_options import DEFAULT_SIM_OPTIONS, SimOptions
from asset_pipeline.validate.dynamic import dynamic_checks
from asset_pipeline.validate.kinematic import kinematic_checks
from asset_pipeline.validate.load import load_checks
from asset_pipeline.validate.repair import plan_repairs
from asset_pipeline.validate.report import (
    DEFAULT_TOLERANCES,
    Check,
    RepairRecord,
    Report,
    Tolerances,
    write_report,
)
from asset_pipeline.validate.static import static_checks
from generator.atomic_files import atomic_write_bytes

log = logging.getLogger(__name__)

#: Working copy of an asset under repair, inside the asset folder.
REPAIR_DIR = ".repair"
#: Static failures after which SAPIEN would reject or silently alter the asset.
STRUCTURAL = frozenset(
    {"single_root", "has_movable_part", "axis_unit", "limits_ordered", "mass_positive",
     "inertia_valid"}
)  # fmt: skip


def _files_check(asset_dir: Path) -> tuple[Check, BuiltAsset | None]:
    """The ``urdf`` (or ``asset_json``) check: the files read, every mesh path stays
    inside the folder, every referenced file exists."""
    try:
        asset = load_asset(asset_dir, metadata=False)
    except AssetFormatError as e:
        name = "asset_json" if e.path.name == ASSET_JSON_NAME else "urdf"
        return Check(name, "static", "asset", False, str(e), "reads", str(e)), None
    missing = missing_files(asset)
    check = Check(
        "urdf",
        "static",
        "asset",
        not missing,
        value=missing or "parsed",
        tolerance="parses, files exist",
        message="" if not missing else f"missing files: {missing}",
    )
    return check, asset


def check_asset(
    asset_dir: str | Path,
    tol: Tolerances = DEFAULT_TOLERANCES,
    options: SimOptions = DEFAULT_SIM_OPTIONS,
    timings: dict[str, float] | None = None,
) -> tuple[list[Check], BuiltAsset | None]:
    """Run every stage once; returns the checks and the asset read (None if unreadable).

    ``timings`` (when given) accumulates seconds per stage.
    """
    timings = timings if timings is not None else {}

    def timed(stage: str, fn: Callable[[], Any]) -> Any:
        t = time.perf_counter()
        try:
            return fn()
        finally:
            timings[stage] = timings.get(stage, 0.0) + time.perf_counter() - t

    first, asset = timed("static", lambda: _files_check(Path(asset_dir)))
    checks = [first]
    if asset is None or not first.passed:
        return checks, asset
    checks += timed("static", lambda: static_checks(asset, tol))
    if "usd" in formats_in(asset_dir):
        from asset_pipeline.validate.usd_checks import usd_checks

        checks += timed("static", lambda: usd_checks(asset))
    if any(not c.passed and c.name in STRUCTURAL for c in checks):
        return checks, asset
    checks += timed("load", lambda: load_checks(asset, tol, options))
    if any(not c.passed and c.name == "sapien_load" for c in checks):
        return checks, asset
    checks += timed("kinematic", lambda: kinematic_checks(asset, tol))
    checks += timed("dynamic", lambda: dynamic_checks(asset, tol, options))
    return checks, asset


def _working_copy(asset_dir: Path) -> Path:
    """A fresh ``asset_dir/.repair`` holding hard links (or copies) of the asset's files."""
    work = asset_dir / REPAIR_DIR
    shutil.rmtree(work, ignore_errors=True)
    for src in asset_dir.rglob("*"):
        rel = src.relative_to(asset_dir)
        if rel.parts[0] == REPAIR_DIR or not src.is_file() or src.is_symlink():
            continue
        dst = work / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)
    return work


def _changed_files(asset: BuiltAsset, formats: tuple[str, ...]) -> list[str]:
    """Relative names of the files :func:`save_asset` rewrites for ``asset`` in ``formats``,
    asset.json last."""
    pieces = [p.filename for k in asset.links for p in k.collisions if p.mesh is not None]
    models = [FORMAT_FILES[f] for f in formats if f != "urdf"]
    return [*pieces, URDF_NAME, *models, ASSET_JSON_NAME]


def _copy_back(work: Path, asset_dir: Path, names: list[str]) -> None:
    for name in names:
        src = work / name
        if src.is_file():
            atomic_write_bytes(asset_dir / name, src.read_bytes())


def validate_asset(
    asset_dir: str | Path,
    *,
    repair: bool = True,
    max_rounds: int = 3,
    preview: bool = True,
    tolerances: Tolerances = DEFAULT_TOLERANCES,
    options: SimOptions = DEFAULT_SIM_OPTIONS,
    write: bool = True,
    engines: Sequence[str] = (),
) -> Report:
    """Check a built asset, repair what can be repaired, write ``report.json`` (+ preview).

    See the module docstring. Status: "ok" (passed without repairs), "repaired"
    (passed after repairs; the repaired files replace the old ones), "failed"
    (``reasons`` says why; the asset's files are left as they were). ``write=False``
    changes nothing on disk. ``engines`` (of :data:`~asset_pipeline.validate.engines.ENGINES`)
    runs the behaviour checks of :mod:`asset_pipeline.validate.engines` on the final asset in
    each of them (``report.engines``, with the parity against SAPIEN); they do not change
    the status.
    """
    asset_dir = Path(asset_dir)
    timings: dict[str, float] = {}
    repairs: list[RepairRecord] = []
    rounds: list[dict[str, Any]] = []
    reasons: list[str] = []
    changed: list[str] = []
    shutil.rmtree(asset_dir / REPAIR_DIR, ignore_errors=True)
    formats = formats_in(asset_dir) or ("urdf",)
    work = asset_dir
    rnd = 0
    while True:
        checks, asset = check_asset(work, tolerances, options, timings)
        failed = [c for c in checks if not c.passed]
        rounds.append({"round": rnd, "failed": [c.key for c in failed]})
        if not failed:
            break
        if not repair or rnd >= max_rounds or asset is None:
            reasons = [f"{c.key}: {c.message or 'failed'}" for c in failed]
            if repair and rnd >= max_rounds:
                reasons.append(f"still failing after {max_rounds} rounds of repairs")
            break
        t = time.perf_counter()
        applied, unrepairable = plan_repairs(asset, checks, tolerances)
        if applied:
            if work is asset_dir:
                work = _working_copy(asset_dir)
            names = _changed_files(asset, formats)
            save_asset(asset, work, formats=formats)
            changed += [n for n in names if n not in changed]
            for r in applied:
                r.round = rnd + 1
                r.files = names
            log.info(
                "%s: round %d: %d repairs: %s",
                asset_dir.name,
                rnd + 1,
                len(applied),
                ", ".join(f"{r.kind}({r.target})" for r in applied),
            )
        timings["repair"] = timings.get("repair", 0.0) + time.perf_counter() - t
        repairs += applied
        if not applied:
            reasons = [f"{c.key}: {c.message or 'failed'}" for c in failed]
            reasons += [f"not repairable: {r}" for r in unrepairable]
            break
        rnd += 1
    status = "failed" if failed else ("repaired" if repairs else "ok")
    if work is not asset_dir:
        if status == "repaired" and write:
            # asset.json last: a folder with an asset.json holds a complete asset
            _copy_back(work, asset_dir, [n for n in changed if n != ASSET_JSON_NAME])
            _copy_back(work, asset_dir, [ASSET_JSON_NAME])
        shutil.rmtree(work, ignore_errors=True)
    report = Report(
        asset=asset.id if asset is not None else asset_dir.name,
        status=status,
        checks=checks,
        repairs=repairs,
        rounds=rounds,
        reasons=reasons,
        timings=timings,
        tolerances=tolerances,
        sim_options=options,
    )
    if engines and asset is not None and status != "failed":
        from asset_pipeline.validate.engines import engine_report

        t = time.perf_counter()
        final = load_asset(asset_dir) if write or work is asset_dir else asset
        report.engines = engine_report(final, list(engines), tolerances)
        timings["engines"] = time.perf_counter() - t
    if preview and write:
        from asset_pipeline.validate.preview import render_preview

        t = time.perf_counter()
        try:
            p = render_preview(asset_dir)
        except Exception as e:  # noqa: BLE001 - a preview must never fail validation
            log.warning("%s: preview failed: %s", asset_dir, e)
            p = None
        timings["preview"] = time.perf_counter() - t
        report.preview = p.name if p is not None else None
    if write:
        write_report(report, asset_dir)
    log.info("%s: %s (%d checks, %d repairs)", report.asset, status, len(checks), len(repairs))
    return report
