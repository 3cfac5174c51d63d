"""The bundle file format: an :class:`~generator.articulated.ArticulatedObject` on disk as
``object.json`` beside ``parts/<name>.glb`` (docs/architecture.md). One reader
(:func:`load_bundle`) and one writer (:func:`save_bundle`); they round-trip exactly
(vertex positions are stored as float32 in glTF, so the model keeps them
float32-representable).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import trimesh

from generator.articulated import (
    SCHEMA,
    SCHEMA_VERSION,
    ArticulatedObject,
    Handle,
    Joint,
    ObjectModelError,
    Part,
    Primitive,
)
from generator.atomic_files import atomic_write_bytes


def mesh_to_glb(mesh: trimesh.Trimesh) -> bytes:
    return trimesh.Scene(mesh).export(file_type="glb")


def mesh_from_glb(data: bytes | Path, source: str = "<glb>") -> trimesh.Trimesh:
    """Load one triangle mesh from glTF binary, keeping its visuals and vertex order."""
    try:
        if isinstance(data, (str, Path)):
            loaded = trimesh.load(str(data), file_type="glb", process=False)
        else:
            loaded = trimesh.load(trimesh.util.wrap_as_stream(data), file_type="glb", process=False)
    except Exception as e:  # trimesh raises many types on corrupt input
        raise ObjectModelError(f"{source}: cannot read glTF mesh: {e}") from e
    if isinstance(loaded, trimesh.Scene):
        geoms = list(loaded.dump()) if loaded.graph.nodes_geometry else []
        if not geoms:
            raise ObjectModelError(f"{source}: glTF file holds no mesh")
        loaded = geoms[0] if len(geoms) == 1 else trimesh.util.concatenate(geoms)
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise ObjectModelError(f"{source}: glTF file holds no triangle mesh")
    return loaded


def save_bundle(obj: ArticulatedObject, directory: str | Path) -> Path:
    """Write ``obj`` as a bundle (``object.json`` + ``parts/<name>.glb``); return the folder.

    Part meshes are written first and ``object.json`` last, each atomically, so a
    folder with an ``object.json`` always has all of its parts.
    """
    directory = Path(directory)
    obj.validate(str(directory / "object.json"))
    for p in obj.parts:
        atomic_write_bytes(directory / "parts" / f"{p.name}.glb", mesh_to_glb(p.mesh))
    text = json.dumps(obj.to_json(), indent=2)
    atomic_write_bytes(directory / "object.json", text.encode())
    return directory


def _need(d: dict[str, Any], key: str, where: str, source: str) -> Any:
    if key not in d:
        raise ObjectModelError(f"{source}: {where}: missing field {key!r}")
    return d[key]


def load_bundle(directory: str | Path) -> ArticulatedObject:
    """Load a bundle folder; every error names the file and the field at fault."""
    directory = Path(directory)
    src = directory / "object.json"
    if not src.is_file():
        raise ObjectModelError(f"{src}: not found (a bundle folder holds object.json and parts/)")
    try:
        d = json.loads(src.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ObjectModelError(f"{src}: not valid JSON: {e}") from e
    if not isinstance(d, dict):
        raise ObjectModelError(f"{src}: top level must be a JSON object")
    if d.get("schema") != SCHEMA:
        raise ObjectModelError(f"{src}: schema: expected {SCHEMA!r}, got {d.get('schema')!r}")
    version = d.get("version")
    if version != SCHEMA_VERSION:
        raise ObjectModelError(
            f"{src}: version: this code reads version {SCHEMA_VERSION}, file has {version!r}"
        )
    raw_parts = _need(d, "parts", "object", str(src))
    if not isinstance(raw_parts, list):
        raise ObjectModelError(f"{src}: parts: must be a list")
    parts = []
    for i, pd in enumerate(raw_parts):
        where = f"parts[{i}]"
        if not isinstance(pd, dict):
            raise ObjectModelError(f"{src}: {where}: must be an object")
        name = _need(pd, "name", where, str(src))
        mesh_rel = pd.get("mesh", f"parts/{name}.glb")
        mesh_path = directory / mesh_rel
        if not mesh_path.is_file():
            raise ObjectModelError(f"{src}: {where}.mesh: part mesh {mesh_path} not found")
        try:
            joint = None if pd.get("joint") is None else Joint.from_json(pd["joint"])
            handle = None if pd.get("handle") is None else Handle.from_json(pd["handle"])
            prims = [Primitive.from_json(q) for q in pd.get("primitives", [])]
        except (KeyError, TypeError, ValueError) as e:
            raise ObjectModelError(
                f"{src}: {where} ({name}): malformed joint/handle/primitive: {e}"
            ) from e
        parts.append(
            Part(
                name=name,
                semantic=pd.get("semantic", "base" if joint is None else "part"),
                mesh=mesh_from_glb(mesh_path, source=str(mesh_path)),
                joint=joint,
                primitives=prims,
                handle=handle,
                material=pd.get("material", "wood"),
            )
        )
    obj = ArticulatedObject(
        parts=parts,
        category=d.get("category", "unknown"),
        scale=d.get("scale", 1.0),
        provenance=d.get("provenance", {}),
    )
    obj.validate(str(src))
    return obj


def remove_bundle(directory: str | Path) -> None:
    """Remove the bundle files of ``directory`` (``object.json`` first, then ``parts/``),
    leaving whatever else the folder holds (a built asset)."""
    directory = Path(directory)
    (directory / "object.json").unlink(missing_ok=True)
    shutil.rmtree(directory / "parts", ignore_errors=True)


def is_bundle(directory: str | Path) -> bool:
    return (Path(directory) / "object.json").is_file()


def find_bundles(path: str | Path) -> list[Path]:
    """A bundle folder itself, or every bundle folder directly under ``path`` (sorted)."""
    path = Path(path)
    if is_bundle(path):
        return [path]
    if not path.is_dir():
        raise ObjectModelError(f"{path}: not a bundle folder or a folder of bundles")
    return sorted(p for p in path.iterdir() if p.is_dir() and is_bundle(p))
