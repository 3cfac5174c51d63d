"""One bundle in, one simulation asset out (``pact build``).

:func:`build_asset` reads a bundle (``object.json`` + ``parts/*.glb``), makes it
metric and watertight (:mod:`asset_pipeline.geometry.metric`), cuts convex collision pieces
(:mod:`asset_pipeline.geometry.coacd_collision`), rigs it (:mod:`asset_pipeline.assets.rig`) and writes the
built-asset layout of ``docs/architecture.md`` into the bundle folder::

    visual/<part>.glb  visual/<part>.obj (+ .png)  collision/<part>_<k>.obj
    model.urdf  model.xml  asset.json

The visuals are the part meshes within ``BuildOptions.visual_faces`` triangles in all
(decimated; the collision pieces, masses and joints come from the full meshes).

Every file is written atomically (temporary name + rename). ``asset.json`` is
removed first and written last, so a folder whose ``asset.json`` exists holds a
complete build; files of an earlier build that the new one does not produce
(e.g. ``collision/base_7.obj`` when there are now 5 pieces) are removed.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import trimesh

from asset_pipeline.assets.built_asset import BuiltAsset
from asset_pipeline.assets.folder import FORMATS, check_formats, save_asset
from asset_pipeline.assets.layout import MJCF_NAME, URDF_NAME
from asset_pipeline.assets.rig import PhysicsDefaults, build_rig
from asset_pipeline.geometry.coacd_collision import CoacdFailed, CoacdParams, part_pieces
from asset_pipeline.geometry.metric import DEFAULT_HEIGHTS, to_metric
from asset_pipeline.geometry.voxel_collision import (
    VoxelCollisionParams,
    articulated_boxes,
    box_primitive,
)
from generator.articulated import ArticulatedObject
from generator.bundle import load_bundle
from generator.mesh_repair.closing import REMESH_RESOLUTION, MeshRepairError, watertight_object
from generator.mesh_repair.decimation import DEFAULT_VISUAL_FACES, light_meshes

log = logging.getLogger(__name__)


COLLISION_METHODS = ("auto", "voxel", "coacd")


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
    #: How parts collide: "auto" (a part's primitives where it has them, else
    #: articulation-aware voxel boxes), "voxel" (voxel boxes from every part's mesh,
    #: primitives ignored) or "coacd" (each part's mesh decomposed alone by CoACD).
    collision: str = "auto"
    voxel: VoxelCollisionParams = VoxelCollisionParams()
    #: Visual triangles of the asset in all (``--visual-faces``; 0 keeps every triangle):
    #: the visuals are decimated to it (:mod:`generator.mesh_repair.decimation`); collision
    #: pieces and masses come from the full meshes.
    visual_faces: int = DEFAULT_VISUAL_FACES
    #: The model files written (``--formats``): ``urdf`` (always), ``mjcf``, ``usd``
    #: (:data:`asset_pipeline.assets.folder.FORMATS`).
    formats: tuple[str, ...] = FORMATS

    def __post_init__(self) -> None:
        object.__setattr__(self, "formats", check_formats(self.formats))
        if self.collision not in COLLISION_METHODS:
            raise ValueError(
                f"collision must be one of {COLLISION_METHODS}, got {self.collision!r}"
            )


@dataclass
class BuildResult:
    """What :func:`build_asset` wrote: the asset (model and folder) and its piece counts."""

    asset: BuiltAsset
    pieces: dict[str, int]
    seconds: float

    @property
    def id(self) -> str:
        return self.asset.id

    @property
    def directory(self) -> Path:
        assert self.asset.folder is not None
        return self.asset.folder

    @property
    def urdf(self) -> Path:
        return self.directory / URDF_NAME

    @property
    def mjcf(self) -> Path:
        return self.directory / MJCF_NAME


def collide_boxes(obj: ArticulatedObject, options: BuildOptions = BuildOptions()) -> None:
    """Give the parts that need them articulation-aware collision boxes as primitives.

    "auto": the parts without primitives (when there are any); "voxel": every part, from
    its mesh. The boxes (:mod:`asset_pipeline.geometry.voxel_collision`) are decomposed for the
    whole object at once, so the base's never enter a drawer's slot or a door's swing;
    they become the part's primitives, its collision pieces and its mass solid.
    """
    names = set(voxel_parts(obj, options))
    todo = [p for p in obj.parts if p.name in names]
    if not todo:
        return
    cache = None if options.cache_dir is None else Path(options.cache_dir) / "voxel"
    boxes, pitch, cached = articulated_boxes(obj, options.voxel, cache)
    for p in todo:
        if not boxes[p.name]:
            raise BuildError(
                f"part {p.name}: no collision box survived (is it all inside a sweep?)"
            )
        p.primitives = [box_primitive(b) for b in boxes[p.name]]
    log.info(
        "%d part(s): %d voxel boxes at pitch %.1f mm%s",
        len(todo),
        sum(len(p.primitives) for p in todo),
        pitch * 1000,
        " (cached)" if cached else "",
    )


def prepare_object(
    obj: ArticulatedObject,
    height: float | None = None,
    options: BuildOptions = BuildOptions(),
) -> ArticulatedObject:
    """``obj`` at metric scale, in the frame convention, with watertight part meshes.

    The parts that will collide as voxel boxes (:func:`collide_boxes`) keep their meshes:
    those are visuals only.
    """
    metric = to_metric(obj, height=height, default_heights=options.default_heights)
    return watertight_object(metric, options.remesh_resolution, keep=voxel_parts(metric, options))


def voxel_parts(obj: ArticulatedObject, options: BuildOptions) -> list[str]:
    """The parts :func:`collide_boxes` gives voxel boxes: none with "coacd", every part
    with "voxel", those without primitives with "auto"."""
    if options.collision == "coacd":
        return []
    return [p.name for p in obj.parts if options.collision == "voxel" or not p.primitives]


def part_source(root: Path, obj: ArticulatedObject, part: str | None) -> str:
    """Where a part's mesh comes from, for an error: its bundle file, and the source
    meshes an importer recorded for it (``provenance["meshes"]``) with the source."""
    if part is None:
        return str(root / "parts")
    where = str(root / "parts" / f"{part}.glb")
    sources = (obj.provenance.get("meshes") or {}).get(part)
    if sources:
        origin = obj.provenance.get("source", "its source")
        where += f" (from {', '.join(map(str, sources))} of {origin})"
    return where


def build_asset(
    bundle_dir: str | Path,
    *,
    height: float | None = None,
    options: BuildOptions = BuildOptions(),
) -> BuildResult:
    """Build the simulation asset of the bundle in ``bundle_dir`` (id = folder name).

    ``height`` (metres) sizes objects whose bundle has no metric scale; see
    :func:`asset_pipeline.geometry.metric.to_metric`. Raises ObjectModelError for an invalid
    bundle and BuildError when a part cannot be made watertight or decomposed, or a
    file cannot be written; each message names the file at fault.
    """
    t0 = time.perf_counter()
    root = Path(bundle_dir)
    asset_id = root.resolve().name
    obj = load_bundle(root)  # ObjectModelError names object.json / the part mesh
    (root / "asset.json").unlink(missing_ok=True)

    try:
        built = prepare_object(obj, height, options)
    except MeshRepairError as e:
        raise BuildError(f"{part_source(root, obj, e.part)}: {e}") from e

    collide_boxes(built, options)
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

    visuals = light_meshes({p.name: p.mesh for p in built.parts}, options.visual_faces)
    asset = build_rig(built, pieces, asset_id, options.physics, visuals=visuals)
    try:
        save_asset(asset, root, formats=options.formats)
    except OSError as e:
        raise BuildError(f"{e.filename or root}: cannot write: {e.strerror or e}") from e
    seconds = time.perf_counter() - t0
    log.info("built %s in %.1f s", asset_id, seconds)
    return BuildResult(asset=asset, pieces={n: len(v) for n, v in pieces.items()}, seconds=seconds)
