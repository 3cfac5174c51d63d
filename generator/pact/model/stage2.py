"""Stage 2 as a whole: configuration (one JSON per size), building its four networks,
tokenizing an object's structured latents, the joint training step (L_fm + lambda L_art)
and sampling with feature aggregation for the articulation head.

Networks (``build_stage2``): ``vae`` (SLAT VAE, ``slat_vae``), ``image_encoder`` (a ViT of
stage 1's architecture, trained jointly with the stage-2 flow: stage 1's encoder is
trained for a different task and its checkpoints ship separately, so stage 2 keeps its
own), ``flow`` (``stage2_flow``) and ``head`` (``articulation``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch
import torch.nn as nn

from generator.pact.model import model_configs
from generator.pact.model.articulation import (
    ArticulationHeadConfig,
    ArticulationTargets,
    FeatureAggregator,
    articulation_loss,
    pool_parts,
)
from generator.pact.model.flow import guided_at, noisy, rand, randn, sample_t
from generator.pact.model.image_encoder import ViTConfig
from generator.pact.model.slat_vae import SlatVAEConfig, SlatVAETrainConfig, shell_voxels
from generator.pact.model.stage1 import ConfigMismatchError
from generator.pact.model.stage2_flow import Stage2FlowConfig, Stage2FlowTransformer, TokenBatch

CONFIG_DIR = Path(__file__).parents[1] / "configs"


@dataclass
class Stage2TrainConfig:
    t_mean: float = 1.0
    t_std: float = 1.0
    p_uncond: float = 0.1
    art_weight: float = 1.0  # lambda
    lr: float = 3e-4
    batch_size: int = 4
    bf16: bool = True


@dataclass
class Stage2SamplerConfig:
    steps: int = 25
    cfg_scale: float = 3.0
    rescale_t: float = 1.0
    agg_steps: int = 20  # S: features averaged over the last S steps
    # guidance only at steps whose t lies in [lo, hi] (flow.guided_at); the others v_c
    cfg_interval: tuple[float, float] = (0.0, 1.0)


@dataclass
class Stage2Config:
    vae: SlatVAEConfig = field(default_factory=SlatVAEConfig)
    vae_train: SlatVAETrainConfig = field(default_factory=SlatVAETrainConfig)
    image_encoder: ViTConfig = field(default_factory=ViTConfig)
    flow: Stage2FlowConfig = field(default_factory=Stage2FlowConfig)
    head: ArticulationHeadConfig = field(default_factory=ArticulationHeadConfig)
    flow_train: Stage2TrainConfig = field(default_factory=Stage2TrainConfig)
    sampler: Stage2SamplerConfig = field(default_factory=Stage2SamplerConfig)

    def check(self) -> Stage2Config:
        pairs = {
            "flow.latent_channels vs vae.latent_channels": (
                self.flow.latent_channels,
                self.vae.latent_channels,
            ),
            "flow.resolution vs vae.resolution": (self.flow.resolution, self.vae.resolution),
            "flow.cond_dim vs image_encoder.width": (self.flow.cond_dim, self.image_encoder.width),
            "head.in_dim vs flow.width": (self.head.in_dim, self.flow.width),
        }
        bad = {k: v for k, v in pairs.items() if v[0] != v[1]}
        if bad:
            raise ConfigMismatchError(f"inconsistent stage-2 config: {bad}")
        if not 1 <= self.sampler.agg_steps <= self.sampler.steps:
            raise ConfigMismatchError("sampler.agg_steps must be in 1..sampler.steps")
        return self

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


_CLASSES = {
    "vae": SlatVAEConfig,
    "vae_train": SlatVAETrainConfig,
    "image_encoder": ViTConfig,
    "flow": Stage2FlowConfig,
    "head": ArticulationHeadConfig,
    "flow_train": Stage2TrainConfig,
    "sampler": Stage2SamplerConfig,
}


def config_from_dict(data: dict[str, Any]) -> Stage2Config:
    return Stage2Config(**model_configs.sections_from_dict(_CLASSES, data, "stage-2")).check()


def load_config(name_or_path: str | Path) -> Stage2Config:
    """``load_config("stage2_small")`` reads configs/stage2_small.json; else a JSON path."""
    return config_from_dict(model_configs.read_config_json(name_or_path, CONFIG_DIR, "stage-2"))


def build_stage2(cfg: Stage2Config) -> dict[str, nn.Module]:
    cfg.check()
    return {
        "vae": model_configs.build("slat_vae", cfg.vae),
        "image_encoder": model_configs.build("vit", cfg.image_encoder),
        "flow": model_configs.build("stage2_flow", cfg.flow),
        "head": model_configs.build("articulation_head", cfg.head),
    }


# --------------------------------------------------------------------------- tokens


class ObjectTokens(NamedTuple):
    """One object's tokens (numpy) and the map from its token voxels to them.

    x (L, p^3 * C) float32, active / interior (L, p^3) bool, slot / patch (L,) int64,
    voxel_token / voxel_within (M,) int64: token and in-patch index of each token voxel.
    """

    x: np.ndarray
    active: np.ndarray
    interior: np.ndarray
    slot: np.ndarray
    patch: np.ndarray
    voxel_token: np.ndarray
    voxel_within: np.ndarray


def tokenize(
    coords: np.ndarray,
    slot: np.ndarray,
    occupancy: np.ndarray,
    cfg: Stage2FlowConfig,
    latents: np.ndarray | None = None,
) -> ObjectTokens:
    """Group token voxels into (part, p^3 patch) tokens.

    coords (M, 3) voxel indices, slot (M,) part slots, occupancy (K, R, R, R) bool,
    latents (M, C) normalized (None: zeros). Tokens are sorted by (slot, patch).
    """
    p, g, C = cfg.patch_size, cfg.grid, cfg.latent_channels
    c = coords.astype(np.int64)
    pc, wc = c // p, c % p
    patch = pc[:, 0] * g * g + pc[:, 1] * g + pc[:, 2]  # (M,)
    within = wc[:, 0] * p * p + wc[:, 1] * p + wc[:, 2]  # (M,)
    key = slot.astype(np.int64) * g**3 + patch
    uniq, inv = np.unique(key, return_inverse=True)
    L = len(uniq)
    x = np.zeros((L, p**3, C), np.float32)
    if latents is not None:
        x[inv, within] = latents
    active = np.zeros((L, p**3), bool)
    active[inv, within] = True
    t_slot, t_patch = uniq // g**3, uniq % g**3
    K = occupancy.shape[0]
    blocks = occupancy.reshape(K, g, p, g, p, g, p).transpose(0, 1, 3, 5, 2, 4, 6)
    blocks = blocks.reshape(K, g**3, p**3)  # (K, g^3, p^3), in-patch order [x, y, z]
    interior = blocks[t_slot, t_patch] & ~active
    return ObjectTokens(
        x.reshape(L, p**3 * C), active, interior, t_slot, t_patch, inv.astype(np.int64), within
    )


def collate(objects: list[ObjectTokens], max_tokens: int) -> TokenBatch:
    """Pad objects' tokens into a TokenBatch (B, L_max, ...)."""
    Lm = max(len(o.slot) for o in objects)
    if Lm > max_tokens:
        raise ValueError(
            f"an object has {Lm} tokens, more than max_tokens={max_tokens}; "
            "use a larger patch_size or max_tokens"
        )
    B = len(objects)
    d, pv = objects[0].x.shape[1], objects[0].active.shape[1]
    x = torch.zeros(B, Lm, d)
    active = torch.zeros(B, Lm, pv, dtype=torch.bool)
    interior = torch.zeros(B, Lm, pv, dtype=torch.bool)
    slot = torch.zeros(B, Lm, dtype=torch.long)
    patch = torch.zeros(B, Lm, dtype=torch.long)
    valid = torch.zeros(B, Lm, dtype=torch.bool)
    for b, o in enumerate(objects):
        n = len(o.slot)
        x[b, :n] = torch.from_numpy(o.x)
        active[b, :n] = torch.from_numpy(o.active)
        interior[b, :n] = torch.from_numpy(o.interior)
        slot[b, :n] = torch.from_numpy(o.slot)
        patch[b, :n] = torch.from_numpy(o.patch)
        valid[b, :n] = True
    return TokenBatch(x, active, interior, slot, patch, valid)


def untokenize(x: np.ndarray, tokens: ObjectTokens, C: int) -> np.ndarray:
    """Token latents (L, p^3 * C) -> per token-voxel latents (M, C)."""
    return x.reshape(len(tokens.slot), -1, C)[tokens.voxel_token, tokens.voxel_within]


def voxels_from_occupancy(occupancy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Token voxels of every part: (K, R, R, R) bool -> coords (M, 3), slot (M,)."""
    coords, slots = [], []
    for k in range(occupancy.shape[0]):
        c = np.argwhere(shell_voxels(occupancy[k]))
        coords.append(c)
        slots.append(np.full(len(c), k, np.int64))
    return np.concatenate(coords), np.concatenate(slots)


def element_mask(tokens: TokenBatch, C: int) -> torch.Tensor:
    """(B, L, p^3 * C) bool: latent entries that exist (token voxels of valid tokens)."""
    return tokens.active.repeat_interleave(C, dim=-1) & tokens.valid[..., None]


# --------------------------------------------------------------------------- training


def training_step(
    models: dict[str, nn.Module],
    tokens: TokenBatch,
    images: torch.Tensor,
    targets: ArticulationTargets,
    cfg: Stage2TrainConfig,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, dict[str, float]]:
    """L = L_fm + lambda L_art on one batch; L_art reads the same forward's (single
    timestep) last-block features. tokens.x holds clean normalized latents x_0."""
    flow: Stage2FlowTransformer = models["flow"]  # type: ignore[assignment]
    B, device = tokens.x.shape[0], tokens.x.device
    C = flow.cfg.latent_channels
    m = element_mask(tokens, C).float()  # (B, L, p^3 C)
    x0 = tokens.x.float() * m
    t = sample_t(B, cfg.t_mean, cfg.t_std, generator, device)  # (B,)
    eps = randn(tuple(x0.shape), generator, device) * m
    drop = rand(B, generator, device) < cfg.p_uncond
    cond = models["image_encoder"](images)  # (B, N_img, D_img)
    out = flow(tokens.with_x(noisy(x0, eps, t)), t, cond, cond_drop=drop)
    fm = ((out.velocity.float() - (eps - x0)).pow(2) * m).sum() / m.sum().clamp(min=1)
    pooled, present = pool_parts(out.features, tokens.slot, tokens.valid, flow.cfg.max_parts)
    art = models["head"](pooled)
    l_art, am = articulation_loss(art, targets, present)
    loss = fm + cfg.art_weight * l_art
    return loss, {"loss": loss.item(), "fm": fm.item(), **am}


# --------------------------------------------------------------------------- sampling


@torch.no_grad()
def sample_stage2(
    flow: Stage2FlowTransformer,
    tokens: TokenBatch,
    cond: torch.Tensor | None,
    cfg: Stage2SamplerConfig | None = None,
    generator: torch.Generator | None = None,
    callback: FeatureAggregator | None = None,
) -> torch.Tensor:
    """Euler sampling from t = 1 to 0 with CFG (v_u + s (v_c - v_u), null = zero image
    tokens) at the steps whose t lies in ``cfg.cfg_interval``, v_c alone at the others.
    Returns normalized latents (B, L, p^3 C), zero where no token voxel.

    ``callback(step_index, t, features)`` gets the conditional branch's last-block
    features (B, L, D) at every step. Deterministic for a given ``generator`` seed.
    """
    cfg = cfg or Stage2SamplerConfig()
    device = tokens.x.device
    B = tokens.x.shape[0]
    m = element_mask(tokens, flow.cfg.latent_channels).float()
    x = randn(tuple(tokens.x.shape), generator, device) * m
    ts = torch.linspace(1.0, 0.0, cfg.steps + 1, dtype=torch.float64)
    ts = cfg.rescale_t * ts / (1.0 + (cfg.rescale_t - 1.0) * ts)
    for i in range(cfg.steps):
        t, t_next = float(ts[i]), float(ts[i + 1])
        tt = torch.full((B,), t, device=device)
        if cond is None or not guided_at(t, cfg.cfg_interval):
            out = flow(tokens.with_x(x), tt, cond)  # unguided: the conditional branch
            v, feats = out.velocity.float(), out.features
        else:
            both = TokenBatch(*(torch.cat([a, a]) for a in tokens.with_x(x)))
            drop = torch.cat([torch.zeros(B, dtype=torch.bool), torch.ones(B, dtype=torch.bool)])
            out = flow(both, torch.cat([tt, tt]), torch.cat([cond, cond]), drop.to(device))
            v_c, v_u = out.velocity.float().chunk(2)
            v, feats = v_u + cfg.cfg_scale * (v_c - v_u), out.features[:B]
        if callback is not None:
            callback(i, t, feats)
        x = (x + (t_next - t) * v) * m
    return x
