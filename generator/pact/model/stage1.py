"""Stage 1 as a whole: its configuration (one JSON per size), building its three models,
and generating part occupancies from an image (+ optional mask).

``load_config("small")`` / ``load_config("full")`` read ``configs/<name>.json`` in this
package; any other argument is a path to a JSON file of the same layout.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn as nn
from safetensors.torch import load_file, save_file

from generator.pact.model import model_configs
from generator.pact.model.flow import FlowTrainConfig, SamplerConfig, sample
from generator.pact.model.image_encoder import ViTConfig
from generator.pact.model.part_flow import PartFlowConfig
from generator.pact.model.ss_vae import SSVAEConfig, SSVAETrainConfig

CONFIG_DIR = Path(__file__).parents[1] / "configs"


class ConfigMismatchError(ValueError):
    """Two sub-configs disagree (e.g. VAE latent shape vs flow latent shape)."""


@dataclass
class Stage1Config:
    vae: SSVAEConfig = field(default_factory=SSVAEConfig)
    image_encoder: ViTConfig = field(default_factory=ViTConfig)
    flow: PartFlowConfig = field(default_factory=PartFlowConfig)
    vae_train: SSVAETrainConfig = field(default_factory=SSVAETrainConfig)
    flow_train: FlowTrainConfig = field(default_factory=FlowTrainConfig)
    sampler: SamplerConfig = field(default_factory=SamplerConfig)

    def check(self) -> Stage1Config:
        v, e, f = self.vae, self.image_encoder, self.flow
        pairs = {
            "flow.latent_channels vs vae.latent_channels": (f.latent_channels, v.latent_channels),
            "flow.latent_resolution vs vae latent": (f.latent_resolution, v.latent_resolution),
            "flow.cond_dim vs image_encoder.width": (f.cond_dim, e.width),
            "flow.cond_grid vs image_encoder grid": (f.cond_grid, e.grid),
            "flow.cond_prefix_tokens vs image_encoder prefix": (
                f.cond_prefix_tokens,
                e.num_prefix_tokens,
            ),
        }
        bad = {k: a for k, a in pairs.items() if a[0] != a[1]}
        if bad:
            raise ConfigMismatchError(f"inconsistent stage-1 config: {bad}")
        return self

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


_SECTIONS = {
    "vae": SSVAEConfig,
    "image_encoder": ViTConfig,
    "flow": PartFlowConfig,
    "vae_train": SSVAETrainConfig,
    "flow_train": FlowTrainConfig,
    "sampler": SamplerConfig,
}


def config_from_dict(data: dict[str, Any]) -> Stage1Config:
    return Stage1Config(**model_configs.sections_from_dict(_SECTIONS, data, "stage-1")).check()


def load_config(name_or_path: str | Path) -> Stage1Config:
    return config_from_dict(model_configs.read_config_json(name_or_path, CONFIG_DIR, "stage-1"))


def build_stage1(cfg: Stage1Config) -> dict[str, nn.Module]:
    """The three stage-1 networks, by role: ``vae``, ``image_encoder``, ``flow``."""
    cfg.check()
    return {
        "vae": model_configs.build("ss_vae", cfg.vae),
        "image_encoder": model_configs.build("vit", cfg.image_encoder),
        "flow": model_configs.build("part_flow", cfg.flow),
    }


@dataclass
class LatentStats:
    """Per-channel normalisation of the VAE latents the flow model is trained on:
    the flow sees ``(z - mean) / std``; sampling returns that and ``denormalize`` maps it
    back before decoding. ``mean``/``std`` (C,); identity when never set."""

    mean: tuple[float, ...] = ()
    std: tuple[float, ...] = ()

    def _view(self, values: tuple[float, ...], like: torch.Tensor) -> torch.Tensor | None:
        if not values:
            return None
        t = torch.tensor(values, dtype=like.dtype, device=like.device)
        return t.view(len(values), 1, 1, 1)  # (C, 1, 1, 1), broadcasts over (..., C, r, r, r)

    def normalize(self, z: torch.Tensor) -> torch.Tensor:
        """z (..., C, r, r, r) -> (z - mean) / std."""
        m, s = self._view(self.mean, z), self._view(self.std, z)
        return z if m is None else (z - m) / s

    def denormalize(self, x: torch.Tensor) -> torch.Tensor:
        m, s = self._view(self.mean, x), self._view(self.std, x)
        return x if m is None else x * s + m


@torch.no_grad()
def generate_parts(
    models: dict[str, nn.Module],
    images: torch.Tensor,
    mask: torch.Tensor | None = None,
    sampler: SamplerConfig | None = None,
    generator: torch.Generator | None = None,
    exists_threshold: float = 0.5,
    latent_stats: LatentStats | None = None,
    callback: Any = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """images (B, 3, H, W) in [0, 1], mask (B, H', W') ids or None ->
    occupancy (B, T, R, R, R) bool (dropped slots all False), exists (B, T) bool.
    ``callback(step, t, features)`` receives each sampling step's last-block features."""
    cond = models["image_encoder"](images)  # (B, N_img, D_img)
    latents, exists_logits = sample(
        models["flow"], cond, mask, sampler, generator, callback=callback
    )
    if latent_stats is not None:
        latents = latent_stats.denormalize(latents)
    occ = models["vae"].decode_parts(latents) > 0  # (B, T, R, R, R)
    exists = torch.sigmoid(exists_logits) > exists_threshold  # (B, T)
    return occ & exists[..., None, None, None], exists


def tidy_parts(
    occ: np.ndarray,
    exists: np.ndarray,
    mask_ids: np.ndarray | None = None,
    min_voxels: int = 8,
) -> tuple[np.ndarray, np.ndarray]:
    """Stage-1 output -> disjoint part occupancies, before meshing.

    ``occ`` (T, R, R, R) bool (dropped slots already all False), ``exists`` (T,) bool;
    ``mask_ids`` the ids present in the input's part mask (0 background, slot + 1 parts).

    - With a mask the slots it shows are the parts, whatever the existence logits say
      (the mask is the user's part list); the others are dropped.
    - A voxel claimed by several slots goes to one: a movable part (slot >= 1) wins over
      the base, and among movable parts the lower slot wins (the base's shell around a
      door or drawer is where stage 1 errs; overlapping links fail validation).
    - A movable part (slot >= 1) keeps its largest 26-connected component of at least
      ``min_voxels`` voxels (a door or a drawer is one rigid piece; a stray chunk
      stretches its box over its siblings); the base keeps every component of at least
      ``min_voxels`` voxels (its largest one when all are smaller): specks become no part.

    Returns (occupancy, exists) with ``exists[k] == occupancy[k].any()``.
    """
    from scipy import ndimage

    occ = np.asarray(occ, bool).copy()
    exists = np.asarray(exists, bool).copy()
    T = len(occ)
    if mask_ids is not None:
        slots = {int(i) - 1 for i in np.asarray(mask_ids).ravel() if 0 < int(i) <= T}
        exists = np.array([k in slots for k in range(T)])
    occ &= exists[:, None, None, None]
    claimed = np.zeros(occ.shape[1:], bool)
    for k in [*range(1, T), 0]:  # movable parts first (lower slot first), the base last
        occ[k] &= ~claimed
        labels, n = ndimage.label(occ[k], structure=np.ones((3, 3, 3), bool))
        if n:
            sizes = np.bincount(labels.ravel())[1:]
            keep = np.flatnonzero(sizes >= min_voxels) + 1
            if k > 0 and len(keep) > 1:
                keep = [int(np.argmax(sizes)) + 1]
            if len(keep) == 0 and k == 0:
                keep = [int(np.argmax(sizes)) + 1]
            occ[k] = np.isin(labels, keep)
        claimed |= occ[k]
    return occ, occ.reshape(T, -1).any(axis=1)


#: ``close_surface`` fills a cell between occupied cells along at least this many axes
CLOSE_AXES = 2


def _between(union: np.ndarray, axis: int) -> np.ndarray:
    """Cells of ``union`` (R, R, R) that lie between two occupied cells along ``axis``
    (the occupied cells included)."""
    ahead = np.maximum.accumulate(union, axis=axis)
    behind = np.flip(np.maximum.accumulate(np.flip(union, axis), axis=axis), axis)
    return ahead & behind


def close_surface(occ: np.ndarray, axes: int = CLOSE_AXES) -> np.ndarray:
    """Part occupancies (T, R, R, R) with the holes in the object's outer shell filled.

    The small model draws a cabinet of many drawers as a shell full of holes (one test
    cabinet's base: 2807 surface voxels, its main piece a surface of genus 32), and stage 2 decodes
    them as holes: the asset is debris however good its parts' layout. The object's
    *hull* is every cell that lies between occupied cells along at least ``axes`` of the
    three axes (``_between``): a hole in a side wall lies between the front and back
    walls and between top and bottom, so it is inside; a desk's kneehole, open at the
    front and the floor, lies between cells along one axis only (the pedestals), so it
    stays open (so does a table's space between its legs). The hull's cells that touch
    its outside (26-neighbours) and are empty are added, each to the part holding the
    nearest occupied cell (a hole in a drawer's front closes with the drawer) when that
    part is the base or the cell touches the part (a movable part stays one piece), else
    to the base. The hull's interior is not filled (stage 2 reads surface voxels).
    An open compartment that lies between walls on two axes is closed too. Returns a
    new array; the parts stay disjoint.
    """
    from scipy import ndimage

    occ = np.array(occ, bool)
    union = occ.any(axis=0)
    if not union.any():
        return occ
    votes = sum(_between(union, a).astype(np.int8) for a in range(3))
    hull = union | (votes >= axes)
    cube = np.ones((3, 3, 3), bool)
    shell = hull & ~ndimage.binary_erosion(hull, cube, border_value=0)
    added = np.argwhere(shell & ~union)
    if len(added) == 0:
        return occ
    owner = np.argmax(occ, axis=0)  # the part of each occupied cell
    _, nearest = ndimage.distance_transform_edt(~union, return_indices=True)
    part = owner[tuple(nearest[:, added[:, 0], added[:, 1], added[:, 2]])]
    for k in np.unique(part[part > 0]):
        sel = part == k
        touches = ndimage.binary_dilation(occ[k], cube)[tuple(added[sel].T)]
        part[np.flatnonzero(sel)[~touches]] = 0
    occ[part, added[:, 0], added[:, 1], added[:, 2]] = True
    return occ


# --- the stage-1 checkpoint: image encoder + flow in one folder ------------------------

STAGE1_SCHEMA = "pact.stage1"


def save_stage1(
    models: dict[str, nn.Module],
    cfg: Stage1Config,
    path: str | Path,
    latent_stats: LatentStats | None = None,
    dtype: torch.dtype = torch.float32,
    extra: dict[str, Any] | None = None,
) -> Path:
    """Write ``image_encoder`` + ``flow`` to folder ``path``: ``model.safetensors`` (keys
    ``image_encoder.*``, ``flow.*``, stored in ``dtype``) and ``config.json`` (the whole
    stage-1 config, the latent statistics). Written under a temporary name, then renamed."""
    path = Path(path)
    tensors = {
        f"{role}.{k}": v.detach()
        .to("cpu", dtype if v.is_floating_point() else v.dtype)
        .contiguous()
        for role in ("image_encoder", "flow")
        for k, v in models[role].state_dict().items()
    }
    stats = latent_stats or LatentStats()
    meta = {
        "schema": STAGE1_SCHEMA,
        "version": 1,
        "config": cfg.to_dict(),
        "latent_stats": {"mean": list(stats.mean), "std": list(stats.std)},
        "dtype": str(dtype).removeprefix("torch."),
        "extra": extra or {},
    }
    tmp = path.with_name(path.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    save_file(tensors, str(tmp / "model.safetensors"))
    (tmp / "config.json").write_text(json.dumps(meta, indent=2))
    if path.exists():
        shutil.rmtree(path)
    tmp.rename(path)
    return path


def load_stage1(
    path: str | Path, device: torch.device | str = "cpu"
) -> tuple[dict[str, nn.Module], Stage1Config, LatentStats]:
    """Read a ``save_stage1`` folder: models ``image_encoder`` and ``flow`` (float32),
    the config and the latent statistics. The VAE is a separate checkpoint."""
    path = Path(path)
    meta_file = path / "config.json"
    if not meta_file.is_file():
        raise FileNotFoundError(f"{path}: no config.json; not a stage-1 checkpoint folder")
    meta = json.loads(meta_file.read_text())
    if meta.get("schema") != STAGE1_SCHEMA:
        raise ValueError(f"{meta_file}: schema {meta.get('schema')!r}, expected {STAGE1_SCHEMA!r}")
    cfg_dict = dict(meta["config"])
    cfg_dict["image_encoder"] = {**cfg_dict["image_encoder"], "weights": None}
    cfg = config_from_dict(cfg_dict)
    state = load_file(str(path / "model.safetensors"), device=str(device))
    models = {}
    for role, name in (("image_encoder", "vit"), ("flow", "part_flow")):
        model = model_configs.build(name, getattr(cfg, role))
        own = {k[len(role) + 1 :]: v for k, v in state.items() if k.startswith(role + ".")}
        model.load_state_dict(own, strict=True)  # casts float16 files back to float32
        models[role] = model.to(device).eval()
    s = meta.get("latent_stats", {})
    stats = LatentStats(tuple(s.get("mean", ())), tuple(s.get("std", ())))
    return models, cfg, stats
