"""The ``pact`` command line: sample, build, validate, convert, train and evaluate.

Library code lives in the packages; this module only parses arguments, shows
progress and maps failures to exit codes: a problem with an input is one line
``error: PATH: what is wrong, what to do`` and exit code 2, a batch with failed items
exits 1. Packages are imported inside their command functions, so ``pact --help``
stays fast.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from generator.mesh_repair.decimation import DEFAULT_VISUAL_FACES
from generator.procedural import CATEGORIES

app = typer.Typer(
    help="Photos of articulated furniture and appliances -> simulation-ready assets and RL tasks.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
# messages are never hard-wrapped: a path in an error stays on one line (greppable)
console = Console(stderr=True, soft_wrap=True)


def _user_errors() -> tuple[type[BaseException], ...]:
    """The typed errors whose message names the file and says what to do: shown as one
    ``error:`` line, never as a traceback."""
    from asset_pipeline.assets.build import BuildError
    from asset_pipeline.assets.layout import AssetFormatError
    from asset_pipeline.catalog.batch import OutputFolderError, OutputLockedError
    from asset_pipeline.catalog.registry import CatalogError
    from asset_pipeline.importers.source_format import ImportFormatError
    from asset_pipeline.inputs.errors import InputError
    from asset_pipeline.validate import ReportFormatError
    from generator.articulated import ObjectModelError
    from generator.data import DatasetError
    from sim_envs.asset_sources import AssetSourceError
    from tasks.train import TrainingArgsError

    return (
        AssetFormatError, OutputFolderError, OutputLockedError, BuildError, CatalogError,
        ImportFormatError, InputError, ReportFormatError, ObjectModelError, DatasetError,
        AssetSourceError, TrainingArgsError, FileNotFoundError, FileExistsError, NotADirectoryError,
        IsADirectoryError, PermissionError,
    )  # fmt: skip


def reports_errors(command: Callable) -> Callable:
    """Run a command; a user error (:func:`_user_errors`) becomes ``error: ...``, exit 2."""

    @functools.wraps(command)
    def run(*args: Any, **kwargs: Any) -> Any:
        try:
            return command(*args, **kwargs)
        except typer.Exit:
            raise
        except Exception as e:
            if isinstance(e, _user_errors()):
                raise fail(e) from e
            raise

    return run


def fail(message: object, code: int = 2) -> typer.Exit:
    """Print ``error: MESSAGE`` (never read as markup) and return the exit to raise.

    An OSError reads ``PATH: what the system says``.
    """
    if isinstance(message, OSError) and message.filename is not None:
        message = f"{message.filename}: {message.strerror or message}"
    console.print(f"[red]error:[/red] {escape(str(message))}")
    return typer.Exit(code)


def wide_console() -> Console:
    """Stdout console at least 160 columns wide, so ids in tables are never cut when piped."""
    return Console(width=max(Console().width, 160))


@app.callback()
def _root(verbose: bool = typer.Option(False, "--verbose", "-v", help="Debug logging.")) -> None:
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )


@app.command()
@reports_errors
def sample(
    category: str = typer.Option(
        ..., "--category", "-c", help=f"One of: {', '.join(CATEGORIES)}, or 'all'."
    ),
    n: int = typer.Option(1, "--n", min=1, help="How many objects."),
    seed: int = typer.Option(0, "--seed", help="Seed of the first object; object k uses seed + k."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder; one bundle per object."),
    split: str = typer.Option("train", "--split", help="Parameter ranges: train or test."),
    realistic: bool = typer.Option(
        False,
        "--realistic",
        help="The realistic factory (the parser's training objects: real proportions, "
        "handles, legs, plinths, knobs; ids <category>_r...); also -c other.",
    ),
) -> None:
    """Sample seeded procedural articulated objects as bundles in OUT/<id>/."""
    from generator.bundle import save_bundle
    from generator.procedural import UnknownCategoryError, object_id, sample_object
    from generator.procedural.realistic import realistic_object_id, sample_realistic_object

    if split not in ("train", "test"):
        raise fail(f"--split {split!r}: train or test")
    sampler, name = (
        (sample_realistic_object, realistic_object_id) if realistic else (sample_object, object_id)
    )
    cats = list(CATEGORIES) if category == "all" else [category]
    written = []
    for cat in cats:
        for k in range(n):
            try:
                obj = sampler(cat, seed + k, split=split)
            except UnknownCategoryError as e:
                raise fail(e) from e
            d = save_bundle(obj, out / name(cat, seed + k, split))
            written.append(d)
    for d in written:
        print(d)


@app.command("eval-gen")
@reports_errors
def eval_gen(
    pred: Path = typer.Option(
        ..., "--pred", help="Folder of predicted bundles (<id>/object.json)."
    ),
    gt: Path = typer.Option(..., "--gt", help="Folder of ground-truth bundles, matched by <id>."),
    out: Path = typer.Option(
        None, "--out", help="JSON file to write (default: PRED/metrics.json)."
    ),
    n_states: int = typer.Option(5, help="Articulated states sampled for AS- metrics."),
    n_points: int = typer.Option(10_000, help="Surface points per object for dCD."),
    seed: int = typer.Option(0, help="Seed of the surface sampling."),
) -> None:
    """Generation metrics (RS/AS dgIoU, dcDist, dCD, AOR) of predictions against ground truth."""
    import json

    from generator.atomic_files import atomic_write_bytes
    from generator.metrics import evaluate_dirs, format_table

    results = evaluate_dirs(pred, gt, n_states=n_states, n_points=n_points, seed=seed)
    wide_console().print(format_table(results))
    path = out or pred / "metrics.json"
    atomic_write_bytes(path, json.dumps(results, indent=2, allow_nan=False).encode())
    console.print(f"wrote {escape(str(path))}")
    if results["missing"] or results.get("failed"):
        raise typer.Exit(1)


#: --collision values -> asset_pipeline.assets.build collision methods.
COLLISION_OPTIONS = {"auto": "auto", "mesh": "voxel", "voxel": "voxel", "coacd": "coacd"}
SEGMENTER_DEFAULT = "parser"
SEGMENTER_HELP = (
    "How the part mask of a photo without one is made: parser (the project's photo parser) "
    "or sam2 (SAM2's automatic masks merged into parts by the parser, as in the PAct paper; "
    "needs the sam2 extra and --sam2-checkpoint, docs/segmenters.md)."
)
PARSER_WEIGHTS_HELP = (
    "The photo parser's weights: 'shipped' (procedural renders only), 'partnet' (also "
    "fine-tuned on PartNet-Mobility renders: non-commercial terms, docs/parser.md) or a "
    "weights folder."
)


def check_parser_weights(weights: str) -> str | None:
    """None for the default weights; otherwise the weights, loaded once to fail early."""
    if weights == "shipped":
        return None
    from asset_pipeline.catalog.batch import load_parser
    from generator.parser.inference import NAMED_WEIGHTS

    if weights not in NAMED_WEIGHTS:
        weights = str(Path(weights).resolve())
    try:
        load_parser(weights)
    except (OSError, ValueError) as e:
        raise fail(f"--parser-weights {weights}: {e}") from e
    return weights


SAM2_CHECKPOINT_HELP = "A SAM2 checkpoint file (with --segmenter sam2; docs/segmenters.md)."


def check_segmenter(segmenter: str, checkpoint: Path | None) -> str:
    from asset_pipeline.inputs.parsing import SEGMENTERS

    if segmenter not in SEGMENTERS:
        raise fail(f"--segmenter {segmenter!r}: choose one of {', '.join(SEGMENTERS)}")
    if segmenter == "sam2" and checkpoint is None:
        raise fail("--segmenter sam2 needs --sam2-checkpoint FILE (docs/segmenters.md)")
    if checkpoint is not None and not checkpoint.is_file():
        raise fail(f"{checkpoint}: no such SAM2 checkpoint file")
    return segmenter


VISUAL_FACES_HELP = (
    "Visual triangles per asset in all: its visual meshes are decimated to it (collisions "
    "and masses come from the full meshes); 0 keeps every triangle."
)


def check_collision(value: str) -> None:
    if value not in COLLISION_OPTIONS:
        raise fail(f"--collision {value!r}: choose one of {', '.join(COLLISION_OPTIONS)}")


FORMATS_DEFAULT = "urdf,mjcf,usd"
FORMATS_HELP = (
    "Model files to write, comma-separated: urdf (always: the pipeline reads it), mjcf "
    "(model.xml), usd (model.usdc, OpenUSD with UsdPhysics; docs/usd.md)."
)


def check_formats_option(value: str) -> tuple[str, ...]:
    from asset_pipeline.assets.folder import check_formats

    try:
        return check_formats(value)
    except ValueError as e:
        raise fail(f"--formats {value!r}: {e}") from e


def _build_one(
    bundle: Path,
    height: float | None,
    validate: bool,
    repair: bool,
    collision: str,
    visual_faces: int,
    formats: tuple[str, ...] = ("urdf", "mjcf", "usd"),
) -> tuple[str, str]:
    """Build (and validate) one bundle; return (status, detail)."""
    from asset_pipeline.assets.build import BuildOptions, build_asset

    options = BuildOptions(collision=collision, visual_faces=visual_faces, formats=formats)
    result = build_asset(bundle, height=height, options=options)
    detail = f"{sum(result.pieces.values())} pieces, {result.seconds:.1f} s"
    if not validate:
        return "built", detail
    from asset_pipeline.validate import validate_asset

    report = validate_asset(bundle, repair=repair)
    if not report.ok:
        failed = "; ".join(f"{c.key}" for c in report.failed_checks[:4])
        return report.status, f"{detail}; failed: {failed}"
    return report.status, detail


@app.command()
@reports_errors
def build(
    paths: list[Path] = typer.Argument(..., help="Bundle folders, or folders of bundles."),
    height: float = typer.Option(None, help="Metric height (m) for bundles without a scale."),
    validate: bool = typer.Option(True, "--validate/--no-validate", help="Validate in SAPIEN."),
    repair: bool = typer.Option(True, "--repair/--no-repair", help="Repair what validation finds."),
    collision: str = typer.Option(
        "auto",
        help="auto (a part's primitives, else articulation-aware boxes from its mesh), mesh "
        "(boxes from every part's mesh) or coacd (each part decomposed alone).",
    ),
    catalog: bool = typer.Option(
        True,
        "--catalog/--no-catalog",
        help="Register the assets of a folder of bundles in FOLDER/registry.sqlite.",
    ),
    visual_faces: int = typer.Option(
        DEFAULT_VISUAL_FACES, min=0, help=VISUAL_FACES_HELP, show_default=True
    ),
    formats: str = typer.Option(FORMATS_DEFAULT, help=FORMATS_HELP, show_default=True),
) -> None:
    """Build bundles into sim assets: collision/*.obj, model.urdf, model.xml, model.usdc,
    asset.json.

    Goes on past bad bundles, reports each at the end and exits 1 if any failed. The
    assets built from a folder of bundles are registered in that folder's catalog (so
    `pact ls`, `pact gallery`, the tasks and `pact check-tasks` find them).
    """
    import contextlib

    from asset_pipeline.catalog.batch import output_lock
    from asset_pipeline.catalog.registry import Catalog
    from generator.articulated import ObjectModelError
    from generator.bundle import find_bundles, is_bundle

    check_collision(collision)
    model_formats = check_formats_option(formats)
    bundles: list[Path] = []
    catalog_of: dict[Path, Path] = {}  # bundle -> the folder whose catalog lists it
    bad: list[tuple[str, str]] = []
    for p in paths:
        try:
            found = find_bundles(p)
        except ObjectModelError as e:
            bad.append((str(p), str(e)))
            continue
        if not found:
            bad.append((str(p), "no bundle (object.json) found here"))
        bundles.extend(found)
        if catalog and not is_bundle(p):
            catalog_of.update({b: p for b in found})
    with contextlib.ExitStack() as stack:
        catalogs = {}
        for root in sorted(set(catalog_of.values())):
            stack.enter_context(output_lock(root))
            catalogs[root] = stack.enter_context(Catalog(root))
        build = functools.partial(
            _build_one, height=height, validate=validate, repair=repair,
            collision=COLLISION_OPTIONS.get(collision, collision), visual_faces=visual_faces,
            formats=model_formats,
        )  # fmt: skip
        _build_all(bundles, build, catalogs, catalog_of, bad)
    for where, why in bad:
        console.print(f"[red]failed[/red] {escape(f'{where}: {why}')}")
    if bad:
        raise typer.Exit(1)


def _build_all(
    bundles: list[Path],
    build: Callable[[Path], tuple[str, str]],
    catalogs: dict,
    catalog_of: dict[Path, Path],
    bad: list[tuple[str, str]],
) -> None:
    """Build every bundle, print the table, register each result in its catalog."""
    from asset_pipeline.catalog.registry import register_asset_dir
    from generator.articulated import ObjectModelError
    from generator.bundle import load_bundle

    table = Table(title="pact build")
    for col in ("asset", "status", "detail"):
        table.add_column(col)
    for b in bundles:
        try:
            status, detail = build(b)
        except Exception as e:  # one bad bundle never stops the batch
            logging.getLogger("pact.build").debug("build of %s failed", b, exc_info=True)
            status, detail = "failed", f"{type(e).__name__}: {e}"
        if status == "failed":
            bad.append((str(b), detail))
        colour = {"failed": "red", "repaired": "yellow"}.get(status, "green")
        table.add_row(escape(str(b)), f"[{colour}]{status}[/{colour}]", escape(detail))
        root = catalog_of.get(b)
        if root is not None:
            try:
                provenance = load_bundle(b).provenance
            except ObjectModelError:  # the failure above names the file
                provenance = {}
            origin = dict(
                source_image=provenance.get("source") or provenance.get("source_image"),
                generator=provenance.get("importer") or provenance.get("generator"),
            )
            if (b / "asset.json").is_file():
                register_asset_dir(catalogs[root], b, **origin)
            else:
                catalogs[root].record_failure(b.name, detail, **origin)
    wide_console().print(table)


@app.command("validate")
@reports_errors
def validate_cmd(
    paths: list[Path] = typer.Argument(..., help="Built asset folders, or folders of them."),
    repair: bool = typer.Option(True, "--repair/--no-repair", help="Repair what can be repaired."),
    preview: bool = typer.Option(True, "--preview/--no-preview", help="Render preview.png."),
    max_rounds: int = typer.Option(3, help="Repair rounds, each followed by a full re-check."),
    engines: str = typer.Option(
        "sapien",
        help="Engines to run the behaviour checks in besides validation (sapien: the URDF, "
        "mujoco: the MJCF, usd: the USD in Newton on CPU), e.g. sapien,mujoco,usd; each "
        "engine's verdict per check and part goes into report.json's 'engines' "
        "(docs/validation.md). sapien alone (the default) adds nothing.",
    ),
) -> None:
    """Check built assets in SAPIEN, repair, write report.json; exit 1 if any fails."""
    from asset_pipeline.validate import validate_asset
    from asset_pipeline.validate.engines import ENGINES

    engine_list = [e.strip() for e in engines.split(",") if e.strip()]
    unknown = [e for e in engine_list if e not in ENGINES]
    if unknown:
        raise fail(f"unknown engine(s) {unknown}; engines: {', '.join(ENGINES)}")
    extra_engines = engine_list if engine_list != ["sapien"] else []

    assets: list[Path] = []
    for p in paths:
        if (p / "model.urdf").is_file():
            assets.append(p)
        elif p.is_dir():
            assets.extend(sorted(d for d in p.iterdir() if (d / "model.urdf").is_file()))
    if not assets:
        raise fail("no built asset (model.urdf) under " + ", ".join(map(str, paths)))
    table = Table(title="pact validate")
    for col in ("asset", "status", "rounds", "repairs", "failed checks (value / tolerance)"):
        table.add_column(col)
    for e in extra_engines:
        table.add_column(e)
    failed = 0
    for a in assets:
        try:
            report = validate_asset(
                a, repair=repair, preview=preview, max_rounds=max_rounds, engines=extra_engines
            )
        except Exception as e:  # a broken asset never stops the batch
            failed += 1
            table.add_row(
                escape(str(a)),
                "[red]failed[/red]",
                "-",
                "-",
                escape(f"{type(e).__name__}: {e}"),
                *["-"] * len(extra_engines),
            )
            continue
        failed += report.status == "failed"
        colour = {"failed": "red", "repaired": "yellow"}.get(report.status, "green")
        fails = "; ".join(
            f"{c.key} ({c.value} / {c.tolerance})" for c in report.failed_checks[:5]
        ) or ", ".join(report.reasons[:3])
        table.add_row(
            escape(str(a)),
            f"[{colour}]{report.status}[/{colour}]",
            str(len(report.rounds)),
            ", ".join(r.kind for r in report.repairs) or "-",
            escape(fails),
            *[engine_verdict(report.engines, e) for e in extra_engines],
        )
    wide_console().print(table)
    if failed:
        raise typer.Exit(1)


def engine_verdict(section: dict | None, engine: str) -> str:
    """One engine's verdict for the validate table: passed, or its failed checks."""
    result = (section or {}).get(engine)
    if result is None:
        return "-"
    if result.get("error"):
        return f"[red]error[/red] {escape(result['error'][:60])}"
    bad = [c for c in result["checks"] if not c.passed]
    if not bad:
        return f"[green]passed[/green] ({len(result['checks'])})"
    return "[red]failed[/red] " + escape(", ".join(c.key for c in bad[:3]))


@app.command("export")
@reports_errors
def export_cmd(
    paths: list[Path] = typer.Argument(..., help="Built asset folders, or folders of them."),
    format: str = typer.Option("usd", "--format", help="The format to write: usd or mjcf."),
) -> None:
    """Write another model file for assets built before (model.usdc for --format usd),
    reading each asset with load_asset; the files it has are left as they are."""
    import time

    from asset_pipeline.assets.folder import FORMAT_FILES, asset_folders, load_asset
    from asset_pipeline.assets.layout import AssetFormatError

    if format not in ("usd", "mjcf"):
        raise fail(f"--format must be usd or mjcf, not {format!r}")
    assets = asset_folders(paths)
    if not assets:
        raise fail("no built asset (model.urdf) under " + ", ".join(map(str, paths)))
    table = Table(title=f"pact export --format {format}")
    for col in ("asset", "file", "seconds"):
        table.add_column(col)
    bad = 0
    for a in assets:
        t = time.perf_counter()
        try:
            asset = load_asset(a, metadata=(a / "asset.json").is_file())
            if format == "usd":
                from asset_pipeline.assets.usd import write_usd

                path = write_usd(asset, a)
            else:
                from asset_pipeline.assets.mjcf import mjcf_string
                from generator.atomic_files import atomic_write_bytes

                path = a / FORMAT_FILES["mjcf"]
                atomic_write_bytes(path, mjcf_string(asset).encode())
        except (AssetFormatError, OSError, ValueError) as e:
            bad += 1
            table.add_row(escape(str(a)), f"[red]failed[/red] {escape(str(e))}", "-")
            continue
        table.add_row(escape(str(a)), escape(path.name), f"{time.perf_counter() - t:.2f}")
    wide_console().print(table)
    if bad:
        raise typer.Exit(1)


@app.command("ls")
@reports_errors
def ls(
    out: Path = typer.Argument(..., help="Output folder with registry.sqlite (or the file)."),
    status: str = typer.Option(None, help="ok, repaired or failed."),
    category: str = typer.Option(None, help="Category filter."),
    joint_type: str = typer.Option(None, help="prismatic or revolute."),
    min_fidelity: float = typer.Option(
        None,
        "--min-fidelity",
        help="Only assets whose fidelity score (likeness to the photo, 0..1; "
        "docs/fidelity.md) is at least this; unscored assets are left out.",
    ),
) -> None:
    """List catalogued assets."""
    from asset_pipeline.catalog.registry import Catalog, CatalogError, format_table

    try:
        with Catalog(out, readonly=True) as cat:
            rows = cat.query(
                status=status,
                category=category,
                joint_type=joint_type,
                min_fidelity=min_fidelity,
            )
    except CatalogError as e:
        raise fail(e) from e
    wide_console().print(format_table(rows))


@app.command("import")
@reports_errors
def import_(
    path: Path = typer.Argument(
        ...,
        help="A PAct or SINGAPO output (object.json), a PartNet-Mobility object folder "
        "(mobility.urdf + textured_objs/), or a folder of them (searched recursively).",
    ),
    out: Path = typer.Option(..., "--out", "-o", help="Folder to write bundles into."),
    up: str = typer.Option("y", help="Up axis of the source meshes (y for SINGAPO/PAct)."),
    category: str = typer.Option(
        None, help="Category to record (overrides the source's, e.g. PartNet's model_cat)."
    ),
    overwrite: bool = typer.Option(False, help="Replace existing bundles."),
    height: float = typer.Option(
        None,
        "--height",
        help="Closed height in metres of PartNet-Mobility objects: sets the bundle's metric "
        "scale (default: the category's height, applied by pact build).",
    ),
    add_handles: bool = typer.Option(
        True,
        "--add-handles/--no-add-handles",
        help="Give a PartNet-Mobility door, drawer or lid with no handle (neither a handle "
        "node nor one on its mesh) an added bar grip; --no-add-handles keeps the artist's "
        "meshes untouched.",
    ),
) -> None:
    """Import PAct / SINGAPO outputs (diffuse_tree object.json) and PartNet-Mobility objects.

    Prints one bundle folder per line. A PartNet-Mobility object that cannot be read
    is reported (``failed PATH: what is wrong``) and the others go on; exit code 1 when
    some failed, 2 when nothing could be imported. Each added grip is reported
    (``grip PATH: part: ...``).
    """
    from asset_pipeline.importers import import_path
    from asset_pipeline.importers.diffuse_tree import ImportOptions
    from asset_pipeline.importers.partnet import GRIP_NOTE
    from asset_pipeline.importers.source_format import ImportFormatError

    if height is not None and not 0 < height <= 10:
        raise fail(f"--height: must be the object's height in metres, in (0, 10]; got {height}")
    try:
        written = import_path(
            path,
            out,
            ImportOptions(up=up, category=category, overwrite=overwrite),
            height=height,
            add_handles=add_handles,
        )
    except ImportFormatError as e:
        raise fail(e) from e
    for d in written:
        print(d)
    for w in getattr(written, "warnings", []):
        if GRIP_NOTE in w:
            console.print(f"[yellow]grip[/yellow] {escape(w)}")
    failures = getattr(written, "failures", [])
    for f in failures:
        where = "" if f.message.startswith(str(f.source)) else f"{f.source}: "
        console.print(f"[red]failed[/red] {escape(where + f.message)}")
    if failures:
        console.print(
            f"imported {len(written)} of {len(written) + len(failures)} objects; "
            f"{len(failures)} failed"
        )
        raise typer.Exit(1 if written else 2)


@app.command()
@reports_errors
def gallery(
    out: Path = typer.Argument(..., help="Output folder of a convert or build run."),
    serve: bool = typer.Option(
        False, "--serve", help="Then serve OUT over HTTP (its 3D views need it) until Ctrl-C."
    ),
    port: int = typer.Option(8000, help="Port of --serve (0: any free one)."),
    host: str = typer.Option("127.0.0.1", help="Interface of --serve (default: loopback)."),
) -> None:
    """Write OUT/index.html: photo, photo view, previews, fidelity, joints, validation status
    and a 3D view with joint sliders per asset."""
    from asset_pipeline.catalog.registry import CatalogError
    from asset_pipeline.gallery.page import write_gallery
    from asset_pipeline.gallery.server import gallery_server, serve_until_interrupted

    try:
        print(write_gallery(out))
        server = gallery_server(out, port, host) if serve else None
    except (FileNotFoundError, CatalogError, OSError) as e:
        raise fail(e) from e
    if server is None:
        return
    bound_host, bound_port = server.server_address[:2]
    console.print(f"serving {escape(str(out))} at http://{bound_host}:{bound_port}/ (Ctrl-C stops)")
    serve_until_interrupted(server)


@app.command("parse")
@reports_errors
def parse_photos(
    images: Path = typer.Argument(..., help="A folder of photos, or one photo."),
    segmenter: str = typer.Option(SEGMENTER_DEFAULT, help=SEGMENTER_HELP),
    sam2_checkpoint: Path = typer.Option(None, help=SAM2_CHECKPOINT_HELP),
    parser_weights: str = typer.Option("shipped", help=PARSER_WEIGHTS_HELP),
    overwrite: bool = typer.Option(
        False, help="Replace the part masks that are there with the parser's."
    ),
) -> None:
    """Write the photo parser's part masks and hints beside the photos, for a person to check.

    For each photo: without a part mask, <name>.mask.png (0 background, 1 base, 2.. parts)
    and <name>.json with the category and each part's motion; with one, the category and
    the motions its hints lack. The hints' 'parsed' record names what the parser wrote and
    its confidence (pact convert reports those fields as the parser's); keys already in
    the hints are kept. Then check them (the gallery's mask editor, or any editor) and run
    pact convert.
    """
    from asset_pipeline.catalog.batch import ConvertSettings, load_parser, load_segmenter
    from asset_pipeline.inputs.errors import InputError
    from asset_pipeline.inputs.folder import discover_inputs, load_input
    from asset_pipeline.inputs.parsing import write_parsed

    settings = ConvertSettings(
        segmenter=check_segmenter(segmenter, sam2_checkpoint),
        sam2_checkpoint=None if sam2_checkpoint is None else str(sam2_checkpoint),
        parser_weights=check_parser_weights(parser_weights),
    )
    try:
        listing = discover_inputs(images)
    except InputError as e:
        raise fail(str(e)) from e
    parser, seg = load_parser(settings.parser_weights), load_segmenter(settings)
    table = Table(title="pact parse")
    for col in ("photo", "category", "parts (motion confidence)", "wrote"):
        table.add_column(col)
    bad = []
    for item in listing:
        try:
            written = write_parsed(load_input(item), parser, seg, overwrite=overwrite)
        except InputError as e:
            bad.append(str(e))
            table.add_row(escape(item.name), "-", "-", f"[red]failed[/red]: {escape(str(e))}")
            continue
        s = written.sources
        cat = s.to_json()["category"]
        parts = ", ".join(
            f"{k} {m}" + (f" {src.confidence:.2f}" if src.confidence is not None else " (user)")
            for k, (m, src) in sorted(s.parts.items())
        )
        wrote = ", ".join(p.name for p in (written.mask, written.hints) if p is not None) or "-"
        label = cat.get("source", "none")
        if "confidence" in cat:
            label += f" {cat['confidence']:.2f}"
        table.add_row(escape(item.name), escape(f"{label}"), escape(parts or "-"), escape(wrote))
    wide_console().print(table)
    if bad:
        raise typer.Exit(1)


@app.command()
@reports_errors
def convert(
    images: Path = typer.Argument(..., help="Folder of images (+ .mask.png, + .json hints)."),
    out: Path = typer.Option(
        ..., "--out", "-o", help="Output folder: OUT/<id>/ and OUT/registry.sqlite."
    ),
    generator: str = typer.Option(
        "pact",
        help="pact (default: the PAct network, docs/model-card.md) or retrieval (the nearest "
        "procedural object, the baseline).",
    ),
    workers: int = typer.Option(1, min=1, help="Local worker processes."),
    executor: str = typer.Option("local", help="local (process pool) or ray."),
    ray_address: str = typer.Option(None, help="Ray cluster address (with --executor ray)."),
    force: bool = typer.Option(
        False, help="Redo items already converted with the same input and settings."
    ),
    validate: bool = typer.Option(
        True, "--validate/--no-validate", help="Validate and repair in SAPIEN."
    ),
    preview: bool = typer.Option(
        True, "--preview/--no-preview", help="Render preview.png per asset."
    ),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar or table."),
    log_json: Path = typer.Option(
        None, help="Append one JSON line per item to this file ('-' = stdout)."
    ),
    collision: str = typer.Option(
        "auto",
        help="auto (a generated object's box layout), mesh (articulation-aware boxes cut "
        "from the generated part meshes) or coacd.",
    ),
    texture: bool = typer.Option(
        True,
        "--texture/--no-texture",
        help="Bake the photo into the asset's textures (from the photo's estimated camera).",
    ),
    fidelity: bool = typer.Option(
        True,
        "--fidelity/--no-fidelity",
        help="Render the asset from the photo's camera and score its likeness to the photo "
        "(report.json, pact ls; needs --validate).",
    ),
    visual_faces: int = typer.Option(
        DEFAULT_VISUAL_FACES, min=0, help=VISUAL_FACES_HELP, show_default=True
    ),
    keep_intermediate: bool = typer.Option(
        False,
        "--keep-intermediate",
        help="Keep the generator's bundle (object.json, parts/) in each asset folder, for "
        "`pact build` to rebuild it.",
    ),
    parse: bool = typer.Option(
        True,
        "--parser/--no-parser",
        help="Read what a photo lacks (part mask, category, each part's motion) with the "
        "photo parser; what the mask and hints files give always wins.",
    ),
    segmenter: str = typer.Option(SEGMENTER_DEFAULT, help=SEGMENTER_HELP),
    sam2_checkpoint: Path = typer.Option(None, help=SAM2_CHECKPOINT_HELP),
    parser_weights: str = typer.Option("shipped", help=PARSER_WEIGHTS_HELP),
    formats: str = typer.Option(FORMATS_DEFAULT, help=FORMATS_HELP, show_default=True),
) -> None:
    """Convert an image folder into validated, catalogued sim assets (resumable)."""
    import json
    import sys

    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from asset_pipeline.catalog.batch import (
        ConvertSettings,
        OutputFolderError,
        OutputLockedError,
        run_convert,
    )
    from asset_pipeline.catalog.registry import CatalogError
    from asset_pipeline.inputs.errors import InputError

    check_collision(collision)
    settings = ConvertSettings(
        generator=generator,
        validate=validate,
        preview=preview,
        collision=COLLISION_OPTIONS.get(collision, collision),
        texture=texture,
        fidelity=fidelity,
        visual_faces=visual_faces,
        keep_intermediate=keep_intermediate,
        parse=parse,
        segmenter=check_segmenter(segmenter, sam2_checkpoint),
        sam2_checkpoint=None if sam2_checkpoint is None else str(sam2_checkpoint.resolve()),
        parser_weights=check_parser_weights(parser_weights) if parse else None,
        formats=check_formats_option(formats),
    )
    if parse and settings.segmenter == "sam2":  # a SAM2 that cannot load stops the run
        from asset_pipeline.catalog.batch import load_segmenter

        try:
            load_segmenter(settings)
        except (ImportError, ValueError, OSError) as e:
            raise fail(str(e)) from e
    log_file = None
    if log_json is not None and str(log_json) != "-":
        try:
            log_file = open(log_json, "a")  # noqa: SIM115
        except OSError as e:
            raise fail(f"{log_json}: cannot open the log: {e.strerror}") from e
    elif log_json is not None:
        log_file = sys.stdout
    progress = Progress(
        TextColumn("[bold]convert"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("{task.description}"),
        console=console,
        disable=quiet,
    )
    task = progress.add_task("", total=None)
    running: dict[str, str] = {}

    def on_start(n_todo: int, n_skipped: int) -> None:
        progress.update(task, total=n_todo)
        if n_skipped and not quiet:
            console.print(f"skipping {n_skipped} item(s) already converted (use --force to redo)")

    def on_stage(name: str, stage: str) -> None:
        running[name] = stage
        progress.update(
            task, description=" ".join(f"{n}:{s}" for n, s in list(running.items())[-3:])
        )

    def on_result(r) -> None:  # noqa: ANN001
        running.pop(r.name, None)
        progress.advance(task)
        if log_file is not None:
            log_file.write(json.dumps({"event": "item", **r.__dict__}) + "\n")
            log_file.flush()

    try:
        with progress:
            summary = run_convert(
                images,
                out,
                settings,
                workers=workers,
                executor=executor,
                ray_address=ray_address,
                force=force,
                on_start=on_start,
                on_stage=on_stage,
                on_result=on_result,
            )
    except (
        InputError,
        OutputFolderError,
        OutputLockedError,
        CatalogError,
        ValueError,
        OSError,  # a file the run could not read or write: "PATH: what the system says"
    ) as e:
        raise fail(e) from e
    finally:
        if log_file is not None and log_file is not sys.stdout:
            log_file.close()
    if not quiet:
        for note in summary.reconciled:
            console.print(f"[yellow]catalog:[/yellow] {escape(note)}")
        if summary.ignored:
            console.print(f"ignored {len(summary.ignored)} file(s) that are not photos:")
            for f in summary.ignored:
                console.print(f"  {escape(f'{f.path}: {f.reason}')}")
        table = Table(title=f"pact convert -> {out}")
        for col in ("id", "status", "category", "seconds", "reason"):
            table.add_column(col)
        for r in summary.results:
            colour = {"failed": "red", "repaired": "yellow"}.get(r.status, "green")
            note = "; ".join(x for x in (r.reason, r.id_note, *r.warnings) if x)
            table.add_row(
                escape(r.id),
                f"[{colour}]{r.status}[/{colour}]",
                r.category,
                f"{sum(r.stage_seconds.values()):.1f}",
                escape(note),
            )
        Console(stderr=True).print(table)
        console.print(
            f"{len(summary.results) - len(summary.failed)} converted, {len(summary.failed)} failed, "
            f"{len(summary.skipped)} skipped, {len(summary.ignored)} ignored files; "
            f"catalog {out / 'registry.sqlite'}; gallery: pact gallery {out}"
        )
    if summary.failed:
        raise typer.Exit(1)


# --------------------------------------------------------------------------- tasks (thin entry points)


@app.command("check-tasks")
@reports_errors
def check_tasks_cmd(
    path: Path = typer.Argument(..., help="Folder of built assets, one asset or a catalog file."),
    category: str = typer.Option(None, help="Category filter."),
    seed: int = typer.Option(0, help="Seed of the episode resets."),
    out: Path = typer.Option(None, help="Write the per-part results as JSON here."),
    fixed_base: bool = typer.Option(
        False,
        "--fixed-base",
        help="Never move the robot's base to another stand (a fixed Panda, as in the RL tasks).",
    ),
) -> None:
    """Can a robot really open each part? Runs the scripted solver on every movable part."""
    import json
    from dataclasses import asdict

    from tasks.solver import SolverConfig, check_tasks, summarize

    config = SolverConfig(restand=not fixed_base)
    results = check_tasks(path, seed=seed, category=category, config=config)
    if not results:
        console.print(
            f"[red]{path}: no movable parts to check[/red] (no built assets there, none of "
            "the category, or every asset's report.json says it failed validation: "
            "those are skipped)"
        )
        raise typer.Exit(1)
    table = Table(title="pact check-tasks")
    for col in ("asset", "part", "task", "opened", "fraction", "stands", "seconds", "reason"):
        table.add_column(col)
    for r in results:
        ok = "[green]yes[/green]" if r.success else "[red]no[/red]"
        table.add_row(
            escape(r.asset_id),
            r.part,
            r.env_id,
            ok,
            f"{r.final_fraction:.2f}",
            str(1 + r.stands),
            f"{r.seconds:.1f}",
            escape(r.reason),
        )
    wide_console().print(table)
    summary = summarize(results)
    console.print(
        f"opened {summary['opened']} of {summary['parts']} parts ({summary['rate']:.0%}; "
        f"{summary['opened_where_placed']} without moving the robot's base)"
    )
    if out is not None:
        from generator.atomic_files import atomic_write_bytes

        atomic_write_bytes(
            out, json.dumps({**summary, "results": [asdict(r) for r in results]}, indent=2).encode()
        )
    if summary["opened"] < summary["parts"]:
        raise typer.Exit(1)


@app.command()
@reports_errors
def train(
    task: str = typer.Option("OpenDrawer-v0", "--task", help="Registered task id."),
    assets: str = typer.Option(..., "--assets", help="Folder of built assets or catalog file."),
    steps: int = typer.Option(200_000, "--steps", help="Environment steps."),
    eval_assets: str = typer.Option(None, help="Held-out assets for periodic evaluation."),
    category: str = typer.Option(None, help="Only assets of this category."),
    num_envs: int = typer.Option(4, help="Parallel envs (processes with --vector async)."),
    vector: str = typer.Option("async", help="CPU: async (a process per env) or sync."),
    control_mode: str = typer.Option(
        "pd_ee_delta_pos", help="pd_ee_delta_pos, pd_ee_delta_pose or pd_joint_delta_pos."
    ),
    minutes: float = typer.Option(None, help="Stop after this wall-clock (then save)."),
    episode_steps: int = typer.Option(
        None, help="Training episode length (default: the recipe's)."
    ),
    eval_every: int = typer.Option(20_000, help="Env steps between held-out evaluations."),
    eval_episodes: int = typer.Option(10, help="Episodes per periodic evaluation."),
    video_episodes: int = typer.Option(2, help="Held-out episodes recorded at the end."),
    resume: bool = typer.Option(False, "--resume", help="Go on from OUT/checkpoint."),
    lr_anneal_steps: int = typer.Option(
        600_000,
        help="Steps at which the learning rate has decayed to 0 (0: constant); "
        "match it to what --minutes reaches.",
    ),
    randomize_physics: bool = typer.Option(
        False,
        "--randomize-physics",
        help="Scale each training object's part masses, damping and friction at every load.",
    ),
    demo_episodes: int = typer.Option(
        0,
        help="Opening tasks: first clone the scripted teacher's successful episodes on the "
        "training assets (this many episodes; 0: PPO from scratch).",
    ),
    demos_from: Path = typer.Option(
        None,
        help="A run's teacher_demos.npz: clone those steps instead of running the teacher "
        "(other clone settings on the same episodes).",
    ),
    dagger_rounds: int = typer.Option(
        0,
        help="With --demo-episodes: rounds of DAgger after the first clone (the clone's own "
        "episodes, labelled by the teacher, added to what it is fitted to).",
    ),
    dagger_episodes: int = typer.Option(200, help="The clone's episodes per DAgger round."),
    clone_members: int = typer.Option(
        1,
        help="With --demo-episodes or --demos-from: clones fitted from different initial "
        "weights, averaged in one policy (its MLP that many times as wide).",
    ),
    bc_obs_noise: float = typer.Option(
        0.0, help="Gaussian noise on the normalized observations while cloning (std)."
    ),
    learning_rate: float = typer.Option(3e-4, help="PPO's initial learning rate."),
    n_steps: int = typer.Option(
        128, help="PPO's rollout length per env between updates, in policy steps."
    ),
    batch_size: int = typer.Option(256, help="PPO's minibatch size, in transitions."),
    anchor_batches: int = typer.Option(
        0,
        help="With --demo-episodes: minibatches of behaviour cloning on the teacher's steps "
        "between PPO's updates, so that PPO keeps the clone's grasps (0: none).",
    ),
    update_obs_norm: bool = typer.Option(
        True,
        "--update-obs-norm/--fixed-obs-norm",
        help="Update the observation normalization from PPO's rollouts, or keep the "
        "statistics it starts with (with --demo-episodes: the teacher's, so that the "
        "clone's inputs do not drift).",
    ),
    critic_warmup_steps: int = typer.Option(
        0, help="Env steps at the start of PPO that train only the value function."
    ),
    log_std_init: float = typer.Option(
        -2.0,
        help="Initial log standard deviation of PPO's action noise, in the action's -1..1 "
        "units (-2.0: 1.4 cm a step in pd_ee_delta_pos).",
    ),
    robot_frame_obs: bool = typer.Option(
        True,
        "--robot-frame-obs/--no-robot-frame-obs",
        help="Also observe the hand-to-handle vector, the joint axis and a door's "
        "hinge-to-handle vector along the robot base's axes (docs/tasks.md).",
    ),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Progress bar."),
    sim_backend: str = typer.Option("physx_cpu", help="physx_cpu or physx_cuda."),
    out: str = typer.Option(
        "runs/ppo",
        help="Run folder: policy.zip, curve.png, eval.csv, progress.csv, videos/, checkpoint/.",
    ),
    seed: int = typer.Option(0),
) -> None:
    """Train a PPO policy (stable-baselines3) on a drawer/door task: resumable (--resume),
    the held-out curve as eval.csv and curve.png, videos of held-out episodes at the end."""
    from tasks.train import Args, TrainingStopped, recipe_episode_steps
    from tasks.train import train as run_training

    args = Args(
        env_id=task,
        assets=assets,
        total_timesteps=steps,
        eval_assets=eval_assets,
        category=category,
        num_envs=num_envs,
        vector=vector,
        control_mode=control_mode,
        max_minutes=minutes,
        max_episode_steps=episode_steps or recipe_episode_steps(task),
        eval_every=eval_every,
        eval_episodes=eval_episodes,
        video_episodes=video_episodes,
        resume=resume,
        lr_anneal_steps=lr_anneal_steps or None,
        randomize_physics=randomize_physics,
        demo_episodes=demo_episodes,
        demos_from=str(demos_from) if demos_from else None,
        dagger_rounds=dagger_rounds,
        dagger_episodes=dagger_episodes,
        clone_members=clone_members,
        bc_obs_noise=bc_obs_noise,
        learning_rate=learning_rate,
        n_steps=n_steps,
        batch_size=batch_size,
        log_std_init=log_std_init,
        anchor_batches=anchor_batches,
        critic_warmup_steps=critic_warmup_steps,
        update_obs_norm=update_obs_norm,
        robot_frame_obs=robot_frame_obs,
        progress_bar=progress,
        sim_backend=sim_backend,
        out_dir=out,
        seed=seed,
    )
    try:
        summary = run_training(args)
    except TrainingStopped as stop:  # the exit status of a process a signal ended
        raise fail(stop, code=128 + stop.signum) from None
    console.print(summary)


@app.command("eval-policy")
@reports_errors
def eval_policy(
    policy: Path = typer.Argument(..., help="policy.zip written by pact train."),
    task: str = typer.Option("OpenDrawer-v0", "--task"),
    assets: str = typer.Option(..., "--assets", help="Held-out assets (folder or catalog)."),
    episodes: int = typer.Option(50, help="Episodes (each samples an asset and a part)."),
    category: str = typer.Option(None, help="Only assets of this category."),
    seed: int = typer.Option(10_000, help="Episode k is seeded SEED + k."),
    video_dir: Path = typer.Option(None, help="Record one video per episode here."),
    out: Path = typer.Option(None, help="Write the result (every episode) as JSON here."),
) -> None:
    """Success of a trained policy on held-out assets, per category and part kind; for
    the failures, how far the part opened."""
    import json

    from rich.table import Table

    from tasks.train import evaluate

    if not policy.is_file():
        raise fail(f"{policy}: no such policy file (pact train writes OUT/policy.zip)")
    result = evaluate(
        str(policy), task, assets, episodes=episodes, seed=seed, video_dir=video_dir,
        category=category,
    )  # fmt: skip
    for key, rows in (("category", result["by_category"]), ("part kind", result["by_part_kind"])):
        table = Table(title=f"{task}: success per {key}")
        for col in (key, "episodes", "opened", "rate", "failures opened (mean fraction)"):
            table.add_column(col)
        for name, r in rows.items():
            failed = r["failed_open_fraction"]
            table.add_row(
                name, str(r["episodes"]), str(r["success"]), f"{r['success_rate']:.0%}",
                "-" if failed is None else f"{failed:.2f}",
            )  # fmt: skip
        wide_console().print(table)
    console.print(
        f"success {result['success_rate']:.0%} of {episodes} episodes "
        f"(grasped in {result['grasp_rate']:.0%}), mean return {result['mean_return']:.2f}"
    )
    if out is not None:
        from generator.atomic_files import atomic_write_bytes

        atomic_write_bytes(out, json.dumps(result, indent=2).encode())


@app.command("train-gen")
@reports_errors
def train_gen(
    stage: int = typer.Option(1, "--stage", min=1, max=2, help="PAct stage to train (1 or 2)."),
    data: Path = typer.Option(..., "--data", help="Dataset folder (pact dataset build)."),
    config: str = typer.Option(
        "small", "--config", help="small, full or a config JSON path (stage 2: stage2_small, ...)."
    ),
    what: str = typer.Option(
        "flow", help="Stage 2 only: cache, vae, flow, eval-vae or head-stage1 (see docs/pact.md)."
    ),
    part: str = typer.Option("all", help="Stage 1 only: vae, flow or all."),
    out: Path = typer.Option(
        None,
        help="Run / checkpoint folder (default: runs/pact/stage1, runs/pact/stage2/weights).",
    ),
    cache: Path = typer.Option(
        Path("runs/pact/slat_cache"), help="Stage 2: the token cache (written by --what cache)."
    ),
    resume: bool = typer.Option(
        True, "--resume/--no-resume", help="Continue from the run's checkpoint."
    ),
    minutes: float = typer.Option(None, help="Stop (with a checkpoint) after this wall-clock."),
    steps: int = typer.Option(None, help="Optimiser steps (stage 1: the schedule's length)."),
    threads: int = typer.Option(None, help="torch threads (1 on a shared 2-core machine)."),
    write_shipped_weights: bool = typer.Option(
        False,
        help="Allow --out or --cache inside generator/pact/weights/ (overwrites the shipped "
        "model).",
    ),
) -> None:
    """Train the PAct generator: stage 1 (sparse-structure VAE, then the part-aware flow) or
    stage 2 (structured-latent VAE, then the stage-2 flow with the articulation head).

    Never writes into generator/pact/weights/ (any folder it writes: --out, the stage-2
    --cache) unless --write-shipped-weights is given.
    Stage 1 runs data-parallel under torchrun (one process per GPU or node); see docs/pact.md.
    """
    from generator.pact.model.checkpoint import check_output_dir

    if stage == 2:
        from generator.pact.training.train_stage2 import check_written_folders, parse_args
        from generator.pact.training.train_stage2 import main as train_stage2

        argv = [what, "--data", str(data), "--cache", str(cache)]
        argv += ["--out", str(out or "runs/pact/stage2/weights")]
        argv += ["--config", f"stage2_{config}" if config in ("small", "full") else config]
        if resume:
            argv.append("--resume")
        if minutes is not None:
            argv += ["--minutes", str(minutes)]
        if steps is not None:
            argv += ["--steps", str(steps)]
        if threads is not None:
            argv += ["--threads", str(threads)]
        if write_shipped_weights:
            argv.append("--write-shipped-weights")
        try:
            check_written_folders(parse_args(argv))
        except ValueError as e:
            raise fail(e) from e
        train_stage2(argv)
        return
    from generator.pact.training.train_stage1 import train_stage1

    out = out or Path("runs/pact/stage1")
    try:
        check_output_dir(out, write_shipped_weights)
    except ValueError as e:
        raise fail(e) from e
    run = train_stage1(
        data_dir=data,
        out_dir=out,
        config=config,
        part=part,
        steps=steps,
        resume=resume,
        max_minutes=minutes,
        threads=threads,
        write_shipped_weights=write_shipped_weights,
    )
    console.print(f"checkpoints: {run.checkpoints}")


dataset_app = typer.Typer(
    help="Rendered procedural training data (docs/dataset.md).", no_args_is_help=True
)
app.add_typer(dataset_app, name="dataset")


@dataset_app.command("build")
@reports_errors
def dataset_build(
    n: int = typer.Option(
        ..., "--n", min=1, help="Number of objects (cycling through categories)."
    ),
    views: int = typer.Option(8, "--views", min=1, help="Rendered views per object."),
    out: Path = typer.Option(..., "--out", "-o", help="Dataset folder (manifest.json + shards)."),
    seed: int = typer.Option(0, "--seed", help="Object i uses seed + i."),
    split: str = typer.Option("train", help="train or test (held-out parameter ranges)."),
    resolution: int = typer.Option(32, help="Occupancy grid resolution R (32 small, 64 full)."),
    image_size: int = typer.Option(256, help="Rendered image size in pixels."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Render a deterministic, resumable dataset of procedural objects."""
    from generator.data import DatasetError, build_dataset

    try:
        manifest = build_dataset(
            out,
            n,
            views,
            seed,
            split=split,
            resolution=resolution,
            image_size=image_size,
            progress=not quiet,
        )
    except DatasetError as e:
        raise fail(e) from e
    print(manifest)


@dataset_app.command("parser")
@reports_errors
def dataset_parser(
    out: Path = typer.Option(..., "--out", "-o", help="Data folder (manifest.json + images/)."),
    objects: int = typer.Option(0, "--objects", min=0, help="Objects 0..N-1 of the plan."),
    bundles: list[Path] = typer.Option(
        [],
        "--bundle",
        help="Render this object bundle (e.g. an imported PartNet-Mobility object) instead "
        "of procedural objects; repeat for more.",
    ),
    views: int = typer.Option(4, "--views", min=1, help="Photos per object."),
    seed: int = typer.Option(0, "--seed", help="Dataset seed (objects, views, split)."),
    image_size: int = typer.Option(256, "--image-size", min=16, help="Photo size in pixels."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
) -> None:
    """Render the photo parser's training data: realistic procedural objects (or the
    given bundles) as photos with part masks and motion labels (docs/dataset.md, "Parser
    training data")."""
    from contextlib import nullcontext

    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    from generator.data.parser_data import (
        ParserDataError,
        write_parser_data,
        write_parser_data_from_bundles,
    )

    if bool(objects) == bool(bundles):
        raise fail("give either --objects N (procedural objects) or --bundle DIR (repeatable)")
    bar = Progress(BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), console=console)
    task = bar.add_task("objects", total=objects or len(bundles))
    shown = None if quiet else (lambda done, _n: bar.update(task, completed=done))
    try:
        with bar if not quiet else nullcontext():
            if bundles:
                manifest = write_parser_data_from_bundles(
                    out, bundles, views, seed, image_size, progress=shown
                )
            else:
                manifest = write_parser_data(out, objects, views, seed, image_size, progress=shown)
    except ParserDataError as e:
        raise fail(e) from e
    print(f"{out}: {len(manifest['items'])} images, {len(manifest['failed'])} failed objects")
    if manifest["failed"]:
        raise typer.Exit(1)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
