"""Part-aware flow transformer (PAct stage 1, paper sec. 4.2).

Input: noisy part latents x_t (B, K, C, r, r, r), one slot per part (K <= T). Each slot is
patchified to L = (r / p)^3 tokens; every token is concatenated with its slot's part
identity embedding E[k] (E in R^{T x d_p}), projected to width D, and given a fixed 3D
sinusoidal code of its position (all parts share the object's grid, so slot k token j
and slot k' token j sit at the same place).

Blocks (TRELLIS ``ModulatedTransformerCrossBlock`` layout): adaLN-modulated
self-attention, cross-attention to the image tokens, adaLN-modulated FFN. Even-indexed
blocks attend globally over all K * L tokens; odd-indexed blocks attend only within a
part (tokens reshaped to (B * K, L, D)). Cross-attention and FFN are per token, so
they do not mix parts in either kind of block.

Mask conditioning: the mask M (B, H, W) holds ids 0 background, 1 base, 2.. movable
parts (id = slot + 1, docs/dataset.md). id m >= 1 looks up row E[m - 1], the SAME row that
tags slot m - 1's latent tokens; background and "no mask" have two extra learned rows
(``mask_extra[0]`` and ``mask_extra[1]``). The (B, H, W, d_p) map is average-pooled to the
image-token grid, projected d_p -> D_img (zero-initialised, so a pretrained network starts
unchanged) and added to the patch tokens of the image encoder output.

Part count: the model always denoises all K slots. Unused slots are trained towards the
VAE latent of an empty grid (they decode to nothing) and a per-slot "exists" logit is
read from the last block's features (mean over the slot's tokens); with no mask the model
decides the parts itself (mask dropout in training, see flow.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import torch
import torch.nn as nn
import torch.nn.functional as F
import torch.utils.checkpoint

from generator.pact.model.model_configs import register
from generator.pact.model.transformer import (
    MLP,
    CrossAttention,
    SelfAttention,
    TimestepEmbedder,
    check_prediction,
    init_adaln_transformer,
    output_to_velocity,
    sincos_3d,
)


@dataclass
class PartFlowConfig:
    max_parts: int = 8  # T, part slots (rows of E)
    latent_channels: int = 8  # C
    latent_resolution: int = 8  # r
    patch_size: int = 2  # p; tokens per part L = (r / p)^3
    part_embed_dim: int = 64  # d_p
    width: int = 192  # D
    depth: int = 8
    heads: int = 6
    mlp_ratio: float = 4.0
    qk_norm: bool = True  # RMS norm on self-attention queries/keys (TRELLIS qk_rms_norm)
    cond_dim: int = 192  # D_img, width of the image tokens
    cond_grid: int = 8  # image-token patch grid side (mask is pooled to it)
    cond_prefix_tokens: int = 1  # cls + register tokens before the patch tokens
    grad_checkpoint: bool = False
    part_embed_std: float = 0.02  # initial scale of E (the latent inputs are unit-scale)
    zero_init_mask_proj: bool = True  # mask projection starts at 0 (image tokens unchanged)
    # What the output layer predicts. "velocity": v = eps - x_0 directly (TRELLIS). "x0": the
    # clean latent x0_hat, returned as the velocity it implies, (x_t - x0_hat) / max(t, t_min).
    # Use "x0" when a token (C p^3 values) is wider than the model (width D): a velocity
    # output must then pass the noise eps through a D-wide bottleneck, which it cannot do,
    # while x_0 is structured and fits (docs/pact.md, "The patch bottleneck").
    predict: str = "velocity"
    x0_t_min: float = 0.02  # t floor in the x0 -> velocity conversion

    @property
    def tokens_per_part(self) -> int:
        return (self.latent_resolution // self.patch_size) ** 3

    @property
    def cond_tokens(self) -> int:
        return self.cond_prefix_tokens + self.cond_grid**2


class FlowOutput(NamedTuple):
    velocity: torch.Tensor  # (B, K, C, r, r, r), whatever ``predict`` is
    exists_logits: torch.Tensor  # (B, K)
    features: torch.Tensor  # (B, K, L, D), last-block token features


def modulate(x: torch.Tensor, shift: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    # x (B, K, L, D), shift/scale (B, D)
    return x * (1 + scale[:, None, None]) + shift[:, None, None]


class PartFlowBlock(nn.Module):
    def __init__(self, cfg: PartFlowConfig, within_part: bool) -> None:
        super().__init__()
        D = cfg.width
        self.within_part = within_part
        self.norm1 = nn.LayerNorm(D, elementwise_affine=False, eps=1e-6)
        self.self_attn = SelfAttention(D, cfg.heads, qk_norm=cfg.qk_norm)
        self.norm2 = nn.LayerNorm(D, eps=1e-6)
        self.cross_attn = CrossAttention(D, cfg.cond_dim, cfg.heads)
        self.norm3 = nn.LayerNorm(D, elementwise_affine=False, eps=1e-6)
        self.mlp = MLP(D, int(D * cfg.mlp_ratio), approximate="tanh")
        self.adaLN = nn.Sequential(nn.SiLU(), nn.Linear(D, 6 * D))

    def forward(self, h: torch.Tensor, c: torch.Tensor, ctx: torch.Tensor) -> torch.Tensor:
        """h (B, K, L, D) tokens, c (B, D) timestep embedding, ctx (B, N, D_img)."""
        B, K, L, D = h.shape
        shift1, scale1, gate1, shift2, scale2, gate2 = self.adaLN(c).chunk(6, dim=-1)  # (B, D)
        x = modulate(self.norm1(h), shift1, scale1)
        if self.within_part:
            a = self.self_attn(x.reshape(B * K, L, D))  # (B*K, L, D): one part per row
        else:
            a = self.self_attn(x.reshape(B, K * L, D))  # (B, K*L, D): all parts together
        h = h + gate1[:, None, None] * a.reshape(B, K, L, D)
        h = h + self.cross_attn(self.norm2(h).reshape(B, K * L, D), ctx).reshape(B, K, L, D)
        h = h + gate2[:, None, None] * self.mlp(modulate(self.norm3(h), shift2, scale2))
        return h  # (B, K, L, D)


@register("part_flow", PartFlowConfig)
class PartFlowTransformer(nn.Module):
    def __init__(self, cfg: PartFlowConfig) -> None:
        super().__init__()
        if cfg.latent_resolution % cfg.patch_size:
            raise ValueError("latent_resolution must be a multiple of patch_size")
        check_prediction(cfg.predict)
        self.cfg = cfg
        T, dp, D = cfg.max_parts, cfg.part_embed_dim, cfg.width
        patch_dim = cfg.latent_channels * cfg.patch_size**3

        std = cfg.part_embed_std
        self.part_embed = nn.Parameter(torch.randn(T, dp) * std)  # E, (T, d_p)
        self.mask_extra = nn.Parameter(torch.randn(2, dp) * std)  # rows: background, no mask
        self.mask_proj = nn.Linear(dp, cfg.cond_dim)
        self.input_proj = nn.Linear(patch_dim + dp, D)
        grid = cfg.latent_resolution // cfg.patch_size
        self.register_buffer("pos", sincos_3d(grid, D), persistent=False)  # (L, D)
        self.t_embed = TimestepEmbedder(D)
        self.blocks = nn.ModuleList(
            PartFlowBlock(cfg, within_part=(i % 2 == 1)) for i in range(cfg.depth)
        )
        self.final_norm = nn.LayerNorm(D, elementwise_affine=False, eps=1e-6)
        self.final_adaLN = nn.Sequential(nn.SiLU(), nn.Linear(D, 2 * D))
        self.out_proj = nn.Linear(D, patch_dim)
        self.exists_head = nn.Sequential(nn.LayerNorm(D), nn.Linear(D, 1))
        self._init_weights()

    def _init_weights(self) -> None:
        zero = (self.final_adaLN[-1], self.out_proj)
        if self.cfg.zero_init_mask_proj:
            zero = (*zero, self.mask_proj)
        init_adaln_transformer(self, zero=zero)

    # --- shapes -----------------------------------------------------------------------

    def patchify(self, x: torch.Tensor) -> torch.Tensor:
        """(B, K, C, r, r, r) -> (B, K, L, C * p^3), tokens in [x, y, z] raster order."""
        B, K, C, r = x.shape[:4]
        p, g = self.cfg.patch_size, r // self.cfg.patch_size
        x = x.reshape(B, K, C, g, p, g, p, g, p)
        x = x.permute(0, 1, 3, 5, 7, 2, 4, 6, 8)  # (B, K, g, g, g, C, p, p, p)
        return x.reshape(B, K, g**3, C * p**3)

    def unpatchify(self, tokens: torch.Tensor) -> torch.Tensor:
        """(B, K, L, C * p^3) -> (B, K, C, r, r, r)."""
        B, K = tokens.shape[:2]
        C, p = self.cfg.latent_channels, self.cfg.patch_size
        g = self.cfg.latent_resolution // p
        x = tokens.reshape(B, K, g, g, g, C, p, p, p)
        x = x.permute(0, 1, 5, 2, 6, 3, 7, 4, 8)  # (B, K, C, g, p, g, p, g, p)
        return x.reshape(B, K, C, g * p, g * p, g * p)

    # --- conditioning -----------------------------------------------------------------

    def mask_table(self) -> torch.Tensor:
        """Rows looked up by mask pixels, (T + 2, d_p): E[0..T-1], background, no mask."""
        return torch.cat([self.part_embed, self.mask_extra], dim=0)

    def mask_weights(
        self, mask: torch.Tensor | None, drop: torch.Tensor | None, batch: int
    ) -> torch.Tensor:
        """Fraction of each table row under each image patch, (B, T + 2, g, g)."""
        T, g = self.cfg.max_parts, self.cfg.cond_grid
        device = self.part_embed.device
        null = torch.zeros(batch, T + 2, g, g, device=device)
        null[:, T + 1] = 1.0
        if mask is None:
            return null
        mask = mask.long()
        if int(mask.min()) < 0 or int(mask.max()) > T:
            raise ValueError(f"mask ids must be in 0..{T} (0 background, slot + 1 for parts)")
        rows = torch.where(mask == 0, torch.full_like(mask, T), mask - 1)  # (B, H, W)
        onehot = F.one_hot(rows, T + 2).permute(0, 3, 1, 2).float()  # (B, T+2, H, W)
        w = F.adaptive_avg_pool2d(onehot, (g, g))  # (B, T+2, g, g)
        if drop is not None:
            w = torch.where(drop[:, None, None, None], null, w)
        return w

    def mask_embedding(
        self, mask: torch.Tensor | None, drop: torch.Tensor | None, batch: int
    ) -> torch.Tensor:
        """Pooled part embedding of the mask, (B, g*g, d_p) (before the d_p -> D_img proj)."""
        w = self.mask_weights(mask, drop, batch)  # (B, T+2, g, g)
        emb = torch.einsum("bkhw,kd->bhwd", w, self.mask_table())  # (B, g, g, d_p)
        return emb.flatten(1, 2)

    def context(
        self,
        cond: torch.Tensor | None,
        mask: torch.Tensor | None,
        cond_drop: torch.Tensor | None,
        mask_drop: torch.Tensor | None,
        batch: int,
    ) -> torch.Tensor:
        """Image tokens + mask embedding, (B, N_img, D_img).

        ``cond=None`` or ``cond_drop[b]`` zeroes sample b's image tokens (TRELLIS's null
        condition) and drops its mask too; ``mask=None`` or ``mask_drop[b]`` use the
        "no mask" row.
        """
        cfg = self.cfg
        if cond is None:
            ctx = torch.zeros(batch, cfg.cond_tokens, cfg.cond_dim, device=self.part_embed.device)
            drop = torch.ones(batch, dtype=torch.bool, device=ctx.device)
        else:
            if cond.shape[1:] != (cfg.cond_tokens, cfg.cond_dim):
                raise ValueError(
                    f"image tokens {tuple(cond.shape)} do not match the config "
                    f"({cfg.cond_tokens} tokens of width {cfg.cond_dim})"
                )
            ctx, drop = cond, cond_drop
            if cond_drop is not None:
                ctx = torch.where(cond_drop[:, None, None], torch.zeros_like(cond), cond)
        if mask_drop is not None:
            drop = mask_drop if drop is None else (drop | mask_drop)
        m = self.mask_proj(self.mask_embedding(mask, drop, batch))  # (B, g*g, D_img)
        P = cfg.cond_prefix_tokens
        return torch.cat([ctx[:, :P], ctx[:, P:] + m.to(ctx.dtype)], dim=1)

    # --- forward ----------------------------------------------------------------------

    def forward(
        self,
        x: torch.Tensor,
        t: torch.Tensor,
        cond: torch.Tensor | None,
        mask: torch.Tensor | None = None,
        cond_drop: torch.Tensor | None = None,
        mask_drop: torch.Tensor | None = None,
    ) -> FlowOutput:
        """x (B, K, C, r, r, r) noisy latents, t (B,) in [0, 1], cond (B, N_img, D_img) or
        None, mask (B, H, W) ids or None, cond_drop / mask_drop (B,) bool or None."""
        B, K = x.shape[:2]
        if K > self.cfg.max_parts:
            raise ValueError(f"{K} part slots but the model has max_parts={self.cfg.max_parts}")
        tokens = self.patchify(x)  # (B, K, L, C p^3)
        L = tokens.shape[2]
        ident = self.part_embed[:K][None, :, None].expand(B, K, L, -1)  # (B, K, L, d_p)
        h = self.input_proj(torch.cat([tokens, ident.to(tokens.dtype)], dim=-1))  # (B, K, L, D)
        h = h + self.pos.to(h.dtype)
        c = self.t_embed(t)  # (B, D)
        ctx = self.context(cond, mask, cond_drop, mask_drop, B)  # (B, N_img, D_img)
        for block in self.blocks:
            if self.cfg.grad_checkpoint and self.training:
                h = torch.utils.checkpoint.checkpoint(block, h, c, ctx, use_reentrant=False)
            else:
                h = block(h, c, ctx)
        shift, scale = self.final_adaLN(c).chunk(2, dim=-1)  # (B, D)
        out = self.unpatchify(self.out_proj(modulate(self.final_norm(h), shift, scale)))
        out = output_to_velocity(out, x, t, self.cfg.predict, self.cfg.x0_t_min)
        exists = self.exists_head(h).mean(dim=2).squeeze(-1)  # (B, K)
        return FlowOutput(out, exists, h)
