"""Stage 1 as a whole: its configuration (one JSON per size), building its three models,
and generating part occupancies from an image (+ optional mask).

``load_config("small")`` / ``load_config("full")`` read ``configs/<name>.json`` in this
package; any other argument is a path to a JSON file of the same layout.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
import torch.nn as nn

from . import registry
from .flow import FlowTrainConfig, SamplerConfig, sample
from .image_encoder import ViTConfig
from .part_flow import PartFlowConfig
from .ss_vae import SSVAEConfig, SSVAETrainConfig

CONFIG_DIR = Path(__file__).parent / "configs"


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
    unknown = set(data) - set(_SECTIONS)
    if unknown:
        raise ValueError(f"unknown stage-1 config sections {sorted(unknown)}")
    kwargs = {k: registry.config_from_dict(cls, data.get(k, {})) for k, cls in _SECTIONS.items()}
    return Stage1Config(**kwargs).check()


def load_config(name_or_path: str | Path) -> Stage1Config:
    path = Path(name_or_path)
    if not path.suffix:
        path = CONFIG_DIR / f"{name_or_path}.json"
    if not path.is_file():
        known = sorted(p.stem for p in CONFIG_DIR.glob("*.json"))
        raise FileNotFoundError(f"no stage-1 config {name_or_path!r}; packaged: {known}")
    return config_from_dict(json.loads(path.read_text()))


def build_stage1(cfg: Stage1Config) -> dict[str, nn.Module]:
    """The three stage-1 networks, by role: ``vae``, ``image_encoder``, ``flow``."""
    cfg.check()
    return {
        "vae": registry.build("ss_vae", cfg.vae),
        "image_encoder": registry.build("vit", cfg.image_encoder),
        "flow": registry.build("part_flow", cfg.flow),
    }


@torch.no_grad()
def generate_parts(
    models: dict[str, nn.Module],
    images: torch.Tensor,
    mask: torch.Tensor | None = None,
    sampler: SamplerConfig | None = None,
    generator: torch.Generator | None = None,
    exists_threshold: float = 0.5,
) -> tuple[torch.Tensor, torch.Tensor]:
    """images (B, 3, H, W) in [0, 1], mask (B, H', W') ids or None ->
    occupancy (B, T, R, R, R) bool (dropped slots all False), exists (B, T) bool."""
    cond = models["image_encoder"](images)  # (B, N_img, D_img)
    latents, exists_logits = sample(models["flow"], cond, mask, sampler, generator)
    occ = models["vae"].decode_parts(latents) > 0  # (B, T, R, R, R)
    exists = torch.sigmoid(exists_logits) > exists_threshold  # (B, T)
    return occ & exists[..., None, None, None], exists
