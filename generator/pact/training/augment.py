"""Training-time augmentation of stage 1's inputs (issue 23: lean on what does not change
between a render and a photo).

A photo differs from the dataset's renders in its colours, materials and light, and a
user's part mask (SAM-style) has ragged, shifted edges; the silhouette and the part
layout stay. ``augment_inputs`` changes a batch's image and mask the way a photo would,
so that the model learns to rely on the mask and the silhouette:

- ``recolor``: per sample with this probability, every part (mask id) gets its own
  random tint: the pixel's luminance times a random colour, blended in by a random
  weight (shading kept, hue and brightness of the material not);
- ``photometric``: per sample, random brightness (x 0.6-1.4), contrast (x 0.6-1.4)
  and saturation (x 0-1.5) of the whole image;
- ``rgb_dropout``: per sample, the object's pixels (mask != 0) become one flat random
  colour: only the silhouette and the mask remain;
- ``mask_noise``: per sample, every pixel takes the id of a random neighbour up to 1-3
  px away with probability 1/2: ragged part and object edges, holes one pixel wide,
  nothing changed inside a part.

All draws come from ``generator`` (a ``torch.Generator``), so a resumed run augments
exactly as an uninterrupted one. Images (B, 3, S, S) in [0, 1], masks (B, S, S) int64
ids (0 background); returns new tensors.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

LUMA = (0.299, 0.587, 0.114)


@dataclass(frozen=True)
class AugmentConfig:
    recolor: float = 0.0  # probabilities per sample
    photometric: float = 0.0
    rgb_dropout: float = 0.0
    mask_noise: float = 0.0
    max_parts: int = 16  # ids 1..max_parts + 1 are recoloured (0 is the background)

    @property
    def active(self) -> bool:
        return max(self.recolor, self.photometric, self.rgb_dropout, self.mask_noise) > 0


def _rand(generator: torch.Generator | None, *shape: int) -> torch.Tensor:
    return torch.rand(*shape, generator=generator)


def _luma(image: torch.Tensor) -> torch.Tensor:
    w = torch.tensor(LUMA, dtype=image.dtype, device=image.device).view(1, 3, 1, 1)
    return (image * w).sum(1, keepdim=True)  # (B, 1, H, W)


def recolor_parts(
    image: torch.Tensor, mask: torch.Tensor, pick: torch.Tensor, generator, max_id: int
) -> torch.Tensor:
    """Samples where ``pick`` (B,) bool: every mask id (background included) tinted by
    its own random colour, blended in by a random weight in [0.5, 1]."""
    B = image.shape[0]
    ids = mask.clamp(0, max_id)  # (B, H, W)
    colors = _rand(generator, B, max_id + 1, 3).to(image)  # per sample and id
    weight = (0.5 + 0.5 * _rand(generator, B, max_id + 1)).to(image)
    flat = ids.flatten(1)  # (B, HW)
    c = torch.gather(colors, 1, flat[..., None].expand(-1, -1, 3))  # (B, HW, 3)
    c = c.transpose(1, 2).reshape(image.shape)  # (B, 3, H, W)
    w = torch.gather(weight, 1, flat).reshape(B, 1, *image.shape[2:])
    tinted = (2.0 * _luma(image) * c).clamp(0.0, 1.0)
    out = image * (1 - w) + tinted * w
    return torch.where(pick.view(B, 1, 1, 1).to(image.device), out, image)


def photometric(image: torch.Tensor, pick: torch.Tensor, generator) -> torch.Tensor:
    """Samples where ``pick``: random brightness, contrast and saturation."""
    B = image.shape[0]
    u = _rand(generator, B, 3).to(image)
    bright = (0.6 + 0.8 * u[:, 0]).view(B, 1, 1, 1)
    contrast = (0.6 + 0.8 * u[:, 1]).view(B, 1, 1, 1)
    sat = (1.5 * u[:, 2]).view(B, 1, 1, 1)
    gray = _luma(image)
    out = gray + (image - gray) * sat
    mean = out.mean(dim=(1, 2, 3), keepdim=True)
    out = ((out - mean) * contrast + mean) * bright
    return torch.where(pick.view(B, 1, 1, 1).to(image.device), out.clamp(0.0, 1.0), image)


def drop_rgb(
    image: torch.Tensor, mask: torch.Tensor, pick: torch.Tensor, generator
) -> torch.Tensor:
    """Samples where ``pick``: the object's pixels (mask != 0) one flat random colour."""
    B = image.shape[0]
    color = _rand(generator, B, 3).to(image).view(B, 3, 1, 1)
    fg = (mask != 0)[:, None] & pick.view(B, 1, 1, 1).to(mask.device)
    return torch.where(fg, color.expand_as(image), image)


def ragged_mask(mask: torch.Tensor, pick: torch.Tensor, generator) -> torch.Tensor:
    """Samples where ``pick``: each pixel, with probability 1/2, takes the id of a random
    pixel up to r (1-3, per sample) away along each axis (clamped at the border)."""
    B, H, W = mask.shape
    r = torch.randint(1, 4, (B, 1, 1), generator=generator)
    dy = (torch.randint(-3, 4, (B, H, W), generator=generator)).clamp(-r, r)
    dx = (torch.randint(-3, 4, (B, H, W), generator=generator)).clamp(-r, r)
    move = (_rand(generator, B, H, W) < 0.5) & pick.view(B, 1, 1)
    ys = torch.arange(H).view(1, H, 1)
    xs = torch.arange(W).view(1, 1, W)
    y = torch.where(move, (ys + dy).clamp(0, H - 1), ys.expand(B, H, W))
    x = torch.where(move, (xs + dx).clamp(0, W - 1), xs.expand(B, H, W))
    flat = (y * W + x).to(mask.device).flatten(1)
    return torch.gather(mask.flatten(1), 1, flat).view(B, H, W)


def augment_inputs(
    image: torch.Tensor,
    mask: torch.Tensor,
    cfg: AugmentConfig,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """A batch's (image, mask) augmented as the module docstring says. The image is
    recoloured along the clean mask (the image's own edges); the noise goes only into the
    mask returned, the one the model is given."""
    if not cfg.active:
        return image, mask
    B = image.shape[0]
    picks = _rand(generator, 4, B)
    out = image
    if cfg.recolor > 0:
        out = recolor_parts(out, mask, picks[0] < cfg.recolor, generator, cfg.max_parts + 1)
    if cfg.photometric > 0:
        out = photometric(out, picks[1] < cfg.photometric, generator)
    if cfg.rgb_dropout > 0:
        out = drop_rgb(out, mask, picks[2] < cfg.rgb_dropout, generator)
    noisy = mask
    if cfg.mask_noise > 0:
        noisy = ragged_mask(mask, picks[3] < cfg.mask_noise, generator)
    return out, noisy
