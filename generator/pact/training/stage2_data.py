"""Stage-2 training data: structured-latent (SLAT) inputs per object, cached on disk.

For every object of a dataset folder (docs/dataset.md) and every part slot, the part's
*token voxels* are the shell of its R = 32 occupancy (occupied voxels with at least one
unoccupied voxel among their 26 neighbours). Interior voxels are implied by the
occupancy: their fine SDF is "deep inside" (-1 after truncation) and carries no
appearance, so they need no token (TRELLIS likewise keeps only surface voxels).

Per token voxel the cache stores
  * ``sdf``: the part's signed distance at a 4 x 4 x 4 sub-grid of points inside the voxel
    (fine grid R * 4 = 128, fine sample (4 i + a) sits at ``-0.5 + (4 i + a + 0.5) / 128``),
    truncated at one voxel (``TRUNCATION`` = 1 / 32 normalized units) and divided by it,
    so values lie in [-1, 1] (negative inside), quantized to uint8;
  * ``rgb``: the colour of the nearest surface sample of the part (dataset
    ``surface_points`` / ``surface_colors``), uint8 sRGB.

The SDF is exact: procedural parts are unions of boxes and cylinders (``Part.primitives``),
regenerated with the factory (``sample_object``) from the object id, posed at rest and
normalized with the dataset's stored normalization; the SDF of a union is the minimum
of the primitives' SDFs (a part without primitives falls back to trimesh's mesh SDF).

Cache layout (``runs/pact/slat_cache``): ``shard_<k>.npz`` per dataset shard with
``object_ids`` (N,), ``offsets`` (N + 1,) int64 into the voxel arrays, ``coords``
(M, 3) uint8 voxel index [x, y, z], ``slot`` (M,) int8, ``sdf`` (M, 64) uint8, ``rgb``
(M, 3) uint8; and ``manifest.json``. Deterministic; resumable (finished shards are kept);
files are written under a temporary name and renamed.
"""

from __future__ import annotations

import json
import logging
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from generator.articulated import ArticulatedObject, Part, Primitive
from generator.pact.model.slat_vae import RESOLUTION, SUB, shell_voxels

log = logging.getLogger(__name__)

FINE = RESOLUTION * SUB  # 128, fine grid of the decoded SDF
TRUNCATION = 1.0 / RESOLUTION  # SDF truncation (normalized units), one voxel
CACHE_VERSION = 1


class SlatDataError(ValueError):
    """A cache folder or an object that does not fit the expected layout."""


# --------------------------------------------------------------------------- geometry


def subsample_points(coords: np.ndarray, resolution: int = RESOLUTION) -> np.ndarray:
    """(N, 3) int voxel indices -> (N, SUB^3, 3) sub-sample centres, sub index [a, b, c] raster."""
    a = (np.arange(SUB) + 0.5) / SUB  # (SUB,) offsets inside a voxel, in voxel units
    off = np.stack(np.meshgrid(a, a, a, indexing="ij"), -1).reshape(-1, 3)  # (SUB^3, 3)
    return -0.5 + (coords[:, None, :].astype(np.float64) + off[None]) / resolution


def primitive_sdf(prim: Primitive, points: np.ndarray) -> np.ndarray:
    """Exact signed distance of (P, 3) points to a box or cylinder (negative inside)."""
    inv = np.linalg.inv(prim.transform)
    q = points @ inv[:3, :3].T + inv[:3, 3]  # (P, 3) in the primitive's frame
    if prim.kind == "box":
        d = np.abs(q) - prim.size / 2.0
    else:  # cylinder along local z: size = [radius, height]
        radial = np.linalg.norm(q[:, :2], axis=1) - prim.size[0]
        d = np.stack([radial, np.abs(q[:, 2]) - prim.size[1] / 2.0], axis=1)
    outside = np.linalg.norm(np.maximum(d, 0.0), axis=1)
    inside = np.minimum(d.max(axis=1), 0.0)
    return outside + inside


def part_sdf(
    part: Part, points: np.ndarray, rest: np.ndarray, cutoff: float | None = None
) -> np.ndarray:
    """Signed distance (metric units) of (P, 3) metric points to ``part`` posed by ``rest``.

    With ``cutoff``, distances beyond it are only guaranteed to be >= cutoff.
    """
    if not part.primitives:
        import trimesh

        mesh = part.mesh.copy()
        mesh.apply_transform(rest)
        return -trimesh.proximity.signed_distance(mesh, points)  # trimesh: positive inside
    # Points farther than ``cutoff`` from a primitive's box are truncated anyway: evaluate
    # each primitive only inside its bounding box grown by the cutoff.
    d = np.full(len(points), np.inf if cutoff is None else 2.0 * cutoff)
    for prim in part.primitives:
        posed = Primitive(prim.kind, prim.size, rest @ prim.transform)
        if cutoff is None:
            d = np.minimum(d, primitive_sdf(posed, points))
            continue
        half = posed.size / 2.0 if posed.kind == "box" else posed.size[[0, 0, 1]] * [1, 1, 0.5]
        corners = np.array(np.meshgrid(*[[-1.0, 1.0]] * 3, indexing="ij")).reshape(3, -1).T
        world = (corners * half) @ posed.transform[:3, :3].T + posed.transform[:3, 3]  # (8, 3)
        lo, hi = world.min(0) - cutoff, world.max(0) + cutoff
        near = np.flatnonzero(((points >= lo) & (points <= hi)).all(axis=1))
        if len(near):
            d[near] = np.minimum(d[near], primitive_sdf(posed, points[near]))
    return d


def part_slat_inputs(
    part: Part,
    occ: np.ndarray,
    normalization: np.ndarray,
    surface_points: np.ndarray,
    surface_colors: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Token voxels of one part and their targets.

    occ: (R, R, R) bool occupancy; normalization: (4,) [cx, cy, cz, s];
    surface_points (P, 3) normalized, surface_colors (P, 3) uint8.
    Returns coords (N, 3) uint8, sdf (N, SUB^3) float32 in [-1, 1], rgb (N, 3) uint8.
    """
    coords = np.argwhere(shell_voxels(occ)).astype(np.int64)  # (N, 3)
    c, s = normalization[:3].astype(np.float64), float(normalization[3])
    rest = np.eye(4) if part.joint is None else part.joint.transform(part.joint.lower)
    pts = subsample_points(coords)  # (N, SUB^3, 3) normalized
    d = (
        part_sdf(part, pts.reshape(-1, 3) * s + c, rest, cutoff=1.5 * TRUNCATION * s) / s
    )  # normalized units
    sdf = np.clip(d / TRUNCATION, -1.0, 1.0).reshape(len(coords), -1).astype(np.float32)
    centres = -0.5 + (coords + 0.5) / RESOLUTION
    if len(surface_points):
        _, nearest = cKDTree(surface_points).query(centres)
        rgb = surface_colors[nearest]
    else:
        rgb = np.zeros((len(coords), 3), np.uint8)
    return coords.astype(np.uint8), sdf, rgb.astype(np.uint8)


def quantize_sdf(sdf: np.ndarray) -> np.ndarray:
    return np.round((np.clip(sdf, -1, 1) + 1.0) * 127.5).astype(np.uint8)


def dequantize_sdf(q: np.ndarray) -> np.ndarray:
    return q.astype(np.float32) / 127.5 - 1.0


def object_from_id(object_id: str) -> ArticulatedObject:
    """Regenerate a dataset object from its id ``<category>_s<seed>`` / ``_t<seed>``."""
    from generator.procedural import sample_object

    cat, tag = object_id.rsplit("_", 1)
    split = {"s": "train", "t": "test"}.get(tag[:1])
    if split is None or not tag[1:].isdigit():
        raise SlatDataError(f"object id {object_id!r} is not <category>_s<seed> / _t<seed>")
    return sample_object(cat, int(tag[1:]), split)


def object_slat_inputs(arrays: dict[str, np.ndarray], i: int) -> dict[str, np.ndarray]:
    """SLAT inputs of object ``i`` of a loaded dataset shard (all of its part slots)."""
    from generator.data import unpack_occupancy
    from generator.data.render import part_slots

    oid = str(arrays["object_ids"][i])
    obj = object_from_id(oid)
    slots = part_slots(obj)
    n = int(arrays["part_count"][i])
    if len(slots) != n:
        raise SlatDataError(f"{oid}: factory gives {len(slots)} parts, dataset has {n}")
    occ = unpack_occupancy(arrays["occupancy"][i][None], RESOLUTION)[0]  # (S, R, R, R)
    out = {"coords": [], "slot": [], "sdf": [], "rgb": []}
    for k, part in enumerate(slots):
        coords, sdf, rgb = part_slat_inputs(
            part,
            occ[k],
            arrays["normalization"][i],
            arrays["surface_points"][i, k],
            arrays["surface_colors"][i, k],
        )
        out["coords"].append(coords)
        out["slot"].append(np.full(len(coords), k, np.int8))
        out["sdf"].append(quantize_sdf(sdf))
        out["rgb"].append(rgb)
    return {k: np.concatenate(v) for k, v in out.items()}


# --------------------------------------------------------------------------- cache


def _build_shard(args: tuple[str, str]) -> str:
    shard_file, out_file = args
    from generator.data import load_shard

    arrays = load_shard(shard_file)
    per = [object_slat_inputs(arrays, i) for i in range(len(arrays["object_ids"]))]
    counts = [len(p["coords"]) for p in per]
    data = {
        "object_ids": arrays["object_ids"],
        "offsets": np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        **{k: np.concatenate([p[k] for p in per]) for k in ("coords", "slot", "sdf", "rgb")},
    }
    tmp = out_file + ".tmp.npz"
    np.savez_compressed(tmp, **data)
    os.replace(tmp, out_file)
    return out_file


def build_cache(dataset: str | Path, out: str | Path, workers: int = 2) -> Path:
    """Precompute the SLAT inputs of every shard of ``dataset`` into ``out`` (resumable)."""
    from generator.data.shards import read_manifest

    dataset, out = Path(dataset), Path(out)
    manifest = read_manifest(dataset)
    if manifest is None:
        raise SlatDataError(f"{dataset} has no dataset manifest.json")
    if manifest["resolution"] != RESOLUTION:
        raise SlatDataError(f"dataset resolution {manifest['resolution']} != {RESOLUTION}")
    out.mkdir(parents=True, exist_ok=True)
    jobs = []
    for sh in manifest["shards"]:
        target = out / sh["file"]
        if not target.is_file():
            jobs.append((str(dataset / sh["file"]), str(target)))
    log.info("slat cache: %d of %d shards to build", len(jobs), len(manifest["shards"]))
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(workers) as pool:
            for done in pool.map(_build_shard, jobs):
                log.info("wrote %s", done)
    else:
        for job in jobs:
            log.info("wrote %s", _build_shard(job))
    meta = {
        "schema": "pact.slat_cache",
        "version": CACHE_VERSION,
        "dataset": str(dataset),
        "resolution": RESOLUTION,
        "sub": SUB,
        "truncation": TRUNCATION,
        "shards": [sh["file"] for sh in manifest["shards"]],
    }
    tmp = out / "manifest.json.tmp"
    tmp.write_text(json.dumps(meta, indent=1))
    os.replace(tmp, out / "manifest.json")
    return out


def load_cache(out: str | Path, partial: bool = False) -> tuple[dict, list[dict[str, np.ndarray]]]:
    """(manifest, one dict of arrays per shard) of a built cache.

    ``partial``: a cache still being built is read as the shards finished so far.
    """
    out = Path(out)
    meta_file = out / "manifest.json"
    if meta_file.is_file():
        meta = json.loads(meta_file.read_text())
    elif partial:
        names = sorted(p.name for p in out.glob("shard_*.npz") if ".tmp" not in p.name)
        meta = {"shards": names}
    else:
        raise SlatDataError(f"{out} has no manifest.json: build it with build_cache first")
    shards = []
    for name in meta["shards"]:
        with np.load(out / name) as z:
            shards.append({k: z[k] for k in z.files})
    return meta, shards


class SlatObjects:
    """The stage-2 training set in memory: SLAT cache + the dataset arrays stage 2 needs.

    Object ``i`` is the i-th object of the dataset (shard order). ``max_parts`` caps the
    slots kept (objects with more parts keep their first ``max_parts`` slots).
    ``latents`` (set by the trainer after the SLAT VAE is trained): (M,) rows aligned with
    the voxel arrays.
    """

    KEYS = (
        "part_count",
        "occupancy",
        "joint_type",
        "semantic",
        "joint_origin",
        "joint_axis",
        "joint_range",
    )

    def __init__(
        self,
        cache: str | Path,
        dataset: str | Path,
        images: bool = True,
        max_parts: int = 8,
        partial: bool = False,
    ) -> None:
        dataset = Path(dataset)
        meta, shards = load_cache(cache, partial)
        self.max_parts = max_parts
        keys = self.KEYS + (("images", "masks") if images else ())
        arrays: dict[str, list[np.ndarray]] = {k: [] for k in keys}
        coords, slot, sdf, rgb, offsets, ids = [], [], [], [], [0], []
        for name, sh in zip(meta["shards"], shards, strict=True):
            with np.load(dataset / name, allow_pickle=False) as z:
                if list(z["object_ids"]) != list(sh["object_ids"]):
                    raise SlatDataError(f"{name}: cache and dataset list different objects")
                for k in keys:
                    arrays[k].append(z[k][:, :max_parts] if k in self.KEYS[1:] else z[k])
            keep = sh["slot"] < max_parts
            n_keep = np.add.reduceat(keep, sh["offsets"][:-1]) if len(keep) else []
            coords.append(sh["coords"][keep])
            slot.append(sh["slot"][keep])
            sdf.append(sh["sdf"][keep])
            rgb.append(sh["rgb"][keep])
            offsets.extend(offsets[-1] + np.cumsum(n_keep))
            ids.extend(sh["object_ids"].tolist())
        self.ids = ids
        self.arrays = {k: np.concatenate(v) for k, v in arrays.items()}
        self.arrays["part_count"] = np.minimum(self.arrays["part_count"], max_parts)
        self.coords = np.concatenate(coords)  # (M, 3) uint8
        self.slot = np.concatenate(slot)  # (M,) int8
        self.sdf_q = np.concatenate(sdf)  # (M, SUB^3) uint8
        self.rgb = np.concatenate(rgb)  # (M, 3) uint8
        self.offsets = np.asarray(offsets, np.int64)  # (N + 1,)
        self.latents: np.ndarray | None = None
        log.info("stage-2 data: %d objects, %d token voxels", len(ids), len(self.coords))

    def __len__(self) -> int:
        return len(self.ids)

    def rows(self, i: int) -> slice:
        return slice(int(self.offsets[i]), int(self.offsets[i + 1]))

    def occupancy(self, i: int) -> np.ndarray:
        """(max_parts, R, R, R) bool part occupancies of object i."""
        from generator.data import unpack_occupancy

        return unpack_occupancy(self.arrays["occupancy"][i], RESOLUTION)


if __name__ == "__main__":
    import argparse

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    ap = argparse.ArgumentParser(description="build the stage-2 SLAT cache")
    ap.add_argument("--data", default="runs/data/train")
    ap.add_argument("--out", default="runs/pact/slat_cache")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    build_cache(a.data, a.out, a.workers)
