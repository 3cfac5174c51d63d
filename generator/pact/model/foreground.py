"""Foreground segmentation for images that come without a part mask.

A foreground-cropping image encoder (``ViTConfig.foreground_crop``) needs the object's
silhouette. With a part mask it is the mask's non-zero pixels; without one it comes
from this small U-Net (TRELLIS uses rembg for the same job; nothing can be downloaded
here, so it is trained on the training data engine's renders, whose part masks give
the silhouettes for free):

    python -m generator.pact.training.train_foreground --data runs/data/train --out runs/pact/stage1 \
        --steps 600 --threads 1

``ForegroundNet(images) -> logits (B, H, W)``; ``predict`` thresholds them and keeps
the largest connected component (a render holds one object). The renders' backgrounds
are domain-randomized (colours, checkers, noise), so the net learns the object, not a
backdrop; photos far from those renders are its known limit (docs/model-card.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from generator.pact.model.model_configs import register


@dataclass
class ForegroundConfig:
    image_size: int = 64  # inputs are resized to this side; logits come back full size
    channels: tuple[int, ...] = (16, 32, 64, 64)  # per resolution level, finest first


def _conv(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, padding=1),
        nn.GroupNorm(min(8, cout), cout),
        nn.SiLU(),
        nn.Conv2d(cout, cout, 3, padding=1),
        nn.GroupNorm(min(8, cout), cout),
        nn.SiLU(),
    )


@register("foreground_unet", ForegroundConfig)
class ForegroundNet(nn.Module):
    """A U-Net: a conv block per level, 2x max-pool down, bilinear up + skip."""

    def __init__(self, cfg: ForegroundConfig) -> None:
        super().__init__()
        self.cfg = cfg
        ch = list(cfg.channels)
        self.down = nn.ModuleList(_conv(a, b) for a, b in zip([3, *ch[:-1]], ch, strict=True))
        self.up = nn.ModuleList(_conv(ch[i + 1] + ch[i], ch[i]) for i in range(len(ch) - 1))
        self.out = nn.Conv2d(ch[0], 1, 1)
        mean, std = (0.485, 0.456, 0.406), (0.229, 0.224, 0.225)
        self.register_buffer("pixel_mean", torch.tensor(mean).view(1, 3, 1, 1), False)
        self.register_buffer("pixel_std", torch.tensor(std).view(1, 3, 1, 1), False)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        """images (B, 3, H, W) in [0, 1] -> foreground logits (B, H, W)."""
        H, W = images.shape[-2:]
        S = self.cfg.image_size
        x = images
        if (H, W) != (S, S):
            x = F.interpolate(x, size=(S, S), mode="bilinear", antialias=True)
        x = (x - self.pixel_mean) / self.pixel_std
        skips = []
        for i, block in enumerate(self.down):
            x = block(x if i == 0 else F.max_pool2d(x, 2))
            skips.append(x)
        for i in reversed(range(len(self.up))):
            x = F.interpolate(x, size=skips[i].shape[-2:], mode="bilinear", align_corners=False)
            x = self.up[i](torch.cat([x, skips[i]], dim=1))
        logits = self.out(x)
        if (H, W) != (S, S):
            logits = F.interpolate(logits, size=(H, W), mode="bilinear", align_corners=False)
        return logits[:, 0]

    @torch.no_grad()
    def predict(self, images: torch.Tensor, threshold: float = 0.5) -> torch.Tensor:
        """images (B, 3, H, W) -> foreground (B, H, W) bool: the largest 8-connected
        component of the thresholded probabilities (all False when no pixel passes the
        threshold; ``preprocess.foreground_crop`` then keeps the whole image)."""
        from scipy import ndimage

        fg = (torch.sigmoid(self(images)) > threshold).cpu().numpy()
        for b in range(len(fg)):
            labels, n = ndimage.label(fg[b], structure=np.ones((3, 3), bool))
            if n > 1:
                sizes = np.bincount(labels.ravel())[1:]
                fg[b] = labels == 1 + int(np.argmax(sizes))
        return torch.from_numpy(fg).to(images.device)


def segmentation_loss(logits: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Binary cross-entropy + soft Dice (the Dice term keeps thin legs and handles)."""
    target = target.float()
    bce = F.binary_cross_entropy_with_logits(logits, target)
    p = torch.sigmoid(logits)
    inter = (p * target).flatten(1).sum(1)
    dice = 1 - (2 * inter + 1) / (p.flatten(1).sum(1) + target.flatten(1).sum(1) + 1)
    return bce + dice.mean()


def iou(pred: torch.Tensor, target: torch.Tensor) -> float:
    """Mean per-image IoU of two (B, H, W) bool masks."""
    inter = (pred & target).flatten(1).sum(1).float()
    union = (pred | target).flatten(1).sum(1).float().clamp(min=1)
    return float((inter / union).mean())
