"""Image encoder: a ViT producing image tokens (B, N_img, D_img) for cross-attention.

Small configs train this ViT from scratch together with the flow model. The full config
has the DINOv2 ViT-L/14 shape (1024-d tokens, 24 blocks, 16 heads, 4 register tokens as in
``dinov2_vitl14_reg`` that TRELLIS uses) and loads official weights from a LOCAL file
(``weights`` in the config, or ``load_dinov2_weights``); nothing is ever downloaded.

Token order is DINOv2's: [cls, registers..., patches (row-major grid)], so
``num_prefix_tokens = 1 + num_register_tokens`` and the part mask is added to the
remaining ``grid * grid`` patch tokens.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path

import torch
import torch.nn as nn
import torch.nn.functional as F

from generator.pact.model.model_configs import register
from generator.pact.model.preprocess import foreground_crop
from generator.pact.model.transformer import MLP, SelfAttention

log = logging.getLogger(__name__)

_IMAGENET_MEAN = (0.485, 0.456, 0.406)
_IMAGENET_STD = (0.229, 0.224, 0.225)


@dataclass
class ViTConfig:
    image_size: int = 128  # input side in pixels (images are resized to it)
    patch_size: int = 16
    width: int = 192  # D_img
    depth: int = 4
    heads: int = 3
    mlp_ratio: float = 4.0
    num_register_tokens: int = 0
    layerscale_init: float | None = None  # DINOv2 uses 1e-5; None: no LayerScale
    # "norm": final LayerNorm (DINOv2 x_norm); "prenorm_layernorm": affine-free
    # LayerNorm of the pre-norm tokens, as TRELLIS conditions on DINOv2.
    output: str = "norm"
    weights: str | None = None  # local DINOv2 state dict (.pth / .safetensors)
    freeze: bool = False  # frozen encoders run in eval mode without gradients
    # inputs whitened outside the foreground and cropped round it (preprocess.py);
    # the margin is the fraction of the box's longer side added on each side
    foreground_crop: bool = False
    crop_margin: float = 0.1
    # > 0: a linear head on the patch tokens predicting each patch's part-id histogram
    # (0 background, 1 base, 2.. parts), an auxiliary training loss (train.py)
    aux_seg_classes: int = 0

    @property
    def grid(self) -> int:
        return self.image_size // self.patch_size

    @property
    def num_prefix_tokens(self) -> int:
        return 1 + self.num_register_tokens

    @property
    def num_tokens(self) -> int:
        return self.num_prefix_tokens + self.grid**2


class ViTBlock(nn.Module):
    def __init__(self, cfg: ViTConfig) -> None:
        super().__init__()
        D = cfg.width
        self.ln1 = nn.LayerNorm(D, eps=1e-6)
        self.attn = SelfAttention(D, cfg.heads)
        self.ln2 = nn.LayerNorm(D, eps=1e-6)
        self.mlp = MLP(D, int(D * cfg.mlp_ratio))
        if cfg.layerscale_init is not None:
            self.ls1 = nn.Parameter(torch.full((D,), cfg.layerscale_init))
            self.ls2 = nn.Parameter(torch.full((D,), cfg.layerscale_init))
        else:
            self.ls1 = self.ls2 = None

    def forward(self, x: torch.Tensor) -> torch.Tensor:  # (B, N, D)
        a = self.attn(self.ln1(x))
        x = x + (a * self.ls1 if self.ls1 is not None else a)
        m = self.mlp(self.ln2(x))
        return x + (m * self.ls2 if self.ls2 is not None else m)


@register("vit", ViTConfig)
class ImageEncoder(nn.Module):
    def __init__(self, cfg: ViTConfig) -> None:
        super().__init__()
        if cfg.image_size % cfg.patch_size:
            raise ValueError(f"image_size {cfg.image_size} not a multiple of {cfg.patch_size}")
        if cfg.output not in ("norm", "prenorm_layernorm"):
            raise ValueError(f"output must be 'norm' or 'prenorm_layernorm', got {cfg.output!r}")
        self.cfg = cfg
        D = cfg.width
        self.patch_embed = nn.Conv2d(3, D, cfg.patch_size, stride=cfg.patch_size)
        self.cls_token = nn.Parameter(torch.zeros(1, 1, D))
        self.register_tokens = (
            nn.Parameter(torch.zeros(1, cfg.num_register_tokens, D))
            if cfg.num_register_tokens
            else None
        )
        self.pos_embed = nn.Parameter(torch.randn(1, 1 + cfg.grid**2, D) * 0.02)
        self.blocks = nn.ModuleList(ViTBlock(cfg) for _ in range(cfg.depth))
        self.ln_f = nn.LayerNorm(D, eps=1e-6)
        self.seg_head = nn.Linear(D, cfg.aux_seg_classes) if cfg.aux_seg_classes else None
        self.register_buffer("pixel_mean", torch.tensor(_IMAGENET_MEAN).view(1, 3, 1, 1), False)
        self.register_buffer("pixel_std", torch.tensor(_IMAGENET_STD).view(1, 3, 1, 1), False)
        if cfg.weights:
            load_dinov2_weights(self, cfg.weights)
        if cfg.freeze:
            self.requires_grad_(False)

    @property
    def out_dim(self) -> int:
        return self.cfg.width

    def train(self, mode: bool = True) -> ImageEncoder:
        return super().train(mode and not self.cfg.freeze)

    def prepare(
        self,
        images: torch.Tensor,
        fg: torch.Tensor | None,
        masks: torch.Tensor | None = None,
        jitter: float = 0.0,
        generator: torch.Generator | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """The inputs this encoder was trained on: with ``foreground_crop``, images
        (B, 3, H, W) whitened outside ``fg`` (B, H, W) and cropped round it, the part
        ``masks`` (B, H, W) cropped alike (preprocess.foreground_crop); else unchanged."""
        if not self.cfg.foreground_crop:
            return images, masks
        if fg is None:
            raise ValueError("this image encoder expects foreground-cropped inputs: give fg")
        return foreground_crop(
            images,
            fg,
            masks,
            size=self.cfg.image_size,
            margin=self.cfg.crop_margin,
            jitter=jitter,
            generator=generator,
        )

    def segment(self, tokens: torch.Tensor) -> torch.Tensor:
        """tokens (B, N_img, D) from ``forward`` -> per-patch part-id logits
        (B, grid, grid, aux_seg_classes)."""
        if self.seg_head is None:
            raise ValueError("this image encoder has no segmentation head (aux_seg_classes 0)")
        g = self.cfg.grid
        return self.seg_head(tokens[:, self.cfg.num_prefix_tokens :]).view(len(tokens), g, g, -1)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        """images (B, 3, H, W) RGB in [0, 1] -> tokens (B, 1 + n_reg + grid^2, D_img)."""
        S = self.cfg.image_size
        if images.shape[-2:] != (S, S):
            images = F.interpolate(images, size=(S, S), mode="bilinear", antialias=True)
        x = (images - self.pixel_mean) / self.pixel_std
        x = self.patch_embed(x).flatten(2).transpose(1, 2)  # (B, grid^2, D)
        B = x.shape[0]
        x = torch.cat([self.cls_token.expand(B, -1, -1), x], dim=1) + self.pos_embed
        if self.register_tokens is not None:
            x = torch.cat([x[:, :1], self.register_tokens.expand(B, -1, -1), x[:, 1:]], dim=1)
        for block in self.blocks:
            x = block(x)  # (B, N_img, D)
        if self.cfg.output == "norm":
            return self.ln_f(x)
        return F.layer_norm(x, x.shape[-1:])


# --- DINOv2 weights from a local file ---------------------------------------------------

_DINOV2_RENAMES = [
    (r"^patch_embed\.proj\.", "patch_embed."),
    (r"^blocks\.(\d+)\.norm1\.", r"blocks.\1.ln1."),
    (r"^blocks\.(\d+)\.norm2\.", r"blocks.\1.ln2."),
    (r"^blocks\.(\d+)\.attn\.qkv\.", r"blocks.\1.attn.qkv."),
    (r"^blocks\.(\d+)\.attn\.proj\.", r"blocks.\1.attn.out."),
    (r"^blocks\.(\d+)\.ls1\.gamma$", r"blocks.\1.ls1"),
    (r"^blocks\.(\d+)\.ls2\.gamma$", r"blocks.\1.ls2"),
    (r"^blocks\.(\d+)\.mlp\.fc1\.", r"blocks.\1.mlp.fc1."),
    (r"^blocks\.(\d+)\.mlp\.fc2\.", r"blocks.\1.mlp.fc2."),
    (r"^norm\.", "ln_f."),
    (r"^(cls_token|pos_embed|register_tokens)$", r"\1"),
]
_DINOV2_DROPPED = {"mask_token"}  # used only by DINOv2's masked-image training
_PREFIXES = ("module.", "backbone.", "teacher.backbone.", "student.backbone.")


class WeightsLayoutError(ValueError):
    """The weights file does not fit this encoder (keys or shapes); the message says which."""


def dinov2_key_to_local(key: str) -> str | None:
    """Official DINOv2 key -> this module's key; None for keys that have no counterpart."""
    for p in _PREFIXES:
        if key.startswith(p):
            key = key[len(p) :]
    key = re.sub(r"^blocks\.\d+\.(\d+)\.", r"blocks.\1.", key)  # block_chunks layout
    if key in _DINOV2_DROPPED:
        return None
    for pattern, repl in _DINOV2_RENAMES:
        if re.match(pattern, key):
            return re.sub(pattern, repl, key)
    raise WeightsLayoutError(f"unrecognised DINOv2 key {key!r}")


def read_state_dict(path: str | Path) -> dict[str, torch.Tensor]:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"DINOv2 weights not found at {path}; put the official state dict there "
            "(e.g. dinov2_vitl14_reg4_pretrain.pth) or set weights to null"
        )
    if path.suffix == ".safetensors":
        from safetensors.torch import load_file

        return load_file(str(path))
    sd = torch.load(path, map_location="cpu", weights_only=True)
    for wrapper in ("model", "state_dict", "teacher"):
        if isinstance(sd, dict) and wrapper in sd and isinstance(sd[wrapper], dict):
            sd = sd[wrapper]
    return sd


def _resize_pos_embed(pe: torch.Tensor, grid: int) -> torch.Tensor:
    """(1, 1 + g0^2, D) -> (1, 1 + grid^2, D), bicubic over the patch grid."""
    n = pe.shape[1] - 1
    g0 = int(round(n**0.5))
    if g0 * g0 != n:
        raise WeightsLayoutError(f"pos_embed has {n} patch positions, not a square grid")
    if g0 == grid:
        return pe
    patch = pe[:, 1:].reshape(1, g0, g0, -1).permute(0, 3, 1, 2).float()  # (1, D, g0, g0)
    patch = F.interpolate(patch, size=(grid, grid), mode="bicubic", align_corners=False)
    patch = patch.permute(0, 2, 3, 1).reshape(1, grid * grid, -1).to(pe.dtype)
    return torch.cat([pe[:, :1], patch], dim=1)


def load_dinov2_weights(model: ImageEncoder, path: str | Path) -> None:
    """Load an official-layout DINOv2 state dict from a local file into ``model`` (strict)."""
    src = read_state_dict(path)
    local: dict[str, torch.Tensor] = {}
    for key, value in src.items():
        new = dinov2_key_to_local(key)
        if new is not None:
            local[new] = value
    if "pos_embed" in local:
        local["pos_embed"] = _resize_pos_embed(local["pos_embed"], model.cfg.grid)
    own = model.state_dict()
    missing = sorted(set(own) - set(local) - {"pixel_mean", "pixel_std"})
    unexpected = sorted(set(local) - set(own))
    bad = [k for k in local if k in own and local[k].shape != own[k].shape]
    if missing or unexpected or bad:
        raise WeightsLayoutError(
            f"{path}: does not match ViTConfig(width={model.cfg.width}, depth={model.cfg.depth}, "
            f"registers={model.cfg.num_register_tokens}); missing {missing[:5]}, "
            f"unexpected {unexpected[:5]}, shape mismatch {bad[:5]}"
        )
    model.load_state_dict(local, strict=False)
    log.info("loaded %d DINOv2 tensors from %s", len(local), path)
