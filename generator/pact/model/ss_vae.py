"""Sparse-structure VAE: occupancy grid (B, 1, R, R, R) <-> latent (B, C, r, r, r).

The TRELLIS stage-1 autoencoder shape, as a plain 3D conv net: residual blocks with
GroupNorm + SiLU, stride-2 convolutions down, nearest-upsample + conv up. Each part's
occupancy is encoded independently (``encode_parts`` folds parts into the batch), so an
empty slot (all-zero grid) maps to one fixed latent, ``empty_latent()``; the flow model is
trained to produce that latent for unused slots and the decoder turns it into nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn as nn
import torch.nn.functional as F

from generator.pact.model.model_configs import register


@dataclass
class SSVAEConfig:
    resolution: int = 32  # R, occupancy grid side
    latent_channels: int = 8  # C
    channels: tuple[int, ...] = (16, 32, 64)  # one entry per level; R / r = 2 ** (levels - 1)
    num_res_blocks: int = 1  # per level, encoder and decoder
    num_mid_blocks: int = 1  # at the latent resolution
    # 2: the stem is a stride-2 2^3 conv (and the head its transpose), so no conv runs at
    # full resolution; CPU conv3d backward is slow and full-res layers dominate the cost.
    stem_stride: int = 1

    @property
    def latent_resolution(self) -> int:
        return self.resolution // (self.stem_stride * 2 ** (len(self.channels) - 1))


@dataclass
class SSVAETrainConfig:
    """Loss weights and optimiser settings a VAE trainer reads."""

    kl_weight: float = 1e-3
    dice_weight: float = 1.0
    lr: float = 1e-3
    batch_size: int = 16
    bf16: bool = True


def _norm(c: int) -> nn.GroupNorm:
    return nn.GroupNorm(max(1, min(32, c // 4)), c)


class ResBlock3d(nn.Module):
    def __init__(self, c_in: int, c_out: int) -> None:
        super().__init__()
        self.norm1 = _norm(c_in)
        self.conv1 = nn.Conv3d(c_in, c_out, 3, padding=1)
        self.norm2 = _norm(c_out)
        self.conv2 = nn.Conv3d(c_out, c_out, 3, padding=1)
        self.skip = nn.Conv3d(c_in, c_out, 1) if c_in != c_out else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:  # (B, c_in, S, S, S)
        h = self.conv1(F.silu(self.norm1(x)))
        h = self.conv2(F.silu(self.norm2(h)))
        return self.skip(x) + h  # (B, c_out, S, S, S)


class Upsample3d(nn.Module):
    def __init__(self, c_in: int, c_out: int) -> None:
        super().__init__()
        self.conv = nn.Conv3d(c_in, c_out, 3, padding=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.conv(F.interpolate(x, scale_factor=2, mode="nearest"))


@register("ss_vae", SSVAEConfig)
class SparseStructureVAE(nn.Module):
    def __init__(self, cfg: SSVAEConfig) -> None:
        super().__init__()
        self.cfg = cfg
        ch = cfg.channels
        s = cfg.stem_stride
        if s not in (1, 2) or cfg.resolution % (s * 2 ** (len(ch) - 1)):
            raise ValueError(f"resolution {cfg.resolution} does not fit stem {s}, {len(ch)} levels")
        C = cfg.latent_channels

        # encoder: R -> r
        stem = nn.Conv3d(1, ch[0], 3, padding=1) if s == 1 else nn.Conv3d(1, ch[0], 2, stride=2)
        enc: list[nn.Module] = [stem]
        for i, c in enumerate(ch):
            enc += [ResBlock3d(c, c) for _ in range(cfg.num_res_blocks)]
            if i + 1 < len(ch):
                enc.append(nn.Conv3d(c, ch[i + 1], 3, stride=2, padding=1))
        enc += [ResBlock3d(ch[-1], ch[-1]) for _ in range(cfg.num_mid_blocks)]
        enc += [_norm(ch[-1]), nn.SiLU(), nn.Conv3d(ch[-1], 2 * C, 3, padding=1)]
        self.encoder = nn.Sequential(*enc)

        # decoder: r -> R
        dec: list[nn.Module] = [nn.Conv3d(C, ch[-1], 3, padding=1)]
        dec += [ResBlock3d(ch[-1], ch[-1]) for _ in range(cfg.num_mid_blocks)]
        for i in range(len(ch) - 1, -1, -1):
            dec += [ResBlock3d(ch[i], ch[i]) for _ in range(cfg.num_res_blocks)]
            if i > 0:
                dec.append(Upsample3d(ch[i], ch[i - 1]))
        head = nn.Conv3d(ch[0], 1, 3, padding=1) if s == 1 else nn.ConvTranspose3d(ch[0], 1, 2, 2)
        dec += [_norm(ch[0]), nn.SiLU(), head]
        self.decoder = nn.Sequential(*dec)

    def encode(
        self,
        occ: torch.Tensor,
        sample_posterior: bool = False,
        generator: torch.Generator | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """occ (B, 1, R, R, R) in {0, 1} -> z, mean, logvar, each (B, C, r, r, r)."""
        h = self.encoder(occ.float() * 2.0 - 1.0)  # (B, 2C, r, r, r)
        mean, logvar = h.float().chunk(2, dim=1)
        logvar = logvar.clamp(-30.0, 20.0)
        if not sample_posterior:
            return mean, mean, logvar
        noise = torch.randn(mean.shape, generator=generator, device=mean.device)
        return mean + torch.exp(0.5 * logvar) * noise, mean, logvar

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        """z (B, C, r, r, r) -> occupancy logits (B, 1, R, R, R)."""
        return self.decoder(z)

    def forward(self, occ: torch.Tensor, generator: torch.Generator | None = None):
        z, mean, logvar = self.encode(occ, sample_posterior=self.training, generator=generator)
        return self.decode(z), mean, logvar

    # --- per-part helpers -------------------------------------------------------------

    @torch.no_grad()
    def encode_parts(self, occ: torch.Tensor) -> torch.Tensor:
        """occ (B, K, R, R, R) -> posterior means (B, K, C, r, r, r); parts are independent."""
        B, K = occ.shape[:2]
        _, mean, _ = self.encode(occ.reshape(B * K, 1, *occ.shape[2:]))
        return mean.reshape(B, K, *mean.shape[1:])

    @torch.no_grad()
    def decode_parts(self, z: torch.Tensor) -> torch.Tensor:
        """z (B, K, C, r, r, r) -> occupancy logits (B, K, R, R, R)."""
        B, K = z.shape[:2]
        logits = self.decode(z.reshape(B * K, *z.shape[2:]))  # (B*K, 1, R, R, R)
        return logits.reshape(B, K, *logits.shape[2:])

    @torch.no_grad()
    def empty_latent(self) -> torch.Tensor:
        """Latent of an all-empty grid, (C, r, r, r): the target for unused part slots."""
        R = self.cfg.resolution
        p = next(self.parameters())
        return self.encode(torch.zeros(1, 1, R, R, R, device=p.device))[1][0]


def occupancy_iou(logits: torch.Tensor, occ: torch.Tensor) -> torch.Tensor:
    """IoU of (logits > 0) against a {0, 1} grid over all voxels of the batch, a scalar."""
    pred = logits > 0
    gt = occ > 0.5
    inter = (pred & gt).sum()
    union = (pred | gt).sum()
    return inter.float() / union.clamp_min(1).float()


def vae_loss(
    vae: SparseStructureVAE,
    occ: torch.Tensor,
    cfg: SSVAETrainConfig | None = None,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, dict[str, float]]:
    """One VAE training loss: BCE + dice on occupancy logits + KL to N(0, I).

    occ: (N, R, R, R) or (N, 1, R, R, R), {0, 1} (one part per item; empty parts allowed).
    Returns (scalar loss, metrics). The caller owns autocast, backward and the optimiser.
    """
    cfg = cfg or SSVAETrainConfig()
    if occ.dim() == 4:
        occ = occ[:, None]
    occ = occ.float()  # (N, 1, R, R, R)
    logits, mean, logvar = vae(occ, generator=generator)
    logits = logits.float()
    bce = F.binary_cross_entropy_with_logits(logits, occ)
    p = torch.sigmoid(logits).flatten(1)  # (N, R^3)
    y = occ.flatten(1)
    dice = 1.0 - (2.0 * (p * y).sum(1) + 1.0) / (p.sum(1) + y.sum(1) + 1.0)  # (N,)
    dice = dice.mean()
    kl = 0.5 * (mean.pow(2) + logvar.exp() - logvar - 1.0).mean()
    loss = bce + cfg.dice_weight * dice + cfg.kl_weight * kl
    with torch.no_grad():
        iou = occupancy_iou(logits, occ)
    metrics = {
        "loss": loss.item(),
        "bce": bce.item(),
        "dice": dice.item(),
        "kl": kl.item(),
        "iou": iou.item(),
    }
    return loss, metrics
