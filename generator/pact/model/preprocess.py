"""Image preprocessing before the image encoder: background to white, object cropped.

TRELLIS conditions on images whose background has been removed and whose object has
been cropped to a square around it and resized, so the encoder sees the object large,
centred and alone. Our from-scratch encoder needs that more than DINOv2 does: trained
on the domain-randomized renders of the training data engine (random backgrounds,
random framing), a ViT classifying the 7 categories reached 0.2-0.34 validation
accuracy after 300-400 steps on the raw renders and 0.44-0.52 on whitened crops
(docs/pact.md).

``foreground_crop`` does both in one batched resampling:

- pixels outside the foreground become ``background`` (white);
- the square crop is the foreground's bounding box, its longer side grown by
  ``margin`` on each side, centred on the box (the part outside the image is
  background; a part mask there is 0);
- the crop is resampled to ``size`` pixels (bilinear for the image, nearest for the
  part mask).

The foreground is the part mask's non-zero pixels when there is a mask; without one,
the photo's alpha channel when it has one, else ``generator.pact.model.foreground.ForegroundNet``
(``encoder_inputs``). An image with no foreground at
all is only resized. ``jitter`` (training only) moves the crop's centre and margin a
little so the encoder tolerates an imprecise box.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F


def square_inputs(
    image: np.ndarray, mask: np.ndarray | None, size: int, max_parts: int | None = None
) -> tuple[torch.Tensor, torch.Tensor | None, np.ndarray, np.ndarray | None]:
    """uint8 (H, W, 3+) image and (H, W) part-id mask -> model inputs (1, 3, size, size)
    in [0, 1] and (1, size, size) int64 ids (or None), plus the squared uint8 image and
    mask. A non-square image is padded to a square with its edge colours, its mask with
    background; mask ids past ``max_parts`` become the base's (1): the model cannot embed
    them, and the silhouette stays whole."""
    image = np.asarray(image)[..., :3]
    if mask is not None:
        mask = np.asarray(mask).astype(np.int64)
        if mask.shape != image.shape[:2]:
            raise ValueError(f"mask {mask.shape} does not match image {image.shape[:2]}")
        if max_parts is not None:
            mask = np.where(mask > max_parts, 1, mask)
    H, W = image.shape[:2]
    if H != W:
        S = max(H, W)
        top, left = (S - H) // 2, (S - W) // 2
        pad = ((top, S - H - top), (left, S - W - left))
        image = np.pad(image, (*pad, (0, 0)), mode="edge")
        mask = None if mask is None else np.pad(mask, pad)
    img = torch.from_numpy(np.array(image, np.uint8)).permute(2, 0, 1)[None].float() / 255
    if img.shape[-1] != size:
        img = F.interpolate(img, size=(size, size), mode="bilinear", antialias=True)
    m = None
    if mask is not None:
        m = torch.from_numpy(np.ascontiguousarray(mask))[None, None].float()
        m = F.interpolate(m, size=(size, size), mode="nearest")[0].long()
    return img.clamp(0, 1), m, image, mask


def square_silhouette(alpha: np.ndarray, size: int) -> torch.Tensor:
    """(H, W) uint8 alpha (255 = object) -> (1, size, size) bool, squared and resized as
    ``square_inputs`` does the image."""
    image = np.zeros((*np.asarray(alpha).shape[:2], 3), np.uint8)
    _, m, _, _ = square_inputs(image, (np.asarray(alpha) > 127).astype(np.int64), size)
    return m > 0


def crop_boxes(fg: torch.Tensor, margin: float) -> torch.Tensor:
    """fg (B, H, W) bool -> (B, 3) square crops (centre x, centre y, half side) in the
    [-1, 1] coordinates of ``grid_sample`` (x along W, y along H); the whole image
    (0, 0, 1) where fg is empty."""
    B, H, W = fg.shape
    out = torch.tensor([0.0, 0.0, 1.0], device=fg.device).repeat(B, 1)
    rows, cols = fg.any(dim=2), fg.any(dim=1)  # (B, H), (B, W)
    for b in range(B):
        if not rows[b].any():
            continue
        r = torch.nonzero(rows[b]).flatten()
        c = torch.nonzero(cols[b]).flatten()
        # pixel edges -> [-1, 1] (align_corners=False: pixel i spans [i, i + 1] / n * 2 - 1)
        y0, y1 = r[0].item() / H * 2 - 1, (r[-1].item() + 1) / H * 2 - 1
        x0, x1 = c[0].item() / W * 2 - 1, (c[-1].item() + 1) / W * 2 - 1
        # half side in pixels of the longer side, back to each axis' normalized units
        half_px = max((x1 - x0) * W, (y1 - y0) * H) / 4 * (1 + 2 * margin)
        out[b] = torch.tensor([(x0 + x1) / 2, (y0 + y1) / 2, half_px])
    return out


def foreground_crop(
    images: torch.Tensor,
    fg: torch.Tensor,
    masks: torch.Tensor | None = None,
    size: int | None = None,
    margin: float = 0.1,
    background: float = 1.0,
    jitter: float = 0.0,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, torch.Tensor | None]:
    """images (B, 3, H, W) in [0, 1], fg (B, H, W) bool, masks (B, H, W) int ids or None
    -> cropped images (B, 3, size, size) and masks (B, size, size) (or None).

    ``jitter`` > 0: the crop's centre moves by up to ``jitter`` of its side and its margin
    varies by up to ``jitter`` (uniform, from ``generator``)."""
    B, _, H, W = images.shape
    size = size or H
    fg = fg.to(images.device).bool()
    if fg.shape != (B, H, W):
        raise ValueError(f"foreground {tuple(fg.shape)} does not match images {(B, H, W)}")
    boxes = crop_boxes(fg, margin)  # (B, 3): cx, cy, half side in pixels
    if jitter > 0:
        u = torch.rand(B, 3, generator=generator).to(images.device) * 2 - 1
        boxes[:, 2] = boxes[:, 2] * (1 + jitter * u[:, 2])
        boxes[:, :2] = boxes[:, :2] + jitter * u[:, :2] * boxes[:, 2:3] * 2 / W
    has_fg = fg.flatten(1).any(dim=1)  # (B,)
    half_x = torch.where(has_fg, boxes[:, 2] * 2 / W, torch.ones_like(boxes[:, 2]))
    half_y = torch.where(has_fg, boxes[:, 2] * 2 / H, torch.ones_like(boxes[:, 2]))
    theta = torch.zeros(B, 2, 3, device=images.device)
    theta[:, 0, 0], theta[:, 0, 2] = half_x, boxes[:, 0]
    theta[:, 1, 1], theta[:, 1, 2] = half_y, boxes[:, 1]
    grid = F.affine_grid(theta, (B, 1, size, size), align_corners=False)
    keep = (fg | ~has_fg[:, None, None]).to(images.dtype)[:, None]  # whiten where not fg
    shifted = (images - background) * keep  # background -> 0, so zero padding is background
    if size < min(H, W):  # shrinking: low-pass first so the resampling does not alias
        scale = size / (2 * float(boxes[:, 2].max()))
        if scale < 1:
            shifted = F.interpolate(
                shifted,
                scale_factor=max(scale, size / max(H, W)),
                mode="bilinear",
                antialias=True,
            )
    out = F.grid_sample(shifted, grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    out = (out + background).clamp(0.0, 1.0)
    out_masks = None
    if masks is not None:
        m = masks.to(images.device)[:, None].float()
        m = F.grid_sample(m, grid, mode="nearest", padding_mode="zeros", align_corners=False)
        out_masks = m[:, 0].round().long()
    return out, out_masks


class ForegroundMissingError(ValueError):
    """A foreground-cropping encoder got an image without a mask and no foreground net."""


def encoder_inputs(
    encoder: torch.nn.Module,
    images: torch.Tensor,
    masks: torch.Tensor | None,
    foreground: torch.nn.Module | None = None,
    silhouette: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor | None]:
    """Inference inputs of ``encoder`` (an ``ImageEncoder``): its ``prepare`` with the
    foreground taken from the part masks (B, H, W) when given, else from ``silhouette``
    (B, H, W) bool (a photo's alpha channel), else predicted by ``foreground`` (a
    ``ForegroundNet``)."""
    if not encoder.cfg.foreground_crop:
        return images, masks
    if masks is not None:
        fg = masks > 0
    elif silhouette is not None:
        fg = silhouette.to(images.device).bool()
    elif foreground is not None:
        fg = foreground.predict(images)
    else:
        raise ForegroundMissingError(
            "this image encoder crops round the object: give a part mask, or load a "
            "foreground checkpoint (python -m generator.pact.training.train_foreground)"
        )
    return encoder.prepare(images, fg, masks)
