"""The photo parser's network: a small residual U-Net with three heads.

    ParserNet(images (B, 3, S, S) in [0, 1]) -> ParserOutput
        seg       (B, 3, S/2, S/2)  logits of SEG_CLASSES: background, base, movable part
        boundary  (B, 1, S/2, S/2)  logit: a movable part's edge (where it meets another
                                   part, the base or the background) passes here
        motion    (B, 6, S/2, S/2)  logits of generator.motions.MOTIONS per pixel
        category  (B, 8)            logits of CATEGORIES (pooled features)
        box       (B, 4, S/2, S/2)  (with ``ParserConfig.box``) on a movable part's pixel,
                                   the distances from it to its part's box (left, top,
                                   right, bottom), as fractions of the crop side: the
                                   pixels of one part agree on one box, so adjacent parts
                                   (two stacked drawers) separate without a visible edge

Encoder: a stride-2 stem then one stage per level (a strided residual block, then
``blocks`` residual blocks), widths ``channels`` at 1/2 .. 1/32 of the input. A global
context vector (the bottleneck's mean) is added back to the bottleneck, so every pixel
sees the whole object (a door's hinge side is where its handle is not). Decoder: bilinear
2x up, concatenation with the encoder's skip, a conv + residual block, up to 1/2
resolution, where the two dense heads read. BatchNorm (folded at inference would be
cheap; CPU-friendly), SiLU. Sizes are data (``ParserConfig``); ``build`` makes a model
from a config dict.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import NamedTuple

import torch
import torch.nn as nn
import torch.nn.functional as F
from safetensors.torch import load_file, save_file

from generator.motions import MOTIONS
from generator.procedural import CATEGORIES as OBJECT_CATEGORIES

#: The category head's classes, in its order: the procedural categories, then "other".
CATEGORIES: tuple[str, ...] = (*OBJECT_CATEGORIES, "other")
SEG_CLASSES: tuple[str, ...] = ("background", "base", "part")


@dataclass
class ParserConfig:
    image_size: int = 256
    channels: tuple[int, ...] = (32, 48, 96, 160, 256)  # at 1/2, 1/4, 1/8, 1/16, 1/32
    blocks: tuple[int, ...] = (0, 1, 1, 2, 2)  # extra residual blocks per encoder level
    decoder_channels: tuple[int, ...] = (32, 48, 96, 128)  # at 1/2 .. 1/16
    n_categories: int = len(CATEGORIES)
    n_motions: int = len(MOTIONS)
    n_seg: int = len(SEG_CLASSES)
    dropout: float = 0.1  # before the category head
    upsample: str = "nearest"  # decoder's 2x upsampling: "nearest" (cheap backward) or "bilinear"
    box: bool = False  # the part-box head (``ParserOutput.box``)

    @classmethod
    def from_dict(cls, d: dict) -> ParserConfig:
        names = {f.name for f in fields(cls)}
        kw = {k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items() if k in names}
        return cls(**kw)

    def to_dict(self) -> dict:
        return asdict(self)


class ParserOutput(NamedTuple):
    seg: torch.Tensor  # (B, 3, S/2, S/2)
    boundary: torch.Tensor  # (B, 1, S/2, S/2)
    motion: torch.Tensor  # (B, 6, S/2, S/2)
    category: torch.Tensor  # (B, 8)
    box: torch.Tensor | None = None  # (B, 4, S/2, S/2) distances (>= 0), or None


def conv_bn(cin: int, cout: int, stride: int = 1, k: int = 3) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, k, stride, k // 2, bias=False), nn.BatchNorm2d(cout), nn.SiLU()
    )


class ResBlock(nn.Module):
    """x -> x' = act(x W1) W2 + shortcut(x); ``stride`` 2 halves the resolution."""

    def __init__(self, cin: int, cout: int, stride: int = 1) -> None:
        super().__init__()
        self.conv1 = conv_bn(cin, cout, stride)
        self.conv2 = nn.Sequential(nn.Conv2d(cout, cout, 3, 1, 1, bias=False), nn.BatchNorm2d(cout))
        self.short = (
            nn.Identity()
            if stride == 1 and cin == cout
            else nn.Sequential(
                nn.AvgPool2d(stride) if stride > 1 else nn.Identity(),
                nn.Conv2d(cin, cout, 1, bias=False),
                nn.BatchNorm2d(cout),
            )
        )
        self.act = nn.SiLU()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.act(self.conv2(self.conv1(x)) + self.short(x))


class ParserNet(nn.Module):
    """Residual U-Net: image -> part classes, motions per pixel, category."""

    def __init__(self, cfg: ParserConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or ParserConfig()
        ch, dch = list(cfg.channels), list(cfg.decoder_channels)
        self.stem = conv_bn(3, ch[0], 2)  # 1/2
        self.stages = nn.ModuleList()
        for i, c in enumerate(ch):
            layers: list[nn.Module] = [] if i == 0 else [ResBlock(ch[i - 1], c, 2)]
            layers += [ResBlock(c, c) for _ in range(cfg.blocks[i])]
            self.stages.append(nn.Sequential(*layers))
        self.context = nn.Sequential(nn.Linear(ch[-1], ch[-1]), nn.SiLU())
        # decoder: from the bottleneck (1/32) up to 1/2
        self.up = nn.ModuleList()
        below = ch[-1]
        for i in reversed(range(len(dch))):
            self.up.append(
                nn.Sequential(conv_bn(below + ch[i], dch[i], k=1), ResBlock(dch[i], dch[i]))
            )
            below = dch[i]
        self.head = conv_bn(dch[0], dch[0])
        self.seg_head = nn.Conv2d(dch[0], cfg.n_seg + 1, 1)  # classes + boundary
        self.motion_head = nn.Conv2d(dch[0], cfg.n_motions, 1)
        self.box_head = nn.Conv2d(dch[0], 4, 1) if cfg.box else None
        if self.box_head is not None:  # softplus(-2) ~ 0.13 of the crop to start
            nn.init.zeros_(self.box_head.weight)
            nn.init.constant_(self.box_head.bias, -2.0)
        self.category_head = nn.Sequential(
            nn.Dropout(cfg.dropout), nn.Linear(ch[-1] + ch[-2], cfg.n_categories)
        )
        mean, std = (0.485, 0.456, 0.406), (0.229, 0.224, 0.225)
        self.register_buffer("pixel_mean", torch.tensor(mean).view(1, 3, 1, 1), False)
        self.register_buffer("pixel_std", torch.tensor(std).view(1, 3, 1, 1), False)

    def forward(self, images: torch.Tensor) -> ParserOutput:
        """images (B, 3, S, S) in [0, 1], S a multiple of 32."""
        x = (images - self.pixel_mean) / self.pixel_std
        x = self.stem(x)  # (B, C0, S/2, S/2)
        skips = []
        for stage in self.stages:
            x = stage(x)
            skips.append(x)  # (B, Ci, S/2^(i+1), ...)
        g = x.mean((2, 3))  # (B, C4)
        x = x + self.context(g)[:, :, None, None]
        pooled = torch.cat([g, skips[-2].amax((2, 3))], 1)  # (B, C4 + C3)
        category = self.category_head(pooled.float())
        for k, block in enumerate(self.up):
            skip = skips[len(self.up) - 1 - k]
            if self.cfg.upsample == "nearest":
                x = F.interpolate(x, size=skip.shape[-2:], mode="nearest")
            else:
                x = F.interpolate(x, size=skip.shape[-2:], mode="bilinear", align_corners=False)
            x = block(torch.cat([x, skip], 1))
        x = self.head(x)
        seg = self.seg_head(x)
        box = None if self.box_head is None else F.softplus(self.box_head(x).float())
        return ParserOutput(
            seg[:, : self.cfg.n_seg], seg[:, self.cfg.n_seg :], self.motion_head(x), category, box
        )


WEIGHTS_SCHEMA = "pact.parser_weights"


class ParserWeightsError(ValueError):
    """A folder that holds no parser weights of a known schema."""


def save_weights(model: ParserNet, path: str | Path, extra: dict | None = None) -> Path:
    """``path``/model.safetensors (float16 matrices, float32 vectors and norms) +
    ``config.json``; written under a temporary name, then renamed."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    tensors = {}
    for k, v in model.state_dict().items():
        v = v.detach().to("cpu").contiguous()
        tensors[k] = v.half() if v.is_floating_point() and v.dim() > 1 else v
    save_file(tensors, str(tmp / "model.safetensors"))
    meta = {
        "schema": WEIGHTS_SCHEMA,
        "version": 1,
        "config": model.cfg.to_dict(),
        "extra": extra or {},
    }
    (tmp / "config.json").write_text(json.dumps(meta, indent=2))
    if path.exists():
        shutil.rmtree(path)
    tmp.rename(path)
    return path


def load_weights(path: str | Path, device: str | torch.device = "cpu") -> tuple[ParserNet, dict]:
    """The model of a weights folder (float32, eval mode) and its config.json."""
    path = Path(path)
    cfg_path = path / "config.json"
    if not cfg_path.is_file():
        raise ParserWeightsError(f"{path}: no config.json; is it a parser weights folder?")
    meta = json.loads(cfg_path.read_text())
    if meta.get("schema") != WEIGHTS_SCHEMA:
        raise ParserWeightsError(
            f"{cfg_path}: schema {meta.get('schema')!r}, expected {WEIGHTS_SCHEMA!r}"
        )
    model = build(meta["config"])
    state = load_file(str(path / "model.safetensors"))
    model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in state.items()})
    return model.to(device).eval(), meta


def build(config: dict | ParserConfig | None = None) -> ParserNet:
    if isinstance(config, dict):
        config = ParserConfig.from_dict(config)
    return ParserNet(config)


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


def cpu_has_native_bf16() -> bool:
    """Whether this machine's CPU computes bfloat16 natively (the AVX512-BF16 or AMX
    instructions, read from ``/proc/cpuinfo``). Elsewhere torch emulates bfloat16 and a
    pass of this network under bf16 autocast is about ten times slower than in float32
    (measured on an AVX2-only AMD EPYC), so the parser runs in float32 there."""
    try:
        flags = Path("/proc/cpuinfo").read_text()
    except OSError:
        return False
    return any(f in flags for f in ("avx512_bf16", "amx_bf16"))


__all__ = [
    "CATEGORIES",
    "SEG_CLASSES",
    "ParserConfig",
    "ParserNet",
    "ParserOutput",
    "build",
    "count_parameters",
    "cpu_has_native_bf16",
    "load_weights",
    "save_weights",
]
