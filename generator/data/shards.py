"""The dataset on disk (docs/dataset.md): manifest, npz shards, and a torch-free reader.

A dataset folder holds ``manifest.json`` and ``shard_<k>.npz``. Every file is written
to a temporary name and renamed, so a file that exists is whole.
"""

from __future__ import annotations

import json
import logging
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from generator.atomic_files import atomic_write_bytes

log = logging.getLogger(__name__)

SCHEMA = "pact.dataset"
VERSION = 1
SEMANTICS = ("base", "drawer", "door", "lid")
JOINT_TYPES = ("none", "fixed", "prismatic", "revolute")
MANIFEST = "manifest.json"


class DatasetError(RuntimeError):
    """A dataset folder or shard is missing, malformed, or built with other arguments."""


def shard_name(k: int) -> str:
    return f"shard_{k:05d}.npz"


def array_spec(
    views: int, image_size: int, max_parts: int, resolution: int, points_per_part: int
) -> dict[str, tuple[tuple[int, ...], str]]:
    """Per-object shape (without the leading N) and dtype of every shard array."""
    V, H, S, R, P = views, image_size, max_parts, resolution, points_per_part
    return {
        "object_ids": ((), "U"),
        "category": ((), "U"),
        "images": ((V, H, H, 3), "uint8"),
        "masks": ((V, H, H), "uint8"),
        "intrinsics": ((V, 3, 3), "float32"),
        "extrinsics": ((V, 4, 4), "float32"),
        "view_qpos": ((V, S), "float32"),
        "part_count": ((), "int16"),
        "occupancy": ((S, R * R * R // 8), "uint8"),
        "surface_points": ((S, P, 3), "float32"),
        "surface_colors": ((S, P, 3), "uint8"),
        "joint_type": ((S,), "int8"),
        "semantic": ((S,), "int8"),
        "joint_origin": ((S, 3), "float32"),
        "joint_axis": ((S, 3), "float32"),
        "joint_range": ((S, 2), "float32"),
        "normalization": ((4,), "float32"),
    }


def stack_records(records: list[dict[str, np.ndarray]], spec: dict) -> dict[str, np.ndarray]:
    """Stack per-object arrays into shard arrays (N leading); N may be 0."""
    out = {}
    for key, (shape, dtype) in spec.items():
        if records:
            out[key] = np.stack([np.asarray(r[key]) for r in records])
        else:
            out[key] = np.zeros((0, *shape), dtype="<U1" if dtype == "U" else dtype)
        if dtype != "U" and out[key].dtype != np.dtype(dtype):
            raise DatasetError(f"array {key!r} has dtype {out[key].dtype}, expected {dtype}")
    return out


def load_shard(file: str | Path) -> dict[str, np.ndarray]:
    """All arrays of one shard, loaded into memory (no pickles)."""
    file = Path(file)
    if not file.is_file():
        raise DatasetError(f"{file}: shard not found; rebuild with `pact dataset build`")
    try:
        with np.load(file, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise DatasetError(f"{file}: not a readable npz shard ({e}); delete it and rebuild") from e


def unpack_occupancy(packed: np.ndarray, resolution: int) -> np.ndarray:
    """``np.packbits`` occupancy (..., R^3/8) back to a bool grid (..., R, R, R), [x, y, z]."""
    R = resolution
    bits = np.unpackbits(np.asarray(packed, np.uint8), axis=-1, count=R * R * R)
    return bits.reshape(*packed.shape[:-1], R, R, R).astype(bool)


def pack_occupancy(grid: np.ndarray) -> np.ndarray:
    """(..., R, R, R) bool -> (..., R^3/8) uint8 (inverse of ``unpack_occupancy``)."""
    R = grid.shape[-1]
    return np.packbits(grid.reshape(*grid.shape[:-3], R * R * R).astype(bool), axis=-1)


def read_manifest(folder: str | Path) -> dict[str, Any] | None:
    """The manifest of a dataset folder, or None when there is none yet."""
    path = Path(folder) / MANIFEST
    if not path.is_file():
        return None
    try:
        m = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DatasetError(f"{path}: not valid JSON ({e}); delete it to rebuild the dataset") from e
    if m.get("schema") != SCHEMA or m.get("version") != VERSION:
        raise DatasetError(
            f"{path}: expected schema {SCHEMA!r} version {VERSION}, "
            f"got {m.get('schema')!r} version {m.get('version')!r}"
        )
    return m


def write_manifest(folder: str | Path, manifest: dict[str, Any]) -> None:
    path = Path(folder) / MANIFEST
    atomic_write_bytes(path, json.dumps(manifest, indent=1).encode())
    os.chmod(path, 0o644)


def remove_stale_temporaries(folder: Path) -> None:
    """Remove leftover temporary files of an interrupted write (``.<name>.*.tmp``)."""
    for tmp in folder.glob(".*.tmp"):
        try:
            tmp.unlink()
        except OSError:  # pragma: no cover - another writer may own it
            pass


class Dataset:
    """Read a dataset folder: ``len(ds)`` objects, ``ds[i]`` one object's arrays.

    ``ds[i]`` returns the shard arrays indexed at that object (no N axis) plus
    ``occupancy_grid`` (S, R, R, R) bool. Shards are loaded on demand and the last one
    is kept in memory, so iterate in order (or per shard with ``shards()``) for speed.
    """

    def __init__(self, path: str | Path):
        self.root = Path(path)
        manifest = read_manifest(self.root)
        if manifest is None:
            raise DatasetError(f"{self.root}: no {MANIFEST}; build one with `pact dataset build`")
        self.manifest = manifest
        self.resolution = int(manifest["resolution"])
        self.files = [self.root / s["file"] for s in manifest["shards"]]
        counts = [len(s["objects"]) for s in manifest["shards"]]
        self.offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.object_ids = [o for s in manifest["shards"] for o in s["objects"]]
        self._cache: tuple[int, dict[str, np.ndarray]] | None = None

    def __len__(self) -> int:
        return int(self.offsets[-1])

    def shard(self, k: int) -> dict[str, np.ndarray]:
        if self._cache is None or self._cache[0] != k:
            self._cache = (k, load_shard(self.files[k]))
        return self._cache[1]

    def shards(self) -> Iterator[dict[str, np.ndarray]]:
        for k in range(len(self.files)):
            yield self.shard(k)

    def __getitem__(self, i: int) -> dict[str, np.ndarray]:
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"object index {i} out of range for {len(self)} objects")
        k = int(np.searchsorted(self.offsets, i, side="right") - 1)
        data = self.shard(k)
        j = i - int(self.offsets[k])
        item = {key: value[j] for key, value in data.items()}
        item["occupancy_grid"] = unpack_occupancy(item["occupancy"], self.resolution)
        return item


def write_shard(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write a compressed npz through a temporary file in the same folder, then rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
