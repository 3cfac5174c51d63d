"""Structure-conditioned flow transformer (PAct stage 2, paper sec. 4.3.1).

Input: one object's structured latents, all parts together. Every part's token voxels
(``slat_data``) carry a C = 8 latent; they are grouped into p x p x p voxel patches
(p = 4 in the small config: the R = 32 grid has (R / p)^3 = 512 patch positions), one
token per (part, patch) holding at least one token voxel. Token input = the patch's
p^3 * C noisy latents (zero at voxels that are not token voxels) concatenated with the
patch's structure (two p^3 bit maps: token voxel, interior voxel), projected to width D.

Token count bound: a part contributes at most (R / p)^3 = 512 tokens; on the 1,400-object
training set (first 8 slots) an object has 255 tokens on average, 410 at the 95th
percentile and 668 at most (p = 4). ``max_tokens`` (768 small) is enforced in training
(a larger object is an error that names the count); at inference any count runs, with
attention memory growing as L^2.

Each token gets
  * a learned PART EMBEDDING ``part_embed[slot]`` (max_parts x D), added to every token
    of that part (separate from stage 1's identity embedding), and
  * a fixed 3D sinusoidal code of its patch position.

Blocks (TRELLIS ``ModulatedTransformerCrossBlock``): adaLN-modulated global
self-attention over ALL tokens of the object (the global object token sequence, with a
key-padding mask for batching), cross-attention to image tokens, adaLN-modulated FFN.
The last block's token features (B, L, D) are returned for the articulation head.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import torch
import torch.nn as nn
import torch.nn.functional as F

from generator.pact.model.model_configs import register
from generator.pact.model.transformer import (
    MLP,
    CrossAttention,
    RMSNorm,
    TimestepEmbedder,
    check_prediction,
    init_adaln_transformer,
    output_to_velocity,
    sincos_3d,
)


@dataclass
class Stage2FlowConfig:
    max_parts: int = 8
    latent_channels: int = 8  # C
    patch_size: int = 4  # p
    resolution: int = 32  # R (voxel grid)
    width: int = 160  # D
    depth: int = 6
    heads: int = 5
    mlp_ratio: float = 4.0
    qk_norm: bool = True
    cond_dim: int = 128  # D_img
    max_tokens: int = 768
    # "velocity" (TRELLIS) or "x0": see PartFlowConfig.predict; a small-config token
    # (p^3 C = 512 latents) is wider than the model, so a velocity output cannot carry eps
    predict: str = "velocity"
    x0_t_min: float = 0.02

    @property
    def grid(self) -> int:
        return self.resolution // self.patch_size

    @property
    def patch_voxels(self) -> int:
        return self.patch_size**3


class TokenBatch(NamedTuple):
    """A padded batch of objects' tokens.

    x (B, L, p^3 * C) latents, active (B, L, p^3) bool token voxels, interior (B, L, p^3)
    bool, slot (B, L) long part slot, patch (B, L) long patch index (x * g^2 + y * g + z),
    valid (B, L) bool (False = padding).
    """

    x: torch.Tensor
    active: torch.Tensor
    interior: torch.Tensor
    slot: torch.Tensor
    patch: torch.Tensor
    valid: torch.Tensor

    def to(self, device: torch.device | str) -> TokenBatch:
        return TokenBatch(*(t.to(device) for t in self))

    def with_x(self, x: torch.Tensor) -> TokenBatch:
        return self._replace(x=x)


class Stage2Output(NamedTuple):
    velocity: torch.Tensor  # (B, L, p^3 * C)
    features: torch.Tensor  # (B, L, D), last-block token features


class MaskedSelfAttention(nn.Module):
    def __init__(self, dim: int, heads: int, qk_norm: bool) -> None:
        super().__init__()
        self.heads = heads
        self.qkv = nn.Linear(dim, 3 * dim)
        self.out = nn.Linear(dim, dim)
        self.q_norm = RMSNorm(dim // heads) if qk_norm else nn.Identity()
        self.k_norm = RMSNorm(dim // heads) if qk_norm else nn.Identity()

    def forward(self, x: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
        B, N, D = x.shape  # (B, N, D), valid (B, N)
        qkv = self.qkv(x).view(B, N, 3, self.heads, D // self.heads)
        q, k, v = qkv.permute(2, 0, 3, 1, 4).unbind(0)  # each (B, H, N, hd)
        q, k = self.q_norm(q), self.k_norm(k)
        mask = valid[:, None, None, :]  # (B, 1, 1, N): keys that exist
        y = F.scaled_dot_product_attention(q, k, v, attn_mask=mask)
        return self.out(y.transpose(1, 2).reshape(B, N, D))


def modulate(x: torch.Tensor, shift: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    return x * (1 + scale[:, None]) + shift[:, None]  # x (B, L, D), shift/scale (B, D)


class Stage2Block(nn.Module):
    def __init__(self, cfg: Stage2FlowConfig) -> None:
        super().__init__()
        D = cfg.width
        self.norm1 = nn.LayerNorm(D, elementwise_affine=False, eps=1e-6)
        self.self_attn = MaskedSelfAttention(D, cfg.heads, cfg.qk_norm)
        self.norm2 = nn.LayerNorm(D, eps=1e-6)
        self.cross_attn = CrossAttention(D, cfg.cond_dim, cfg.heads)
        self.norm3 = nn.LayerNorm(D, elementwise_affine=False, eps=1e-6)
        self.mlp = MLP(D, int(D * cfg.mlp_ratio), approximate="tanh")
        self.adaLN = nn.Sequential(nn.SiLU(), nn.Linear(D, 6 * D))

    def forward(
        self, h: torch.Tensor, c: torch.Tensor, ctx: torch.Tensor, valid: torch.Tensor
    ) -> torch.Tensor:
        """h (B, L, D), c (B, D), ctx (B, N_img, D_img), valid (B, L)."""
        shift1, scale1, gate1, shift2, scale2, gate2 = self.adaLN(c).chunk(6, dim=-1)
        h = h + gate1[:, None] * self.self_attn(modulate(self.norm1(h), shift1, scale1), valid)
        h = h + self.cross_attn(self.norm2(h), ctx)
        h = h + gate2[:, None] * self.mlp(modulate(self.norm3(h), shift2, scale2))
        return h


@register("stage2_flow", Stage2FlowConfig)
class Stage2FlowTransformer(nn.Module):
    def __init__(self, cfg: Stage2FlowConfig) -> None:
        super().__init__()
        if cfg.resolution % cfg.patch_size:
            raise ValueError("resolution must be a multiple of patch_size")
        check_prediction(cfg.predict)
        self.cfg = cfg
        D, pv = cfg.width, cfg.patch_voxels
        self.input_proj = nn.Linear(pv * cfg.latent_channels + 2 * pv, D)
        self.part_embed = nn.Parameter(torch.randn(cfg.max_parts, D) * 0.02)  # (T, D)
        self.register_buffer("pos", sincos_3d(cfg.grid, D), persistent=False)  # (g^3, D)
        self.t_embed = TimestepEmbedder(D)
        self.blocks = nn.ModuleList(Stage2Block(cfg) for _ in range(cfg.depth))
        self.final_norm = nn.LayerNorm(D, elementwise_affine=False, eps=1e-6)
        self.final_adaLN = nn.Sequential(nn.SiLU(), nn.Linear(D, 2 * D))
        self.out_proj = nn.Linear(D, pv * cfg.latent_channels)
        self._init_weights()

    def _init_weights(self) -> None:
        init_adaln_transformer(self, zero=(self.final_adaLN[-1], self.out_proj))

    def embed_tokens(self, tokens: TokenBatch) -> torch.Tensor:
        """Input tokens -> (B, L, D): projection + part embedding + position code."""
        struct = torch.cat([tokens.active, tokens.interior], dim=-1).to(tokens.x.dtype)
        h = self.input_proj(torch.cat([tokens.x, struct], dim=-1))  # (B, L, D)
        h = h + self.part_embed[tokens.slot].to(h.dtype)  # the part's embedding, every token
        return h + self.pos[tokens.patch].to(h.dtype)

    def forward(
        self,
        tokens: TokenBatch,
        t: torch.Tensor,
        cond: torch.Tensor | None,
        cond_drop: torch.Tensor | None = None,
    ) -> Stage2Output:
        """tokens (noisy latents in ``x``), t (B,) in [0, 1], cond (B, N_img, D_img) image
        tokens or None (the null condition: zeros), cond_drop (B,) bool zeroes some."""
        B, L = tokens.slot.shape
        if self.training and L > self.cfg.max_tokens:
            raise ValueError(f"{L} tokens exceed max_tokens={self.cfg.max_tokens}")
        h = self.embed_tokens(tokens)
        c = self.t_embed(t)  # (B, D)
        if cond is None:
            ctx = torch.zeros(B, 1, self.cfg.cond_dim, device=h.device, dtype=h.dtype)
        elif cond_drop is not None:
            ctx = torch.where(cond_drop[:, None, None], torch.zeros_like(cond), cond)
        else:
            ctx = cond
        valid = tokens.valid
        for block in self.blocks:
            h = block(h, c, ctx, valid)
        shift, scale = self.final_adaLN(c).chunk(2, dim=-1)
        out = self.out_proj(modulate(self.final_norm(h), shift, scale))  # (B, L, p^3 C)
        out = output_to_velocity(out, tokens.x, t, self.cfg.predict, self.cfg.x0_t_min)
        # only token voxels carry latents: zero the velocity elsewhere
        C = self.cfg.latent_channels
        keep = tokens.active.repeat_interleave(C, dim=-1) & valid[..., None]
        return Stage2Output(out * keep.to(out.dtype), h)
