"""One bundle in, one simulation asset out (``pact build``).

:func:`build_asset` reads a bundle (``object.json`` + ``parts/*.glb``), makes it
metric and watertight (:mod:`asset_pipeline.mesh`), cuts convex collision pieces
(:mod:`asset_pipeline.collision`), rigs it (:mod:`asset_pipeline.rig`) and writes the
built-asset layout of ``docs/architecture.md`` into the bundle folder::

    visual/<part>.glb  visual/<part>.obj  collision/<part>_<k>.obj
    model.urdf  model.xml  asset.json

Every file is written atomically (temporary name + rename). ``asset.json`` is
removed first and written last, so a folder whose ``asset.json`` exists holds a
complete build; files of an earlier build that the new one does not produce
(e.g. ``collision/base_7.obj`` when there are now 5 pieces) are removed.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from generator.articulated import (
    ArticulatedObject,
    Handle,
    Part,
    atomic_write_bytes,
    load_bundle,
    mesh_to_glb,
)

from .collision import CoacdFailed, CoacdParams, part_pieces
from .mesh import (
    DEFAULT_HEIGHTS,
    REMESH_RESOLUTION,
    MeshRepairError,
    to_metric,
    watertight_object,
)
from .rig import (
    PhysicsDefaults,
    Rig,
    build_rig,
    link_origin,
    mjcf_string,
    part_solid,
    urdf_string,
)

log = logging.getLogger(__name__)

ASSET_SCHEMA = "pact.asset"
ASSET_VERSION = 1
#: A fallback handle sits this far (fraction of the part's width) in from the edge
#: opposite the hinge, but at most HANDLE_INSET_MAX metres.
HANDLE_INSET_FRACTION = 0.15
HANDLE_INSET_MAX = 0.05


class BuildError(ValueError):
    """A bundle could not be built; the message names the file and what is wrong."""


@dataclass(frozen=True)
class BuildOptions:
    """Knobs of one build. Defaults are the documented ones of each stage."""

    default_heights: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_HEIGHTS))
    physics: PhysicsDefaults = PhysicsDefaults()
    coacd: CoacdParams = CoacdParams()
    coacd_timeout: float = 300.0
    #: CoACD cache folder; None: ``$PACT_CACHE_DIR`` or ``~/.cache/pact/coacd``.
    cache_dir: Path | None = None
    remesh_resolution: int = REMESH_RESOLUTION


@dataclass
class BuildResult:
    """What :func:`build_asset` wrote: the asset folder, its main files and metadata."""

    id: str
    directory: Path
    urdf: Path
    mjcf: Path
    asset_json: Path
    asset: dict[str, Any]
    pieces: dict[str, int]
    seconds: float


# --------------------------------------------------------------------------- pure parts


def prepare_object(
    obj: ArticulatedObject,
    height: float | None = None,
    options: BuildOptions = BuildOptions(),
) -> ArticulatedObject:
    """``obj`` at metric scale, in the frame convention, with watertight part meshes."""
    metric = to_metric(obj, height=height, default_heights=options.default_heights)
    return watertight_object(metric, options.remesh_resolution)


def fallback_handle(part: Part) -> Handle:
    """Grasp point of a movable part without a modelled handle (object frame, kind ``none``).

    The centre of the part's front face (the +x side of the bounding box of its solid,
    :func:`asset_pipeline.rig.part_solid`: what it collides with), moved in
    the face plane away from the hinge line toward the opposite edge, stopping
    ``min(HANDLE_INSET_FRACTION * extent, HANDLE_INSET_MAX)`` short of it. Prismatic
    parts keep the face centre. The handle axis is the hinge axis for revolute
    parts (a bar parallel to the hinge) and +y otherwise.
    """
    lo, hi = part_solid(part).bounds
    centre = np.array([hi[0], 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])])
    j = part.joint
    if j is None or j.type != "revolute":
        return Handle(position=centre, axis=np.array([0.0, 1.0, 0.0]), kind="none")
    axis = np.asarray(j.axis, dtype=float)
    away = centre - j.origin
    away -= axis * float(away @ axis)  # perpendicular to the hinge line
    away[0] = 0.0  # stay on the front face
    n = float(np.linalg.norm(away))
    if n < 1e-9:
        return Handle(position=centre, axis=axis, kind="none")
    d = away / n
    half = 0.5 * (hi - lo)
    reach = float(np.abs(d) @ half)  # distance from the centre to the bbox edge along d
    inset = min(HANDLE_INSET_FRACTION * 2 * reach, HANDLE_INSET_MAX)
    return Handle(position=centre + d * max(reach - inset, 0.0), axis=axis, kind="none")


def link_frame_mesh(mesh: trimesh.Trimesh, origin: np.ndarray) -> trimesh.Trimesh:
    """Copy of an object-frame ``mesh`` expressed in a link frame at ``origin`` (3,)."""
    out = mesh.copy()
    out.apply_translation(-np.asarray(origin, dtype=float))
    return out


def textured_for_render(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """``mesh`` with its vertex colours baked into a palette texture.

    SAPIEN's renderer ignores glTF vertex colours (COLOR_0) but draws base-colour
    textures, so coloured visuals are written textured; textured meshes pass through.
    """
    if mesh.visual.kind not in ("vertex", "face"):
        return mesh
    out = mesh.copy()
    out.visual = mesh.visual.to_texture()
    return out


def obj_text(mesh: trimesh.Trimesh) -> str:
    """Wavefront OBJ of the geometry only (positions and faces; MuJoCo and PhysX read it)."""
    return trimesh.exchange.obj.export_obj(
        mesh, include_normals=False, include_color=False, include_texture=False, header=None
    )


def _round(v: Any) -> Any:
    return [round(float(x) + 0.0, 9) for x in np.asarray(v, dtype=float).ravel()]


def asset_metadata(
    asset_id: str, obj: ArticulatedObject, rig: Rig, metric_scale: float
) -> dict[str, Any]:
    """The ``asset.json`` document (schema ``pact.asset`` v1) of a built object."""
    links = [
        {
            "name": link.name,
            "semantic": link.semantic,
            "mass": round(link.mass.mass, 9),
            "material": link.material,
            "visual": link.visual_glb,
            "collision": list(link.collisions),
        }
        for link in rig.links
    ]
    joints = [
        {
            "name": j.name,
            "parent": j.parent,
            "child": j.child,
            "type": j.type,
            "origin": _round(j.origin + link_origin(obj, j.parent)),
            "axis": _round(j.axis),
            "lower": round(j.lower, 9),
            "upper": round(j.upper, 9),
            "damping": j.physics.damping,
            "friction": j.physics.friction,
            "effort": j.physics.effort,
            "velocity": j.physics.velocity,
        }
        for j in rig.joints
    ]
    handles = {}
    for p in obj.movable_parts:
        h = p.handle if p.handle is not None else fallback_handle(p)
        handles[p.name] = {
            "position": _round(h.position),
            "position_link": _round(h.position - link_origin(obj, p.name)),
            "axis": _round(h.axis),
            "kind": h.kind,
        }
    b = obj.bounds()
    return {
        "schema": ASSET_SCHEMA,
        "version": ASSET_VERSION,
        "id": asset_id,
        "category": obj.category,
        "metric_scale": metric_scale,
        "bounds": [_round(b[0]), _round(b[1])],
        "links": links,
        "joints": joints,
        "handles": handles,
    }


# --------------------------------------------------------------------------- files


def _write(path: Path, data: bytes | str) -> None:
    try:
        atomic_write_bytes(path, data.encode() if isinstance(data, str) else data)
    except OSError as e:
        raise BuildError(f"{path}: cannot write: {e}") from e


def _remove_stale(folder: Path, pattern: str, keep: set[Path]) -> None:
    for old in sorted(folder.glob(pattern)):
        if old not in keep:
            log.debug("removing stale %s", old)
            old.unlink()


def build_asset(
    bundle_dir: str | Path,
    *,
    height: float | None = None,
    options: BuildOptions = BuildOptions(),
) -> BuildResult:
    """Build the simulation asset of the bundle in ``bundle_dir`` (id = folder name).

    ``height`` (metres) sizes objects whose bundle has no metric scale; see
    :func:`asset_pipeline.mesh.to_metric`. Raises ObjectModelError for an invalid
    bundle and BuildError when a part cannot be made watertight or decomposed, or a
    file cannot be written; each message names the file at fault.
    """
    t0 = time.perf_counter()
    root = Path(bundle_dir)
    asset_id = root.resolve().name
    obj = load_bundle(root)  # ObjectModelError names object.json / the part mesh
    asset_json = root / "asset.json"
    asset_json.unlink(missing_ok=True)

    try:
        built = prepare_object(obj, height, options)
    except MeshRepairError as e:
        raise BuildError(f"{root / 'parts'}: {e}") from e
    metric_scale = float(built.provenance["metric_scale"])

    pieces: dict[str, list[trimesh.Trimesh]] = {}
    for p in built.parts:
        try:
            found = part_pieces(
                p, options.coacd, timeout=options.coacd_timeout, cache_dir=options.cache_dir
            )
        except CoacdFailed as e:
            raise BuildError(f"{root / 'parts' / (p.name + '.glb')}: {e}") from e
        pieces[p.name] = found
        log.info("%s/%s: %d convex pieces", asset_id, p.name, len(found))

    written: set[Path] = set()
    for p in built.parts:
        origin = link_origin(built, p.name)
        vis = link_frame_mesh(p.mesh, origin)
        for path, data in (
            (root / "visual" / f"{p.name}.glb", mesh_to_glb(textured_for_render(vis))),
            (root / "visual" / f"{p.name}.obj", obj_text(vis)),
        ):
            _write(path, data)
            written.add(path)
        for k, piece in enumerate(pieces[p.name]):
            path = root / "collision" / f"{p.name}_{k}.obj"
            _write(path, obj_text(link_frame_mesh(piece, origin)))
            written.add(path)
    _remove_stale(root / "collision", "*.obj", written)
    _remove_stale(root / "visual", "*.glb", written)
    _remove_stale(root / "visual", "*.obj", written)

    rig = build_rig(built, {n: len(v) for n, v in pieces.items()}, asset_id, options.physics)
    urdf, mjcf = root / "model.urdf", root / "model.xml"
    _write(urdf, urdf_string(rig))
    _write(mjcf, mjcf_string(rig))
    meta = asset_metadata(asset_id, built, rig, metric_scale)
    _write(asset_json, json.dumps(meta, indent=2) + "\n")
    seconds = time.perf_counter() - t0
    log.info("built %s in %.1f s", asset_id, seconds)
    return BuildResult(
        id=asset_id,
        directory=root,
        urdf=urdf,
        mjcf=mjcf,
        asset_json=asset_json,
        asset=meta,
        pieces={n: len(v) for n, v in pieces.items()},
        seconds=seconds,
    )
