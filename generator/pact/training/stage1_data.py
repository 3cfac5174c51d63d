"""Stage-1 training data: a torch ``Dataset`` over a dataset folder (docs/dataset.md).

One item is one (object, view) pair: index ``i = object * views + view``, so drawing
indices uniformly is "a random object, a random view of it". Items hold

- ``image``      (3, S, S) float32 in [0, 1] (what ``ImageEncoder`` expects; resized to
                 ``image_size`` when the dataset's images have another size),
- ``mask``       (S, S) int64 part ids: 0 background, 1 base, 2.. = slot + 1,
- ``occupancy``  (T, R, R, R) bool, slot k = part k, unused slots all False,
- ``exists``     (T,) bool, slot used,
- ``object``     int, the object's index in this split (keys the latent cache).

T is the model's ``max_parts`` (8 in the small config). Objects with more than T parts
are SKIPPED (not truncated): their masks would hold ids the part embedding cannot look
up, and dropping parts would teach the model to miss parts. In the 1400-object training
set that is about 1 % of the objects; ``skipped`` lists them.

Train/validation split: an object is in ``val`` when ``crc32(object_id) % 10_000 <
val_fraction * 10_000``; stable across runs, machines and dataset sizes. (The separate
test split of held-out procedural objects is ``generator.data.test_split``.)

Shards are read lazily, only the arrays needed here, and kept in memory (1400 objects x
6 views at 128 px: ~0.6 GB). Nothing here is random: samplers and the training loop own
the randomness.
"""

from __future__ import annotations

import logging
import zlib
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import Dataset as TorchDataset

from generator.data.shards import Dataset as ShardDataset
from generator.data.shards import unpack_occupancy

log = logging.getLogger(__name__)

_KEYS = ("images", "masks", "occupancy")


def in_val_split(object_id: str, val_fraction: float) -> bool:
    """Stable hash split: True for the held-out validation objects."""
    return zlib.crc32(object_id.encode()) % 10_000 < int(round(val_fraction * 10_000))


class Stage1Dataset(TorchDataset):
    """(object, view) items of one split of a dataset folder; see the module docstring."""

    def __init__(
        self,
        root: str | Path,
        max_parts: int = 8,
        split: str = "train",
        val_fraction: float = 0.05,
        image_size: int | None = None,
        limit: int | None = None,
    ) -> None:
        if split not in ("train", "val", "all"):
            raise ValueError(f"split must be 'train', 'val' or 'all', got {split!r}")
        self.shards = ShardDataset(root)
        m = self.shards.manifest
        self.root = Path(root)
        self.max_parts = max_parts
        self.resolution = int(m["resolution"])
        self.views = int(m["views"])
        self.source_size = int(m["image_size"])
        self.image_size = image_size or self.source_size
        self._cache: dict[int, dict[str, np.ndarray]] = {}

        # index: (shard, row) of every kept object; part counts come from a cheap read
        # of one small array per shard (npz members decompress independently)
        keep: list[tuple[int, int]] = []
        ids: list[str] = []
        counts: list[int] = []
        self.skipped: list[str] = []
        for k, file in enumerate(self.shards.files):
            with np.load(file, allow_pickle=False) as z:
                pc = z["part_count"].astype(np.int64)
                oid = z["object_ids"]
            for j, (o, c) in enumerate(zip(oid.tolist(), pc.tolist(), strict=True)):
                if split != "all" and in_val_split(o, val_fraction) != (split == "val"):
                    continue
                if c > max_parts:
                    self.skipped.append(o)
                    continue
                keep.append((k, j))
                ids.append(o)
                counts.append(c)
        if limit is not None:
            keep, ids, counts = keep[:limit], ids[:limit], counts[:limit]
        if not keep:
            raise ValueError(f"{root}: no objects in split {split!r} with <= {max_parts} parts")
        self.index = np.asarray(keep, dtype=np.int64)  # (N, 2): shard, row
        self.object_ids = ids
        self.part_count = np.asarray(counts, dtype=np.int64)  # (N,)
        log.info(
            "%s [%s]: %d objects, %d skipped (> %d parts)",
            root,
            split,
            len(ids),
            len(self.skipped),
            max_parts,
        )

    # --- raw access ---------------------------------------------------------------------

    def _shard(self, k: int) -> dict[str, np.ndarray]:
        if k not in self._cache:
            with np.load(self.shards.files[k], allow_pickle=False) as z:
                self._cache[k] = {key: z[key] for key in _KEYS}
        return self._cache[k]

    @property
    def num_objects(self) -> int:
        return len(self.index)

    def __len__(self) -> int:
        return self.num_objects * self.views

    def occupancy(self, obj: int) -> tuple[np.ndarray, np.ndarray]:
        """Object ``obj``'s part grids (T, R, R, R) bool and used slots (T,) bool."""
        k, j = self.index[obj]
        T, c = self.max_parts, int(self.part_count[obj])
        packed = self._shard(int(k))["occupancy"][int(j), :c]  # (c, R^3/8)
        occ = np.zeros((T, self.resolution, self.resolution, self.resolution), dtype=bool)
        occ[:c] = unpack_occupancy(packed, self.resolution)
        exists = np.arange(T) < c
        return occ, exists

    def part_grid(self, obj: int, slot: int) -> np.ndarray:
        """One part's (R, R, R) bool grid."""
        k, j = self.index[obj]
        packed = self._shard(int(k))["occupancy"][int(j), slot]
        return unpack_occupancy(packed, self.resolution)

    def view(self, obj: int, view: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Image (3, S, S) float in [0, 1] and mask (S, S) int64 of one view."""
        k, j = self.index[obj]
        data = self._shard(int(k))
        image = torch.from_numpy(data["images"][int(j), view]).permute(2, 0, 1).float() / 255.0
        mask = torch.from_numpy(data["masks"][int(j), view].astype(np.int64))
        if self.image_size != self.source_size:
            S = self.image_size
            image = F.interpolate(image[None], size=(S, S), mode="bilinear", antialias=True)[0]
            mask = F.interpolate(mask[None, None].float(), size=(S, S), mode="nearest")[0, 0]
            mask = mask.long()
        return image.clamp(0.0, 1.0), mask

    # --- torch Dataset ------------------------------------------------------------------

    def __getitem__(self, i: int) -> dict[str, torch.Tensor | int]:
        obj, v = divmod(int(i), self.views)
        if not 0 <= obj < self.num_objects:
            raise IndexError(f"item {i} out of range for {len(self)} items")
        image, mask = self.view(obj, v)
        occ, exists = self.occupancy(obj)
        return {
            "image": image,  # (3, S, S)
            "mask": mask,  # (S, S)
            "occupancy": torch.from_numpy(occ),  # (T, R, R, R)
            "exists": torch.from_numpy(exists),  # (T,)
            "object": obj,
        }

    def batch(self, items: list[int]) -> dict[str, torch.Tensor]:
        """Stack items into a batch (the same as DataLoader's default collate)."""
        rows = [self[i] for i in items]
        return {
            k: torch.stack([r[k] for r in rows])
            if isinstance(rows[0][k], torch.Tensor)
            else torch.tensor([r[k] for r in rows])
            for k in rows[0]
        }

    def part_slots(self) -> np.ndarray:
        """(P, 2) (object, slot) of every used part slot: the VAE's training samples."""
        obj = np.repeat(np.arange(self.num_objects), self.part_count)
        slot = np.concatenate([np.arange(c) for c in self.part_count])
        return np.stack([obj, slot], axis=1)
