"""Import articulated objects made elsewhere as bundles of this project (``pact import``).

:func:`find_sources` finds every source under a path: ``diffuse_tree`` object.json
files (CAGE, SINGAPO, the official PAct release; :mod:`asset_pipeline.importers.diffuse_tree`)
and PartNet-Mobility folders (:mod:`asset_pipeline.importers.partnet`); :func:`import_path`
converts them into bundle folders.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from asset_pipeline.importers import partnet
from asset_pipeline.importers.diffuse_tree import ImportOptions, convert_tree, object_id, tree_of
from asset_pipeline.importers.source_format import ImportFormatError
from generator.bundle import is_bundle, save_bundle

log = logging.getLogger(__name__)


def find_sources(path: str | Path) -> list[Path]:
    """Every ``diffuse_tree`` object.json and PartNet-Mobility folder at or under ``path`` (sorted).

    ``path`` may be an object.json file, an object folder, or any folder above
    object folders (searched recursively). Bundles of this project are skipped.
    PartNet-Mobility objects (a folder holding ``mobility.urdf`` and
    ``textured_objs/``, see :mod:`asset_pipeline.importers.partnet`) are returned as their
    folders; ``path`` may also be one of them or its ``mobility.urdf``.
    """
    path = Path(path)
    if path.is_file() and path.name == partnet.URDF_NAME:
        path = path.parent
    if path.is_dir() and partnet.is_partnet_folder(path):
        return [path]
    partnet_dirs: list[Path] = []
    if path.is_file():
        candidates = [path]
    elif path.is_dir():
        if (path / "object.json").is_file():
            candidates = [path / "object.json"]
        else:
            partnet_dirs = partnet.find_objects(path)
            candidates = [
                c
                for c in sorted(path.rglob("*.json"))
                if not any(c.is_relative_to(d) for d in partnet_dirs)
            ]
    else:
        raise ImportFormatError(f"{path}: no such file or folder")
    found = []
    for c in candidates:
        if c.name.endswith(".mask.json") or c.name in ("asset.json", "report.json"):
            continue
        try:
            data = json.loads(c.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
            if path.is_file() or c.name == "object.json":
                raise ImportFormatError(f"{c}: not readable JSON: {e}") from None
            continue
        if tree_of(data) is not None:
            found.append(c)
        elif path.is_file() or c == path / "object.json":
            if isinstance(data, dict) and data.get("schema") == "pact.object":
                raise ImportFormatError(f"{c}: already a bundle of this project; nothing to import")
            raise ImportFormatError(
                f"{c}: no 'diffuse_tree' (or 'arti_tree') list; supported: CAGE/SINGAPO/PAct object.json"
            )
    found = sorted(found + partnet_dirs)
    if not found:
        raise ImportFormatError(
            f"{path}: no CAGE/SINGAPO/PAct object.json (with 'diffuse_tree') "
            "or PartNet-Mobility folder (mobility.urdf + textured_objs/) found"
        )
    return found


def import_path(
    path: str | Path,
    out: str | Path,
    options: ImportOptions | None = None,
    *,
    height: float | None = None,
    add_handles: bool = True,
) -> partnet.ImportResult:
    """Import every CAGE/SINGAPO/PAct or PartNet-Mobility object under ``path`` into ``out/<id>/``.

    Returns the bundle folders, in source order, as an
    :class:`~asset_pipeline.importers.partnet.ImportResult` (a list of paths whose
    ``failures`` lists the PartNet-Mobility objects that could not be imported). The
    id is the object folder's name (made filename-safe; a numeric suffix keeps ids
    unique). ``diffuse_tree`` sources are all-or-nothing: an existing bundle is an
    error unless ``options.overwrite``, and :class:`ImportFormatError` naming the
    file and field is raised on unsupported input before anything is written.
    PartNet-Mobility objects are converted by :mod:`asset_pipeline.importers.partnet`, one at a
    time: a bad one is recorded in ``failures`` and the others go on; ``height``
    (metres) sets their metric scale and ``add_handles=False`` keeps their meshes free
    of added grips (neither applies to ``diffuse_tree`` sources).
    """
    opts = options or ImportOptions()
    path, out = Path(path), Path(out)
    pn_opts = partnet.PartnetOptions(
        category=opts.category, height=height, overwrite=opts.overwrite, add_handles=add_handles
    )
    sources = find_sources(path)
    objects = {
        src: convert_tree(src, opts) for src in sources if not src.is_dir()
    }  # all-or-nothing
    if objects and height is not None:
        log.warning(
            "--height applies to PartNet-Mobility objects only; %d object.json source(s) "
            "keep the category default",
            len(objects),
        )
    written = partnet.ImportResult()
    used: set[str] = set()
    for src in sources:
        if src.is_dir():  # a PartNet-Mobility object folder
            res = partnet.import_objects([src], out, pn_opts, used=used)
            written.extend(res)
            written.failures.extend(res.failures)
            written.warnings.extend(res.warnings)
            written.seconds.update(res.seconds)
            continue
        obj = objects[src]
        base_id = object_id(src)
        oid, k = base_id, 1
        while oid in used:
            oid, k = f"{base_id}_{k}", k + 1
        used.add(oid)
        dest = out / oid
        if is_bundle(dest) and not opts.overwrite:
            raise ImportFormatError(
                f"{dest}: a bundle already exists; pass overwrite to replace it"
            )
        if dest.exists() and opts.overwrite:
            for old in (dest / "parts").glob("*.glb"):
                old.unlink()
        obj.provenance["id"] = oid
        save_bundle(obj, dest)
        log.info("imported %s -> %s (%d parts)", src, dest, len(obj.parts))
        written.warnings.extend(f"{src}: {w}" for w in obj.provenance.get("warnings", []))
        written.append(dest)
    return written
