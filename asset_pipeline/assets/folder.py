"""The built-asset folder: its file names, and loading and saving a whole asset.

A built asset folder (docs/architecture.md, "Built asset")::

    model.urdf                 links, joints, inertials, one <collision> per convex piece
    model.xml                  MJCF of the same model (written, never read)
    model.usdc                 OpenUSD stage with UsdPhysics of the same model (written,
                               never read; asset_pipeline.assets.usd)
    asset.json                 what URDF cannot say: category, semantics, materials,
                               colours, handles, bounds, metric scale (schema pact.asset v1)
    visual/<part>.glb, .obj    visual meshes (the OBJ for MJCF)
    collision/<part>_<k>.obj   convex pieces

:func:`save_asset` writes a :class:`~asset_pipeline.assets.built_asset.BuiltAsset` (and the
meshes it holds in memory) into a folder through the one writer of each format
(:mod:`asset_pipeline.urdf`, :mod:`asset_pipeline.mjcf`, :mod:`asset_pipeline.asset_json`,
:mod:`asset_pipeline.mesh_files`); :func:`load_asset` reads one back: the URDF, then
``asset.json``. Every file is written atomically; ``asset.json`` is removed first and
written last, so a folder whose ``asset.json`` exists holds a complete asset.

Reading is strict: a URDF that is not XML or not a ``<robot>``, a joint without a
parent, a number that is NaN or infinite anywhere, a mesh path that leaves the asset
folder (absolute, ``..``, a symlink out) or a malformed ``asset.json`` raise
:class:`AssetFormatError`, whose message names the file and every problem found.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from asset_pipeline.assets.asset_json import apply_metadata, asset_json_document, read_asset_json
from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.assets.layout import (
    ASSET_JSON_NAME,
    MESH_FOLDERS,
    MJCF_NAME,
    URDF_NAME,
    AssetFormatError,
)
from asset_pipeline.assets.mesh_files import obj_text, texture_image
from asset_pipeline.assets.mjcf import mjcf_string
from asset_pipeline.assets.urdf import read_urdf, urdf_string
from asset_pipeline.assets.usd import USD_NAME
from generator.atomic_files import atomic_write_bytes
from generator.bundle import mesh_to_glb

log = logging.getLogger(__name__)

#: The file formats a built asset can be written in, and their files. The URDF is always
#: written: it is what :func:`load_asset` reads back.
FORMATS = ("urdf", "mjcf", "usd")
FORMAT_FILES = {"urdf": URDF_NAME, "mjcf": MJCF_NAME, "usd": USD_NAME}


def check_formats(formats: str | tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """The formats of a ``--formats`` value (``"urdf,mjcf,usd"`` or a sequence), in
    :data:`FORMATS` order; raises ValueError naming an unknown one or a missing ``urdf``."""
    names = [
        f.strip().lower() for f in (formats.split(",") if isinstance(formats, str) else formats)
    ]
    unknown = [f for f in names if f and f not in FORMATS]
    if unknown:
        raise ValueError(f"unknown format(s) {unknown}; formats: {', '.join(FORMATS)}")
    if "urdf" not in names:
        raise ValueError("the formats must include urdf (load_asset and validation read it)")
    return tuple(f for f in FORMATS if f in names)


def formats_in(folder: str | Path) -> tuple[str, ...]:
    """The formats whose model file ``folder`` holds."""
    return tuple(f for f in FORMATS if (Path(folder) / FORMAT_FILES[f]).is_file())


def asset_folders(paths: list[str | Path] | list[Path]) -> list[Path]:
    """The built-asset folders (holding ``model.urdf``) among ``paths``: each path that is
    one, else the ones directly inside it, sorted."""
    out: list[Path] = []
    for p in map(Path, paths):
        if (p / URDF_NAME).is_file():
            out.append(p)
        elif p.is_dir():
            out += sorted(d for d in p.iterdir() if (d / URDF_NAME).is_file())
    return out


def load_asset(folder: str | Path, *, metadata: bool = True) -> BuiltAsset:
    """Read the built asset in ``folder`` (the URDF, then ``asset.json``).

    ``metadata=False`` reads a folder that has only a URDF (an asset made elsewhere):
    links then have no semantics and movable parts no handles. Raises
    :class:`AssetFormatError`; see the module docstring. Mesh files are not opened.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise AssetFormatError(folder, ["not a folder (a built asset is a folder)"])
    name, links, joints = read_urdf(folder / URDF_NAME)
    asset = BuiltAsset(id=name or folder.name, links=links, joints=joints, folder=folder)
    for link in asset.links:
        if asset.joint_of(link.name) is None:
            link.semantic = "base"
    meta = folder / ASSET_JSON_NAME
    if metadata or meta.is_file():
        apply_metadata(asset, read_asset_json(meta), meta)
    return asset


def missing_files(asset: BuiltAsset) -> list[str]:
    """Referenced files of ``asset`` (relative names) that do not exist, in link order."""
    out = []
    for link in asset.links:
        for name in [v.filename for v in link.visuals] + [p.filename for p in link.collisions]:
            if not asset.path_of(name).is_file():
                out.append(name)
    return out


# --------------------------------------------------------------------------- writing


def _write(path: Path, data: bytes | str) -> None:
    atomic_write_bytes(path, data.encode() if isinstance(data, str) else data)


def save_asset(
    asset: BuiltAsset, folder: str | Path | None = None, formats: tuple[str, ...] = FORMATS
) -> Path:
    """Write ``asset`` into ``folder`` (default: ``asset.folder``) and set ``asset.folder``.

    Meshes held in memory (``Visual.mesh``, ``CollisionPiece.mesh``) are written; files
    under ``visual/`` and ``collision/`` that the asset no longer references are
    removed; then ``model.urdf``, ``model.xml`` (format ``mjcf``), ``model.usdc``
    (format ``usd``: :func:`asset_pipeline.assets.usd.write_usd`) and, last,
    ``asset.json``. A model file of a format not asked for is removed (it would describe
    an older build). Raises OSError when a file cannot be written. Returns the folder.
    """
    formats = check_formats(formats)
    folder = Path(folder) if folder is not None else asset.folder
    if folder is None:
        raise ValueError(f"asset {asset.id!r}: no folder to save into")
    folder.mkdir(parents=True, exist_ok=True)
    (folder / ASSET_JSON_NAME).unlink(missing_ok=True)
    keep: set[Path] = set()
    for link in asset.links:
        for v in link.visuals:
            keep.update({folder / v.filename, folder / v.obj_filename})
            if v.mesh is not None:
                _write(folder / v.filename, mesh_to_glb(v.mesh))
                textured = texture_image(v.mesh)
                v.texture = None
                if textured is not None:
                    v.texture = Path(v.filename).with_suffix(".png").as_posix()
                    _write(folder / v.texture, textured[1])
                _write(
                    folder / v.obj_filename,
                    obj_text(v.mesh, None if textured is None else textured[0]),
                )
            if v.texture:
                keep.add(folder / v.texture)
        for piece in link.collisions:
            keep.add(folder / piece.filename)
            if piece.mesh is not None:
                _write(folder / piece.filename, obj_text(piece.mesh))
    for sub in MESH_FOLDERS:
        for old in sorted((folder / sub).glob("*")) if (folder / sub).is_dir() else []:
            if old.is_file() and old not in keep and old.suffix in (".obj", ".glb", ".png"):
                log.debug("removing stale %s", old)
                old.unlink()
    _write(folder / URDF_NAME, urdf_string(asset))
    if "mjcf" in formats:
        _write(folder / MJCF_NAME, mjcf_string(asset))
    if "usd" in formats:
        from asset_pipeline.assets.usd import write_usd

        write_usd(asset, folder)
    for fmt in FORMATS:
        if fmt not in formats:
            (folder / FORMAT_FILES[fmt]).unlink(missing_ok=True)
    _write(folder / ASSET_JSON_NAME, json.dumps(asset_json_document(asset), indent=2) + "\n")
    asset.folder = folder
    return folder
